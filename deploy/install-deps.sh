#!/usr/bin/env bash
# Installs every Debian 12 package afr needs to build, test and run. Idempotent: packages
# already present are left alone. Run as root (or through sudo).
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake ninja-build pkg-config git clang-format
  # sanitizer and fuzzing builds (clang with its ASan/UBSan/TSan and libFuzzer runtimes)
  clang libclang-rt-dev
  # deploy/soak.py and the scene generators
  python3 curl
  # rendering
  libembree-dev libglm-dev libtinygltf-dev nlohmann-json3-dev libopenimageio-dev openimageio-tools
  libwebp-dev libdraco-dev libmeshoptimizer-dev
  # tests: meshoptimizer's own glTF packer, to check afr reads what it writes
  gltfpack
  # display
  libglfw3-dev libegl-dev libepoxy-dev libgl1-mesa-dri xvfb xauth libstb-dev
  # the dashboard's browser test; promtool for deploy/monitoring's check
  chromium prometheus
  # messaging
  libzmq3-dev cppzmq-dev libsodium-dev libcpp-httplib-dev prometheus-cpp-dev iproute2 nftables
  # flags, logging
  libcli11-dev libspdlog-dev libfmt-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev gnuplot-nox
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO=sudo
echo "install-deps: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
