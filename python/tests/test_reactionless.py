"""Tests of the Python package against the CLI's own evidence (docs/python.md).

- plans are bit-identical to ``host-sim record``'s golden records (the reference task and a
  12-joint arm): eta, f, end pose, the trajectory digest, the counts;
- ``model()`` agrees with Pinocchio's centroidal map on random configurations;
- each exception type, with the CLI's message naming the key;
- the GIL is released: two plans in two threads take less wall time than in sequence.

Run with the wheel installed (``pip install ./python``) from any directory:
``python -m pytest python/tests``. Requirements: RL-PY (docs/requirements.md); each test names the IDs it verifies.
"""

import json
import os
import struct
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import reactionless as rl

ROOT = Path(__file__).resolve().parents[2]
ETA_HAT = [3.14771, 0.809316, 1.12249, 0.754006, 4.7352, 0.406031, -4.1572, 4.29895]


def bits(v: float) -> str:
    return "0x%016x" % struct.unpack("<Q", struct.pack("<d", v))[0]


def record(name: str) -> dict:
    return json.loads((ROOT / "tests" / "records" / f"{name}.json").read_text())


@pytest.mark.parametrize("name", ["paper-ms", "arm12-a003-ms", "paper"])
def test_plan_is_the_records_bit_for_bit(name):
    """Verifies RL-PY-001: the reference task (multistart, and C-PSO) and a 12-joint task."""
    r = record(name)
    # The task as recorded (what `host-sim replay` plans), its robot from the task file's.
    robot = rl.Task.from_toml(ROOT / r["task_file"]).robot
    task = rl.Task.from_toml_str(r["task_toml"], robot, origin=ROOT / r["task_file"])
    p = rl.plan(
        task,
        seed=r["seed"],
        strategy=r.get("strategy", "cpso"),  # records older than strategies are C-PSO
        refine_tolerance=r["refine_tolerance"],
        refine_against=r.get("refine_against", "planner"),
        paper=True,
    )
    o = r["outputs"]
    assert p.status == o["status"]
    assert [bits(v) for v in p.eta] == o["eta_bits"]
    assert bits(p.f) == o["f_bits"]
    assert [bits(v) for v in p.trajectory.end_position] == o["end_pose_bits"]["position"]
    assert [bits(v) for v in p.trajectory.end_quat_wxyz] == o["end_pose_bits"]["quat_wxyz"]
    assert p.trajectory.trajectory_digest == o["trajectory_digest"]
    assert len(p.trajectory) == o["trajectory_samples"]
    assert (p.rollouts, p.iterations, p.restarts, p.stagnation_events) == (
        o["rollouts"],
        o["iterations"],
        o.get("restarts", 0),  # older records: C-PSO, no restarts
        o["stagnation_events"],
    )
    # The arrays: seconds from 0 to t_f, radians from the task's start.
    n = task.n_joints
    assert p.q.shape == (len(p.trajectory), n) and p.qd.shape == p.q.shape
    assert p.t[0] == 0.0 and p.t[-1] == task.tf_s
    assert np.array_equal(p.q[0], task.start)
    assert np.all(np.abs(p.qd) <= task.robot.velocity_limits.min() * (1 + 1e-12))


def test_rollout_gives_the_records_digest_and_the_cli_values():
    """Verifies RL-PY-001: rollout() of a record's eta is the record's trajectory."""
    r = record("paper")
    task = rl.Task.from_toml(ROOT / r["task_file"])
    tr = rl.rollout(task, np.array(r["outputs"]["eta"]))
    assert tr.trajectory_digest == r["outputs"]["trajectory_digest"]
    assert bits(tr.f) == r["outputs"]["f_bits"]
    assert tr.base_disturbance_deg > 0 and tr.truth_f > 0
    # The paper's eta-hat (ETA_HAT of the spec): a plain list works too.
    assert len(rl.rollout(task, ETA_HAT)) == 3001


def _reduced(ab, am):
    """H~b, H~bm from Pinocchio's centroidal map at the base's identity attitude: the linear
    momentum rows eliminated (zero linear momentum), the angular rows kept."""
    alv, alw, alm = ab[0:3, 0:3], ab[0:3, 3:6], am[0:3]
    aav, aaw, aam = ab[3:6, 0:3], ab[3:6, 3:6], am[3:6]
    hb = aaw - aav @ np.linalg.solve(alv, alw)
    hbm = aam - aav @ np.linalg.solve(alv, alm)
    return hb, hbm


