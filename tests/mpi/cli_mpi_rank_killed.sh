#!/usr/bin/env bash
# A rank of `scenecal calibrate --backend mpi` killed mid-run (kill -9) ends
# every rank within 10 s, with a non-zero exit, a message naming the rank and
# no result file; no rank is left waiting for the dead one.
#   cli_mpi_rank_killed.sh SCENECAL MPIEXEC
set -euo pipefail
scenecal=$1
mpiexec=$2
work=$(mktemp -d)
mpirun_pid=
cleanup() {
  [[ -n "$mpirun_pid" ]] && kill -9 "$mpirun_pid" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT

"$scenecal" -q simulate --preset robotcar --seed 5 --distance 90 --image-size 320x240 --no-shadows --output "$work/a" >/dev/null

# The ranks are mpirun's children (one node); each carries its rank in its environment.
rank_pids() {
  local pid
  for pid in $(pgrep -P "$mpirun_pid"); do
    if tr '\0' '\n' <"/proc/$pid/environ" 2>/dev/null | grep -q '^OMPI_COMM_WORLD_RANK='; then echo "$pid"; fi
  done
}
rank_of() { tr '\0' '\n' <"/proc/$1/environ" | sed -n 's/^OMPI_COMM_WORLD_RANK=//p'; }

# kill_rank RANK: runs a 20-alternation calibration on 3 ranks and kill -9s RANK once the alternations run.
kill_rank() {
  local victim_rank=$1 log="$work/rank$1.log" output="$work/rank$1.yaml"
  "$mpiexec" --oversubscribe --allow-run-as-root -np 3 "$scenecal" calibrate "$work/a" --output "$output" \
    --scheme alt --scenes 6 --alternations 20 --backend mpi >"$log" 2>&1 &
  mpirun_pid=$!
  local waited=0
  until grep -qs "alternation 2:" "$log"; do
    if ! kill -0 "$mpirun_pid" 2>/dev/null; then echo "FAIL: the run ended before its second alternation" >&2; cat "$log" >&2; exit 1; fi
    ((waited += 1)) && ((waited < 1200)) || { echo "FAIL: no second alternation within 120 s" >&2; exit 1; }
    sleep 0.1
  done
  local ranks victim= pid
  ranks=$(rank_pids)
  for pid in $ranks; do [[ "$(rank_of "$pid")" == "$victim_rank" ]] && victim=$pid; done
  [[ -n "$victim" ]] || { echo "FAIL: no process of rank $victim_rank among mpirun's children ($ranks)" >&2; exit 1; }
  local start_ns
  start_ns=$(date +%s%N)
  kill -9 "$victim"
  # Every rank and mpirun gone within 10 s.
  local deadline=$((SECONDS + 10))
  while ((SECONDS <= deadline)); do
    local alive=0
    for pid in $ranks "$mpirun_pid"; do kill -0 "$pid" 2>/dev/null && alive=1; done
    ((alive == 0)) && break
    sleep 0.1
  done
  for pid in $ranks "$mpirun_pid"; do
    if kill -0 "$pid" 2>/dev/null; then
      echo "FAIL: process $pid still runs 10 s after rank $victim_rank was killed" >&2
      cat "$log" >&2
      exit 1
    fi
  done
  local status=0
  wait "$mpirun_pid" || status=$?
  mpirun_pid=
  echo "rank $victim_rank killed: every rank ended within $((($(date +%s%N) - start_ns) / 1000000)) ms, exit $status"
  grep -E "rank $victim_rank( |,)" "$log" | head -3
  if ((status == 0)); then echo "FAIL: exit 0 although rank $victim_rank was killed" >&2; cat "$log" >&2; exit 1; fi
  # OpenMPI's mpirun names the rank ("process rank 1 with PID ... exited on signal 9 (Killed)").
  grep -Eq "rank $victim_rank( |,).*(signal 9|Killed)" "$log" ||
    { echo "FAIL: no message naming rank $victim_rank" >&2; cat "$log" >&2; exit 1; }
  [[ ! -e "$output" ]] || { echo "FAIL: a result was written although rank $victim_rank was killed" >&2; exit 1; }
  if ls -A "$work" | grep -q '^\.'; then echo "FAIL: temporary files left in $work" >&2; ls -A "$work" >&2; exit 1; fi
}

kill_rank 1  # a serving rank: rank 0 must not wait for its share forever
kill_rank 0  # rank 0: the serving ranks must not wait for the next batch forever
echo "2 passed, 0 failed"
