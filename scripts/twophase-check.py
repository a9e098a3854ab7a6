#!/usr/bin/env python3
"""Independent re-check of a two-phase plan (issue #30, spec §15) with Pinocchio.

PLANDIR is the output of `host-sim plan` for a task with `[preshape]`: task.toml,
robot.urdf, plan.json, phase1.csv and phase2/ (an ordinary plan bundle).

Phase 1 (attitude controlled): for every written sample (q, q̇) of phase1.csv, Pinocchio's
centroidal map (`pin.computeCentroidalMap`, the free-flyer model of robot.urdf) gives the
momentum about the system CoM of the robot with the base attitude held (base angular
velocity 0) and the base translating so that the linear momentum is 0; the wheels hold
minus its angular part. Compared with plan.json: the largest |h_w| (N m s), the largest
|h_w(k+1) - h_w(k)|/dt (N m), and the base shift at q_s (the CoM of the start, base at the
origin, minus that of q_s: `pin.centerOfMass`). The end effector at q_s (base at the shift,
attitude identity) must keep the standoff of task.toml's `[preshape]` from the target.

Phase 2 (free floating): scripts/disperse-check.py on PLANDIR/phase2 (base attitude
integrated along the written path by Pinocchio's momentum, base disturbance and truth end
pose against phase2/summary.json).

Exit 0 if everything agrees (relative 1e-6, absolute 1e-12), 1 if not, 2 on bad input.

    /tmp/pin-venv/bin/python scripts/twophase-check.py PLANDIR
"""

from __future__ import annotations

import importlib.util
import json
import math
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
spec = importlib.util.spec_from_file_location("disperse_check", HERE / "disperse-check.py")
dc = importlib.util.module_from_spec(spec)
spec.loader.exec_module(dc)
pin = dc.pin


def agree(a: float, b: float, rtol: float = 1e-6, atol: float = 1e-12) -> bool:
    return abs(a - b) <= max(rtol * max(abs(a), abs(b)), atol)


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    d = Path(sys.argv[1])
    try:
        task = tomllib.loads((d / "task.toml").read_text())
        plan = json.loads((d / "plan.json").read_text())
        task2 = tomllib.loads((d / "phase2" / "task.toml").read_text())
    except (OSError, ValueError) as e:
        print(f"twophase-check: {d}: {e}", file=sys.stderr)
        return 2
    urdf = dc.normalized_urdf(d / "robot.urdf")
    ee_link = task["robot"].get("ee_link") or dc.leaf_link(urdf)
    q0 = np.radians(np.array(task["start"]["q_deg"], dtype=float))
    qs = np.radians(np.array(task2["start"]["q_deg"], dtype=float))
    ff = dc.FreeFloating(urdf, ee_link, len(q0))
    t, q = dc.read_trajectory(d / "phase1.csv")
    qd = np.loadtxt(d / "phase1.csv", delimiter=",", skiprows=1)[:, 1 + len(q0) :][:, : len(q0)]
    dt = float(task["motion"]["dt_s"])
    hw = []
    for qa, qda in zip(q, qd):
        ab, am = ff.centroidal(ff.config(qa))
        # Base angular velocity 0 (held); linear velocity v so that the linear momentum is 0.
        v = np.linalg.solve(ab[0:3, 0:3], -am[0:3] @ qda)
        h = ab[3:6, 0:3] @ v + am[3:6] @ qda
        hw.append(-h)
    hw = np.array(hw)
    momentum = float(np.max(np.linalg.norm(hw, axis=1)))
    torque = float(np.max(np.linalg.norm(np.diff(hw, axis=0), axis=1) / dt)) if len(hw) > 1 else 0.0
    c0 = ff.com(ff.config(q0))
    cs = ff.com(ff.config(qs))
    shift = c0 - cs
    p1 = plan["phase1"]
    rows = [
        ("phase 1 largest |h_w| (N m s)", p1["momentum_nms"], momentum),
        ("phase 1 largest |dh_w/dt| (N m)", p1["torque_nm"], torque),
    ] + [(f"base shift {'xyz'[i]} (m)", p1["base_shift_m"][i], float(shift[i])) for i in range(3)]
    ok = True
    print(f"{'quantity':<34} {'host-sim':>22} {'Pinocchio':>22}  agree")
    for name, a, b in rows:
        good = agree(a, b, atol=1e-9 if "shift" in name else 1e-12)
        ok &= good
        print(f"{name:<34} {a:>22.15g} {b:>22.15g}  {'yes' if good else 'NO'}")
    # The standoff at q_s, in the task's frame: the base at the shift, attitude identity.
    p, r = ff.ee_pose(ff.config(qs, pos=shift))
    target_p = np.array(task["target"]["position_m"], dtype=float)
    target_r = dc.quat_to_matrix(np.array(task["target"]["quat_wxyz"], dtype=float))
    dist = float(np.linalg.norm(target_p - p))
    ang = math.degrees(dc.rotation_angle(target_r @ r.T))
    pre = {"standoff_m": 0.2, "standoff_deg": 10.0} | task.get("preshape", {})
    kept = dist >= pre["standoff_m"] or ang >= pre["standoff_deg"]
    ok &= kept
    print(
        f"standoff at q_s: {dist:.6g} m, {ang:.6g} deg from the target "
        f"(needs >= {pre['standoff_m']} m or >= {pre['standoff_deg']} deg): {'yes' if kept else 'NO'}"
    )
    # Phase 2: the ordinary bundle, with the existing check.
    r2 = subprocess.run(
        [sys.executable, str(HERE / "disperse-check.py"), "--urdf", str(d / "phase2" / "robot.urdf"),
         "--dir", str(d / "phase2")],
        check=False,
    )
    ok &= r2.returncode == 0
    print(f"twophase-check: {'PASS' if ok else 'FAIL'} ({d})")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
