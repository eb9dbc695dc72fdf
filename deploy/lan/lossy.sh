#!/usr/bin/env bash
# Lossy LAN: the same run of the afr service across network namespaces (deploy/lan/lan.sh)
# twice on a still scene, once on clean links and once with random drops (nft) and a rate
# limit (tbf) on every link; prints each run's image error against the ideal render and
# exits 1 when the lossy run's error exceeds the loss-free one's by more than --bound (0-255
# RMS). Needs root and `ip netns` (exit 77, skipped, without them).
#
#   sudo deploy/lan/lossy.sh                         5% drops, 100mbit, 3 samplers, 10 s each
#   sudo deploy/lan/lossy.sh --drop 10 --rate 20mbit --seconds 20 --bound 4
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
samplers=3 seconds=10 drop=5 rate=100mbit size=128x96 bound=3 build="$root/build"
output="$root/out/lossy" scene="$root/tests/service/data/static_scene.gltf"
while [ $# -gt 0 ]; do
  case "$1" in
    --samplers) samplers=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --drop) drop=$2; shift 2 ;;
    --rate) rate=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --bound) bound=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --output) output=$2; shift 2 ;;
    -h|--help) sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "lossy.sh: unknown option '$1'" >&2; exit 1 ;;
  esac
done
if [ "$(id -u)" -ne 0 ]; then echo "lossy.sh: needs root (network namespaces): skipped"; exit 77; fi
render="$build/bench/afr-render"
[ -x "$render" ] || { echo "lossy.sh: $render not built" >&2; exit 1; }
command -v idiff >/dev/null || { echo "lossy.sh: idiff missing (apt-get install openimageio-tools)" >&2; exit 1; }

mkdir -p "$output"
"$render" "$scene" --time 0 --size "$size" --spp 64 -o "$output/reference.png" --log warn
rms() {  # RMS difference (0-255) of an image from the reference
  { idiff -a "$output/reference.png" "$1" || true; } | awk '/RMS error/ { printf "%.2f", $4 * 255 }'
}

common=(--samplers "$samplers" --seconds "$seconds" --size "$size" --scene "$scene"
        --build "$build" --check)
set +e
"$root/deploy/lan/lan.sh" "${common[@]}" --output "$output/clean" >"$output/clean.log" 2>&1
clean_status=$?
"$root/deploy/lan/lan.sh" "${common[@]}" --drop "$drop" --rate "$rate" --output "$output/lossy" \
  >"$output/lossy.log" 2>&1
lossy_status=$?
set -e
for s in $clean_status $lossy_status; do [ "$s" -eq 77 ] && { echo "lossy.sh: skipped"; exit 77; }; done
if [ $clean_status -ne 0 ] || [ $lossy_status -ne 0 ]; then
  echo "lossy.sh: a run failed (clean $clean_status, lossy $lossy_status): see $output/*.log"
  tail -n 5 "$output/clean.log" "$output/lossy.log"
  exit 1
fi
clean=$(rms "$output/clean/final.png")
lossy=$(rms "$output/lossy/final.png")
samples() { grep -o '"reported_samples": [0-9]*' "$1/stats.json" 2>/dev/null | awk '{ s += $2 } END { print s + 0 }'; }
echo "| run | links | samples at the end | RMS vs ideal (0-255) |"
echo "|---|---|---|---|"
echo "| clean | unlimited | $(samples "$output/clean") | $clean |"
echo "| lossy | $rate, ${drop}% drops | $(samples "$output/lossy") | $lossy |"
if awk -v c="$clean" -v l="$lossy" -v b="$bound" 'BEGIN { exit !(l > c + b) }'; then
  echo "lossy.sh: FAILED: lossy error $lossy exceeds clean $clean by more than $bound"
  exit 1
fi
echo "lossy.sh: passed: the lossy run's error is within $bound of the loss-free run's"
