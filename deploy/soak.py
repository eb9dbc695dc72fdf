#!/usr/bin/env python3
"""Soak test of the afr service: N samplers and a headless display on loopback for a long run,
killing (SIGKILL) and restarting a random sampler at a fixed interval.

It samples, every few seconds, the resident memory (RSS) of every process, the display's
/stats (store fill, members, drops, sequence gaps, rejected messages) and, from the display's
periodic screenshots, the image's RMS error against an ideal render of the same still scene.
At the end it prints a report and exits non-zero when a check fails:

  - RSS after warm-up stays within --rss-tolerance (5%) of its median, for the display and for
    every sampler incarnation that lived past warm-up;
  - the store never holds more than its capacity and ZeroMQ queues stay bounded (samples
    dropped by a sampler's full queue are counted, never queued without bound);
  - no log line at error level or above, no process exits on its own;
  - the image keeps converging: after warm-up every screenshot's error stays within
    --rms-bound of the first converged one (it does not drift upward as samplers come and go).

  deploy/soak.py --build build --minutes 10 --samplers 4 --kill-every 30
  deploy/soak.py --minutes 1 --kill-every 10        (a short smoke run)

Writes everything (logs, screenshots, soak.json with every reading) to --output.
"""
import argparse
import json
import os
import random
import re
import signal
import statistics
import subprocess
import sys
import time
import urllib.request

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STATIC_SCENE = os.path.join(ROOT, "tests", "service", "data", "static_scene.gltf")


def rss_kib(pid):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def get_stats(port):
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/stats", timeout=2) as r:
            return json.loads(r.read())
    except (OSError, ValueError):
        return None


def rms_255(reference, image):
    """RMS difference (0-255 scale) of two images, by OpenImageIO's idiff."""
    out = subprocess.run(["idiff", "-a", reference, image], capture_output=True, text=True).stdout
    m = re.search(r"RMS error\s*=\s*([0-9.eE+-]+)", out)
    return float(m.group(1)) * 255.0 if m else None


class Node:
    def __init__(self, argv, log_path):
        self.argv, self.log_path = argv, log_path
        self.log = open(log_path, "ab")
        self.proc = subprocess.Popen(argv, stdout=self.log, stderr=subprocess.STDOUT)
        self.started = time.monotonic()

    def kill(self, sig=signal.SIGKILL):
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.log.close()


