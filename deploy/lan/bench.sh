#!/usr/bin/env bash
# Service benchmarks on loopback, as tables (docs/service.md, "Figures"):
#  1. k = 1..4 samplers each capped at CAP samples/s: samples the display receives / sum of caps
#  2. sample-to-display latency p50 / p99 (display at --fps), and bytes per sample on the wire
# Usage: deploy/lan/bench.sh [--build DIR] [--cap 40000] [--seconds 6] [--fps 60]
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build="$root/build" cap=40000 seconds=6 fps=60 port=7400
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --cap) cap=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --fps) fps=$2; shift 2 ;;
    *) echo "bench.sh: unknown option '$1'" >&2; exit 1 ;;
  esac
done
out=$(mktemp -d)
pids=()
cleanup() { for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; rm -rf "$out"; }
trap cleanup EXIT INT TERM

echo "| k | cap each (samples/s) | received (samples/s) | received / sum of caps | latency p50 (ms) | p99 (ms) | batch bytes/sample |"
echo "|---|---|---|---|---|---|---|"
for k in 1 2 3 4; do
  pids=()
  "$build/display_node/display_node" --headless --bind "tcp://127.0.0.1:$port" --size 128x128 \
    --fps "$fps" --metrics-port $((port + 3)) --output "" --backend cpu >"$out/d$k.log" 2>&1 &
  pids+=("$!")
  for i in $(seq 1 "$k"); do
    "$build/sampler_node/sampler_node" --display "tcp://127.0.0.1:$port" --max-samples-per-second "$cap" \
      --cache "$out/cache" >"$out/s$k-$i.log" 2>&1 &
    pids+=("$!")
  done
  sleep 3  # joins, scene, pools filled, rates settled
  s0=$(curl -s "http://127.0.0.1:$((port + 3))/stats")
  sleep "$seconds"
  s1=$(curl -s "http://127.0.0.1:$((port + 3))/stats")
  python3 - "$k" "$cap" "$seconds" "$s0" "$s1" <<'PY'
import json, sys
k, cap, secs = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
a, b = json.loads(sys.argv[4]), json.loads(sys.argv[5])
def tot(s, key): return sum(m[key] for m in s["samplers"])
samples = tot(b, "samples") - tot(a, "samples")
nbytes = tot(b, "batch_bytes") - tot(a, "batch_bytes")  # sample batches only
rate = samples / secs
d = b["display"]
print(f"| {k} | {cap:.0f} | {rate:.0f} | {rate / (k * cap):.3f} | {d['latency_p50'] * 1e3:.1f} | {d['latency_p99'] * 1e3:.1f} | {nbytes / max(samples, 1):.2f} |")
PY
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
  port=$((port + 10))
done
