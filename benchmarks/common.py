"""Helpers shared by the benchmark scripts (the statistics live in ``prehensile.benchmarking.stats``)."""

from __future__ import annotations

from prehensile.benchmarking.stats import machine as _machine
from prehensile.benchmarking.stats import median_seconds, versions

__all__ = ["machine", "median_seconds"]


def machine() -> dict:
    """Where and with what a benchmark ran: machine description plus package versions."""
    return {**_machine(), "versions": versions()}
