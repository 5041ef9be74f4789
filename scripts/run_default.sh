#!/usr/bin/env bash
# The main job on the built-in default: install what is missing, build,
# simulate the default RobotCar-like drive, inspect it and calibrate it,
# printing the error against the simulator's ground truth.
# Outputs go to ./out (override with OUT=DIR).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${OUT:-out}
SCENECAL_WITH_BROWSER=0 scripts/install_deps.sh
scripts/build.sh
scenecal=build/bin/scenecal
mkdir -p "$out"
if [[ ! -f "$out/robotcar/rig.yaml" ]]; then
  "$scenecal" simulate --preset robotcar --seed 1 --output "$out/robotcar"
fi
"$scenecal" inspect "$out/robotcar"
"$scenecal" calibrate "$out/robotcar" --output "$out/robotcar_calibration.yaml"
echo "result written to $out/robotcar_calibration.yaml" >&2
