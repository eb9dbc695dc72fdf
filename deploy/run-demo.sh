#!/usr/bin/env bash
# The main job until the network service exists: builds afr and renders the built-in scene's
# 10 s animation with the ideal renderer into out/builtin/, printing per-frame statistics.
# Usage: deploy/run-demo.sh [FRAMES] [SIZE]   (defaults: 60 frames, i.e. one every 1/6 s; 256x256)
set -euo pipefail
cd "$(dirname "$0")/.."
frames=${1:-60}
size=${2:-256x256}
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build --target afr-render
fps=$(awk -v f="$frames" 'BEGIN { printf "%.6f", f / 10.0 }')
./build/bench/afr-render --frames "$frames" --fps "$fps" --size "$size" --spp 4 \
  -o out/builtin/frame_%04d.png
echo "frames written to out/builtin/"
