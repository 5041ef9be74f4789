#!/usr/bin/env bash
# What `scenecal calibrate` gives with no method option (--setting auto), against each named preset and the
# paper's pipeline, on simulated drives it was not tuned on.
#
#   scripts/bench_defaults.sh [OUT_DIR]
#
# Rows: simulator preset (PRESETS, default "robotcar trinocular spin3d") x odometry (ODOMETRY, "exact drifting":
# --odometry-noise 0, or the simulator's visual-odometry-like drift), over the worlds in WORLDS (default "1 2 3",
# --seed of simulate). Columns: SETTINGS (default "auto push-broom push-broom-alt push-broom-drifting 3d-lidar paper"; auto is the no-flag
# default). Each run starts PERTURB_T m / PERTURB_R deg (default 0.1, 3) from the truth in a random direction per
# seed of STARTS (default "1 2 3 4 5") and skips the uncertainty and the basin check. rig.yaml's
# trajectory_source is removed from the simulated data unless SOURCE=given, so that auto has to find the drift
# from the data, as on most recordings. A preset that does not fit the data (a push-broom preset on a 3D lidar)
# is shown as "-".
#
# Prints a Markdown table (median / worst translation and rotation error per lidar, median wall time, largest
# resident memory) and keeps it in OUT_DIR/table.md; with WRITE_BENCHMARK=1 it also replaces the table between
# the "bench_defaults" markers in BENCHMARK.md. Simulated data stay in OUT_DIR/data (reused when present).
# Other variables: SCENECAL (build/bin/scenecal), DISTANCE (simulate --distance; empty: the preset's own),
# THREADS (calibrate --threads, 0 = all), TABLE_ONLY=1 (the table again from OUT_DIR/results.tsv, no run).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/bench_defaults}
scenecal=${SCENECAL:-build/bin/scenecal}
presets=${PRESETS:-"robotcar trinocular spin3d"}
odometries=${ODOMETRY:-"exact drifting"}
worlds=${WORLDS:-"1 2 3"}
settings=${SETTINGS:-"auto push-broom push-broom-alt push-broom-drifting 3d-lidar paper"}
starts=${STARTS:-"1 2 3 4 5"}
perturb_t=${PERTURB_T:-0.1}
perturb_r=${PERTURB_R:-3}
source_mode=${SOURCE:-unknown}
threads=${THREADS:-0}

[[ -x "$scenecal" ]] || { echo "bench_defaults: $scenecal not built (scripts/build.sh)" >&2; exit 2; }
[[ -x /usr/bin/time ]] || { echo "bench_defaults: /usr/bin/time is missing (apt-get install time)" >&2; exit 2; }
case "$source_mode" in unknown | given) ;; *) echo "bench_defaults: SOURCE must be unknown or given" >&2; exit 2 ;; esac
mkdir -p "$out/data" "$out/runs"
results="$out/results.tsv"
[[ ${TABLE_ONLY:-0} == 1 ]] && presets=""  # the table again from $results, no run
[[ ${TABLE_ONLY:-0} == 1 ]] || printf 'preset\todometry\tworld\tsetting\tstart\tlidar\ttranslation_m\trotation_deg\tseconds\tmax_rss_kb\tchosen\n' >"$results"

source scripts/bench_simulate.sh

