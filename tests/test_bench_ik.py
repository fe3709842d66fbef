"""`prehensile bench ik` and its runner: schema, sane numbers, peers, determinism."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import erd_robot
from prehensile import robots
from prehensile.benchmarking.ik import IKBenchSettings, make_problem, run_ik_bench, verify
from prehensile.benchmarking.ik_peers import PinocchioDLS
from prehensile.cli.main import app
from prehensile.errors import PrehensileError

runner = CliRunner()
SUMMARY_KEYS = {"kind", "targets", "solved", "success_rate", "within_budget_rate", "mean_ms", "median_ms", "p95_ms",
                "iterations", "position_only"}


@pytest.fixture(scope="module")
def panda_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "ik_panda.json"
    result = runner.invoke(app, ["bench", "ik", "--robot", "panda", "--base", "panda_link0", "--tip", "panda_hand_tcp",
                                 "--n", "50", "--method", "dls,pinv", "--peers", "pinocchio,ikpy",
                                 "--ikpy-targets", "4", "--budget", "0.05", "--json", str(out)])
    assert result.exit_code == 0, result.output
    assert "dls" in result.stdout and "pinocchio" in result.stdout
    return json.loads(out.read_text())


def test_report_schema_and_sane_numbers(panda_report):
    r = panda_report
    assert r["robot"] == "panda" and r["n"] == 50
    assert r["tolerance"] == {"position_m": 1e-4, "rotation_rad": 1e-3}
    assert r["chain"]["joints"] == [f"panda_joint{i}" for i in range(1, 8)]
    assert {"machine", "versions", "command", "ratios"} <= set(r)
    assert set(r["methods"]) == {"dls", "pinv", "pinocchio", "ikpy"}
    for name, m in r["methods"].items():
        assert SUMMARY_KEYS <= set(m), name
        assert 0 <= m["within_budget_rate"] <= m["success_rate"] <= 1
        assert 0 < m["median_ms"] <= m["p95_ms"] and m["mean_ms"] > 0
    assert r["methods"]["dls"]["success_rate"] >= 0.95
    assert r["methods"]["ikpy"]["targets"] == 4 and "first 4 targets" in r["methods"]["ikpy"]["note"]
    assert r["methods"]["pinocchio"]["kind"] == "peer" and r["methods"]["pinocchio"]["targets"] == 50
    assert r["ratios"]["dls"]["mean_vs_pinocchio"] > 0 and r["ratios"]["dls"]["mean_vs_ikpy_subset"] > 0


def test_any_urdf_by_base_and_tip():
    urdf = erd_robot("panda_description/urdf/panda.urdf")
    report = run_ik_bench(robots.load(urdf), "panda_link0", "panda_hand", IKBenchSettings(
        n=50, methods=("dls", "fabrik"), peers=("pinocchio",), time_budget_s=0.05))
    assert report["chain"]["base"] == "panda_link0" and report["chain"]["tip"] == "panda_hand"
    assert report["methods"]["dls"]["success_rate"] >= 0.95
    assert report["methods"]["fabrik"]["position_only"] and not report["methods"]["dls"]["position_only"]
    assert 0 <= report["methods"]["pinocchio"]["success_rate"] <= 1


def test_same_seed_same_success_counts():
    model = robots.load("nao")
    settings = IKBenchSettings(n=50, methods=("dls", "analytic"), peers=("pinocchio",), time_budget_s=0.05, seed=4)
    first, second = (run_ik_bench(model, "torso", "l_gripper", settings) for _ in range(2))
    for name in ("dls", "analytic", "pinocchio"):
        assert first["methods"][name]["solved"] == second["methods"][name]["solved"], name
    batch = first["methods"]["analytic"]["batch"]
    assert batch["success_rate"] == 1.0 and batch["solutions_verified"] == 1.0 and batch["us_per_target"] > 0
    other = run_ik_bench(model, "torso", "l_gripper", IKBenchSettings(n=50, methods=("dls",), peers=(), seed=5))
    assert other["start"] == first["start"]


def test_targets_are_reachable_and_verified_by_our_fk():
    problem = make_problem(robots.load("panda"), "panda_link0", "panda_hand_tcp", 20, seed=1)
    settings = IKBenchSettings()
    everything = np.arange(20)
    assert verify(problem, problem.q_sampled, everything, False, settings).all()
    assert not verify(problem, np.repeat(problem.q_start[None], 20, axis=0), everything, False, settings).any()


def test_pinocchio_peer_solves_a_reachable_target():
    problem = make_problem(robots.load("armar3"), "Platform", "TCP_R", 3, seed=2)  # link and joint names clash
    peer = PinocchioDLS(problem.model, problem.chain, problem.q_start, 1e-4, 1e-3)
    q, iterations = peer.solve(problem.targets[0], 0.2, 0)
    assert iterations > 0
    assert verify(problem, q[None], np.array([0]), False, IKBenchSettings())[0]


@pytest.mark.parametrize("kwargs, message", [
    ({"methods": ("magic",)}, "unknown method magic"),
    ({"peers": ("moveit",)}, "valid: pinocchio, ikpy"),
    ({"n": 0}, ">= 1"),
])
def test_bad_settings(kwargs, message):
    with pytest.raises(PrehensileError, match=message):
        IKBenchSettings(**kwargs)


def test_analytic_on_a_non_nao_chain_is_bad_input():
    result = runner.invoke(app, ["bench", "ik", "--robot", "panda", "--base", "panda_link0", "--tip", "panda_hand_tcp",
                                 "--n", "5", "--method", "analytic", "--peers", "none"])
    assert result.exit_code == 2
    assert "not a NAO-type arm" in result.stderr


def test_peers_refuse_chains_with_mimic_joints():
    """NAO's right leg starts at RHipYawPitch, which follows LHipYawPitch: a peer would solve another robot."""
    for peer in ("pinocchio", "ikpy"):
        result = runner.invoke(app, ["bench", "ik", "--robot", "nao", "--base", "torso", "--tip", "r_sole", "--n", "5",
                                     "--peers", peer])
        assert result.exit_code == 2
        assert "RHipYawPitch (follows LHipYawPitch)" in " ".join(result.stderr.split())


