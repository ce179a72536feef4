"""Universal file format (UFF/UNV) dataset 58: one time response per channel, read with
``pyuff`` (the field's reader for UFF, https://github.com/ladisk/pyuff)."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from .._core import ContractError, Violation
from . import AccelerationLayout, convert_units, describe, layout_start, warn_if_gravity_in_g

__all__ = ["UFF_SUFFIXES", "read_uff_accelerations"]

UFF_SUFFIXES = (".uff", ".unv")

_DIRECTIONS = {
    0: "",
    1: "+X",
    2: "+Y",
    3: "+Z",
    -1: "-X",
    -2: "-Y",
    -3: "-Z",
    4: "+RX",
    5: "+RY",
    6: "+RZ",
}
_DATE = re.compile(
    r"\d{4}-\d\d-\d\d[T ]\d\d:\d\d:\d\d(?:\.\d+)?(?:Z|[+-]\d\d:?\d\d)?"
    r"|\d\d?-[A-Za-z]{3}-\d{2,4}\s+\d\d:\d\d:\d\d(?:\.\d+)?"
)


#: Fewest samples of a time response: fewer is a header, a test record or a cut file. [-]
MIN_RECORD_SAMPLES = 16

#: A record delimiter: ``    -1`` alone on its line (blanks may pad it to 80 columns).
_DELIMITER = re.compile(rb"^    -1 *(?:\r?\n|\r|\Z)", re.MULTILINE)


def _check_complete(path: Path, fail) -> None:
    """Refuse a file that ends inside a record (a copy cut short reads as fewer channels).

    Records open and close with a delimiter line, so a whole file has an even number of
    them and nothing but blanks after the last.
    """
    data = path.read_bytes()
    tags = list(_DELIMITER.finditer(data))
    tail = data[tags[-1].end() :] if tags else data
    if len(tags) % 2 or tail.strip():
        raise fail(
            f"the file ends inside a record, after {len(tags) // 2} complete record(s): cut short?"
        )


def _record_name(record: dict, index: int) -> str:
    node = record.get("rsp_node", "?")
    direction = _DIRECTIONS.get(int(record.get("rsp_dir", 0)), str(record.get("rsp_dir", "")))
    return f"record {index + 1} (node {node}{direction})"


def _check_records(responses: list[dict], fail) -> None:
    """Each time response: evenly spaced with a positive abscissa increment, its declared
    number of points equal to the values it holds, at least :data:`MIN_RECORD_SAMPLES`."""
    for index, record in enumerate(responses):
        name = _record_name(record, index)
        if int(record.get("abscissa_spacing", 1)) != 1:
            raise fail(
                f"{name}: uneven abscissa (spacing 0); a time response must be evenly spaced"
            )
        step = float(record.get("abscissa_inc", float("nan")))
        if not (np.isfinite(step) and step > 0):
            raise fail(f"{name}: abscissa increment {step:g} s is not a positive time step")
        declared = int(record.get("num_pts", -1))
        held = len(record["data"])
        if declared != held:
            raise fail(f"{name} declares {declared} points but holds {held}: cut or damaged")
        if held < MIN_RECORD_SAMPLES:
            raise fail(
                f"{name} holds {held} samples; a time response needs at least {MIN_RECORD_SAMPLES}"
            )


def read_uff_accelerations(path: str | os.PathLike, layout: AccelerationLayout):
    """Read the time responses (dataset 58, function type 1) of a UFF file.

    Channels are named by response node and direction (``101+Z``). The start time is the
    layout's, else the first date in the records' ID lines (``2026-11-23 10:00:00`` or
    ``23-Nov-26 10:00:00``), plus the abscissa minimum.
    """
    from ..accelerations import AccelerationRecord

    path = Path(path)

    def fail(reason: str) -> ContractError:
        return ContractError([Violation(None, reason)], source=path, contract="accelerations")

    try:
        import pyuff
    except ImportError:
        raise fail("reading UFF files needs pyuff: pip install 'workbench[formats]'") from None
    _check_complete(path, fail)
    uff = pyuff.UFF(str(path))
    types = [int(t) for t in uff.get_set_types()]
    sets = uff.read_sets()
    sets = [sets] if isinstance(sets, dict) else list(sets)
    responses = [s for s in sets if int(s.get("type", 0)) == 58 and int(s.get("func_type", 0)) == 1]
    if not responses:
        kinds = [
            f"58 (function type {int(s.get('func_type', 0))})"
            if int(s.get("type", 0)) == 58
            else str(t)
            for s, t in zip(sets, types, strict=False)
        ]
        raise fail(
            "no time responses (dataset 58 with function type 1); "
            + describe(sorted(set(kinds)), "datasets")
        )
    _check_records(responses, fail)
    steps = {float(s["abscissa_inc"]) for s in responses}
    lengths = {len(s["data"]) for s in responses}
    if len(lengths) > 1 or max(steps) - min(steps) > 1e-9 * max(steps):
        raise fail(
            f"time responses differ in length {sorted(lengths)} or step {sorted(steps)}; "
            "a file must hold one record of all channels"
        )
    step = steps.pop()
    channels = []
    for s in responses:
        node = int(s.get("rsp_node", 0))
        direction = _DIRECTIONS.get(int(s.get("rsp_dir", 0)), str(s.get("rsp_dir", "")))
        channels.append(f"{node}{direction}")
    if len(set(channels)) != len(channels):
        channels = [
            str(s.get("id1", "")).strip() or c for s, c in zip(responses, channels, strict=True)
        ]
    columns = [np.asarray(s["data"]) for s in responses]
    complex_nodes = [
        str(s.get("rsp_node"))
        for s, c in zip(responses, columns, strict=True)
        if np.iscomplexobj(c)
    ]
    if complex_nodes:
        raise fail(
            f"records of node(s) {', '.join(complex_nodes)} hold complex values, not time responses"
        )
    acceleration = np.column_stack(columns).astype(float)
    start = layout_start(layout, path)
    if start is None:
        ids = [str(s.get(f"id{k}", "")) for s in responses[:1] for k in range(1, 6)]
        match = next((m.group(0) for text in ids if (m := _DATE.search(text))), None)
        if match is None:
            raise fail(
                "no date in the ID lines of the records ("
                + " | ".join(i.strip() for i in ids if i.strip())
                + "); give the start time"
            )
        start = pd.Timestamp(match)
    start = start.tz_localize("UTC") if start.tzinfo is None else start.tz_convert("UTC")
    start = start + pd.Timedelta(seconds=float(responses[0].get("abscissa_min", 0.0)))
    header_units = []
    for s in responses:
        label = str(s.get("ordinate_axis_units_lab", "")).strip()
        header_units.append(None if label.upper() in ("", "NONE") else label)
    if layout.channels is not None:
        missing = [c for c in layout.channels if c not in channels]
        if missing:
            raise fail(f"channel(s) {', '.join(missing)} not among {', '.join(channels)}")
        keep = [channels.index(c) for c in layout.channels]
        acceleration = acceleration[:, keep]
        header_units = [header_units[j] for j in keep]
        channels = list(layout.channels)
    acceleration = convert_units(acceleration, channels, header_units, layout, path)
    stated = layout.units is not None or any(u is not None for u in header_units)
    warn_if_gravity_in_g(acceleration, channels, stated, path)
    return AccelerationRecord(acceleration, 1.0 / step, start, tuple(channels))
