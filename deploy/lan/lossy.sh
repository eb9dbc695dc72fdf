#!/usr/bin/env bash
# Lossy LAN: the same run of the afr service across network namespaces (deploy/lan/lan.sh)
# on a still scene, on clean links and with random drops (nft) and a rate limit (tbf) on every
# link, --repeats times each (alternating, so both see the same machine load); prints each
# run's image error against the ideal render and the medians, and exits 1 when the median
# lossy error exceeds the median loss-free one by more than --bound (0-255 RMS), or a run fails
# (a node exits with an error, a sampler does not join, no image). Needs root and `ip netns`
# (exit 77, skipped, without them).
#
#   sudo deploy/lan/lossy.sh                  5% drops, 100mbit, 3 samplers, 10 s, 3 repeats
#   sudo deploy/lan/lossy.sh --drop 10 --rate 20mbit --seconds 20 --repeats 5 --bound 4
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
samplers=3 seconds=10 drop=5 rate=100mbit size=128x96 bound=3 repeats=3 build="$root/build"
output="$root/out/lossy" scene="$root/tests/service/data/static_scene.gltf"
while [ $# -gt 0 ]; do
  case "$1" in
    --samplers) samplers=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --drop) drop=$2; shift 2 ;;
    --rate) rate=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --bound) bound=$2; shift 2 ;;
    --repeats) repeats=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --output) output=$2; shift 2 ;;
    -h|--help) sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
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
samples() { grep -o '"reported_samples": [0-9]*' "$1/stats.json" 2>/dev/null | awk '{ s += $2 } END { print s + 0 }'; }
echo "| run | links | samples at the end | RMS vs ideal (0-255) |"
echo "|---|---|---|---|"
clean_rms=() lossy_rms=()
for r in $(seq 1 "$repeats"); do
  for kind in clean lossy; do
    links=()
    [ "$kind" = lossy ] && links=(--drop "$drop" --rate "$rate")
    set +e
    "$root/deploy/lan/lan.sh" "${common[@]}" "${links[@]}" --output "$output/$kind-$r" \
      >"$output/$kind-$r.log" 2>&1
    status=$?
    set -e
    [ $status -eq 77 ] && { echo "lossy.sh: skipped"; exit 77; }
    if [ $status -ne 0 ]; then
      echo "lossy.sh: the $kind run $r failed (exit $status): see $output/$kind-$r.log"
      tail -n 5 "$output/$kind-$r.log"
      exit 1
    fi
    e=$(rms "$output/$kind-$r/final.png")
    if [ "$kind" = clean ]; then clean_rms+=("$e"); label=unlimited; else lossy_rms+=("$e"); label="$rate, ${drop}% drops"; fi
    echo "| $kind $r | $label | $(samples "$output/$kind-$r") | $e |"
  done
done
median() { printf '%s\n' "$@" | sort -g | awk '{ v[NR] = $1 } END { print (NR % 2 ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2) }'; }
clean=$(median "${clean_rms[@]}")
lossy=$(median "${lossy_rms[@]}")
echo "median RMS: clean $clean, lossy $lossy (difference $(awk -v c="$clean" -v l="$lossy" 'BEGIN { printf "%.2f", l - c }'))"
if awk -v c="$clean" -v l="$lossy" -v b="$bound" 'BEGIN { exit !(l > c + b) }'; then
  echo "lossy.sh: FAILED: the median lossy error $lossy exceeds the clean $clean by more than $bound"
  exit 1
fi
echo "lossy.sh: passed: the median lossy error is within $bound of the loss-free run's"
