"""The `prehensile` command line (typer CliRunner)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from prehensile.cli.main import app
from prehensile.kinematics import forward_kinematics
from prehensile.model import load_urdf

DATA = Path(__file__).parent / "data" / "scenes"
URDF = DATA / "two_link.urdf"
runner = CliRunner()


def _run(*args: str):
    return runner.invoke(app, [str(a) for a in args])


def test_robot_info_bundled_json():
    result = _run("robot", "info", "panda", "--json")
    assert result.exit_code == 0, result.output
    info = json.loads(result.stdout)
    assert info["dof"] == len(info["joints"]) > 0
    joint = info["joints"][0]
    assert joint["type"] == "revolute"
    assert joint["lower_deg"] == pytest.approx(np.degrees(joint["lower"]))
    assert info["n_links"] > info["dof"]
    assert all("preshapes" in e for e in info["end_effectors"])
    assert info["mimic_joints"] == [{"name": "panda_finger_joint2", "follows": "panda_finger_joint1",
                                     "multiplier": 1.0, "offset": 0.0}]
    assert "panda_finger_joint2" not in [j["name"] for j in info["joints"]]  # not a variable of q


def test_robot_info_table_on_urdf_path():
    result = _run("robot", "info", URDF)
    assert result.exit_code == 0, result.output
    for text in ("two_link", "dof: 2", "joint1", "joint2", "revolute", "-171.9", "143.2"):
        assert text in result.stdout


def test_an_mjcf_robot_takes_the_srdf_beside_it_or_the_one_given(tmp_path):
    """Chains of an MJCF model come from <stem>.srdf next to it, or from --srdf (robot info, ik)."""
    pytest.importorskip("mujoco")
    xml = tmp_path / "arm.xml"
    xml.write_text((Path(__file__).parent / "data" / "mjcf" / "arm7.xml").read_text())
    group = '<robot name="arm7"><group name="{}"><chain base_link="base" tip_link="{}"/></group></robot>'
    (tmp_path / "arm.srdf").write_text(group.format("arm", "link7"))
    (tmp_path / "wrist.srdf").write_text(group.format("wrist", "link4"))
    chains = [json.loads(_run("robot", "info", xml, *extra, "--json").stdout)["chains"][0]
              for extra in ([], ["--srdf", tmp_path / "wrist.srdf"])]
    assert [(c["name"], len(c["joints"])) for c in chains] == [("arm", 7), ("wrist", 4)]
    assert json.loads(_run("robot", "info", xml, "--json").stdout)["srdf"] == str(tmp_path / "arm.srdf")
    solved = _run("ik", xml, "--srdf", tmp_path / "wrist.srdf", "--chain", "wrist", "--target", "0.1", "0.0", "0.3")
    assert solved.exit_code in (0, 1) and "wrist" in solved.stdout


def test_a_bug_exits_3_with_its_traceback_not_with_a_result_code(monkeypatch):
    from prehensile.cli import robot as robot_cmd

    def broken(model):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(robot_cmd, "robot_info", broken)
    result = _run("robot", "info", "panda")
    assert result.exit_code == 3 and "ZeroDivisionError" in result.output and "internal error" in result.output


def test_robot_list_names_bundled_robots():
    result = _run("robot", "list")
    assert result.exit_code == 0 and "panda" in result.stdout.split()


def test_fk_matches_library():
    q = [0.1, -0.4]
    result = _run("fk", URDF, "--q", *q, "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    model = load_urdf(URDF)
    expected = forward_kinematics(model, np.array(q))
    for name, pose in data["links"].items():
        np.testing.assert_allclose(pose["matrix"], expected[model.link_index(name)], atol=1e-12)


def test_fk_bundled_one_link_neutral_and_negative_values():
    result = _run("fk", "panda", "--link", "panda_link4", "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert list(data["links"]) == ["panda_link4"]
    table = _run("fk", URDF, "--q", "-0.5", "-1.0", "--link", "tool")
    assert table.exit_code == 0, table.output
    assert "tool" in table.stdout


@pytest.mark.parametrize("args, fragment", [
    (("fk", URDF, "--q", "0.1"), "has 2 joints"),
    (("fk", URDF, "--q", "0.1", "abc"), "--q: expected numbers, got 'abc'"),
    (("plan", "--goal", "0.1", "0.2", "plan_demo"), "--goal: expected numbers, got 'plan_demo'; if it is an argument "
     "of the command, give it before --goal"),
    (("plan", "--chain", "arm", "--target", "0.3", "0", "0.5", "plan_demo"),
     "--target: expected numbers, got 'plan_demo'"),
    (("fk", URDF, "--link", "nope"), "has no link 'nope'"),
    (("robot", "info", "r2d2"), "r2d2"),
    (("fk", URDF, "0.1", "0.2"), "unexpected arguments 0.1 0.2; give joint values after --q"),
    (("fk", URDF, "--q", "0.1", "-0.2", "--bogus", "1"), "no such option: --bogus (see --help)"),
    (("robot", "info", "r2d2"), "r2d2"),
    (("robot", "info", DATA), "is a directory, not a file"),
    (("check", DATA / "missing.yaml"), "scene file not found"),
    (("check", DATA), "is a directory, not a scene file"),
    (("plan", "plan_demo", "--bogus-option", "3"), "no such option: --bogus-option"),
    (("plan", "plan_demo", "--seed", "-1"), "--seed: must be in 0 .. 4294967294, got -1"),
    (("bench", "mbm", DATA, "--robot", "panda", "--seed", str(2**64 - 1)), "--seed: must be in 0 .. 4294967294"),
    (("ik", "panda", "--chain", "arm", "--target", "0.3", "0", "0.5", "--bogus"), "no such option: --bogus"),
    (("bench", "mbm", DATA, "--robot", "panda"), "no MoveIt problems found"),
    (("bench", "mbm", DATA, "--robot", "panda", "--limit", "-1"), "--limit: must be >= 0"),
    (("bench", "mbm", DATA, "--robot", "panda", "--srdf", DATA), "--srdf " + str(DATA) + ": is a directory"),
])
def test_bad_input_is_one_red_line_with_exit_code_2(args, fragment):
    result = _run(*args)
    assert result.exit_code == 2
    assert fragment in result.output
    assert "Traceback" not in result.output
    assert len(result.output.splitlines()) == 1  # not even a blank line before it


def test_check_exit_codes():
    free = _run("check", DATA / "free.yaml")
    assert free.exit_code == 0, free.output
    assert "collision-free" in free.stdout
    colliding = _run("check", DATA / "colliding.yaml", "--json")
    assert colliding.exit_code == 1, colliding.output
    data = json.loads(colliding.stdout)
    assert data["free"] is False and data["robots"][0]["colliding_links"] == ["link2"]
    assert data["colliding_bodies"] == ["post"]
    bundled = _run("check", "plan_demo")  # a bundled scene by name, as for plan
    assert bundled.exit_code == 0, bundled.output


def test_check_bad_scene_file(tmp_path):
    bad = tmp_path / "typo.yaml"
    bad.write_text("obstacels: []\n")
    result = _run("check", bad)
    assert result.exit_code == 2
    assert "typo.yaml" in result.output and "did you mean 'obstacles'" in result.output


@pytest.mark.parametrize("entry, message", [
    ("robots: [{robot: [nao]}]", "robots[0].robot: expected a bundled robot name or a robot file path"),
    ("robots: [{robot: nao}]\nobstacles: [{name: wall, shape: {type: mesh, file: empty.stl}}]",
     "empty.stl: no triangles"),
    ("robots: [{robot: nao}]\nobstacles: [{name: wall, shape: {type: mesh, file: notes.yaml}}]",
     "notes.yaml: not readable as a triangle"),
    ("robots: [{robot: panda, goal: {panda_joint9: 0.1}}]", "robots[0].goal"),  # check validates goals as plan does
])
def test_bad_scene_entries_exit_2(tmp_path, entry, message):
    (tmp_path / "empty.stl").write_text("solid empty\nendsolid empty\n")
    (tmp_path / "notes.yaml").write_text("a: 1\n")
    scene = tmp_path / "scene.yaml"
    scene.write_text(f"version: 1\n{entry}\n")
    result = _run("check", scene)
    assert result.exit_code == 2, result.output
    assert message in " ".join(result.output.split())


def test_robot_info_shows_unlimited_lower_limits_as_minus_inf(tmp_path):
    urdf = tmp_path / "wheel.urdf"
    urdf.write_text('<robot name="w"><link name="a"/><link name="b"/><joint name="wheel" type="continuous">'
                    '<parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint></robot>')
    result = _run("robot", "info", urdf)
    assert result.exit_code == 0, result.output
    assert "-inf rad" in result.output and "inf rad" in result.output.replace("-inf rad", "")


def test_demo_writes_png_and_json(tmp_path):
    result = _run("demo", "--out", tmp_path / "out")
    assert result.exit_code == 0, result.output
    png, report = tmp_path / "out" / "demo.png", tmp_path / "out" / "demo.json"
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    data = json.loads(report.read_text())
    assert {r["name"] for r in data["bundled_robots"]} >= {"nao", "armar3", "panda"}
    links = {r["name"]: r["colliding_links"] for r in data["robots"]}
    assert "panda_hand" in links["panda"] and links["nao"] == [] and links["armar3"] == []
    assert data["free"] is False and "shelf" in data["colliding_bodies"]
    assert "demo.png" in result.stdout and "demo.json" in result.stdout


def test_unwritable_outputs_exit_2_before_any_work(tmp_path):
    a_file = tmp_path / "afile.txt"
    a_file.write_text("")
    cases = [(("demo", "--out", a_file), "is a file, not a folder"),
             (("plan", "plan_demo", "--out", a_file / "out"), "is a file, not a folder"),
             (("bench", "mbm", tmp_path, "--robot", "panda", "--json", tmp_path), "is a folder"),
             (("bench", "ik", "--robot", "panda", "--base", "panda_link0", "--tip", "panda_hand_tcp",
               "--json", a_file / "ik.json"), "is a file, not a folder")]
    if Path("/proc").is_dir():  # its permission bits let root write, but nothing can be created there
        cases.append((("plan", "plan_demo", "--out", "/proc/out"), "cannot write in /proc"))
    for args, message in cases:
        result = _run(*args)
        assert result.exit_code == 2, result.output
        assert message in " ".join(result.output.split()) and "Traceback" not in result.output


def test_check_with_sphere_models():
    assert _run("check", DATA / "free.yaml", "--spheres").exit_code == 0
    colliding = _run("check", DATA / "colliding.yaml", "--spheres", "--json")
    assert colliding.exit_code == 1, colliding.output
    report = json.loads(colliding.stdout)
    assert report["method"] == "spheres" and report["colliding_bodies"] == []  # the balls name no body
    (arm,) = report["robots"]
    assert arm["colliding_links"] == ["link2"]  # the link the exact check names too
    table = _run("check", DATA / "colliding.yaml", "--spheres").output
    assert "link2" in table and "world" in table
