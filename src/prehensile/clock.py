"""The clock of time budgets and reported solve times: wall time without numba compilation.

A compiled kernel is compiled on its first call in a process (tens of seconds on a fresh
install, all kernels together) or loaded from numba's on-disk cache (tens of milliseconds).
A planner or solver given a 50 ms budget on its first call would otherwise spend it all on
that, time out, and report a time that says nothing about the work. So budgets and the times
in results read :func:`clock`: the monotonic clock (s) minus the time spent waiting for or
holding numba's compiler lock (compiling or loading from the cache, in any thread), which numba
announces as ``"numba:compiler_lock"`` events. Compiled kernels read the same clock
(:func:`kernel_clock` with :data:`COMPILING`), so they can stop at
a deadline themselves. Benchmarks that compare against peers warm up first and time with
``time.perf_counter`` directly.
"""

from __future__ import annotations

import time

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils, event
from numba.extending import intrinsic

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
    return _monotonic() - COMPILING.item()


def compile_time() -> float:
    """Seconds spent compiling or loading numba kernels in this process so far."""
    return float(COMPILING[0])


@intrinsic
def _monotonic_ns(typingctx):
    """POSIX ``clock_gettime(CLOCK_MONOTONIC)`` in ns, called by name (so kernels that read it stay cacheable)."""

    def codegen(context, builder, signature, args):
        i32, i64 = ir.IntType(32), ir.IntType(64)
        spec = cgutils.alloca_once(builder, ir.ArrayType(i64, 2))  # struct timespec {tv_sec, tv_nsec}
        gettime = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i32, [i32, spec.type]),
                                                 "clock_gettime")
        builder.call(gettime, [ir.Constant(i32, time.CLOCK_MONOTONIC), spec])
        seconds, nanoseconds = (builder.load(builder.gep(spec, [ir.Constant(i32, 0), ir.Constant(i32, k)]))
                                for k in (0, 1))
        return builder.add(builder.mul(seconds, ir.Constant(i64, 1_000_000_000)), nanoseconds)

    return types.int64(), codegen


@njit(cache=True, _nrt=False)
def kernel_clock(compiling):
    """:func:`clock` read in a compiled kernel (about 25 ns); ``compiling`` is :data:`COMPILING`."""
    return _monotonic_ns() * 1e-9 - compiling[0]
