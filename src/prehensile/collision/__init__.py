"""Collision checking: sphere models (fast, batched), exact meshes (coal), allowed pairs."""

from prehensile.collision.world import Obstacle

__all__ = ["Obstacle"]
