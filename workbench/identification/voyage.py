"""The voyage runner: every block of a voyage identified, in parallel and resumable, into
a :class:`~workbench.store.BlockStore`, then exported."""

from __future__ import annotations

import dataclasses
import functools
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import pandas as pd

from data_contracts import POLES, read_table

from ..errors import OptionError, UnreadableInputError, WorkbenchError
from ..parallel import RunSummary, UnreadableBlock, run_blocks
from ..results import StageResult, write_frame
from ..sid.harmonics import HarmonicOptions
from ..store import BlockStore, block_ranges
from .engine import _block_tasks, _file_tasks, identify_block, identify_from_files
from .export import export_store
from .options import IdentifyOptions
from .planning import (
    acceleration_files,
    follow_on_starts,
    input_fingerprints,
    left_out_notes,
    plan_identification,
    resolved_run,
)


@dataclass
class IdentifyResult(StageResult):
    """What an identification run did and wrote: the result of :func:`identify_voyage` and of
    the identify stage (:func:`workbench.stages.identify`).

    ``table`` holds the modes selected per block (the input of :meth:`track`), ``poles`` the
    poles of every model order and block.

    Attributes
    ----------
    run : RunSummary
        Blocks processed, already in the store, skipped (and why).
    files : dict of str to Path
        The tables written (``selected``, ``poles``, ``blocks``, ``faults``...).
    n_blocks : int
        Blocks of the run.
    n_selected : int
        Rows of the selected-modes table.
    warnings : list of str
        What the run found changed in its store and did about it (damaged store files,
        input files no longer given), one line each.
    notes : list of str
        The input files left out (another sampling rate, a duplicate:
        :func:`~workbench.identification.planning.left_out_notes`), those re-timed for
        clock jitter (how many, the largest shift:
        :func:`~workbench.signals.block_plan.clock_jitter_note`), the records whose sample
        clock drifts from their stamps (the rate offset in ppm:
        :func:`~workbench.signals.block_plan.clock_drift_note`) and what the harmonic tests
        marked (:meth:`workbench.sid.harmonics.HarmonicMarker.lines`).
    """

    run: RunSummary
    files: dict[str, Path] = field(default_factory=dict)
    n_blocks: int = 0
    n_selected: int = 0
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    title = "identified modes"

    @property
    def lines(self) -> list[str]:  # type: ignore[override]
        """The run summary, the notes (files left out, clock jitter and drift, harmonics),
        the SSI/LSCF agreement and the files."""
        out = [*str(self.run).splitlines(), *self.notes]
        crosscheck = self.files.get("crosscheck")
        if crosscheck is not None:
            from ..sid.crosscheck import agreement_lines

            out += agreement_lines(pd.read_csv(crosscheck))
        out += [f"{kind}: {path}" for kind, path in self.files.items()]
        return out

    @cached_property
    def table(self) -> pd.DataFrame:  # type: ignore[override]
        """Selected modes, one row per block and mode (the input of :meth:`track`)."""
        path = self.files.get("selected")
        if path is None:
            return pd.DataFrame(columns=["block", "block_start", "block_end", "frequency_hz"])
        frame = pd.read_parquet(path)
        for column in ("block_start", "block_end"):
            if column in frame.columns:
                frame[column] = pd.to_datetime(frame[column], utc=True)
        return frame

    @cached_property
    def poles(self) -> pd.DataFrame:
        """Poles of every model order and block (POLES contract)."""
        path = self.files.get("poles")
        if path is None:
            raise ValueError("the run wrote no pole table (no block was identified)")
        return read_table(path, POLES)

    def track(self, *, reference_modes=None, options=None, progress: bool = False):
        """:func:`~workbench.stages.track` of the selected modes; the tracked result keeps
        this run's poles for the forecast's pole-cluster option (B)."""
        from ..stages.tracking import track

        result = track(
            self.table, reference_modes=reference_modes, options=options, progress=progress
        )
        result.poles = self.poles if "poles" in self.files else None
        return result

    def save(self, out_dir: str | os.PathLike) -> dict[str, Path]:
        """selected.parquet and poles.parquet in *out_dir*."""
        out = Path(out_dir)
        return {
            "selected": write_frame(self.table, out / "selected.parquet"),
            "poles": write_frame(self.poles, out / "poles.parquet", POLES),
        }


