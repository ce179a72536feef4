"""One BLAS kernel for the whole test run, so that the recorded references reproduce.

OpenBLAS picks its kernels by the processor: SkylakeX on an Intel Xeon with AVX-512,
Haswell on an AMD EPYC with the same instructions. The kernels sum in different orders,
and the chain's discrete decisions (a stable pole kept or not, a Huber weight, a run of
large innovations, a stepwise entry) turn a difference in the last bit into one a recorded
table sees: on the same commit the demo's selected poles came from other model orders and
the memory forecast's reference moved by 0.2 mHz from one machine to the other, far below
SSI's scatter and far above the 1e-9 the recorded-reference tests allow
(``tests/test_demo.py``, ``tests/forecast/test_memory_speed.py``). Haswell's kernels
(AVX2 and FMA) run on every x86-64 processor of the last ten years, so the tests ask for
them there; the variable must be set before numpy loads OpenBLAS, which no test module has
done when pytest reads this file, and subprocesses (the command-line tests) inherit it.
A value the user set is left alone.
"""

from __future__ import annotations

import os
import platform
import sys


def _cpu_flags() -> set[str]:
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


if (
    "numpy" not in sys.modules
    and platform.machine() in ("x86_64", "AMD64")
    and {"avx2", "fma"} <= _cpu_flags()
):
    os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")
