"""A simulated voyage's state folder and a dashboard server over it, for the tests."""

from __future__ import annotations

import dataclasses
import threading

import pytest

from workbench.dashboard import DashboardOptions, DemoState, demo_state, make_server


@pytest.fixture(scope="session")
def voyage(tmp_path_factory) -> DemoState:
    """24 h simulated voyage (3 % stiffness loss on mode 3 at 21 h), nothing published."""
    return demo_state(tmp_path_factory.mktemp("voyage"), blocks=0, seed=0)


def publish(voyage: DemoState, folder, upto_block: int | None = None) -> DemoState:
    """A copy of *voyage* publishing into *folder*, with blocks up to *upto_block* written."""
    state = dataclasses.replace(voyage, folder=folder, written_block=None)
    if upto_block is not None:
        state.write(upto_block)
    return state


class Served:
    """A dashboard server running in a thread."""

    def __init__(self, folder, options: DashboardOptions | None = None):
        self.server = make_server(folder, port=0, options=options)
        self.url = self.server.url
        self._thread = threading.Thread(
            target=self.server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
        )
        self._thread.start()

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()
        self._thread.join(timeout=10)


@pytest.fixture
def serve():
    """``serve(folder, options=None)`` starts a server; all are stopped after the test."""
    started: list[Served] = []

    def start(folder, options=None) -> Served:
        served = Served(folder, options)
        started.append(served)
        return served

    yield start
    for served in started:
        served.close()