def _check_run_options(scheduler, n_workers, batch_blocks) -> None:
    if int(batch_blocks) != batch_blocks or batch_blocks < 1:
        raise OptionError(f"batch_blocks={batch_blocks} must be a whole number of at least 1")
    if n_workers is not None and (int(n_workers) != n_workers or n_workers < 1):
        raise OptionError(f"n_workers={n_workers} must be a whole number of at least 1")
    if scheduler is None or scheduler == "synchronous":
        return
    from urllib.parse import urlsplit

    text = str(scheduler)
    parsed = urlsplit(text if "://" in text else f"tcp://{text}")
    try:
        port = parsed.port
    except ValueError:
        port = None
    if parsed.scheme not in ("tcp", "tls", "inproc", "ucx", "ws", "wss") or not (
        parsed.hostname and port
    ):
        raise OptionError(
            f"scheduler={text!r} must be 'synchronous' or a dask.distributed scheduler "
            "address such as tcp://host:8786"
        )


def _removed_inputs(
    store: BlockStore,
    fingerprints: list[dict],
    grid,
    *,
    per_file: bool,
    keep: bool,
    unreadable: Iterable[str] = (),
    damaged: Iterable[str] = (),
) -> list[str]:
    """Report the recorded input files no longer given and drop (or, with *keep*, keep)
    the stored blocks that depended on them; the notices, one line per file.

    The content a file read whole before had is not *removed* while the file is still
    given but damaged (*damaged*, resolved paths; :func:`_damaged_since_read`): the
    blocks computed from it stay. A damaged content recorded and no longer given (the
    file repaired, replaced or gone) fed no block: it is forgotten without a notice.

    A block depends on the files its span overlaps; when files are conditioned once each
    (*per_file*), also on each file's neighbours (their edges pad the conditioning), so
    the blocks of the files next to a removed one are dropped too. Dropped blocks and the
    forgotten file make the store what a fresh run over the remaining files would make.
    A file still given but left out as unreadable (*unreadable*, paths as given) is
    treated alike without a notice: its warning names it.
    """
    quiet = {str(Path(name).resolve()) for name in unreadable}
    damaged = set(damaged)
    removed = store.removed_inputs(fingerprints)
    gone = [r for r in removed if r.get("damaged") and r["path"] not in damaged]
    if gone:
        store.forget_inputs(gone)
    removed = [r for r in removed if not r.get("damaged") and r["path"] not in damaged]
    if not removed:
        return []
    recorded = sorted(
        (r for r in store.recorded_inputs() if not r.get("damaged")),
        key=lambda r: pd.Timestamp(r["start"]),
    )
    order = {r["sha256"]: k for k, r in enumerate(recorded)}
    stored = sorted(store.completed_blocks())
    notices = []
    for entry in sorted(removed, key=lambda r: pd.Timestamp(r["start"])):
        k = order[entry["sha256"]]
        low = recorded[max(k - 1, 0) if per_file else k]["start"]
        high = recorded[min(k + 1, len(recorded) - 1) if per_file else k]["end"]
        low, high = pd.Timestamp(low), pd.Timestamp(high)
        blocks = [b for b in stored if grid.start(b) < high and grid.end(b) > low]
        what = f"{entry['path']}: input no longer given (recorded in the store {store.root})"
        if keep:
            if entry["path"] in quiet:
                continue
            notices.append(
                f"{what}: block(s) {block_ranges(blocks) or 'none'} computed from it are kept "
                "(--keep-removed-inputs)"
            )
            continue
        dropped = store.drop_blocks(blocks)
        store.forget_inputs([entry])
        stored = [b for b in stored if b not in dropped]
        if entry["path"] in quiet:
            continue
        notices.append(
            f"{what}: block(s) {block_ranges(dropped) or 'none'} computed from it are dropped "
            "(--keep-removed-inputs keeps them)"
        )
    return notices


def _moved_inputs(store: BlockStore, moved: list[dict], grid, *, per_file: bool) -> list[str]:
    """Drop the stored blocks computed from input files that the files given now place
    elsewhere (*moved*, from :meth:`~workbench.store.BlockStore.check_inputs`: a file
    filling a gap in a drifting record places the files after it on the record's sample
    count, up to the clock's walk from where an earlier run placed them), so they are
    computed again as a fresh run computes them; one notice for them."""
    stored = store.completed_blocks()
    if not moved or not stored:
        return []
    blocks: set[int] = set()
    for entry in moved:
        low, high = pd.Timestamp(entry["start"]), pd.Timestamp(entry["end"])
        if per_file:  # a file's filters are padded with its neighbours' raw edges
            low, high = low - (high - low), high + (high - low)
        blocks |= {b for b in stored if grid.start(b) < high and grid.end(b) > low}
    dropped = store.drop_blocks(sorted(blocks))
    if not dropped:
        return []
    shifts = [
        (pd.Timestamp(e["now_start"]) - pd.Timestamp(e["start"])).total_seconds() * 1e3
        for e in moved
    ]
    largest = max(shifts, key=abs)
    return [
        f"{len(moved)} input file(s) placed elsewhere than when the store's blocks were "
        f"computed (up to {largest:+.1f} ms, the files given now placing the record again): "
        f"block(s) {block_ranges(dropped)} computed again"
    ]


