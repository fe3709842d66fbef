"""Visualisation: static pictures (matplotlib) and, later, the web viewer."""

from prehensile.viz.picture import decimate, render_scene, scene_image, scene_triangles

__all__ = ["decimate", "render_scene", "scene_image", "scene_triangles"]
