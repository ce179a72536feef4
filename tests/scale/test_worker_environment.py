"""The local cluster's worker processes allocate like a plain process (issue 33)."""

from __future__ import annotations

import os

from workbench.parallel import _WORKER_MALLOC, _client


def test_local_workers_reuse_the_heap_for_block_sized_arrays():
    # dask's default MALLOC_TRIM_THRESHOLD_=65536 pins glibc's mmap threshold at 128 KiB,
    # so that every temporary of a block is mapped and zeroed afresh; the workers get
    # 32 MiB / 64 MiB instead
    with _client(None, 1) as client:
        seen = client.run(
            lambda: (
                os.environ.get("MALLOC_MMAP_THRESHOLD_"),
                os.environ.get("MALLOC_TRIM_THRESHOLD_"),
            )
        )
    assert len(seen) == 1
    (mmap_threshold, trim_threshold), *_ = seen.values()
    assert int(mmap_threshold) == 32 * 2**20
    assert int(trim_threshold) == 64 * 2**20
    assert set(_WORKER_MALLOC.values()) == {32 * 2**20, 64 * 2**20}