def _plan_cuts(plan, digests: Mapping) -> dict[int, tuple[str, int]]:
    """Where *plan* cuts its drifting blocks, for the store (:func:`~workbench.signals.
    block_plan.cut_in_file`): block -> (the file's SHA-256, from *digests* by path; the
    sample's index)."""
    import numpy as np

    from ..signals.block_plan import cut_in_file

    drifting = [p for p in plan.blocks if p.drifting]
    if not drifting:
        return {}
    starts = np.array([info.start_time.value for info in plan.files], dtype=np.int64)
    out = {}
    for planned in drifting:
        position, index = cut_in_file(plan.files, starts, planned.sample_start.value)
        out[int(planned.block)] = (digests[plan.files[position].path], index)
    return out


def _moved_cuts(store: BlockStore, plan, digests: Mapping) -> list[str]:
    """Drop the stored blocks that *plan* cuts elsewhere than where they were computed
    from (:meth:`~workbench.store.BlockStore.block_cuts`; a block without a stored cut
    was cut at its label): a drifting record's blocks are cut where its clock line puts
    their labels, and the line refitted over the files given now (more of them, a gap
    filled) may move a cut by a sample or more, so they are computed again as a fresh run
    computes them; one notice for them. *digests*: the SHA-256 of *plan*'s files, by
    path."""
    from ..signals.block_plan import cut_placed_ns

    stored = store.completed_blocks()
    if not stored:
        return []
    cuts = store.block_cuts()
    infos = {digests[info.path]: info for info in plan.files}
    half_ns = 0.5e9 / plan.sampling_rate_hz
    moved = {}
    for planned in plan.blocks:
        block = int(planned.block)
        if block not in stored:
            continue
        was = planned.block_start.value  # cut at its label
        if block in cuts:
            digest, index = cuts[block]
            if digest not in infos:  # the file is no longer given: _removed_inputs
                continue
            was = cut_placed_ns(infos[digest], index)
        if abs(planned.sample_start.value - was) > half_ns:
            moved[block] = (planned.sample_start.value - was) / 1e6
    if not moved:
        return []
    dropped = store.drop_blocks(sorted(moved))
    if not dropped:
        return []
    largest = max(moved.values(), key=abs)
    return [
        f"block(s) {block_ranges(dropped)} cut elsewhere than when stored (by up to "
        f"{largest:+.1f} ms: the clock line of the drifting record, refitted over the files "
        "given now, puts their labels elsewhere on its samples): computed again"
    ]


def unreadable_places(files, plan, unreadable: Mapping[str, str]) -> dict[str, tuple]:
    """Where each file of *unreadable* (path as given -> why) left out of *plan* lies:
    path -> ``(low, high)``, the end of the readable file before it and the start of the
    one after it (UTC).

    Such a file's span is not known (its header may be what fails): it is taken to lie in
    its place among *files* (in the order found, by name within a folder), between the
    readable files before and after it, when those leave a gap where it belongs and no
    readable file lies in that gap. A file at either end of the data, or whose place is
    not known that way, is not listed.
    """
    infos = {str(info.path): info for info in plan.files}
    half = pd.Timedelta(seconds=0.5 / plan.sampling_rate_hz)
    order = [str(f) for f in files]
    places = {}
    for k, name in enumerate(order):
        if name not in unreadable:
            continue
        before = next((infos[n] for n in reversed(order[:k]) if n in infos), None)
        after = next((infos[n] for n in order[k + 1 :] if n in infos), None)
        if before is None or after is None or after.start_time - before.end_time <= half:
            continue
        if any(before.end_time <= i.start_time < after.start_time for i in plan.files):
            continue  # a readable file lies in the gap: the file's place is not known
        places[name] = (before.end_time, after.start_time)
    return places


