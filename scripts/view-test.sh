#!/usr/bin/env bash
# The 3-D replay page (host-sim view) in a real browser: Debian's headless Chromium,
# software rendering, no GPU, no network. For the reference plan (7 joints) and a 9-joint
# plan it
#  - plans with --plots (which writes DIR/view.html) and checks that `host-sim view DIR`
#    writes the same page;
#  - checks the file references no external URL;
#  - opens FILE.html?t=0, ?t=t_f and ?t=T (mid-way), reads <pre id="rl-state"> from the
#    DOM and compares: ee_position_m at t = 0 with the start pose (host-sim model at q0)
#    and at t_f with summary.json's end_pose.position (<= 1e-9 m), q at t_f with q_final,
#    the base angle with summary.json's base_disturbance_deg, t with the nearest sample;
#  - takes a screenshot and checks it is not blank: the robot's pixels (link colour)
#    differ from the background.
# Needs chromium (apt-get install -y chromium) and python3; builds host-sim (release) unless
# HOST_SIM names one.
#  - exports a closed-loop flight of the reference plan (disperse --closed-loop
#    --export-sample 2), draws it, and checks that the DOM state carries the loop's estimate
#    of the cycle shown (cycles.csv's) and the panel names it.
# Usage: scripts/view-test.sh [OUT_DIR]   (default target/view-test). Verifies RL-SIM-VIEW-001..004,
# RL-SIM-VIEW-006.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-target/view-test}
CHROMIUM=${CHROMIUM:-chromium}
command -v "$CHROMIUM" >/dev/null || {
  echo "view-test: $CHROMIUM not found (apt-get install -y chromium)" >&2
  exit 2
}
# HOST_SIM: a host-sim already built (CI: its test step's); else the release build.
if [ -n "${HOST_SIM:-}" ]; then
  H=$HOST_SIM
else
  cargo build -q --release -p host-sim
  H=target/release/host-sim
fi
rm -rf "$OUT"
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
PROFILE=$(mktemp -d)
trap 'rm -rf "$PROFILE"' EXIT
# The flags the README names; --virtual-time-budget lets the page draw before the dump.
FLAGS=(--headless --no-sandbox --disable-gpu --disable-quic --no-first-run
  --disable-background-networking --disable-component-update --disable-sync
  --user-data-dir="$PROFILE" --hide-scrollbars --virtual-time-budget=5000)

dump() { # URL -> the DOM on stdout
  timeout 120 "$CHROMIUM" "${FLAGS[@]}" --dump-dom "$1" 2>/dev/null
}
shot() { # URL PNG
  timeout 120 "$CHROMIUM" "${FLAGS[@]}" --window-size=1280,760 --screenshot="$2" "$1" \
    >/dev/null 2>&1
  test -s "$2"
}

for case in "paper spec/tasks/paper.toml" "arm9 tests/tasks/a/arm9/task_001.toml"; do
  set -- $case
  name=$1 task=$2 dir="$OUT/$1"
  echo "== $name ($task)"
  "$H" plan "$task" --plots --out "$dir" 2>/dev/null
  "$H" view "$dir" --out "$OUT/$name.html" 2>/dev/null
  cmp "$dir/view.html" "$OUT/$name.html"
  read -r q0 ee < <(python3 -c 'import sys, tomllib; t = tomllib.load(open(sys.argv[1], "rb")); print(",".join(repr(v) for v in t["start"]["q_deg"]), t["robot"]["ee_link"])' "$dir/task.toml")
  "$H" model --urdf "$dir/robot.urdf" --ee "$ee" --q-deg "$q0" > "$OUT/$name.model.json"
  tf=$(python3 -c 'import json, sys; print(repr(json.load(open(sys.argv[1]))["tf_s"]))' "$dir/summary.json")
  url="file://$dir/view.html"
  dump "$url?t=0" > "$OUT/$name.t0.html"
  dump "$url?t=$tf" > "$OUT/$name.tf.html"
  dump "$url?t=12.3456" > "$OUT/$name.tmid.html"
  shot "$url?t=$tf" "$OUT/$name.png"
  python3 - "$OUT" "$name" <<'PY'
import html, json, re, struct, sys, zlib

out, name = sys.argv[1], sys.argv[2]
d = f"{out}/{name}"
summary = json.load(open(f"{d}/summary.json"))
model = json.load(open(f"{out}/{name}.model.json"))
page = open(f"{d}/view.html", encoding="utf-8").read()

# No external URL: no scheme, no src/href attribute, no CSS url() or @import, no fetch.
bad = re.findall(r"(?i)\b(?:https?|ftp|wss?|file|data):|\b(?:src|href)\s*=|url\(|@import|"
                 r"\bimport\s*\(|XMLHttpRequest|\bfetch\s*\(", page)
assert not bad, f"{name}: the page references something outside itself: {bad[:5]}"

def state(which):
    dom = open(f"{out}/{name}.{which}.html", encoding="utf-8").read()
    m = re.search(r'<pre id="rl-state">(.*?)</pre>', dom, re.S)
    assert m, f"{name} {which}: no <pre id=rl-state> in the DOM (the page did not draw)"
    return json.loads(html.unescape(m.group(1)))

def dist(a, b):
    return sum((x - y) ** 2 for x, y in zip(a, b)) ** 0.5

