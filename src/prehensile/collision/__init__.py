"""Collision checking: sphere models (fast, batched), exact meshes (coal), allowed pairs."""

from prehensile.collision.acm import allowed_collision_matrix, compute_acm, rigid_bodies
from prehensile.collision.attached import AttachedObject, attach_objects
from prehensile.collision.exact import ExactChecker
from prehensile.collision.sphere_checker import SphereChecker
from prehensile.collision.spheres import (
    SphereModel, generate_sphere_model, pad_sphere_model, spheres_from_urdf,
)
from prehensile.collision.world import Obstacle

__all__ = [
    "AttachedObject", "ExactChecker", "Obstacle", "SphereChecker", "SphereModel", "allowed_collision_matrix",
    "attach_objects", "compute_acm", "generate_sphere_model", "pad_sphere_model", "rigid_bodies", "spheres_from_urdf",
]
