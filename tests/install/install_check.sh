#!/usr/bin/env bash
# install_check.sh BUILD_DIR EXAMPLES_SOURCE_DIR WORK_DIR
# Installs the scenecal build BUILD_DIR into WORK_DIR/prefix, builds the examples as an outside project against
# it (find_package(scenecal CONFIG)), simulates a small drive with the installed command and runs both examples
# on it; fails unless each exits 0 and prints finite numbers. The compiler, its launcher (ccache) and the CMake
# generator come from the environment (tests/install/CMakeLists.txt passes the build's own).
set -euo pipefail
build=$1
examples=$2
work=$3
rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix

# The installed targets are up to date (nothing to do after a full build).
cmake --build "$build" --target scenecal >"$work/build.log"
cmake --install "$build" --prefix "$prefix" >"$work/install.log"
for file in bin/scenecal bin/libscenecal_odometry.so include/scenecal/core/calibrate.hpp \
    include/scenecal/io/dataset.hpp lib/cmake/scenecal/scenecalConfig.cmake; do
  [[ -e "$prefix/$file" ]] || { echo "install_check: $prefix/$file is missing after cmake --install" >&2; exit 1; }
done

# An outside project: only the prefix tells it where scenecal is.
cmake -S "$examples" -B "$work/examples" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" >"$work/examples.log"
cmake --build "$work/examples" -j 2 >>"$work/examples.log"

"$prefix/bin/scenecal" simulate --preset robotcar --seed 3 --distance 60 --image-size 320x240 \
  --output "$work/dataset" 2>"$work/simulate.log"

# Fails when the output has no line matching `expected` (an extended regex) or holds a non-finite number.
check_output() {
  local name=$1 expected=$2 output=$3
  if ! grep -Eq "$expected" "$output" || grep -Eiq '(^|[^a-z])-?(nan|inf)([^a-z]|$)' "$output"; then
    echo "install_check: $name printed no line matching '$expected', or a non-finite number:" >&2
    cat "$output" >&2
    exit 1
  fi
  cat "$output"
}
number='-?[0-9]+\.[0-9]+'
"$work/examples/example_evaluate_cost" "$work/dataset" >"$work/evaluate_cost.out"
check_output example_evaluate_cost "^ground truth +cost $number$" "$work/evaluate_cost.out"
"$work/examples/example_calibrate_dataset" "$work/dataset" "$work/calibration.yaml" \
  >"$work/calibrate_dataset.out" 2>"$work/calibrate_dataset.log"
check_output example_calibrate_dataset \
  "^lidar lms_rear T_base_lidar: x $number y $number z $number m, roll $number pitch $number yaw $number deg$" \
  "$work/calibrate_dataset.out"
[[ -s "$work/calibration.yaml" ]] || { echo "install_check: no $work/calibration.yaml" >&2; exit 1; }
