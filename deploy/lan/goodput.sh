#!/usr/bin/env bash
# Goodput of sample batches across a rate-limited link (docs/service.md, "Figures"): two
# network namespaces on a bridge (a display host 10.77.0.1 and a sender host 10.77.0.2, the
# layout of lan.sh), a tbf rate limit on both directions of both links, a synthetic sampler
# (`afr-bench-service send`: valid batches through SampleSender, the real encoder and socket
# options, at full speed) and a receiver: display_node itself (its /stats, --receiver display)
# or the display's ingest thread alone (`afr-bench-service receive`, --receiver ingest).
# Per run, over SECONDS after WARMUP: link rate, bytes on the link (the sender's tbf), afr
# message bytes received per second, goodput / link rate, what the sender offered, handed to
# ZeroMQ and dropped from its queue (ZeroMQ's high-water mark was full), the display's sequence
# gaps, and the CPU each process used; then the medians. Needs root and `ip netns`; exits 77
# (skipped) without them. Tears down every namespace it made (also on Ctrl-C or failure).
#
#   sudo deploy/lan/goodput.sh --build build-d --seconds 10 --repeats 3
#   sudo deploy/lan/goodput.sh --build build-d --receiver ingest --mode flush --fields 3
# Options: --rate RATE (tc syntax, 1gbit), --burst B (tbf burst, 256kb), --latency L (tbf
# latency, 20ms), --seconds S, --warmup S, --repeats R, --receiver display|ingest, --mode
# drop|flush (sender: never wait, as a sampler, or wait for room), --fields 1|3, --batch N,
# --fps F (display_node's refresh rate), --size WxH, --build DIR, --ss (print the sender's TCP
# state from `ss -tmi` after each run), -- ARGS (more arguments for the sender, e.g.
# --sndhwm 1000 or --sndbuf 0 to try other socket options; the defaults are the protocol's).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
rate=1gbit burst=256kb latency=20ms seconds=10 warmup=2 repeats=3 receiver=display mode=drop
fields=1 batch=128 fps=10 size=256x256 build="$root/build" show_ss=0 port=7100
sender_args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --rate) rate=$2; shift 2 ;;
    --burst) burst=$2; shift 2 ;;
    --latency) latency=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --warmup) warmup=$2; shift 2 ;;
    --repeats) repeats=$2; shift 2 ;;
    --receiver) receiver=$2; shift 2 ;;
    --mode) mode=$2; shift 2 ;;
    --fields) fields=$2; shift 2 ;;
    --batch) batch=$2; shift 2 ;;
    --fps) fps=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --ss) show_ss=1; shift ;;
    --) shift; sender_args=("$@"); break ;;
    -h|--help) sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "goodput.sh: unknown option '$1'" >&2; exit 1 ;;
  esac
done
case "$receiver" in display|ingest) ;; *) echo "goodput.sh: --receiver display|ingest" >&2; exit 1 ;; esac
[[ "$size" =~ ^([0-9]+)x([0-9]+)$ ]] || { echo "goodput.sh: --size must be WxH" >&2; exit 1; }
width=${BASH_REMATCH[1]} height=${BASH_REMATCH[2]}

# shellcheck source=deploy/lan/netns.sh
. "$root/deploy/lan/netns.sh"
netns_require goodput.sh
bench_bin="$build/bench/afr-bench-service"
display_bin="$build/display_node/display_node"
need=("$bench_bin")
[ "$receiver" = display ] && need+=("$display_bin")
for b in "${need[@]}"; do
  [ -x "$b" ] || { echo "goodput.sh: $b not built (cmake --build $build --target afr-bench-service display_node)" >&2; exit 1; }
done

p="afrg$$"  # prefix of every name made here, so teardown removes exactly these
sw="${p}sw" dh="${p}d" sh="${p}s"
hosts=("$dh" "$sh")
out=$(mktemp -d)
pids=()
teardown() {
  netns_stop "${pids[@]}"
  netns_down "$sw" "${hosts[@]}"
  rm -rf "$out"
}
trap teardown EXIT INT TERM

