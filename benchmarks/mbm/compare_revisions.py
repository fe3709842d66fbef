"""Paired timing of our RRT-Connect at another git revision against the working tree, in one process.

Timings of separate processes on a shared VM differ by up to 40 % for the same code, so a change
of a few percent cannot be seen by comparing two benchmark runs. Here both versions run in the
same process, problem by problem and in alternating order, each query followed by its own
certification as in ``prehensile bench mbm`` (certification evicts the caches the next query
starts from). Both versions are exported to a temporary folder and imported as the packages
``prehensile_rev`` (``git archive``) and ``prehensile_now`` (the working tree). Reported: per
version the median over problems of each problem's fastest planning time (search +
simplification, as the benchmark reports it) and the median per-problem ratio, on the problems
around the median; and whether both versions spent the same clearance evaluations (the same
search) on every problem.

    NUMBA_NUM_THREADS=1 taskset -c 1 python benchmarks/mbm/compare_revisions.py HEAD~1 --limit 25 --reps 15

Needs ../shared (the MotionBenchMaker Panda problems). Compare the revision with itself first: on
the 2-core VM of the README the same code gave paired ratios from 0.960 to 1.027 (five runs), so
one run does not resolve differences under about 4 % (separate benchmark runs: about 40 %).
"""

from __future__ import annotations

import argparse
import importlib
import io
import re
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
MBM = ROOT.parent / "shared" / "bench" / "mbm" / "panda"


def export(revision: str | None, package: str, folder: Path) -> str:
    """Write src/prehensile at ``revision`` (None: the working tree) to folder/package, its imports
    renamed; returns the package name. Both versions are exported alike, so that neither is
    favoured by where it lives or by numba's cache."""
    if revision is None:
        shutil.copytree(ROOT / "src" / "prehensile", folder / package, ignore=shutil.ignore_patterns("__pycache__"))
    else:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", revision, "src/prehensile"], check=True,
                                 capture_output=True).stdout
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(folder / "archive", filter="data")
        (folder / "archive" / "src" / "prehensile").rename(folder / package)
    for path in (folder / package).rglob("*.py"):
        path.write_text(re.sub(r"\bprehensile(?=\.[a-z_]| import)", package, path.read_text()))
    return package


def query_runner(package: str, limit: int):
    """(run(i) -> (planning s, clearance evaluations), number of problems) for the package's planner."""
    robots = importlib.import_module(f"{package}.robots")
    mbm = importlib.import_module(f"{package}.benchmarking.mbm")
    planning = importlib.import_module(f"{package}.planning")
    model = robots.load(str(MBM / "panda.urdf"), str(MBM / "panda.srdf"))
    spheres = mbm.benchmark_spheres(model, str(MBM / "panda_spherized.urdf"), False, None)
    settings = mbm.MBMSettings(time_budget_s=5.0, limit=limit)
    problems = [mbm.PreparedProblem(model, spheres, p, settings)
                for p in mbm.load_problems(str(MBM / "problems.tar.bz2"), model, limit)]

    def run(i: int) -> tuple[float, int]:
        p = problems[i]
        rng = np.random.default_rng(mbm.problem_seed(settings, p.problem))
        result = planning.rrt_connect(p.ctx, p.q_start, p.q_goal, planning.RRTConnectSettings(time_budget_s=5.0), rng)
        return result.stats.plan_time_s + result.stats.simplify_time_s, result.stats.collision_checks

    return run, len(problems)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("revision", help="git revision to compare the working tree with")
    parser.add_argument("--limit", type=int, default=25, help="problems per scenario (0: all)")
    parser.add_argument("--reps", type=int, default=15, help="runs per problem and version")
    parser.add_argument("--middle", type=int, default=40, help="problems around the median that are timed")
    args = parser.parse_args()
    if not MBM.is_dir():
        sys.exit(f"compare_revisions: {MBM} not found (the MotionBenchMaker problems of ../shared)")
    with tempfile.TemporaryDirectory() as folder:
        sys.path.insert(0, folder)
        versions = [query_runner(export(args.revision, "prehensile_rev", Path(folder)), args.limit),
                    query_runner(export(None, "prehensile_now", Path(folder)), args.limit)]
        count = versions[0][1]
        first = np.array([[versions[v][0](i) for v in (0, 1)] for i in range(count)])  # (problems, 2, 2), warms up
        same = np.mean(first[:, 0, 1] == first[:, 1, 1])
        order = np.argsort(first[:, 0, 0])
        middle = order[max(count // 2 - args.middle // 2, 0):][:args.middle]
        best = np.full((len(middle), 2), np.inf)
        started = time.perf_counter()
        for rep in range(args.reps):
            for k, i in enumerate(middle):
                for v in ((0, 1) if (rep + k) % 2 == 0 else (1, 0)):
                    best[k, v] = min(best[k, v], versions[v][0](i)[0])
    median = np.median(best, axis=0) * 1e3
    print(f"{len(middle)} problems around the median, fastest of {args.reps} runs each "
          f"({time.perf_counter() - started:.0f} s); same evaluations on {same:.0%} of {count} problems")
    print(f"median planning ms: {args.revision} {median[0]:.3f}, working tree {median[1]:.3f}; "
          f"paired ratio working tree / {args.revision}: {np.median(best[:, 1] / best[:, 0]):.3f}")


if __name__ == "__main__":
    main()
