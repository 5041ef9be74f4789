#!/usr/bin/env bash
# Does the result's sigma cover the true error? Runs `scenecal calibrate` with no method option (uncertainty and
# basin check on, as by default) on simulated drives and compares each lidar's error with its covariance.
#
#   scripts/bench_uncertainty.sh [OUT_DIR]
#
# Runs: PRESETS (default "robotcar trinocular spin3d") x ODOMETRY ("exact drifting") x WORLDS ("1 2 3") x STARTS
# ("1 2"), each start PERTURB_T m / PERTURB_R deg (0.1, 3) from the truth. rig.yaml's trajectory_source is removed
# so that the default decides about drift from the data, unless SOURCE=given (then the default follows rig.yaml, and
# the basin check measures the drift model's move; use another OUT_DIR: the simulated data differ). Per lidar and run: the error, the Mahalanobis distance of
# the error under the result's covariance (6 dof: 95 % within 3.55), 2 sigma over the error per axis, the
# verdict, the uncertainty's time (local estimate + basin check) against the calibration's, and the error in
# pixels (the RMS misalignment it causes normal to the image edges).
#
# Prints a Markdown table per group and in all (OUT_DIR/table.md): runs, the share within the 95 % ellipsoid, the
# median over axes and runs of 2 sigma / |error|, the verdicts, and the share of `good` verdicts whose error is
# within 1 cm / 0.2 deg; then the scene-choice table of scripts/bench_scenes.sh in OUT_DIR/scenes (SCENES=0 skips
# it). Simulated data stay in OUT_DIR/data (reused). SCENECAL (build/bin/scenecal), DISTANCE
# (simulate --distance), TABLE_ONLY=1 (the table again from OUT_DIR/results.tsv).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/bench_uncertainty}
scenecal=${SCENECAL:-build/bin/scenecal}
presets=${PRESETS:-"robotcar trinocular spin3d"}
odometries=${ODOMETRY:-"exact drifting"}
worlds=${WORLDS:-"1 2 3"}
starts=${STARTS:-"1 2"}
perturb_t=${PERTURB_T:-0.1}
perturb_r=${PERTURB_R:-3}
source_mode=${SOURCE:-unknown}
case "$source_mode" in unknown | given) ;; *) echo "bench_uncertainty: SOURCE must be unknown or given" >&2; exit 2 ;; esac

source scripts/bench_simulate.sh
[[ -x "$scenecal" ]] || { echo "bench_uncertainty: $scenecal not built (scripts/build.sh)" >&2; exit 2; }
mkdir -p "$out/data" "$out/runs"
results="$out/results.tsv"
[[ ${TABLE_ONLY:-0} == 1 ]] && presets=""
[[ ${TABLE_ONLY:-0} == 1 || -f $results ]] ||
  printf 'preset\todometry\tworld\tstart\tlidar\ttranslation_m\trotation_deg\tmahalanobis\tratios\tverdict\tcalibrate_s\tuncertainty_s\terror_px\tsource\n' >"$results"

for preset in $presets; do
  for odometry in $odometries; do
    for world in $worlds; do
      data=$(simulate_once bench_uncertainty "$preset" "$odometry" "$world" "$source_mode")
      has_source=unknown
      grep -q '^trajectory_source:' "$data/rig.yaml" && has_source=given
      [[ $has_source == "$source_mode" ]] || {
        echo "bench_uncertainty: $data was simulated with SOURCE=$has_source, this run has SOURCE=$source_mode;" \
          "use another OUT_DIR" >&2
        exit 2
      }
      for start in $starts; do
        tag="${preset}_${odometry}_w${world}_${start}"
        grep -q "^${preset}	${odometry}	${world}	${start}	" "$results" && continue  # done in an earlier run
        status=0
        "$scenecal" calibrate "$data" --output "$out/runs/$tag.yaml" --seed "$start" --perturb-from-truth \
          --perturb-translation "$perturb_t" --perturb-rotation "$perturb_r" \
          >"$out/runs/$tag.txt" 2>"$out/runs/$tag.log" || status=$?
        [[ $status == 0 ]] || { echo "bench_uncertainty: $tag failed (exit $status), see $out/runs/$tag.log" >&2; exit 1; }
        python3 - "$preset" "$odometry" "$world" "$start" "$out/runs/$tag" "$data/ground_truth.yaml" "$source_mode" \
          >>"$results" <<'PY'
