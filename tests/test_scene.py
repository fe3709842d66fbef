"""YAML scene files: loading, saving, validation messages, the bundled demo scene."""

from __future__ import annotations

import dataclasses
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from prehensile.errors import SceneError
from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Sphere
from prehensile.scene import Body, Hold, PlacedRobot, Scene, bundled_scene_path, check_scene, load_scene, save_scene
from prehensile.spatial import quaternion_to_matrix, rpy_to_matrix

DATA = Path(__file__).parent / "data" / "scenes"


def _write(tmp_path: Path, data: dict, name: str = "scene.yaml") -> Path:
    for file in ("two_link.urdf", "wedge.obj"):
        shutil.copy(DATA / file, tmp_path / file)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _base() -> dict:
    return {
        "version": 1,
        "robots": [{"name": "arm", "robot": "two_link.urdf", "pose": {"position": [0.1, 0.2, 0.3], "rpy": [0, 0, 0.5]},
                    "joints": {"joint1": 0.25, "joint2": -0.5}}],
        "obstacles": [
            {"name": "table", "pose": {"position": [1.0, 0.0, 0.4]},
             "shapes": [{"type": "box", "size": [1.0, 0.6, 0.05]},
                        {"type": "cylinder", "radius": 0.02, "length": 0.4, "pose": {"position": [0.4, 0.2, -0.2]}}]},
            {"name": "shelf", "pose": {"position": [0, 1, 0], "quaternion": [math.cos(0.2), 0, 0, math.sin(0.2)]},
             "shape": {"type": "mesh", "file": "wedge.obj", "scale": [1.0, 2.0, 1.5]}},
        ],
        "objects": [
            {"name": "ball", "pose": {"position": [0.5, 0.5, 0.5]}, "shape": {"type": "sphere", "radius": 0.04}},
            {"name": "pill", "shape": {"type": "capsule", "radius": 0.01, "length": 0.05, "name": "body"}},
        ],
    }


def test_load_all_shape_types_and_poses(tmp_path):
    scene = load_scene(_write(tmp_path, _base()))
    (robot,) = scene.robots
    assert robot.name == "arm" and robot.model.name == "two_link"
    np.testing.assert_allclose(robot.T_world_base[:3, 3], [0.1, 0.2, 0.3])
    np.testing.assert_allclose(robot.T_world_base[:3, :3], rpy_to_matrix(np.array([0, 0, 0.5])))
    np.testing.assert_allclose(robot.configuration, [0.25, -0.5])
    table, shelf = scene.obstacles
    assert isinstance(table.geometries[0].shape, Box) and table.geometries[0].shape.size == (1.0, 0.6, 0.05)
    assert isinstance(table.geometries[1].shape, Cylinder)
    np.testing.assert_allclose(table.geometries[1].T_link_geom[:3, 3], [0.4, 0.2, -0.2])
    np.testing.assert_allclose(shelf.T_world_body[:3, :3], quaternion_to_matrix(np.array([math.cos(0.2), 0, 0, math.sin(0.2)])))
    mesh = shelf.geometries[0].shape
    assert isinstance(mesh, Mesh) and mesh.path == (tmp_path / "wedge.obj").resolve() and mesh.scale == (1.0, 2.0, 1.5)
    ball, pill = scene.objects
    assert isinstance(ball.geometries[0].shape, Sphere)
    assert isinstance(pill.geometries[0].shape, Capsule) and pill.geometries[0].name == "body"
    assert len(scene.collision_obstacles()) == 5


def test_round_trip_to_another_folder(tmp_path):
    original = load_scene(_write(tmp_path, _base()))
    target = tmp_path / "elsewhere" / "copy.yaml"
    save_scene(original, target)
    assert not list(target.parent.glob("*.tmp"))
    again = load_scene(target)
    assert again.robots[0].model.source == original.robots[0].model.source
    np.testing.assert_allclose(again.robots[0].T_world_base, original.robots[0].T_world_base, atol=1e-12)
    np.testing.assert_allclose(again.robots[0].configuration, original.robots[0].configuration)
    for a, b in zip(original.bodies, again.bodies):
        assert a.name == b.name
        np.testing.assert_allclose(a.T_world_body, b.T_world_body, atol=1e-12)
        for ga, gb in zip(a.geometries, b.geometries):
            np.testing.assert_allclose(ga.T_link_geom, gb.T_link_geom, atol=1e-12)
            if isinstance(ga.shape, Mesh):
                assert ga.shape.path == gb.shape.path and ga.shape.scale == gb.shape.scale
            else:
                assert ga.shape == gb.shape
    text = target.read_text()
    assert "../wedge.obj" in text and "../two_link.urdf" in text


