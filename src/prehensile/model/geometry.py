"""Geometric shapes attached to links and scene objects (SI units).

Every shape sits in its own frame: boxes, spheres and ellipsoids are centred on its origin;
cylinders and capsules are centred on it with their axis along z (URDF convention). Each shape
checks its sizes when built and raises :class:`~prehensile.errors.ModelError` naming the bad value;
the loaders check them first, so that their errors name the file and element.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from prehensile.errors import ModelError


def _check(shape: object, name: str, field: str, count: int, valid, rule: str) -> None:
    """ModelError naming the shape unless its ``field`` holds ``count`` finite numbers (1: a
    scalar) that are all ``valid``."""
    value = getattr(shape, field)
    try:
        x = np.asarray(value)
    except ValueError:  # a ragged sequence
        x = np.asarray(None)
    if not (x.dtype.kind in "iuf" and x.shape == (() if count == 1 else (count,))
            and np.all(np.isfinite(x)) and np.all(valid(x))):
        raise ModelError(f"{name}: {field} must be {rule}, got {value!r}")


@dataclass(frozen=True)
class Box:
    """Box with full side lengths ``size`` (m), shape (3,), each > 0."""

    size: tuple[float, float, float]

    def __post_init__(self) -> None:
        _check(self, "Box", "size", 3, lambda x: x > 0, "three finite side lengths > 0 (m)")


@dataclass(frozen=True)
class Sphere:
    """Sphere of ``radius`` > 0 (m)."""

    radius: float

    def __post_init__(self) -> None:
        _check(self, "Sphere", "radius", 1, lambda x: x > 0, "a finite length > 0 (m)")


@dataclass(frozen=True)
class Cylinder:
    """Cylinder of ``radius`` > 0 and total ``length`` > 0 (m) along z."""

    radius: float
    length: float

    def __post_init__(self) -> None:
        _check(self, "Cylinder", "radius", 1, lambda x: x > 0, "a finite length > 0 (m)")
        _check(self, "Cylinder", "length", 1, lambda x: x > 0, "a finite length > 0 (m)")


@dataclass(frozen=True)
class Capsule:
    """Capsule: cylinder of ``radius`` > 0 and ``length`` >= 0 (m) along z with hemispherical
    caps (length 0: a ball)."""

    radius: float
    length: float

    def __post_init__(self) -> None:
        _check(self, "Capsule", "radius", 1, lambda x: x > 0, "a finite length > 0 (m)")
        _check(self, "Capsule", "length", 1, lambda x: x >= 0, "a finite length >= 0 (m; 0 makes a ball)")


@dataclass(frozen=True, eq=False)
class Mesh:
    """Triangle mesh read from ``path`` and scaled per axis by ``scale`` (three finite non-zero
    factors; a negative one mirrors, as URDF allows, and a mirrored mesh keeps its faces
    outward: their winding is reversed when the factors' product is negative).

    The file is read on first use of :attr:`trimesh`. An in-memory mesh (e.g. one compiled by
    MuJoCo) has ``path=None`` and carries ``vertices`` (V, 3) in m and ``faces`` (F, 3) vertex
    indices instead; build it with :meth:`from_arrays`.
    """

    path: Path | None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None

    def __post_init__(self) -> None:
        _check(self, f"Mesh {self.path or '(in memory)'}", "scale", 3, lambda x: x != 0,
               "three finite non-zero factors (a negative one mirrors)")

    @classmethod
    def from_arrays(cls, vertices: np.ndarray, faces: np.ndarray) -> "Mesh":
        """An in-memory mesh from vertices (V, 3) in m and triangle indices (F, 3)."""
        vertices = np.array(vertices, dtype=float).reshape(-1, 3)
        faces = np.array(faces, dtype=np.int64).reshape(-1, 3)
        vertices.setflags(write=False)
        faces.setflags(write=False)
        return cls(None, vertices=vertices, faces=faces)

    @cached_property
    def trimesh(self):
        """The mesh as a ``trimesh.Trimesh`` (scenes are merged into one mesh)."""
        import trimesh

        if self.vertices is not None:
            loaded = trimesh.Trimesh(np.array(self.vertices), np.array(self.faces), process=False)
        else:
            try:
                loaded = trimesh.load(self.path, force="mesh", process=False)
            except Exception as error:  # trimesh raises many kinds for unreadable files
                raise ModelError(f"mesh {self.path}: not readable as a triangle mesh ({error}); "
                                 "formats: STL, OBJ, PLY, OFF, DAE, GLB") from None
            if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
                raise ModelError(f"mesh {self.path}: no triangles")
            if loaded.units not in (None, "m", "meters"):  # a COLLADA file's <unit>, as ROS tools read it
                loaded.convert_units("meters")
        mesh = loaded.copy()
        mesh.apply_scale(np.asarray(self.scale, dtype=float))  # reverses the winding of a mirror image
        return mesh


Shape = Box | Sphere | Cylinder | Capsule | Mesh


@dataclass(frozen=True, eq=False)
class Geometry:
    """A shape placed in a link (or object) frame by ``T_link_geom`` (4, 4)."""

    shape: Shape
    T_link_geom: np.ndarray = field(default_factory=lambda: np.eye(4))
    name: str = ""


def shape_to_trimesh(shape: Shape, sections: int = 24):
    """A triangle mesh of ``shape`` in its own frame (used for drawing and sphere fitting)."""
    import trimesh

    if isinstance(shape, Box):
        return trimesh.creation.box(extents=shape.size)
    if isinstance(shape, Sphere):
        return trimesh.creation.icosphere(subdivisions=2, radius=shape.radius)
    if isinstance(shape, Cylinder):
        return trimesh.creation.cylinder(radius=shape.radius, height=shape.length, sections=sections)
    if isinstance(shape, Capsule):
        return trimesh.creation.capsule(radius=shape.radius, height=shape.length, count=[sections, sections])
    return shape.trimesh