import math, re, sys, yaml
preset, odometry, world, start, run, truth_file, source = sys.argv[1:8]
result = yaml.safe_load(open(run + '.yaml'))
truth = yaml.safe_load(open(truth_file))['lidars']
timings = result.get('timings_s', {})
calibrate_s = timings.get('total', 0.0) - timings.get('uncertainty', 0.0) - timings.get('basin_check', 0.0)
uncertainty_s = timings.get('uncertainty', 0.0) + timings.get('basin_check', 0.0)
distance, pixels = {}, {}
for line in open(run + '.txt'):
    if 'error in sigmas: Mahalanobis' in line:
        distance[line.split()[1]] = float(line.split('Mahalanobis')[1].split()[0])
    if 'error in pixels:' in line:
        pixels[line.split()[1]] = float(line.split('error in pixels:')[1].split()[0])
for name, lidar in result['lidars'].items():
    estimate, reference = lidar['T_base_lidar'], truth[name]['T_base_lidar']
    error = [estimate[i] - reference[i] if i < 3 else math.remainder(estimate[i] - reference[i], 2 * math.pi)
             for i in range(6)]
    sigma = lidar.get('sigma')
    ratios = ','.join(f'{2 * s / max(abs(e), 1e-12):.3g}' for s, e in zip(sigma, error)) if sigma else ''
    verdict = result.get('uncertainty', {}).get(name, {}).get('verdict', 'none')
    t_error = r_error = float('nan')  # FORMAT.md's errors, as calibrate prints them
    for line in open(run + '.txt'):
        if line.startswith(f'lidar {name} T_base_lidar error:'):
            t_error, r_error = [float(x) for x in re.findall(r'[-+]?\d+\.\d+', line.split('error:')[1])[:2]]
    print('\t'.join([preset, odometry, world, start, name, f'{t_error:.5f}', f'{r_error:.4f}',
                     f'{distance.get(name, float("inf")):.3f}', ratios, verdict, f'{calibrate_s:.1f}',
                     f'{uncertainty_s:.1f}', f'{pixels.get(name, float("nan")):.3f}', source]))
PY
        tail -n1 "$results" >&2
      done
    done
  done
done

python3 - "$results" "$out/table.md" <<'PY'
import csv, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1]), delimiter='\t', quoting=csv.QUOTE_NONE))
def line(label, rs):
    inside = sum(float(r['mahalanobis']) <= 3.55 for r in rs)
    ratios = [float(x) for r in rs if r['ratios'] for x in r['ratios'].split(',')]
    verdicts = {}
    for r in rs: verdicts[r['verdict']] = verdicts.get(r['verdict'], 0) + 1
    good = [r for r in rs if r['verdict'] == 'good']
    good_ok = sum(float(r['translation_m']) <= 0.01 and float(r['rotation_deg']) <= 0.2 for r in good)
    share = statistics.median(float(r['uncertainty_s']) / max(float(r['calibrate_s']), 1e-9) for r in rs)
    t = statistics.median(100 * float(r['translation_m']) for r in rs)
    a = statistics.median(float(r['rotation_deg']) for r in rs)
    px = [float(r.get('error_px') or 'nan') for r in rs]
    px = statistics.median(px) if all(p == p for p in px) else float('nan')
    return (f'| {label} | {len(rs)} | {inside} ({100 * inside / len(rs):.0f} %) | '
            f'{statistics.median(ratios) if ratios else float("nan"):.2f} | {t:.2f} cm, {a:.3f} deg, {px:.2f} px | '
            + ', '.join(f'{k} {v}' for k, v in sorted(verdicts.items()))
            + f' | {good_ok} of {len(good)} | {share:.2f} |')
groups = {}
for r in rows: groups.setdefault((r['preset'], r['odometry'], r.get('source') or 'unknown'), []).append(r)
lines = ['| data | lidar runs | error within the 95 % ellipsoid | median 2 sigma / abs(error), per axis | '
         'median error (and in pixels normal to the image edges) | verdicts | `good` within 1 cm / 0.2 deg | uncertainty time / calibration time (median) |',
         '|---|---|---|---|---|---|---|---|']
for (preset, odometry, source), rs in groups.items():
    lines.append(line(f'{preset}, {odometry} odometry' + (', trajectory_source given' if source == 'given' else ''), rs))
if rows: lines.append(line('all', rows))
table = '\n'.join(lines) + '\n'
open(sys.argv[2], 'w').write(table)
print(table, end='')
PY

# The issue's second table: informative scenes against the spread by distance (SCENES=0 skips it).
if [[ ${SCENES:-1} == 1 ]]; then
  echo "bench_uncertainty: the scene-choice table (scripts/bench_scenes.sh $out/scenes)" >&2
  SCENECAL="$scenecal" TABLE_ONLY="${TABLE_ONLY:-0}" scripts/bench_scenes.sh "$out/scenes"
fi