def test_a_mirrored_mesh_round_trips(tmp_path):
    """A negative scale factor mirrors the mesh, as in URDF; what save_scene writes loads again."""
    scene = load_scene(_write(tmp_path, _mutate(lambda d: d["obstacles"][1]["shape"].update(scale=[1.0, -2.0, 1.5]))))
    save_scene(scene, tmp_path / "copy.yaml")
    for loaded in (scene, load_scene(tmp_path / "copy.yaml")):
        assert loaded.obstacles[1].geometries[0].shape.scale == (1.0, -2.0, 1.5)


def test_bundled_robot_by_name_round_trips(tmp_path):
    pytest.importorskip("prehensile.robots")
    from prehensile import robots

    name = robots.available()[0]
    path = _write(tmp_path, {"robots": [{"robot": name}]})
    scene = load_scene(path)
    assert scene.robots[0].reference == name
    save_scene(scene, tmp_path / "out.yaml")
    assert yaml.safe_load((tmp_path / "out.yaml").read_text())["robots"][0]["robot"] == name
    # a bundled model placed by hand (no scene file named it) is written by name: its SRDF comes along
    save_scene(Scene(robots=(PlacedRobot("r", robots.load(name)),)), tmp_path / "by_hand.yaml")
    assert yaml.safe_load((tmp_path / "by_hand.yaml").read_text())["robots"][0]["robot"] == name


def _mutate(change):
    data = _base()
    change(data)
    return data


