#!/usr/bin/env bash
# End-to-end timing of `scenecal calibrate` on the default simulated RobotCar
# dataset: wall time and peak RSS (/usr/bin/time -v) per scheme, with the
# scenes, points per evaluation and evaluations the calibrate log reports.
#
#   scripts/bench_end_to_end.sh [DATASET] [OUT_DIR]
#
# DATASET defaults to /tmp/rc (simulated first when missing:
# scenecal simulate --preset robotcar --seed 1 --output DATASET). SCHEMES
# (default "joint alt"), SCENECAL (default build/bin/scenecal) and
# CALIBRATE_ARGS (extra options, e.g. "--binning bspline --threads 1") can be
# set. Prints a Markdown table; logs stay in OUT_DIR.
set -euo pipefail
cd "$(dirname "$0")/.."
dataset=${1:-/tmp/rc}
out=${2:-/tmp/scenecal_bench_end_to_end}
scenecal=${SCENECAL:-build/bin/scenecal}
schemes=${SCHEMES:-"joint alt"}
extra=${CALIBRATE_ARGS:-}

[[ -x "$scenecal" ]] || { echo "bench_end_to_end: $scenecal not built (scripts/build.sh)" >&2; exit 2; }
[[ -x /usr/bin/time ]] || { echo "bench_end_to_end: /usr/bin/time missing (apt-get install time)" >&2; exit 2; }
if [[ ! -f "$dataset/rig.yaml" ]]; then
  echo "bench_end_to_end: simulating $dataset" >&2
  "$scenecal" simulate --preset robotcar --seed 1 --output "$dataset" >&2
fi
mkdir -p "$out"
echo "| scheme | options | scenes (used/selected) | points per evaluation | evaluations | wall s | user s | peak RSS MB | exit |"
echo "|---|---|---|---|---|---|---|---|---|"
for scheme in $schemes; do
  log="$out/$scheme.log"
  status=0
  # shellcheck disable=SC2086
  /usr/bin/time -v "$scenecal" calibrate "$dataset" --scheme "$scheme" --output "$out/$scheme.yaml" $extra \
    >"$log" 2>&1 || status=$?
  wall=$(awk -F': ' '/Elapsed \(wall clock\)/{n=split($2,a,":"); s=0; for(i=1;i<=n;i++) s=s*60+a[i]; printf "%.1f", s}' "$log")
  user=$(awk -F': ' '/User time \(seconds\)/{print $2}' "$log")
  rss=$(awk -F': ' '/Maximum resident set size/{printf "%.0f", $2/1024}' "$log")
  # The calibrate log's own figures (spdlog lines); "?" when it does not print them.
  scenes=$(grep -oE '[0-9]+ of [0-9]+ scenes used' "$log" | awk '{u+=$1; t+=$3} END{if(NR) print u "/" t}' || true)
  # Projected points per evaluation: the per-scene ranges of every pair (min..max per scene).
  points=$(grep -oE '[0-9]+\.\.[0-9]+ projected points per scene' "$log" | head -2 | tr '\n' ';' || true)
  evaluations=$(grep -oE '[0-9]+ (cost )?evaluations' "$log" | tail -1 | awk '{print $1}' || true)
  echo "| $scheme | ${extra:-default} | ${scenes:-?} | ${points:-?} | ${evaluations:-?} | $wall | $user | $rss | $status |"
done
