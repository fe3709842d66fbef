"""Range checks of the frozen settings dataclasses: a bad field is named with its valid values.

Each settings class checks itself in ``__post_init__`` with :func:`check_fields`, so a bad value
fails where it is given, not later inside a solver.
"""

from __future__ import annotations

from math import inf
from typing import Any, Callable

from prehensile.errors import PrehensileError

Rule = tuple[Callable[[Any], bool], str]  # (test of a value, the valid values in words)

POSITIVE: Rule = (lambda v: v > 0, "> 0")
FINITE_POSITIVE: Rule = (lambda v: 0 < v < inf, "> 0 and finite")
NON_NEGATIVE: Rule = (lambda v: v >= 0, ">= 0")
FINITE_NON_NEGATIVE: Rule = (lambda v: 0 <= v < inf, ">= 0 and finite")
UNIT_INTERVAL: Rule = (lambda v: 0 <= v <= 1, "in [0, 1]")


def at_least(n: int) -> Rule:
    """An integer count of at least ``n`` (a whole float such as 1e5 counts)."""
    return (lambda v: v >= n and float(v).is_integer(), f"an integer >= {n}")


def or_none(rule: Rule) -> Rule:
    """``rule``, or None for "no limit"."""
    test, valid = rule
    return (lambda v: v is None or test(v), f"{valid} or None")


def check_fields(settings: Any, **rules: Rule) -> None:
    """Raise PrehensileError naming the first field of ``settings`` that breaks its rule (NaN
    and values of the wrong type break every rule)."""
    for name, (test, valid) in rules.items():
        value = getattr(settings, name)
        try:
            good = bool(test(value))
        except TypeError:
            good = False
        if not good:
            raise PrehensileError(f"{type(settings).__name__}.{name} must be {valid}, got {value!r}")