CASES = [
    ("unknown robot", lambda d: d["robots"][0].update(robot="r2d2"), ["robots[0] 'arm'", "unknown robot 'r2d2'", "bundled robots:"]),
    ("missing robot file", lambda d: d["robots"][0].update(robot="nope/arm.urdf"), ["robots[0] 'arm'", "not found"]),
    ("unknown joint", lambda d: d["robots"][0]["joints"].update(elbow=0.1), ["robots[0] 'arm'.joints", "'elbow'", "joint1, joint2"]),
    ("joint outside limits", lambda d: d["robots"][0]["joints"].update(joint2=3.0), ["robots[0] 'arm'.joints.joint2", "limits"]),
    ("missing mesh", lambda d: d["obstacles"][1]["shape"].update(file="gone.stl"), ["obstacles[1] 'shelf'", "gone.stl", "not found"]),
    ("pose wrong length", lambda d: d["obstacles"][0]["pose"].update(position=[1, 2]), ["obstacles[0] 'table'", "position", "3 numbers"]),
    ("rpy wrong length", lambda d: d["objects"][0].update(pose={"rpy": [0, 0]}), ["objects[0] 'ball'", "rpy", "3 numbers"]),
    ("not a rotation", lambda d: d["obstacles"][1]["pose"].update(quaternion=[1, 1, 0, 0]), ["obstacles[1] 'shelf'", "not a rotation"]),
    ("rpy and quaternion", lambda d: d["obstacles"][1]["pose"].update(rpy=[0, 0, 0]), ["obstacles[1] 'shelf'", "either 'rpy' or 'quaternion'"]),
    ("nan pose", lambda d: d["objects"][0]["pose"].update(position=[0, float("nan"), 0]), ["objects[0] 'ball'", "finite"]),
    ("nan size", lambda d: d["obstacles"][0]["shapes"][0].update(size=[1, float("nan"), 1]), ["obstacles[0] 'table'.shapes[0]", "finite"]),
    ("negative radius", lambda d: d["objects"][0]["shape"].update(radius=-0.1), ["objects[0] 'ball'.shape", "radius", "positive"]),
    ("zero length", lambda d: d["obstacles"][0]["shapes"][1].update(length=0), ["obstacles[0] 'table'.shapes[1]", "length", "positive"]),
    ("negative capsule", lambda d: d["objects"][1]["shape"].update(length=-0.1), ["objects[1] 'pill'.shape", "length", ">= 0"]),
    ("zero mesh scale", lambda d: d["obstacles"][1]["shape"].update(scale=[1.0, 0.0, 1.0]),
     ["obstacles[1] 'shelf'.shape (mesh).scale", "every factor must be non-zero", "[1.0, 0.0, 1.0]"]),
    ("zero mesh scale number", lambda d: d["obstacles"][1]["shape"].update(scale=0),
     ["'shelf'.shape (mesh).scale", "non-zero"]),
    ("unknown shape type", lambda d: d["objects"][0]["shape"].update(type="cone"), ["objects[0] 'ball'", "unknown shape type 'cone'", "box, sphere, cylinder, capsule, mesh"]),
    ("typo in body key", lambda d: d["objects"][0].update(shpe={}), ["objects[0] 'ball'", "unknown key 'shpe'", "did you mean 'shape'", "valid keys"]),
    ("typo in shape key", lambda d: d["objects"][0]["shape"].update(raduis=1), ["objects[0] 'ball'.shape", "unknown key 'raduis'", "radius"]),
    ("typo in scene key", lambda d: d.update(obstacle=[]), ["unknown key 'obstacle'", "did you mean 'obstacles'"]),
    ("typo in pose key", lambda d: d["objects"][0]["pose"].update(postion=[0, 0, 0]), ["objects[0] 'ball': pose", "'postion'", "position"]),
    ("duplicate body name", lambda d: d["objects"][1].update(name="ball"), ["'ball' is used twice"]),
    ("shape and shapes", lambda d: d["objects"][0].update(shapes=[]), ["objects[0] 'ball'", "exactly one of 'shape'"]),
    ("string size", lambda d: d["obstacles"][0]["shapes"][0].update(size="big"), ["obstacles[0] 'table'", "list of 3 numbers"]),
    ("bad version", lambda d: d.update(version=7), ["version", "unsupported"]),
    ("held obstacle", lambda d: d["obstacles"][0].update(held_by={"robot": "arm", "link": "link2"}),
     ["obstacles[0] 'table'.held_by", "an obstacle cannot be held", "'objects'"]),
    ("unknown holder", lambda d: d["objects"][0].update(held_by={"robot": "r2", "link": "link2"}),
     ["objects[0] 'ball'.held_by.robot", "no robot 'r2'", "robots: arm"]),
    ("unknown holding link", lambda d: d["objects"][0].update(held_by={"robot": "arm", "link": "hand"}),
     ["objects[0] 'ball'.held_by.link", "no link 'hand'", "links: base_link, link1, link2, tool"]),
    ("unknown touch link", lambda d: d["objects"][0].update(held_by={"robot": "arm", "link": "tool",
                                                                     "touch_links": ["link2", "finger"]}),
     ["'ball'.held_by.touch_links[1]", "no link 'finger'"]),
    ("touch links not a list", lambda d: d["objects"][0].update(held_by={"robot": "arm", "link": "tool",
                                                                         "touch_links": "link2"}),
     ["'ball'.held_by.touch_links", "expected a list of link names"]),
    ("touch links false", lambda d: d["objects"][0].update(held_by={"robot": "arm", "link": "tool",
                                                                    "touch_links": False}),
     ["'ball'.held_by.touch_links", "expected a list of link names"]),
    ("holder not a name", lambda d: d["objects"][0].update(held_by={"robot": ["arm"], "link": "tool"}),
     ["'ball'.held_by.robot", "no robot ['arm']", "robots: arm"]),
    ("typo in held_by", lambda d: d["objects"][0].update(held_by={"robot": "arm", "lnk": "tool"}),
     ["'ball'.held_by", "unknown key 'lnk'", "did you mean 'link'"]),
]


