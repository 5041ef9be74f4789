#!/usr/bin/env bash
# Installs dependencies, builds with warnings as errors and runs the test suite: the slow and the
# integration tests in the release build, the fast tests under AddressSanitizer and
# UndefinedBehaviorSanitizer (scripts/sanitize.sh); then every parser's fuzz harness for about a
# minute in all (scripts/fuzz.sh --smoke). docs/robustness.md says what these check.
# SCENECAL_TESTS=unit builds and runs the whole suite in the release build only.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh
jobs=$(nproc 2>/dev/null || echo 2)
if [[ "${SCENECAL_TESTS:-all}" == "unit" ]]; then
  scripts/build.sh -DSCENECAL_WARNINGS_AS_ERRORS=ON -DSCENECAL_BUILD_TESTS=ON -DSCENECAL_FAST_TESTS=ON
  ctest --test-dir build --output-on-failure -j "$jobs"
  exit 0
fi
# Each test runs once: the release build runs the slow end-to-end tests and the integration tests
# (MPI, reports, the installed package), the sanitized build the fast ones (tests/CMakeLists.txt).
scripts/build.sh -DSCENECAL_WARNINGS_AS_ERRORS=ON -DSCENECAL_BUILD_TESTS=ON -DSCENECAL_FAST_TESTS=OFF
ctest --test-dir build --output-on-failure -j "$jobs"
echo "test.sh: the fast tests under AddressSanitizer and UndefinedBehaviorSanitizer" >&2
scripts/sanitize.sh
echo "test.sh: fuzz smoke of every parser" >&2
SCENECAL_FUZZ_BUILD_DIR="$PWD/build-asan" scripts/fuzz.sh --smoke