def _unreadable_blocks(files, plan, unreadable: Mapping[str, str]) -> dict[int, UnreadableBlock]:
    """The planned blocks that need a file of *unreadable* left out of *plan* (the blocks
    the plan skips over its place, :func:`unreadable_places`), as tasks recorded skipped
    with that file as the reason."""
    half = pd.Timedelta(seconds=0.5 / plan.sampling_rate_hz)
    out: dict[int, UnreadableBlock] = {}
    for name, (low, high) in unreadable_places(files, plan, unreadable).items():
        reason = f"{name}: unreadable ({unreadable[name]})"
        path = str(Path(name).resolve())
        for planned in plan.blocks:
            if not planned.skipped_reason or planned.block_end - half <= low:
                continue
            if planned.block_start + half >= high:
                continue
            task = out.get(planned.block)
            out[planned.block] = (
                UnreadableBlock(planned.block, planned.block_start, reason, (path,))
                if task is None
                else dataclasses.replace(task, paths=(*task.paths, path))
            )
    return out


def _retry_unreadable(
    store: BlockStore,
    plan,
    fingerprints: list[dict],
    per_file: bool,
    unreadable: Iterable[str],
    damaged: Iterable[str] = (),
):
    """Take out of the store the blocks of input files an earlier run could not read and
    that have changed since (repaired, replaced or gone), so they are computed again, and
    record the files this run leaves out (*unreadable*, paths as given); the notices, one
    line per file readable again.

    The files of earlier runs are those the store's skipped blocks name and those it
    listed as left out (:meth:`~workbench.store.BlockStore.unreadable_files`). A file
    readable now takes with it the blocks its samples feed (with *per_file* conditioning
    also those of its neighbours, whose filters its edges pad, left unpadded before), and
    its recorded fingerprint (of the damaged content) is forgotten, so the repaired file
    is not refused as a changed input. A file unchanged since (its content recorded)
    keeps its blocks skipped.

    A file read whole before and damaged since (its damaged content recorded,
    :meth:`~workbench.store.BlockStore.record_damaged`) is still damaged while it is in
    *damaged* (resolved paths, :func:`_damaged_since_read`); with any other content now
    (repaired or replaced) its blocks and those near it are computed again, every
    fingerprint of it forgotten.
    """
    damaged = set(damaged)
    flagged = {r["path"] for r in store.recorded_inputs() if r.get("damaged")}
    recorded = {
        **{path: {"blocks": set(), "reason": ""} for path in flagged},
        **{path: {"blocks": set(), "reason": ""} for path in store.unreadable_files()},
        **store.unreadable_inputs(),
    }
    store.set_unreadable_files(str(Path(name).resolve()) for name in unreadable)
    if not recorded:
        return []
    inputs = store.recorded_inputs()
    known = {r["sha256"] for r in inputs}
    given = {f["path"]: f for f in fingerprints}
    position = {str(Path(info.path).resolve()): k for k, info in enumerate(plan.files)}
    shown = {str(Path(info.path).resolve()): info.path for info in plan.files}
    stored = store.completed_blocks()
    drop: set[int] = set()
    forget: list[dict] = []
    notices = []
    for path, entry in sorted(recorded.items()):
        now = given.get(path)
        if path in damaged:
            continue  # damaged after a read, still: its blocks stay (kept or skipped)
        if path not in flagged and now is not None and now["sha256"] in known:
            continue  # the same content: still unreadable, its blocks stay skipped
        blocks = set(entry["blocks"])
        if now is not None:
            forget += [r for r in inputs if r["path"] == path]
            k, files = position[path], plan.files
            low = files[max(k - 1, 0) if per_file else k].start_time
            high = files[min(k + 1, len(files) - 1) if per_file else k].end_time
            blocks |= {b for b in stored if plan.grid.start(b) < high and plan.grid.end(b) > low}
            again = block_ranges(blocks & stored)
            notices.append(
                f"{shown[path]}: unreadable in an earlier run and changed since: read now"
                + (f", block(s) {again} stored near it computed again" if again else "")
            )
        drop |= blocks
    if forget:
        store.forget_inputs(forget)
    if drop:
        store.drop_blocks(drop)
    return notices


#: How a block skipped for data missing from the files begins its reason (that of
#: :func:`~workbench.signals.block_plan.plan_file_infos`, or - stores of earlier versions -
#: of the block builder for a block without a file).
_MISSING_DATA = ("gap of ", "no data (gap ", "no acceleration files")


def _filled_gaps(store: BlockStore, plan) -> list[str]:
    """Take out of the store the blocks an earlier run skipped for data missing (a gap, no
    data) that the files given now hold (a file that landed late, or was copied since), so
    they are identified as a fresh run identifies them; one notice line naming them."""
    from ..store import BLOCKS_KIND

    table = store.read(BLOCKS_KIND)
    if table.empty:
        return []
    missing = (table["status"] != "ok") & table["reason"].astype(str).str.startswith(_MISSING_DATA)
    built = {int(b.block) for b in plan.blocks if not b.skipped_reason}
    again = set(table.loc[missing, "block"].astype(int)) & built
    if not again:
        return []
    store.drop_blocks(again)
    return [
        f"block(s) {block_ranges(again)} skipped by an earlier run for data missing: the files "
        "given now hold it, identified"
    ]


