#!/usr/bin/env bash
# Loads and renders every .gltf and .glb under a folder with afr-render (16 x 16, 1 sample per
# pixel) and sorts the outcomes: rendered, refused with a named error (exit 1), or anything
# else (a crash, a hang past the timeout, an error without a message), which is a defect. For
# corpora of files nobody here wrote, such as the glTF-Validator's test files (most of them
# broken on purpose):
#
#   tools/gltf_corpus.sh [--build build] [--timeout 20] [--list] DIR
#
# Prints one line per outcome with its count, then every defect; --list also prints each
# file's outcome and the last line afr-render wrote. Exits 1 when there is a defect.
set -euo pipefail
BUILD=build
TIMEOUT=20
LIST=0
while [ $# -gt 0 ]; do
  case $1 in
    --build) BUILD=$2; shift 2 ;;
    --timeout) TIMEOUT=$2; shift 2 ;;
    --list) LIST=1; shift ;;
    -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
    *) break ;;
  esac
done
[ $# -eq 1 ] || { echo "usage: $0 [--build DIR] [--timeout S] [--list] DIR" >&2; exit 2; }
DIR=$1
RENDER=$BUILD/bench/afr-render
[ -x "$RENDER" ] || { echo "$0: no $RENDER (build it first)" >&2; exit 2; }
[ -d "$DIR" ] || { echo "$0: no folder $DIR" >&2; exit 2; }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
rendered=0 refused=0 defects=0
defect_lines=()
while IFS= read -r -d '' file; do
  set +e
  out=$(timeout "$TIMEOUT" "$RENDER" "$file" --size 16x16 --spp 1 -o "$work/out.png" --log warn 2>&1)
  rc=$?
  set -e
  last=$(printf '%s\n' "$out" | { grep -v '^[[:space:]]*$' || true; } | tail -n 1 | cut -c1-300)
  if [ $rc -eq 0 ]; then
    outcome=rendered
    rendered=$((rendered + 1))
  elif [ $rc -eq 1 ] && printf '%s' "$last" | grep -q " error .*$(basename "$file")"; then
    outcome=refused
    refused=$((refused + 1))
  else
    outcome="defect (exit $rc)"
    defects=$((defects + 1))
    defect_lines+=("$file: exit $rc: $last")
  fi
  [ $LIST -eq 1 ] && printf '%s\t%s\t%s\n' "$outcome" "$file" "$last"
done < <(find "$DIR" -type f \( -name '*.gltf' -o -name '*.glb' \) -print0 | sort -z)

echo "rendered: $rendered"
echo "refused with a named error: $refused"
echo "defects (crash, hang past ${TIMEOUT} s, error without the file's name): $defects"
for line in "${defect_lines[@]}"; do echo "  $line"; done
[ $defects -eq 0 ]
