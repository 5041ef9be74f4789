#!/usr/bin/env bash
# A/B timing of cost-kernel benchmarks of two bench_cost binaries on the same
# machine state: the runs are interleaved (A, B, A, B, ...) ROUNDS times and the
# minimum over the rounds is kept per benchmark (the machine may be shared: the
# minimum is the least disturbed run). Prints a Markdown table of points per
# second from CPU time and from wall time.
#
#   benchmarks/ab_kernel.sh BENCH_A BENCH_B [FILTER] [ROUNDS]
#
# FILTER is a --benchmark_filter regex (default: the 1-thread hard NID cases of
# BM_Evaluate and BM_HardKernel); ROUNDS defaults to 5.
set -euo pipefail
a=$1
b=$2
filter=${3:-'BM_Evaluate/bspline:0/threads:1/|BM_HardKernel/threads:1/'}
rounds=${4:-5}
out=$(mktemp -d)
for ((r = 0; r < rounds; ++r)); do
  for side in A B; do
    bin=$a
    [[ $side == B ]] && bin=$b
    "$bin" --benchmark_filter="$filter" --benchmark_min_time=0.5 --benchmark_format=csv 2>/dev/null |
      awk -F, -v side="$side" '/^"BM_/{print side "," $0}' >>"$out/runs.csv"
  done
done
echo "load average before/after: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "| binary | benchmark | points | min CPU ms | M points/s (CPU) | min wall ms | M points/s (wall) |"
echo "|---|---|---|---|---|---|---|"
# csv columns: side,name,iterations,real_time,cpu_time,time_unit,bytes_per_second,items_per_second,label,...,points
awk -F, '{
  key = $1 "," $2; gsub(/"/, "", key)
  if (!(key in cpu) || $5 < cpu[key]) cpu[key] = $5
  if (!(key in real) || $4 < real[key]) real[key] = $4
  items[key] = $8 * $4 / 1000.0  # items/s x wall time per iteration (UseRealTime) = points per evaluation
} END {
  for (k in cpu) {
    split(k, parts, ",")
    printf "| %s | %s | %.0f | %.2f | %.1f | %.2f | %.1f |\n", parts[1], parts[2], items[k], cpu[k], items[k] / cpu[k] / 1000.0, real[k], items[k] / real[k] / 1000.0
  }
}' "$out/runs.csv" | sort -t'|' -k3,3 -k2,2
rm -rf "$out"
