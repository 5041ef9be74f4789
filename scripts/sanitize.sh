#!/usr/bin/env bash
# Builds the scenecal command and the fast unit tests with AddressSanitizer (LeakSanitizer included)
# and UndefinedBehaviorSanitizer into ./build-asan (clang, -O1 -g) and runs those tests under them.
# Any finding fails the run, also one in a scenecal process a test starts. The slow end-to-end
# test executables (label `slow`, listed with their reasons in tests/CMakeLists.txt) are left out.
# The same folder builds the parsers' fuzz harnesses (scripts/test.sh runs their smoke from it), so
# CI configures and builds one folder for both. Extra arguments go to cmake.
set -euo pipefail
cd "$(dirname "$0")/.."
build=build-asan
jobs=$(nproc 2>/dev/null || echo 2)
compiler="$(command -v clang++-14 || command -v clang++ || true)"
if [[ -z "$compiler" ]]; then
  echo "sanitize.sh: clang++ not found (scripts/install_deps.sh installs it)" >&2
  exit 1
fi
# A folder configured with another compiler (CMake keeps the first) is made again.
if [[ -f "$build/CMakeCache.txt" ]] && ! grep -q "^CMAKE_CXX_COMPILER:[A-Z]*=$compiler\$" "$build/CMakeCache.txt"; then
  echo "sanitize.sh: $build was configured with another compiler; configuring it again with $compiler" >&2
  rm -rf "$build"
fi
# -O1 -g: fast enough under ASan (its documentation's advice) with exact lines in the reports;
# NDEBUG as in the release build. Clang compiles the sanitized code in three quarters of GCC's time.
generator=()
if [[ ! -f "$build/CMakeCache.txt" ]] && command -v ninja >/dev/null; then generator=(-G Ninja); fi
cmake -S . -B "$build" "${generator[@]}" -DCMAKE_CXX_COMPILER="$compiler" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DSCENECAL_SANITIZE=ON -DSCENECAL_BUILD_FUZZERS=ON \
  -DSCENECAL_WARNINGS_AS_ERRORS=ON -DSCENECAL_BUILD_TESTS=ON "$@" >/dev/null
# scenecal_fast_tests: the scenecal command and every test executable not labelled slow.
cmake --build "$build" -j "$jobs" --target scenecal_fast_tests fuzzers

# Reports go to files, printed at the end, so that a finding in a scenecal process whose output a
# test discards (or whose non-zero exit it expects) is not lost.
logs="$PWD/$build/sanitizer-logs"
rm -rf "$logs"
mkdir -p "$logs"
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:check_initialization_order=1:strict_init_order=1:log_path=$logs/asan"
export LSAN_OPTIONS="suppressions=$PWD/tests/sanitizer/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:log_path=$logs/ubsan"
status=0
ctest --test-dir "$build" --output-on-failure -j "$jobs" -L fast || status=$?
if compgen -G "$logs/*" >/dev/null; then
  echo "sanitizer reports (in $logs):" >&2
  cat "$logs"/* >&2
  status=1
fi
exit "$status"