@pytest.mark.parametrize("change, fragments", [(c, f) for _, c, f in CASES], ids=[n for n, _, _ in CASES])
def test_validation_errors_name_file_and_entry(tmp_path, change, fragments):
    path = _write(tmp_path, _mutate(change), "bad_scene.yaml")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    assert "bad_scene.yaml" in message
    for fragment in fragments:
        assert fragment in message


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(SceneError, match="scene file not found"):
        load_scene(tmp_path / "none.yaml")
    broken = tmp_path / "broken.yaml"
    broken.write_text("robots: [unclosed\n")
    with pytest.raises(SceneError, match="broken.yaml: not valid YAML") as error:
        load_scene(broken)
    assert f'in "{broken}", line 2' in str(error.value)  # yaml's own position names the file too
    assert load_scene(_write(tmp_path, {}, "empty.yaml")).bodies == ()
    moveit = tmp_path / "moveit.yaml"
    moveit.write_text("name: scene\nworld: {collision_objects: []}\n")
    with pytest.raises(SceneError, match="moveit.yaml: a MoveIt PlanningScene, not a prehensile scene file"):
        load_scene(moveit)
    (tmp_path / "garbage.stl").write_text("not a mesh")
    scene = {"obstacles": [{"name": "g", "shape": {"type": "mesh", "file": "garbage.stl"}}]}
    with pytest.raises(SceneError, match=r"scene.yaml: obstacles\[0\] 'g'.shape \(mesh\).file: mesh .*garbage.stl"):
        load_scene(_write(tmp_path, scene))


def test_test_data_scenes_check_free_and_colliding():
    free = check_scene(load_scene(DATA / "free.yaml"))
    assert free.free and free.colliding_links == {}
    colliding = check_scene(load_scene(DATA / "colliding.yaml"))
    assert not colliding.free
    assert colliding.colliding_links == {"arm": ("link2",)}
    assert colliding.colliding_bodies() == ("post",)


def test_bundled_demo_scene_has_colliding_and_free_robots():
    scene = load_scene(bundled_scene_path("demo"))
    assert [r.name for r in scene.robots] == ["panda", "nao", "armar3"]
    result = check_scene(scene)
    links = result.colliding_links
    assert set(links) == {"panda"} and "panda_hand" in links["panda"]
    assert "shelf" in result.colliding_bodies()
    assert {r.robot for r in result.robots if r.free} == {"nao", "armar3"}


def test_robot_robot_contacts_are_reported(tmp_path):
    data = {"robots": [{"name": "a", "robot": "two_link.urdf"},
                       {"name": "b", "robot": "two_link.urdf", "pose": {"position": [0.05, 0, 0]}}]}
    result = check_scene(load_scene(_write(tmp_path, data)))
    others = {c.other for r in result.robots for c in r.contacts}
    assert "b/base_link" in others and "a/base_link" in others


def _held_ball(position, touch_links=()) -> dict:
    """The base scene with its ball held by the arm's tool frame, the ball at ``position`` (world, m)."""
    hold = {"robot": "arm", "link": "tool", **({"touch_links": list(touch_links)} if touch_links else {})}
    return _mutate(lambda d: d["objects"][0].update(pose={"position": position}, held_by=hold))


def _link_position(scene: Scene, link: str) -> np.ndarray:
    robot = scene.robots[0]
    return robot.link_poses()[robot.model.link_index(link)][:3, 3]


def test_a_held_object_round_trips_and_moves_with_its_link(tmp_path):
    plain = load_scene(_write(tmp_path, _base()))
    tip = _link_position(plain, "tool") + [0.0, 0.0, 0.05]
    scene = load_scene(_write(tmp_path, _held_ball(tip.tolist(), ["link2"])))
    assert scene.objects[0].held_by == Hold("arm", "tool", ("link2",)) and scene.objects[1].held_by is None
    (ball,) = scene.attached_objects("arm")
    assert ball.name == "ball" and ball.link == "tool" and ball.touch_links == ("link2",)
    robot = scene.robots[0]
    T_world_tool = robot.link_poses()[robot.model.link_index("tool")]
    np.testing.assert_allclose(T_world_tool @ ball.T_link_object, scene.objects[0].T_world_body, atol=1e-12)
    assert len(scene.collision_obstacles()) == 5 and len(scene.collision_obstacles("arm")) == 4
    assert len(scene.collision_obstacles("another robot")) == 5
    save_scene(scene, tmp_path / "copy.yaml")
    again = load_scene(tmp_path / "copy.yaml")
    assert again.objects[0].held_by == scene.objects[0].held_by
    np.testing.assert_allclose(again.attached_objects("arm")[0].T_link_object, ball.T_link_object, atol=1e-12)
    bare = load_scene(_write(tmp_path, _held_ball(tip.tolist())))  # no touch links: none written
    save_scene(bare, tmp_path / "bare.yaml")
    assert yaml.safe_load((tmp_path / "bare.yaml").read_text())["objects"][0]["held_by"] == {"robot": "arm",
                                                                                            "link": "tool"}


