#!/usr/bin/env bash
# `scenecal calibrate --scheme alt --backend mpi` on 3 ranks writes the same
# calibration as the thread backend, and ranks that read different inputs stop
# with an error naming them instead of hanging.
#   cli_mpi_check.sh SCENECAL MPIEXEC
set -euo pipefail
scenecal=$1
mpiexec=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mpi=("$mpiexec" --oversubscribe --allow-run-as-root)

"$scenecal" -q simulate --preset robotcar --seed 5 --distance 90 --image-size 320x240 --no-shadows --output "$work/a" >/dev/null
"$scenecal" -q simulate --preset robotcar --seed 6 --distance 90 --image-size 320x240 --no-shadows --output "$work/b" >/dev/null
args=(--scheme alt --scenes 4 --alternations 3 --max-iterations 40 --min-points 50)

"$scenecal" -q calibrate "$work/a" --output "$work/threads.yaml" "${args[@]}" >/dev/null
timeout 300 "${mpi[@]}" -np 3 "$scenecal" -q calibrate "$work/a" --output "$work/mpi.yaml" "${args[@]}" --backend mpi >/dev/null
# Everything before the timings must match: transforms, costs, termination, settings but the backend.
strip() { sed -n '/^timings_s:/q;p' "$1" | grep -v 'backend:'; }
# The per-alternation history block alone (the options block after it records the backend), without times.
history_block() { awk '/^history:/ { inside = 1; print; next } inside && /^[^ -]/ { exit } inside' "$1" | grep -v elapsed_s; }
if ! diff <(strip "$work/threads.yaml") <(strip "$work/mpi.yaml"); then
  echo "FAIL: the MPI result differs from the thread result" >&2
  exit 1
fi
grep -q 'backend: "mpi, 3 ranks"' "$work/mpi.yaml" || { echo "FAIL: the result does not record the MPI backend" >&2; exit 1; }
# The per-alternation history of both runs holds the same solutions.
[[ -n "$(history_block "$work/threads.yaml")" ]] || { echo "FAIL: no history in the thread result" >&2; exit 1; }
diff <(history_block "$work/threads.yaml") <(history_block "$work/mpi.yaml") >/dev/null ||
  { echo "FAIL: the histories differ" >&2; exit 1; }

# The same with the L-BFGS lower level (its options travel with the tasks).
"$scenecal" -q calibrate "$work/a" --output "$work/threads_lbfgs.yaml" "${args[@]}" --lower-solver lbfgs >/dev/null
timeout 300 "${mpi[@]}" -np 3 "$scenecal" -q calibrate "$work/a" --output "$work/mpi_lbfgs.yaml" "${args[@]}" \
  --lower-solver lbfgs --backend mpi >/dev/null
if ! diff <(strip "$work/threads_lbfgs.yaml") <(strip "$work/mpi_lbfgs.yaml"); then
  echo "FAIL: the MPI result differs from the thread result with --lower-solver lbfgs" >&2
  exit 1
fi
grep -q 'lower_solver: "\?lbfgs' "$work/mpi_lbfgs.yaml" || { echo "FAIL: the result does not record the lbfgs solver" >&2; exit 1; }
diff <(history_block "$work/threads_lbfgs.yaml") <(history_block "$work/mpi_lbfgs.yaml") >/dev/null ||
  { echo "FAIL: the lbfgs histories differ" >&2; exit 1; }

# The same with the swathes' drift correction: every rank estimates the frames'
# shared corrections from the broadcast upper estimates, so they must agree.
"$scenecal" -q calibrate "$work/a" --output "$work/threads_motion.yaml" "${args[@]}" \
  --motion-correction turn --motion-correction-from-stage 0 >/dev/null
timeout 300 "${mpi[@]}" -np 3 "$scenecal" -q calibrate "$work/a" --output "$work/mpi_motion.yaml" "${args[@]}" \
  --motion-correction turn --motion-correction-from-stage 0 --backend mpi >/dev/null
if ! diff <(strip "$work/threads_motion.yaml") <(strip "$work/mpi_motion.yaml"); then
  echo "FAIL: the MPI result differs from the thread result with --motion-correction" >&2
  exit 1
fi
grep -q 'turn_a_deg_per_m' "$work/mpi_motion.yaml" || { echo "FAIL: no frame's drift correction in the MPI result" >&2; exit 1; }
diff <(sed -n '/^motion_correction:/,/^[a-z]/p' "$work/threads_motion.yaml") \
     <(sed -n '/^motion_correction:/,/^[a-z]/p' "$work/mpi_motion.yaml") >/dev/null ||
  { echo "FAIL: the frames' drift corrections differ" >&2; exit 1; }

# Rank 0 reads dataset a, ranks 1-2 read dataset b: a clear error, no hang, no result.
set +e
timeout 300 "${mpi[@]}" -np 1 "$scenecal" -q calibrate "$work/a" --output "$work/mixed.yaml" "${args[@]}" --backend mpi : \
  -np 2 "$scenecal" -q calibrate "$work/b" --output "$work/mixed.yaml" "${args[@]}" --backend mpi >"$work/mixed.log" 2>&1
status=$?
set -e
if [[ $status -eq 0 || $status -eq 124 ]]; then
  echo "FAIL: mismatched ranks exited with status $status (0 = accepted, 124 = hang)" >&2
  cat "$work/mixed.log" >&2
  exit 1
fi
grep -q "differ from rank 0" "$work/mixed.log" || { echo "FAIL: no message naming the differing ranks" >&2; cat "$work/mixed.log" >&2; exit 1; }
[[ ! -e "$work/mixed.yaml" ]] || { echo "FAIL: a result was written despite the mismatch" >&2; exit 1; }
echo "5 passed, 0 failed"
