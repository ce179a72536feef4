"""Typed options of the sliding forecast: the model, the noise, the measurement choice.

Descriptive names with the reference work's labels kept as aliases:

=====================  ===========  ======================================================
name                   alias        meaning
=====================  ===========  ======================================================
``"tracked_pole"``     ``"A"``      measurement = the block's tracked pole (modal table)
``"pole_cluster"``     ``"B"``      measurement = a consistent pole cluster of the block's
                                    stabilisation diagram inside the prediction gate
``"single_window"``    ``1``        one training window, one long forward prediction
``"rolling"``          ``2``        predict *horizon* blocks, filter them, refit, repeat
=====================  ===========  ======================================================
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from .innovation_consistency import MIN_BLOCKS, WINDOW_BLOCKS
from .kalman import relaxation_factor

__all__ = [
    "DEFAULT_HORIZON",
    "DEFAULT_MODEL",
    "DEFAULT_TRUST",
    "ForecastOptions",
    "NoiseOptions",
    "check_train_blocks",
    "check_trust",
    "method_label",
    "option_label",
]

#: Default forecast horizon per scheme (1 single-window, 2 rolling). [blocks]
DEFAULT_HORIZON = {1: 34, 2: 4}
#: Steady-state weight on the SSI estimate of the window model when *trust* is "auto". [-]
DEFAULT_TRUST = 0.65

#: The predictive model of the forecast stage, the command line and the demo: "memory"
#: measures best on benchmarks/bench_forecast_accuracy.py
#: (benchmarks/results/forecast_accuracy_after.txt); "window" is the reference configuration.
DEFAULT_MODEL: Literal["memory", "window"] = "memory"


def check_trust(trust, model: str) -> None:
    """Refuse a hand-set *trust* for a model that does not take one.

    One rule for the forecast stage, the sliding forecast and the live monitor: only
    ``model="window"`` (the reference configuration) takes a steady-state weight on SSI;
    ``"memory"`` estimates its noise levels from the data (*trust* ``"auto"`` or None).

    Raises
    ------
    ValueError
        Naming trust and model.
    """
    if model != "window" and trust not in ("auto", None):
        raise ValueError(
            f"trust={trust!r} applies to model='window' (the reference configuration); "
            f"model={model!r} estimates its noise levels from the data"
        )


#: Prior standard deviation of a mode's relative frequency change per unit of a predictor's
#: move beyond the range the model saw (``extrapolation_sensitivity``) [1/unit]: the speed
#: 0.2 % a knot (water's added mass and hydrodynamic stiffness: global hull modes lower by
#: 1-3 % at service speed), a temperature 0.1 % a degree (steel's modulus, the water's and
#: ice's added stiffness). A prior, not a measurement: what a mode may do where nothing
#: the forecast has seen says.
EXTRAPOLATION_SENSITIVITY: dict[str, float] = {
    "speed_kn": 0.002,
    "water_temp_c": 0.001,
    "air_temp_c": 0.001,
}

#: The fewest training blocks a model is fitted on unless ``min_train_blocks`` is given:
#: ``max(5, train_blocks // 2)``. [blocks]
MIN_TRAIN_BLOCKS = 5


def default_min_train_blocks(train_blocks: int) -> int:
    """``min_train_blocks`` when not given: ``max(5, train_blocks // 2)``. [blocks]"""
    return max(MIN_TRAIN_BLOCKS, int(train_blocks) // 2)


def check_train_blocks(train_blocks, min_train_blocks: int | None = None) -> None:
    """Refuse a training window shorter than the fewest blocks a model is fitted on.

    One rule for the forecast stage, the sliding forecast, the live monitor and the
    configuration file.

    Raises
    ------
    ValueError
        Naming train_blocks and the constraint.
    """
    if int(train_blocks) != train_blocks:
        raise ValueError(f"train_blocks={train_blocks!r} must be a whole number of blocks")
    low = default_min_train_blocks(train_blocks) if min_train_blocks is None else min_train_blocks
    if min_train_blocks is None and train_blocks < MIN_TRAIN_BLOCKS:
        raise ValueError(
            f"train_blocks={train_blocks} must be at least {MIN_TRAIN_BLOCKS} (the fewest "
            "blocks a model is fitted on)"
        )
    if not 2 <= low <= train_blocks:
        raise ValueError(f"min_train_blocks={low} must be in [2, train_blocks={train_blocks}]")


_OPTIONS = {
    "A": "A",
    "B": "B",
    "tracked_pole": "A",
    "pole_cluster": "B",
    "tracked-pole": "A",
    "pole-cluster": "B",
}
_METHODS = {1: 1, 2: 2, "1": 1, "2": 2, "single_window": 1, "single-window": 1, "rolling": 2}


def option_label(option: str) -> Literal["A", "B"]:
    """'A' or 'B' for an option name or alias (``"tracked_pole"``, ``"pole_cluster"``)."""
    try:
        return _OPTIONS[option]  # type: ignore[return-value]
    except (KeyError, TypeError):
        raise ValueError(
            f"option={option!r} must be 'A' ('tracked_pole') or 'B' ('pole_cluster')"
        ) from None


def method_label(method: int | str) -> Literal[1, 2]:
    """1 or 2 for a method number or name (``"single_window"``, ``"rolling"``)."""
    try:
        return _METHODS[method]  # type: ignore[return-value]
    except (KeyError, TypeError):
        raise ValueError(
            f"scheme={method!r} must be 'single_window' (1) or 'rolling' (2)"
        ) from None


@dataclass(frozen=True)
class NoiseOptions:
    """Noise levels of the Kalman blend (model ``"memory"``).

    Parameters
    ----------
    noise_blocks : int
        Newest blocks whose residuals the covariance matching uses
        (:mod:`workbench.forecasting.noise`). [blocks]
    huber_sigma : float
        Innovations beyond this many standard deviations get a Huber weight (the
        measurement counts as if it were this far out): mis-selected poles and
        heavy-tailed errors cannot pull the estimate far. [-]
    pole_scatter : bool
        Scale each block's measurement variance by its cluster's frequency scatter across
        model orders (needs *poles*).
    consistency_blocks : int
        Newest out-of-sample blocks whose normalised innovations the consistency tests
        use (:mod:`workbench.forecasting.innovation_consistency`: model variance is added
        while they are larger or more one-sided than the noise model says); 0 turns the
        safeguard off. [blocks]
    model_trust : bool
        Weigh the blend against a filter that does not use the model by how well each
        predicts the measurements (:mod:`workbench.forecasting.model_trust`): the estimate
        falls back to the model-free filter, which follows SSI, while the model does not
        explain the mode (an unrecorded change: fuel, ballast, ice). False: the blend
        alone.
    """

    noise_blocks: int = 576
    huber_sigma: float = 2.5
    pole_scatter: bool = True
    consistency_blocks: int = WINDOW_BLOCKS
    model_trust: bool = True

    def __post_init__(self):
        if int(self.noise_blocks) < 10:
            raise ValueError(f"noise_blocks={self.noise_blocks} must be >= 10")
        if self.consistency_blocks != 0 and self.consistency_blocks < MIN_BLOCKS:
            raise ValueError(
                f"consistency_blocks={self.consistency_blocks} must be 0 (off) or >= {MIN_BLOCKS}"
            )
        if not self.huber_sigma > 0:
            raise ValueError(f"huber_sigma={self.huber_sigma!r} must be > 0")


@dataclass(frozen=True)
class ForecastOptions:
    """Every setting of a forecast, from the command line or the API down to the filter.

    ``workbench forecast`` and :func:`workbench.forecast` build one, and
    :func:`~workbench.forecasting.sliding_forecast`, the window model
    (:mod:`workbench.forecasting.window`) and the memory model
    (:mod:`workbench.forecasting.memory`) read it as it is.

    Parameters
    ----------
    options : tuple of {"A", "B"}
        Measurement options, each run into one table. A (``"tracked_pole"``): the block's
        tracked pole; B (``"pole_cluster"``): an automatic pole selection from the block's
        stabilisation diagram: among the poles inside the gate ``gate_sigma * sqrt(P⁻ + R)``
        around the a-priori estimate whose shape matches the mode's reference shape
        (MAC >= *mac_min*), the best by a score (:mod:`workbench.forecasting.sliding`,
        Notes). Without shape columns in the poles and the modal table: the nearest pole
        inside the gate, stable poles preferred, no MAC check (with a warning); with
        ``model="memory"`` a pick nearer to another mode's tracked pole of the block (else
        its a-priori estimate) than to the mode's own is refused and the mode's tracked pole
        measured (:func:`~workbench.forecasting.measurement.nearer_to_another_mode`).
    scheme : {"rolling", "single_window"} or {2, 1}
        How the forecast slides (the reference work's methods 2 and 1). ``"rolling"`` (2):
        predict *horizon* blocks, Kalman-filter them, slide the window by *horizon* blocks
        (model ``"window"``: with the Kalman estimates as new training targets), refit,
        repeat to the end. ``"single_window"`` (1): one training window, one forward
        prediction of *horizon* blocks.
    train_blocks : int
        Training window length N (the first window of ``"memory"``). [blocks]
    horizon : int, optional
        Blocks predicted per window; default :data:`DEFAULT_HORIZON` of the scheme (34 for
        single-window, 4 for rolling). [blocks]
    trust : float, None or "auto"
        Model ``"window"``: steady-state Kalman gain, the weight on the SSI estimate (0.65:
        65 % SSI, 35 % model); Q follows from R
        (:func:`~workbench.forecasting.kalman.process_variance_for_gain`). ``None``: Q =
        s_m² (1 - φ²) with s_m² the model's mean-prediction variance over the window's
        forecast blocks. ``"auto"``: :data:`DEFAULT_TRUST` for ``"window"``; ``"memory"``
        estimates its noise levels from the data and takes no other value.
    model : {"memory", "window"}, optional
        The predictive model. ``"memory"`` (default, :data:`DEFAULT_MODEL`): stepwise terms
        with coefficients over the whole history with exponential forgetting, noise levels
        from the data, an AR(1) measurement-error state and a measurement equation for
        SSI's excitation weighting (:mod:`workbench.forecasting.memory`). ``"window"``: the
        reference configuration, a stepwise model fitted on the last *train_blocks* blocks,
        Kalman trust *trust*; the default when *trust* is given as a number or None, since
        only the window model takes a hand-set trust. How the two compare:
        ``benchmarks/bench_forecast_accuracy.py``, results in
        ``benchmarks/results/forecast_accuracy_after.txt``.
    correction_time_blocks : float
        Model ``"window"``: time constant τ of the Kalman correction, φ = exp(-1/τ);
        ``inf`` gives the random walk x⁻_k = x⁺_{k-1} + (m_k - m_{k-1}). Default 36 blocks
        (3 h of 5-min steps). [blocks]
    gate_sigma : float
        Option B gate in innovation standard deviations.
    mac_min : float
        Option B: a pole is admissible for a mode only when the MAC of its shape with the
        mode's reference shape is at least this, compared on the channels both shapes have.
        Why 0.9: ``benchmarks/results/forecast_option_b_settings.txt``. [-]
    reacquire_blocks : int
        Option B: consecutive blocks with no admissible pole inside the gate but one near
        the mode (within *reacquire_band*) after which the track is re-acquired outside the
        gate (model ``"window"``) or the column seen there is measured, Huber-weighted,
        without resetting the prior (model ``"memory"``,
        :class:`~workbench.forecasting.measurement.ClusterChooser`). Why 1:
        ``benchmarks/results/forecast_option_b_settings.txt``. [blocks]
    reacquire_band : float
        Option B: relative half-width of the band searched for the mode outside the gate,
        around the last chosen pole's frequency and around the a-priori estimate (0.05:
        ±5 %). [-]
    max_gate : float
        Option B (model ``"memory"``): the gate's half-width is at most this fraction of the
        a-priori frequency. [-]
    predictor_columns : sequence of str, optional
        Candidate predictors; default every numeric column of the predictors except
        ``block``.
    stepwise_options : mapping, optional
        Keyword arguments for :func:`workbench.stats.stepwise` (``upper``, ``p_enter``...).
        Model ``"window"`` fits a window's model on the rows complete in every candidate
        predictor (``missing="complete"``) unless they say otherwise.
    min_train_blocks : int, optional
        Fewest valid targets for a stepwise fit (else a fallback); default
        ``max(5, train_blocks // 2)``. A predictor with fewer valid values in the window is
        left out of that window's candidates. [blocks]
    gap_warning_blocks : int
        Consecutive blocks without a measurement after which rows carry a warning. [blocks]
    alpha : float
        1 - confidence of the prediction interval (0.05: 95 %).
    extrapolation_limit : float
        Normalised predictors are clipped to ±this many window standard deviations before
        prediction, so a long forecast cannot extrapolate a 20-block fit without bound
        (e.g. a time trend); clipped blocks carry a warning.
    extrapolation_sensitivity : mapping of str to float, optional
        Model ``"memory"``: per predictor column, the prior standard deviation of a mode's
        relative frequency change per unit of the predictor beyond the range the model was
        fitted on [1/unit]. In a row where the mode is not measured (a hole in the record)
        and a predictor lies a distance d beyond that range, of width w, the estimate's
        variance grows by (ρ f d)² d / (d + w), f the model's frequency: a predictor the model
        saw constant (the speed in port) widens the band by its whole excursion, one it saw
        over a range wider than the step hardly at all. The estimate is unchanged. Default
        :data:`EXTRAPOLATION_SENSITIVITY`; ``{}``: none.
    memory_blocks : float
        Model ``"memory"``: forgetting time constant, λ = exp(-1/memory_blocks). Default
        576 blocks (2 days of 5-minute blocks). [blocks]
    selection_blocks : int
        Model ``"memory"``: measured blocks the stepwise term selection uses (the newest).
        [blocks]
    reselect_blocks : int
        Model ``"memory"``: blocks between two term selections. [blocks]
    selection_stride : int
        Model ``"memory"``: the term selection uses every this-many-th block (4:
        non-overlapping 20-minute blocks), so that F-tests do not count one correlated SSI
        error several times.
    time_trend : bool
        Model ``"memory"``: add ``elapsed_hours`` to the candidate predictors (fuel burn and
        ballast drift slowly and no log records them), unless *predictor_columns* is given.
    excitation_bias : bool
        Model ``"memory"``: model the bias of SSI in a block whose speed changes (it weights
        the faster part, :mod:`workbench.forecasting.excitation`): the measurement equation
        evaluates the model at the excitation-weighted speed v̄ + κ σ_v², σ_v² the
        within-block speed variance recovered from the overlapping blocks' means, κ >= 0
        estimated from the data (pooled over the modes); the state (the block's time
        average) is the model at v̄. Needs ``speed_kn``, ``block_end`` and blocks that
        overlap by a whole number of steps.
    short_history_selection : bool
        Model ``"memory"``: while the history holds fewer non-overlapping measured blocks
        than a stepwise selection needs (10), select main effects only on every measured
        block, with the entry p-value divided by *selection_stride* (0.05 / 4: the F-tests
        count each correlated SSI error up to *selection_stride* times), instead of the
        constant model. A 20-block first window otherwise has no speed term at all.
    noise : NoiseOptions
        Model ``"memory"``: the noise levels of the Kalman blend.
    min_presence : float
        The forecast stage forecasts only modes measured in at least this share of the
        blocks with data (those of the tracked modal table: a block without an
        acceleration record, given up or skipped as faulty is no block a mode was absent
        from). [-]
    n_workers : int
        Processes the forecast stage spreads the modes over (the table is the same whatever
        the number).
    """

    options: tuple[str, ...] = ("A",)
    scheme: int | str = 2
    train_blocks: int = 20
    horizon: int | None = None
    trust: float | None | Literal["auto"] = "auto"
    model: Literal["memory", "window"] | None = None
    correction_time_blocks: float = 36.0
    gate_sigma: float = 3.0
    mac_min: float = 0.9
    reacquire_blocks: int = 1
    reacquire_band: float = 0.05
    max_gate: float = 0.02
    predictor_columns: Sequence[str] | None = None
    stepwise_options: Mapping[str, Any] | None = None
    min_train_blocks: int | None = None
    gap_warning_blocks: int = 12
    alpha: float = 0.05
    extrapolation_limit: float = 4.0
    extrapolation_sensitivity: Mapping[str, float] | None = None
    memory_blocks: float = 576.0
    selection_blocks: int = 288
    reselect_blocks: int = 36
    selection_stride: int = 4
    time_trend: bool = True
    excitation_bias: bool = True
    short_history_selection: bool = True
    noise: NoiseOptions = field(default_factory=NoiseOptions)
    min_presence: float = 0.5
    n_workers: int = 1

    def __post_init__(self) -> None:
        options = self.options
        if isinstance(options, str):
            options = tuple(options) if options == "AB" else (options,)
        object.__setattr__(self, "options", tuple(option_label(o) for o in options))
        if not self.options:
            raise ValueError("options=() must name at least one measurement option")
        object.__setattr__(self, "scheme", method_label(self.scheme))
        if self.model is None:
            object.__setattr__(self, "model", DEFAULT_MODEL if self.trust == "auto" else "window")
        if self.model not in ("memory", "window"):
            raise ValueError(f"model={self.model!r} must be 'memory' or 'window'")
        if self.predictor_columns is not None:
            object.__setattr__(self, "predictor_columns", tuple(self.predictor_columns))
        check_trust(self.trust, self.model)
        self._check_numbers()

    def sensitivities(self) -> dict[str, float]:
        """``extrapolation_sensitivity`` with its default: column -> ρ [1/unit]."""
        given = self.extrapolation_sensitivity
        return {
            k: float(v) for k, v in (EXTRAPOLATION_SENSITIVITY if given is None else given).items()
        }

    def _check_numbers(self) -> None:
        """ValueError naming the first setting out of its range."""
        check_train_blocks(self.train_blocks, self.min_train_blocks)
        if self.horizon is not None and not int(self.horizon) >= 1:
            raise ValueError(f"horizon={self.horizon} must be >= 1")
        if self.trust not in ("auto", None) and not 0.0 < float(self.trust) < 1.0:
            raise ValueError(f"trust={self.trust!r} must be in (0, 1) or None")
        if self.trust is None and relaxation_factor(self.correction_time_blocks) == 1.0:
            raise ValueError("trust=None needs a finite correction_time_blocks")
        for name in ("gate_sigma", "reacquire_band", "max_gate", "extrapolation_limit"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}={getattr(self, name)!r} must be > 0")
        for name, value in dict(self.extrapolation_sensitivity or {}).items():
            if not (math.isfinite(float(value)) and float(value) >= 0.0):
                raise ValueError(f"extrapolation_sensitivity[{name!r}]={value!r} must be >= 0")
        if not 0.0 <= self.mac_min < 1.0:
            raise ValueError(f"mac_min={self.mac_min!r} must be in [0, 1)")
        if int(self.reacquire_blocks) != self.reacquire_blocks or self.reacquire_blocks < 1:
            raise ValueError(f"reacquire_blocks={self.reacquire_blocks!r} must be an integer >= 1")
        if not 0.0 < self.alpha < 1.0:
            raise ValueError(f"alpha={self.alpha!r} must be in (0, 1)")
        if not self.memory_blocks > 0:
            raise ValueError(f"memory_blocks={self.memory_blocks!r} must be > 0")
        if int(self.selection_blocks) < 5:
            raise ValueError(f"selection_blocks={self.selection_blocks} must be >= 5")
        if int(self.reselect_blocks) < 1:
            raise ValueError(f"reselect_blocks={self.reselect_blocks} must be >= 1")
        if not 0.0 <= self.min_presence <= 1.0:
            raise ValueError(f"min_presence={self.min_presence} must be in [0, 1]")
        if self.n_workers < 1:
            raise ValueError(f"n_workers={self.n_workers} must be at least 1")

    @property
    def horizon_blocks(self) -> int:
        """*horizon*, or the scheme's default when not given. [blocks]"""
        return DEFAULT_HORIZON[self.scheme] if self.horizon is None else int(self.horizon)

    @property
    def min_train(self) -> int:
        """*min_train_blocks*, or ``max(5, train_blocks // 2)`` when not given. [blocks]"""
        if self.min_train_blocks is None:
            return default_min_train_blocks(self.train_blocks)
        return int(self.min_train_blocks)

    @property
    def window_trust(self) -> float | None:
        """*trust* of model ``"window"``: :data:`DEFAULT_TRUST` for ``"auto"``."""
        return DEFAULT_TRUST if self.trust == "auto" else self.trust

    @property
    def transition(self) -> float:
        """φ = exp(-1/correction_time_blocks) of model ``"window"``."""
        return relaxation_factor(self.correction_time_blocks)
