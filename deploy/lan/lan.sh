#!/usr/bin/env bash
# A LAN in network namespaces: one display host and N sampler hosts on a bridge with private
# addresses (10.77.0.0/24), optionally a tbf rate limit on every link and random packet drops
# with nft; runs the afr service across them for SECONDS, prints the display's stats, and tears
# everything down (also on Ctrl-C or failure). Needs root and `ip netns`; exits 77 (skipped)
# without them. `tc netem` is not needed (nor available here).
#
#   sudo deploy/lan/lan.sh --samplers 3 --seconds 10
#   sudo deploy/lan/lan.sh --samplers 2 --rate 1gbit --drop 0.5 --curve --seconds 20
#   sudo deploy/lan/lan.sh --samplers 2 --wall 2x2 --size 256x256 --check   (a display wall:
#        the lead on the display host, a follower display host per other cell; docs/wall.md)
# Options: --samplers N, --seconds S, --rate RATE (tc syntax: 100mbit, 1gbit), --drop PERCENT
# (per packet sent by each host), --threads T, --cap SAMPLES_PER_S, --send-buffer BYTES
# (sampler_node's), --size WxH, --scene FILE,
# --curve (CurveZMQ with generated keys, else --insecure), --build DIR, --output DIR,
# --wall CxR (follower display hosts for the other cells), --ipv6 (an IPv6-only LAN, fd77::/64:
# the display binds its address, samplers and followers reach it by a name that every host's
# /etc/hosts gives that address alone), --check (exit 1 unless every sampler and wall node
# joined and every image was written).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
samplers=3 seconds=10 rate="" drop="" threads=1 cap=0 send_buffer=0 size=128x96 scene="" curve=0
build="$root/build" output="$root/out/lan" check=0 port=7100 wall=1x1 ipv6=0
while [ $# -gt 0 ]; do
  case "$1" in
    --samplers) samplers=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --rate) rate=$2; shift 2 ;;
    --drop) drop=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --cap) cap=$2; shift 2 ;;
    --send-buffer) send_buffer=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --scene) scene=$2; shift 2 ;;
    --curve) curve=1; shift ;;
    --build) build=$2; shift 2 ;;
    --output) output=$2; shift 2 ;;
    --check) check=1; shift ;;
    --wall) wall=$2; shift 2 ;;
    --ipv6) ipv6=1; shift ;;
    -h|--help) sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "lan.sh: unknown option '$1'" >&2; exit 1 ;;
  esac
done

# shellcheck source=deploy/lan/netns.sh
. "$root/deploy/lan/netns.sh"
netns_require lan.sh
if [ -n "$drop" ] && ! command -v nft >/dev/null; then
  echo "lan.sh: --drop needs nft (apt-get install nftables)" >&2; exit 1
fi
display_bin="$build/display_node/display_node"
sampler_bin="$build/sampler_node/sampler_node"
for b in "$display_bin" "$sampler_bin"; do
  [ -x "$b" ] || { echo "lan.sh: $b not built (cmake --build $build --target display_node sampler_node)" >&2; exit 1; }
done

[[ "$wall" =~ ^([0-9]+)x([0-9]+)$ ]] || { echo "lan.sh: --wall must be COLUMNSxROWS" >&2; exit 1; }
cols=${BASH_REMATCH[1]} rows=${BASH_REMATCH[2]}
followers=$((cols * rows - 1))

p="afr$$"            # prefix of every name made here, so teardown removes exactly these
sw="${p}sw"
hosts=("${p}d")
for i in $(seq 1 "$samplers"); do hosts+=("${p}s$i"); done
for k in $(seq 1 "$followers"); do hosts+=("${p}w$k"); done
pids=()
teardown() {
  netns_stop "${pids[@]}"
  netns_down "$sw" "${hosts[@]}"
}
trap teardown EXIT INT TERM

netns_rate=$rate netns_drop=$drop netns_ipv6=""
[ "$ipv6" = 1 ] && netns_ipv6=1
netns_up "$p" "$sw" "${hosts[@]}"
# Host K's address, and how the others reach the display: by address on IPv4, by name on IPv6.
host_addr() { if [ "$ipv6" = 1 ]; then echo "[fd77::$1]"; else echo "10.77.0.$1"; fi; }
display_host=$(host_addr 1)
if [ "$ipv6" = 1 ]; then
  display_host=afr-display
  for h in "${hosts[@]}"; do netns_hosts "$h" "127.0.0.1 localhost" "::1 localhost" "fd77::1 afr-display"; done
