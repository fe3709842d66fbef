"""Collision-check throughput on the MotionBenchMaker Panda scenes: compiled sphere checker vs
exact coal checks, in one process on the same scenes.

Per scene (the first ``--scenes`` problems of each of the 4 scenarios) and checker, the rate is
configurations checked per second on uniform random configurations (one thread: numba is set
to 1 thread). Checkers: :class:`SphereChecker` batched with the generated cover and with the
padded MBM spheres; :class:`ExactChecker` (coal through Python, meshes as BVHs); and
pinocchio + coal (``pin.computeCollisions`` with stop-at-first-collision) when pinocchio is
installed. Medians over scenes and ratios sphere / exact are printed and written, with machine
info, versions and seeds, to ``benchmarks/results/collision_throughput.json`` (atomic write).

Run: ``NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/collision_throughput.py``
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MBM = ROOT.parent / "shared" / "bench" / "mbm" / "panda"
SCENARIOS = ("table_pick_panda", "box_panda", "bookshelf_small_panda", "cage_panda")


def scenes(n_per_scenario: int):
    """(scenario, index, obstacles) for the first problems of each scenario."""
    from prehensile.scene.moveit import iter_mbm_problems

    for problem in iter_mbm_problems(MBM / "problems.tar.bz2"):
        if problem.scenario in SCENARIOS and problem.index <= n_per_scenario:
            yield problem.scenario, problem.index, problem.scene.collision_obstacles()


def rate(check, q: np.ndarray, repeats: int) -> float:
    """Best-of-``repeats`` configurations per second of ``check(q)``."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        check(q)
        best = min(best, time.perf_counter() - start)
    return len(q) / best


class PinocchioChecker:
    """pinocchio + coal: robot collision geometry from the URDF, obstacles on the universe
    joint, pairs = robot x obstacles plus the robot pairs that our ACM checks."""

    def __init__(self, model, obstacles, acm):
        import coal
        import pinocchio as pin

        from prehensile.collision.exact import coal_geometry

        self.pin = pin
        self.model = pin.buildModelFromUrdf(str(MBM / "panda.urdf"))
        self.geom = pin.buildGeomFromUrdf(self.model, str(MBM / "panda.urdf"), pin.COLLISION, package_dirs=[str(MBM)])
        n_robot = len(self.geom.geometryObjects)
        link_of = [o.name.rsplit("_", 1)[0] for o in self.geom.geometryObjects]
        for k, obstacle in enumerate(obstacles):
            T = np.asarray(obstacle.T_world_shape)
            placement = pin.SE3(T[:3, :3].copy(), T[:3, 3].copy())
            obj = pin.GeometryObject(f"obstacle{k}", 0, 0, placement, coal_geometry(obstacle.shape))
            self.geom.addGeometryObject(obj)
        names = list(model.link_names)
        for a in range(n_robot):
            for b in range(n_robot, len(self.geom.geometryObjects)):
                self.geom.addCollisionPair(pin.CollisionPair(a, b))
            for b in range(a + 1, n_robot):
                la, lb = link_of[a], link_of[b]
                if la in names and lb in names and not acm[names.index(la), names.index(lb)]:
                    self.geom.addCollisionPair(pin.CollisionPair(a, b))
        self.data = self.model.createData()
        self.geom_data = pin.GeometryData(self.geom)
        del coal

    def is_free(self, q: np.ndarray) -> np.ndarray:
        pin = self.pin
        return np.array([not pin.computeCollisions(self.model, self.data, self.geom, self.geom_data, qi, True)
                         for qi in q])


