"""The planners' random source: reproducible unless asked otherwise."""

from __future__ import annotations

import numpy as np

from prehensile.errors import PrehensileError


def planner_rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    """``rng`` itself if it is a generator, else a new one seeded with it (seed 0 for None, so
    that the same call gives the same result; pass ``np.random.default_rng()`` for fresh
    randomness)."""
    if isinstance(rng, np.random.Generator):
        return rng
    try:
        return np.random.default_rng(0 if rng is None else rng)
    except (TypeError, ValueError):
        raise PrehensileError(f"rng: expected a numpy Generator, a seed (integer >= 0) or None, got {rng!r}") from None