def _damaged_since_read(
    store: BlockStore, plan, fingerprints: list[dict], unreadable: Mapping[str, str], read_options
) -> dict[str, dict]:
    """The input files an earlier run read whole whose content cannot be read now (a bad
    checksum, cut short: damaged on disk since).

    A file whose content is new, at a path whose content the store recorded, is read
    whole: when that fails, the file is damaged, not changed (a file that reads is a
    changed input, refused by :meth:`~workbench.store.BlockStore.check_inputs`). A file
    whose damaged content is recorded already, or whose header cannot be read now (in
    *unreadable*, paths as given -> why), is damaged too. The blocks computed from the
    content read before are of good data: they are kept, and the content recorded
    (:meth:`~workbench.store.BlockStore.record_damaged`).

    Returns
    -------
    dict
        Resolved path -> ``name`` (as given), ``why`` (the reader's complaint), ``entry``
        (the damaged content's fingerprint, with ``why``) and ``good`` (the recorded
        fingerprint of the content read before).
    """
    from ..fingerprints import sha256

    recorded = store.recorded_inputs()
    flagged = {r["sha256"]: r for r in recorded if r.get("damaged")}
    # a file unreadable from the first run on was never read whole: not one of these
    never_read = set(store.unreadable_inputs()) | set(store.unreadable_files())
    never_read -= {r["path"] for r in flagged.values()}
    good: dict[str, dict] = {}
    for r in recorded:
        if not r.get("damaged") and r["path"] not in never_read:
            good[r["path"]] = r
    if not good:
        return {}
    known = {r["sha256"] for r in recorded}
    shown = {str(Path(info.path).resolve()): str(info.path) for info in plan.files}
    found: dict[str, dict] = {}
    for item in fingerprints:
        path = item["path"]
        if path not in good:
            continue
        before = flagged.get(item["sha256"])
        if before is not None:  # the damaged content an earlier run found
            found[path] = {"name": shown[path], "why": str(before.get("why", "")), "entry": before}
        elif item["sha256"] not in known:
            why = _unreadable_now(shown[path], read_options)
            if why is not None:
                found[path] = {"name": shown[path], "why": why, "entry": {**item, "why": why}}
    for name, why in unreadable.items():  # the header unreadable now
        path = str(Path(name).resolve())
        if path not in good or path in found:
            continue
        try:
            stat, digest = Path(name).stat(), sha256(Path(name))
        except OSError:
            continue  # gone since it was listed: a removed input
        entry = {
            "path": path,
            "start": good[path]["start"],
            "end": good[path]["end"],
            "size": int(stat.st_size),
            "mtime_ns": int(stat.st_mtime_ns),
            "sha256": digest,
            "why": why,
        }
        found[path] = {"name": name, "why": why, "entry": entry}
    for path, item in found.items():
        item["good"] = good[path]
    return found


def _unreadable_now(name: str, read_options) -> str | None:
    """Why the acceleration file *name* cannot be read whole now (None: it can)."""
    from data_contracts import read_accelerations

    try:
        read_accelerations(name, **dict(read_options))
    except (OSError, ValueError, KeyError, EOFError) as error:
        if isinstance(error, OptionError):
            raise
        return UnreadableInputError.of(name, error).detail
    return None


def _damaged_warnings(store: BlockStore, damaged: Mapping[str, dict], grid) -> list[str]:
    """One line per file damaged since an earlier run read it: the blocks computed from
    that read, kept, and those that need it and are not identified."""
    if not damaged:
        return []
    table = store.read("blocks")
    ok = [] if table.empty else table.loc[table["status"] == "ok", "block"].astype(int).tolist()
    skipped = store.unreadable_inputs()
    lines = []
    for path, item in sorted(damaged.items(), key=lambda kv: kv[1]["name"]):
        low, high = pd.Timestamp(item["good"]["start"]), pd.Timestamp(item["good"]["end"])
        kept = sorted(b for b in ok if grid.start(b) < high and grid.end(b) > low)
        line = f"{item['name']}: unreadable ({item['why']}), damaged since an earlier run read it"
        line += (
            f"; block(s) {block_ranges(kept)} computed from that read are kept"
            if kept
            else "; no block computed from that read is stored"
        )
        missed = skipped.get(path, {}).get("blocks", set())
        if missed:
            line += f"; block(s) {block_ranges(missed)} that need it not identified"
        lines.append(line)
    return lines


