"""Sphere models of robots: read from a spherized URDF or generated from collision geometry.

A :class:`SphereModel` is a flat list of balls, each fixed to one link. Generated and padded
models *cover* the link's collision geometry (see :mod:`prehensile.collision.sphere_fit`), so a
sphere checker built on them never calls a configuration free that the exact meshes call
colliding. Generated models are cached on disk (:mod:`prehensile.collision.sphere_cache`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from prehensile.collision import sphere_cache
from prehensile.collision.sphere_fit import (
    PRIMITIVE_OVERSHOOT, cover_geometries, cover_primitive, cover_triangles, geometry_triangles, pad_to_cover,
)
from prehensile.errors import ModelError
from prehensile.model.geometry import Mesh, Sphere
from prehensile.model.robot_model import RobotModel
from prehensile.settings import FINITE_NON_NEGATIVE, FINITE_POSITIVE, POSITIVE, at_least, check_value, or_none

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class SphereModel:
    """Balls fixed to the links of a robot.

    Attributes:
        link_names: the model's links, (L,) names; ``sphere_link`` indexes into them.
        sphere_link: (S,) int64 link index of each ball.
        centers: (S, 3) ball centres in the link frame (m).
        radii: (S,) radii (m).
        covering: the balls of every link cover its collision geometry (generated and padded
            models; a spherized URDF's balls are not known to).
    """

    link_names: tuple[str, ...]
    sphere_link: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    covering: bool = False

    def __post_init__(self) -> None:
        link = np.ascontiguousarray(self.sphere_link, dtype=np.int64)
        order = np.argsort(link, kind="stable")
        for name, value in (("sphere_link", link[order]),
                            ("centers", np.asarray(self.centers, dtype=float).reshape(-1, 3)[order]),
                            ("radii", np.asarray(self.radii, dtype=float).reshape(-1)[order])):
            value = np.ascontiguousarray(value)
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if not (len(self.sphere_link) == len(self.centers) == len(self.radii)):
            raise ModelError("SphereModel: sphere_link, centers and radii differ in length")
        if len(link) and (link.min() < 0 or link.max() >= len(self.link_names)):
            raise ModelError("SphereModel: sphere_link index outside the link list")
        if not (np.all(self.radii >= 0) and np.all(np.isfinite(self.radii)) and np.all(np.isfinite(self.centers))):
            raise ModelError("SphereModel: negative or non-finite radius, or non-finite centre")

    @property
    def n_spheres(self) -> int:
        return len(self.radii)

    def link_spheres(self, link: int | str) -> tuple[np.ndarray, np.ndarray]:
        """Centres (k, 3) and radii (k,) of the balls on ``link`` (index or name)."""
        index = self.link_names.index(link) if isinstance(link, str) else int(link)
        mask = self.sphere_link == index
        return self.centers[mask], self.radii[mask]

    def link_ranges(self) -> np.ndarray:
        """(L, 2) int64: the balls of link i are ``[start, stop)`` (balls are sorted by link)."""
        n = len(self.link_names)
        start = np.searchsorted(self.sphere_link, np.arange(n), side="left")
        stop = np.searchsorted(self.sphere_link, np.arange(n), side="right")
        return np.column_stack([start, stop]).astype(np.int64)

    def link_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """One ball per link enclosing all of its balls: centres (L, 3) (link frame), radii (L,).

        Links without balls get radius -1.
        """
        n = len(self.link_names)
        centers, radii = np.zeros((n, 3)), np.full(n, -1.0)
        for i, (a, b) in enumerate(self.link_ranges()):
            if b > a:
                c, r = self.centers[a:b], self.radii[a:b]
                center = 0.5 * (np.min(c - r[:, None], axis=0) + np.max(c + r[:, None], axis=0))
                centers[i] = center
                radii[i] = float(np.max(np.linalg.norm(c - center, axis=1) + r))
        return centers, radii

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays for storage (see :func:`sphere_model_from_arrays`)."""
        return {"link_names": np.array(self.link_names), "sphere_link": self.sphere_link,
                "centers": self.centers, "radii": self.radii, "covering": np.array(self.covering)}


def replace_link_balls(spheres: SphereModel, other: SphereModel, links: set[str]) -> SphereModel:
    """``spheres`` with the balls of ``links`` (names) taken from ``other`` (same link list)."""
    if tuple(spheres.link_names) != tuple(other.link_names):
        raise ModelError("replace_link_balls: the sphere models belong to different link lists")
    take = np.isin(np.array(spheres.link_names), list(links))
    keep, swap = ~take[spheres.sphere_link], take[other.sphere_link]
    return SphereModel(spheres.link_names, np.concatenate([spheres.sphere_link[keep], other.sphere_link[swap]]),
                       np.vstack([spheres.centers[keep], other.centers[swap]]),
                       np.concatenate([spheres.radii[keep], other.radii[swap]]),
                       spheres.covering and other.covering)


def sphere_model_from_arrays(arrays) -> SphereModel:
    """Inverse of :meth:`SphereModel.arrays` (accepts an ``np.load`` result)."""
    return SphereModel(tuple(str(s) for s in arrays["link_names"]), arrays["sphere_link"],
                       arrays["centers"], arrays["radii"], bool(arrays["covering"]))


def _from_lists(model: RobotModel, per_link: list[tuple[np.ndarray, np.ndarray]], covering: bool) -> SphereModel:
    links = np.concatenate([np.full(len(r), i, dtype=np.int64) for i, (_, r) in enumerate(per_link)] or [np.zeros(0, np.int64)])
    centers = np.concatenate([c for c, _ in per_link] or [np.zeros((0, 3))])
    radii = np.concatenate([r for _, r in per_link] or [np.zeros(0)])
    return SphereModel(model.link_names, links, centers, radii, covering)


def _check_arguments(who: str, **values: tuple) -> None:
    """ModelError naming ``who`` and the first argument that breaks its rule; ``values``:
    name=(value, :data:`~prehensile.settings.Rule`)."""
    for name, (value, rule) in values.items():
        check_value(f"{who}: {name}", value, rule, ModelError)


def generate_sphere_model(
    model: RobotModel, n_spheres: int = 8, max_radius: float | None = None, max_edge: float = 0.02,
    max_overshoot: float = PRIMITIVE_OVERSHOOT, cache: bool = True,
) -> SphereModel:
    """Balls covering every link's collision geometry (meshes and primitives).

    Mesh triangles are subdivided to ``max_edge``, clustered into ``n_spheres`` groups and each
    group is enclosed by a near-minimal ball holding all vertices of its triangles (a ball
    holding a triangle's vertices holds the triangle), so the union covers the surface.
    Primitives get exact covers of the solid, with more balls (up to 64) while a ball reaches
    more than ``max_overshoot`` out of it (a target, see
    :func:`~prehensile.collision.sphere_fit.cover_geometries`). The result is cached on disk,
    keyed by a hash of the geometry (mesh file contents included) and the parameters.

    Args:
        model: the robot; links without collision geometry get no balls.
        n_spheres: balls per link mesh set (and budget per primitive).
        max_radius: optional target for the largest ball radius (m): more balls (up to 64 per
            link) are tried while a link's largest ball exceeds it. A target, not a bound: a
            ball primitive keeps its radius, and a mesh's clusters stop shrinking at some size
            (the Panda's links at about 0.07 m); the links left above it are logged (WARNING).
        max_edge: triangle subdivision length (m).
        max_overshoot: how far (m) a primitive's balls may reach out of it (a target, like
            ``max_radius``; infinite: ``n_spheres`` balls per primitive).
        cache: read and write the disk cache.

    Raises:
        ModelError: ``n_spheres`` below 1, or ``max_radius`` / ``max_edge`` / ``max_overshoot``
            not positive.
    """
    _check_arguments("generate_sphere_model", n_spheres=(n_spheres, at_least(1)),
                     max_radius=(max_radius, or_none(FINITE_POSITIVE)), max_edge=(max_edge, FINITE_POSITIVE),
                     max_overshoot=(max_overshoot, POSITIVE))
    params = {"kind": "generate", "n_spheres": int(n_spheres), "max_radius": max_radius, "max_edge": float(max_edge)}
    if any(not isinstance(g.shape, Mesh) for geometries in model.collisions for g in geometries):
        params["max_overshoot"] = float(max_overshoot)  # only primitives use it: meshes keep their cached balls

    def build() -> SphereModel:
        return _from_lists(model, [cover_geometries(geoms, n_spheres, max_radius, max_edge,
                                                    max_overshoot=max_overshoot) for geoms in model.collisions],
                           covering=True)

    spheres = sphere_cache.cached(model, params, build) if cache else build()
    if max_radius is not None:
        above = [f"{model.link_names[i]} {spheres.radii[spheres.sphere_link == i].max():.3f} m"
                 for i in np.unique(spheres.sphere_link[spheres.radii > max_radius])]
        if above:
            log.warning("%s: balls above the target radius %.3g m on %s", model.name, max_radius, ", ".join(above))
    return spheres


def spheres_from_urdf(model: RobotModel, path: str | Path) -> SphereModel:
    """Balls of a spherized URDF (e.g. MotionBenchMaker's ``panda_spherized.urdf``).

    The file's links are matched to ``model``'s by name (their frames must agree); every
    ``<sphere>`` collision becomes a ball; other primitives get exact covers.

    Raises:
        ModelError: the file names no link of ``model`` or has mesh collisions.
    """
    from prehensile.model.urdf import load_urdf

    spherized = load_urdf(path)
    per_link: list[tuple[np.ndarray, np.ndarray]] = []
    matched = 0
    for name in model.link_names:
        if name not in spherized.link_names:
            per_link.append((np.zeros((0, 3)), np.zeros(0)))
            continue
        matched += 1
        centers, radii = [np.zeros((0, 3))], [np.zeros(0)]
        for geometry in spherized.collisions[spherized.link_index(name)]:
            if isinstance(geometry.shape, Mesh):
                raise ModelError(f"{path}: link '{name}' has a mesh collision; expected spheres")
            if isinstance(geometry.shape, Sphere):
                centers.append(np.asarray(geometry.T_link_geom, dtype=float)[None, :3, 3])
                radii.append(np.array([float(geometry.shape.radius)]))
            else:
                c, r = cover_primitive(geometry)
                centers.append(c)
                radii.append(r)
        per_link.append((np.concatenate(centers), np.concatenate(radii)))
    if matched == 0:
        raise ModelError(f"{path}: none of its links is a link of robot '{model.name}'")
    return _from_lists(model, per_link, covering=False)


def pad_sphere_model(
    spheres: SphereModel, model: RobotModel, max_edge: float = 0.01, max_growth: float = 0.005,
    extra_radius: float = 0.025, cache: bool = True,
) -> SphereModel:
    """Grow (and if needed add) balls of ``spheres`` per link until they cover the link's geometry.

    Mesh triangles are subdivided to ``max_edge`` (m); each one not inside a single ball of its
    link grows the ball that needs the smallest increase if that is at most ``max_growth`` (m).
    Triangles still uncovered are enclosed by new balls (:func:`cover_triangles`, as few as
    give radii up to ``extra_radius`` m, trying 1, 2, 4, 8, 16). Primitive
    geometries get their exact covers added. Links with geometry
    but no balls get generated balls (:func:`generate_sphere_model`). Afterwards every triangle
    lies in one ball, so the union covers the geometry. A model that covers already
    (``spheres.covering``, e.g. a generated one) comes back as it is.
    """
    if tuple(spheres.link_names) != tuple(model.link_names):
        raise ModelError("pad_sphere_model: the sphere model belongs to a different link list")
    _check_arguments("pad_sphere_model", max_edge=(max_edge, FINITE_POSITIVE),
                     max_growth=(max_growth, FINITE_NON_NEGATIVE), extra_radius=(extra_radius, FINITE_POSITIVE))
    if spheres.covering:
        return spheres
    params = {"kind": "pad", "max_edge": float(max_edge), "max_growth": float(max_growth),
              "extra_radius": float(extra_radius), "spheres": sphere_cache.array_digest(spheres.arrays())}

    def build() -> SphereModel:
        per_link = []
        for i, geometries in enumerate(model.collisions):
            centers, radii = spheres.link_spheres(i)
            if not geometries:
                per_link.append((centers, radii))
                continue
            if len(radii) == 0:
                per_link.append(cover_geometries(geometries, max_edge=max(max_edge, 0.02)))
                continue
            meshes = [g for g in geometries if isinstance(g.shape, Mesh)]
            if meshes:
                triangles = np.concatenate([geometry_triangles(g, max_edge) for g in meshes])
                radii, uncovered = pad_to_cover(centers, radii, triangles, max_growth)
                if uncovered.any():
                    k = 1
                    while True:
                        c, r = cover_triangles(triangles[uncovered], k)
                        if r.max() <= extra_radius or k >= 16 or len(r) < k:
                            break
                        k *= 2
                    centers, radii = np.vstack([centers, c]), np.concatenate([radii, r])
            for g in geometries:
                if not isinstance(g.shape, Mesh):
                    c, r = cover_primitive(g)
                    centers, radii = np.vstack([centers, c]), np.concatenate([radii, r])
            per_link.append((centers, radii))
        return _from_lists(model, per_link, covering=True)

    return sphere_cache.cached(model, params, build) if cache else build()
