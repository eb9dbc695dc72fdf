#!/usr/bin/env bash
# Builds afr (Release) into build/ and runs every test, the format check included. Without a
# display server the tests run under xvfb-run, so the window test runs too.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build
run=()
if [ -z "${DISPLAY:-}" ] && command -v xvfb-run >/dev/null; then
  run=(xvfb-run -a)
fi
"${run[@]}" ctest --test-dir build --output-on-failure -j "$(nproc)"