# The same tbf on each host's uplink and the switch's port towards it, so both directions of
# both links are limited (as in lan.sh).
netns_rate=$rate netns_burst=$burst netns_latency=$latency
netns_up "$p" "$sw" "${hosts[@]}"
display_ip=10.77.0.1
endpoint="tcp://$display_ip:$port"

# Bytes sent by the sender host's tbf (Ethernet frames as tbf counts them), and its drops.
tbf_sent() { ip netns exec "$sh" tc -s qdisc show dev eth0 | awk '/Sent/ { print $2, $4; exit }'; }
tbf_dropped() { ip netns exec "$sh" tc -s qdisc show dev eth0 | awk '/Sent/ { gsub(",", "", $7); print $7; exit }'; }
# utime + stime of a process, in clock ticks.
cpu_ticks() { awk '{ print $14 + $15 }' "/proc/$1/stat" 2>/dev/null || echo 0; }
now() { date +%s.%N; }

# One snapshot: "t sender-line receiver-json-or-line tbf-bytes tbf-packets tbf-drops cpu-s cpu-r"
snapshot() {  # $1 = run, $2 = tag
  local r=$1 tag=$2 t0 t1
  kill -USR1 "$sender_pid"
  t0=$(now)
  if [ "$receiver" = display ]; then
    ip netns exec "$dh" curl -s --max-time 2 --retry 3 --retry-connrefused \
      "http://127.0.0.1:9100/stats" >"$out/$r-$tag.json" || echo '{}' >"$out/$r-$tag.json"
  else
    kill -USR1 "$receiver_pid"
  fi
  t1=$(now)
  read -r bytes packets < <(tbf_sent)
  echo "$t0 $t1 $bytes $packets $(tbf_dropped) $(cpu_ticks "$sender_pid") $(cpu_ticks "$receiver_pid")" >"$out/$r-$tag.snap"
  sleep 0.1
  grep '^counters' "$out/sender-$r.log" | tail -n 1 >"$out/$r-$tag.sender"
  if [ "$receiver" = ingest ]; then grep '^counters' "$out/receiver-$r.log" | tail -n 1 >"$out/$r-$tag.receiver"; fi
}