def _plan_without(plan, paths: set[str]):
    """*plan* (same grid and channels) without the files of *paths* (resolved)."""
    from ..signals.block_plan import plan_file_infos

    rest = [info for info in plan.files if str(Path(info.path).resolve()) not in paths]
    return plan_file_infos(
        rest, plan.grid, max_gap_s=plan.max_gap_s, channels=plan.channels, lattice=plan.lattice
    )


def _detail(entry: dict, name: str) -> str:
    """Why a file stored blocks name is unreadable: their reason without ``"<name>:
    unreadable (...)"`` around it."""
    return entry["reason"].removeprefix(f"{name}: unreadable (").removesuffix(")")


def _without_unread_edges(store: BlockStore, plan, known, unreadable: dict, run, summary):
    """With files conditioned once each, the blocks next to a file whose samples this run
    found unreadable again, without it; the run's summary over both passes.

    A file's conditioning is padded with its neighbours' edges, read in place without the
    checksum of the whole file (that would read every neighbour twice), so a file whose
    checksum fails lent its edges to the blocks beside it before its own blocks found it
    bad. Those blocks are taken out of the store and identified again from the plan
    without the file (added to *unreadable*), as a run without it identifies them.
    *known*: the files the store named as unreadable before this run.
    """
    index = {str(Path(info.path).resolve()): k for k, info in enumerate(plan.files)}
    found = {p: e for p, e in store.unreadable_inputs().items() if p not in known and p in index}
    if not found or len(found) == len(plan.files):
        return summary
    from collections import Counter

    files = plan.files
    stored = store.completed_blocks()
    again: set[int] = set()
    for path, entry in found.items():
        k = index[path]
        name = str(files[k].path)
        unreadable[name] = _detail(entry, name)
        low = files[max(k - 1, 0)].start_time
        high = files[min(k + 1, len(files) - 1)].end_time
        near = {b for b in stored if plan.grid.start(b) < high and plan.grid.end(b) > low}
        again |= near - set(entry["blocks"])
    table = store.read("blocks")
    redone = table[table["block"].astype(int).isin(again)]
    store.drop_blocks(again)
    second, _ = run(_plan_without(plan, set(found)))
    ok = int((redone["status"] == "ok").sum())
    reasons = Counter(summary.skip_reasons)
    reasons.subtract(Counter(redone.loc[redone["status"] != "ok", "reason"].astype(str)))
    reasons.update(second.skip_reasons)
    return RunSummary(
        processed=max(summary.processed - ok, 0) + second.processed,
        skipped=max(summary.skipped - (len(redone) - ok), 0) + second.skipped,
        already_done=summary.already_done,
        skip_reasons={reason: n for reason, n in reasons.items() if n > 0},
        notes=dict(Counter(summary.notes) + Counter(second.notes)),
        seconds=summary.seconds + second.seconds,
    )


def _unreadable_warnings(
    store: BlockStore, files, unreadable: dict[str, str], damaged: Iterable[str] = ()
) -> list[str]:
    """One line per input file that cannot be read, naming it and the blocks not
    identified for it (those found now and those an earlier run stored); not those of
    *damaged* (resolved paths: :func:`_damaged_warnings` names them)."""
    stored = store.unreadable_inputs()
    damaged = set(damaged)
    lines = []
    for name in dict.fromkeys(str(f) for f in files):
        if str(Path(name).resolve()) in damaged:
            continue
        entry = stored.get(str(Path(name).resolve()))
        if entry is None and name not in unreadable:
            continue
        reason = f"{name}: unreadable ({unreadable[name]})" if name in unreadable else None
        reason = reason or entry["reason"]
        blocks = entry["blocks"] if entry is not None else set()
        lines.append(
            f"{reason}; left out"
            + (f": block(s) {block_ranges(blocks)} not identified" if blocks else "")
        )
    return lines


def _ship_log(dship, mapping) -> pd.DataFrame | None:
    """The canonical ship log of *dship* (a path or a canonical log), or None."""
    if dship is None:
        return None
    if isinstance(dship, pd.DataFrame):
        return dship
    from data_contracts import read_dship

    return read_dship(dship, mapping=mapping)


