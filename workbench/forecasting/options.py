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

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

from .._deprecation import renamed_fields
from .innovation_consistency import MIN_BLOCKS, WINDOW_BLOCKS

__all__ = [
    "DEFAULT_MODEL",
    "check_train_blocks",
    "check_trust",
    "MeasurementOptions",
    "ModelOptions",
    "NoiseOptions",
    "method_label",
    "option_label",
]

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
            f"method={method!r} must be 1 ('single_window') or 2 ('rolling')"
        ) from None


@dataclass(frozen=True)
class ModelOptions:
    """The predictive model.

    Parameters
    ----------
    kind : {"memory", "window"}
        ``"memory"`` (default): stepwise terms, coefficients by exponentially weighted least
        squares over all measured blocks so far (:mod:`workbench.forecasting.memory.model`);
        ``"window"``: the reference configuration, a stepwise fit on the last
        *train_blocks* blocks (method 2: on the Kalman estimates).
    train_blocks : int
        First training window (and the window of ``"window"``). [blocks]
    memory_blocks : float
        Forgetting time constant of ``"memory"``, λ = exp(-1/memory_blocks). Default 576
        blocks (2 days of 5-minute blocks). [blocks]
    selection_blocks : int
        Measured blocks the stepwise term selection of ``"memory"`` uses (the newest).
        [blocks]
    reselect_blocks : int
        Blocks between two term selections of ``"memory"``. [blocks]
    selection_stride : int
        The term selection uses every this-many-th block (4: non-overlapping 20-minute
        blocks), so that F-tests do not count one correlated SSI error several times.
    time_trend : bool
        ``"memory"``: add ``elapsed_hours`` to the candidate predictors (fuel burn and
        ballast drift slowly and no log records them), unless *predictor_columns* is
        given.
    excitation_bias : bool
        ``"memory"``: model the bias of SSI in a block whose speed changes (it weights the
        faster part, :mod:`workbench.forecasting.excitation`): the measurement equation
        evaluates the model at the excitation-weighted speed v̄ + κ σ_v², σ_v² the
        within-block speed variance recovered from the overlapping blocks' means, κ >= 0
        estimated from the data (pooled over the modes); the state (the block's time
        average) is the model at v̄. Needs
        ``speed_kn``, ``block_end`` and blocks that overlap by a whole number of steps.
    short_history_selection : bool
        ``"memory"``: while the history holds fewer non-overlapping measured blocks than a
        stepwise selection needs (10), select main effects only on every measured block,
        with the entry p-value divided by *selection_stride* (0.05 / 4: the F-tests count
        each correlated SSI error up to *selection_stride* times), instead of the constant
        model. A 20-block first window otherwise has no speed term at all.
    """

    kind: Literal["memory", "window"] = "memory"
    train_blocks: int = 20
    memory_blocks: float = 576.0
    selection_blocks: int = 288
    reselect_blocks: int = 36
    selection_stride: int = 4
    time_trend: bool = True
    excitation_bias: bool = True
    short_history_selection: bool = True
    min_train_blocks: int | None = None
    predictor_columns: Sequence[str] | None = None
    stepwise_options: Mapping[str, Any] | None = None
    extrapolation_limit: float = 4.0
    alpha: float = 0.05

    def __post_init__(self):
        if self.kind not in ("memory", "window"):
            raise ValueError(f"model kind={self.kind!r} must be 'memory' or 'window'")
        if int(self.train_blocks) < 2:
            raise ValueError(f"train_blocks={self.train_blocks} must be >= 2")
        if not self.memory_blocks > 0:
            raise ValueError(f"memory_blocks={self.memory_blocks!r} must be > 0")
        if int(self.selection_blocks) < 5:
            raise ValueError(f"selection_blocks={self.selection_blocks} must be >= 5")
        if int(self.reselect_blocks) < 1:
            raise ValueError(f"reselect_blocks={self.reselect_blocks} must be >= 1")
        if not self.extrapolation_limit > 0:
            raise ValueError(f"extrapolation_limit={self.extrapolation_limit!r} must be > 0")
        if not 0.0 < self.alpha < 1.0:
            raise ValueError(f"alpha={self.alpha!r} must be in (0, 1)")


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


@renamed_fields(shape_mac_min="mac_min")
@dataclass(frozen=True)
class MeasurementOptions:
    """What each block measures (option A or B) and option B's gate.

    Parameters
    ----------
    option : {"A", "B", "tracked_pole", "pole_cluster"}
    gate_sigma : float
        Option B gate in innovation standard deviations.
    mac_min : float
        Option B with shapes: lowest MAC of a pole with the mode's reference shape.
    reacquire_blocks : int
        Option B: blocks with the mode seen only outside the gate before it is re-acquired
        (model ``"window"``) or measured there, Huber-weighted (model ``"memory"``,
        :class:`~workbench.forecasting.measurement.ClusterChooser`). Default 1.
    reacquire_band : float
        Option B: relative half-width searched outside the gate. [-]
    max_gate : float
        Option B (model ``"memory"``): the gate's half-width is at most this fraction of
        the a-priori frequency. [-]
    """

    option: str = "A"
    gate_sigma: float = 3.0
    mac_min: float = 0.9
    reacquire_blocks: int = 1
    reacquire_band: float = 0.05
    max_gate: float = 0.02

    def __post_init__(self):
        object.__setattr__(self, "option", option_label(self.option))
        if not self.max_gate > 0:
            raise ValueError(f"max_gate={self.max_gate!r} must be > 0")
        if not self.gate_sigma > 0:
            raise ValueError(f"gate_sigma={self.gate_sigma!r} must be > 0")
        if not 0.0 <= self.mac_min < 1.0:
            raise ValueError(f"mac_min={self.mac_min!r} must be in [0, 1)")
        if int(self.reacquire_blocks) != self.reacquire_blocks or self.reacquire_blocks < 1:
            raise ValueError(f"reacquire_blocks={self.reacquire_blocks!r} must be an integer >= 1")
        if not self.reacquire_band > 0:
            raise ValueError(f"reacquire_band={self.reacquire_band!r} must be > 0")
