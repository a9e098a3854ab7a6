#!/usr/bin/env python3
"""Dev-only: make benchmark tasks whose unconstrained plan collides with a keep-out (issue
#33).

For each source task (a reachable target, no collision tables), this:
1. moves it to the free-amplitude family in as many segments as fit, at most 2
   (`[motion] family`, `segments`), and plans it (seed 1): the unconstrained plan P0;
2. takes the point of P0's end-effector path farthest from both its ends (every tenth
   sample; Pinocchio, a free-flyer root, the base shifted so that the system centre of
   mass stays at its start: the planner model of spec §1), and puts a sphere of `--radius`
   beside it, its centre `--radius + --offset` away along the path's normal
   `t × z` (`t` the path's direction there): with `--offset` below the radius of the
   arm's last primitive, the unconstrained plan runs into it;
3. asks for `--clearance`, and keeps the task only if `host-sim check` fails P0 on the
   keep-out and on nothing else (a target whose own plan self-collides is not a keep-out
   benchmark) and the new task loads (the sphere clears the start).

Reactionless paths to one target form a thin family (plans with other seeds run within a
few millimetres of P0 on arm9, within 8 cm on arm12, in the paper's family), so a keep-out
on the path's axis leaves no way around it; one beside the path, intruding by a few
centimetres, does, in the free-amplitude family far more often than in the paper's. Whether the planner finds a collision-free plan is what a campaign
over the set measures.

    /tmp/pin-venv/bin/python scripts/blocked-set.py --host-sim target/release/host-sim \
        --out tests/tasks/collision/blocked --radius 0.1 --offset 0.02 --clearance 0.02 \
        tests/tasks/{a,b}/{chaser7,arm9,arm12}/task_0*.toml

Prints one line per source task. Not a runtime dependency of anything.
"""
import argparse
import csv
import json
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import tomllib

import numpy as np
import pinocchio as pin


def ee_path(plan: pathlib.Path, ee_link: str) -> list:
    """The end effector's position at every tenth sample and the last (m, inertial)."""
    model = pin.buildModelFromUrdf(str(plan / "robot.urdf"), pin.JointModelFreeFlyer())
    data = model.createData()
    frame = model.getFrameId(ee_link)
    rows = list(csv.DictReader(open(plan / "trajectory.csv")))
    n = model.nq - 7
    root = np.array([0, 0, 0, 0, 0, 0, 1.0])

    def at(row):
        q = np.concatenate([root, [float(row[f"q{j + 1}"]) for j in range(n)]])
        com = pin.centerOfMass(model, data, q)
        pin.updateFramePlacements(model, data)
        return data.oMf[frame].translation.copy(), com.copy()

    _, com0 = at(rows[0])
    path = []
    for row in rows[::10] + [rows[-1]]:
        p, com = at(row)
        path.append(p + (com0 - com))
    return path


def blocker(p0: list, radius: float, offset: float):
    """The sphere's centre beside P0's path where the path is farthest from its ends."""
    def room(i):
        return min(np.linalg.norm(p0[i] - p0[0]), np.linalg.norm(p0[i] - p0[-1]))
    i = max(range(1, len(p0) - 1), key=room)
    t = p0[i + 1] - p0[i - 1]
    n = np.cross(t, [0.0, 0.0, 1.0])
    if np.linalg.norm(n) < 1e-9 * np.linalg.norm(t):
        n = np.cross(t, [1.0, 0.0, 0.0])
    return p0[i] + n / np.linalg.norm(n) * (radius + offset)


def check(hs, plan: pathlib.Path, task_text: str, out: pathlib.Path):
    """`host-sim check` of `plan` against `task_text`: the pairs below the clearance, or
    None if check refused the task."""
    (plan / "task.toml").write_text(task_text)
    if out.exists():
        out.unlink()
    subprocess.run([hs, "check", plan, "--clearance-json", out], capture_output=True, text=True)
    if not out.exists():
        return None
    d = json.loads(out.read_text())
    return [p for p in d["pairs"] if p["min_m"] < d["required_m"]]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--host-sim", required=True, type=pathlib.Path)
    ap.add_argument("--out", required=True, type=pathlib.Path)
    ap.add_argument("--radius", type=float, default=0.1)
    ap.add_argument("--clearance", type=float, default=0.02)
    ap.add_argument("--offset", type=float, default=0.02)
    ap.add_argument("sources", nargs="+", type=pathlib.Path)
    a = ap.parse_args()
    hs = a.host_sim.resolve()
    kept = 0
    for src in a.sources:
        src = src.resolve()
        robot = src.parent.name
        dest = (a.out / robot / f"{src.parent.parent.name}-{src.name}").resolve()
        with tempfile.TemporaryDirectory() as tmp:
            tmp = pathlib.Path(tmp)
            task = tomllib.loads(src.read_text())
            # The free-amplitude family in as many segments as fit, at most 2: the paper's
            # family cannot bend a path to one target around a keep-out (docs/collision.md).
            joints = len(task["start"]["q_deg"])
            segments = min(2, 32 // (2 * (joints - 3)))
            source = re.sub(r"^\[motion\]$",
                            f'[motion]\nfamily = "free_amplitude"\nsegments = {segments}',
                            src.read_text(), count=1, flags=re.M)
            staged = tmp / "source.toml"
            staged.write_text(re.sub(r'^urdf = ".*"$',
                                     f'urdf = "{(src.parent / task["robot"]["urdf"]).resolve()}"',
                                     source, count=1, flags=re.M))
            free = tmp / "free"
            r = subprocess.run([hs, "plan", staged, "--out", free, "--seed", "1"],
                               capture_output=True, text=True)
            if r.returncode != 0:
                print(f"{robot}/{dest.name}: skipped, the unconstrained plan did not converge")
                continue
            c = blocker(ee_path(free, task["robot"]["ee_link"]), a.radius, a.offset)
            urdf = (src.parent / task["robot"]["urdf"]).resolve()
            rel = os.path.relpath(urdf, dest.parent)
            base = re.sub(r'^urdf = ".*"$', f'urdf = "{rel}"', source, count=1,
                          flags=re.M).rstrip("\n")
            text = base + (
                "\n\n# Beside the unconstrained plan's end-effector path, midway"
                " (scripts/blocked-set.py).\n"
                f'[[keep_out]]\nname = "blocker"\nshape = "sphere"\n'
                f"position_m = [{float(c[0])!r}, {float(c[1])!r}, {float(c[2])!r}]\n"
                f"radius_m = {a.radius!r}\n\n"
                f"[collision]\nclearance_m = {a.clearance!r}\n"
            )
            local = text.replace(f'urdf = "{rel}"', f'urdf = "{urdf}"', 1)
            bad = check(hs, free, local, tmp / "c.json")
            if bad is None:
                print(f"{robot}/{dest.name}: skipped, the sphere touches the start")
                continue
            if not any(p["b_is_keep_out"] for p in bad):
                print(f"{robot}/{dest.name}: skipped, the plan does not reach the keep-out")
                continue
            if any(not p["b_is_keep_out"] for p in bad):
                names = ", ".join(f"{p['a']}-{p['b']}" for p in bad if not p["b_is_keep_out"])
                print(f"{robot}/{dest.name}: skipped, its plan self-collides ({names})")
                continue
            dest.parent.mkdir(parents=True, exist_ok=True)
            dest.write_text(text)
            kept += 1
            worst = min(p["min_m"] for p in bad)
            print(f"{robot}/{dest.name}: kept, unconstrained plan at {worst:.4f} m")
    print(f"{kept} of {len(a.sources)} kept")
    return 0


if __name__ == "__main__":
    sys.exit(main())
