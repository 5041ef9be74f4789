#!/usr/bin/env bash
# Short recordings: `scenecal calibrate` with no flags on a few consecutive camera frames cut from a simulated
# drive, against the preset's whole schedule (its wide, blurred first stages forced with --stages) and its narrow
# stages alone.
#
#   scripts/bench_short.sh [OUT_DIR]
#
# Rows: simulator preset (PRESETS, default "spin3d robotcar", exact odometry) x world (WORLDS, default "1 2 3") x
# recording length (FRAMES, default "3 5 8 12": that many consecutive camera frames from the FIRST-th, default 10;
# the scans and trajectory rows within 0.3 s / 0.6 s of them). Each run starts PERTURB_T m / PERTURB_R deg (default
# 0.1, 2) from the truth in a random direction per seed of STARTS (default "1 2 3"), without the uncertainty and the
# basin check. Columns (COLUMNS, default "auto wide narrow"): no flags (what auto chose and whether it left the wide
# stages out), the preset's whole schedule, its narrow stages. Each run adds a row to OUT_DIR/results.tsv (remove
# it to start afresh). Prints a Markdown table (median / worst translation and rotation error, the frames with a
# scene, median time) and keeps it in OUT_DIR/table.md. Whole drives stay in OUT_DIR/data (reused; spin3d
# DISTANCE 150 m as in BENCHMARK.md), the cut recordings in OUT_DIR/short. Other variables: SCENECAL
# (build/bin/scenecal), TABLE_ONLY=1 (the table again from OUT_DIR/results.tsv).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/bench_short}
scenecal=${SCENECAL:-build/bin/scenecal}
presets=${PRESETS:-"spin3d robotcar"}
worlds=${WORLDS:-"1 2 3"}
frame_counts=${FRAMES:-"3 5 8 12"}
first=${FIRST:-10}
starts=${STARTS:-"1 2 3"}
columns=${COLUMNS:-"auto wide narrow"}
perturb_t=${PERTURB_T:-0.1}
perturb_r=${PERTURB_R:-2}
wide="1:0.02:1,1:0.004:2,0.3:0.0015:1,0.1:0:1"  # the push-broom and 3d-lidar presets' schedule
narrow="0.3:0.0015:1,0.1:0:1"

[[ -x "$scenecal" ]] || { echo "bench_short: $scenecal not built (scripts/build.sh)" >&2; exit 2; }
[[ -x /usr/bin/time ]] || { echo "bench_short: /usr/bin/time is missing (apt-get install time)" >&2; exit 2; }
mkdir -p "$out/data" "$out/short" "$out/runs"
results="$out/results.tsv"
[[ ${TABLE_ONLY:-0} == 1 ]] && presets=""
[[ ${TABLE_ONLY:-0} == 1 || -f $results ]] || printf 'preset\tworld\tframes\tcolumn\tstart\tused_frames\ttranslation_m\trotation_deg\tseconds\tnarrowed\n' >"$results"

source scripts/bench_simulate.sh

