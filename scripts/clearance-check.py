#!/usr/bin/env python3
"""Dev-only: recompute the clearance of a written trajectory with Pinocchio and coal.

For DIR (an output of `host-sim plan` or `rollout`, with task.toml, robot.urdf and
trajectory.csv) and JSON (what `host-sim check DIR --clearance-json JSON` wrote), rebuilds
the scene of spec §13 independently of host-sim:
- the robot from robot.urdf by Pinocchio (a free-flyer root, so the base carries its mass),
  placed as the planner model places it: identity attitude, the base shifted so that the
  system centre of mass stays at its start (`pin.centerOfMass`);
- the collision primitives from the URDF's `<collision>` elements, read here with
  ElementTree and placed on Pinocchio's link frames (`oMf`); a `<cylinder>` whose name
  contains "capsule" is a `coal.Capsule`, as spec §13 and host-sim read it;
- the keep-outs of task.toml's `[[keep_out]]` and the ignored pairs of `[collision]`;
- the pairs: bodies two or more joints apart (the base counts as the joint before the
  first), every body against every keep-out;
and measures every pair with `coal.distance` (GJK/EPA at 1e-12) at every written sample
and at `--sub` points between consecutive samples (the path is piecewise linear in q).

Asserts, pair by pair:
- the same pairs as host-sim;
- host-sim's smallest distance at the samples equals coal's within `--tol` (1e-9 m);
- host-sim's reported smallest distance over the path is never larger than coal's over
  the samples and the points between them (plus `--tol`): no false clearance;
- if host-sim says the path passes a required clearance, coal finds none closer.
Prints one line per pair and exits 1 on any failure.

    /tmp/pin-venv/bin/python scripts/clearance-check.py DIR JSON [--sub 4]

Not a runtime dependency of anything.
"""
import argparse
import json
import math
import pathlib
import sys
import tomllib
import xml.etree.ElementTree as ET

import coal
import numpy as np
import pinocchio as pin


def rpy(v):
    return pin.rpy.rpyToMatrix(np.array(v, dtype=float))


def floats(s, n=3):
    v = [float(x) for x in (s or " ".join(["0"] * n)).split()]
    assert len(v) == n, s
    return v


def shape_of(name, geom):
    g = list(geom)[0]
    if g.tag == "sphere":
        return coal.Sphere(float(g.get("radius")))
    if g.tag == "box":
        return coal.Box(*floats(g.get("size")))
    if g.tag == "capsule" or (g.tag == "cylinder" and "capsule" in (name or "").lower()):
        return coal.Capsule(float(g.get("radius")), float(g.get("length")))
    raise SystemExit(f"unsupported collision geometry {g.tag} ({name})")


