#!/usr/bin/env bash
# Installs every Debian 12 package Reconduit needs to build, test and run.
#
# This is the one place the package list lives: the README's two commands, .ci/run and
# docker/Dockerfile all call it. It is idempotent and returns in well under a second when
# everything is already installed (it asks dpkg first and only calls apt-get for what is missing).
#
# Usage: docker/install-deps.sh [build|test|runtime]
#   build (default): runtime + compilers + -dev packages + Node.js and npm (for the web page's
#   modules); test: build + what the browser tests need (chromium).
set -euo pipefail

mode="${1:-build}"

# Shared libraries the programs load at run time.
runtime_packages=(
  ca-certificates
  libopencv-core406 libopencv-imgproc406 libopencv-imgcodecs406 libopencv-features2d406
  libopencv-calib3d406
  libceres3 libexiv2-27 libzip4 libsqlite3-0 libopenblas0-pthread
  libboost-filesystem1.74.0 libboost-program-options1.74.0 libssl3
  libgmp10 libmpfr6 libmaxflow0 libmeshoptimizer2d
)

# Toolchain, headers and test tools (clang with libFuzzer only for the fuzz targets, fuzz/).
build_packages=(
  build-essential cmake ninja-build pkg-config git clang-format ccache python3
  libeigen3-dev libopencv-dev libceres-dev libsuitesparse-dev libopenblas-dev
  libboost1.74-dev libboost-filesystem1.74-dev libboost-program-options1.74-dev
  nlohmann-json3-dev libsqlite3-dev libzip-dev libtinygltf-dev libexiv2-dev libssl-dev
  libgtest-dev libgmock-dev
  libcgal-dev libmaxflow-dev libmeshoptimizer-dev
  clang libclang-rt-14-dev
  curl zip unzip
)

# The web page's browser test (tests/web): Debian's chromium, driven from Node.js.
test_packages=(chromium)

case "$mode" in
  runtime) wanted=("${runtime_packages[@]}") ;;
  build) wanted=("${runtime_packages[@]}" "${build_packages[@]}") ;;
  test) wanted=("${runtime_packages[@]}" "${build_packages[@]}" "${test_packages[@]}") ;;
  *) echo "usage: $0 [build|test|runtime]" >&2; exit 2 ;;
esac
# Node.js and npm to build and test: npm installs the web page's modules (three.js,
# scripts/web_deps.sh) and the browser tests' packages. Debian's, unless a node with npm is
# already installed some other way (a second one would conflict with it).
if [ "$mode" != runtime ]; then
  if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
    wanted+=(nodejs npm)
  fi
fi

missing=()
for p in "${wanted[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ "${#missing[@]}" -eq 0 ]; then
  echo "install-deps: all ${#wanted[@]} packages present"
  exit 0
fi

sudo=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then sudo="sudo"; else
    echo "install-deps: missing packages (${missing[*]}) and not root; run as root or install sudo" >&2
    exit 1
  fi
fi

echo "install-deps: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"