for preset in $presets; do
  for odometry in $odometries; do
    for world in $worlds; do
      data=$(simulate_once bench_defaults "$preset" "$odometry" "$world" "$source_mode")
      for setting in $settings; do
        for start in $starts; do
          tag="${preset}_${odometry}_w${world}_${setting}_${start}"
          setting_args=()
          [[ $setting == auto ]] || setting_args=(--setting "$setting")
          status=0
          /usr/bin/time -f '%e %M' -o "$out/runs/$tag.time" "$scenecal" calibrate "$data" --output "$out/runs/$tag.yaml" \
            "${setting_args[@]}" --seed "$start" --perturb-from-truth --perturb-translation "$perturb_t" \
            --perturb-rotation "$perturb_r" --no-uncertainty --no-basin-check --threads "$threads" \
            >"$out/runs/$tag.txt" 2>"$out/runs/$tag.log" || status=$?
          if [[ $status == 2 ]] && grep -q "the preset is for swathes" "$out/runs/$tag.log"; then
            break  # the preset does not fit these data: "-" in the table
          fi
          [[ $status == 0 ]] || { echo "bench_defaults: $tag failed (exit $status), see $out/runs/$tag.log" >&2; exit 1; }
          python3 - "$preset" "$odometry" "$world" "$setting" "$start" "$out/runs/$tag" >>"$results" <<'PY'
import re, sys
preset, odometry, world, setting, start, run = sys.argv[1:7]
seconds, rss_kb = open(run + '.time').read().split()[-2:]
chosen = ''
for line in open(run + '.yaml'):
    m = re.match(r'\s*setting: "?([^":\s]+)', line)
    if m and not chosen: chosen = m.group(1)
for line in open(run + '.txt'):
    if 'T_base_lidar error' not in line: continue
    lidar = line.split()[1]
    t, r = re.findall(r'[-+]?\d+\.\d+', line.split('error:')[1])[:2]
    print('\t'.join([preset, odometry, world, setting, start, lidar, t, r, seconds, rss_kb, chosen or 'none']))
PY
          tail -n1 "$results" >&2
        done
      done
    done
  done
done

python3 - "$results" "$settings" "$out/table.md" <<'PY'
import csv, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1]), delimiter='\t', quoting=csv.QUOTE_NONE))
settings = sys.argv[2].split()
groups = {}
for row in rows:
    groups.setdefault((row['preset'], row['odometry'], row['lidar']), {}).setdefault(row['setting'], []).append(row)
header = ['data', 'lidar', 'worlds x starts'] + [('no flags (auto)' if s == 'auto' else s) for s in settings]
lines = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
for (preset, odometry, lidar), by_setting in groups.items():
    runs = max(len(v) for v in by_setting.values())
    cells = []
    for s in settings:
        rs = by_setting.get(s)
        if not rs:
            cells.append('-')
            continue
        t = [100 * float(r['translation_m']) for r in rs]
        a = [float(r['rotation_deg']) for r in rs]
        secs = statistics.median(float(r['seconds']) for r in rs)
        gb = max(int(r['max_rss_kb']) for r in rs) / 1024 / 1024
        cell = f'{statistics.median(t):.2f} / {max(t):.2f} cm, {statistics.median(a):.3f} / {max(a):.3f} deg, {secs:.0f} s, {gb:.1f} GB'
        if s == 'auto':
            chosen = sorted(set(r['chosen'] for r in rs))
            cell += ' (' + ', '.join(chosen) + ')'
        cells.append(cell)
    worlds = len(set(r['world'] for v in by_setting.values() for r in v))
    lines.append(f'| {preset}, {odometry} odometry | {lidar} | {worlds} x {runs // max(worlds, 1)} | ' + ' | '.join(cells) + ' |')
table = '\n'.join(lines) + '\n'
open(sys.argv[3], 'w').write(table)
print(table, end='')
PY

if [[ ${WRITE_BENCHMARK:-0} == 1 ]]; then
  python3 - "$out/table.md" BENCHMARK.md <<'PY'
import sys
table = open(sys.argv[1]).read()
text = open(sys.argv[2]).read()
begin, end = '<!-- bench_defaults:begin -->\n', '<!-- bench_defaults:end -->'
if begin not in text or end not in text: sys.exit('bench_defaults: BENCHMARK.md has no bench_defaults markers')
head, rest = text.split(begin, 1)
open(sys.argv[2], 'w').write(head + begin + table + end + rest.split(end, 1)[1])
PY
  echo "bench_defaults: table written into BENCHMARK.md" >&2
fi
