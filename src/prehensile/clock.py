"""The clock of time budgets and reported solve times: wall time without numba compilation.

A compiled kernel is compiled on its first call in a process (tens of seconds on a fresh
install, all kernels together) or loaded from numba's on-disk cache (tens of milliseconds).
A planner or solver given a 50 ms budget on its first call would otherwise spend it all on
that, time out, and report a time that says nothing about the work. So budgets and the times
in results read :func:`clock`: the monotonic clock (s) minus the time spent waiting for or
holding numba's compiler lock (compiling or loading from the cache, in any thread), which numba
announces as ``"numba:compiler_lock"`` events. Compiled kernels read the same clock
(:func:`~prehensile.planning.kernels.kernel_clock` with :data:`COMPILING`), so they can stop at
a deadline themselves. Benchmarks that compare against peers warm up first and time with
``time.perf_counter`` directly.
"""

from __future__ import annotations

import time

import numpy as np
from numba.core import event

COMPILING = np.zeros(1)  # seconds spent compiling or loading numba kernels in this process so far


def _monotonic() -> float:
    return time.clock_gettime(time.CLOCK_MONOTONIC)


class _CompilerLockTime(event.Listener):
    """Adds to :data:`COMPILING` the time between the outermost start and end of numba's
    compiler-lock events."""

    def __init__(self) -> None:
        self._depth = 0
        self._since = 0.0

    def on_start(self, ev) -> None:
        if self._depth == 0:
            self._since = _monotonic()
        self._depth += 1

    def on_end(self, ev) -> None:
        self._depth -= 1
        if self._depth == 0:
            COMPILING[0] += _monotonic() - self._since


event.register("numba:compiler_lock", _CompilerLockTime())


def clock() -> float:
    """Seconds on a monotonic clock that stands still while numba compiles or loads a kernel."""
    return _monotonic() - COMPILING[0]


def compile_time() -> float:
    """Seconds spent compiling or loading numba kernels in this process so far."""
    return float(COMPILING[0])
