#!/usr/bin/env bash
# Runs the afr service on this machine: N sampler nodes and one display node on loopback.
# Headless by default (images and stats to out/); with a window when $DISPLAY is set and
# --window is given. Stops everything cleanly after SECONDS (or on Ctrl-C). Exits 1 with the
# reason when a node fails: the display exits with an error, or a sampler exits.
#
#   deploy/run-local.sh 2                          2 samplers, 20 s, built-in scene, out/
#   deploy/run-local.sh 3 --seconds 60 --window    a window (needs $DISPLAY)
#   deploy/run-local.sh 2 --scene kitchen.glb --size 512x512 --threads 2 --port 7300
#   deploy/run-local.sh 2 --bundle DIR             programs from deploy/bundle.sh DIR (no build)
set -euo pipefail
cd "$(dirname "$0")/.."

usage() {
  sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'
  echo "options: --seconds S --size WxH --scene FILE --threads T --port P --metrics-port P"
  echo "         --preset fast|balanced|accurate --window --output DIR --build DIR --every K"
  echo "         --bundle DIR (display_node and sampler_node from deploy/bundle.sh DIR, not built)"
  echo "         --backend gl|cpu|auto --gpu N (the display's reconstructor and EGL device)"
  echo "         --fps F (the display's refresh; default 60 where the samplers' threads leave it a"
  echo "         core of its own, else 30)"
  echo "         --display-args \"ARGS\" (more display_node options, e.g. \"--recut-interval 10\")"
  echo "         --sampler-args \"ARGS\" (more sampler_node options, e.g. \"--light-samples 2\")"
  echo "         --worker-priority idle|nice|normal (the samplers' tracing threads; default nice)"
  exit "${1:-0}"
}

[ $# -ge 1 ] || usage 1
case "$1" in -h|--help) usage 0 ;; esac
n=$1; shift
[[ "$n" =~ ^[0-9]+$ ]] && [ "$n" -ge 1 ] && [ "$n" -le 64 ] || { echo "run-local: N must be 1..64, got '$n'" >&2; exit 1; }
seconds=20 size=256x256 scene="" threads=1 port=7100 metrics_port=9100 preset=balanced
window=0 output=out build=build bundle="" every=0 fps="" backend=auto gpu=-1 display_args="" sampler_args="" worker_priority=nice
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) seconds=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --scene) scene=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --port) port=$2; shift 2 ;;
    --metrics-port) metrics_port=$2; shift 2 ;;
    --preset) preset=$2; shift 2 ;;
    --window) window=1; shift ;;
    --output) output=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --bundle) bundle=$2; shift 2 ;;
    --every) every=$2; shift 2 ;;
    --fps) fps=$2; shift 2 ;;
    --backend) backend=$2; shift 2 ;;
    --gpu) gpu=$2; shift 2 ;;
    --display-args) display_args=$2; shift 2 ;;
    --sampler-args) sampler_args=$2; shift 2 ;;
    --worker-priority) worker_priority=$2; shift 2 ;;
    -h|--help) usage 0 ;;
    *) echo "run-local: unknown option '$1'" >&2; usage 1 ;;
  esac
done

case "$worker_priority" in
  idle) worker_flags=--worker-idle ;;
  nice) worker_flags="--worker-nice 10" ;;
  normal) worker_flags="" ;;
  *) echo "run-local: --worker-priority must be idle, nice or normal, got '$worker_priority'" >&2; exit 1 ;;
esac

# shellcheck source=deploy/nodes.sh
. deploy/nodes.sh
# Always brings the two programs up to date (a no-op when they are), unless they come from a
# bundle: a machine without afr's build dependencies (a GPU server).
if [ -n "$bundle" ]; then
  for program in display_node sampler_node; do
    [ -x "$bundle/bin/$program" ] || { echo "run-local: $bundle/bin/$program not found (deploy/bundle.sh)" >&2; exit 1; }
  done
  display_program=("$bundle/run" display_node)
  sampler_program=("$bundle/run" sampler_node)
else
  build_nodes "$build" run-local
  display_program=("$build/display_node/display_node")
  sampler_program=("$build/sampler_node/sampler_node")
fi

# The display's refresh: 60 images/s when it has a core of its own (more cores than the
# samplers' tracing threads), else 30, which a display sharing its cores with the samplers
# holds (docs/service.md, "Refresh").
if [ -z "$fps" ]; then
  if [ "$(nproc)" -gt $((n * threads)) ]; then fps=60; else fps=30; fi
fi

mkdir -p "$output" "$output/logs"
headless=--headless
if [ "$window" = 1 ]; then
  if [ -n "${DISPLAY:-}" ]; then headless=""; else echo "run-local: no \$DISPLAY: headless"; fi
fi

trap cleanup EXIT
trap 'cleanup; exit 130' INT TERM

echo "run-local: display on tcp://127.0.0.1:$port (metrics http://127.0.0.1:$metrics_port/stats) at $fps images/s, $n sampler(s), $seconds s"
# shellcheck disable=SC2086
"${display_program[@]}" $scene $headless --bind "tcp://127.0.0.1:$port" \
  --size "$size" --preset "$preset" --seconds "$seconds" --output "$output" \
  --screenshot-every "$every" --metrics-port "$metrics_port" --backend "$backend" --gpu "$gpu" \
  --fps "$fps" \
  $display_args > >(tee "$output/logs/display.log") 2>&1 &
start_node display display "$output/logs/display.log"
for i in $(seq 1 "$n"); do
  # Sampling threads at a lower priority: the display keeps its refresh when they share its
  # cores, while each sampler's control thread (its heartbeats) keeps the normal priority.
  # shellcheck disable=SC2086
  "${sampler_program[@]}" --display "tcp://127.0.0.1:$port" --threads "$threads" $worker_flags \
    --name "local-$i" --cache "$output/scene-cache" $sampler_args >"$output/logs/sampler-$i.log" 2>&1 &
  start_node sampler "sampler $i" "$output/logs/sampler-$i.log"
done
if ! watch_nodes run-local; then
  echo "run-local: failed; logs in $output/logs/" >&2
  exit 1
fi
echo "run-local: images in $output/ (final.png, final_tiling.png, final_density.png), logs in $output/logs/"
