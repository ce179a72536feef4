"""A state folder like the monitor's, from the batch stages, for demos, tests and benchmarks.

:func:`demo_state` simulates a block-level voyage with
:func:`workbench.simulate.simulate_health_voyage` (the demo hull's modal law, the demo
operating profile, SSI-like scatter, optionally a stiffness loss part-way), forecasts it
with the real sliding model frozen after a training period
(:func:`workbench.shm.frozen_forecast`, Kalman-blended, option A) and runs the health
chart (:func:`workbench.shm.health_chart`) over it. :meth:`DemoState.write` then
publishes the state as the monitor would after a given block, each file atomically, and
:meth:`DemoState.append` publishes the next block, to exercise a live dashboard.

The data-health table is synthesised, since a block-level voyage has no files: the demo
voyage's channels, its dead channel dropped for an hour and a dropout channel now and
then, short gaps, and a latency drawn from a log-normal law. The monitor writes measured
values in its place.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import ALARMS, FORECAST, HEALTH, MODAL, atomic_path, write_table

from .state import DATA_HEALTH, STATE_FILES

__all__ = ["DemoState", "demo_state"]

#: Block step of the demo grid. [s]
_STEP_SECONDS = 300
#: Block length of the demo grid. [s]
_BLOCK_SECONDS = 1200


@dataclass
class DemoState:
    """A simulated voyage's complete state, published block by block into *folder*.

    Parameters
    ----------
    folder : Path
        The state folder written into.
    tracked, forecast, health, alarms, data_health : DataFrame
        The complete tables of the voyage (MODAL, FORECAST, HEALTH, ALARMS, DATA_HEALTH).
    reference_end_block : int
        Last block of the health chart's reference period; the chart is published once
        this block is (the control limit does not exist before).
    written_block : int or None
        Newest block published so far.
    """

    folder: Path
    tracked: pd.DataFrame
    forecast: pd.DataFrame
    health: pd.DataFrame
    alarms: pd.DataFrame
    data_health: pd.DataFrame
    reference_end_block: int
    written_block: int | None = None
    seed: int = 0
    blocks: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.blocks = np.sort(self.data_health["block"].unique())

    @property
    def last_block(self) -> int:
        """Newest block of the voyage."""
        return int(self.blocks[-1])

    def write(self, upto_block: int, *, state: str = "running", message: str = "") -> None:
        """Publish the state after block *upto_block*: every table cut at that block,
        each file written atomically, ``status.json`` last."""
        upto = int(upto_block)
        self.folder.mkdir(parents=True, exist_ok=True)
        path = {name: self.folder / file for name, (file, _) in STATE_FILES.items()}
        write_table(self.tracked[self.tracked["block"] <= upto], path["tracked"], MODAL)
        write_table(self.forecast[self.forecast["block"] <= upto], path["forecast"], FORECAST)
        if upto >= self.reference_end_block:
            health = self.health[self.health["block"] <= upto]
            write_table(health, path["health"], HEALTH)
            write_table(_alarms_upto(self.alarms, health), path["alarms"], ALARMS)
        write_table(
            self.data_health[self.data_health["block"] <= upto], path["data_health"], DATA_HEALTH
        )
        done = int((self.blocks <= upto).sum())
        status = {
            "updated_at": pd.Timestamp.now(tz="UTC").strftime("%Y-%m-%dT%H:%M:%S.%fZ"),
            "last_block": upto if done else None,
            "blocks_done": done,
            "state": state,
            "pid": os.getpid(),
            "watch": f"simulated voyage (seed {self.seed})",
            "message": message,
        }
        with atomic_path(path["status"]) as tmp:
            Path(tmp).write_text(json.dumps(status), encoding="utf-8")
        self.written_block = upto

    def append(self, n_blocks: int = 1) -> int:
        """Publish the next *n_blocks* blocks; returns the newest block published."""
        if self.written_block is None:
            following = self.blocks
        else:
            following = self.blocks[self.blocks > self.written_block]
        if len(following) == 0:
            raise ValueError(f"the voyage ends at block {self.last_block}; nothing to append")
        upto = int(following[min(n_blocks, len(following)) - 1])
        self.write(upto)
        return upto


def _alarms_upto(alarms: pd.DataFrame, health: pd.DataFrame) -> pd.DataFrame:
    """Alarm episodes as known after the newest block of *health*: episodes not yet
    started are left out, an open episode ends at the newest block and its peak is the
    peak so far (the contributing modes and shift are those of the whole episode)."""
    newest = int(health["block"].max())
    out = alarms[alarms["start_block"] <= newest].copy()
    for index, row in out.iterrows():
        if row["end_block"] > newest:
            seen = health[(health["block"] >= row["start_block"]) & (health["block"] <= newest)]
            peak = seen.loc[seen["statistic"].idxmax()]
            out.loc[index, "end_block"] = newest
            out.loc[index, "end_time"] = seen["block_start"].iloc[-1]
            out.loc[index, "peak_block"] = int(peak["block"])
            out.loc[index, "peak_statistic"] = float(peak["statistic"])
    return out


def _data_health(starts: pd.Series, blocks: np.ndarray, rng: np.random.Generator) -> pd.DataFrame:
    from ..simulate import CHANNELS
    from ..simulate.voyage import DEAD_CHANNEL, DROPOUT_CHANNELS

    n = len(blocks)
    hours = (starts - starts.iloc[0]).dt.total_seconds().to_numpy() / 3600.0
    dead = (hours >= 3.0) & (hours < 4.0)
    dropout = rng.random(n) < 0.05
    dropped = [
        ",".join([DEAD_CHANNEL] * bool(d) + [DROPOUT_CHANNELS[0]] * bool(o))
        for d, o in zip(dead, dropout, strict=True)
    ]
    gap = np.where(rng.random(n) < 0.04, rng.uniform(1.0, 60.0, n), 0.0)
    gap = np.where(dropout, gap + rng.uniform(5.0, 30.0, n), gap)
    landed = (
        starts
        + pd.Timedelta(seconds=_BLOCK_SECONDS)
        + pd.to_timedelta(rng.exponential(3.0, n), unit="s")
    )
    latency = rng.lognormal(np.log(20.0), 0.3, n)
    return pd.DataFrame(
        {
            "block": blocks,
            "block_start": starts.to_numpy(),
            "n_channels": len(CHANNELS)
            - np.array([len(d.split(",")) if d else 0 for d in dropped]),
            "dropped_channels": dropped,
            "gap_seconds": gap,
            "last_file_landed": landed.to_numpy(),
            "identified_at": (landed + pd.to_timedelta(latency, unit="s")).to_numpy(),
            "latency_s": latency,
        }
    )


def demo_state(
    folder: str | os.PathLike,
    *,
    hours: float = 24.0,
    blocks: int | None = None,
    seed: int = 0,
    damaged_mode: int | None = 3,
    stiffness_loss: float = 0.03,
    damage_after_hours: float | None = None,
    train_hours: float = 12.0,
    reference_hours: float = 6.0,
) -> DemoState:
    """Simulate a voyage and publish its first *blocks* blocks into *folder*.

    Parameters
    ----------
    folder : path
        State folder to write (created if needed).
    hours : float
        Voyage length. [h]
    blocks : int, optional
        Blocks to publish now (default all; 0 publishes nothing).
    seed : int
        Seed of the voyage and of the synthesised data health.
    damaged_mode, stiffness_loss, damage_after_hours
        Stiffness loss of one mode from a time on (default: 3 % on mode 3 at 7/8 of the
        voyage: 21 h into the default 24 h); ``damaged_mode=None`` for an undamaged voyage. [-], [h]
    train_hours, reference_hours : float
        Training period of the frozen forecast model (the demo profile repeats every
        12 h), then the health chart's reference period. [h]

    Returns
    -------
    DemoState
        Call :meth:`DemoState.append` to publish further blocks.
    """
    from ..shm import HealthOptions, frozen_forecast, health_chart
    from ..simulate import simulate_health_voyage

    train_blocks = int(round(train_hours * 3600 / _STEP_SECONDS))
    reference_blocks = int(round(reference_hours * 3600 / _STEP_SECONDS))
    if damaged_mode is not None and damage_after_hours is None:
        damage_after_hours = 0.875 * hours
    voyage = simulate_health_voyage(
        hours,
        seed=seed,
        damaged_mode=damaged_mode,
        stiffness_loss=stiffness_loss if damaged_mode is not None else 0.0,
        damage_after_hours=damage_after_hours if damaged_mode is not None else None,
    )
    forecast = frozen_forecast(voyage, train_blocks)
    # the MEWMA chart of the frozen stepwise forecast: a display demo of 24 h. (The
    # monitor charts the operational model's residuals with the CUSUM; fitted on 12 h, that
    # model's extrapolation uncertainty over the next 12 h is as large as the 3 % loss
    # shown here, and the chart rightly stays quiet.)
    chart = health_chart(
        forecast,
        HealthOptions(reference_blocks=reference_blocks, seed=seed, statistic="mewma"),
    )
    predictors = voyage.predictors
    state = DemoState(
        folder=Path(folder),
        tracked=voyage.modal,
        forecast=forecast,  # with its warning column, as the forecast stage writes it
        health=chart.table,  # with the contribution of each mode to the statistic
        alarms=chart.alarms,
        data_health=_data_health(
            predictors["block_start"],
            predictors["block"].to_numpy(),
            np.random.default_rng(seed + 1),
        ),
        reference_end_block=chart.reference.end_block,
        seed=seed,
    )
    state.folder.mkdir(parents=True, exist_ok=True)
    if blocks is None:
        state.write(state.last_block)
    elif blocks > 0:
        state.write(int(state.blocks[min(blocks, len(state.blocks)) - 1]))
    return state


class DemoReplay:
    """Publish a simulated voyage into *folder* one block every *interval* seconds, in a
    background thread, for ``workbench dashboard --demo``.

    Parameters
    ----------
    folder : path
        State folder to write.
    interval : float
        Seconds between blocks. [s]
    seed : int
        Seed of the voyage.
    lead_hours : float
        Hours published at once before the replay starts, so the page opens on a full
        view (the health chart's reference period already learned). [h]
    """

    def __init__(
        self, folder: str | os.PathLike, *, interval: float = 2.0, seed: int = 0, lead_hours=19.0
    ):
        import threading

        if not interval > 0:
            raise ValueError(f"interval={interval!r} must be > 0")
        self.interval = float(interval)
        self.state = demo_state(folder, blocks=0, seed=seed)
        first = int(round(lead_hours * 3600 / _STEP_SECONDS))
        self.state.write(int(self.state.blocks[min(first, len(self.state.blocks) - 1)]))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="dashboard-demo", daemon=True)

    def _run(self) -> None:
        while not self._stop.wait(self.interval):
            if self.state.written_block >= self.state.last_block:
                self.state.write(self.state.last_block, state="stopped", message="voyage ended")
                return
            self.state.append()

    def start(self) -> DemoReplay:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=10)
