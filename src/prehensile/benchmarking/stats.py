"""Summaries shared by the benchmarks: timing statistics, machine and version records.

Percentiles use numpy's default linear interpolation between order statistics, so the
95th percentile of fewer than 20 values lies between the two largest.
"""

from __future__ import annotations

import os
import platform
import statistics
import time
from importlib import metadata
from typing import Callable, Iterable, Sequence

import numpy as np

DEFAULT_PACKAGES = ("prehensile", "numpy", "numba", "coal", "trimesh", "pin", "ompl", "ikpy")


def time_summary(seconds: Sequence[float]) -> dict[str, float | None]:
    """Median, 95th percentile and mean of durations given in s, reported in ms.

    Returns:
        ``{"median_ms", "p95_ms", "mean_ms"}``; None for each when ``seconds`` is empty.
    """
    values = np.asarray(list(seconds), dtype=float)
    if values.size == 0:
        return {"median_ms": None, "p95_ms": None, "mean_ms": None}
    return {
        "median_ms": float(np.median(values) * 1e3),
        "p95_ms": float(np.percentile(values, 95) * 1e3),
        "mean_ms": float(np.mean(values) * 1e3),
    }


def mean_or_none(values: Iterable[float]) -> float | None:
    """Arithmetic mean, or None for no values."""
    values = list(values)
    return float(np.mean(values)) if values else None


def ratio(numerator: float | None, denominator: float | None) -> float | None:
    """numerator / denominator, or None when either is missing or the denominator is 0."""
    if numerator is None or denominator is None or denominator == 0:
        return None
    return float(numerator / denominator)


def median_seconds(function: Callable[[], object], repeats: int = 7, number: int = 1) -> float:
    """Median wall time (s) per call of ``function``: ``repeats`` runs of ``number`` calls each,
    after one warm-up call (numba compilation, caches)."""
    function()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(number):
            function()
        times.append((time.perf_counter() - start) / number)
    return statistics.median(times)


def versions(packages: Iterable[str] = DEFAULT_PACKAGES) -> dict[str, str]:
    """Installed version of each package that is installed (distribution names)."""
    out = {}
    for package in packages:
        try:
            out[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            continue
    return out


def machine() -> dict:
    """Where a benchmark ran: platform, processor, CPU count, load, numba threads, Python, date."""
    info = {
        "platform": platform.platform(),
        "machine": platform.machine(),
        "processor": _cpu_model() or platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
    if hasattr(os, "getloadavg"):  # other work on the machine skews absolute times
        info["load_average_1_5_15_min"] = [round(v, 2) for v in os.getloadavg()]
    try:
        import numba

        info["numba_threads"] = numba.get_num_threads()
    except ImportError:
        pass
    return info


def _cpu_model() -> str:
    """The CPU model name from /proc/cpuinfo (Linux), "" elsewhere."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as handle:
            for line in handle:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return ""
