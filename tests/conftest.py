"""Shared test fixtures: where the optional ../shared material and example-robot-data live.

The shared material is ``../shared`` beside the repository, or wherever ``PREHENSILE_SHARED``
points (a clone elsewhere can still run the tests that need it).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PREHENSILE_SHARED", REPO.parent / "shared"))
MBM = SHARED / "bench" / "mbm"
WEDGE = REPO / "tests" / "data" / "scenes" / "wedge.obj"  # tetrahedron: x, y, z >= 0, x + y + z <= 0.1 (m)


def require_shared(path: Path = SHARED) -> Path:
    """Skip the calling test cleanly when the ../shared material is not there."""
    if not path.exists():
        pytest.skip(f"{path} not present (only developer machines have ../shared; PREHENSILE_SHARED moves it)")
    return path


def erd_robot(relative: str) -> Path:
    """Path of a URDF shipped by the pip package example-robot-data."""
    from prehensile.model.resources import package_search_roots

    for root in package_search_roots():
        candidate = root / "example-robot-data" / "robots" / relative
        if candidate.is_file():
            return candidate
    pytest.skip(f"example-robot-data robot {relative} not installed")


def part_urdf(directory: Path, geometry: str) -> Path:
    """A URDF file written in ``directory``: link 'part', whose collision geometry is the URDF
    element ``geometry`` (e.g. '<sphere radius="0.1"/>'), on a revolute joint about z at the
    origin of link 'base'."""
    path = directory / "part.urdf"
    path.write_text(f"""<robot name="part"><link name="base"/>
  <link name="part"><collision><geometry>{geometry}</geometry></collision></link>
  <joint name="turn" type="revolute"><parent link="base"/><child link="part"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3"/></joint></robot>""")
    return path
