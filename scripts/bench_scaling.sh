#!/usr/bin/env bash
# Scaling of the cost evaluation and of `scenecal calibrate --scheme joint`
# with the data (swathe points, scenes, cameras) and the threads (issue 6).
#
#   scripts/bench_scaling.sh [DATASET] [OUT_DIR]
#
# DATASET: a simulated RobotCar drive (default /tmp/rc, made with
#   scenecal simulate --preset robotcar --seed 1 --output /tmp/rc; not remade here).
# Environment:
#   SCENECAL       scenecal binary (default build-bench/bin/scenecal)
#   BENCH_DATASET  bench_dataset binary (default build-bench/bin/bench_dataset)
#   TRINO          optional trinocular dataset (scenecal simulate --preset trinocular --seed 1):
#                  adds 3-camera rows, its rear lidar only (another drive: not the same data)
#   PARTS          "kernel e2e" (default both)
#   REPS           kernel repetitions, minimum kept (default 5)
#
# Views: DATASET itself (2 cameras) and OUT_DIR/views/one_camera (its first
# camera only: rig.yaml rewritten, the data symlinked), so the camera axis is
# measured on the same drive. Kernel: bench_dataset's BM_JointCost (one
# EvaluateJoint at the rig.yaml guess, hard NID 32 bins, visitor kernel of
# PairCost::Evaluate and AddHardCounts). End to end: calibrate --setting paper --scheme joint
# (the paper's pipeline) except the varied option, wall/user time and peak RSS
# from /usr/bin/time -v, evaluations and optimisation seconds from its log.
# Prints Markdown (tables and least-squares fits) and keeps every log in OUT_DIR.
set -euo pipefail
cd "$(dirname "$0")/.."
dataset=${1:-/tmp/rc}
out=${2:-/tmp/scenecal_bench_scaling}
scenecal=${SCENECAL:-build-bench/bin/scenecal}
bench=${BENCH_DATASET:-build-bench/bin/bench_dataset}
parts=${PARTS:-"kernel e2e"}
reps=${REPS:-5}
trino=${TRINO:-}

[[ -f "$dataset/rig.yaml" ]] || { echo "bench_scaling: no dataset at $dataset" >&2; exit 2; }
[[ -x /usr/bin/time ]] || { echo "bench_scaling: /usr/bin/time missing (apt-get install time)" >&2; exit 2; }
mkdir -p "$out/views"

# A view of a dataset restricted to some cameras and lidars (rig.yaml rewritten, the rest symlinked).
make_view() {  # source target "camera ..." "lidar ..."
  python3 - "$1" "$2" "$3" "$4" <<'EOF'
import os, sys, yaml
source, target, cameras, lidars = sys.argv[1], sys.argv[2], sys.argv[3].split(), sys.argv[4].split()
os.makedirs(os.path.join(target, "cameras"), exist_ok=True)
os.makedirs(os.path.join(target, "lidars"), exist_ok=True)
rig = yaml.safe_load(open(os.path.join(source, "rig.yaml")))
rig["cameras"] = {name: rig["cameras"][name] for name in cameras}
rig["lidars"] = {name: rig["lidars"][name] for name in lidars}
with open(os.path.join(target, "rig.yaml"), "w") as f:
    yaml.safe_dump(rig, f, sort_keys=False, default_flow_style=None)
truth_path = os.path.join(source, "ground_truth.yaml")
if os.path.exists(truth_path):
    truth = yaml.safe_load(open(truth_path))
    truth["lidars"] = {name: truth["lidars"][name] for name in lidars if name in truth.get("lidars", {})}
    with open(os.path.join(target, "ground_truth.yaml"), "w") as f:
        yaml.safe_dump(truth, f, sort_keys=False, default_flow_style=None)
def link(relative):
    path = os.path.join(target, relative)
    if not os.path.lexists(path):
        os.symlink(os.path.abspath(os.path.join(source, relative)), path)
link("trajectory.csv")
for name in cameras: link(os.path.join("cameras", name))
for name in lidars: link(os.path.join("lidars", name))
EOF
}

