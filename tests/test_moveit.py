"""MoveIt PlanningScene / MotionPlanRequest import, on MotionBenchMaker problems and by hand."""

from __future__ import annotations

import logging
import tarfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from conftest import SHARED
from prehensile.errors import SceneError
from prehensile.model import load_urdf
from prehensile.model.geometry import Box, Cylinder, Sphere
from prehensile.scene import iter_mbm_problems, load_motion_plan_request, load_moveit_scene, load_scene, save_scene
from prehensile.scene.moveit import motion_plan_request_from_dict, moveit_scene_from_dict
from prehensile.spatial import make_pose

MBM = SHARED / "bench" / "mbm" / "panda"
TARBALL = MBM / "problems.tar.bz2"
needs_mbm = pytest.mark.skipif(not TARBALL.is_file(), reason=f"MBM problems not found at {TARBALL}")


def _member_yaml(name: str) -> dict:
    with tarfile.open(TARBALL) as archive:
        return yaml.safe_load(archive.extractfile(name).read())


def _expected_pose(pose: dict) -> np.ndarray:
    """World pose from a MoveIt pose with scipy's (x, y, z, w) quaternion convention."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(pose["orientation"]).as_matrix()
    T[:3, 3] = pose["position"]
    return T


@pytest.fixture(scope="module")
def problems():
    if not TARBALL.is_file():
        pytest.skip(f"MBM problems not found at {TARBALL}")
    return list(iter_mbm_problems(TARBALL))


@needs_mbm
def test_all_400_problems_parse(problems):
    assert len(problems) == 400
    scenarios = {p.scenario for p in problems}
    assert scenarios == {"table_pick_panda", "box_panda", "bookshelf_small_panda", "cage_panda"}
    for scenario in scenarios:
        assert sorted(p.index for p in problems if p.scenario == scenario) == list(range(1, 101))
    for scenario, index, scene, request in problems:
        assert scene.obstacles and request.group == "panda_arm"
        assert len(request.goal) == 7 and "panda_finger_joint1" in request.start
    first = list(iter_mbm_problems(TARBALL, per_scenario=2))
    assert [(p.scenario, p.index) for p in first] == [(p.scenario, p.index) for p in problems if p.index <= 2]


@needs_mbm
def test_known_box_has_size_and_pose_from_the_file(problems):
    raw = _member_yaml("problems/table_pick_panda/scene0001.yaml")
    entry = next(o for o in raw["world"]["collision_objects"] if o["id"] == "table_top")
    scene = next(p.scene for p in problems if p.scenario == "table_pick_panda" and p.index == 1)
    body = next(b for b in scene.obstacles if b.name == "table_top")
    ((geometry, T_world_geom),) = body.world_geometries()
    assert isinstance(geometry.shape, Box)
    np.testing.assert_allclose(geometry.shape.size, entry["primitives"][0]["dimensions"])
    np.testing.assert_allclose(T_world_geom, _expected_pose(entry["primitive_poses"][0]), atol=1e-12)


@needs_mbm
def test_cylinders_keep_height_radius_order(problems):
    raw = _member_yaml("problems/table_pick_panda/scene0001.yaml")
    scene = next(p.scene for p in problems if p.scenario == "table_pick_panda" and p.index == 1)
    bodies = {b.name: b for b in scene.obstacles}
    checked = 0
    for entry in raw["world"]["collision_objects"]:
        if entry["primitives"][0]["type"] == "cylinder":
            height, radius = entry["primitives"][0]["dimensions"]
            shape = bodies[entry["id"]].geometries[0].shape
            assert isinstance(shape, Cylinder) and shape.length == height and shape.radius == radius
            checked += 1
    assert checked >= 2  # Can1 is [0.12, 0.03]: 12 cm tall, 3 cm radius


@needs_mbm
def test_request_start_and_goal_configurations():
    with tarfile.open(TARBALL) as archive:
        raw = yaml.safe_load(archive.extractfile("problems/box_panda/request0007.yaml").read())
    problem = next(p for p in iter_mbm_problems(TARBALL) if p.scenario == "box_panda" and p.index == 7)
    group, start, goal = problem.request
    assert group == raw["group_name"]
    assert list(start.values()) == raw["start_state"]["joint_state"]["position"]
    assert goal == {c["joint_name"]: c["position"] for c in raw["goal_constraints"][0]["joint_constraints"]}
    model = load_urdf(MBM / "panda.urdf")
    q_goal = problem.request.goal_configuration(model)
    assert q_goal[model.joint_index("panda_joint3")] == goal["panda_joint3"]
    if "panda_finger_joint1" in model.joint_names:
        assert q_goal[model.joint_index("panda_finger_joint1")] == start["panda_finger_joint1"]


@needs_mbm
def test_folder_and_single_files_with_robot(tmp_path):
    with tarfile.open(TARBALL) as archive:
        for name in ("scene0003.yaml", "request0003.yaml"):
            member = archive.getmember(f"problems/cage_panda/{name}")
            (tmp_path / "cage_panda").mkdir(exist_ok=True)
            (tmp_path / "cage_panda" / name).write_bytes(archive.extractfile(member).read())
    ((scenario, index, scene, request),) = list(iter_mbm_problems(tmp_path))
    assert (scenario, index) == ("cage_panda", 3)
    model = load_urdf(MBM / "panda.urdf")
    single = load_moveit_scene(tmp_path / "cage_panda" / "scene0003.yaml", robot=model)
    assert len(single.obstacles) == len(scene.obstacles)
    (robot,) = single.robots
    assert robot.model is model and robot.configuration.shape == (model.dof,)
    assert model.within_limits(robot.configuration)  # MBM's robot_state holds panda_joint4 = 0: clipped
    save_scene(single, tmp_path / "saved.yaml")
    assert len(load_scene(tmp_path / "saved.yaml").obstacles) == len(scene.obstacles)
    single_request = load_motion_plan_request(tmp_path / "cage_panda" / "request0003.yaml")
    assert tuple(single_request) == tuple(request) and single_request.source == request.source


def test_scenario_folders_sharing_a_name_stay_apart_and_archives_name_their_top(tmp_path):
    scene = {"name": "s", "world": {"collision_objects": []}}
    request = {"group_name": "arm", "goal_constraints": [{"joint_constraints": [{"joint_name": "j", "position": 0}]}]}
    for folder in ("a/x", "b/x", "y"):
        (tmp_path / "set" / folder).mkdir(parents=True)
        for index in (1, 2):
            (tmp_path / "set" / folder / f"scene{index:04d}.yaml").write_text(yaml.safe_dump(scene))
            (tmp_path / "set" / folder / f"request{index:04d}.yaml").write_text(yaml.safe_dump(request))
    found = [(p.scenario, p.index) for p in iter_mbm_problems(tmp_path / "set")]
    assert found == [("a/x", 1), ("a/x", 2), ("b/x", 1), ("b/x", 2), ("y", 1), ("y", 2)]
    (tmp_path / "set" / "b" / "x" / "scene0002.yaml").unlink()  # not paired with a/x's scene
    with pytest.raises(SceneError, match="b/x problem 0002 has no scene file"):
        list(iter_mbm_problems(tmp_path / "set"))
    with tarfile.open(tmp_path / "y.tar.bz2", "w:bz2") as archive:  # files at the archive's top
        for name in ("scene0001.yaml", "request0001.yaml"):
            archive.add(tmp_path / "set" / "y" / name, arcname=name)
    assert [(p.scenario, p.index) for p in iter_mbm_problems(tmp_path / "y.tar.bz2")] == [("y", 1)]


def test_a_start_given_as_a_diff_changes_the_scenes_robot_state(tmp_path):
    scene = {"name": "s", "robot_state": {"joint_state": {"name": ["j1", "j2", "j3"], "position": [0.1, 0.2, 0.3]}},
             "world": {"collision_objects": []}}
    goal = [{"joint_constraints": [{"joint_name": "j1", "position": 0.5}]}]
    folder = tmp_path / "set" / "x"
    folder.mkdir(parents=True)
    for index, start in ((1, {"is_diff": True, "joint_state": {"name": ["j2"], "position": [0.7]}}),
                         (2, {"joint_state": {"name": ["j2"], "position": [0.7]}})):
        (folder / f"scene{index:04d}.yaml").write_text(yaml.safe_dump(scene))
        request = {"start_state": start, "goal_constraints": goal}
        (folder / f"request{index:04d}.yaml").write_text(yaml.safe_dump(request))
    diff, whole = (p.request for p in iter_mbm_problems(tmp_path / "set"))
    assert diff.start_is_diff and dict(diff.start) == {"j1": 0.1, "j2": 0.7, "j3": 0.3}
    assert not whole.start_is_diff and dict(whole.start) == {"j2": 0.7}
    with pytest.raises(SceneError, match=r"r.yaml: start_state.is_diff: expected true or false, got 'yes'"):
        motion_plan_request_from_dict({"start_state": {"is_diff": "yes"}, "goal_constraints": goal}, "r.yaml")


def _one_problem(folder: Path) -> None:
    folder.mkdir(parents=True)
    (folder / "scene0001.yaml").write_text(yaml.safe_dump({"name": "s", "world": {"collision_objects": []}}))
    (folder / "request0001.yaml").write_text(yaml.safe_dump(
        {"group_name": "arm", "goal_constraints": [{"joint_constraints": [{"joint_name": "j", "position": 0}]}]}))


def test_archives_skip_other_files_and_name_bad_text_and_damage(tmp_path):
    _one_problem(tmp_path / "set" / "x")
    (tmp_path / "set" / "x" / "picture.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)))
    with tarfile.open(tmp_path / "set.tar.bz2", "w:bz2") as archive:
        archive.add(tmp_path / "set" / "x", arcname="x")
    assert [(p.scenario, p.index) for p in iter_mbm_problems(tmp_path / "set.tar.bz2")] == [("x", 1)]
    data = (tmp_path / "set.tar.bz2").read_bytes()
    (tmp_path / "cut.tar.bz2").write_bytes(data[:len(data) // 2])
    with pytest.raises(SceneError, match="cut.tar.bz2: (damaged or truncated archive|not a folder or a tar archive)"):
        list(iter_mbm_problems(tmp_path / "cut.tar.bz2"))
    (tmp_path / "set" / "x" / "scene0001.yaml").write_bytes("name: sc\xe8ne\n".encode("latin-1"))
    with pytest.raises(SceneError, match="scene0001.yaml: not UTF-8 text"):
        list(iter_mbm_problems(tmp_path / "set"))
    with tarfile.open(tmp_path / "latin.tar.bz2", "w:bz2") as archive:
        archive.add(tmp_path / "set" / "x", arcname="x")
    with pytest.raises(SceneError, match="latin.tar.bz2:x/scene0001.yaml: not UTF-8 text"):
        list(iter_mbm_problems(tmp_path / "latin.tar.bz2"))


def test_objects_may_sit_in_the_robots_root_frame():
    """MoveIt scenes often give poses in the robot's root link, placed by robot_state's virtual joint."""
    from prehensile import robots

    model = robots.load("panda")
    placed = {"transforms": [{"translation": [1.0, 2.0, 0.5], "rotation": [0, 0, 0, 1]}]}
    base = {"joint_state": {"name": [], "position": []}, "multi_dof_joint_state": placed}
    obj = {"id": "x", "header": {"frame_id": model.link_names[0]}, "primitive_poses": [{"position": [0.1, 0, 0]}],
           "primitives": [{"type": "box", "dimensions": [1, 1, 1]}]}
    scene = moveit_scene_from_dict({"robot_state": base, "world": {"collision_objects": [obj]}}, "s.yaml", model)
    body = scene.obstacles[0]
    np.testing.assert_allclose((body.T_world_body @ body.geometries[0].T_link_geom)[:3, 3], [1.1, 2.0, 0.5])
    with pytest.raises(SceneError, match=f"frame '{model.link_names[0]}' is not supported"):
        moveit_scene_from_dict({"world": {"collision_objects": [obj]}}, "s.yaml")  # no robot: no root frame
    in_the_hand = {**obj, "header": {"frame_id": "panda_hand"}}  # placed where the state puts the hand
    scene = moveit_scene_from_dict({"robot_state": base, "world": {"collision_objects": [in_the_hand]}}, "s.yaml",
                                   model)
    T_world_hand = scene.robots[0].link_poses()[model.link_index("panda_hand")]
    np.testing.assert_allclose(scene.obstacles[0].T_world_body, T_world_hand, atol=1e-12)
    with pytest.raises(SceneError, match="frame 'panda_hand' is not supported; valid: world$"):
        moveit_scene_from_dict({"world": {"collision_objects": [in_the_hand]}}, "s.yaml")  # no robot


def _attached(link: str = "panda_hand", frame: str = "", touch=("panda_leftfinger", "panda_rightfinger")) -> dict:
    """A robot state holding a 20 cm rod 10 cm below ``link`` (in ``frame``; '' is the link's)."""
    rod = {"id": "rod", "header": {"frame_id": frame}, "primitives": [{"type": "box", "dimensions": [0.02, 0.02, 0.2]}],
           "primitive_poses": [{"position": [0, 0, 0.1], "orientation": [0, 0, 0, 1]}]}
    return {"joint_state": {"name": ["panda_joint4"], "position": [-1.5]}, "multi_dof_joint_state": {
        "transforms": [{"translation": [0.5, 0.0, 0.0], "rotation": [0, 0, 0, 1]}]},
        "attached_collision_objects": [{"link_name": link, "object": rod, "touch_links": list(touch)}]}


@needs_mbm
def test_attached_collision_objects_are_held_by_their_link(caplog):
    from prehensile import robots
    from prehensile.scene import Hold

    model = robots.load("panda")
    for frame in ("", "panda_hand", "world"):
        scene = moveit_scene_from_dict({"robot_state": _attached(frame=frame)}, "s.yaml", model)
        (rod,) = scene.objects
        assert rod.name == "rod" and not scene.obstacles
        assert rod.held_by == Hold("panda", "panda_hand", ("panda_leftfinger", "panda_rightfinger"))
        (attached,) = scene.attached_objects("panda")
        if frame != "world":  # in the hand's frame: 10 cm along its z-axis
            np.testing.assert_allclose(attached.T_link_object @ attached.geometries()[0].T_link_geom,
                                       make_pose(position=[0.0, 0.0, 0.1]), atol=1e-12)
        else:  # given in the world frame: the rod stands at the origin, wherever the hand is
            robot = scene.robots[0]
            T_world_hand = robot.link_poses()[model.link_index("panda_hand")]
            np.testing.assert_allclose(T_world_hand @ attached.T_link_object, np.eye(4), atol=1e-12)
        assert not scene.collision_obstacles("panda") and len(scene.collision_obstacles()) == 1
    with pytest.raises(SceneError, match=r"attached_collision_objects\[0\].link_name: robot 'panda' has no link 'paw'"):
        moveit_scene_from_dict({"robot_state": _attached(link="paw")}, "s.yaml", model)
    with pytest.raises(SceneError, match=r"\[0\].touch_links\[1\]: robot 'panda' has no link 'thumb'"):
        moveit_scene_from_dict({"robot_state": _attached(touch=("panda_hand", "thumb"))}, "s.yaml", model)
    with caplog.at_level(logging.WARNING):
        assert not moveit_scene_from_dict({"robot_state": _attached()}, "s.yaml").objects  # no robot to hold it
    assert "attached_collision_objects skipped" in caplog.text


@needs_mbm
def test_an_object_attached_beyond_a_joint_limit_keeps_its_grip():
    """MBM-like states hold panda_joint4 = 0, beyond its limit: the robot is clipped into the
    limits, the object keeps its pose in the hand frame that the state as given defines."""
    from prehensile import robots
    from prehensile.kinematics import link_pose

    model = robots.load("panda")
    state = _attached(frame="world")
    state["joint_state"]["position"] = [0.0]  # panda_joint4, limits [-3.07, -0.07]
    scene = moveit_scene_from_dict({"robot_state": state}, "s.yaml", model)
    (rod,) = scene.attached_objects("panda")
    q_given = model.neutral_configuration()
    q_given[model.joint_index("panda_joint4")] = 0.0
    T_hand_world = np.linalg.inv(link_pose(model, q_given, "panda_hand", T_world_base=scene.robots[0].T_world_base))
    np.testing.assert_allclose(rod.T_link_object, T_hand_world, atol=1e-12)  # the rod's frame is the world's origin
    assert scene.robots[0].configuration[model.joint_index("panda_joint4")] == pytest.approx(-0.0698, abs=1e-4)


def _with(change) -> dict:
    state = _attached()
    change(state["attached_collision_objects"])
    return {"robot_state": state, "world": {"collision_objects": [{
        "id": "table", "primitives": [{"type": "box", "dimensions": [1, 1, 0.1]}], "primitive_poses": [{}]}]}}


@needs_mbm
@pytest.mark.parametrize("data, fragment", [
    (_with(lambda a: a.append(dict(a[0]))), "attached_collision_objects[1] 'rod': the object id is used twice"),
    (_with(lambda a: a[0]["object"].update(id="table")), "[0] 'table': the object id is used twice"),
    (_with(lambda a: a[0].update(touch_links="panda_leftfinger")), "[0].touch_links: expected a list of link names"),
    (_with(lambda a: a[0].pop("link_name")), "[0]: missing 'link_name'"),
    (_with(lambda a: a[0]["object"].pop("id")), "[0].object: missing 'id'"),
    ({"robot_state": {"attached_collision_objects": {"link_name": "panda_hand"}}},
     "attached_collision_objects: expected a list, got dict"),
])
def test_bad_attached_collision_objects(data, fragment):
    from prehensile import robots

    with pytest.raises(SceneError) as info:
        moveit_scene_from_dict(data, "bad.yaml", robots.load("panda"))
    message = str(info.value)
    assert message.startswith("bad.yaml: robot_state.attached_collision_objects") and fragment in message


def test_a_request_with_attached_objects_is_refused():
    start = {"joint_state": {"name": ["j"], "position": [0.0]}, "attached_collision_objects": [{"link_name": "hand"}]}
    request = {"start_state": start, "goal_constraints": [{"joint_constraints": [{"joint_name": "j", "position": 1}]}]}
    with pytest.raises(SceneError, match="r.yaml: start_state.attached_collision_objects: not supported in a request"):
        motion_plan_request_from_dict(request, "r.yaml")


def test_object_pose_composes_with_primitive_poses():
    data = {"world": {"collision_objects": [{
        "id": "crate",
        "pose": {"position": [1.0, 0.0, 0.0], "orientation": [0, 0, 0.7071067811865476, 0.7071067811865476]},
        "primitives": [{"type": "box", "dimensions": [0.1, 0.2, 0.3]}, {"type": 2, "dimensions": [0.05]}],
        "primitive_poses": [{"position": [0.5, 0, 0], "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}},
                            {"position": {"x": 0, "y": 0, "z": 1}, "orientation": [0, 0, 0, 1]}],
    }]}}
    scene = moveit_scene_from_dict(data, "inline")
    (box, T_box), (ball, T_ball) = scene.obstacles[0].world_geometries()
    assert isinstance(box.shape, Box) and isinstance(ball.shape, Sphere)
    np.testing.assert_allclose(T_box[:3, 3], [1.0, 0.5, 0.0], atol=1e-12)  # rotated 90 deg about z
    np.testing.assert_allclose(T_ball[:3, 3], [1.0, 0.0, 1.0], atol=1e-12)


def test_cone_becomes_enclosing_cylinder(caplog):
    data = {"world": {"collision_objects": [{
        "id": "cone", "primitives": [{"type": "cone", "dimensions": [0.4, 0.1]}],
        "primitive_poses": [{"position": [0, 0, 0], "orientation": [0, 0, 0, 1]}]}]}}
    with caplog.at_level(logging.WARNING):
        scene = moveit_scene_from_dict(data, "inline")
    assert scene.obstacles[0].geometries[0].shape == Cylinder(radius=0.1, length=0.4)
    assert "enclosing cylinder" in caplog.text


def test_inline_mesh_is_kept():
    data = {"world": {"collision_objects": [{
        "id": "tri",
        "meshes": [{"vertices": [{"x": 0, "y": 0, "z": 0}, [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                    "triangles": [{"vertex_indices": [0, 1, 2]}, [0, 1, 3]]}],
        "mesh_poses": [{"position": [0, 0, 0], "orientation": [0, 0, 0, 1]}]}]}}
    shape = moveit_scene_from_dict(data, "inline").obstacles[0].geometries[0].shape
    assert shape.trimesh.faces.shape == (2, 3)


@pytest.mark.parametrize("obj, fragment", [
    ({"id": "x", "primitives": [{"type": "prism", "dimensions": [1]}], "primitive_poses": [{}]}, "unsupported primitive type"),
    ({"id": "x", "primitives": [{"type": "box", "dimensions": [1, 2]}], "primitive_poses": [{}]}, "needs 3 dimensions"),
    ({"id": "x", "primitives": [{"type": "sphere", "dimensions": [-1]}], "primitive_poses": [{}]}, "must be positive"),
    ({"id": "x", "primitives": [{"type": "box", "dimensions": [1, 1, 1]}], "primitive_poses": []}, "1 primitives but 0"),
    ({"id": "x", "header": {"frame_id": "panda_hand"}, "primitives": [{"type": "box", "dimensions": [1, 1, 1]}],
      "primitive_poses": [{}]}, "frame 'panda_hand' is not supported"),
    ({"id": "x"}, "has no primitives or meshes"),
])
def test_bad_collision_objects(obj, fragment):
    with pytest.raises(SceneError) as info:
        moveit_scene_from_dict({"world": {"collision_objects": [obj]}}, "bad.yaml")
    assert "bad.yaml: world.collision_objects[0] 'x'" in str(info.value) and fragment in str(info.value)


@pytest.mark.parametrize("orientation, rotation", [
    ([0, 0, 0, 0], np.eye(3)),  # the message default
    ([0, 0, 0, 2], np.eye(3)),
    ([0, 0, 2, 0], np.diag([-1.0, -1.0, 1.0])),  # half a turn about z
])
def test_quaternions_are_read_as_moveit_reads_them(orientation, rotation, caplog):
    """MoveIt takes an all-zero quaternion as the identity and normalises the others (warning)."""
    obj = {"id": "x", "primitives": [{"type": "box", "dimensions": [1, 1, 1]}],
           "primitive_poses": [{"orientation": orientation}]}
    body = moveit_scene_from_dict({"world": {"collision_objects": [obj]}}, "q.yaml").obstacles[0]
    np.testing.assert_allclose(body.T_world_body[:3, :3] @ body.geometries[0].T_link_geom[:3, :3], rotation,
                               atol=1e-12)
    assert "world.collision_objects[0] 'x'" in caplog.text and "quaternion" in caplog.text


_GOAL = [{"joint_constraints": [{"joint_name": "j", "position": 1.0}]}]


@pytest.mark.parametrize("request_data, message", [
    ({"goal_constraints": {"joint_constraints": []}}, "r.yaml: goal_constraints: expected a list, got dict"),
    ({"goal_constraints": [{"joint_constraints": {"joint_name": "j"}}]},
     "r.yaml: goal_constraints[0].joint_constraints: expected a list, got dict"),
    ({"start_state": {"joint_state": {"name": ["j"], "position": 5}}, "goal_constraints": _GOAL},
     "r.yaml: start_state.joint_state.position: expected a list, got int"),
    ({"start_state": {"joint_state": {"name": 7, "position": [0.0]}}, "goal_constraints": _GOAL},
     "r.yaml: start_state.joint_state.name: expected a list, got int"),
    ({"goal_constraints": _GOAL, "num_planning_attempts": "two"},
     "r.yaml: num_planning_attempts: expected a whole number >= 1, got 'two'"),
    ({"goal_constraints": [{"joint_constraints": _GOAL[0]["joint_constraints"] * 2}]},
     "r.yaml: goal_constraints[0].joint_constraints[1]: joint 'j' is constrained twice in this goal"),
    ({"start_state": {"joint_state": {"name": ["j", "k", "j"], "position": [0.0, 0.0, 1.0]}},
      "goal_constraints": _GOAL}, "r.yaml: start_state.joint_state.name: j given twice"),
])
def test_wrongly_typed_request_fields_are_named(request_data, message):
    with pytest.raises(SceneError) as info:
        motion_plan_request_from_dict(request_data, "r.yaml")
    assert str(info.value) == message


@pytest.mark.parametrize("scene, message", [
    ({"robot_state": {"multi_dof_joint_state": {"transforms": {"translation": [0, 0, 0]}}}},
     "s.yaml: robot_state.multi_dof_joint_state.transforms: expected a list, got dict"),
    ({"world": {"collision_objects": {"id": "box"}}}, "s.yaml: world.collision_objects: expected a list, got dict"),
    ({"world": {"collision_objects": [{"id": "x", "primitives": {"type": "box"}}]}},
     "s.yaml: world.collision_objects[0] 'x'.primitives: expected a list, got dict"),
])
def test_wrongly_typed_scene_fields_are_named(scene, message):
    from prehensile import robots

    with pytest.raises(SceneError) as info:
        moveit_scene_from_dict(scene, "s.yaml", robots.load("panda"))
    assert str(info.value) == message


_REGION = {"primitives": [{"type": "sphere", "dimensions": [0.01]}],
           "primitive_poses": [{"position": [0.4, 0.1, 0.5], "orientation": [0, 0, 0, 1]}]}


def _orientation(**changes):
    quaternion = Rotation.from_euler("x", 90, degrees=True).as_quat().tolist()  # (x, y, z, w)
    return {"link_name": "hand", "orientation": quaternion, "absolute_x_axis_tolerance": 0.1,
            "absolute_y_axis_tolerance": 0.2, "absolute_z_axis_tolerance": 0.3, **changes}


def test_a_pose_goal_is_read_from_position_and_orientation_constraints():
    position = {"header": {"frame_id": "world"}, "link_name": "hand", "target_point_offset": {"x": 0, "y": 0, "z": 0.1},
                "constraint_region": _REGION}
    request = motion_plan_request_from_dict({"group_name": "arm", "goal_constraints": [
        {"position_constraints": [position], "orientation_constraints": [_orientation(parameterization=1)]}]}, "r.yaml")
    goal = request.pose_goal
    assert request.goal == {} and goal.link == "hand" and goal.frame == ""
    np.testing.assert_allclose(goal.offset, [0, 0, 0.1])
    (shape, T_frame_region), = goal.regions
    assert shape == Sphere(0.01) and T_frame_region[:3, 3].tolist() == [0.4, 0.1, 0.5]
    np.testing.assert_allclose(goal.orientation, Rotation.from_euler("x", 90, degrees=True).as_matrix(), atol=1e-12)
    assert goal.tolerances.tolist() == [0.1, 0.2, 0.3] and goal.rotation_vector
    alone = motion_plan_request_from_dict({"goal_constraints": [{"position_constraints": [position]}]}, "r.yaml")
    assert alone.pose_goal.orientation is None


@pytest.mark.parametrize("constraints, message", [
    ({"position_constraints": [{"link_name": "hand"}]},
     "r.yaml: goal_constraints[0].position_constraints[0].constraint_region: expected primitives and as many "
     "primitive_poses (at least one), got 0 and 0"),
    ({"position_constraints": [{"constraint_region": _REGION}]},
     "r.yaml: goal_constraints[0].position_constraints[0]: missing 'link_name'"),
    ({"orientation_constraints": [_orientation()]},
     "r.yaml: goal_constraints[0]: one position constraint and at most one orientation constraint are supported, "
     "got 0 and 1"),
    ({"position_constraints": [{"link_name": "hand", "constraint_region": {**_REGION, "meshes": [{}]}}]},
     "r.yaml: goal_constraints[0].position_constraints[0].constraint_region.meshes: mesh regions are not supported"),
    ({"position_constraints": [{"link_name": "hand", "constraint_region": {
        "primitives": [{"type": 4, "dimensions": [1, 1]}], "primitive_poses": [{}]}}]},
     "r.yaml: goal_constraints[0].position_constraints[0].constraint_region.primitives[0]: cone regions are not"),
    ({"position_constraints": [{"link_name": "hand", "constraint_region": {
        "primitives": [{"type": "CONE", "dimensions": [1, 1]}], "primitive_poses": [{}]}}]},
     "r.yaml: goal_constraints[0].position_constraints[0].constraint_region.primitives[0]: cone regions are not"),
    ({"position_constraints": [{"link_name": "hand", "constraint_region": {
        "primitives": [{"type": True, "dimensions": [1, 1, 1]}], "primitive_poses": [{}]}}]},
     "r.yaml: goal_constraints[0].position_constraints[0].constraint_region.primitives[0]: unsupported primitive "
     "type True"),
    ({"position_constraints": [{"link_name": "hand", "constraint_region": _REGION}],
      "orientation_constraints": [_orientation(link_name="wrist")]},
     "r.yaml: goal_constraints[0].orientation_constraints[0]: link_name and header.frame_id must be those of the "
     "position constraint ('hand', '')"),
    ({"position_constraints": [{"link_name": "hand", "constraint_region": _REGION}],
      "orientation_constraints": [_orientation(parameterization=2)]},
     "r.yaml: goal_constraints[0].orientation_constraints[0].parameterization: expected 0 (XYZ Euler angles) or 1"),
    ({"position_constraints": [{"link_name": "hand", "constraint_region": _REGION}],
      "orientation_constraints": [_orientation(parameterization=True)]},
     "r.yaml: goal_constraints[0].orientation_constraints[0].parameterization: expected 0 (XYZ Euler angles) or 1"),
    ({"position_constraints": [{"link_name": "hand", "constraint_region": _REGION}],
      "orientation_constraints": [_orientation(absolute_y_axis_tolerance=-0.1)]},
     "r.yaml: goal_constraints[0].orientation_constraints[0]: the axis tolerances must be >= 0"),
    ({"position_constraints": [{"link_name": "hand", "constraint_region": _REGION}],
      "joint_constraints": [{"joint_name": "j", "position": 1.0}]},
     "r.yaml: goal_constraints[0]: joint constraints together with position or orientation constraints are not "
     "supported"),
    ({"joint_constraints": []}, "r.yaml: goal_constraints[0] has no joint_constraints and no position_constraints"),
])
def test_bad_pose_goals_are_named(constraints, message):
    with pytest.raises(SceneError) as info:
        motion_plan_request_from_dict({"group_name": "arm", "goal_constraints": [constraints]}, "r.yaml")
    assert str(info.value).startswith(message), str(info.value)


def _example_goal(rotation_vector: bool = False):
    """(T_world_frame, PoseGoal): the point 0.1 m along a hand's z axis in one of three regions
    (box, sphere, cylinder turned to lie along y) of a frame turned 30 deg about z, the
    orientation within (0.05, 0.1, 0.2) rad of a turn by 20 deg about y."""
    from prehensile.scene.pose_goal import PoseGoal

    T_world_frame = make_pose(Rotation.from_euler("z", 30, degrees=True).as_matrix(), [1.0, 0.0, 0.0])
    regions = ((Box((0.2, 0.1, 0.1)), make_pose(position=[0.5, 0, 0])), (Sphere(0.05), make_pose(position=[0, 1, 0])),
               (Cylinder(radius=0.05, length=0.4), make_pose(Rotation.from_euler("x", 90, degrees=True).as_matrix(),
                                                                 [0, 0, 1])))
    wanted = Rotation.from_euler("y", 20, degrees=True).as_matrix()
    return T_world_frame, PoseGoal("hand", regions, frame="base", offset=np.array([0, 0, 0.1]), orientation=wanted,
                                   tolerances=np.array([0.05, 0.1, 0.2]), rotation_vector=rotation_vector)


def test_a_pose_goal_decides_as_moveit_does():
    """The constrained point in any region (box, sphere, cylinder along z), each angle of
    R_wanted^T R_link within its tolerance (XYZ Euler angles or rotation vector)."""
    from prehensile.scene.pose_goal import PoseGoal
    from prehensile.spatial import invert

    T_world_frame, goal = _example_goal()
    regions, wanted = goal.regions, goal.orientation

    def link_at(point, rotation=np.eye(3)):
        """T_world_link whose offset point is at ``point`` (frame), rotated by ``rotation`` from the wanted one."""
        R = wanted @ rotation
        return T_world_frame @ make_pose(R, np.asarray(point) - R @ goal.offset)

    for point, inside in (([0.59, 0.04, -0.04], True), ([0.61, 0, 0], False), ([0, 1.03, 0.03], True),
                          ([0, 1.04, 0.04], False), ([0.04, 0.19, 1.0], True), ([0, 0.21, 1.0], False),
                          ([0.06, 0, 1.0], False)):
        assert goal.satisfied(T_world_frame, link_at(point)) == inside, point
    target = goal.target(T_world_frame)
    assert goal.satisfied(T_world_frame, target @ invert(goal.T_link_point))
    for angles, ok in (((0.04, 0.09, 0.19), True), ((0.06, 0, 0), False), ((0, 0.11, 0), False),
                       ((0, 0, -0.21), False), ((-0.04, -0.09, -0.19), True)):
        twist = Rotation.from_euler("XYZ", angles).as_matrix()  # intrinsic: Rx(a) Ry(b) Rz(c)
        assert goal.satisfied(T_world_frame, link_at([0.5, 0, 0], twist)) == ok, angles
        np.testing.assert_allclose(goal.angles(T_world_frame, link_at([0.5, 0, 0], twist)), angles, atol=1e-12)
    by_vector = _example_goal(rotation_vector=True)[1]
    vector = np.array([0.0, 0.09, 0.19])
    turned = link_at([0.5, 0, 0], Rotation.from_rotvec(vector).as_matrix())
    assert by_vector.satisfied(T_world_frame, turned)
    np.testing.assert_allclose(by_vector.angles(T_world_frame, turned), vector, atol=1e-12)
    assert not by_vector.satisfied(T_world_frame, link_at([0.5, 0, 0], Rotation.from_rotvec([0.06, 0, 0]).as_matrix()))
    assert PoseGoal("hand", regions).target(T_world_frame).shape == (3,)


@pytest.mark.parametrize("rotation_vector", [False, True])
def test_pose_goal_targets_keep_their_margin(rotation_vector):
    """Random targets (uniform in a region, each as likely; angles within the tolerances) and the
    target closest to a link pose all meet the goal shrunk by the margin; a pose that meets
    the shrunk goal is its own closest target."""
    import dataclasses

    from prehensile.spatial import invert

    T_world_frame, goal = _example_goal(rotation_vector)
    margin = (0.01, 0.02)
    (box, T_box), (sphere, T_sphere), (cylinder, T_cylinder) = goal.regions
    shrunk = dataclasses.replace(goal, tolerances=goal.tolerances - margin[1], regions=(
        (Box(tuple(np.subtract(box.size, 2 * margin[0]))), T_box), (Sphere(sphere.radius - margin[0]), T_sphere),
        (Cylinder(cylinder.radius - margin[0], cylinder.length - 2 * margin[0]), T_cylinder)))
    rng = np.random.default_rng(0)
    targets = np.array([goal.sample(rng, T_world_frame, margin) for _ in range(3000)])
    links = targets @ invert(goal.T_link_point)
    assert all(shrunk.satisfied(T_world_frame, T) for T in links)
    points = (invert(T_world_frame) @ targets[:, :, 3].T).T[:, :3]
    in_box = np.all(np.abs(points - [0.5, 0, 0]) <= [0.09, 0.04, 0.04], axis=1)
    assert abs(in_box.mean() - 1 / 3) < 0.03  # each region as likely
    np.testing.assert_allclose(points[in_box].min(axis=0), [0.41, -0.04, -0.04], atol=0.005)
    np.testing.assert_allclose(points[in_box].max(axis=0), [0.59, 0.04, 0.04], atol=0.005)
    angles = np.array([goal.angles(T_world_frame, T) for T in links])
    np.testing.assert_allclose(np.abs(angles).max(axis=0), goal.tolerances - margin[1], rtol=0.02)

    outside = T_world_frame @ make_pose(goal.orientation @ Rotation.from_euler("XYZ", [0.3, -0.4, 0.5]).as_matrix(),
                                        [0.8, 0.3, 0.2])
    closest = goal.closest(T_world_frame, outside, margin)
    assert shrunk.satisfied(T_world_frame, closest @ invert(goal.T_link_point))
    np.testing.assert_allclose(invert(T_world_frame) @ closest[:, 3], [0.59, 0.04, 0.04, 1], atol=1e-12)
    bounds = goal.tolerances - margin[1]
    np.testing.assert_allclose(goal.angles(T_world_frame, closest),
                               np.clip(goal.angles(T_world_frame, outside), -bounds, bounds), atol=1e-12)
    for T_world_link in links[:20]:
        np.testing.assert_allclose(goal.closest(T_world_frame, T_world_link, margin), T_world_link @ goal.T_link_point,
                                   atol=1e-12)
    # a region or tolerance below its margin: its centre and the wanted orientation
    tiny = dataclasses.replace(goal, regions=((Sphere(0.001), T_sphere),), tolerances=np.full(3, 0.001))
    np.testing.assert_allclose(tiny.sample(rng, T_world_frame, margin), tiny.target(T_world_frame), atol=1e-12)
    position_only = dataclasses.replace(goal, orientation=None)
    point = position_only.sample(rng, T_world_frame, margin)
    pointing = make_pose(T_world_frame[:3, :3] @ goal.orientation, point) @ invert(goal.T_link_point)
    assert point.shape == (3,) and shrunk.satisfied(T_world_frame, pointing)
    np.testing.assert_allclose(position_only.closest(T_world_frame, outside, margin), closest[:3, 3], atol=1e-12)


def test_alternative_goals_are_all_read_and_of_one_kind():
    goals = [{"joint_constraints": [{"joint_name": "j1", "position": value}]} for value in (0.5, -0.5)]
    request = motion_plan_request_from_dict({"group_name": "arm", "goal_constraints": goals}, "r.yaml")
    assert dict(request.goal) == {"j1": 0.5} and [dict(g) for g in request.joint_goals] == [{"j1": 0.5}, {"j1": -0.5}]
    assert request.pose_goals == () and request.pose_goal is None
    position = {"link_name": "hand", "constraint_region": {"primitives": [{"type": 2, "dimensions": [0.1]}],
                                                           "primitive_poses": [{"position": [0.4, 0, 0.5]}]}}
    poses = [{"position_constraints": [dict(position, target_point_offset=[0, 0, z])]} for z in (0.0, 0.1)]
    request = motion_plan_request_from_dict({"goal_constraints": poses}, "r.yaml")
    assert request.goal == {} and request.joint_goals == () and len(request.pose_goals) == 2
    assert np.allclose(request.pose_goals[1].offset, [0, 0, 0.1]) and request.pose_goals[0] is request.pose_goal
    with pytest.raises(SceneError, match="r.yaml: goal_constraints: joint goals and pose goals mixed as alternatives"):
        motion_plan_request_from_dict({"goal_constraints": [goals[0], poses[0]]}, "r.yaml")
    with pytest.raises(SceneError, match=r"r.yaml: goal_constraints\[1\] has no joint_constraints"):
        motion_plan_request_from_dict({"goal_constraints": [goals[0], {}]}, "r.yaml")
    with pytest.raises(SceneError, match="r.yaml: goal_constraints: no goal given"):
        motion_plan_request_from_dict({"goal_constraints": []}, "r.yaml")


@pytest.mark.parametrize("changes, message", [
    ({"regions": ()}, "no regions"),
    ({"regions": ((Sphere(0.1),),)}, r"regions\[0\] must be \(Box \| Sphere \| Cylinder"),
    ({"regions": ((Sphere(0.1), 2 * np.eye(4)),)}, r"regions\[0\] pose: upper-left 3x3 block is not a rotation"),
    ({"tolerances": np.array([np.nan, 0, 0])}, "tolerances must be 3 finite numbers"),
    ({"tolerances": np.array([-0.1, 0, 0])}, r"tolerances must be >= 0 \(rad\)"),
    ({"offset": np.zeros(2)}, "offset must be 3 finite numbers"),
    ({"orientation": 2 * np.eye(3)}, "orientation: upper-left 3x3 block is not a rotation matrix"),
])
def test_a_bad_pose_goal_is_named(changes, message):
    import dataclasses

    from prehensile.errors import PrehensileError

    with pytest.raises(PrehensileError, match=f"PoseGoal of link 'hand': {message}"):
        dataclasses.replace(_example_goal()[1], **changes)


def test_missing_path_is_a_scene_error(tmp_path):
    with pytest.raises(SceneError, match="absent: no such folder or archive"):
        list(iter_mbm_problems(tmp_path / "absent"))
    (tmp_path / "notes.txt").write_text("not an archive")
    with pytest.raises(SceneError, match="notes.txt: not a folder or a tar archive"):
        list(iter_mbm_problems(tmp_path / "notes.txt"))
    with pytest.raises(SceneError, match="file not found"):
        load_moveit_scene(tmp_path / "scene0001.yaml")


@needs_mbm
def test_request_for_another_robot_is_rejected():
    request = next(iter(iter_mbm_problems(TARBALL))).request
    model = load_urdf(MBM / "panda.urdf")
    with pytest.raises(SceneError, match="has no joint"):
        request.start_configuration(model, strict="panda_finger_joint1" not in model.joint_names)
    other = type(request)("arm", {"elbow": 1.0}, {"elbow": 0.0}, source="other.yaml")
    with pytest.raises(SceneError, match="other.yaml: start_state: robot 'panda' has no joint 'elbow'"):
        other.goal_configuration(model)


def test_a_mimic_joint_in_a_request_must_follow_its_leader():
    """MoveIt accepts values for mimic joints; they must agree with the joint they follow."""
    from prehensile import robots
    from prehensile.scene.moveit import MotionPlanRequest

    panda = robots.load("panda")  # panda_finger_joint2 mimics panda_finger_joint1
    assert dict(panda.mimic_joints) == {"panda_finger_joint2": (panda.joint_index("panda_finger_joint1"), 1.0, 0.0)}
    fingers = {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}
    request = MotionPlanRequest("hand", fingers, {**fingers, "panda_finger_joint1": 0.03,
                                                  "panda_finger_joint2": 0.03}, source="r.yaml")
    assert request.start_configuration(panda, strict=True)[panda.joint_index("panda_finger_joint1")] == 0.02
    assert request.goal_configuration(panda, strict=True)[panda.joint_index("panda_finger_joint1")] == 0.03
    apart = MotionPlanRequest("hand", {**fingers, "panda_finger_joint2": 0.035}, fingers, source="r.yaml")
    with pytest.raises(SceneError, match=r"r.yaml: start_state: mimic joint 'panda_finger_joint2' = 0.035 disagrees "
                                         r"with the joint it follows: 1 \* panda_finger_joint1 \+ 0 = 0.02"):
        apart.start_configuration(panda)
