"""Helpers shared by the benchmark scripts: timing, machine description, JSON output."""

from __future__ import annotations

import platform
import statistics
import time
from importlib import metadata
from typing import Callable


def median_seconds(function: Callable[[], object], repeats: int = 7, number: int = 1) -> float:
    """Median wall time (s) of ``number`` calls of ``function``, over ``repeats`` runs, per call."""
    function()  # warm-up (numba compilation, caches)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(number):
            function()
        times.append((time.perf_counter() - start) / number)
    return statistics.median(times)


def machine() -> dict:
    """Where and with what a benchmark ran."""
    versions = {}
    for package in ("prehensile", "numpy", "numba", "pin", "coal", "trimesh", "ompl"):
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            pass
    return {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": __import__("os").cpu_count(),
        "versions": versions,
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
