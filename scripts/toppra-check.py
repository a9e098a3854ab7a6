#!/usr/bin/env python3
"""Dev-only: compare `host-sim retime` with an independent TOPP-RA (the `toppra` package).

For each DIR (an output of `host-sim plan` or `rollout`) and each acceleration limit, runs
`host-sim retime DIR --out TMP --accel-deg-s2 A` and toppra on the same path: the written
trajectory.csv of DIR, parameterised by joint-space arc length (s = t fails at rest-to-rest
ends), a cubic spline through the samples, the URDF rate limits and the same acceleration
limit, 3000 grid points. Prints a Markdown table; exits 1 if any duration differs by more
than 1 % plus one dt.

    python3 -m venv /tmp/tvenv && /tmp/tvenv/bin/pip install toppra
    /tmp/tvenv/bin/python scripts/toppra-check.py --host-sim target/release/host-sim \
        --accel 5,1 DIR...

Not a runtime dependency of anything.
"""
import argparse
import json
import pathlib
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET

import numpy as np
import toppra as ta
import toppra.algorithm as algo
import toppra.constraint as constraint

ta.setup_logging("WARNING")


def read_plan(d):
    rows = np.loadtxt(d / "trajectory.csv", delimiter=",", skiprows=1)
    n = (rows.shape[1] - 1) // 2
    q = rows[:, 1 : 1 + n]
    root = ET.parse(d / "robot.urdf").getroot()
    vmax = [
        float(j.find("limit").get("velocity"))
        for j in root.iter("joint")
        if j.get("type") == "revolute"
    ]
    assert len(vmax) == n, (len(vmax), n)
    return rows[1, 0] - rows[0, 0], q, np.array(vmax)


def toppra_duration(q, vmax, amax, grid):
    step = np.linalg.norm(np.diff(q, axis=0), axis=1)
    keep = np.concatenate([[True], step > 0])
    q = q[keep]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])
    path = ta.SplineInterpolator(s, q)
    pc_vel = constraint.JointVelocityConstraint(np.stack([-vmax, vmax], axis=1))
    pc_acc = constraint.JointAccelerationConstraint(np.stack([-amax, amax], axis=1))
    inst = algo.TOPPRA(
        [pc_vel, pc_acc], path, gridpoints=np.linspace(0, s[-1], grid), parametrizer="ParametrizeConstAccel"
    )
    t0 = time.perf_counter()
    traj = inst.compute_trajectory(0, 0)
    wall = time.perf_counter() - t0
    return traj.duration, wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", type=pathlib.Path)
    ap.add_argument("--host-sim", default="target/release/host-sim")
    ap.add_argument("--accel", default="5,1", help="deg/s^2, comma-separated")
    ap.add_argument("--grid", type=int, default=3000, help="toppra grid points")
    args = ap.parse_args()
    ok = True
    print("| plan | N | accel (°/s²) | toppra (s) | host-sim minimum (s) | written (s) | difference | toppra wall (ms) |")
    print("|---|---|---|---|---|---|---|---|")
    for d in args.dirs:
        dt, q, vmax = read_plan(d)
        for a in [float(x) for x in args.accel.split(",")]:
            amax = np.full(q.shape[1], np.radians(a))
            t_ref, wall = toppra_duration(q, vmax, amax, args.grid)
            with tempfile.TemporaryDirectory() as tmp:
                out = pathlib.Path(tmp) / "rt"
                subprocess.run(
                    [args.host_sim, "retime", str(d), "--out", str(out), "--accel-deg-s2", str(a)],
                    check=True,
                    capture_output=True,
                )
                s = json.loads((out / "summary.json").read_text())
            diff = (s["optimal_duration_s"] - t_ref) / t_ref
            good = abs(s["duration_s"] - t_ref) <= 0.01 * t_ref + dt
            ok &= good
            print(
                f"| {d.name} | {q.shape[1]} | {a:g} | {t_ref:.3f} | {s['optimal_duration_s']:.3f} | "
                f"{s['duration_s']:.2f} | {100 * diff:+.2f} %{'' if good else ' FAIL'} | {1000 * wall:.0f} |"
            )
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
