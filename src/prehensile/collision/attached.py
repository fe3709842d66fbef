"""Grasped objects attached to robot links: :class:`AttachedObject` and :func:`attach_objects`.

An attached object becomes one more link, fixed to the link that holds it, so every checker
(balls, exact geometry, motion bounds) covers it without special cases.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from prehensile.collision.acm import rigid_bodies
from prehensile.collision.sphere_fit import cover_geometries
from prehensile.collision.spheres import SphereModel
from prehensile.collision.world import SHAPE_SIZES, positive_size
from prehensile.errors import PrehensileError, UnknownFrameError
from prehensile.model.geometry import Geometry, Shape
from prehensile.model.robot_model import FIXED, RobotModel
from prehensile.spatial.transforms import check_one_pose


@dataclass(frozen=True, eq=False)
class AttachedObject:
    """A grasped object that moves with a robot link.

    It collides with the world and with every link except ``link``'s rigid body (the links
    fixed to it, e.g. the hand on the flange) and ``touch_links`` (e.g. the fingers).

    Attributes:
        name: object name (unique among the attached objects).
        link: the link that holds it.
        shape: a shape in the object frame, a :class:`Geometry` or a tuple of them.
        T_link_object: (4, 4) pose of the object frame in the link frame.
        touch_links: further links allowed to touch it (names, or one name).
    """

    name: str
    link: str
    shape: Shape | Geometry | Sequence[Shape | Geometry]
    T_link_object: np.ndarray = field(default_factory=lambda: np.eye(4))
    touch_links: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        where = f"AttachedObject '{self.name}'"
        if isinstance(self.touch_links, str):  # one link, not its letters
            object.__setattr__(self, "touch_links", (self.touch_links,))
        check_one_pose(self.T_link_object, f"{where}: T_link_object")
        parts = self._parts()
        if not parts:
            raise PrehensileError(f"{where}: no shape given")
        for part in parts:
            shape = part.shape if isinstance(part, Geometry) else part
            if not positive_size(shape):
                raise PrehensileError(f"{where}: {shape} {SHAPE_SIZES}")
            if isinstance(part, Geometry):
                check_one_pose(part.T_link_geom, f"{where}: T_link_geom of {part.name or 'a geometry'}")

    def _parts(self) -> tuple:
        """``shape`` as a tuple of shapes and geometries."""
        return tuple(self.shape) if isinstance(self.shape, (list, tuple)) else (self.shape,)

    def geometries(self) -> tuple[Geometry, ...]:
        """The object's geometries in the object frame."""
        return tuple(part if isinstance(part, Geometry) else Geometry(part, name=self.name) for part in self._parts())


def attach_objects(model: RobotModel, spheres: SphereModel | None, acm: np.ndarray,
                   attached: Sequence[AttachedObject],
                   balls: int = 16) -> tuple[RobotModel, SphereModel | None, np.ndarray]:
    """The model, sphere model and ACM with one fixed link ``attached/<name>`` per object.

    The new links come after the model's links (the variables are unchanged). Their balls
    cover the object's geometry (:func:`~prehensile.collision.sphere_fit.cover_geometries`,
    ``balls`` per mesh); ``spheres`` None gives None (no balls needed, e.g. for exact checks).
    """
    if not attached:
        return model, spheres, acm
    names = [f"attached/{obj.name}" for obj in attached]
    if len(set(names)) != len(names) or set(names) & set(model.link_names):
        raise PrehensileError(f"attached objects need unique names, got {[obj.name for obj in attached]}")
    for obj in attached:
        for role, link in (("link", obj.link), *(("touch_links", name) for name in obj.touch_links)):
            try:
                model.link_index(link)
            except UnknownFrameError as error:
                raise UnknownFrameError(f"attached object '{obj.name}', {role}: {error}") from None
    n, k = model.n_links, len(attached)
    parents = [model.link_index(obj.link) for obj in attached]
    origins = [np.asarray(obj.T_link_object, dtype=float) for obj in attached]  # checked by AttachedObject
    geometries = tuple(obj.geometries() for obj in attached)
    augmented = dataclasses.replace(
        model, link_names=model.link_names + tuple(names), link_joint_names=model.link_joint_names + tuple(names),
        link_parent=np.concatenate([model.link_parent, parents]),
        joint_type=np.concatenate([model.joint_type, [FIXED] * k]),
        joint_origin=np.concatenate([model.joint_origin, origins]),
        joint_axis=np.concatenate([model.joint_axis, np.zeros((k, 3))]),
        joint_q_index=np.concatenate([model.joint_q_index, [-1] * k]),
        joint_multiplier=np.concatenate([model.joint_multiplier, np.ones(k)]),
        joint_offset=np.concatenate([model.joint_offset, np.zeros(k)]),
        visuals=model.visuals + geometries, collisions=model.collisions + geometries)
    augmented_spheres = None if spheres is None else _attach_balls(spheres, augmented.link_names, geometries, balls)
    body = rigid_bodies(model)
    allowed = np.zeros((n + k, n + k), dtype=bool)
    allowed[:n, :n] = acm
    for i, obj in enumerate(attached):
        touching = body == body[parents[i]]
        touching[[model.link_index(name) for name in obj.touch_links]] = True
        allowed[n + i, :n] = allowed[:n, n + i] = touching
        for j in range(k):  # objects held by the same body may touch each other
            allowed[n + i, n + j] = body[parents[i]] == body[parents[j]]
    return augmented, augmented_spheres, allowed


def _attach_balls(spheres: SphereModel, link_names: tuple[str, ...], geometries: tuple, balls: int) -> SphereModel:
    """``spheres`` with balls covering each object's ``geometries`` on the links after the model's."""
    n = len(spheres.link_names)
    centers, radii, links = [spheres.centers], [spheres.radii], [spheres.sphere_link]
    for i, geoms in enumerate(geometries):
        c, r = cover_geometries(geoms, n_spheres=balls)
        centers.append(c), radii.append(r), links.append(np.full(len(r), n + i))
    return SphereModel(link_names, np.concatenate(links), np.concatenate(centers), np.concatenate(radii),
                       spheres.covering)