def test_a_peer_that_is_not_installed_is_bad_input_with_the_install_hint(monkeypatch):
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "ikpy" else find_spec(name, *a))
    result = runner.invoke(app, ["bench", "ik", "--robot", "panda", "--base", "panda_link0", "--tip", "panda_hand_tcp",
                                 "--n", "5", "--peers", "ikpy"])
    assert result.exit_code == 2
    assert "peer ikpy is not installed: pip install 'prehensile[bench]'" in " ".join(result.stderr.split())


def test_the_ikpy_peer_takes_a_urdf_axis_that_is_not_unit_length(tmp_path):
    """ikpy scales a joint's motion by its axis length; ours and pinocchio normalise it."""
    pytest.importorskip("ikpy")
    from prehensile.benchmarking.ik_peers import IkpyPeer
    from prehensile.kinematics import link_pose
    from prehensile.model.builder import resolve_chain
    from prehensile.model.robot_model import Chain

    urdf = tmp_path / "tilt.urdf"
    urdf.write_text('<robot name="tilt"><link name="base"/><link name="arm"/><link name="tip"/>'
                    '<joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 1"/>'
                    '<limit lower="-2" upper="2" effort="1" velocity="1"/></joint>'
                    '<joint name="j2" type="revolute"><parent link="arm"/><child link="tip"/><origin xyz="0.3 0 0"/>'
                    '<axis xyz="0 0 2"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint></robot>')
    model = robots.load(urdf)
    q = np.array([0.7, -0.4])
    peer = IkpyPeer(model, resolve_chain(model, Chain("base->tip", "base", "tip", ())), q)
    np.testing.assert_allclose(peer.chain.forward_kinematics(peer.initial), link_pose(model, q, "tip"), atol=1e-12)