def test_a_mimic_joint_value_must_follow_its_leader(tmp_path):
    """As in MoveIt requests: a mimic joint's value is accepted when its leader's implies it."""
    pytest.importorskip("prehensile.robots")
    fingers = {"panda_finger_joint1": 0.03, "panda_finger_joint2": 0.03}
    scene = load_scene(_write(tmp_path, {"robots": [{"robot": "panda", "joints": fingers}]}))
    model = scene.robots[0].model
    assert scene.robots[0].configuration[model.joint_index("panda_finger_joint1")] == 0.03
    apart = {"robots": [{"robot": "panda", "joints": {**fingers, "panda_finger_joint2": 0.02}}]}
    with pytest.raises(SceneError, match=r"robots\[0\].joints: mimic joint 'panda_finger_joint2' = 0.02 "
                                         r"disagrees with the joint it follows: 1 \* panda_finger_joint1 \+ 0 = 0.03"):
        load_scene(_write(tmp_path, apart))
    with pytest.raises(SceneError, match=r"joints.panda_finger_joint2: expected a number"):
        load_scene(_write(tmp_path, {"robots": [{"robot": "panda", "joints": {"panda_finger_joint2": "open"}}]}))


def test_a_scene_refuses_holds_it_cannot_keep():
    ball = Body("ball", (Geometry(Sphere(0.04)),), held_by=Hold("arm", "tool"))
    arm = load_scene(DATA / "free.yaml").robots[0]
    with pytest.raises(SceneError, match="obstacle 'ball' is held by 'arm'; only objects can be held"):
        Scene(robots=(arm,), obstacles=(ball,))
    with pytest.raises(SceneError, match=r"object 'ball'.held_by.robot: no robot 'arm' in the scene; robots: \(none\)"):
        Scene(objects=(ball,))
    with pytest.raises(SceneError, match=r"object 'ball'.held_by.link: robot 'arm' has no link 'hand'"):
        Scene(robots=(arm,), objects=(dataclasses.replace(ball, held_by=Hold("arm", "hand")),))
    assert Scene(robots=(arm,), objects=(ball,)).attached_objects("arm")[0].link == "tool"


def test_check_treats_a_held_object_as_part_of_its_robot(tmp_path):
    """The ball held by the tool may overlap the links fixed to the tool (link2) and its touch
    links; elsewhere it collides like a link: with the world, and with the robot's other links
    (self contacts)."""
    elbow = _link_position(load_scene(_write(tmp_path, _base())), "link2")  # a 4 cm ball there meets link1's top
    for method in ("exact", "spheres"):
        for touch, free in (((), False), (("link1",), True)):
            held = load_scene(_write(tmp_path, _held_ball(elbow.tolist(), touch)))
            (robot,) = check_scene(held, method).robots
            assert robot.free == free, (method, touch, robot.contacts)
            if not free:
                assert {(c.link, c.other, c.kind) for c in robot.contacts} == {("link1", "attached/ball", "self")}
    in_the_table = load_scene(_write(tmp_path, _held_ball([1.0, 0.0, 0.4], ["link2"])))
    (robot,) = check_scene(in_the_table).robots
    assert {(c.link, c.other, c.kind) for c in robot.contacts} == {("attached/ball", "table", "world")}
    assert robot.contacts[0].depth > 0.03


def test_an_obstacle_named_like_a_link_is_a_world_contact(tmp_path):
    scene = yaml.safe_load((DATA / "colliding.yaml").read_text())
    scene["obstacles"][0]["name"] = "link2"  # the arm's own link name
    (robot,) = check_scene(load_scene(_write(tmp_path, scene))).robots
    assert [(c.link, c.other, c.kind) for c in robot.contacts] == [("link2", "link2", "world")]


