#!/usr/bin/env bash
# tools/gltf_corpus.sh sorts files into rendered and refused, and catches a renderer that
# crashes or fails without naming the file. Arguments: the build folder, the source folder.
set -euo pipefail
BUILD=$1
SRC=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
corpus=$work/corpus
mkdir -p "$corpus/good" "$corpus/broken"
cp "$SRC"/tests/data/khronos/*.gltf "$corpus/good/"
printf '{"asset": {"version": "2.0"}, "nodes": [{"mesh": 0}, }]' > "$corpus/broken/syntax.gltf"
printf 'glTF\002\000\000\000\100\000\000\000' > "$corpus/broken/cut.glb"
printf '{"asset": {"version": "2.0"}, "scenes": [{"nodes": [3]}]}' > "$corpus/broken/no_node.gltf"

out=$("$SRC"/tools/gltf_corpus.sh --build "$BUILD" --list "$corpus")
echo "$out"
good=$(ls "$corpus/good" | wc -l)
grep -qx "rendered: $good" <<<"$out"
grep -qx "refused with a named error: 3" <<<"$out"
grep -q "^defects .*: 0$" <<<"$out"
grep -P "^refused\t.*cut.glb\t.*truncated .glb" <<<"$out"

# A renderer that crashes, and one that fails without naming the file: defects, exit 1.
for fake in 'kill -SEGV $$' 'echo "error: something"; exit 1'; do
  mkdir -p "$work/fake/bench"
  printf '#!/usr/bin/env bash\n%s\n' "$fake" > "$work/fake/bench/afr-render"
  chmod +x "$work/fake/bench/afr-render"
  set +e
  out=$("$SRC"/tools/gltf_corpus.sh --build "$work/fake" "$corpus/broken")
  rc=$?
  set -e
  echo "$out"
  [ $rc -eq 1 ] || { echo "expected exit 1 for a defective renderer, got $rc"; exit 1; }
  grep -q "^defects .*: 3$" <<<"$out"
done
echo "gltf_corpus: ok"