s0, sf, sm = state("t0"), state("tf"), state("tmid")
start = model["ee"]["position"]
e0 = dist(s0["ee_position_m"], start)
ef = dist(sf["ee_position_m"], summary["end_pose"]["position"])
assert s0["t"] == 0 and s0["sample"] == 0, s0["t"]
assert e0 <= 1e-9, f"{name}: t=0 end effector {s0['ee_position_m']} vs start pose {start}: {e0:.3e} m"
assert sf["t"] == summary["tf_s"] and sf["sample"] == summary["steps"], (sf["t"], sf["sample"])
assert ef <= 1e-9, f"{name}: t_f end effector vs summary.json end_pose: {ef:.3e} m"
assert sf["q"] == summary["q_final"], f"{name}: q at t_f is not summary.json's q_final"
assert s0["base_angle_deg"] == 0.0
assert 0 < sf["base_angle_deg"] <= summary["base_disturbance_deg"]
dt = summary["dt_s"]
assert abs(sm["t"] - 12.3456) <= dt / 2 + 1e-12, f"{name}: ?t=12.3456 showed t={sm['t']}"
assert len(sf["q"]) == len(summary["q_final"])

# The screenshot: decode the PNG (zlib, the five filters), then count pixels.
def png_rgb(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, w = 8, b"", 0
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, ctype = struct.unpack(">IIBB", body[:10])
            assert depth == 8 and ctype in (2, 6), (depth, ctype)
            bpp = 3 if ctype == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw, stride, rows, prev = zlib.decompress(idat), w * bpp, [], bytearray(w * bpp)
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b, c = prev[i], (prev[i - bpp] if i >= bpp else 0)
            if f == 1: line[i] = (line[i] + a) & 255
            elif f == 2: line[i] = (line[i] + b) & 255
            elif f == 3: line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line[i:i + 3]) for i in range(0, stride, bpp))
        rows[-1] = list(rows[-1])
        prev = line
    return w, h, rows

w, h, rows = png_rgb(f"{out}/{name}.png")
scene = [px for row in rows[:h - 60] for px in row[:w - 380]]  # the canvas, not the panel
background = bytes((247, 248, 250))
link = (61, 111, 168)
differ = sum(px != background for px in scene) / len(scene)
robot = sum(all(abs(p - q) <= 40 for p, q in zip(px, link)) for px in scene)
assert differ > 0.02, f"{name}: the scene is blank ({100 * differ:.2f}% of pixels differ from the background)"
assert robot > 300, f"{name}: only {robot} pixels in the links' colour: the robot was not drawn"
print(f"{name}: ee at t=0 within {e0:.1e} m of the start pose, at t_f within {ef:.1e} m of "
      f"summary.json; screenshot {w}x{h}: {100 * differ:.1f}% of the scene differs from the "
      f"background, {robot} link pixels; no external URL")
PY
done
cp "$OUT/paper.png" "$OUT/view.png"

# A closed-loop flight: sample 2 of the README's dispersion, exported and drawn; the DOM's
# state carries the loop's estimate at the cycle shown, and the end is the flight's.
echo "== closed loop (sample 2 of seed 1)"
"$H" disperse "$OUT/paper" --seed 1 --mass-rel-sigma 0.05 --inertia-rel-sigma 0.1 \
  --com-sigma-m 0.01 --closed-loop --export-sample 2 --out "$OUT/flight" 2>/dev/null
"$H" view "$OUT/flight" --out "$OUT/flight.html" 2>/dev/null
tend=$(python3 -c 'import sys; print(open(sys.argv[1]).read().splitlines()[-1].split(",")[0])' "$OUT/flight/trajectory.csv")
dump "file://$OUT/flight.html?t=$tend" > "$OUT/flight.tf.html"
dump "file://$OUT/flight.html?t=15" > "$OUT/flight.tmid.html"
shot "file://$OUT/flight.html?t=15" "$OUT/flight.png"
python3 - "$OUT" <<'PY'
import csv, html, json, re, sys
out = sys.argv[1]
summary = json.load(open(f"{out}/flight/summary.json"))
cycles = list(csv.DictReader(open(f"{out}/flight/cycles.csv")))
def state(which):
    dom = open(f"{out}/flight.{which}.html", encoding="utf-8").read()
    m = re.search(r'<pre id="rl-state">(.*?)</pre>', dom, re.S)
    assert m, f"flight {which}: no <pre id=rl-state> in the DOM (the page did not draw)"
    return json.loads(html.unescape(m.group(1)))
sf, sm = state("tf"), state("tmid")
ef = sum((a - b) ** 2 for a, b in zip(sf["ee_position_m"], summary["end_pose"]["position"])) ** 0.5
assert ef <= 1e-9, f"flight: end effector at the end vs summary.json: {ef:.3e} m"
assert sf["base_estimate_deg"] == float(cycles[-1]["estimate_deg"]), sf
mid = [c for c in cycles if float(c["t_s"]) <= sm["t"]][-1]
assert sm["base_estimate_deg"] == float(mid["estimate_deg"]), (sm, mid)
assert 0 < sm["base_angle_deg"] <= summary["figures"]["base_disturbance_deg"]
dom = open(f"{out}/flight.tmid.html", encoding="utf-8").read()
assert "the loop estimates" in dom, "the panel does not show the loop's estimate"
print(f"flight: the end within {ef:.1e} m of summary.json, the loop's estimate at t={sm['t']} "
      f"is cycles.csv's ({sm['base_estimate_deg']:.3e} deg, truth {sm['base_angle_deg']:.3e} deg)")
PY
echo "view-test: PASS ($OUT)"
