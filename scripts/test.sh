#!/usr/bin/env bash
# Installs dependencies, builds with warnings as errors and runs the test suite; then the fast tests
# again under AddressSanitizer and UndefinedBehaviorSanitizer (scripts/sanitize.sh) and every
# parser's fuzz harness for about a minute in all (scripts/fuzz.sh --smoke). docs/robustness.md
# says what these check. SCENECAL_TESTS=unit runs the first part only.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh
scripts/build.sh -DSCENECAL_WARNINGS_AS_ERRORS=ON -DSCENECAL_BUILD_TESTS=ON
jobs=$(nproc 2>/dev/null || echo 2)
ctest --test-dir build --output-on-failure -j "$jobs"
if [[ "${SCENECAL_TESTS:-all}" == "unit" ]]; then exit 0; fi
echo "test.sh: the fast tests under AddressSanitizer and UndefinedBehaviorSanitizer" >&2
scripts/sanitize.sh
echo "test.sh: fuzz smoke of every parser" >&2
SCENECAL_FUZZ_BUILD_DIR="$PWD/build-asan" scripts/fuzz.sh --smoke