fi

mkdir -p "$output/logs"
display_addr=$(host_addr 1)
security=(--insecure)
sampler_security=()
if [ "$curve" = 1 ]; then
  "$display_bin" keygen "$output/keys" --samplers "$samplers" >/dev/null
  security=(--keys "$output/keys")
fi
# shellcheck disable=SC2086
ip netns exec "${p}d" "$display_bin" $scene --headless --bind "tcp://$display_addr:$port" \
  --size "$size" --seconds "$seconds" --output "$output" --metrics-port 9100 --wall "$wall" \
  --backend cpu "${security[@]}" >"$output/logs/display.log" 2>&1 &
display_pid=$!
pids+=("$display_pid")
# Wall followers: host k shows the k-th cell after 0,0 (row by row).
k=0 follower_pids=()
for r in $(seq 0 $((rows - 1))); do
  for c in $(seq 0 $((cols - 1))); do
    [ "$c" = 0 ] && [ "$r" = 0 ] && continue
    k=$((k + 1))
    ip=$(host_addr $((samplers + 1 + k)))
    ip netns exec "${p}w$k" "$display_bin" --headless --follow "tcp://$display_host:$port" \
      --cell "$c,$r" --bind "tcp://$ip:$port" --seconds "$(awk -v s="$seconds" 'BEGIN { print s - 0.5 }')" \
      --output "$output/cell-$c-$r" --backend cpu "${security[@]}" \
      >"$output/logs/cell-$c-$r.log" 2>&1 &
    pids+=("$!")
    follower_pids+=("$!")
  done
done
for i in $(seq 1 "$samplers"); do
  [ "$curve" = 1 ] && sampler_security=(--key "$output/keys/sampler-$i.key" --server-key "$output/keys/display.pub")
  ip netns exec "${p}s$i" "$sampler_bin" --display "tcp://$display_host:$port" --threads "$threads" \
    --max-samples-per-second "$cap" --send-buffer "$send_buffer" --name "host-$i" --cache "$output/cache-$i" \
    "${sampler_security[@]}" >"$output/logs/sampler-$i.log" 2>&1 &
  pids+=("$!")
done
echo "lan.sh: display $display_addr (tcp://$display_host:$port), samplers $(host_addr 2)..$(host_addr $((samplers + 1)))${rate:+, links $rate}${drop:+, ${drop}% drops}; ${seconds} s"
sleep "$(awk -v s="$seconds" 'BEGIN { print (s > 1.5 ? s - 1.0 : s / 2) }')"
ip netns exec "${p}d" curl -s "http://127.0.0.1:9100/stats" >"$output/stats.json" 2>/dev/null || true
status=0
for pid in "${follower_pids[@]}"; do wait "$pid" || status=$?; done
wait "$display_pid" || status=$?
grep -E "joined|t=|lost|REFUSED" "$output/logs/display.log" | tail -n 12 || true
if [ "$check" = 1 ]; then
  joined=$(grep -c "joined:" "$output/logs/display.log" || true)
  nodes=$(grep -c "joined the wall" "$output/logs/display.log" || true)
  images=$(find "$output" -name final.png | wc -l)
  # A wall's lead received its neighbours' coverage across the namespaces (docs/wall.md).
  coverage=$(python3 -c 'import json, sys
s = json.load(open(sys.argv[1]))
print(s["display"]["wall"].get("exchange", {}).get("coverage_in", 0))' "$output/stats.json" 2>/dev/null || echo 0)
  if [ "$status" -ne 0 ] || [ ! -s "$output/final.png" ] || [ "$joined" -lt "$samplers" ] ||
     [ "$nodes" -lt "$followers" ] || [ "$images" -lt $((followers + 1)) ] ||
     { [ "$followers" -gt 0 ] && [ "$coverage" -eq 0 ]; }; then
    echo "lan.sh: CHECK FAILED (exit $status, $joined of $samplers samplers and $nodes of $followers wall nodes joined, $images images, $coverage coverage messages at the lead)"
    exit 1
  fi
  echo "lan.sh: check passed: $joined samplers and $nodes wall nodes joined across namespaces, $images image(s) in $output${coverage:+, $coverage coverage messages at the lead}"
fi
