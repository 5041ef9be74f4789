#!/usr/bin/env bash
# Accuracy benchmark of `scenecal calibrate` from perturbed initial guesses.
#
#   scripts/bench_accuracy.sh [DATASET] [OUT_DIR]
#
# DATASET defaults to /tmp/rc; it is simulated first when missing
# (scenecal simulate --preset robotcar --seed 1 --output DATASET).
# For every scheme x metric (SCHEMES, METRICS; default once joint x nid mi)
# and every seed in SEEDS (default 1..10) the lidar's initial guess is set to
# the TRUE T_base_lidar moved by PERTURB_T metres and PERTURB_R
# degrees (default 0.1, 3) in random directions drawn from the seed
# (--perturb-from-truth --perturb-translation/--perturb-rotation), then
# calibrated. Prints, per scheme x metric x lidar, the median, max and
# interquartile range of the translation / rotation error of T_base_lidar
# against ground_truth.yaml, the largest final gap between the alternating
# scheme's lower and upper levels, and the wall time per run, as a Markdown
# table; per-run logs and results stay in OUT_DIR. Extra calibrate options
# can be given in CALIBRATE_ARGS. The basin check is skipped (--no-basin-check):
# it reports, it does not change the result, and it would add to the times.
set -euo pipefail
cd "$(dirname "$0")/.."
dataset=${1:-/tmp/rc}
out=${2:-/tmp/scenecal_bench_accuracy}
scenecal=${SCENECAL:-build/bin/scenecal}
seeds=${SEEDS:-"1 2 3 4 5 6 7 8 9 10"}
schemes=${SCHEMES:-"once joint"}
metrics=${METRICS:-"nid mi"}
perturb_t=${PERTURB_T:-0.1}
perturb_r=${PERTURB_R:-3}
extra=${CALIBRATE_ARGS:-}

[[ -x "$scenecal" ]] || { echo "bench_accuracy: $scenecal not built (scripts/build.sh)" >&2; exit 2; }
if [[ ! -f "$dataset/rig.yaml" ]]; then
  echo "bench_accuracy: simulating $dataset" >&2
  "$scenecal" simulate --preset robotcar --seed 1 --output "$dataset" >&2
fi
mkdir -p "$out"
results="$out/results.tsv"
printf 'scheme\tmetric\tseed\tlidar\ttranslation_m\trotation_deg\tseconds\tdx_cm\tdy_cm\tdz_cm\tdroll_deg\tdpitch_deg\tdyaw_deg\tlevels_apart_m\tlevels_apart_deg\n' >"$results"
for scheme in $schemes; do
  for metric in $metrics; do
    for seed in $seeds; do
      tag="${scheme}_${metric}_${seed}"
      start=$(date +%s.%N)
      # shellcheck disable=SC2086
      "$scenecal" calibrate "$dataset" --output "$out/$tag.yaml" --scheme "$scheme" --metric "$metric" \
        --seed "$seed" --perturb-from-truth --perturb-translation "$perturb_t" --perturb-rotation "$perturb_r" --no-basin-check $extra \
        >"$out/$tag.txt" 2>"$out/$tag.log"
      end=$(date +%s.%N)
      # One row per lidar: "lidar NAME T_base_lidar error: translation A m, rotation B deg | dx .. cm | droll .. deg"
      python3 - "$scheme" "$metric" "$seed" "$start" "$end" "$out/$tag.txt" "$out/$tag.yaml" >>"$results" <<'PY'
import math, re, sys
scheme, metric, seed, start, end, text, result = sys.argv[1:8]
lines = [l for l in open(text) if 'T_base_lidar error' in l]
if not lines: sys.exit(f'bench_accuracy: no "T_base_lidar error" line in {text} (calibration failed? see the .log)')
# The alternating scheme's last history entry: how far apart its two levels ended (all pairs).
apart_m = apart_rad = ''
for l in open(result):
    m = re.match(r'\s*levels_apart_m: (\S+)', l)
    if m: apart_m = m.group(1)
    m = re.match(r'\s*levels_apart_rad: (\S+)', l)
    if m: apart_rad = m.group(1)
apart_deg = f'{math.degrees(float(apart_rad)):.6f}' if apart_rad else ''
for line in lines:
    lidar = line.split()[1]
    numbers = re.findall(r'[-+]?\d+\.\d+', line.split('error:')[1])
    t, r, dx, dy, dz, droll, dpitch, dyaw = numbers[:8]
    print('\t'.join([scheme, metric, seed, lidar, t, r, f'{float(end) - float(start):.1f}', dx, dy, dz, droll, dpitch,
                     dyaw, apart_m, apart_deg]))
PY
      tail -n"$(grep -c 'T_base_lidar error' "$out/$tag.txt")" "$results" >&2
    done
  done
done
python3 - "$results" <<'PY'
import csv, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1]), delimiter='\t'))
def iqr(values):
    if len(values) < 4: return float('nan')
    q = statistics.quantiles(values, n=4, method='inclusive')
    return q[2] - q[0]
print('| scheme | metric | lidar | runs | median t (cm) | max t (cm) | IQR t (cm) | median r (deg) | max r (deg) | IQR r (deg) | '
      'median abs droll (deg) | max levels apart (mm / deg) | median time (s) |')
print('|---|---|---|---|---|---|---|---|---|---|---|---|---|')
groups = {}
for row in rows: groups.setdefault((row['scheme'], row['metric'], row['lidar']), []).append(row)
for (scheme, metric, lidar), rs in groups.items():
    t = [100 * float(r['translation_m']) for r in rs]
    a = [float(r['rotation_deg']) for r in rs]
    roll = [abs(float(r['droll_deg'])) for r in rs]
    s = [float(r['seconds']) for r in rs]
    apart = [(1000 * float(r['levels_apart_m']), float(r['levels_apart_deg'])) for r in rs if r['levels_apart_m']]
    apart_text = f'{max(x for x, _ in apart):.3f} / {max(y for _, y in apart):.4f}' if apart else '-'
    print(f'| {scheme} | {metric} | {lidar} | {len(rs)} | {statistics.median(t):.2f} | {max(t):.2f} | {iqr(t):.2f} | '
          f'{statistics.median(a):.3f} | {max(a):.3f} | {iqr(a):.3f} | {statistics.median(roll):.3f} | {apart_text} | '
          f'{statistics.median(s):.1f} |')
PY
