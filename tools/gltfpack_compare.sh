#!/usr/bin/env bash
# Checks afr's reading of what meshoptimizer's own tool writes: every .gltf and .glb under DIR
# is packed by gltfpack three ways (quantized only; compressed with EXT_meshopt_compression, -c;
# compressed harder with EXT_mesh_gpu_instancing, -cc -mi), each is rendered by afr-render, and
# the two compressed renders are compared with the quantized one (RMS over the image, 0-1).
# Compression keeps the quantized data exactly, up to the order of a triangle's corners, so the
# compressed renders should equal the quantized one wherever no two surfaces tie.
#
#   tools/gltfpack_compare.sh [--build build] [--size 96x96] DIR
#
# Needs gltfpack (Debian's `gltfpack` package, not a build dependency) and idiff
# (openimageio-tools). Prints one row per file; exits 1 when a packed file fails to render.
set -euo pipefail
BUILD=build
SIZE=96x96
while [ $# -gt 0 ]; do
  case $1 in
    --build) BUILD=$2; shift 2 ;;
    --size) SIZE=$2; shift 2 ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    *) break ;;
  esac
done
[ $# -eq 1 ] || { echo "usage: $0 [--build DIR] [--size WxH] DIR" >&2; exit 2; }
DIR=$1
RENDER=$BUILD/bench/afr-render
[ -x "$RENDER" ] || { echo "$0: no $RENDER (build it first)" >&2; exit 2; }
command -v gltfpack > /dev/null || { echo "$0: no gltfpack (apt-get install gltfpack)" >&2; exit 2; }
command -v idiff > /dev/null || { echo "$0: no idiff (apt-get install openimageio-tools)" >&2; exit 2; }
[ -d "$DIR" ] || { echo "$0: no folder $DIR" >&2; exit 2; }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failed=0
# RMS of image $2 against image $1, as idiff reports it (it reports none for equal images).
rms() {
  local r
  r=$(idiff -a "$1" "$2" 2>&1 | awk '/RMS error/ {print $4}')
  echo "${r:-0 (equal)}"
}

echo "| file | -c: RMS against quantized | -cc -mi: RMS against quantized |"
echo "|---|---:|---:|"
while IFS= read -r -d '' file; do
  name=$(basename "$file")
  cells=()
  ok=1
  for variant in q c cmi; do
    case $variant in
      q) flags=() ;;
      c) flags=(-c) ;;
      cmi) flags=(-cc -mi) ;;
    esac
    if ! gltfpack -i "$file" -o "$work/$variant.glb" "${flags[@]}" > "$work/pack.log" 2>&1; then
      ok=0  # gltfpack itself refused the file: nothing of afr's to check
      break
    fi
    if ! "$RENDER" "$work/$variant.glb" --size "$SIZE" --spp 4 -o "$work/$variant.png" \
         --log error > "$work/render.log" 2>&1; then
      cells+=("render failed: $(tail -n 1 "$work/render.log" | cut -c1-120)")
      failed=1
      ok=2
      break
    fi
  done
  if [ $ok -eq 0 ]; then
    echo "| $name | (gltfpack: $(tail -n 1 "$work/pack.log" | cut -c1-80)) | |"
  elif [ $ok -eq 2 ]; then
    echo "| $name | ${cells[0]} | |"
  else
    echo "| $name | $(rms "$work/q.png" "$work/c.png") | $(rms "$work/q.png" "$work/cmi.png") |"
  fi
done < <(find "$DIR" -type f \( -name '*.gltf' -o -name '*.glb' \) -print0 | sort -z)
exit $failed
