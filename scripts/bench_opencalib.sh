#!/usr/bin/env bash
# Real-data accuracy benchmark on the OpenCalib frames (issue 3).
#
#   scripts/bench_opencalib.sh [OUT_DIR]
#
# Imports the three OpenCalib sets of $SCENECAL_SHARED_DATA (default
# /work/shared/data)/opencalib into OUT_DIR/data/{1,2,3} (scenecal import
# opencalib), then for every set and every seed in SEEDS (default 1..10)
# calibrates from the data set's reference T_camera_lidar (ground_truth.yaml)
# moved by PERTURB_T metres and PERTURB_R degrees (default 0.05, 1) in random
# directions drawn from the seed (--perturb-from-truth). The same seed gives
# the same initial guess on sets 1 and 2 (same rig, same reference).
# Prints, as Markdown tables:
#   - per set: median / max translation and rotation error to the reference,
#     the median per-axis error (camera frame), and the median wall time;
#   - per set: the spread of its own results (the largest distance of a
#     result from the set's median result: does the set converge to one point
#     whatever the start?);
#   - sets 1 vs 2: for each seed the distance between their results (median, max).
# Per-run logs and results stay in OUT_DIR (default /tmp/scenecal_bench_opencalib).
# SCHEME (default joint: one camera, so once = joint), METRIC (nid), THREADS (1)
# and extra calibrate options in CALIBRATE_ARGS.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-/tmp/scenecal_bench_opencalib}
scenecal=${SCENECAL:-build/bin/scenecal}
source_root=${SCENECAL_SHARED_DATA:-/work/shared/data}/opencalib
seeds=${SEEDS:-"1 2 3 4 5 6 7 8 9 10"}
sets=${SETS:-"1 2 3"}
scheme=${SCHEME:-joint}
metric=${METRIC:-nid}
threads=${THREADS:-1}
perturb_t=${PERTURB_T:-0.05}
perturb_r=${PERTURB_R:-1}
extra=${CALIBRATE_ARGS:-}

[[ -x "$scenecal" ]] || { echo "bench_opencalib: $scenecal not built (scripts/build.sh)" >&2; exit 2; }
mkdir -p "$out/data"
for set in $sets; do
  "$scenecal" import opencalib "$source_root/$set" --output "$out/data/$set" --force >/dev/null 2>"$out/import_$set.log"
done
results="$out/results.tsv"
printf 'set\tseed\tseconds\tresult_file\n' >"$results"
for set in $sets; do
  for seed in $seeds; do
    tag="set${set}_seed${seed}"
    start=$(date +%s.%N)
    # shellcheck disable=SC2086
    "$scenecal" calibrate "$out/data/$set" --output "$out/$tag.yaml" --scheme "$scheme" --metric "$metric" \
      --threads "$threads" --seed "$seed" --perturb-from-truth --perturb-translation "$perturb_t" \
      --perturb-rotation "$perturb_r" --no-basin-check $extra >"$out/$tag.txt" 2>"$out/$tag.log" ||
      { echo "bench_opencalib: calibrate failed for $tag (see $out/$tag.log)" >&2; exit 1; }
    end=$(date +%s.%N)
    printf '%s\t%s\t%.2f\t%s\n' "$set" "$seed" "$(awk "BEGIN{print $end - $start}")" "$out/$tag.yaml" >>"$results"
    grep -m1 'T_camera_lidar error' "$out/$tag.txt" | sed "s/^/$tag: /" >&2
  done
done
# Errors and agreement from the result files (pairs[0].T_camera_lidar, the
# 6-tuple x y z roll pitch yaw with R = Rz Ry Rx) and each set's ground_truth.yaml.
python3 - "$results" "$out/data" <<'PY'
import csv, math, re, statistics, sys

def tuple_from_yaml(path, key):
    text = open(path).read()
    m = re.search(key + r':\s*\[([^\]]*)\]', text)
    return [float(v) for v in m.group(1).split(',')]

def rot(r, p, y):
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr]]

def matmul(a, b): return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
def transpose(a): return [list(r) for r in zip(*a)]

def difference(est, ref):
    """(translation m, rotation deg, per-axis dt cm (camera frame), rotation vector deg of R_est R_ref^T)."""
    dt = [100 * (e - r) for e, r in zip(est[:3], ref[:3])]
    d = matmul(rot(*est[3:]), transpose(rot(*ref[3:])))
    angle = math.acos(max(-1.0, min(1.0, (d[0][0] + d[1][1] + d[2][2] - 1) / 2)))
    s = 2 * math.sin(angle) if angle > 1e-12 else 2.0
    k = angle / s if angle > 1e-12 else 0.5
    w = [math.degrees(k * (d[2][1] - d[1][2])), math.degrees(k * (d[0][2] - d[2][0])), math.degrees(k * (d[1][0] - d[0][1]))]
    return math.hypot(*dt) / 100, math.degrees(angle), dt, w

rows = list(csv.DictReader(open(sys.argv[1]), delimiter='\t'))
data = sys.argv[2]
by_set = {}
for row in rows:
    est = tuple_from_yaml(row['result_file'], 'T_camera_lidar')
    ref = tuple_from_yaml(f"{data}/{row['set']}/ground_truth.yaml", 'T_base_lidar')  # base = camera
    by_set.setdefault(row['set'], {})[row['seed']] = (est, ref, float(row['seconds']))

med = statistics.median
print('| set | runs | median t (cm) | max t (cm) | median r (deg) | max r (deg) | median abs dx dy dz (cm) | median abs rx ry rz (deg) | median time (s) |')
print('|---|---|---|---|---|---|---|---|---|')
for s, runs in by_set.items():
    diffs = [difference(e, r) for e, r, _ in runs.values()]
    t = [100 * d[0] for d in diffs]
    a = [d[1] for d in diffs]
    axes_t = ' '.join(f'{med(abs(d[2][i]) for d in diffs):.1f}' for i in range(3))
    axes_r = ' '.join(f'{med(abs(d[3][i]) for d in diffs):.2f}' for i in range(3))
    print(f'| {s} | {len(diffs)} | {med(t):.2f} | {max(t):.2f} | {med(a):.3f} | {max(a):.3f} | {axes_t} | {axes_r} | '
          f'{med(x[2] for x in runs.values()):.1f} |')

print()
print('| set | spread: max distance of a result from the median result, t (cm) | r (deg) |')
print('|---|---|---|')
for s, runs in by_set.items():
    ests = [e for e, _, _ in runs.values()]
    centre = [med(e[i] for e in ests) for i in range(6)]
    d = [difference(e, centre) for e in ests]
    print(f'| {s} | {max(100 * x[0] for x in d):.2f} | {max(x[1] for x in d):.3f} |')

if '1' in by_set and '2' in by_set:
    seeds = sorted(set(by_set['1']) & set(by_set['2']), key=int)
    d = [difference(by_set['1'][k][0], by_set['2'][k][0]) for k in seeds]
    if d:
        t = [100 * x[0] for x in d]
        a = [x[1] for x in d]
        print()
        print('| sets 1 vs 2 (same seed) | runs | median t (cm) | max t (cm) | median r (deg) | max r (deg) |')
        print('|---|---|---|---|---|---|')
        print(f'| agreement | {len(d)} | {med(t):.2f} | {max(t):.2f} | {med(a):.3f} | {max(a):.3f} |')
PY
