#!/usr/bin/env bash
# Runs a display wall on this machine (docs/wall.md): a lead display_node for cell 0,0 of a
# COLUMNSxROWS grid over a WxH virtual display, one follower display_node per other cell, and
# N sampler nodes, all headless on loopback. Near the end the lead asks every cell for its image
# of one display time (POST /snapshot) and the script stitches those into OUTPUT/wall.png (a cell
# whose node died is drawn dark gray); each node's last image stays in OUTPUT/cell-C-R/final.png.
# Exits 1 with the reason when a node fails: a display exits with an error, or a sampler exits.
#
#   deploy/run-wall.sh 2x2 2                         4 display nodes, 2 samplers, 512x512, 20 s
#   deploy/run-wall.sh 2x2 2 --size 8192x8192 --seconds 30 --preset fast
set -euo pipefail
cd "$(dirname "$0")/.."

usage() {
  sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'
  echo "options: --seconds S --size WxH --scene FILE --threads T --port P --preset NAME"
  echo "         --margin PX --cap SAMPLES_PER_S --output DIR --build DIR"
  exit "${1:-0}"
}
[ $# -ge 2 ] || usage 1
grid=$1 n=$2; shift 2
[[ "$grid" =~ ^([0-9]+)x([0-9]+)$ ]] || { echo "run-wall: grid must be COLUMNSxROWS, got '$grid'" >&2; exit 1; }
cols=${BASH_REMATCH[1]} rows=${BASH_REMATCH[2]}
[[ "$n" =~ ^[0-9]+$ ]] && [ "$n" -ge 1 ] && [ "$n" -le 64 ] || { echo "run-wall: N must be 1..64, got '$n'" >&2; exit 1; }
seconds=20 size=512x512 scene="" threads=1 port=7100 preset=balanced margin=-1 cap=0
output=out/wall build=build
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) seconds=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --scene) scene=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --port) port=$2; shift 2 ;;
    --preset) preset=$2; shift 2 ;;
    --margin) margin=$2; shift 2 ;;
    --cap) cap=$2; shift 2 ;;
    --output) output=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    -h|--help) usage 0 ;;
    *) echo "run-wall: unknown option '$1'" >&2; usage 1 ;;
  esac
done

# shellcheck source=deploy/nodes.sh
. deploy/nodes.sh
build_nodes "$build" run-wall
rm -rf "$output"
mkdir -p "$output/logs"

trap cleanup EXIT

lead="tcp://127.0.0.1:$port"
echo "run-wall: lead display on $lead (metrics :$((port + 3))), ${cols}x${rows} cells of $size, $n sampler(s), $seconds s"
# shellcheck disable=SC2086
"$build/display_node/display_node" $scene --headless --bind "$lead" --size "$size" \
  --wall "${cols}x${rows}" --margin "$margin" --preset "$preset" --seconds "$((seconds + 2))" \
  --output "$output/cell-0-0" --metrics-port "$((port + 3))" >"$output/logs/lead.log" 2>&1 &
start_node display "the lead display" "$output/logs/lead.log"
k=0
for r in $(seq 0 $((rows - 1))); do
  for c in $(seq 0 $((cols - 1))); do
    [ "$c" = 0 ] && [ "$r" = 0 ] && continue
    k=$((k + 1))
    base=$((port + 10 * k))
    "$build/display_node/display_node" --headless --follow "$lead" --cell "$c,$r" \
      --bind "tcp://127.0.0.1:$base" --metrics-port "$((base + 3))" --seconds "$seconds" \
      --output "$output/cell-$c-$r" >"$output/logs/cell-$c-$r.log" 2>&1 &
    start_node display "the display of cell $c,$r" "$output/logs/cell-$c-$r.log"
  done
done
for i in $(seq 1 "$n"); do
  "$build/sampler_node/sampler_node" --display "$lead" --threads "$threads" --name "local-$i" \
    --max-samples-per-second "$cap" --cache "$output/scene-cache" >"$output/logs/sampler-$i.log" 2>&1 &
  start_node sampler "sampler $i" "$output/logs/sampler-$i.log"
done
# A snapshot of one moment, 1.5 s before the cells stop: every node writes its image of the same
# display time (docs/wall.md, "Snapshots").
snap_at=$(( seconds > 3 ? seconds - 2 : 1 ))
(sleep "$snap_at"; curl -s -X POST -d "" "http://127.0.0.1:$((port + 3))/snapshot?delay=0.5" \
   >"$output/snapshot.json" 2>/dev/null || true) &
# The lead runs 2 s longer than the cells, so each cell has exited (0) when the lead does.
status=0
watch_nodes run-wall || status=1
cleanup
trap - EXIT

# Stitch the snapshot's cells into one image (the lead's cell is cell-0-0).
id=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["id"])' \
       "$output/snapshot.json" 2>/dev/null || true)
if [ -n "$id" ]; then
  stem=$(printf 'snapshot_%06d' "$id")
  if python3 deploy/wall_stitch.py --grid "${cols}x${rows}" --size "$size" --cells "$output" \
       --stem "$stem" -o "$output/wall.png"; then
    echo "run-wall: stitched $output/wall.png: every cell's image of one moment ($stem)"
  else
    echo "run-wall: stitched $output/wall.png from the cells that wrote $stem (see above)"
  fi
else
  echo "run-wall: no snapshot (the lead did not answer POST /snapshot); cells in $output/cell-*/final.png"
fi
echo "run-wall: logs in $output/logs/"
grep -E "wall layout|joined the wall|lost" "$output/logs/lead.log" | tail -n 6 || true
if [ "$status" != 0 ]; then
  echo "run-wall: failed; logs in $output/logs/" >&2
  exit 1
fi
