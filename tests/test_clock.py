"""Budgets and reported times leave out numba compilation (prehensile.clock)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest
from numba import njit

from prehensile.clock import COMPILING, clock, compile_time, kernel_clock


def test_compiling_a_kernel_does_not_advance_the_clock():
    @njit(cache=False)  # defined here, so its first call compiles
    def sum_of_squares(x):
        total = 0.0
        for v in x:
            total += v * v
        return total

    wall, ticks, compiling = time.perf_counter(), clock(), compile_time()
    assert sum_of_squares(np.arange(4.0)) == 14.0
    wall, ticks, compiling = time.perf_counter() - wall, clock() - ticks, compile_time() - compiling
    assert compiling > 0.5 * wall, (compiling, wall)
    assert ticks == pytest.approx(wall - compiling, abs=1e-3)  # read a few microseconds apart

    compiled, ticks = compile_time(), clock()
    sum_of_squares(np.arange(4.0))  # compiled now: the clock runs as the wall clock
    assert compile_time() == compiled and clock() > ticks


def test_kernels_read_the_same_clock():
    """kernel_clock is clock(), also on its first call in a process, which loads or compiles it
    (the clock stands still meanwhile, so a deadline set before the call still holds)."""
    for _ in range(2):
        before = clock()
        inside = kernel_clock(COMPILING)
        assert before <= inside <= clock()


def test_first_plan_on_a_cold_kernel_cache_keeps_its_budget(tmp_path):
    """A fresh install: every kernel compiles during the first ``prehensile plan``, which must
    still search within its budget (compiling alone takes about 20 s)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    done = subprocess.run([sys.executable, "-m", "prehensile", "plan", "plan_demo", "--seed", "1",
                           "--budget", "1.0", "--out", str(tmp_path / "out")], env=env, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    report = json.loads((tmp_path / "out" / "path.json").read_text())
    assert report["status"] == "success"
    assert report["stats"]["plan_time_s"] < 1.0