def test_the_documented_example_scene_loads_and_is_free(tmp_path):
    import re

    text = (Path(__file__).parents[1] / "docs" / "scenes.md").read_text()
    example = tmp_path / "example.yaml"
    example.write_text(re.search(r"```yaml\n(.*?)```", text, re.S).group(1))
    assert check_scene(load_scene(example)).free


def test_unknown_check_method():
    with pytest.raises(SceneError, match="valid: exact, spheres"):
        check_scene(load_scene(DATA / "free.yaml"), "voxels")


@pytest.mark.parametrize("height, free", [(0.741, True), (0.70, False)])
def test_spheres_judge_a_base_on_a_table_by_its_geometry(tmp_path, height, free):
    """The base's balls reach 5 cm below it: a base 1 mm above the table top is free, one
    sunk 4 cm into it collides (and the contact names the base)."""
    pose = {"panda_joint1": -0.9, "panda_joint2": 0.2, "panda_joint4": -2.0, "panda_joint6": 2.2,
            "panda_joint7": 0.785, "panda_finger_joint1": 0.02}
    scene = {"robots": [{"robot": "panda", "pose": {"position": [0.0, 0.0, height]}, "joints": pose}],
             "obstacles": [{"name": "table", "pose": {"position": [0.3, 0.0, 0.72]},
                            "shape": {"type": "box", "size": [1.0, 0.8, 0.04]}}]}
    (robot,) = check_scene(load_scene(_write(tmp_path, scene)), "spheres").robots
    assert robot.free == free
    assert free or ("panda_link0", "world") in [(c.link, c.other) for c in robot.contacts]


def test_exponents_without_a_decimal_point_are_numbers(tmp_path):
    """``1e-05`` (as Python and JSON write small numbers) is a string to YAML 1.1's resolver."""
    path = tmp_path / "tiny.yaml"
    path.write_text("obstacles:\n  - {name: chip, pose: {position: [0.5, 0, 1e-05]},\n"
                    "     shape: {type: box, size: [1e-2, 2E-2, 0.5]}}\n")
    (chip,) = load_scene(path).obstacles
    assert chip.T_world_body[2, 3] == 1e-05 and chip.geometries[0].shape.size == (0.01, 0.02, 0.5)


def test_a_capsule_of_length_zero_is_a_ball(tmp_path):
    data = {"objects": [{"name": "pill", "shape": {"type": "capsule", "radius": 0.02, "length": 0}}]}
    (pill,) = load_scene(_write(tmp_path, data)).objects
    assert pill.geometries[0].shape == Capsule(0.02, 0.0)


def test_a_scene_is_drawn_in_the_format_its_file_name_asks_for(tmp_path):
    from prehensile.viz import render_scene

    colliding = check_scene(load_scene(DATA / "colliding.yaml"))
    scene = load_scene(DATA / "colliding.yaml")
    png = render_scene(scene, tmp_path / "out" / "scene.png", colliding_links=colliding.colliding_links,
                       title="a post through link2")
    svg = render_scene(scene, tmp_path / "scene.svg", views=((30.0, 45.0),))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and b"<svg" in svg.read_bytes()[:1000]
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["out", "scene.png", "scene.svg"]


def test_copies_of_a_robot_draw_their_still_links_once_in_the_colours_given():
    from matplotlib.colors import to_rgb

    from prehensile import robots
    from prehensile.viz import scene_triangles

    model = robots.load("panda")
    q = model.neutral_configuration()
    bent = q.copy()
    bent[model.joint_index("panda_joint7")] += 0.5  # moves panda_link7 and everything below it
    alone = scene_triangles(Scene(robots=(PlacedRobot("a", model, q=q),)))[0]
    copies = Scene(robots=(PlacedRobot("a", model, q=q), PlacedRobot("b", model, q=bent)))
    triangles, rgba, _ = scene_triangles(copies, robot_colors={"a": "#0000ff", "b": "#ff0000"})
    assert len(alone) < len(triangles) < 2 * len(alone)  # the copy adds only the links joint 7 moves
    hue = rgba[:, :3] / rgba[:, :3].max(axis=1, keepdims=True)  # shading scales the colour
    blue, red = np.all(np.isclose(hue, to_rgb("#0000ff")), axis=1), np.all(np.isclose(hue, to_rgb("#ff0000")), axis=1)
    assert blue.sum() == len(alone) and red.sum() == len(triangles) - len(alone)
