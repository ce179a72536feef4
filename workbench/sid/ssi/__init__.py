"""Stochastic subspace identification (SSI), covariance- and data-driven, reference-based.

Both variants identify, from output-only accelerations, the stochastic state-space model

.. math::

    x_{k+1} = A x_k + w_k, \\qquad y_k = C x_k + v_k,

and return the poles and mode shapes of *every* model order of a stabilisation diagram from
one singular value decomposition (:func:`workbench.sid.modal.poles_all_orders`).

The package, one module per responsibility: :mod:`.preparation` (defaults, checks of the
data and options, the threading policy), :mod:`.hankel` (lagged products by FFT, the exact
Gram matrices of the block Hankel and Toeplitz matrices), :mod:`.decomposition` (leading
singular triplets from a partial eigendecomposition), :mod:`.realisation` (state-space
matrices, noise covariances, Kalman gain and the assembled result), the two public
functions :func:`ssi_cov` (:mod:`.covariance_driven`) and :func:`ssi_data`
(:mod:`.data_driven`), and the result classes :class:`SSIResult` and
:class:`StochasticStateSpace` (:mod:`.results`).

Conventions
-----------
- The mean of every channel is removed first (no other conditioning: detrend, filter and
  decimate with :mod:`workbench.signals` beforehand).
- Reference channels (default: all) are the projection channels of Peeters & De Roeck [1]_.
- Non-physical poles are dropped consistently for both variants: real eigenvalues of A,
  the conjugate of every complex pair (only the eigenvalue with positive imaginary part is
  kept) and poles whose natural frequency is not strictly between 0 and the Nyquist
  frequency. Poles with negative damping are kept in the table (they are never flagged
  stable) so that a diagram shows them.
- Linear algebra runs with single-threaded BLAS: the matrices are moderate (a few hundred
  to a thousand rows), blocks are processed in parallel by processes, and multi-threaded
  LAPACK on such matrices is slower and collapses when other processes compete for the
  cores. Independent pieces (FFT batches, halves of a matrix product, the per-order
  eigenvalue problems) run on Python threads instead, as many as
  :func:`workbench.sid.threads.thread_budget` allows: the BLAS thread limit in effect when
  the function is called, so ``threadpoolctl.threadpool_limits(1)`` makes it serial.

References
----------
.. [1] B. Peeters, G. De Roeck, "Reference-based stochastic subspace identification for
   output-only modal analysis", Mechanical Systems and Signal Processing 13(6), 855-878,
   1999. doi:10.1006/mssp.1999.1249
.. [2] P. Van Overschee, B. De Moor, "Subspace Identification for Linear Systems",
   Kluwer, 1996. doi:10.1007/978-1-4613-0465-4
"""

from .covariance_driven import ssi_cov
from .data_driven import ssi_data
from .results import SSIResult, SSIWarning, StochasticStateSpace

__all__ = [
    "SSIResult",
    "SSIWarning",
    "StochasticStateSpace",
    "ssi_cov",
    "ssi_data",
]
