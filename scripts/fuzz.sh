#!/usr/bin/env bash
# Fuzzes every input parser with libFuzzer (the harnesses are fuzz/fuzz_*.cpp).
#
#   scripts/fuzz.sh [SECONDS] [HARNESS...]    each harness for SECONDS (default 60)
#   scripts/fuzz.sh --smoke [HARNESS...]      CI: all harnesses together ~1 minute
#   scripts/fuzz.sh --runs N [HARNESS...]     each harness for N executions
#   scripts/fuzz.sh --runs N --segment M ...  the same in runs of at most M executions, each resuming from
#                                             the corpus the last one left (libFuzzer's RSS grows over
#                                             millions of executions: ~1 GB per 2.5 M on the YAML harnesses)
#
# Configures and builds build-fuzz (clang, ASan + UBSan; SCENECAL_FUZZ_BUILD_DIR
# overrides it), then runs each harness on a COPY of fuzz/corpus/<harness>/ (the
# committed corpus never grows from a run). Prints per harness the executions
# and exec/s. Exits 1 on any crash, sanitizer report, leak, timeout (10 s per
# input) or out-of-memory (2 GB RSS, 1 GB in one allocation); the inputs that
# caused them are kept in <build dir>/fuzz-findings/<harness>/.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${SCENECAL_FUZZ_BUILD_DIR:-$ROOT/build-fuzz}"
SECONDS_PER_HARNESS=60
RUNS=""
SEGMENT=""
SMOKE=0
HARNESSES=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --smoke) SMOKE=1 ;;
    --runs) RUNS="$2"; shift ;;
    --segment) SEGMENT="$2"; shift ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    [0-9]*) SECONDS_PER_HARNESS="$1" ;;
    fuzz_*) HARNESSES+=("$1") ;;
    *) echo "fuzz.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
  shift
done

CXX_COMPILER="$(command -v clang++-14 || command -v clang++ || true)"
if [[ -z "$CXX_COMPILER" ]]; then
  echo "fuzz.sh: clang++ not found (libFuzzer needs clang; scripts/install_deps.sh installs it)" >&2
  exit 1
fi
if [[ ! -f "$BUILD_DIR/CMakeCache.txt" ]]; then
  cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_CXX_COMPILER="$CXX_COMPILER" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
    -DSCENECAL_BUILD_FUZZERS=ON -DSCENECAL_BUILD_TESTS=OFF -DSCENECAL_WARNINGS_AS_ERRORS=ON >/dev/null
fi
cmake --build "$BUILD_DIR" -j"${SCENECAL_BUILD_JOBS:-2}" --target fuzzers >/dev/null

if [[ -n "$SEGMENT" && -z "$RUNS" ]]; then
  echo "fuzz.sh: --segment needs --runs" >&2
  exit 2
fi
if [[ ${#HARNESSES[@]} -eq 0 ]]; then
  for source in "$ROOT"/fuzz/fuzz_*.cpp; do HARNESSES+=("$(basename "$source" .cpp)"); done
fi
if [[ $SMOKE -eq 1 ]]; then
  # About one minute of fuzzing in all, split evenly (at least 2 s each).
  SECONDS_PER_HARNESS=$(( 60 / ${#HARNESSES[@]} ))
  (( SECONDS_PER_HARNESS >= 2 )) || SECONDS_PER_HARNESS=2
fi

dictionary_for() {
  case "$1" in
    fuzz_rig|fuzz_ground_truth|fuzz_calibration_result|fuzz_option_file) echo "$ROOT/fuzz/dict/yaml.dict" ;;
    fuzz_pcd) echo "$ROOT/fuzz/dict/pcd.dict" ;;
    fuzz_kitti_*|fuzz_opencalib) echo "$ROOT/fuzz/dict/kitti.dict" ;;
  esac
}

WORK="$(mktemp -d "${TMPDIR:-/tmp}/scenecal-fuzz.XXXXXX")"
trap 'rm -rf "$WORK"' EXIT
FAILED=()
printf '%-26s %12s %10s  %s\n' harness executions exec/s result
for harness in "${HARNESSES[@]}"; do
  binary="$BUILD_DIR/bin/$harness"
  [[ -x "$binary" ]] || { echo "fuzz.sh: no harness $binary" >&2; exit 2; }
  corpus="$WORK/$harness/corpus"
  artifacts="$BUILD_DIR/fuzz-findings/$harness"
  mkdir -p "$corpus" "$artifacts"
  cp "$ROOT/fuzz/corpus/$harness/"* "$corpus/"
  options=(-timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=1024 -print_final_stats=1
           -artifact_prefix="$artifacts/")
  dictionary="$(dictionary_for "$harness")"
  [[ -n "$dictionary" ]] && options+=(-dict="$dictionary")
  log="$WORK/$harness/log"
  status=0
  if [[ -z "$RUNS" ]]; then
    "$binary" "${options[@]}" -max_total_time="$SECONDS_PER_HARNESS" "$corpus" >"$log" 2>&1 || status=$?
    executions="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)"
    rate="$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)"
  else
    # One run, or segments that resume from the corpus until RUNS executions in all.
    executions=0
    started=$(date +%s)
    while (( executions < RUNS )); do
      segment_runs=$(( RUNS - executions ))
      if [[ -n "$SEGMENT" ]] && (( segment_runs > SEGMENT )); then segment_runs=$SEGMENT; fi
      "$binary" "${options[@]}" -runs="$segment_runs" "$corpus" >"$log" 2>&1 || status=$?
      done_now="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)"
      executions=$(( executions + ${done_now:-0} ))
      if [[ -z "$SEGMENT" || $status -ne 0 || ${done_now:-0} -eq 0 ]]; then break; fi
      echo "fuzz.sh: $harness: $executions of $RUNS executions" >&2
    done
    rate=$(( executions / ( $(date +%s) - started + 1 ) ))
  fi
  if [[ $status -eq 0 ]]; then
    result=ok
  else
    result="FAILED (exit $status): $(grep -m1 -E 'ERROR|runtime error|fuzz check failed|terminate called|out-of-memory|Test unit written' "$log" || true)"
    cp "$log" "$artifacts/log.txt"
    FAILED+=("$harness")
  fi
  printf '%-26s %12s %10s  %s\n' "$harness" "${executions:-?}" "${rate:-?}" "$result"
done
if [[ ${#FAILED[@]} -gt 0 ]]; then
  echo "fuzz.sh: ${#FAILED[@]} harness(es) failed: ${FAILED[*]}; inputs and logs in $BUILD_DIR/fuzz-findings/" >&2
  exit 1
fi
