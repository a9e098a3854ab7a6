#!/usr/bin/env python3
"""Independent re-check of host-sim's truth model of a joint path, with Pinocchio.

What it checks
--------------
The joint path flown is the (t, q) rows of PLANDIR/trajectory.csv (as `host-sim check`
reads it).  The robot is ROBOT.urdf, loaded with Pinocchio
(`pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())`), so the kinematics and the
momentum come from Pinocchio and not from the project's Rust code.  The base attitude is
integrated along the path with the project's discretisation (spec §5 / §11):

- the joint path is piecewise linear between rows; each segment is split into
  TRUTH_SUBSTEPS = 10 midpoint sub-steps: q_mid = q_a + (j + 1/2)/m (q_b - q_a),
  dq = (q_b - q_a)/m, dt = (t_b - t_a)/m;
- at q_mid, with the base at its current attitude R0, the centroidal momentum matrix
  A_g(q) (`pin.computeCentroidalMap`, momentum about the system CoM, world frame) gives
  h_g = A_g,base x + A_g,arm dq for the base displacement x = [v dt; dtheta] (base frame,
  Pinocchio's free-flyer velocity); the 6x6 system  A_g,base x = [0; L dt] - A_g,arm dq
  (zero linear momentum: the system CoM stays put; angular momentum L, constant, inertial
  frame) is solved for x;
- the attitude is updated by the SO(3) exponential: R0 <- normalized(R0 (x) exp(dtheta))
  (quaternion, `pin.exp3`);
- L = 0 unless an initial base rate w0 (base frame, arm at rest at t = 0) is given; then L
  is the angular momentum of the system at q0 with base velocity [v; w0], v chosen so that
  the linear momentum is zero (i.e. L = H~b(q0) w0, the locked inertia about the CoM);
- the end pose: the base at the final attitude, placed so that the system CoM
  (`pin.centerOfMass`) is where it was at t = 0 (base at the origin, identity attitude, q0
  of task.toml); the end-effector frame is `[robot] ee_link` of task.toml (or the only
  leaf link).

Figures: base disturbance = the largest base rotation angle over the motion (deg, after
every sub-step); final attitude error = the base rotation angle at the end (deg); against
the task target (`[target] position_m`, `quat_wxyz`): position error |p_des - p| (m) and
orientation error = angle of R_des R^T (deg).

Expected values:
- without --runs: PLANDIR/summary.json (`base_disturbance_deg`; position and orientation
  error of `truth_end_pose` against the target; `truth_f`; the pose itself), zero momentum;
- with --runs RUNS.csv --sample K: the row `sample == K` (`base_disturbance_deg`,
  `final_attitude_error_deg`, `position_error_m`, `orientation_error_deg`, `f`), the initial
  base rate from `base_rate_{x,y,z}_deg_s` (deg/s, base frame; host-sim always writes them,
  0.0 when not dispersed, so a missing column is an input error). ROBOT.urdf is then the
  dispersed robot of that sample (`host-sim disperse PLANDIR --seed S [the same sigma flags]
  --export-sample K --out sample.urdf`). Before flying, the row's drawn parameters
  (`LINK.mass_kg`, `LINK.com_{x,y,z}_m`, `LINK.i{xx,xy,xz,yy,yz,zz}_kg_m2`,
  `JOINT.axis_{x,y,z}`) are compared with the URDF's (they must be the same numbers to
  1e-12 relative): a URDF exported with another seed, other sigma flags or another sample
  is reported as such (exit 1) instead of as a disagreement of the figures.

The sub-step count hardly matters at the 1e-6 tolerance (on the reference plan, 10 against
20 sub-steps moves the base disturbance by ~2e-7 relative, a dispersed sample's by ~1e-9):
the check tests the dynamics and kinematics; agreeing to ~1e-13, as observed, also shows the
same scheme.

Prints a table (quantity, host-sim, independent, relative difference); exit 0 if every
quantity agrees (|a - b| <= rtol max(|a|, |b|), or |a - b| <= atol for values ~0) and, with
--runs, the drawn parameters match the URDF; 1 if not, 2 on bad input.

Install and run
---------------
    python3 -m venv /tmp/pin-venv && /tmp/pin-venv/bin/pip install pin numpy
    /tmp/pin-venv/bin/python scripts/disperse-check.py --urdf PLANDIR/robot.urdf --dir PLANDIR
    /tmp/pin-venv/bin/python scripts/disperse-check.py --urdf sample.urdf --dir PLANDIR \\
        --runs DISPERSE_OUT/runs.csv --sample K

Python >= 3.11 (tomllib).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

try:
    import pinocchio as pin
except ImportError:  # pragma: no cover - message for a missing install
    sys.exit(
        "disperse-check: Pinocchio is not installed; "
        "python3 -m venv /tmp/pin-venv && /tmp/pin-venv/bin/pip install pin numpy"
    )

TRUTH_SUBSTEPS = 10  # host-sim/src/artifacts.rs


def fail_input(msg: str) -> None:
    print(f"disperse-check: {msg}", file=sys.stderr)
    sys.exit(2)


# ----------------------------------------------------------------------------- quaternions
# [w, x, y, z], Hamilton product, body -> inertial (p_I = R(q) p_B), as host-sim writes them.


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def quat_from_matrix(r: np.ndarray) -> np.ndarray:
    q = pin.Quaternion(r)
    q.normalize()
    return np.array([q.w, q.x, q.y, q.z])


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()


def quat_angle(q: np.ndarray) -> float:
    """Rotation angle (rad, [0, pi]) of a unit quaternion, accurate for tiny angles."""
    return 2.0 * math.atan2(float(np.linalg.norm(q[1:])), abs(float(q[0])))


def rotation_angle(r: np.ndarray) -> float:
    """Rotation angle (rad) of a rotation matrix, via its quaternion (accurate near 0)."""
    return quat_angle(quat_from_matrix(r))


# ----------------------------------------------------------------------------- inputs


def normalized_urdf(path: Path) -> str:
    """The URDF text with every joint axis normalised (host-sim normalises axes within
    1e-6 of unit length; Pinocchio expects unit axes)."""
    try:
        tree = ET.parse(path)
    except (OSError, ET.ParseError) as e:
        fail_input(f"{path}: cannot read URDF: {e}")
    for axis in tree.getroot().iter("axis"):
        xyz = axis.get("xyz")
        if xyz is None:
            continue
        v = np.array([float(s) for s in xyz.split()])
        n = float(np.linalg.norm(v))
        if n > 0.0 and n != 1.0:
            axis.set("xyz", " ".join(repr(float(c)) for c in v / n))
    return ET.tostring(tree.getroot(), encoding="unicode")


def read_trajectory(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(t, q) of trajectory.csv: header t,q1..qN,qd1..qdN[,qdd1..qddN] (s, rad)."""
    try:
        lines = path.read_text().splitlines()
    except OSError as e:
        fail_input(f"{path}: {e}")
    if not lines:
        fail_input(f"{path}: empty file")
    header = lines[0].split(",")
    if header[0] != "t":
        fail_input(f"{path}: header {lines[0]!r} does not start with t")
    qcols = [i for i, h in enumerate(header) if h.startswith("q") and h[1:].isdigit()]
    n = len(qcols)
    if n == 0 or [header[i] for i in qcols] != [f"q{k}" for k in range(1, n + 1)]:
        fail_input(f"{path}: header {lines[0]!r}: no q1..qN columns")
    rows = [[float(v) for v in line.split(",")] for line in lines[1:] if line]
    data = np.array(rows)
    if data.ndim != 2 or data.shape[1] != len(header):
        fail_input(f"{path}: rows do not match the header")
    return data[:, 0], data[:, qcols]


