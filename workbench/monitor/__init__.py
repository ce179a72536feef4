"""Live monitoring: follow a folder of acquisition files and a growing ship log.

``workbench monitor --watch DIR --dship FILE --state DIR`` identifies every block as soon
as its data is complete, tracks the modes and updates the Kalman-blended forecast and the
structural-health chart block by block, with the same results as the batch commands
(``identify`` + ``track`` + ``forecast``; ``health --modal --predictors``) over the same
files. A dashboard reads the state folder. The health chart charts the residuals of the
operational model fitted on the first ``--health-train-hours`` (12 h), with its reference
period (``--reference-hours``, 6 h) after them; with the ship log's fuel on board
(``fuel_on_board_t``) as a model term, or else a following baseline (``--baseline-hours``)
(:mod:`workbench.monitor.structural_health`).

State folder
------------
Every file is written atomically (temporary name, then rename), so a reader never sees a
half-written file. The tables that grow with the voyage (``tracked``, ``forecast``,
``health``, ``data_health``) are *parted tables* (:mod:`data_contracts.parts`): a folder of
that name holding one Parquet file per day of blocks (``part-000000.parquet`` the blocks
of the first day, ...) and an index (``_parts.json``); an update rewrites only the parts
whose rows changed (the newest day's, as a rule), so its cost does not grow with the
voyage. ``data_contracts.read_table`` (and ``pandas.read_parquet``, and the commands
taking ``--modal``: ``workbench forecast --modal STATE/tracked.parquet``) read such a
folder as the one table its parts make, in block order::

    <state>/state_format.json    {"schema": "workbench.monitor.state/2"}: the folder's
                                 format; a folder without it (format 1, every table one
                                 file) is migrated at the start, one of another format
                                 refused in one line
                                 (:mod:`workbench.monitor.state_format`)
    <state>/tracked.parquet      MODAL contract: the tracked modal table so far (labels
                                 that are shaft harmonics left out, from the logged shaft
                                 speed, or from the speed without it, as identify --dship)
    <state>/labels.json          {"schema": "workbench.monitor.labels/1", "labels":
                                 [{"mode": int, "labelled_block": int, "frequency_hz":
                                 float}]}: every label given so far (also those of
                                 harmonics, left out of the table), the block it was
                                 given at and the mode's frequency then; labels are
                                 never renumbered, and a restart checks that the
                                 replayed tracker gives them again (else it stops with
                                 a message naming the label)
    <state>/harmonics.parquet    the shaft orders' frequencies per tracked block (from a
                                 logged shaft speed, or the speed x the shaft rate per
                                 knot found; workbench.dashboard.state.HARMONIC_LINES)
    <state>/harmonic_tracks.parquet  the tracked lines left out as shaft harmonics, per
                                 block (workbench.dashboard.state.HARMONIC_TRACKS)
    <state>/forecast.parquet     FORECAST contract: sliding forecast + Kalman, all blocks
                                 (several options: each block's rows, option after option)
    <state>/health.parquet       HEALTH contract (empty until model and reference are learned)
    <state>/alarms.parquet       ALARMS contract (empty until then, and while no alarm)
    <state>/data_health.parquet  one row per decided block, in block order:
                                 block (int64), block_start (UTC), n_channels (int64,
                                 channels used; 0 for a skipped block), dropped_channels
                                 (comma-separated, '' if none), gap_seconds (float, time of
                                 the block without data), last_file_landed (UTC, the
                                 modification time of the block's last file when it was
                                 found complete), identified_at (UTC), latency_s
                                 (identified_at - last_file_landed), status ('ok' or
                                 'skipped'), reason (why skipped, else '')
    <state>/status.json          {"updated_at": ISO UTC, "last_block": int|null,
                                  "blocks_done": int, "state": "running"|"stopped",
                                  "pid": int, "watch": str, "message": str,
                                  "given_up": [{"first_block": int, "last_block": int,
                                  "start": ISO UTC, "end": ISO UTC, "reason": str}],
                                  "given_up_note": str, "health_note": str}
    <state>/notes.txt            every note of every run, one line each: the UTC time it
                                 was made, then the note (the command prints the last 10
                                 and, when there were more, names this file)
    <state>/heartbeat.json       {"time": ISO UTC, "pid": int, "host": str,
                                  "poll_s": float, "state": "running"|"stopped",
                                  "last_file": str|null, "last_file_taken_at": ISO UTC|null,
                                  "doing": str, "doing_since": ISO UTC, "stall_s": float,
                                  "worker": {"state": "none"|"alive"|"stopped",
                                             "pid": int|null, "message": str}}
    <state>/shore/key_indicators_YYYY-MM-DD.json and .csv
                                 the day's key indicators for the shore, per mode
                                 (workbench.monitor.shore.write_daily_indicators)
    <state>/alarm_hook.json      the alarm episodes handed to --on-alarm (by first block)
    <state>/outlook/             the forecast's and health chart's state after the newest
                                 committed blocks (outlook.json and its .npz arrays, no
                                 pickle; :class:`~workbench.monitor.incremental.
                                 IncrementalOutlook`): each update runs only the new blocks
    <state>/ship_log.json        the ship log the folder's results came from: its path,
                                 --dship-columns, --dship-utc-offset and the part read so
                                 far (bytes and SHA-256), checked at a restart
                                 (:mod:`workbench.monitor.log_record`)
    <state>/store/               the per-block store (:class:`~workbench.store.BlockStore`,
                                 the same layout and parameters as ``workbench identify``'s)

``health_note`` says from which block (and UTC time) the health chart monitors: after the
operational model's and the reference's hours of this voyage, or from the first block
with a saved baseline (``--baseline``); '' until the first forecast/health update.

``last_block`` is the newest block of the tracked table's span (every block up to it is
decided); ``blocks_done`` counts decided blocks (identified or skipped).

Liveness
--------
``status.json`` changes when a block is decided; ``heartbeat.json`` is written every
``poll_s`` by a thread of its own, whatever the blocks or the forecast are doing, and once
more with ``"state": "stopped"`` on a clean stop. A reader takes a running monitor whose
heartbeat is older than two poll intervals for *not responding* (killed, hung, its machine
or disk gone; :func:`workbench.dashboard.views.heartbeat_stale`); ``last_file`` and
``last_file_taken_at`` say which acquisition file it took last and when (UTC).
``doing`` and ``doing_since`` say what the main loop is doing (``"reading FILE"``,
``"identifying block N"``, ``"waiting for files"``, ...) and since when: the heartbeat
thread lives on when the main loop hangs, so a reader also takes a running monitor whose
loop has stayed in one activity longer than ``stall_s`` for *not responding*
(:data:`workbench.monitor.core.STALL_S`, one file period, or 20 poll intervals if longer).
``worker`` is the background forecast/health process (``--foreground``/``--once``:
``"none"``): ``"stopped"`` once the monitor notices it died (its ``message`` says when and
how; forecast and health stop updating), ``"alive"`` again once a new worker took over at
the next update (the message then says which one it replaced). The dashboard's status
line shows all three and validates the file (:func:`workbench.dashboard.state.read_heartbeat`).

When is a block identified
--------------------------
* A file counts once it is complete (:mod:`workbench.monitor.watcher`: not a hidden
  temporary name, unmodified for ``settle_s``, header readable).
* A block is identified when the files covering its span are all there. When the files
  are decimated (conditioned once per file, :class:`~workbench.signals.file_conditioning.
  FileConditioner`), each file's filters are padded with the raw edges of its neighbours,
  so the block also waits for the file after it: that is what makes it equal to the batch
  result (a batch run has that file too).
* Missing data (a late or lost file) holds the blocks over it until data ``late_s`` newer
  than the hole has landed (data time, so a replay at any speed decides alike); a file
  landing within that window is used as if it had come in order. After it, the blocks
  over the hole are decided as ``workbench identify`` over the files present decides them
  (skipped: gap), and a file landing later still is *not* used for them (a stored block is
  never redone) - blocks later in the record that it completes are identified normally.
  The blocks given up so, which ``workbench identify`` over the folder identifies, are
  listed with their span in ``status.json`` (``given_up``, whose ``reason`` names the
  files that landed late, their span and the files either side, e.g. ``acc_003.npz
  (2026-03-01T00:03:00Z to 2026-03-01T00:04:00Z, 60.0 s between acc_002.npz and
  acc_004.npz) landed after the late window: blocks 2-3 (...) were decided without it and
  given up``; ``given_up_note`` says what to
  run), on the dashboard's status line and in the command's last lines, also after a
  restart (:meth:`Monitor.given_up`). The last blocks of a record (waiting for a next
  file that does not come) are decided after ``flush_after_s`` without new files, or at
  once with ``--once``.
* Blocks are tracked in block order, so a block waiting for a late file holds the tracked
  table (not the identification) of the blocks after it.
* A block skipped (every channel faulty, a gap, ...) is said once in the log with its
  reason, and stored with its data-health row like any block. ``--once`` ends with exit
  1 and one line naming the blocks, their files and the reasons when the blocks it
  decided were all skipped, one at least for what its data holds (not a gap), or when
  no block of the state folder is identified (:meth:`Monitor.nothing_identified`); the
  monitor without ``--once`` goes on.
* The block grid is anchored at the first file (as in ``workbench identify``) and kept in
  the store: a file starting before it is refused with a message. On a new state folder
  the grid is fixed once the data landed reach the end of the first block (or ``late_s``
  past the earliest file; at once with ``--once`` or a flush), so a first file landing
  after the second still anchors it. The voyage's channels are, as in ``workbench
  identify``, those most of the files present then carry (so a first file lacking a
  channel the others have does not lose it), and are kept in the store too: a file
  lacking a few of them is read with them NaN, one carrying a channel they lack is used
  without it (both said in a note).

Blocks of varying length
------------------------
With ``--block-minutes auto`` (:attr:`MonitorOptions.adaptive`) each block takes the length
``identify --block-minutes auto`` gives it over the whole voyage (the rule of
:mod:`workbench.identification.adaptive`, run live by :mod:`workbench.monitor.adaptive`):
every half-step's excitation power is measured once its data can no longer change (the
rule above), and block ``k`` (centred at ``t0 + step / 2 + k step``) gets its length once
the half-steps of its longest candidate span (17.5 min past its centre with the default
5-35 min) are measured and the ship log covers them. So a block is identified at the
earliest 17.5 min after its centre (a fixed 20-min block: 10 min). A ship log behind the
data is waited for until data ``late_s`` newer has landed, then the lengths are decided
without its speed (said in the messages); at the end of the input (``--once``, or no file
for ``flush_after_s``) the last blocks take the lengths that fit the data present, as the
batch run over the same files gives them (said too). A block no length fits (a gap) is
stored as skipped (the batch run leaves it out of its tables). Each block is identified
on its length's grid and stored with its decision (store kind ``lengths``:
``block_start``, ``block_end``, ``block_length_s``, ``excitation_range_db``,
``speed_range_kn``, also columns of its selected modes); ``tracked.parquet`` records the
grid with ``"varying_length": true`` and each row its block's own span; the forecast and
the health chart average the ship log over each block's own span (not weighted by the
excitation: ``forecast --excitation`` over ``<state>/excitation.csv`` does that). The
half-steps measured are kept in ``<state>/excitation.csv`` (the batch run's
``excitation.csv``), read back after a restart. The store records the adaptive options:
a state folder of fixed blocks is not resumed with ``auto``, nor the reverse.

The ship log as it is written
-----------------------------
The ship log (``--dship``) is read again when its size or modification time changed;
only the complete lines appended since the last read are parsed
(:class:`~workbench.monitor.ship_log.LiveShipLog`), giving the table ``read_dship`` gives
over the whole file, with its warnings. A last line without its line end is left out until
it is whole. The log is read whole again when it was rotated or replaced (another file
under the name), truncated, rewritten in its first lines or in the 512 bytes before the
end read (a change further back is not seen: the data system appends), when its new
lines could change how the whole file reads (a time going back or repeated, text in a
column of numbers, a value in a column empty so far, mixed UTC offsets, a byte not UTF-8
in a UTF-8 log), and while it holds fewer than 60 readings. The appended rows are
written into column buffers with room to grow, so a read costs what the new lines cost,
not a copy of the table (``benchmarks/results/monitor_parity_53.txt``). The harmonic
marks of the newest blocks take the log's rows over them as the whole log's spike and
frozen-sensor tests leave them (kept as rows are appended: :class:`~workbench.sid.harmonics.
LiveShaftLog`), the whole log only for a block without a usable shaft speed but with the
speed (the shaft speed per knot is the whole log's). A block's marks and shaft speed
(``harmonics.parquet``) are kept once the log's verdicts on its readings are final
(:meth:`~workbench.sid.harmonics.LiveShaftLog.settled_until`): the spike test of its last
readings waits for the 15 readings after them (15 s of a 1-s log), and a run of equal
readings still open, under 5 min, may yet be a frozen sensor; before, they are marked
again with each block, so they equal ``identify --dship``'s over the whole log, restart
or not (but for a block marked from the speed: its shaft speed per knot is the log's
so far). A restart, or a log read whole again, reads and tests it whole once
(``benchmarks/results/monitor_costs_52.txt``). A shaft speed that stays at one value
while the speed spans a knot is judged against the lines following the speed
(:func:`~workbench.sid.harmonics.shaft_log_against_speed`) over every block tracked so far
and the log read so far, again at each block, as ``identify --dship`` judges the voyage
(the newest blocks alone rarely span a knot); while the log is judged frozen the blocks
are marked from the speed, and when the verdict turns every tracked block is marked again,
with a note naming them (``benchmarks/results/frozen_shaft_log_54.txt``). The forecast
of option B (and A with it)
reads the store's stabilisation diagrams with the harmonic marks ``identify --dship``
gives its poles, from the tracked modes the monitor marked.

The ship log's clock
--------------------
A log kept in local time without a UTC offset moves every predictor hours off its blocks.
With ``--dship``, the monitor runs ``identify``'s check of the log's clock
(:mod:`workbench.predictors.clock`) on the blocks it has identified (each on its own span),
as the log grows: at 24 blocks, then every 12 blocks until it has decided, on the newest
24 h of blocks (:mod:`workbench.monitor.log_clock`). Its warning, naming the likely
``--dship-utc-offset``, is said once per run: in the log and as a note.

Handing on
----------
After each forecast/health update the monitor runs ``--on-alarm COMMAND`` once per new
alarm episode (the episode as JSON on its stdin, in a thread of its own with a timeout;
a failure becomes a message, the monitor goes on) and rewrites the key indicators of the
days that got blocks (:mod:`workbench.monitor.shore`).

Resuming
--------
A block is stored (with its data-health row) before the state files mention it, as one
batch of the store, so killing the monitor at any moment (``kill -9`` included) and
starting it again loses no block and repeats none: the store says which blocks are done,
the tracker is replayed from their stored modes (the labels shown before the restart come
back on the same modes: ``labels.json`` is checked), and the forecast and health chart go on
from the state saved in ``outlook/`` (computed again from the first block when it is
missing, unreadable or of other settings). A restart with another ship log is refused
before anything in the state folder is touched (:mod:`workbench.monitor.log_record`):
``--dship`` left out or naming another file, other ``--dship-columns`` or
``--dship-utc-offset`` (exit 2, naming the option and the folder), or the log itself
cut short or rewritten in what was read (exit 1); a log grown by appended lines, or the
same bytes under another name, is taken up. A part of the tracked, data-health, forecast or
health table that cannot be read (cut short by a power cut or a full disk) is removed with a
note and the table written again: from the store, or the forecast from the first block.
An unreadable ``labels.json`` is written again when the replay gives the modes of the
tracked table the earlier run wrote (else refused, naming the recovery), an unreadable
``state_format.json`` when the folder's tables are parted tables of this format.
"""

from .core import DATA_HEALTH_COLUMNS, Monitor, MonitorOptions
from .outlook import ForecastSettings, update_outlook
from .watcher import FolderWatcher, LandedFile

__all__ = [
    "DATA_HEALTH_COLUMNS",
    "FolderWatcher",
    "ForecastSettings",
    "LandedFile",
    "Monitor",
    "MonitorOptions",
    "update_outlook",
]