def keep_out_shape(k):
    if k["shape"] == "box":
        return coal.Box(*[2.0 * h for h in k["half_extents_m"]])
    if k["shape"] == "sphere":
        return coal.Sphere(k["radius_m"])
    return coal.Capsule(k["radius_m"], k["length_m"])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir", type=pathlib.Path)
    ap.add_argument("json", type=pathlib.Path)
    ap.add_argument("--sub", type=int, default=4, help="points between consecutive samples")
    ap.add_argument("--tol", type=float, default=1e-9)
    a = ap.parse_args()

    urdf = a.dir / "robot.urdf"
    model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
    data = model.createData()
    task = tomllib.loads((a.dir / "task.toml").read_text())
    report = json.loads(a.json.read_text())

    # Body of each Pinocchio joint: the link its joint moves (joint 1 = the free flyer = base).
    body_name = {}
    for f in model.frames:
        if f.type == pin.FrameType.BODY and f.parentJoint not in body_name:
            body_name[f.parentJoint] = f.name
    # Collision primitives per joint, from the URDF text.
    prims = {}
    for link in ET.parse(urdf).getroot().iter("link"):
        fid = model.getFrameId(link.get("name"))
        joint = model.frames[fid].parentJoint
        for k, c in enumerate(link.findall("collision")):
            o = c.find("origin")
            xyz = floats(o.get("xyz") if o is not None else None)
            r = floats(o.get("rpy") if o is not None else None)
            local = pin.SE3(rpy(r), np.array(xyz))
            name = c.get("name") or f"{link.get('name')}/{k}"
            prims.setdefault(joint, []).append((name, fid, local, shape_of(c.get("name"), c.find("geometry"))))
    keep = []
    for k in task.get("keep_out", []):
        r = [math.radians(x) for x in k.get("rpy_deg", [0.0, 0.0, 0.0])]
        keep.append((k["name"], coal.Transform3s(rpy(r), np.array(k["position_m"], dtype=float)), keep_out_shape(k)))
    collision = task.get("collision", {})
    ignore = {tuple(p) for p in collision.get("ignore", [])} | {tuple(reversed(p)) for p in collision.get("ignore", [])}

    joints = sorted(j for j in body_name if j >= 1)
    pairs = []
    for i in joints:
        for j in joints:
            if j >= i + 2 and prims.get(i) and prims.get(j) and (body_name[i], body_name[j]) not in ignore:
                pairs.append(((i, None), (j, None)))
    for i in joints:
        for k, (kname, _, _) in enumerate(keep):
            if prims.get(i) and (body_name[i], kname) not in ignore:
                pairs.append(((i, None), (None, k)))

    def label(side):
        j, k = side
        return body_name[j] if j is not None else keep[k][0]

    ours = {(p["a"], p["b"]): p for p in report["pairs"]}
    theirs = {(label(x), label(y)) for x, y in pairs}
    failures = []
    if set(ours) != theirs:
        failures.append(f"pair lists differ: host-sim only {sorted(set(ours) - theirs)}, coal only {sorted(theirs - set(ours))}")

    rows = np.loadtxt(a.dir / "trajectory.csv", delimiter=",", skiprows=1)
    n = model.nq - 7
    qs = rows[:, 1 : 1 + n]
    req = coal.DistanceRequest()
    req.gjk_tolerance = 1e-12
    req.epa_tolerance = 1e-12
    res = coal.DistanceResult()

    def placements(q):
        full = np.concatenate([[0, 0, 0, 0, 0, 0, 1], q])
        pin.forwardKinematics(model, data, full)
        pin.updateFramePlacements(model, data)
        com = pin.centerOfMass(model, data, full).copy()
        return com, [data.oMf[f].copy() for f in range(model.nframes)]

    com0, _ = placements(qs[0])

    def world(q):
        com, oMf = placements(q)
        shift = com0 - com
        placed = {}
        for j, ps in prims.items():
            placed[j] = []
            for name, fid, local, shape in ps:
                m = oMf[fid] * local
                placed[j].append((shape, coal.Transform3s(m.rotation, m.translation + shift)))
        return placed

    def distance(placed, x, y):
        side = lambda s: placed[s[0]] if s[0] is not None else [(keep[s[1]][2], keep[s[1]][1])]
        best = math.inf
        for sa, ta in side(x):
            for sb, tb in side(y):
                res.clear()
                best = min(best, coal.distance(sa, ta, sb, tb, req, res))
        return best

    at_samples = {p: math.inf for p in pairs}
    anywhere = {p: math.inf for p in pairs}
    for s in range(len(qs)):
        placed = world(qs[s])
        for p in pairs:
            d = distance(placed, *p)
            at_samples[p] = min(at_samples[p], d)
            anywhere[p] = min(anywhere[p], d)
        if s + 1 < len(qs):
            for k in range(1, a.sub + 1):
                u = k / (a.sub + 1)
                placed = world(qs[s] + u * (qs[s + 1] - qs[s]))
                for p in pairs:
                    anywhere[p] = min(anywhere[p], distance(placed, *p))

    worst_err = 0.0
    for p in pairs:
        key = (label(p[0]), label(p[1]))
        o = ours.get(key)
        if o is None:
            continue
        err = abs(o["min_at_samples_m"] - at_samples[p])
        worst_err = max(worst_err, err)
        ok = err <= a.tol and o["min_m"] <= anywhere[p] + a.tol
        if report["required"] and report["pass"] and anywhere[p] < report["required_m"]:
            ok = False
            failures.append(f"{key}: host-sim passes, coal finds {anywhere[p]:.9f} m < {report['required_m']} m")
        if not ok:
            failures.append(
                f"{key}: host-sim {o['min_at_samples_m']:.12f} at samples / {o['min_m']:.12f} on the path, "
                f"coal {at_samples[p]:.12f} at samples / {anywhere[p]:.12f} with {a.sub} points between"
            )
        print(f"{key[0]:>12} - {key[1]:<16} host-sim {o['min_m']: .9f} m (samples {o['min_at_samples_m']: .9f}), "
              f"coal {at_samples[p]: .9f} (with points between {anywhere[p]: .9f})")
    print(f"{len(pairs)} pairs, {len(qs)} samples, {a.sub} points between; "
          f"largest difference at the samples {worst_err:.2e} m (tolerance {a.tol:g})")
    for f in failures:
        print("FAIL", f)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
