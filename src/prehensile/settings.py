"""Range checks of the frozen settings dataclasses: a bad field is named with its valid values.

Each settings class checks itself in ``__post_init__`` with :func:`check_fields`, so a bad value
fails where it is given, not later inside a solver; functions check their arguments with
:func:`check_value` and the same rules.
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
FRACTION: Rule = (lambda v: 0 <= v < 1, "in [0, 1)")


def at_least(n: int) -> Rule:
    """An integer count of at least ``n`` (a whole float such as 1e5 counts)."""
    return (lambda v: v >= n and float(v).is_integer(), f"an integer >= {n}")


def or_none(rule: Rule) -> Rule:
    """``rule``, or None for "no limit"."""
    test, valid = rule
    return (lambda v: v is None or test(v), f"{valid} or None")


def check_value(name: str, value: Any, rule: Rule, error: type[PrehensileError] = PrehensileError) -> None:
    """Raise ``error`` "``name`` must be <valid values>, got ``value``" unless ``value`` keeps
    ``rule`` (NaN and values of the wrong type break every rule)."""
    test, valid = rule
    try:
        good = bool(test(value))
    except TypeError:
        good = False
    if not good:
        raise error(f"{name} must be {valid}, got {value!r}")


def check_fields(settings: Any, **rules: Rule) -> None:
    """Raise PrehensileError naming the first field of ``settings`` that breaks its rule."""
    for name, rule in rules.items():
        check_value(f"{type(settings).__name__}.{name}", getattr(settings, name), rule)
