#!/usr/bin/env bash
# Live display runs on the GL backend (docs/benchmarks.md, "GPU reconstructor"):
# deploy/run-local.sh with two samplers, from a bundle (--bin DIR: deploy/bundle.sh DIR
# build/display_node/display_node build/sampler_node/sampler_node, for a GPU server) or from a
# build folder (--build DIR, default build/). Each run prints the display's backend line, its
# /stats read three times (the GPU's passes, the latest image's hole pixels) and its last
# stats line (refresh, the call's phases, GPU time). With --base PROGRAM (bundles only), another
# display_node (an older build, copied into the bundle's bin/) alternates with the bundle's,
# round by round, so that the two are compared on the same machine at the same time.
#
#   bench/gpu_live.sh --bin DIR                               3840x2160 at 30 images/s, 2 rounds
#   bench/gpu_live.sh --bin DIR --base DIR/bin/display_node-base --size 1920x1080 --fps 60
#   bench/gpu_live.sh --size 256x256 --threads 1 --rounds 1   build/, here
set -euo pipefail
cd "$(dirname "$0")/.."

bin="" build=build base="" size=3840x2160 fps=30 threads="" rounds=2 seconds=14 gpu=-1
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --base) base=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --fps) fps=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --rounds) rounds=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --gpu) gpu=$2; shift 2 ;;
    -h|--help) sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "gpu_live.sh: unknown option '$1'" >&2; exit 2 ;;
  esac
done
if [ -n "$bin" ]; then
  [ -x "$bin/bin/display_node" ] && [ -x "$bin/bin/sampler_node" ] ||
    { echo "gpu_live.sh: --bin DIR must hold bin/display_node and bin/sampler_node" >&2; exit 2; }
  nodes=(--bundle "$bin")
else
  [ -z "$base" ] || { echo "gpu_live.sh: --base needs a bundle (--bin DIR)" >&2; exit 2; }
  nodes=(--build "$build")
fi
[ -z "$base" ] || [ -x "$base" ] || { echo "gpu_live.sh: --base $base is not a program" >&2; exit 2; }
[ "$seconds" -ge 8 ] 2>/dev/null || { echo "gpu_live.sh: --seconds must be >= 8" >&2; exit 2; }
# The samplers get the cores the display leaves: half of them each, less one.
threads=${threads:-$(( $(nproc) / 2 > 2 ? $(nproc) / 2 - 1 : 1 ))}

tmp=$(mktemp -d)
if [ -n "$base" ]; then
  # The bundle's own display program, kept aside while --base stands in for it.
  cp "$bin/bin/display_node" "$tmp/display_node-bundle"
  trap 'cp "$tmp/display_node-bundle" "$bin/bin/display_node"; rm -rf "$tmp"' EXIT
else
  trap 'rm -rf "$tmp"' EXIT
fi

# One /stats reading as a line: the display's uptime, the GPU's passes, the hole pixels.
read -r -d '' reader <<'PY' || true
import json, sys
try:
    d = json.load(sys.stdin)["display"]
except ValueError:
    sys.exit(0)
gpu = " ".join(f"{k} {v:.1f}" for k, v in (d.get("gpu_ms") or {}).items()) or "-"
print(f"  t={d['uptime']:.1f}s GPU ms: {gpu}; hole pixels {d.get('hole_pixels', '-')}")
PY

programs=(own)
[ -n "$base" ] && programs=(base own)
commit=$( ([ -n "$bin" ] && cat "$bin/COMMIT") 2>/dev/null || git rev-parse --short HEAD 2>/dev/null || echo unknown)
echo "$size at $fps images/s, 2 samplers x $threads threads, $seconds s a run; programs of $commit"
for round in $(seq 1 "$rounds"); do
  for p in "${programs[@]}"; do
    if [ -n "$base" ]; then
      if [ "$p" = base ]; then cp "$base" "$bin/bin/display_node"; else cp "$tmp/display_node-bundle" "$bin/bin/display_node"; fi
      echo "--- round $round, display: $p"
    elif [ "$rounds" -gt 1 ]; then
      echo "--- round $round"
    fi
    rm -rf "$tmp/run"
    deploy/run-local.sh 2 "${nodes[@]}" --seconds "$seconds" --size "$size" --threads "$threads" \
      --backend gl --gpu "$gpu" --fps "$fps" --output "$tmp/run" --port 7390 \
      --metrics-port 9390 >/dev/null 2>&1 &
    run=$!
    # /stats at half, three quarters and all but the last second of the run.
    start=$SECONDS
    for at in $(( seconds / 2 )) $(( seconds * 3 / 4 )) $(( seconds - 1 )); do
      sleep "$(( at - (SECONDS - start) > 0 ? at - (SECONDS - start) : 0 ))"
      curl -s "http://127.0.0.1:9390/stats" | python3 -c "$reader" || true
    done
    wait "$run" || true
    log=$tmp/run/logs/display.log
    { grep -m1 "reconstruction backend" "$log"; grep "display .* Hz" "$log" | tail -1; } 2>/dev/null |
      sed 's/^[0-9:.]* info //' | grep . || echo "(no stats line: the display's log is empty)"
  done
done
