"""single_threaded (workbench.sid.threads): every thread-pool library limited to one thread
inside, as threadpoolctl.threadpool_limits(limits=1), and restored after."""

from __future__ import annotations

from threadpoolctl import threadpool_info, threadpool_limits

from workbench.sid.threads import single_threaded


def _threads():
    return {(i["user_api"], i["filepath"]): i["num_threads"] for i in threadpool_info()}


def test_single_threaded_limits_every_library_and_restores():
    with threadpool_limits(limits=2):  # a known state before, whatever the machine
        before = _threads()
        assert before  # numpy's BLAS at least
        with single_threaded():
            inside = _threads()
            with threadpool_limits(limits=1):
                reference = _threads()
        after = _threads()
    assert inside == reference
    assert set(inside.values()) == {1}
    assert after == before
    with single_threaded():  # the libraries found once are reused
        assert set(_threads().values()) == {1}
