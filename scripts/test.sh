#!/usr/bin/env bash
# Installs dependencies, builds with warnings as errors and runs the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh
scripts/build.sh -DSCENECAL_WARNINGS_AS_ERRORS=ON -DSCENECAL_BUILD_TESTS=ON
jobs=$(nproc 2>/dev/null || echo 2)
ctest --test-dir build --output-on-failure -j "$jobs"