first_camera=$(python3 -c "import yaml,sys; print(next(iter(yaml.safe_load(open(sys.argv[1]))['cameras'])))" "$dataset/rig.yaml")
first_lidar=$(python3 -c "import yaml,sys; print(next(iter(yaml.safe_load(open(sys.argv[1]))['lidars'])))" "$dataset/rig.yaml")
make_view "$dataset" "$out/views/one_camera" "$first_camera" "$first_lidar"
views="two_cameras=$dataset one_camera=$out/views/one_camera"
if [[ -n "$trino" ]]; then
  trino_cameras=$(python3 -c "import yaml,sys; print(' '.join(yaml.safe_load(open(sys.argv[1]))['cameras']))" "$trino/rig.yaml")
  make_view "$trino" "$out/views/three_cameras" "$trino_cameras" "$first_lidar"
  views="$views three_cameras=$out/views/three_cameras"
fi

echo "machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'); $(date -u '+%Y-%m-%d %H:%M UTC'); load average at start: $(cut -d' ' -f1-3 /proc/loadavg)" \
  | tee "$out/machine.txt"

if [[ $parts == *kernel* ]]; then
  [[ -x "$bench" ]] || { echo "bench_scaling: $bench not built (-DSCENECAL_BUILD_BENCHMARKS=ON)" >&2; exit 2; }
  for view in $views; do
    name=${view%%=*}
    path=${view#*=}
    filter='BM_JointCost/'
    [[ $name != two_cameras ]] && filter='BM_JointCost/scenes:30/max_scans:0/'
    echo "kernel: $name ($path)" >&2
    SCENECAL_BENCH_DATASET=$path "$bench" --benchmark_filter="$filter" --benchmark_repetitions="$reps" \
      --benchmark_min_time=0.3 --benchmark_format=json >"$out/kernel_$name.json" 2>"$out/kernel_$name.err"
  done
fi

if [[ $parts == *e2e* ]]; then
  [[ -x "$scenecal" ]] || { echo "bench_scaling: $scenecal not built" >&2; exit 2; }
  run() {  # name view_path threads options...
    local name=$1 path=$2 threads=$3
    shift 3
    echo "e2e: $name threads $threads $*" >&2
    /usr/bin/time -v "$scenecal" calibrate "$path" --setting paper --scheme joint --threads "$threads" --no-basin-check \
      --output "$out/e2e_${name}_t$threads.yaml" "$@" >"$out/e2e_${name}_t$threads.log" 2>&1 || true
  }
  for threads in 1 2; do
    for scenes in 10 20 30 40; do run "scenes$scenes" "$dataset" "$threads" --scenes "$scenes"; done
    for scans in 8 16 32; do run "maxscans$scans" "$dataset" "$threads" --max-scans-per-scene "$scans"; done
    run one_camera "$out/views/one_camera" "$threads"
    [[ -n "$trino" ]] && run three_cameras "$out/views/three_cameras" "$threads"
  done
fi

python3 - "$out" <<'EOF'
import glob, json, os, re, sys
out = sys.argv[1]

def fit(xs, ys):
    """Least squares y = a + b x; returns a, b, R^2 and the largest |residual| / y."""
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    b = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx > 0 else 0.0
    a = my - b * mx
    ss_res = sum((y - a - b * x) ** 2 for x, y in zip(xs, ys))
    ss_tot = sum((y - my) ** 2 for y in ys)
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else 1.0
    worst = max(abs(y - a - b * x) / y for x, y in zip(xs, ys))
    return a, b, r2, worst

# ---- kernel ----
rows = {}
for path in sorted(glob.glob(os.path.join(out, "kernel_*.json"))):
    view = os.path.basename(path)[len("kernel_"):-len(".json")]
    try:
        data = json.load(open(path))
    except (ValueError, OSError):
        continue
    for b in data.get("benchmarks", []):
        if b.get("run_type") != "iteration" or "error_occurred" in b:
            continue
        m = re.match(r"BM_JointCost/scenes:(\d+)/max_scans:(\d+)/threads:(\d+)/kernel:(\d+)", b["name"])
        if not m:
            continue
        key = (view,) + tuple(int(g) for g in m.groups())
        r = rows.setdefault(key, {"wall": [], "cpu": []})
        r["wall"].append(b["real_time"])
        r["cpu"].append(b["cpu_time"])
        for c in ("points", "projected", "scenes", "checked_samples", "mismatched_bins"):
            r[c] = b.get(c, 0)
if rows:
    print("\n### One joint cost evaluation (bench_dataset BM_JointCost, min of the repetitions)\n")
    print("| view | scenes/camera | max scans | used scenes | swathe points | projected | threads | visitor ms | AddHardCounts ms | speed-up | M points/s (AddHardCounts) | bins checked: samples / differing |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    configs = sorted({k[:4] for k in rows}, key=lambda k: (k[0] != "two_cameras", k[0], k[3], rows[k + (0,)]["points"] if k + (0,) in rows else 0))
    for c in configs:
        v, h = rows.get(c + (0,)), rows.get(c + (1,))
        if not v or not h:
            continue
        tv, th = min(v["wall"]), min(h["wall"])
        print(f"| {c[0]} | {c[1]} | {c[2] or 'all'} | {int(h['scenes'])} | {int(h['points']):,} | {int(h['projected']):,} | {c[3]} | "
              f"{tv:.2f} | {th:.2f} | {tv / th:.2f}x | {h['points'] / th / 1e3:.0f} | {int(h['checked_samples']):,} / {int(h['mismatched_bins'])} |")
    print()
    for threads in (1, 2):
        for kernel, label in ((0, "visitor"), (1, "AddHardCounts")):
            pts = [(rows[k]["points"], min(rows[k]["wall"])) for k in rows
                   if k[0] == "two_cameras" and k[3] == threads and k[4] == kernel]
            if len(pts) >= 3:
                a, b, r2, worst = fit([p for p, _ in pts], [t for _, t in pts])
                print(f"- fit, two cameras, {threads} thread(s), {label}: t_eval = {a:.2f} ms + {b * 1e6:.2f} ms per million swathe points "
                      f"(R^2 = {r2:.4f}, {len(pts)} sizes, largest residual {100 * worst:.1f} %)")
    for kernel, label in ((0, "visitor"), (1, "AddHardCounts")):
        pairs = [(min(rows[k[:3] + (1, kernel)]["wall"]), min(rows[k[:3] + (2, kernel)]["wall"])) for k in rows
                 if k[0] == "two_cameras" and k[3] == 1 and k[4] == kernel and k[:3] + (2, kernel) in rows]
        if pairs:
            speedups = [t1 / t2 for t1, t2 in pairs]
            print(f"- 2 threads vs 1, {label}: {min(speedups):.2f}x .. {max(speedups):.2f}x over {len(pairs)} sizes")

# ---- end to end ----
def parse_log(path):
    text = open(path, errors="replace").read()
    r = {}
    m = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", text)
    if m:
        secs = 0.0
        for part in m.group(1).split(":"):
            secs = secs * 60 + float(part)
        r["wall"] = secs
    m = re.search(r"User time \(seconds\): (\S+)", text)
    r["user"] = float(m.group(1)) if m else float("nan")
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
    r["rss"] = int(m.group(1)) / 1024 if m else float("nan")
    m = re.search(r"loaded (\d+) lidar points in ([\d.]+) s", text)
    r["load"] = float(m.group(2)) if m else float("nan")
    m = re.search(r"built \d+ lidar problem\(s\) in ([\d.]+) s", text)
    r["build"] = float(m.group(1)) if m else float("nan")
    opt = re.findall(r"joint \S+: \d+ runs, \d+ iterations, (\d+) evaluations, .*?, ([\d.]+) s\s*$", text, re.M)
    r["evaluations"] = sum(int(e) for e, _ in opt)
    r["optimise"] = sum(float(s) for _, s in opt)
    used = re.findall(r"(\d+) of (\d+) scenes used", text)
    r["scenes"] = sum(int(u) for u, _ in used)
    r["exit"] = int(re.search(r"Exit status: (\d+)", text).group(1)) if "Exit status" in text else -1
    return r

e2e = {}
for path in glob.glob(os.path.join(out, "e2e_*_t[12].log")):
    m = re.match(r"e2e_(.+)_t(\d)\.log", os.path.basename(path))
    e2e[(m.group(1), int(m.group(2)))] = parse_log(path)
if e2e:
    # Swathe points per evaluation of the same configuration, from the kernel part (same selection and trimming).
    def points_of(name):
        view, scenes, scans = "two_cameras", 30, 0
        if name.startswith("scenes"): scenes = int(name[6:])
        elif name.startswith("maxscans"): scans = int(name[8:])
        elif name in ("one_camera", "three_cameras"): view = name
        r = rows.get((view, scenes, scans, 1, 1))
        return r["points"] if r else None
    order = lambda n: (n.startswith("maxscans") is False, n.startswith("scenes") is False, points_of(n) or 0)
    print("\n### Full `scenecal calibrate --setting paper --scheme joint`\n")
    print("| run | threads | used scenes | swathe points per evaluation | evaluations | optimisation s | ms per evaluation | load + build s | wall s | user s | peak RSS MB | exit |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for (name, threads) in sorted(e2e, key=lambda k: (k[1], order(k[0]))):
        r = e2e[(name, threads)]
        p = points_of(name)
        per_eval = 1e3 * r["optimise"] / r["evaluations"] if r["evaluations"] else float("nan")
        print(f"| {name} | {threads} | {r['scenes']} | {f'{p:,.0f}' if p else '?'} | {r['evaluations']} | {r['optimise']:.2f} | {per_eval:.2f} | "
              f"{r['load'] + r['build']:.2f} | {r.get('wall', float('nan')):.1f} | {r['user']:.1f} | {r['rss']:.0f} | {r['exit']} |")
    print()
    for threads in (1, 2):
        pts = [(points_of(n), 1e3 * r["optimise"] / r["evaluations"]) for (n, t), r in e2e.items()
               if t == threads and r["evaluations"] and points_of(n) and n != "three_cameras"]
        if len(pts) >= 3:
            a, b, r2, worst = fit([p for p, _ in pts], [t for _, t in pts])
            print(f"- fit, {threads} thread(s), time per evaluation inside calibrate: {a:.2f} ms + {b * 1e6:.2f} ms per million swathe points "
                  f"(R^2 = {r2:.4f}, {len(pts)} runs, largest residual {100 * worst:.1f} %)")
        pts = [(points_of(n), r["load"] + r["build"]) for (n, t), r in e2e.items()
               if t == threads and points_of(n) and n != "three_cameras" and r["load"] == r["load"]]
        if len(pts) >= 3:
            a, b, r2, worst = fit([p for p, _ in pts], [t for _, t in pts])
            print(f"- fit, {threads} thread(s), loading + swathe building: {a:.2f} s + {b * 1e6:.2f} s per million swathe points "
                  f"(R^2 = {r2:.4f}; loading depends on the scans read, not only on the trimmed swathes)")
    pairs = [(e2e[(n, 1)]["optimise"] / e2e[(n, 1)]["evaluations"], e2e[(n, 2)]["optimise"] / e2e[(n, 2)]["evaluations"])
             for (n, t) in e2e if t == 1 and (n, 2) in e2e and e2e[(n, 1)]["evaluations"] and e2e[(n, 2)]["evaluations"]]
    if pairs:
        s = [a / b for a, b in pairs]
        print(f"- 2 threads vs 1, time per evaluation inside calibrate: {min(s):.2f}x .. {max(s):.2f}x over {len(s)} runs")
EOF
