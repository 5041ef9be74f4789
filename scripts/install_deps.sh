#!/usr/bin/env bash
# Installs the Debian 12 packages scenecal needs to build, test and report.
# Idempotent: installs only what is missing; uses sudo when not root.
set -euo pipefail

packages=(
  build-essential cmake ninja-build ccache pkg-config
  # lld: the linker CMakeLists.txt prefers (the test executables link in half the time).
  lld
  libeigen3-dev libceres-dev libopencv-dev libyaml-cpp-dev libcli11-dev
  libspdlog-dev libfmt-dev libtbb-dev liblzf-dev zlib1g-dev
  # DGP import: JSON scenes and .npz point clouds (zip). libzip's CMake package
  # config names its command-line tools, so find_package(libzip) needs them too.
  nlohmann-json3-dev libzip-dev zipcmp zipmerge ziptool
  # Lidar odometry: Open3D's registration (19 packages; PCL would bring VTK, Qt and Boost, ~250).
  libopen3d-dev
  # Fuzzing the parsers (scripts/fuzz.sh): clang with libFuzzer and the sanitizer runtimes.
  clang libclang-rt-14-dev
  libopenmpi-dev openmpi-bin
  libgtest-dev libgmock-dev libbenchmark-dev
  # The timing scripts (scripts/bench_*.sh): /usr/bin/time -v, Python 3 with PyYAML.
  time python3 python3-yaml
)
# Headless Chromium renders the HTML report in the report test.
if [[ "${SCENECAL_WITH_BROWSER:-1}" == "1" ]]; then packages+=(chromium); fi

missing=()
for package in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$package")
  fi
done
if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install_deps: all ${#packages[@]} packages present" >&2
  exit 0
fi

sudo_cmd=()
if [[ $(id -u) -ne 0 ]]; then sudo_cmd=(sudo); fi
echo "install_deps: installing ${missing[*]}" >&2
"${sudo_cmd[@]}" apt-get update -qq
DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
