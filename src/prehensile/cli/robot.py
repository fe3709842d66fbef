"""``prehensile robot info`` and ``prehensile fk``: describe a robot, compute link poses."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from prehensile.errors import PrehensileError, missing_file
from prehensile.kinematics import forward_kinematics
from prehensile.model.robot_model import PRISMATIC, RobotModel
from prehensile.spatial import matrix_to_rpy


def load_robot(name_or_path: str, srdf: Path | None = None) -> RobotModel:
    """A bundled robot by name or a model file by path, with an SRDF if given (through
    ``prehensile.robots.load``)."""
    from prehensile import robots

    if srdf is not None and not srdf.is_file():
        raise PrehensileError(f"--srdf {srdf}: {missing_file(srdf)}")
    return robots.load(name_or_path, srdf)


def joint_rows(model: RobotModel) -> list[dict[str, Any]]:
    """One dict per DoF: name, type (revolute / continuous / prismatic), limits, velocity limit."""
    kinds = {}
    for link in range(model.n_links):
        index = int(model.joint_q_index[link])
        if index >= 0 and index not in kinds:
            kinds[index] = "prismatic" if model.joint_type[link] == PRISMATIC else "revolute"
    rows = []
    for i, name in enumerate(model.joint_names):
        kind = kinds.get(i, "revolute")
        lo, hi = float(model.lower[i]), float(model.upper[i])
        if kind == "revolute" and not (math.isfinite(lo) and math.isfinite(hi)):
            kind = "continuous"
        row = {"name": name, "index": i, "type": kind, "lower": _finite(lo), "upper": _finite(hi),
               "velocity": _finite(float(model.velocity_limit[i]))}
        if kind != "prismatic":
            row["lower_deg"] = _finite(math.degrees(lo))
            row["upper_deg"] = _finite(math.degrees(hi))
        rows.append(row)
    return rows


def mimic_rows(model: RobotModel) -> list[dict[str, Any]]:
    """One dict per mimic joint (it follows a joint of q): name, the joint it follows,
    multiplier and offset (its value = multiplier * followed + offset, rad or m)."""
    rows = []
    for link in range(model.n_links):
        leader = model.mimic_of(link)
        if leader is not None:
            rows.append({"name": model.link_joint_names[link], "follows": leader,
                         "multiplier": float(model.joint_multiplier[link]), "offset": float(model.joint_offset[link])})
    return rows


def robot_info(model: RobotModel) -> dict[str, Any]:
    """A JSON-ready description: source files (``srdf`` None if none was applied), dof, links,
    joints, mimic joints, chains, end effectors with preshapes."""
    return {
        "name": model.name,
        "source": model.source,
        "srdf": model.srdf_source,
        "dof": model.dof,
        "n_links": model.n_links,
        "root_link": model.link_names[0],
        "joints": joint_rows(model),
        "mimic_joints": mimic_rows(model),
        "chains": [
            {"name": c.name, "base_link": c.base_link, "tip_link": c.tip_link, "joints": list(c.joint_names)}
            for c in model.chains.values()
        ],
        "end_effectors": [
            {
                "name": e.name, "base_link": e.base_link, "tcp_link": e.tcp_link, "gcp_link": e.gcp_link,
                "chain": e.chain, "finger_joints": list(e.finger_joints),
                "preshapes": {p: {j: float(v) for j, v in values.items()} for p, values in e.preshapes.items()},
            }
            for e in model.end_effectors.values()
        ],
    }


def parse_q(model: RobotModel, values: list[str] | None) -> np.ndarray:
    """q (dof,) from command-line strings; neutral if none are given.

    Raises:
        PrehensileError: a value is not a number or the count differs from the DoF.
    """
    if not values:
        return model.neutral_configuration()
    try:
        q = np.array([float(v) for v in values], dtype=float)
    except ValueError:
        raise PrehensileError(f"--q: expected numbers (rad or m), got {' '.join(values)}") from None
    if q.shape != (model.dof,):
        raise PrehensileError(
            f"--q: robot '{model.name}' has {model.dof} joints ({', '.join(model.joint_names)}), got {len(q)} values"
        )
    return model.check_configuration(q, "--q")


def link_poses(model: RobotModel, q: np.ndarray, link: str | None = None) -> dict[str, Any]:
    """JSON-ready poses of one link (or all): position (m), rpy (rad), matrix (4x4)."""
    poses = forward_kinematics(model, q)
    names = [link] if link else list(model.link_names)
    out = {}
    for name in names:
        T = poses[model.link_index(name)]
        out[name] = {
            "position": [float(v) for v in T[:3, 3]],
            "rpy": [float(v) for v in matrix_to_rpy(T[:3, :3])],
            "matrix": T.tolist(),
        }
    return {"robot": model.name, "q": [float(v) for v in q], "links": out}


def _finite(value: float) -> float | None:
    """JSON has no infinity: unbounded limits are written as null."""
    return value if math.isfinite(value) else None