def flatness(series, warmup_s):
    """(median, largest relative deviation from it) of RSS readings taken after warm-up."""
    late = [kib for t, kib in series if t >= warmup_s and kib is not None]
    if len(late) < 3:
        return None, None
    med = statistics.median(late)
    return med, max(abs(k - med) for k in late) / med


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--output", default=os.path.join(ROOT, "out", "soak"))
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--samplers", type=int, default=4)
    ap.add_argument("--kill-every", type=float, default=30.0, help="seconds between kills")
    ap.add_argument("--warmup", type=float, default=60.0, help="seconds before RSS must be flat")
    ap.add_argument("--size", default="256x256")
    ap.add_argument("--scene", default=STATIC_SCENE, help="a still glTF scene")
    ap.add_argument("--port", type=int, default=7400)
    ap.add_argument("--interval", type=float, default=5.0, help="seconds between readings")
    ap.add_argument("--rss-tolerance", type=float, default=0.05)
    ap.add_argument("--rms-bound", type=float, default=3.0,
                    help="allowed rise (0-255) of the image error over the run")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    if not 1 <= args.samplers <= 64:
        ap.error(f"--samplers must be 1..64, got {args.samplers}")
    if args.minutes <= 0 or args.kill_every <= 0 or args.interval <= 0:
        ap.error("--minutes, --kill-every and --interval must be positive")

    display_bin = os.path.join(args.build, "display_node", "display_node")
    sampler_bin = os.path.join(args.build, "sampler_node", "sampler_node")
    render_bin = os.path.join(args.build, "bench", "afr-render")
    for b in (display_bin, sampler_bin, render_bin):
        if not os.access(b, os.X_OK):
            sys.exit(f"soak: {b} is missing: build first (cmake --build {args.build})")
    os.makedirs(os.path.join(args.output, "logs"), exist_ok=True)
    shots = os.path.join(args.output, "shots")
    os.makedirs(shots, exist_ok=True)
    for f in os.listdir(shots):
        os.remove(os.path.join(shots, f))
    rng = random.Random(args.seed)
    w, h = (int(v) for v in args.size.split("x"))

    reference = os.path.join(args.output, "reference.png")
    print(f"soak: ideal render of {os.path.basename(args.scene)} at {args.size}", flush=True)
    subprocess.run([render_bin, args.scene, "--time", "0", "--size", args.size, "--spp", "64",
                    "-o", reference, "--log", "warn"], check=True)

    metrics_port = args.port + 3
    endpoint = f"tcp://127.0.0.1:{args.port}"
    fps = 10
    display = Node([display_bin, args.scene, "--headless", "--bind", endpoint, "--size", args.size,
                    "--backend", "cpu", "--fps", str(fps), "--metrics-port", str(metrics_port),
                    "--output", shots, "--screenshot-every", str(fps * 10), "--stats-interval",
                    "10"], os.path.join(args.output, "logs", "display.log"))
    cache = os.path.join(args.output, "scene-cache")
    incarnation = [0] * args.samplers

    def start_sampler(i):
        incarnation[i] += 1
        name = f"soak-{i + 1}.{incarnation[i]}"
        return Node([sampler_bin, "--display", endpoint, "--name", name, "--cache", cache,
                     "--seed", str(1000 * i + incarnation[i])],
                    os.path.join(args.output, "logs", f"sampler-{i + 1}.log"))

    samplers = [start_sampler(i) for i in range(args.samplers)]
    t0 = time.monotonic()
    duration = args.minutes * 60.0
    readings, kills, exits = [], [], []
    rss = {"display": []}  # key: process name -> [(t since its own start, KiB)]
    next_kill, next_read = args.kill_every, 0.0
    try:
        while (now := time.monotonic() - t0) < duration:
            if display.proc.poll() is not None:
                exits.append(("display", display.proc.returncode, now))
                break
            for i, s in enumerate(samplers):
                if s.proc.poll() is not None:
                    exits.append((f"sampler-{i + 1}", s.proc.returncode, now))
                    samplers[i] = start_sampler(i)
            if now >= next_kill:
                i = rng.randrange(args.samplers)
                samplers[i].kill()
                kills.append((round(now, 1), i + 1))
                print(f"soak: {now:6.1f} s  kill -9 sampler {i + 1}, restarting", flush=True)
                samplers[i] = start_sampler(i)
                next_kill += args.kill_every
            if now >= next_read:
                next_read += args.interval
                r = {"t": round(now, 1), "rss_kib": {}}
                rss["display"].append((now, rss_kib(display.proc.pid)))
                r["rss_kib"]["display"] = rss["display"][-1][1]
                for i, s in enumerate(samplers):
                    key = f"sampler-{i + 1}.{incarnation[i]}"
                    rss.setdefault(key, []).append((now - (s.started - t0), rss_kib(s.proc.pid)))
                    r["rss_kib"][key] = rss[key][-1][1]
                st = get_stats(metrics_port)
                if st:
                    d = st["display"]
                    r["store"] = [d["store_samples"], d["store_capacity"]]
                    r["members"] = d["members"]
                    r["rejected"] = d["rejected_sample_messages"] + d["rejected_control_messages"]
                    r["samples_per_second"] = sum(x["samples_per_second"] for x in st["samplers"]
                                                  if x["member"])
                    r["batches_dropped"] = sum(x["batches_dropped"] for x in st["samplers"])
                    r["sequence_gaps"] = sum(x["sequence_gaps"] for x in st["samplers"])
                readings.append(r)
            time.sleep(0.2)
    finally:
        for s in samplers:
            s.kill(signal.SIGTERM)
        display.kill(signal.SIGTERM)

    # Image error of every screenshot, in time order.
    errors = []
    for f in sorted(os.listdir(shots)):
        m = re.fullmatch(r"frame_(\d+)\.png", f)
        if m:
            e = rms_255(reference, os.path.join(shots, f))
            if e is not None:
                errors.append((int(m.group(1)) / fps, e))

    failures = []
    print("\n# soak report")
    print(f"{args.samplers} samplers, {args.minutes:g} min, kill -9 every {args.kill_every:g} s "
          f"({len(kills)} kills), {args.size}, scene {os.path.basename(args.scene)}")
    print("\n| process | readings after warm-up | median RSS (MiB) | largest deviation |")
    print("|---|---|---|---|")
    for key, series in rss.items():
        med, dev = flatness(series, args.warmup)
        if med is None:
            continue
        n = len([1 for t, k in series if t >= args.warmup and k is not None])
        print(f"| {key} | {n} | {med / 1024:.1f} | {100 * dev:.1f}% |")
        if dev > args.rss_tolerance:
            failures.append(f"{key}: RSS varies {100 * dev:.1f}% after warm-up "
                            f"(> {100 * args.rss_tolerance:.0f}%)")
    stored = [r for r in readings if "store" in r]
    if stored:
        worst = max(r["store"][0] / max(1, r["store"][1]) for r in stored)
        print(f"\nstore fill: at most {100 * worst:.0f}% of capacity "
              f"({stored[-1]['store'][1]} samples)")
        if worst > 1.0:
            failures.append("sample store above its capacity")
        last = stored[-1]
        print(f"samples/s at the end: {last['samples_per_second']:.0f}; batches dropped by full "
              f"sampler queues: {last['batches_dropped']}; sequence gaps: {last['sequence_gaps']}; "
              f"rejected messages: {last['rejected']}")
        if last["rejected"]:
            failures.append(f"{last['rejected']} messages rejected")
    else:
        failures.append("no /stats reading")
    logs = os.path.join(args.output, "logs")
    bad_lines = []
    for f in sorted(os.listdir(logs)):
        with open(os.path.join(logs, f), errors="replace") as fh:
            bad_lines += [f"{f}: {ln.rstrip()}" for ln in fh if re.search(r" (error|critical) ", ln)]
    print(f"error lines in logs: {len(bad_lines)}")
    failures += bad_lines[:10]
    for name, code, at in exits:
        failures.append(f"{name} exited by itself with {code} at {at:.0f} s")
    if errors:
        converged = [e for t, e in errors if t >= args.warmup] or [errors[-1][1]]
        print("\nimage RMS error vs the ideal render (0-255), per screenshot: " +
              ", ".join(f"{t:.0f}s {e:.2f}" for t, e in errors))
        first = converged[0]
        print(f"after warm-up: first {first:.2f}, worst {max(converged):.2f}, last "
              f"{converged[-1]:.2f} (allowed rise {args.rms_bound:g})")
        if max(converged) > first + args.rms_bound:
            failures.append(f"image error rose from {first:.2f} to {max(converged):.2f}")
    else:
        failures.append("no screenshots")
    with open(os.path.join(args.output, "soak.json"), "w") as f:
        json.dump({"args": vars(args), "readings": readings, "kills": kills, "errors": errors,
                   "rss": rss, "failures": failures}, f, indent=1)
    print("\nresult: " + ("PASS" if not failures else "FAIL\n  " + "\n  ".join(failures)))
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main())