def atomic_write(path: Path, payload: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.stem, suffix=".tmp", dir=path.parent)
    with os.fdopen(fd, "w") as f:
        json.dump(payload, f, indent=2)
    os.replace(tmp, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=3, help="problems per scenario")
    parser.add_argument("--sphere-configs", type=int, default=200_000)
    parser.add_argument("--exact-configs", type=int, default=500)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "collision_throughput.json")
    args = parser.parse_args()

    import numba

    numba.set_num_threads(1)
    import coal

    from prehensile.collision.acm import allowed_collision_matrix
    from prehensile.collision.exact import ExactChecker
    from prehensile.collision.sphere_checker import SphereChecker
    from prehensile.collision.spheres import generate_sphere_model, pad_sphere_model, spheres_from_urdf
    from prehensile.model import load_urdf

    model = load_urdf(MBM / "panda.urdf", MBM / "panda.srdf")
    acm = allowed_collision_matrix(model)
    sphere_models = {
        "sphere_generated": generate_sphere_model(model),
        "sphere_padded_mbm": pad_sphere_model(spheres_from_urdf(model, MBM / "panda_spherized.urdf"), model),
    }
    try:
        import pinocchio  # noqa: F401

        have_pin = True
    except ImportError:
        have_pin = False
    rng = np.random.default_rng(args.seed)
    rows = []
    for scenario, index, obstacles in scenes(args.scenes):
        q_many = model.random_configurations(rng, args.sphere_configs)
        q_few = q_many[: args.exact_configs]
        row = {"scenario": scenario, "index": index, "obstacles": len(obstacles)}
        exact = ExactChecker(model, obstacles, acm=acm)
        exact_free = exact.is_free(q_few)
        row["exact_coal"] = rate(exact.is_free, q_few, 1)
        row["exact_free_fraction"] = float(exact_free.mean())
        if have_pin:
            pin_checker = PinocchioChecker(model, obstacles, acm)
            pin_free = pin_checker.is_free(q_few)
            row["pinocchio_coal"] = rate(pin_checker.is_free, q_few, 1)
            row["pinocchio_agrees_with_exact"] = float(np.mean(pin_free == exact_free))
        for name, spheres in sphere_models.items():
            checker = SphereChecker(model, obstacles, spheres=spheres, acm=acm)
            checker.is_free(q_few[:2])  # compile / load from cache
            row[name] = rate(checker.is_free, q_many, 3)
            free = checker.is_free(q_few)
            row[f"{name}_false_free"] = int(np.sum(free & ~exact_free))
            row[f"{name}_conservative_rate"] = float(np.sum(~free & exact_free) / max(exact_free.sum(), 1))
        rows.append(row)
        print(f"{scenario} {index:04d}: " + ", ".join(
            f"{k} {v:,.0f}/s" for k, v in row.items() if k in sphere_models or k.startswith(("exact_coal", "pinocchio_coal"))))

    checkers = list(sphere_models) + ["exact_coal"] + (["pinocchio_coal"] if have_pin else [])
    medians = {c: float(np.median([r[c] for r in rows])) for c in checkers}
    ratios = {f"{s}/{e}": medians[s] / medians[e] for s in sphere_models for e in checkers if e not in sphere_models}
    summary = {
        "medians_configs_per_second": medians,
        "ratios": ratios,
        "median_conservative_rate": {s: float(np.median([r[f"{s}_conservative_rate"] for r in rows])) for s in sphere_models},
        "false_free_total": {s: int(sum(r[f"{s}_false_free"] for r in rows)) for s in sphere_models},
    }
    print(json.dumps(summary, indent=2))
    import numba as nb
    import trimesh

    payload = {
        "benchmark": "collision_throughput",
        "command": "NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/collision_throughput.py",
        "settings": vars(args) | {"out": str(args.out)},
        "machine": {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
                    "cpu_count": os.cpu_count(), "python": platform.python_version()},
        "versions": {"numpy": np.__version__, "numba": nb.__version__, "coal": getattr(coal, "__version__", "?"),
                     "trimesh": trimesh.__version__,
                     "pinocchio": __import__("pinocchio").__version__ if have_pin else None},
        "seeds": {"configurations": args.seed},
        "threads": {"numba": nb.get_num_threads()},
        "summary": summary,
        "scenes": rows,
    }
    atomic_write(args.out, payload)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