def _missed_line(plan, blocks: Sequence[int] | None) -> str:
    """:func:`~workbench.signals.block_plan.missed_blocks_note` of *plan*, of the blocks
    asked for (*blocks*; all when None) only."""
    from ..signals.block_plan import missed_blocks, missed_blocks_line

    listed = {int(b.block) for b in plan.blocks}
    missed = missed_blocks(plan.files, plan.grid, plan.sampling_rate_hz, listed)
    if blocks is not None:
        wanted = {int(b) for b in blocks}
        missed = {b: how for b, how in missed.items() if b in wanted}
    return missed_blocks_line(missed)


def identify_voyage(
    inputs: Iterable[str | os.PathLike],
    out_dir: str | os.PathLike,
    *,
    options: IdentifyOptions | None = None,
    store_dir: str | os.PathLike | None = None,
    scheduler: str | None = None,
    n_workers: int | None = None,
    progress: bool = False,
    blocks: Sequence[int] | None = None,
    batch_blocks: int = 16,
    keep_removed_inputs: bool = False,
    dship: str | os.PathLike | pd.DataFrame | None = None,
    dship_mapping: dict[str, str] | None = None,
    harmonics: HarmonicOptions | None = None,
    grid_t0=None,
    unreadable: Mapping[str, str] | None = None,
    warn_unreadable: bool = True,
) -> IdentifyResult:
    """Identify every block of a voyage's acceleration files; resumable and parallel.

    An input file that cannot be read (cut short, a bad checksum) is left out: the blocks
    that need it are skipped with ``"<path>: unreadable (<why>)"`` as the reason
    (``blocks.csv``) and every other block is what a run without the file gives. Each such
    file is one line of :attr:`IdentifyResult.warnings`. The store keeps those blocks as
    skipped only while the file stays as it is: once it changes (repaired), its blocks
    are computed again.

    Parameters
    ----------
    inputs : iterable of path-like
        Acceleration files and/or folders holding them.
    out_dir : path-like
        Where the exported tables go.
    options : IdentifyOptions, optional
    store_dir : path-like, optional
        The per-block store (default ``out_dir / "store"``). Running again with the same
        store resumes; other options than the store's raise :class:`WorkbenchError`.
    scheduler : str, optional
        ``None``: *n_workers* local worker processes (default all cores; see
        :func:`~workbench.parallel.run_blocks`);
        ``"synchronous"``: this process; else a ``dask.distributed`` scheduler address.
    progress : bool
        Progress bar on stderr.
    blocks : sequence of int, optional
        Only these blocks.
    batch_blocks : int
        Blocks written to the store together (also every 30 s); an interruption loses at
        most the blocks of the batch under way.
    keep_removed_inputs : bool
        An input file recorded in the store and no longer given: keep the blocks computed
        from it (default: drop them, so the run equals a fresh run over the files given).
        Either way each such file is one line of :attr:`IdentifyResult.warnings`.
    dship : path-like or DataFrame, optional
        The voyage's ship log (raw DSHIP file or canonical log): its shaft speed (or, when
        not logged, its speed) marks the shaft and blade-pass harmonics among the selected
        modes and poles (``harmonic`` column; :mod:`workbench.sid.harmonics`) and gives
        ``shaft.csv``. Without it nothing is marked.
    dship_mapping : dict, optional
        Column names of the ship log (``{"shaft_rpm": "ME.Shaft.RPM"}``).
    harmonics : HarmonicOptions, optional
        Orders, blade count and tolerances of the harmonic tests.
    grid_t0 : time-like, optional
        Start of block 0 (default: the first sample; the shifted grids of
        :func:`~workbench.identification.adaptive.identify_adaptive`).
    unreadable : mapping, optional
        Input files (paths as given -> why) known to be unreadable: left out as those
        whose header cannot be read are (the adaptive run finds those whose samples fail).
    warn_unreadable : bool
        Name each unreadable input file in :attr:`IdentifyResult.warnings` (the adaptive
        run, which calls this once per block length, names them once itself).

    Raises
    ------
    WorkbenchError
        No input file can be read, or those that can give no block (naming the
        unreadable ones); inconsistent files; a store made with other options.
    """
    from ..sid.harmonics import HarmonicMarker
    from ..signals.block_plan import (
        clock_drift_note,
        clock_jitter_note,
        edge_cut_note,
    )

    options = options or IdentifyOptions()
    _check_run_options(scheduler, n_workers, batch_blocks)
    marker = HarmonicMarker(_ship_log(dship, dship_mapping), harmonics)
    out = Path(out_dir)
    store_path = Path(store_dir) if store_dir is not None else out / "store"
    for what, path in (("output folder", out), ("store", store_path)):
        if path.exists() and not path.is_dir():
            raise WorkbenchError(f"{path}: {what} is a file, not a folder")
    files = acceleration_files(inputs)
    options = follow_on_starts(files, options)
    # files whose header cannot be read (and those known unreadable): left out
    unreadable = {str(f): why for f, why in (unreadable or {}).items()}
    plan, options = plan_identification(
        [f for f in files if str(f) not in unreadable],
        options,
        grid_t0=grid_t0,
        unreadable=unreadable,
    )
    options.check_data(plan)
    grid = plan.grid
    channels = tuple(plan.channels)
    # the analysis rate; decimating blocks are cut from files conditioned once
    options, per_file, parameters = resolved_run(options, plan.sampling_rate_hz, grid, channels)
    with BlockStore.open(store_path, parameters) as store:
        notices = list(store.notices)
        fingerprints = input_fingerprints(plan.files)
        # a file read whole before and damaged on disk since: its blocks are kept, its
        # damaged content is no changed input
        damaged = _damaged_since_read(store, plan, fingerprints, unreadable, options.read_options)
        store.record_damaged(item["entry"] for item in damaged.values())
        # before the check: a repaired file is not another voyage's data
        notices += _retry_unreadable(store, plan, fingerprints, per_file, unreadable, damaged)
        moved = store.check_inputs(fingerprints, every_span=True)
        notices += _moved_inputs(store, moved, grid, per_file=per_file)
        digests = {
            info.path: str(f["sha256"]) for info, f in zip(plan.files, fingerprints, strict=True)
        }
        notices += _moved_cuts(store, plan, digests)
        notices += _filled_gaps(store, plan)
        notices += _removed_inputs(
            store,
            fingerprints,
            grid,
            per_file=per_file,
            keep=keep_removed_inputs,
            unreadable=unreadable,
            damaged=damaged,
        )
        wanted = None if blocks is None else {int(b) for b in blocks}

        def run(plan_now):
            tasks = _block_tasks(
                plan_now, [p for p in plan_now.blocks if wanted is None or int(p.block) in wanted]
            )
            if per_file:
                # each file conditioned once, on any worker, for the blocks holding it
                units = _file_tasks(tasks, plan_now, options)
                func = functools.partial(
                    identify_from_files, grid=grid, channels=channels, options=options
                )
            else:
                units = tasks
                func = functools.partial(
                    identify_block, grid=grid, channels=channels, options=options
                )
            unreadable_blocks = _unreadable_blocks(files, plan_now, unreadable)
            if unreadable_blocks:
                units = [unreadable_blocks.get(int(unit.block), unit) for unit in units]
            summary = run_blocks(
                units,
                func,
                store=store,
                scheduler=scheduler,
                n_workers=n_workers,
                total=len(tasks),
                batch_blocks=batch_blocks,
                progress=progress,
                description="identify",
                cuts=_plan_cuts(plan_now, digests),
            )
            return summary, len(tasks)

        known = store.unreadable_inputs()
        plan_run = plan
        if per_file:
            # files whose samples an earlier run found unreadable (unchanged since), or
            # that are damaged since a run read them: their edges pad no neighbour now
            # either (they stay fingerprinted, in *plan*)
            shown = {str(Path(info.path).resolve()): str(info.path) for info in plan.files}
            left_out = {path: shown[path] for path in known if path in shown}
            left_out |= {path: shown[path] for path in damaged if path in shown}
            if left_out and len(left_out) < len(plan.files):
                unreadable.update(
                    {
                        name: _detail(known[p], name) if p in known else damaged[p]["why"]
                        for p, name in left_out.items()
                    }
                )
                plan_run = _plan_without(plan, set(left_out))
        summary, n_tasks = run(plan_run)
        if per_file:
            summary = _without_unread_edges(
                store, plan, set(known) | set(damaged), unreadable, run, summary
            )
        if warn_unreadable:
            notices += _damaged_warnings(store, damaged, grid)
            notices += _unreadable_warnings(store, files, unreadable, damaged)
        result = IdentifyResult(summary, n_blocks=n_tasks, warnings=notices)
        result.files = export_store(store, out, channels, grid=grid, harmonics=marker)
        # files left out, re-timed for clock jitter or drift: said, not silent
        clock = [
            clock_jitter_note(plan.files),
            clock_drift_note(plan.files),
            edge_cut_note(plan),
            _missed_line(plan, blocks),
        ]
        result.notes = left_out_notes(plan) + [n for n in clock if n] + marker.lines()
        result.warnings += marker.unmarked()
    selected = result.files.get("selected")
    if selected is not None:
        result.n_selected = len(pd.read_parquet(selected, columns=["block"]))
    return result
