"""Shape constructors check their sizes."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import WEDGE
from prehensile.errors import ModelError
from prehensile.model.geometry import Box, Capsule, Cylinder, Mesh, Sphere, shape_to_trimesh

@pytest.mark.parametrize("build, message", [
    (lambda: Box((0.1, -0.1, 0.1)), r"Box: size must be three finite side lengths > 0 \(m\), got \(0.1, -0.1, 0.1\)"),
    (lambda: Box((0.1, 0.1)), r"Box: size must be three .*got \(0.1, 0.1\)"),
    (lambda: Box((0.1, np.nan, 0.1)), r"Box: size .*got \(0.1, nan, 0.1\)"),
    (lambda: Box(("1", "1", "1")), r"Box: size .*got \('1', '1', '1'\)"),
    (lambda: Sphere(0.0), r"Sphere: radius must be a finite length > 0 \(m\), got 0.0"),
    (lambda: Sphere(np.inf), "Sphere: radius .*got inf"),
    (lambda: Cylinder(0.1, 0.0), "Cylinder: length must be a finite length > 0 .*got 0.0"),
    (lambda: Cylinder(-0.1, 0.3), "Cylinder: radius .*got -0.1"),
    (lambda: Capsule(0.0, 0.3), "Capsule: radius .*got 0.0"),
    (lambda: Capsule(0.1, -0.01), r"Capsule: length must be a finite length >= 0 \(m; 0 makes a ball\), got -0.01"),
    (lambda: Mesh(None, (1.0, 0.0, 1.0)), r"Mesh \(in memory\): scale must be three finite non-zero factors"),
    (lambda: Mesh("wedge.obj", (1.0, 1.0, np.nan)), r"Mesh wedge.obj: scale .*got \(1.0, 1.0, nan\)"),
])
def test_bad_sizes_are_model_errors_naming_shape_and_value(build, message):
    with pytest.raises(ModelError, match=message):
        build()


def test_good_sizes_are_kept():
    assert Box((0.1, 0.2, 0.3)).size == (0.1, 0.2, 0.3)
    assert Box(np.array([1, 2, 3])).size.tolist() == [1, 2, 3]  # arrays and integers too
    assert Sphere(np.float64(0.05)).radius == 0.05 and Cylinder(0.1, 0.3).length == 0.3
    assert Capsule(0.02, 0.0).length == 0.0  # a ball, as scene files accept
    assert Mesh(None, (-1.0, 1.0, 0.001)).scale == (-1.0, 1.0, 0.001)  # a negative factor mirrors, as in URDF


@pytest.mark.parametrize("scale", [(1.0, -1.0, 1.0), (-1.0, -1.0, -1.0), (-2.0, 0.5, 3.0)])
def test_a_mirrored_mesh_is_the_mirror_image_with_outward_faces(scale):
    """Scaling by factors of negative product turns triangles inside out unless their winding is
    reversed: the signed volume and the outward normals show it."""
    plain = Mesh(WEDGE).trimesh
    for mesh in (Mesh(WEDGE, scale).trimesh, shape_to_trimesh(Mesh(WEDGE, scale))):
        assert np.allclose(mesh.vertices, plain.vertices * scale)
        assert mesh.volume == pytest.approx(plain.volume * abs(np.prod(scale)))  # signed: > 0
        outward = np.einsum("ij,ij->i", mesh.face_normals, mesh.triangles_center - mesh.vertices.mean(axis=0))
        assert np.all(outward > 0)  # the wedge is convex: every face looks away from its centre


@pytest.mark.parametrize("unit, factor", [(None, 1.0), (1.0, 1.0), (0.001, 0.001), (0.0254, 0.0254)])
def test_collada_meshes_are_read_in_metres(tmp_path, unit, factor):
    """A COLLADA file's <unit meter="..."> scales its vertices to metres, as ROS tools read it."""
    import re

    import trimesh

    text = trimesh.exchange.dae.export_collada(trimesh.creation.box((2.0, 4.0, 6.0)))
    text = text.decode() if isinstance(text, bytes) else text
    if unit is not None:
        text = re.sub(r"<asset>", f'<asset><unit meter="{unit}" name="u"/>', text, count=1)
    (tmp_path / "box.dae").write_text(text)
    mesh = Mesh(str(tmp_path / "box.dae"), (1.0, 2.0, 1.0)).trimesh
    np.testing.assert_allclose(mesh.extents, np.array([2.0, 8.0, 6.0]) * factor)