load_before=$(uptime)
for r in $(seq 1 "$repeats"); do
  pids=()
  if [ "$receiver" = display ]; then
    ip netns exec "$dh" "$display_bin" --headless --bind "$endpoint" --size "$size" --fps "$fps" \
      --metrics-port 9100 --output "" --backend cpu --insecure >"$out/receiver-$r.log" 2>&1 &
  else
    ip netns exec "$dh" "$bench_bin" receive --bind "$endpoint" --width "$width" --height "$height" \
      >"$out/receiver-$r.log" 2>&1 &
  fi
  receiver_pid=$!
  pids+=("$receiver_pid")
  sleep 0.5
  join=()
  [ "$receiver" = display ] && join=(--join)  # display_node takes batches from members only
  ip netns exec "$sh" "$bench_bin" send --display "$endpoint" --mode "$mode" --fields "$fields" \
    --batch "$batch" --width "$width" --height "$height" --id 1 "${join[@]}" "${sender_args[@]}" \
    >"$out/sender-$r.log" 2>&1 &
  sender_pid=$!
  pids+=("$sender_pid")
  # Signals only once both have their handlers ("ready"; display_node: /stats answers).
  for _ in $(seq 1 100); do
    grep -q '^ready' "$out/sender-$r.log" 2>/dev/null &&
      { [ "$receiver" = display ] || grep -q '^ready' "$out/receiver-$r.log" 2>/dev/null; } && break
    sleep 0.1
  done
  sleep "$warmup"
  snapshot "$r" a
  sleep "$seconds"
  snapshot "$r" b
  for pid in "$receiver_pid" "$sender_pid"; do
    kill -0 "$pid" 2>/dev/null || { echo "goodput.sh: run $r: a process exited early:"; tail -n 5 "$out"/*-"$r".log; exit 1; }
  done
  if [ "$show_ss" = 1 ]; then
    echo "run $r, sender's TCP state (ss -tmi):"
    ip netns exec "$sh" ss -tmi "dport = :$((port + 2))" | sed 's/^/    /'
  fi
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
  pids=()
done
load_after=$(uptime)

python3 - "$out" "$repeats" "$receiver" "$rate" "$(getconf CLK_TCK)" <<'PY'
import json, re, statistics, sys
out, repeats, receiver, rate_text, tck = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4], float(sys.argv[5])
units = {"": 1, "k": 1e3, "m": 1e6, "g": 1e9}
m = re.fullmatch(r"([\d.]+)([kmg]?)bit", rate_text.lower())
link_bits = float(m.group(1)) * units[m.group(2)] if m else float("nan")
link_bytes = link_bits / 8

def kv(path):
    line = open(path).read().split()
    return {k: float(v) for k, v in (f.split("=") for f in line[1:])}

def snap(path):
    t0, t1, b, pk, dr, cs, cr = open(path).read().split()
    return (float(t0) + float(t1)) / 2, float(b), float(pk), float(dr), float(cs) / tck, float(cr) / tck

def received(r, tag):
    if receiver == "display":
        j = json.load(open(f"{out}/{r}-{tag}.json"))
        s = [x for x in j.get("samplers", []) if x["id"] == 1]
        return (s[0]["batch_bytes"], s[0]["batches"], s[0]["sequence_gaps"]) if s else (0, 0, 0)
    c = kv(f"{out}/{r}-{tag}.receiver")
    return c["bytes"], c["batches"], c["gaps"]

rows = []
print("| run | link rate (B/s) | on the link (B/s) | payload received (B/s) | goodput / link rate | "
      "offered (batches/s) | handed to ZeroMQ (batches/s) | received (batches/s) | dropped by the sender's queue | "
      "sequence gaps | packets dropped by tbf | sender CPU | receiver CPU |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for r in range(1, repeats + 1):
    ta, wa, _, da, csa, cra = snap(f"{out}/{r}-a.snap")
    tb, wb, _, db, csb, crb = snap(f"{out}/{r}-b.snap")
    sa, sb = kv(f"{out}/{r}-a.sender"), kv(f"{out}/{r}-b.sender")
    ra, rb = received(r, "a"), received(r, "b")
    dt = sb["t"] - sa["t"]   # the sender's clock between the two signals
    wall = tb - ta
    payload = (rb[0] - ra[0]) / wall
    offered = (sb["offered"] - sa["offered"]) / dt
    sent = (sb["sent"] - sa["sent"]) / dt
    dropped = sb["dropped"] - sa["dropped"]
    off = sb["offered"] - sa["offered"]
    got = (rb[1] - ra[1]) / wall
    row = dict(wire=(wb - wa) / wall, payload=payload, ratio=payload / link_bytes, offered=offered,
               sent=sent, got=got, dropped=dropped / off if off else 0.0, gaps=rb[2] - ra[2],
               linkdrops=db - da,
               cs=(csb - csa) / wall, cr=(crb - cra) / wall)
    rows.append(row)
    print(f"| {r} | {link_bytes:.4g} | {row['wire']:.4g} | {payload:.4g} | {row['ratio']:.3f} | "
          f"{offered:.0f} | {sent:.0f} | {got:.0f} | {dropped:.0f} of {off:.0f} ({row['dropped']:.1%}) | "
          f"{row['gaps']:.0f} | {row['linkdrops']:.0f} | {row['cs']:.2f} | {row['cr']:.2f} |")
med = {k: statistics.median(x[k] for x in rows) for k in rows[0]}
print(f"| median | {link_bytes:.4g} | {med['wire']:.4g} | {med['payload']:.4g} | {med['ratio']:.3f} | "
      f"{med['offered']:.0f} | {med['sent']:.0f} | {med['got']:.0f} | {med['dropped']:.1%} | {med['gaps']:.0f} | "
      f"{med['linkdrops']:.0f} | {med['cs']:.2f} | {med['cr']:.2f} |")
print(f"goodput = afr sample-batch message bytes received per second / link rate; "
      f"link bytes / link rate = {med['wire'] / link_bytes:.3f} (Ethernet frames as tbf counts them)")
PY
echo "load before: $load_before"
echo "load after:  $load_after"
echo "links: tbf rate $rate burst $burst latency $latency; receiver: $receiver; sender: --mode $mode --fields $fields --batch $batch ${sender_args[*]}"