# cut_recording SOURCE DESTINATION N: N consecutive camera frames from the FIRST-th (by the first camera's
# image times), every camera's images at those times, the scans and trajectory rows around them.
cut_recording() {
  local source=$1 destination=$2 count=$3
  [[ -f "$destination/rig.yaml" ]] && return 0
  rm -rf "$destination" && mkdir -p "$destination/cameras" "$destination/lidars"
  cp "$source/rig.yaml" "$source/ground_truth.yaml" "$destination/"
  local cameras reference t0 t1 camera lidar file t
  cameras=$(ls "$source/cameras")
  reference=$(echo "$cameras" | head -n1)
  local times
  times=$(ls "$source/cameras/$reference" | sed -n "${first},$((first + count - 1))p" | sed 's/\..*//')
  [[ $(echo "$times" | wc -w) == "$count" ]] || { echo "bench_short: $source has fewer than $((first + count - 1)) frames" >&2; exit 1; }
  t0=$(echo "$times" | head -n1)
  t1=$(echo "$times" | tail -n1)
  for camera in $cameras; do
    mkdir -p "$destination/cameras/$camera"
    for file in "$source/cameras/$camera"/*; do
      t=$(basename "${file%.*}")
      if ((t >= t0 - 50000 && t <= t1 + 50000)); then cp "$file" "$destination/cameras/$camera/"; fi
    done
  done
  for lidar in $(ls "$source/lidars"); do
    mkdir -p "$destination/lidars/$lidar"
    for file in "$source/lidars/$lidar"/*.bin; do
      t=$(basename "${file%.bin}")
      if ((t >= t0 - 300000 && t <= t1 + 300000)); then cp "$file" "$destination/lidars/$lidar/"; fi
    done
  done
  awk -F, -v from=$((t0 - 600000)) -v to=$((t1 + 600000)) 'NR == 1 || ($1 >= from && $1 <= to)' \
    "$source/trajectory.csv" >"$destination/trajectory.csv"
}

for preset in $presets; do
  for world in $worlds; do
    DISTANCE=""
    [[ $preset == spin3d ]] && DISTANCE=150
    data=$(simulate_once bench_short "$preset" exact "$world" unknown)
    for frames in $frame_counts; do
      recording="$out/short/${preset}_w${world}_n${frames}"
      cut_recording "$data" "$recording" "$frames"
      for column in $columns; do
        for start in $starts; do
          tag="${preset}_w${world}_n${frames}_${column}_${start}"
          stages=()
          [[ $column == wide ]] && stages=(--stages "$wide")
          [[ $column == narrow ]] && stages=(--stages "$narrow")
          status=0
          /usr/bin/time -f '%e' -o "$out/runs/$tag.time" "$scenecal" calibrate "$recording" \
            --output "$out/runs/$tag.yaml" --seed "$start" --perturb-from-truth --perturb-translation "$perturb_t" \
            --perturb-rotation "$perturb_r" --no-uncertainty --no-basin-check "${stages[@]}" \
            >"$out/runs/$tag.txt" 2>"$out/runs/$tag.log" || status=$?
          [[ $status == 0 ]] || { echo "bench_short: $tag failed (exit $status), see $out/runs/$tag.log" >&2; exit 1; }
          python3 - "$out/runs/$tag" "$preset" "$world" "$frames" "$column" "$start" >>"$results" <<'PY'
import re, sys, yaml
run, preset, world, frames, column, start = sys.argv[1:7]
result = yaml.safe_load(open(run + '.yaml'))
seconds = open(run + '.time').read().split()[0]
used = int(re.search(r'/ \S+: (\d+) scenes', open(run + '.log').read()).group(1))  # the first solve's
narrowed = 'yes' if 'few_frames' in result.get('settings', {}) else 'no'
for line in open(run + '.txt'):
    if re.match(r'lidar \S+ T_base_lidar error:', line):
        t, r = [float(x) for x in re.findall(r'[-+]?\d+\.\d+', line.split('error:')[1])[:2]]
        print('\t'.join([preset, world, frames, column, start, str(used), f'{t:.4f}', f'{r:.3f}', seconds, narrowed]))
PY
          tail -n1 "$results" >&2
        done
      done
    done
  done
done

python3 - "$results" "$out/table.md" <<'PY'
import statistics, sys
from collections import defaultdict
rows = [line.rstrip('\n').split('\t') for line in open(sys.argv[1])][1:]
cells = defaultdict(list)
for preset, world, frames, column, start, used, t, r, seconds, narrowed in rows:
    cells[(preset, int(frames), column)].append((float(t), float(r), float(seconds), int(used), narrowed))
def cell(runs):
    if not runs:
        return '-'
    t = [x[0] * 100 for x in runs]; r = [x[1] for x in runs]
    return (f'{statistics.median(t):.2f} / {max(t):.2f} cm, {statistics.median(r):.3f} / {max(r):.3f} deg, '
            f'{statistics.median(x[2] for x in runs):.0f} s')
lines = ['| data | frames cut (used) | runs | no flags | no flags left the wide stages out | whole schedule (wide stages) '
         '| narrow stages only |', '|---|---|---|---|---|---|---|']
for preset, frames in sorted({(k[0], k[1]) for k in cells}):
    auto = cells[(preset, frames, 'auto')]
    used = sorted({x[3] for x in auto})
    narrowed = sum(x[4] == 'yes' for x in auto)
    lines.append(f'| {preset}, exact odometry | {frames} ({used[0]}-{used[-1]}) | {len(auto)} | {cell(auto)} | '
                 f'{narrowed} of {len(auto)} | {cell(cells[(preset, frames, "wide")])} | '
                 f'{cell(cells[(preset, frames, "narrow")])} |')
open(sys.argv[2], 'w').write('\n'.join(lines) + '\n')
print('\n'.join(lines))
PY
