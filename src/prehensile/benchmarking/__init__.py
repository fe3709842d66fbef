"""Benchmark runners and their summaries (the ``prehensile bench`` commands use them)."""

from prehensile.benchmarking.stats import machine, mean_or_none, median_seconds, ratio, time_summary, versions

__all__ = ["machine", "mean_or_none", "median_seconds", "ratio", "time_summary", "versions"]
