"""Shared test fixtures: where the optional ../shared material and example-robot-data live."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
MBM = SHARED / "bench" / "mbm"


def require_shared(path: Path = SHARED) -> Path:
    """Skip the calling test cleanly when the ../shared material is not there."""
    if not path.exists():
        pytest.skip(f"{path} not present (only developer machines have ../shared)")
    return path


def erd_robot(relative: str) -> Path:
    """Path of a URDF shipped by the pip package example-robot-data."""
    from prehensile.model.resources import package_search_roots

    for root in package_search_roots():
        candidate = root / "example-robot-data" / "robots" / relative
        if candidate.is_file():
            return candidate
    pytest.skip(f"example-robot-data robot {relative} not installed")
