# %% [markdown]
# # reactionless from Python: plan, check, disperse, plot
#
# A notebook in percent format (open it in Jupyter with jupytext, or in VS Code; CI runs
# it as a script: `python examples/python/tour.py OUT_DIR`). It plans the reference task,
# checks the plan as `host-sim check` does, plans a target computed in Python, flies the
# plan through 200 dispersed robots open and closed loop, and plots. Units: SI and
# radians everywhere; `_deg` names are degrees.

# %%
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files, no display
import matplotlib.pyplot as plt
import numpy as np

import reactionless as rl

ROOT = Path(__file__).resolve().parents[2] if "__file__" in globals() else Path.cwd()
OUT = Path(sys.argv[1]) if len(sys.argv) > 1 and not sys.argv[1].startswith("-") else ROOT / "out/python-tour"
OUT.mkdir(parents=True, exist_ok=True)
print(rl.__build__)

# %% [markdown]
# ## Plan the reference task

# %%
task = rl.Task.from_toml(ROOT / "spec/tasks/paper.toml")
plan = rl.plan(task)
print(plan, f"truth-model f {plan.truth_f:.2e}, base disturbance "
      f"{plan.trajectory.base_disturbance_deg:.2e} deg")
assert plan.converged

# %% [markdown]
# ## Check it as `host-sim check` does

# %%
rows = rl.check(plan)
for r in rows:
    print(f"{'PASS' if r['passed'] else 'FAIL'}  {r['check']:<40} {r['value']:<24} {r['limit']}")
assert all(r["passed"] for r in rows)

# %% [markdown]
# ## Joint angles and rates

# %%
fig, (a, b) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
for j, name in enumerate(task.robot.joint_names):
    a.plot(plan.t, np.degrees(plan.q[:, j]), label=name)
    b.plot(plan.t, np.degrees(plan.qd[:, j]))
b.axhline(np.degrees(task.robot.velocity_limits.min()), color="k", ls="--", lw=0.8)
b.axhline(-np.degrees(task.robot.velocity_limits.min()), color="k", ls="--", lw=0.8)
a.set_ylabel("q (deg)")
b.set_ylabel("q̇ (deg/s)")
b.set_xlabel("t (s)")
a.legend(ncol=4, fontsize=8)
fig.tight_layout()
fig.savefig(OUT / "joints.png", dpi=100)

# %% [markdown]
# ## A target computed in Python
#
# The end pose of the plan, moved 5 mm along x: a new task from a dict of the task file's
# tables, planned with the same robot.

# %%
tables = {
    "start": {"q_deg": list(np.degrees(task.start))},
    "target": {
        "position_m": list(plan.trajectory.end_position + [0.005, 0.0, 0.0]),
        "quat_wxyz": list(plan.trajectory.end_quat_wxyz),
    },
    "motion": {"tf_s": task.tf_s, "dt_s": task.dt_s},
}
moved = rl.plan(rl.Task.from_dict(tables, task.robot))
print("moved target:", moved, f"position error {moved.trajectory.position_error_m * 1e3:.3f} mm")

# %% [markdown]
# ## 200 dispersed robots, open and closed loop

# %%
spread = dict(mass_rel_sigma=0.05, inertia_rel_sigma=0.1, com_sigma_m=0.01)
open_runs, open_summary = rl.disperse(plan, 200, 1, **spread)
closed_runs, closed_summary = rl.disperse(plan, 200, 1, closed_loop=True, **spread)
for name, s in [("open loop", open_summary), ("closed loop", closed_summary)]:
    st = s["statistics"]
    print(f"{name:12} base p99 {st['base_disturbance_deg']['p99']:.4f} deg, "
          f"EE p99 {1e3 * st['position_error_m']['p99']:.1f} mm")

fig, ax = plt.subplots(figsize=(7, 4))
for name, runs in [("open loop", open_runs), ("closed loop", closed_runs)]:
    x = np.sort(np.asarray(runs["base_disturbance_deg"]))
    ax.step(x, np.arange(1, len(x) + 1) / len(x), where="post", label=name)
ax.axvline(0.01, color="k", ls="--", lw=0.8, label="requirement 0.01°")
ax.set_xscale("log")
ax.set_xlabel("base disturbance (deg)")
ax.set_ylabel("fraction of samples")
ax.legend()
fig.tight_layout()
fig.savefig(OUT / "base_disturbance_cdf.png", dpi=100)
print("figures in", OUT)
