"""The combined modal model of one block (workbench.sid.combined)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from workbench.sid.combined import RELATIVE_FLOOR, combine_modes
from workbench.sid.selection import ModeSelection


def _selection(frequency, damping, frequency_std, damping_std, shapes):
    modes = pd.DataFrame(
        {
            "frequency_hz": frequency,
            "damping_ratio": damping,
            "frequency_std_hz": frequency_std,
            "damping_std": damping_std,
        }
    )
    return ModeSelection(modes, np.asarray(shapes, dtype=complex), None, (), "cluster")


SHAPES = np.eye(4)[:, :3]  # three orthogonal shapes


def test_weighted_estimate_and_uncertainty_follow_the_formula():
    ssi = _selection([2.0, 5.0], [0.01, 0.02], [0.002, 0.01], [0.001, 0.004], SHAPES[:, :2])
    lscf = _selection([2.004, 5.01], [0.012, 0.02], [0.001, 0.01], [0.002, 0.004], SHAPES[:, :2])
    table = combine_modes({"ssi": ssi, "lscf": lscf}, estimate="weighted")
    assert list(table["n_methods"]) == [2, 2]
    # mode 1: weights 1/0.002² and 1/0.001² (1 : 4)
    w = np.array([1 / 0.002**2, 1 / 0.001**2])
    f = np.array([2.0, 2.004])
    mean = np.sum(w * f) / w.sum()
    assert table["frequency_hz"].iat[0] == pytest.approx(mean, rel=1e-12)
    assert mean == pytest.approx(2.0032, rel=1e-12)
    spread = np.sum(w * (f - mean) ** 2) / w.sum()
    assert table["frequency_std_hz"].iat[0] == pytest.approx(math.sqrt(1 / w.sum() + spread))
    # mode 2: equal scatter, mean in the middle; disagreement 0.01 adds (0.005)² to 0.01²/2
    assert table["frequency_hz"].iat[1] == pytest.approx(5.005)
    assert table["frequency_std_hz"].iat[1] == pytest.approx(math.sqrt(0.01**2 / 2 + 0.005**2))


def test_reference_estimate_keeps_the_first_method_and_adds_what_it_missed():
    ssi = _selection([2.0], [0.01], [0.002], [0.001], SHAPES[:, :1])
    lscf = _selection([2.004, 3.0], [0.012, 0.015], [0.001, 0.003], [0.002, 0.001], SHAPES[:, :2])
    table = combine_modes({"ssi": ssi, "lscf": lscf})
    assert list(table["frequency_hz"]) == [2.0, 3.0]
    assert list(table["methods"]) == ["ssi+lscf", "lscf"]
    assert list(table["ssi_mode"]) == [0, -1]
    assert list(table["lscf_mode"]) == [0, 1]
    assert table["damping_ratio"].iat[0] == 0.01
    # the uncertainty is the combined one, larger than the better method's scatter alone
    # because the two disagree by 2 sigma of the better one
    assert table["frequency_std_hz"].iat[0] > 0.001
    # a mode of one method keeps its scatter
    assert table["frequency_std_hz"].iat[1] == pytest.approx(0.003)
    assert math.isnan(table["ssi_frequency_hz"].iat[1])


def test_pairs_need_close_frequencies_and_alike_shapes():
    ssi = _selection([2.0, 4.0], [0.01, 0.01], [0.001, 0.001], [0.001, 0.001], SHAPES[:, :2])
    # 2.03 Hz is 1.5 % away (beyond frequency_tol 1 %); 4.001 Hz has an orthogonal shape
    lscf = _selection([2.03, 4.001], [0.01, 0.01], [0.001, 0.001], [0.001, 0.001], SHAPES[:, 1:3])
    table = combine_modes({"ssi": ssi, "lscf": lscf})
    assert len(table) == 4
    assert (table["n_methods"] == 1).all()


def test_a_cluster_without_scatter_gets_the_floor():
    ssi = _selection([2.0], [0.01], [0.0], [0.0], SHAPES[:, :1])
    table = combine_modes({"ssi": ssi})
    assert table["frequency_std_hz"].iat[0] == pytest.approx(RELATIVE_FLOOR * 2.0)
    assert table["damping_std"].iat[0] == pytest.approx(RELATIVE_FLOOR * 0.01)


def test_bad_options_are_refused():
    ssi = _selection([2.0], [0.01], [0.0], [0.0], SHAPES[:, :1])
    with pytest.raises(ValueError, match="estimate") as error:
        combine_modes({"ssi": ssi}, estimate="median")
    assert "'reference' or 'weighted'" in str(error.value)
    with pytest.raises(ValueError, match="selections"):
        combine_modes({})
    with pytest.raises(ValueError, match="frequency_tol"):
        combine_modes({"ssi": ssi}, frequency_tol=0.0)


def test_a_later_methods_second_look_mode_alone_is_left_out():
    ssi = _selection([2.0], [0.01], [0.002], [0.001], SHAPES[:, :1])
    modes = pd.DataFrame(
        {
            "frequency_hz": [2.001, 3.0, 4.0],
            "damping_ratio": [0.01, 0.01, 0.01],
            "frequency_std_hz": [0.001, 0.001, 0.001],
            "damping_std": [0.001, 0.001, 0.001],
            "pole_index": [10, 20, 30],
        }
    )
    shapes = np.eye(4)[:, [0, 1, 2]].astype(complex)
    # the modes at 2.001 and 3.0 Hz are second-look modes of LSCF: the first pairs with
    # SSI's and counts, the second stands alone and is left out; 4.0 Hz is a stage-3 mode
    lscf = ModeSelection(modes, shapes, None, (), "cluster", {"second_look_poles": (10, 20)})
    table = combine_modes({"ssi": ssi, "lscf": lscf})
    assert list(table["frequency_hz"]) == [2.0, 4.0]
    assert list(table["n_methods"]) == [2, 1]
    # the first method's second-look modes stand alone
    alone = combine_modes({"lscf": lscf})
    assert list(alone["frequency_hz"]) == [2.001, 3.0, 4.0]


def test_the_first_methods_second_look_mode_needs_the_other_method():
    """SSI's second look found a column at 6.09 Hz, 3 % above the 5.9-Hz mode, that LSCF
    does not have (bench_close_weak "close 3% MAC 0.5" seed 64, a spurious mode): without
    LSCF's support it is not taken; with it (a pair within 1 %, MAC >= 0.8) it is."""
    modes = pd.DataFrame(
        {
            "frequency_hz": [2.0, 3.0],
            "damping_ratio": [0.01, 0.014],
            "frequency_std_hz": [0.001, 0.003],
            "damping_std": [0.001, 0.004],
            "pole_index": [10, 20],
        }
    )
    shapes = SHAPES[:, :2].astype(complex)
    ssi = ModeSelection(modes, shapes, None, (), "cluster", {"second_look_poles": (20,)})
    lscf = _selection([2.001], [0.01], [0.001], [0.001], SHAPES[:, :1])
    table = combine_modes({"ssi": ssi, "lscf": lscf})
    assert list(table["frequency_hz"]) == [2.0]
    confirming = _selection(
        [2.001, 3.01], [0.01, 0.012], [0.001, 0.002], [0.001, 0.001], SHAPES[:, :2]
    )
    table = combine_modes({"ssi": ssi, "lscf": confirming})
    assert list(table["frequency_hz"]) == [2.0, 3.0]
    assert list(table["methods"]) == ["ssi+lscf", "ssi+lscf"]
    # one method alone: its selection stands
    assert list(combine_modes({"ssi": ssi})["frequency_hz"]) == [2.0, 3.0]