@pytest.mark.parametrize(
    "urdf,ee",
    [("spec/chaser7.urdf", None), ("tests/robots/arm12.urdf", "ee")],
)
def test_model_agrees_with_pinocchio(urdf, ee):
    """Verifies RL-PY-002: H~b, H~bm and the generalized Jacobian against Pinocchio, random q."""
    pin = pytest.importorskip("pinocchio")
    robot = rl.Robot.from_urdf(str(ROOT / urdf), ee=ee)
    model = pin.buildModelFromXML(robot.urdf, pin.JointModelFreeFlyer())
    data = model.createData()
    frame = model.getFrameId(robot.ee_link)
    iq = [model.joints[model.getJointId(j)].idx_q for j in robot.joint_names]
    iv = [model.joints[model.getJointId(j)].idx_v for j in robot.joint_names]
    rng = np.random.default_rng(34)
    for _ in range(20):
        q = rng.uniform(robot.lower, robot.upper)
        m = rl.model(robot, q)
        x = pin.neutral(model)
        x[iq] = q
        ag = pin.computeCentroidalMap(model, data, x)
        ab, am = ag[:, 0:6], ag[:, iv]
        hb, hbm = _reduced(ab, am)
        scale = np.abs(hb).max()
        assert np.abs(m["hb"] - hb).max() <= 1e-9 * scale
        assert np.abs(m["hbm"] - hbm).max() <= 1e-9 * scale
        # Generalized Jacobian: the end effector's twist (world, at its origin) for unit
        # joint rates with the base reacting at zero momentum.
        pin.computeJointJacobians(model, data, x)
        pin.updateFramePlacements(model, data)
        j = pin.getFrameJacobian(model, data, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        base = np.linalg.solve(ab, -am)  # [v; w] of the base per unit joint rate
        jg = j[:, 0:6] @ base + j[:, iv]
        assert np.abs(m["jacobian"] - jg).max() <= 1e-9 * max(1.0, np.abs(jg).max())
        assert m["hbm"].shape == (3, robot.n_joints)
        assert m["rns_basis"].shape == (robot.n_joints, robot.n_joints - 3)
        assert np.abs(m["hbm"] @ m["rns_basis"]).max() <= 1e-9 * scale


def test_each_exception_type_names_what_was_wrong(tmp_path):
    """Verifies RL-PY-003."""
    robot = rl.Robot.from_urdf(str(ROOT / "spec/chaser7.urdf"))
    paper = rl.Task.from_toml(ROOT / "spec/tasks/paper.toml")
    tables = {
        "start": {"q_deg": [-90.0, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0]},
        "target": {
            "position_m": list(paper.target_position),
            "quat_wxyz": list(paper.target_quat_wxyz),
        },
        "motion": {"tf_s": 30.0, "dt_s": 0.01},
    }
    task = rl.Task.from_dict(tables, robot)
    assert task.n_joints == 7 and np.array_equal(task.start, paper.start)
    # An unknown key: InputError, a ValueError, naming the key as the CLI does.
    with pytest.raises(rl.InputError) as e:
        rl.Task.from_dict({**tables, "motion": {"tf_s": 30.0, "dt_s": 0.01, "tf": 3}}, robot)
    assert isinstance(e.value, ValueError) and isinstance(e.value, rl.ReactionlessError)
    # A broken invariant (a bug) is neither the caller's input nor a result: the base class.
    assert not issubclass(rl.ReactionlessError, ValueError)
    assert "tf" in str(e.value)
    with pytest.raises(rl.InputError, match="strategy"):
        rl.plan(task, strategy="annealing")
    with pytest.raises(rl.InputError, match="eta"):
        rl.rollout(task, [1.0, 2.0])
    with pytest.raises(rl.InputError, match="eta"):
        rl.rollout(task, [0.0] * 8)
    with pytest.raises(rl.InputError, match="q has 3 values"):
        rl.model(robot, [0.0, 0.0, 0.0])
    with pytest.raises(rl.InputError):
        rl.Task.from_toml(tmp_path / "missing.toml")
    with pytest.raises(rl.InputError):
        rl.Robot.from_urdf("<robot name='x'></robot>")
    with pytest.raises(rl.InputError, match="max_rollouts"):
        rl.plan(task, max_rollouts=0)
    with pytest.raises(rl.InputError):
        rl.check(tmp_path)
    # A failed result: PlanningError, a RuntimeError. A plan that does not converge is
    # returned, not raised (its status says so).
    assert issubclass(rl.PlanningError, RuntimeError)
    short = rl.plan(task, max_rollouts=3)
    assert short.status == "not_converged" and short.rollouts <= 3


def test_check_gives_the_cli_verdicts(tmp_path):
    """Verifies RL-PY-004: Plan.write() writes host-sim plan's files byte for byte, and check() of a
    Plan gives the rows of check() of that directory (host-sim check's); with HOST_SIM
    naming the binary, the same as `host-sim plan` writes."""
    task = rl.Task.from_toml(ROOT / "spec/tasks/paper.toml")
    p = rl.plan(task)
    mine = Path(p.write(tmp_path / "py"))
    rows = rl.check(p)
    assert rows == rl.check(mine)
    assert rows and all(r["passed"] for r in rows), rows
    assert {"check", "value", "limit", "passed"} <= set(rows[0])
    hs = os.environ.get("HOST_SIM")
    if not hs:
        pytest.skip("HOST_SIM is not set: no comparison with host-sim plan")
    import subprocess

    cli = tmp_path / "cli"
    subprocess.run([hs, "plan", str(ROOT / "spec/tasks/paper.toml"), "--out", str(cli)],
                   check=True, capture_output=True)
    for name in ["task.toml", "robot.urdf", "trajectory.csv", "summary.json"]:
        assert (mine / name).read_bytes() == (cli / name).read_bytes(), name


def _interrupted(script, *args, after=1.0):
    """Runs `script` with `args` in a child Python, sends SIGINT `after` seconds after its
    first line, and returns (stdout, stderr, seconds from the signal to its exit)."""
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-c", script, *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = proc.stdout.readline()
    time.sleep(after)
    t0 = time.perf_counter()
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    return first + out, err, time.perf_counter() - t0


_INTERRUPTED = """
import sys, reactionless as rl
task = rl.Task.from_toml(sys.argv[1])
threads = None if sys.argv[2] == "default" else int(sys.argv[2])
print("planning", flush=True)
rl.plan(task, seed=1, strategy="cpso", max_rollouts=1_000_000, refine_tolerance=1e-15,
        threads=threads)
print("finished", flush=True)
"""


@pytest.mark.parametrize("threads", ["default", "1"])
def test_ctrl_c_interrupts_a_plan(threads):
    """Verifies RL-PY-006: SIGINT during plan() raises KeyboardInterrupt within a slice of
    planning, on rayon's shared pool and on a plan's own pool (threads=1)."""
    out, err, seconds = _interrupted(
        _INTERRUPTED, str(ROOT / "tests/tasks/a/arm12/task_003.toml"), threads)
    assert out.startswith("planning") and "finished" not in out
    assert "KeyboardInterrupt" in err, err
    assert seconds < 5.0


_THREADS = """
import sys, threading, time
import reactionless as rl
task = rl.Task.from_toml(sys.argv[1])
def one():
    rl.plan(task, seed=4, strategy="cpso", max_rollouts=400, threads=1)
one()  # warm up (the thread pool, the page cache)
t0 = time.perf_counter(); one(); one(); sequential = time.perf_counter() - t0
threads = [threading.Thread(target=one) for _ in range(2)]
t0 = time.perf_counter()
for t in threads: t.start()
for t in threads: t.join()
print(sequential, time.perf_counter() - t0)
"""


def test_plans_in_two_threads_overlap():
    """Verifies RL-PY-005: the GIL is released while planning. A plan spreads its rollouts over every
    core by default, so the wall-time comparison gives each plan one worker thread
    (threads=1): two plans in two Python threads then take less time than in sequence.
    And a Python thread keeps running while a plan runs."""
    import subprocess
    import sys

    task = ROOT / "tests/tasks/a/arm12/task_003.toml"
    out = subprocess.run([sys.executable, "-c", _THREADS, str(task)],
                         check=True, capture_output=True, text=True).stdout.split()
    sequential, parallel = float(out[0]), float(out[1])
    assert parallel < 0.8 * sequential, (parallel, sequential)

    t = rl.Task.from_toml(task)
    th = threading.Thread(target=lambda: rl.plan(t, seed=4, strategy="cpso", max_rollouts=400))
    th.start()
    ticks = 0
    while th.is_alive():
        ticks += 1
    th.join()
    assert ticks > 10_000, ticks


DISPERSION = dict(mass_rel_sigma=0.05, inertia_rel_sigma=0.1, com_sigma_m=0.01)


def test_disperse_is_the_clis(tmp_path):
    """Verifies RL-PY-007: disperse() of a Plan gives host-sim disperse's runs (HOST_SIM: compared
    number for number with the binary's runs.csv of the same plan), open and closed loop."""
    task = rl.Task.from_toml(ROOT / "spec/tasks/paper.toml")
    p = rl.plan(task)
    runs, summary = rl.disperse(p, 20, 7, **DISPERSION)
    runs = {k: np.asarray(v) for k, v in dict(runs).items()}
    assert list(runs["sample"]) == list(range(20))
    assert (summary["samples"], summary["seed"], summary["mode"]) == (20, 7, "open_loop")
    assert runs["base_disturbance_deg"].max() == summary["statistics"]["base_disturbance_deg"]["max"]
    closed, cs = rl.disperse(p, 5, 7, closed_loop=True, jobs=1, **DISPERSION)
    assert cs["mode"] == "closed_loop"
    assert np.all(np.asarray(closed["rate_violations"]) == 0)
    with pytest.raises(rl.InputError, match="no-such-flag"):
        rl.disperse(p, 5, 7, no_such_flag=1)
    hs = os.environ.get("HOST_SIM")
    if not hs:
        pytest.skip("HOST_SIM is not set: no comparison with host-sim disperse")
    import csv
    import subprocess

    d = Path(p.write(tmp_path / "plan"))
    flags = ["--mass-rel-sigma", "0.05", "--inertia-rel-sigma", "0.1", "--com-sigma-m", "0.01"]
    subprocess.run([hs, "disperse", str(d), "--samples", "20", "--seed", "7", *flags,
                    "--out", str(tmp_path / "mc")], check=True, capture_output=True)
    with open(tmp_path / "mc" / "runs.csv") as f:
        rows = list(csv.DictReader(f))
    for k, col in runs.items():
        assert [float(r[k]) for r in rows] == [float(v) for v in col], k


def test_retime_stays_within_its_limit():
    """Verifies RL-PY-007: retime() of a Plan: every written sample within the acceleration limit."""
    task = rl.Task.from_toml(ROOT / "spec/tasks/paper.toml")
    p = rl.plan(task)
    samples, summary = rl.retime(p, accel_deg_s2=2.0)
    s = {k: np.asarray(v) for k, v in dict(samples).items()}
    qdd = np.column_stack([s[f"qdd{j}"] for j in range(1, 8)])
    assert np.abs(qdd).max() <= np.radians(2.0) * (1 + 1e-9)
    assert s["t"][-1] < task.tf_s  # faster than the planned 30 s at this limit
    assert np.array_equal(np.column_stack([s[f"q{j}"] for j in range(1, 8)])[0], task.start)


_DISPERSE_INTERRUPTED = """
import sys, reactionless as rl
task = rl.Task.from_toml(sys.argv[1])
p = rl.plan(task)
print("dispersing", flush=True)
rl.disperse(p, 100000, 1, mass_rel_sigma=0.05, closed_loop=True)
print("finished", flush=True)
"""


def test_ctrl_c_interrupts_a_disperse():
    """Verifies RL-PY-006: SIGINT during disperse() raises KeyboardInterrupt at the next samples."""
    out, err, seconds = _interrupted(_DISPERSE_INTERRUPTED, str(ROOT / "spec/tasks/paper.toml"))
    assert out.startswith("dispersing") and "finished" not in out
    assert "KeyboardInterrupt" in err, err
    assert seconds < 10.0


def test_the_binding_costs_under_two_percent_of_a_plan():
    """Verifies RL-PY-008: plan()'s wall time over the Rust call's own (Plan.rust_seconds: the search
    and the trajectory), median of 15 plans of the reference task."""
    task = rl.Task.from_toml(ROOT / "spec/tasks/paper.toml")
    rl.plan(task)  # warm up
    ratios = []
    for _ in range(15):
        t0 = time.perf_counter()
        p = rl.plan(task)
        ratios.append((time.perf_counter() - t0) / p.rust_seconds - 1)
    overhead = float(np.median(ratios))
    print(f"plan() overhead over the Rust call: {100 * overhead:.3f} %")
    assert overhead <= 0.02, ratios