def leaf_link(urdf_text: str) -> str:
    root = ET.fromstring(urdf_text)
    links = [l.get("name") for l in root.iter("link")]
    parents = {j.find("parent").get("link") for j in root.iter("joint")}
    leaves = [l for l in links if l not in parents]
    if len(leaves) != 1:
        fail_input(f"several leaf links ({', '.join(leaves)}); name the end effector")
    return leaves[0]


_INERTIA_FIELDS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def drawn_parameters_vs_urdf(path: Path, row: dict[str, str]) -> tuple[int, list[str]]:
    """Compares the drawn parameters of a runs.csv row (`LINK.mass_kg`, `LINK.com_{x,y,z}_m`,
    `LINK.i.._kg_m2`, `JOINT.axis_{x,y,z}`) with the raw attributes of the URDF at `path`.
    Returns (how many were compared, descriptions of those that differ)."""
    root = ET.parse(path).getroot()
    links = {l.get("name"): l for l in root.iter("link")}
    joints = {j.get("name"): j for j in root.iter("joint")}

    def vec(elem, tag, attr, default):
        e = None if elem is None else elem.find(tag)
        v = None if e is None else e.get(attr)
        return default if v is None else [float(x) for x in v.split()]

    compared, bad = 0, []
    for key, text in row.items():
        if key is None or "." not in key:
            continue
        name, field = key.split(".", 1)
        inertial = links[name].find("inertial") if name in links else None
        want: float | None = None
        if field == "mass_kg":
            m = None if inertial is None else inertial.find("mass")
            want = None if m is None else float(m.get("value"))
        elif field in ("com_x_m", "com_y_m", "com_z_m"):
            if inertial is not None:
                want = vec(inertial, "origin", "xyz", [0.0, 0.0, 0.0])["xyz".index(field[4])]
        elif field.endswith("_kg_m2") and field[:-6] in _INERTIA_FIELDS:
            i = None if inertial is None else inertial.find("inertia")
            want = None if i is None else float(i.get(field[:-6], "0"))
        elif field in ("axis_x", "axis_y", "axis_z"):
            if name in joints:
                # URDF's default axis is (1, 0, 0).
                want = vec(joints[name], "axis", "xyz", [1.0, 0.0, 0.0])["xyz".index(field[5])]
        else:
            continue  # not a drawn parameter this script knows
        compared += 1
        got = float(text)
        if want is None:
            bad.append(f"{key}: {got!r} in the row, nothing in the URDF")
        elif abs(got - want) > 1e-12 * max(abs(got), abs(want)) + 1e-300:
            bad.append(f"{key}: {got!r} in the row, {want!r} in the URDF")
    return compared, bad


