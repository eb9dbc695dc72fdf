#!/usr/bin/env bash
# Flow control of real samplers across a rate-limited link (docs/service.md, "Figures"): the
# service of deploy/lan/lan.sh (a display host and N sampler hosts in network namespaces, tbf
# RATE on every link), REPEATS runs of SECONDS each. Per run, from the display's /stats one
# second before the end: the afr message bytes per second received from all samplers over the
# display's last stats period, against the link rate (each sampler has a link of its own into
# the switch, and the display's link carries them all: the display's link is the bottleneck);
# the batches the samplers traced and dropped from their send queues against those they
# handed on, the display's sequence gaps, its refresh and the latency p50; then the medians.
# A sampler that paces itself to its link traces what it sends: drops near 0 with the link
# full. Needs root and `ip netns` (exits 77 without them, as lan.sh).
#
#   sudo bench/flow.sh --build build --rate 100mbit --samplers 2 --seconds 20 --repeats 3
# Options: --build DIR, --rate RATE (tc syntax), --samplers N, --seconds S, --repeats R,
# --threads T (per sampler), --send-buffer BYTES (sampler_node's; 0: the protocol's), --output
# DIR (the runs' folders; default out/flow).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build="$root/build" rate=100mbit samplers=2 seconds=20 repeats=3 threads=1 send_buffer=0
output="$root/out/flow"
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --rate) rate=$2; shift 2 ;;
    --samplers) samplers=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --repeats) repeats=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --send-buffer) send_buffer=$2; shift 2 ;;
    --output) output=$2; shift 2 ;;
    *) echo "flow.sh: unknown option '$1'" >&2; exit 2 ;;
  esac
done
[ "$(id -u)" -eq 0 ] || { echo "flow.sh: needs root (network namespaces); skipped" >&2; exit 77; }

runs=()
for k in $(seq 1 "$repeats"); do
  dir="$output/run-$k"
  rm -rf "$dir"
  "$root/deploy/lan/lan.sh" --build "$build" --samplers "$samplers" --rate "$rate" \
    --seconds "$seconds" --threads "$threads" --send-buffer "$send_buffer" --output "$dir" >"$output-run-$k.log" 2>&1 || {
    status=$?
    [ "$status" = 77 ] && exit 77
    echo "flow.sh: run $k failed (exit $status, $output-run-$k.log)" >&2
    exit 1
  }
  runs+=("$dir/stats.json")
done

python3 - "$rate" "$seconds" "$send_buffer" "${runs[@]}" <<'PY'
import json, re, statistics, sys
rate_text, seconds, send_buffer, files = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
m = re.fullmatch(r"([0-9.]+)([kmg]?)bit", rate_text.lower())
if not m:
    sys.exit(f"flow.sh: cannot read the rate '{rate_text}' (e.g. 100mbit, 1gbit)")
link = float(m.group(1)) * {"": 1, "k": 1e3, "m": 1e6, "g": 1e9}[m.group(2)] / 8  # bytes/s
rows = []
for path in files:
    s = json.load(open(path))
    members = [x for x in s["samplers"] if x.get("member")]
    received = sum(x["bytes_per_second"] for x in members)
    batches = sum(x["batches"] for x in members)
    dropped = sum(x["batches_dropped"] for x in members)
    gaps = sum(x["sequence_gaps"] for x in members)
    samples = sum(x["samples_per_second"] for x in members)
    d = s["display"]
    rows.append(dict(members=len(members), received=received / 1e6, goodput=received / link,
                     samples=samples / 1e3, batches=batches, dropped=dropped,
                     share=dropped / max(1, batches + dropped), gaps=gaps,
                     hz=d.get("refresh_hz", 0.0), p50=1e3 * d.get("window_latency_p50", 0.0)))
buffer = f"--send-buffer {send_buffer}" if send_buffer else "the protocol's send buffer"
print(f"Links {rate_text} ({link / 1e6:.2f} MB/s), runs of {seconds} s, samplers with {buffer}; "
      "from the display's /stats one second before the end\n")
cols = ["run", "samplers", "received MB/s", "of the link", "samples/s (k)", "batches received",
        "batches dropped", "dropped share", "gaps", "display Hz", "latency p50 ms"]
print("| " + " | ".join(cols) + " |")
print("|" + "---|" * len(cols))
for i, r in enumerate(rows, 1):
    print(f"| {i} | {r['members']} | {r['received']:.2f} | {r['goodput']:.3f} | {r['samples']:.0f} | "
          f"{r['batches']} | {r['dropped']} | {r['share']:.4f} | {r['gaps']} | {r['hz']:.1f} | "
          f"{r['p50']:.1f} |")
med = lambda k: statistics.median(r[k] for r in rows)
print(f"| median | | {med('received'):.2f} | {med('goodput'):.3f} | {med('samples'):.0f} | "
      f"{med('batches'):.0f} | {med('dropped'):.0f} | {med('share'):.4f} | {med('gaps'):.0f} | "
      f"{med('hz'):.1f} | {med('p50'):.1f} |")
PY
