"""Sphere checkers against exact meshes on the MotionBenchMaker Panda scenes.

On sampled configurations in the MBM scenes the sphere model must never call free what the
exact meshes (coal) call colliding; how often it is more conservative is printed (run with
``-s``) and recorded as test properties.
"""

from __future__ import annotations

import tarfile
from pathlib import Path

import numpy as np
import pytest

from conftest import SHARED
from prehensile.collision.exact import ExactChecker
from prehensile.collision.sphere_checker import SphereChecker
from prehensile.collision.spheres import generate_sphere_model, pad_sphere_model, spheres_from_urdf
from prehensile.collision.world import Obstacle
from prehensile.model import load_urdf

MBM = SHARED / "bench" / "mbm" / "panda"
ARCHIVE = MBM / "problems.tar.bz2"
SCENARIOS = ("table_pick_panda", "box_panda", "bookshelf_small_panda", "cage_panda")
SCENES_PER_SCENARIO = 2
CONFIGS_PER_SCENE = 300

pytestmark = pytest.mark.skipif(not ARCHIVE.is_file(), reason="MBM Panda problems not found (../shared/bench/mbm)")


def _local_problems(model):
    """Minimal MoveIt YAML reading, used only while prehensile.scene.moveit is unavailable."""
    import yaml

    from prehensile.model.geometry import Box, Cylinder, Sphere
    from prehensile.spatial import make_pose, quaternion_to_matrix

    with tarfile.open(ARCHIVE) as tar:
        members = {Path(m.name): m for m in tar.getmembers() if m.isfile()}
        for scenario in SCENARIOS:
            for index in range(1, SCENES_PER_SCENARIO + 1):
                read = lambda kind: yaml.safe_load(tar.extractfile(  # noqa: E731
                    next(m for p, m in members.items() if p.parent.name == scenario and p.name == f"{kind}{index:04d}.yaml")))
                scene, request = read("scene"), read("request")
                obstacles = []
                for obj in scene["world"]["collision_objects"]:
                    for prim, pose in zip(obj["primitives"], obj["primitive_poses"]):
                        dims = prim["dimensions"]  # MoveIt: box xyz, cylinder (height, radius), sphere (radius,)
                        shape = {"box": lambda: Box(tuple(dims)), "cylinder": lambda: Cylinder(dims[1], dims[0]),
                                 "sphere": lambda: Sphere(dims[0])}[prim["type"]]()
                        x, y, z, w = pose["orientation"]
                        T = make_pose(quaternion_to_matrix([w, x, y, z]), pose["position"])
                        obstacles.append(Obstacle(obj["id"], shape, T))
                joints = request["start_state"]["joint_state"]
                start = model.configuration_from_dict(
                    {n: v for n, v in zip(joints["name"], joints["position"]) if n in model.joint_names})
                yield scenario, index, obstacles, start


def _problems(model):
    try:
        from prehensile.scene.moveit import iter_mbm_problems
    except ImportError:
        yield from _local_problems(model)
        return
    for problem in iter_mbm_problems(ARCHIVE):
        if problem.scenario in SCENARIOS and problem.index <= SCENES_PER_SCENARIO:
            yield (problem.scenario, problem.index, problem.scene.collision_obstacles(),
                   problem.request.start_configuration(model))


@pytest.fixture(scope="module")
def setup():
    model = load_urdf(MBM / "panda.urdf", MBM / "panda.srdf")
    models = {
        "generated": generate_sphere_model(model),
        "padded_mbm": pad_sphere_model(spheres_from_urdf(model, MBM / "panda_spherized.urdf"), model),
    }
    problems = list(_problems(model))
    assert len(problems) == len(SCENARIOS) * SCENES_PER_SCENARIO
    return model, models, problems


def test_spheres_never_free_where_meshes_collide(setup, record_property):
    model, models, problems = setup
    rng = np.random.default_rng(20240611)
    totals = {name: np.zeros(3, dtype=np.int64) for name in models}  # false free, conservative, exact free
    n_total = 0
    for scenario, index, obstacles, _ in problems:
        q = model.random_configurations(rng, CONFIGS_PER_SCENE)
        exact_free = ExactChecker(model, obstacles).is_free(q)
        n_total += len(q)
        for name, spheres in models.items():
            sphere_free = SphereChecker(model, obstacles, spheres=spheres).is_free(q)
            false_free = sphere_free & ~exact_free
            assert not false_free.any(), (
                f"{name} spheres call {false_free.sum()} configurations free that collide exactly "
                f"({scenario} {index}), e.g. q = {q[np.argmax(false_free)].tolist()}")
            totals[name] += [false_free.sum(), (~sphere_free & exact_free).sum(), exact_free.sum()]
    for name, (false_free, conservative, exact_free) in totals.items():
        rate = conservative / max(exact_free, 1)
        record_property(f"{name}_conservative_rate", float(rate))
        print(f"\n{name}: {n_total} configurations, {exact_free} free on meshes, {false_free} false free, "
              f"{conservative} ({100 * rate:.1f}% of the free ones) called colliding by the spheres")


def test_start_states_are_free(setup):
    model, models, problems = setup
    for scenario, index, obstacles, start in problems:
        assert ExactChecker(model, obstacles).is_free(start), f"{scenario} {index}: start collides (exact)"
        for name, spheres in models.items():
            checker = SphereChecker(model, obstacles, spheres=spheres)
            assert checker.is_free(start), f"{scenario} {index}: start collides with {name} spheres"
            assert checker.first_collision(np.stack([start, start])) == -1