# ----------------------------------------------------------------------------- the model


class FreeFloating:
    """Pinocchio model of the free-floating robot with the arm joints of the chain from the
    root link to the end-effector link, in trajectory-column order."""

    def __init__(self, urdf_text: str, ee_link: str, n: int):
        self.model = pin.buildModelFromXML(urdf_text, pin.JointModelFreeFlyer())
        self.data = self.model.createData()
        m = self.model
        if not m.existFrame(ee_link):
            fail_input(f"end-effector link {ee_link!r} is not a frame of the Pinocchio model")
        self.ee = m.getFrameId(ee_link)
        # Joints from the end effector back to the free flyer (joint 1).
        chain = []
        j = m.frames[self.ee].parentJoint
        while j > 1:
            chain.append(j)
            j = m.parents[j]
        chain.reverse()
        if j != 1:
            fail_input("the end-effector link is not below the root link")
        if len(chain) != n:
            fail_input(f"the chain to {ee_link!r} has {len(chain)} joints, trajectory.csv {n}")
        if m.njoints != n + 2:
            fail_input(f"the model has {m.njoints - 2} arm joints off the chain too")
        for jid in chain:
            if m.joints[jid].nq != 1 or m.joints[jid].nv != 1:
                fail_input(f"joint {m.names[jid]!r} is not a revolute joint")
        self.joint_names = [m.names[jid] for jid in chain]
        self.iq = np.array([m.joints[jid].idx_q for jid in chain])
        self.iv = np.array([m.joints[jid].idx_v for jid in chain])
        self.n = n

    def config(self, q_arm: np.ndarray, quat_wxyz=None, pos=None) -> np.ndarray:
        """Pinocchio configuration: base at `pos` with attitude `quat_wxyz` (free flyer:
        x y z, quaternion x y z w), arm at `q_arm`."""
        q = pin.neutral(self.model)
        if pos is not None:
            q[0:3] = pos
        if quat_wxyz is not None:
            w, x, y, z = quat_wxyz
            q[3:7] = [x, y, z, w]
        q[self.iq] = q_arm
        return q

    def centroidal(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(A_g base columns 6x6, A_g arm columns 6xN): momentum about the CoM, world
        frame (linear; angular), for the free-flyer velocity (base frame) and joint rates."""
        ag = pin.computeCentroidalMap(self.model, self.data, q)
        return ag[:, 0:6], ag[:, self.iv]

    def base_step(self, q_arm, quat_wxyz, dq, l_dt) -> np.ndarray:
        """Base displacement [v dt; dtheta] (base frame) with zero linear momentum and
        angular momentum impulse l_dt (world frame) for the arm increment dq."""
        ab, am = self.centroidal(self.config(q_arm, quat_wxyz))
        rhs = np.concatenate([np.zeros(3), l_dt]) - am @ dq
        return np.linalg.solve(ab, rhs)

    def momentum_from_base_rate(self, q_arm, w0) -> np.ndarray:
        """L (world = base frame at t = 0, about the CoM) of the system at rest but for the
        base turning at w0 (base frame), with zero linear momentum."""
        ab, _ = self.centroidal(self.config(q_arm))
        # Linear momentum rows: ab[0:3, 0:3] v + ab[0:3, 3:6] w0 = 0.
        v = np.linalg.solve(ab[0:3, 0:3], -ab[0:3, 3:6] @ w0)
        return ab[3:6] @ np.concatenate([v, w0])

    def com(self, q: np.ndarray) -> np.ndarray:
        return pin.centerOfMass(self.model, self.data, q).copy()

    def ee_pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pin.framesForwardKinematics(self.model, self.data, q)
        oMf = self.data.oMf[self.ee]
        return oMf.translation.copy(), oMf.rotation.copy()


# ----------------------------------------------------------------------------- truth model


def integrate(ff, t, q, q0, w0, m=TRUTH_SUBSTEPS):
    """Integrates the base attitude along the path (t, q) with `m` midpoint sub-steps per
    segment, initial base rate w0 (rad/s, base frame, arm at rest at q0); returns a dict."""
    l = ff.momentum_from_base_rate(q0, w0) if np.any(w0 != 0.0) else np.zeros(3)
    att = np.array([1.0, 0.0, 0.0, 0.0])
    max_angle = 0.0
    for k in range(1, len(t)):
        a, b = q[k - 1], q[k]
        dq = (b - a) / m
        dt = (t[k] - t[k - 1]) / m
        for j in range(m):
            mid = a + ((j + 0.5) / m) * (b - a)
            x = ff.base_step(mid, att, dq, l * dt)
            d = quat_from_matrix(pin.exp3(x[3:6]))
            att = quat_mul(att, d)
            att = att / np.linalg.norm(att)
            max_angle = max(max_angle, quat_angle(att))
    # End pose: base at the final attitude, placed by CoM conservation.
    com0 = ff.com(ff.config(q0))
    q_end = ff.config(q[-1], att)
    shift = com0 - ff.com(q_end)
    q_end[0:3] = shift
    p, r = ff.ee_pose(q_end)
    return {"momentum": l, "attitude": att, "max_angle": max_angle, "position": p, "rotation": r}


def pose_errors(p, r, target_p, target_r) -> tuple[float, float, float]:
    """(|p_des - p| m, angle of R_des R^T rad, f = |[dp; log(R_des R^T)]|)."""
    dp = target_p - p
    ang = rotation_angle(target_r @ r.T)
    return float(np.linalg.norm(dp)), ang, math.sqrt(float(dp @ dp) + ang * ang)


# ----------------------------------------------------------------------------- self-test


def self_test(ff: FreeFloating, t, q, q0) -> bool:
    """Checks of this implementation that need no host-sim output (--self-test)."""
    ok = True

    def report(name, value, limit):
        nonlocal ok
        passed = value <= limit
        ok &= passed
        print(f"  {name:<68} {value:10.3e} <= {limit:.0e}  {'pass' if passed else 'FAIL'}")

    print("self-test:")
    w0 = np.array([1e-3, -2e-3, 0.5e-3])
    # 1. L = H~b(q0) w0 two ways: A_g with zero linear momentum, and the locked inertia about
    #    the CoM of pin.ccrba (angular block of Ig).
    l = ff.momentum_from_base_rate(q0, w0)
    pin.ccrba(ff.model, ff.data, ff.config(q0), np.zeros(ff.model.nv))
    hb = ff.data.Ig.inertia.copy()
    report("L from A_g vs ccrba Ig.inertia w0 (relative)", np.linalg.norm(l - hb @ w0) / np.linalg.norm(l), 1e-12)
    # 2. The arm at rest for 1 s (100 segments): the base turns at |w0| to first order
    #    (src/path/truth.rs, a_base_rate_at_rest_turns_the_base_at_hb_inverse_l).
    ts = np.arange(101) * 0.01
    qs = np.tile(q0, (101, 1))
    r = integrate(ff, ts, qs, q0, w0)
    report("arm at rest: max angle vs |w0| * 1 s (relative)", abs(r["max_angle"] - np.linalg.norm(w0)) / np.linalg.norm(w0), 1e-5)
    # 3. ... and the torque-free rigid body: RK4 of dq/dt = q (x) [0, w]/2, w = I^-1 R^T L,
    #    1e4 steps; the sub-step scheme agrees to its discretisation error (first order in
    #    L dt: R0 is the attitude at the start of the sub-step, as in src/path/truth.rs).
    hb_inv = np.linalg.inv(hb)

    def rate(qq):
        w = hb_inv @ (quat_to_matrix(qq).T @ l)
        return 0.5 * quat_mul(qq, np.concatenate([[0.0], w]))

    qq = np.array([1.0, 0.0, 0.0, 0.0])
    h = 1e-4
    for _ in range(10000):
        k1 = rate(qq)
        k2 = rate(qq + 0.5 * h * k1)
        k3 = rate(qq + 0.5 * h * k2)
        k4 = rate(qq + h * k3)
        qq = qq + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        qq /= np.linalg.norm(qq)
    diff = quat_angle(quat_mul(np.array([qq[0], *(-qq[1:])]), r["attitude"]))
    report("arm at rest: attitude vs RK4 rigid body, 1 s (rad / angle)", diff / quat_angle(qq), 1e-6)
    # 4. Momentum conservation at the end: R0 H~b w = L with w = H~b^-1 R0^T L.
    r0 = quat_to_matrix(r["attitude"])
    ab, _ = ff.centroidal(ff.config(q0, r["attitude"]))
    x = np.linalg.solve(ab, np.concatenate([np.zeros(3), l]))
    h_end = pin.computeCentroidalMomentum(
        ff.model, ff.data, ff.config(q0, r["attitude"]), np.concatenate([x, np.zeros(ff.n)])
    )
    report("arm at rest: |h_g(end) - [0; L]| / |L| (pin.computeCentroidalMomentum)",
           np.linalg.norm(np.concatenate([h_end.linear, h_end.angular - l])) / np.linalg.norm(l), 1e-12)
    report("arm at rest: |R0 H~b w - L| / |L|", np.linalg.norm(r0 @ hb @ (hb_inv @ (r0.T @ l)) - l) / np.linalg.norm(l), 1e-12)
    # 5. Zero momentum, arm at rest: nothing moves, exactly.
    r = integrate(ff, ts[:11] * 100, qs[:11], q0, np.zeros(3))
    report("zero momentum, arm at rest: max angle (rad)", r["max_angle"], 0.0)
    # 6. The path of --dir with w0: 10 sub-steps against 40 (discretisation error, relative).
    a = integrate(ff, t, q, q0, w0)
    b = integrate(ff, t, q, q0, w0, m=40)
    report("path with w0: base disturbance, 10 vs 40 sub-steps (relative)", abs(a["max_angle"] - b["max_angle"]) / b["max_angle"], 1e-6)
    report("path with w0: end position, 10 vs 40 sub-steps (m)", float(np.linalg.norm(a["position"] - b["position"])), 1e-6)
    return ok


# ----------------------------------------------------------------------------- main


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--urdf", required=True, type=Path, help="robot URDF (nominal or dispersed)")
    ap.add_argument("--dir", required=True, type=Path, help="host-sim plan output directory")
    ap.add_argument("--runs", type=Path, help="runs CSV of host-sim disperse")
    ap.add_argument("--sample", type=int, help="sample of --runs to compare with")
    ap.add_argument("--rtol", type=float, default=1e-6, help="relative tolerance (1e-6)")
    ap.add_argument("--atol", type=float, default=1e-12, help="absolute floor (1e-12)")
    ap.add_argument(
        "--self-test", action="store_true",
        help="also check this implementation (momentum conservation, rigid-body rotation)",
    )
    args = ap.parse_args()
    if (args.runs is None) != (args.sample is None):
        fail_input("--runs and --sample go together")
    started = time.perf_counter()

    try:
        task = tomllib.loads((args.dir / "task.toml").read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        fail_input(f"{args.dir / 'task.toml'}: {e}")
    urdf_text = normalized_urdf(args.urdf)
    ee_link = task.get("robot", {}).get("ee_link") or leaf_link(urdf_text)
    q0 = np.array([math.radians(v) for v in task["start"]["q_deg"]])
    target_p = np.array(task["target"]["position_m"], dtype=float)
    tq = np.array(task["target"]["quat_wxyz"], dtype=float)
    target_r = quat_to_matrix(tq / np.linalg.norm(tq))
    t, q = read_trajectory(args.dir / "trajectory.csv")
    if q.shape[1] != len(q0):
        fail_input(f"trajectory.csv has {q.shape[1]} joints, [start] q_deg {len(q0)}")

    # Expected values.
    w0 = np.zeros(3)
    expected: dict[str, float] = {}
    if args.runs is None:
        try:
            summary = json.loads((args.dir / "summary.json").read_text())
        except (OSError, json.JSONDecodeError) as e:
            fail_input(f"{args.dir / 'summary.json'}: {e}")
        tp = summary["truth_end_pose"]
        hp = np.array(tp["position"], dtype=float)
        hr = quat_to_matrix(np.array(tp["quat_wxyz"], dtype=float))
        pe, oe, f = pose_errors(hp, hr, target_p, target_r)
        expected = {
            "base_disturbance_deg": float(summary["base_disturbance_deg"]),
            "position_error_m": pe,
            "orientation_error_deg": math.degrees(oe),
            "truth_f": float(summary["truth_f"]),
        }
        source = f"{args.dir / 'summary.json'}"
    else:
        try:
            with open(args.runs, newline="") as fh:
                rows = [r for r in csv.DictReader(fh)]
        except OSError as e:
            fail_input(f"{args.runs}: {e}")
        row = next((r for r in rows if r.get("sample", "").strip() == str(args.sample)), None)
        if row is None:
            fail_input(f"{args.runs}: no row with sample == {args.sample}")
        for key in (
            "base_disturbance_deg",
            "final_attitude_error_deg",
            "position_error_m",
            "orientation_error_deg",
            "f",
        ):
            if key not in row:
                fail_input(f"{args.runs}: no column {key}")
            expected[key] = float(row[key])
        rate_cols = [f"base_rate_{c}_deg_s" for c in "xyz"]
        missing = [c for c in rate_cols if not (row.get(c) or "").strip()]
        if missing:
            fail_input(f"{args.runs}: no {', '.join(missing)} (host-sim disperse writes them)")
        w0 = np.array([math.radians(float(row[c])) for c in rate_cols])
        source = f"{args.runs} sample {args.sample}"
        n_params, param_diffs = drawn_parameters_vs_urdf(args.urdf, row)
        if n_params == 0:
            fail_input(f"{args.runs}: no drawn-parameter columns (LINK.mass_kg, JOINT.axis_x, ...)")

    ff = FreeFloating(urdf_text, ee_link, q.shape[1])
    res = integrate(ff, t, q, q0, w0)
    pe, oe, f = pose_errors(res["position"], res["rotation"], target_p, target_r)
    got = {
        "base_disturbance_deg": math.degrees(res["max_angle"]),
        "final_attitude_error_deg": math.degrees(quat_angle(res["attitude"])),
        "position_error_m": pe,
        "orientation_error_deg": math.degrees(oe),
        "truth_f": f,
        "f": f,
    }
    elapsed = time.perf_counter() - started
    if args.self_test:
        if not self_test(ff, t, q, q0):
            print("disperse-check: self-test FAILED")
            return 1
        print()

    print(f"disperse-check: {args.urdf} along {args.dir / 'trajectory.csv'}")
    print(
        f"  Pinocchio {pin.__version__}, {len(t) - 1} segments x {TRUTH_SUBSTEPS} midpoint "
        f"sub-steps, ee link {ee_link!r}, joints {', '.join(ff.joint_names)}"
    )
    print(
        f"  base rate w0 = {np.degrees(w0).tolist()} deg/s, "
        f"L = {res['momentum'].tolist()} kg m^2/s"
    )
    print(f"  expected values from {source}")
    print(f"  final base attitude [w,x,y,z] {res['attitude'].tolist()}")
    if args.runs is None:
        hp = np.array(summary["truth_end_pose"]["position"], dtype=float)
        hq = np.array(summary["truth_end_pose"]["quat_wxyz"], dtype=float)
        dpos = float(np.linalg.norm(hp - res["position"]))
        dang = rotation_angle(quat_to_matrix(hq) @ res["rotation"].T)
        print(
            f"  truth_end_pose vs independent: |dp| = {dpos:.3e} m, "
            f"attitude difference {math.degrees(dang):.3e} deg"
        )
    ok = True
    if args.runs is not None:
        if param_diffs:
            ok = False
            print(
                f"  drawn parameters: {len(param_diffs)} of {n_params} in the row differ from "
                f"{args.urdf} (exported with another seed, other sigma flags or another "
                "sample?): FAIL"
            )
            for d in param_diffs[:10]:
                print(f"    {d}")
        else:
            print(f"  drawn parameters: all {n_params} in the row equal the URDF's: pass")
    print()
    w = max(len(k) for k in expected)
    print(f"{'quantity':<{w}}  {'host-sim':>24}  {'independent':>24}  {'rel. diff':>10}  result")
    for key, a in expected.items():
        b = got[key]
        diff = abs(a - b)
        scale = max(abs(a), abs(b))
        rel = diff / scale if scale > 0.0 else 0.0
        passed = diff <= args.rtol * scale or diff <= args.atol
        ok &= passed
        print(
            f"{key:<{w}}  {a:>24.17g}  {b:>24.17g}  {rel:>10.3e}  {'pass' if passed else 'FAIL'}"
        )
    print()
    verdict = "PASS" if ok else "FAIL"
    print(
        f"disperse-check: {verdict} (rtol {args.rtol:g}, atol {args.atol:g}), {elapsed:.2f} s"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
