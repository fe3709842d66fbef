"""FK and Jacobian throughput, prehensile vs pinocchio, single and batched.

Run: ``python benchmarks/fk_throughput.py [--robots panda nao armar3] [--out FILE]``.
pinocchio is called from Python in a loop (its batched use from Python); both compute every
link pose (pinocchio: framesForwardKinematics) and one frame Jacobian of the deepest link.
Writes benchmarks/results/fk_throughput.json and prints a table of medians and ratios.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numba
import numpy as np
import pinocchio as pin
from common import machine, median_seconds

from prehensile import robots
from prehensile.kinematics import forward_kinematics, frame_jacobian
from prehensile.storage import atomic_write_json

BATCHES = (1, 100, 10_000)


def pinocchio_for(model):
    pin_model = pin.buildModelFromUrdf(model.source)
    return pin_model, pin_model.createData()


def pin_configurations(model, pin_model, q: np.ndarray) -> np.ndarray:
    """Our configurations (n, dof) in pinocchio's layout (mimic joints follow their leader)."""
    out = np.tile(pin.neutral(pin_model), (len(q), 1))
    for link, joint_name in enumerate(model.link_joint_names):
        if joint_name and model.joint_q_index[link] >= 0 and pin_model.existJointName(joint_name):
            value = model.joint_multiplier[link] * q[:, model.joint_q_index[link]] + model.joint_offset[link]
            joint = pin_model.joints[pin_model.getJointId(joint_name)]
            if joint.nq == 2:
                out[:, joint.idx_q], out[:, joint.idx_q + 1] = np.cos(value), np.sin(value)
            else:
                out[:, joint.idx_q] = value
    return out


def bench_robot(name: str, rng: np.random.Generator) -> dict:
    model = robots.load(name)
    pin_model, pin_data = pinocchio_for(model)
    tip = model.link_names[max(range(model.n_links), key=lambda i: len(model.path_to_root(i)))]
    frame_id = pin_model.getFrameId(tip, pin.BODY)
    rows = {}
    for batch in BATCHES:
        q = model.random_configurations(rng, batch)
        pq = pin_configurations(model, pin_model, q)
        single = q[0].copy()
        repeats, number = (7, 2000) if batch == 1 else (5, 1)

        def pin_fk():
            for row in pq:
                pin.framesForwardKinematics(pin_model, pin_data, row)

        def pin_jac():
            for row in pq:
                pin.computeFrameJacobian(pin_model, pin_data, row, frame_id, pin.LOCAL_WORLD_ALIGNED)

        ours_fk = (lambda: forward_kinematics(model, single)) if batch == 1 else (lambda: forward_kinematics(model, q))
        ours_jac = (lambda: frame_jacobian(model, single, tip)) if batch == 1 else (lambda: frame_jacobian(model, q, tip))
        t = {
            "fk_us_per_config": median_seconds(ours_fk, repeats, number) / batch * 1e6,
            "pin_fk_us_per_config": median_seconds(pin_fk, repeats, number) / batch * 1e6,
            "jacobian_us_per_config": median_seconds(ours_jac, repeats, number) / batch * 1e6,
            "pin_jacobian_us_per_config": median_seconds(pin_jac, repeats, number) / batch * 1e6,
        }
        t["fk_ratio_ours_over_pin"] = t["fk_us_per_config"] / t["pin_fk_us_per_config"]
        t["jacobian_ratio_ours_over_pin"] = t["jacobian_us_per_config"] / t["pin_jacobian_us_per_config"]
        rows[str(batch)] = t
    return {"dof": model.dof, "links": model.n_links, "jacobian_link": tip, "batches": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["panda", "nao", "armar3"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "fk_throughput.json")
    args = parser.parse_args()
    numba.set_num_threads(1)
    rng = np.random.default_rng(args.seed)
    results = {name: bench_robot(name, rng) for name in args.robots}
    print(f"{'robot':8} {'batch':>6} {'fk us':>8} {'pin us':>8} {'ratio':>6} {'jac us':>8} {'pin us':>8} {'ratio':>6}")
    for name, result in results.items():
        for batch, t in result["batches"].items():
            print(
                f"{name:8} {batch:>6} {t['fk_us_per_config']:8.3f} {t['pin_fk_us_per_config']:8.3f} "
                f"{t['fk_ratio_ours_over_pin']:6.2f} {t['jacobian_us_per_config']:8.3f} "
                f"{t['pin_jacobian_us_per_config']:8.3f} {t['jacobian_ratio_ours_over_pin']:6.2f}"
            )
    atomic_write_json(args.out, {"benchmark": "fk_throughput", "seed": args.seed, "machine": machine(), "robots": results})
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
