#!/usr/bin/env bash
# Informative scene choice against the paper's spread by distance: the same accuracy with fewer scenes?
# Runs `scenecal calibrate` (its automatic method; uncertainty and basin check off) on simulated drives with
#   spread S      (--scenes S, evenly by distance: the paper)
#   informative S (--scenes S --scene-choice informative --scene-pool P: the S most informative of P*S frames)
#   auto          (--scenes auto: the informative choice, the count from the data)
# for each S in FULL and HALF, and prints the error (median and worst over worlds and starts), time and memory.
#
#   scripts/bench_scenes.sh [OUT_DIR]
#
# PRESETS ("robotcar trinocular"), ODOMETRY ("exact"), WORLDS ("1 2 3"), STARTS ("1 2 3"), FULL (30), HALF (15),
# POOL (2: the informative pool of HALF scenes is the FULL spread set), each start PERTURB_T m / PERTURB_R deg
# (0.1, 3) from the truth, DISTANCE (simulate --distance), CALIBRATE_ARGS (more calibrate options for every run).
# Resumable (OUT_DIR/results.tsv); TABLE_ONLY=1 prints the table again. Simulated data stay in OUT_DIR/data (reused).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/bench_scenes}
scenecal=${SCENECAL:-build/bin/scenecal}
presets=${PRESETS:-"robotcar trinocular"}
odometries=${ODOMETRY:-"exact"}
worlds=${WORLDS:-"1 2 3"}
starts=${STARTS:-"1 2 3"}
full=${FULL:-30}
half=${HALF:-15}
pool=${POOL:-2}
perturb_t=${PERTURB_T:-0.1}
perturb_r=${PERTURB_R:-3}
read -r -a extra_args <<<"${CALIBRATE_ARGS:-}"  # more calibrate options for every run

source scripts/bench_simulate.sh
[[ -x "$scenecal" ]] || { echo "bench_scenes: $scenecal not built (scripts/build.sh)" >&2; exit 2; }
mkdir -p "$out/data" "$out/runs"
results="$out/results.tsv"
[[ ${TABLE_ONLY:-0} == 1 ]] && presets=""
[[ ${TABLE_ONLY:-0} == 1 || -f $results ]] ||
  printf 'preset\todometry\tworld\tstart\tmethod\tlidar\ttranslation_m\trotation_deg\tseconds\tmax_rss_kb\n' >"$results"

configs=("spread_${full}:--scenes $full" "spread_${half}:--scenes $half"
         "informative_${half}:--scenes $half --scene-choice informative --scene-pool $pool" "auto:--scenes auto")
for preset in $presets; do
  for odometry in $odometries; do
    for world in $worlds; do
      data=$(simulate_once bench_scenes "$preset" "$odometry" "$world" given)
      for start in $starts; do
        for config in "${configs[@]}"; do
          method=${config%%:*}
          read -r -a method_args <<<"${config#*:}"
          tag="${preset}_${odometry}_w${world}_${start}_${method}"
          grep -q "^${preset}	${odometry}	${world}	${start}	${method}	" "$results" && continue  # done earlier
          status=0
          /usr/bin/time -f '%e %M' -o "$out/runs/$tag.time" "$scenecal" calibrate "$data" --output "$out/runs/$tag.yaml" \
            --seed "$start" --perturb-from-truth --perturb-translation "$perturb_t" --perturb-rotation "$perturb_r" \
            --no-uncertainty --no-basin-check "${method_args[@]}" "${extra_args[@]}" >"$out/runs/$tag.txt" \
            2>"$out/runs/$tag.log" ||
            status=$?
          [[ $status == 0 ]] || { echo "bench_scenes: $tag failed (exit $status), see $out/runs/$tag.log" >&2; exit 1; }
          read -r seconds rss_kb <"$out/runs/$tag.time"
          # calibrate prints per lidar: "lidar NAME T_base_lidar error: translation T m, rotation R deg | ..."
          sed -n 's/^lidar \([^ ]*\) T_base_lidar error: translation \([0-9.]*\) m, rotation \([0-9.]*\) deg.*/\1 \2 \3/p' \
            "$out/runs/$tag.txt" | while read -r lidar t r; do
            printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$preset" "$odometry" "$world" "$start" "$method" "$lidar" \
              "$t" "$r" "$seconds" "$rss_kb" >>"$results"
          done
        done
      done
    done
  done
done

python3 - "$results" "$out/runs" <<'PY' | tee "$out/table.md"
import collections, os, re, statistics, sys
rows = [line.rstrip('\n').split('\t') for line in open(sys.argv[1])][1:]

def frames_per_pair(tag, lidar):
    """Frames each (camera, lidar) pair scored: the informative choice's kept count, else the selected count."""
    log = os.path.join(sys.argv[2], tag + '.log')
    if not os.path.exists(log):
        return float('nan')
    text = open(log).read()
    kept = [int(n) for n in re.findall(r'scenes [^/ ]+/' + re.escape(lidar) + r': kept the (\d+) most informative', text)]
    if kept:
        return statistics.mean(kept)
    selected = [int(n) for n in re.findall(r'camera [^:]+: \d+ images, (\d+) selected', text)]
    return statistics.mean(selected) if selected else float('nan')

groups = collections.defaultdict(list)
for preset, odometry, world, start, method, lidar, t, r, seconds, rss in rows:
    frames = frames_per_pair(f'{preset}_{odometry}_w{world}_{start}_{method}', lidar)
    groups[(preset, odometry, lidar, method)].append((float(t) * 100, float(r), float(seconds), int(rss) / 1024, frames))
print('| preset | odometry | lidar | scenes | frames per camera | runs | median error (cm / deg) | worst (cm / deg) | median time (s) | max RSS (MB) |')
print('|---|---|---|---|---|---|---|---|---|---|')
for (preset, odometry, lidar, method), values in sorted(groups.items()):
    t = [v[0] for v in values]; r = [v[1] for v in values]
    frames = [v[4] for v in values]
    print(f'| {preset} | {odometry} | {lidar} | {method.replace("_", " ")} | {min(frames):.0f}-{max(frames):.0f} | {len(values)} | '
          f'{statistics.median(t):.2f} / {statistics.median(r):.3f} | {max(t):.2f} / {max(r):.3f} | '
          f'{statistics.median(v[2] for v in values):.1f} | {max(v[3] for v in values):.0f} |')
PY
