#!/usr/bin/env bash
# deploy/run-local.sh and deploy/run-wall.sh end with status 1 and the reason when a node fails
# (the display exits with an error, or every sampler exits), and with 0 after a good run (from
# the build or from a bundle); a good wall run stitches the lead's snapshot, and a missing cell
# is drawn, not the whole image lost.
#
#   tests/service/deploy_scripts_test.sh BUILD_DIR SCENE     (the ctest deploy_scripts)
set -uo pipefail
build=$(realpath "$1") scene=$(realpath "$2")
cd "$(dirname "$0")/../.." || exit 1
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
port=$((20000 + RANDOM % 20000))
failures=0
check() {  # check NAME EXPECTED_STATUS STATUS LOG PATTERN...
  local name=$1 want=$2 got=$3 log=$4 p
  shift 4
  if [ "$got" != "$want" ]; then
    echo "FAIL $name: exit status $got, expected $want"; cat "$log"; failures=$((failures + 1)); return
  fi
  for p in "$@"; do
    if ! grep -qF -- "$p" "$log"; then
      echo "FAIL $name: no '$p' in its output"; cat "$log"; failures=$((failures + 1)); return
    fi
  done
  echo "ok $name"
}
local_run() {
  deploy/run-local.sh "$@" --build "$build" --port "$port" --metrics-port "$((port + 3))" \
    --size 64x64 --backend cpu
}

local_run 2 --threads 0 --seconds 30 --output "$out/dead" >"$out/dead.txt" 2>&1
check "run-local, every sampler exits" 1 $? "$out/dead.txt" \
  "run-local: sampler 1 failed (exit status 105): --threads: Value 0 not in range 1 to 256" \
  "run-local: every sampler has exited: stopping the display" "run-local: failed"

printf '{"asset":' >"$out/broken.gltf"
local_run 1 --scene "$out/broken.gltf" --seconds 30 --output "$out/broken" >"$out/broken.txt" 2>&1
check "run-local, the display fails" 1 $? "$out/broken.txt" \
  "run-local: display failed (exit status 1): " "broken.gltf: invalid glTF" "run-local: failed"

# A good run; the display refreshes 60 times a second where the sampler's one thread leaves it a
# core, else 30, unless told (--fps).
if [ "$(nproc)" -gt 1 ]; then want_fps=60; else want_fps=30; fi
local_run 1 --scene "$scene" --seconds 3 --output "$out/good" >"$out/good.txt" 2>&1
check "run-local, a good run" 0 $? "$out/good.txt" "run-local: images in" "at $want_fps images/s"
local_run 1 --scene "$scene" --seconds 3 --fps 12 --output "$out/fps" >"$out/fps.txt" 2>&1
check "run-local, --fps" 0 $? "$out/fps.txt" "at 12 images/s" "run-local: images in"

# --bundle: the nodes of a deploy/bundle.sh folder, nothing built (a bundle of /bin/true, its
# bin/ then given links to the built nodes); a bundle without the nodes is refused by name.
deploy/bundle.sh "$out/bundle" /bin/true >"$out/bundle.txt" 2>&1
ln -s "$build/display_node/display_node" "$build/sampler_node/sampler_node" "$out/bundle/bin/"
deploy/run-local.sh 1 --bundle "$out/bundle" --port "$port" --metrics-port "$((port + 3))" \
  --size 64x64 --backend cpu --scene "$scene" --seconds 3 --output "$out/bundled" \
  >"$out/bundled.txt" 2>&1
check "run-local, a good run from a bundle" 0 $? "$out/bundled.txt" "run-local: images in"
rm "$out/bundle/bin/sampler_node"
deploy/run-local.sh 1 --bundle "$out/bundle" --port "$port" --seconds 3 --output "$out/unbundled" \
  >"$out/unbundled.txt" 2>&1
check "run-local, a bundle without sampler_node" 1 $? "$out/unbundled.txt" \
  "run-local: $out/bundle/bin/sampler_node not found (deploy/bundle.sh)"

deploy/run-wall.sh 2x1 1 --threads 0 --size 64x32 --seconds 30 --build "$build" --port "$port" \
  --output "$out/wall" >"$out/wall.txt" 2>&1
check "run-wall, every sampler exits" 1 $? "$out/wall.txt" \
  "run-wall: sampler 1 failed (exit status 105)" "run-wall: every sampler has exited" \
  "run-wall: failed"

# A good wall run: the lead's snapshot of one moment, stitched from both cells.
deploy/run-wall.sh 2x1 1 --size 64x32 --seconds 4 --build "$build" --port "$port" \
  --scene "$scene" --output "$out/good-wall" >"$out/good-wall.txt" 2>&1
check "run-wall, a good run stitches a snapshot" 0 $? "$out/good-wall.txt" \
  "run-wall: stitched $out/good-wall/wall.png: every cell's image of one moment (snapshot_000001)"

# A cell whose node died: drawn dark gray, the others stitched all the same (status 3).
rm -f "$out/good-wall/cell-1-0/snapshot_000001.png"
python3 deploy/wall_stitch.py --grid 2x1 --size 64x32 --cells "$out/good-wall" \
  --stem snapshot_000001 -o "$out/missing.png" >"$out/missing.txt" 2>&1
check "wall_stitch, a missing cell" 3 $? "$out/missing.txt" "cell(s) 1,0 missing (drawn dark gray)"
[ -s "$out/missing.png" ] || { echo "FAIL wall_stitch wrote no image"; failures=$((failures + 1)); }

exit $((failures > 0))
