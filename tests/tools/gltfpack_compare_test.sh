#!/usr/bin/env bash
# tools/gltfpack_compare.sh on the Khronos files of tests/data: what Debian's gltfpack writes
# compressed (EXT_meshopt_compression) renders exactly as what it writes quantized only, and
# compressed harder with lossy filters and instancing within RMS 0.01. Arguments: the build
# folder, the source folder. Skipped (77) where gltfpack is not installed.
set -euo pipefail
BUILD=$1
SRC=$2
command -v gltfpack > /dev/null || { echo "no gltfpack: skipped"; exit 77; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp "$SRC"/tests/data/khronos/*.gltf "$work/"
out=$("$SRC"/tools/gltfpack_compare.sh --build "$BUILD" --size 48x48 "$work")
echo "$out"
rows=$(grep -c '\.gltf |' <<<"$out")
[ "$rows" -eq "$(ls "$work"/*.gltf | wc -l)" ]
# Every file packed (no "(gltfpack: ..." cell), its -c render equal, its -cc -mi one close.
! grep -q '(gltfpack:' <<<"$out"
[ "$(grep -c '\.gltf | 0 (equal) |' <<<"$out")" -eq "$rows" ]
awk -F'|' '/\.gltf \|/ { v = $4; sub(/ \(equal\)/, "", v); if (v + 0 > 0.01) exit 1 }' <<<"$out"
