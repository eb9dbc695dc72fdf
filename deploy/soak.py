#!/usr/bin/env python3
"""Soak test of the afr service: N samplers and a headless display on loopback for a long run,
killing (SIGKILL) and restarting a random sampler at a fixed interval.

It samples, every few seconds, the resident memory (RSS) of every process, the display's
/stats (store fill, members, drops, sequence gaps, rejected messages) and, from the display's
periodic screenshots, the image's RMS error against an ideal render of the same still scene.
At the end it prints a report and exits non-zero when a check fails:

  - the display's RSS after warm-up stays within --rss-tolerance (5%) of its median;
  - a sampler's RSS after warm-up stays within --rss-tolerance of a model of its memory: a
    fixed part of its own plus a cost per pixel of its region (the deep buffer), the cost per
    pixel fitted by least squares, within each incarnation, to the readings of every sampler
    incarnation that lived past warm-up. The coordinator cuts regions by error and throughput,
    so a sampler's region changes every few seconds as others die and rejoin, and a new region
    restarts its pool on that region; the model takes the regions out, and what is left (a
    leak, a growing cache) shows as a deviation. Readings within --region-settle seconds of the
    sampler getting a larger region than any before (the old and the new pool both alive) are
    left out of the fit and the check;
  - the store never holds more than its capacity and ZeroMQ queues stay bounded (samples
    dropped by a sampler's full queue are counted, never queued without bound);
  - no log line at error level or above, no process exits on its own;
  - the image keeps converging: after warm-up, every screenshot's error stays within
    --rms-bound of the median screenshot's, and the median of the last third of the screenshots
    within --drift-bound of the first third's (no upward drift as samplers come and go). Left
    out: screenshots written within --recovery seconds after a change of membership, a kill or
    a "lost" or "joined" line of the display's log (on a loaded machine a live sampler that
    stays silent for the member timeout is declared lost too). A lost sampler's region gets no
    fresh samples until the display declares it lost (its failure detector: at least --member-timeout, 1.5 s by default, of silence), and a region
    cut for a joining sampler none until its pool has filled it. Those screenshots are reported,
    and at least half the screenshots after warm-up must lie outside the recovery windows.

  - with --hostile RATE, a hostile peer runs beside the samplers for the whole soak: it pushes
    RATE samples/s of well-formed batches that name sampler 1 without its token (afr-bench-service
    send, no join) into the display's sample channel; the display must drop and count them
    (/stats spoofed_* and unknown_sampler_*), and every check above must still hold: nothing
    of the flood reaches the image, the store or the members.

  deploy/soak.py --build build --minutes 10 --samplers 4 --kill-every 30
  deploy/soak.py --minutes 1 --kill-every 10        (a short smoke run)
  deploy/soak.py --minutes 2 --samplers 2 --kill-every 30 --hostile 200000

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
RECOVERY_S = 5.0  # default --recovery
REGION_SETTLE_S = 5.0  # default --region-settle


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
    late = [r[1] for r in series if r[0] >= warmup_s and r[1] is not None]
    if len(late) < 3:
        return None, None
    med = statistics.median(late)
    return med, max(abs(k - med) for k in late) / med


def checked_sampler_readings(series, warmup_s):
    """(region pixels, KiB) of a sampler's readings after warm-up, its largest region settled."""
    return [(px, kib) for t, kib, px, peak, settled in series
            if t >= warmup_s and kib is not None and px and settled]


def fit_rss_model(incarnations):
    """KiB per region pixel, fitted by least squares to the (pixels, KiB) readings of each
    incarnation around its own means (each has its own fixed part), and the fixed part of each:
    the median of its readings less the pixels' cost. With no change of region after warm-up
    the cost per pixel is not determined: then it is 0."""
    num = den = 0.0
    for points in incarnations.values():
        mean_p = statistics.fmean(p for p, _ in points)
        mean_k = statistics.fmean(k for _, k in points)
        num += sum((p - mean_p) * (k - mean_k) for p, k in points)
        den += sum((p - mean_p) ** 2 for p, _ in points)
    per_pixel = num / den if den > 0 else 0.0
    fixed = {key: statistics.median(k - per_pixel * p for p, k in points)
             for key, points in incarnations.items()}
    return fixed, per_pixel


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
                    help="allowed excess (0-255) of a screenshot's image error over the median")
    ap.add_argument("--drift-bound", type=float, default=1.0,
                    help="allowed rise (0-255) of the median image error, first to last third")
    ap.add_argument("--recovery", type=float, default=RECOVERY_S,
                    help="seconds after a change of membership in which the image error may "
                         "exceed the bound")
    ap.add_argument("--region-settle", type=float, default=REGION_SETTLE_S,
                    help="seconds after a sampler gets a larger region than before until its RSS "
                         "is checked again")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--hostile", type=float, default=0.0,
                    help="samples/s of spoofed batches from a hostile peer beside the samplers")
    args = ap.parse_args()
    if not 1 <= args.samplers <= 64:
        ap.error(f"--samplers must be 1..64, got {args.samplers}")
    if args.minutes <= 0 or args.kill_every <= 0 or args.interval <= 0:
        ap.error("--minutes, --kill-every and --interval must be positive")
    if args.recovery < 0 or args.region_settle < 0:
        ap.error("--recovery and --region-settle must not be negative")

    display_bin = os.path.join(args.build, "display_node", "display_node")
    sampler_bin = os.path.join(args.build, "sampler_node", "sampler_node")
    render_bin = os.path.join(args.build, "bench", "afr-render")
    bench_bin = os.path.join(args.build, "bench", "afr-bench-service")
    needed = (display_bin, sampler_bin, render_bin) + ((bench_bin,) if args.hostile > 0 else ())
    for b in needed:
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
    hostile = None
    if args.hostile > 0:
        # Batches naming sampler 1 (a real member once it has joined) without its token.
        hostile = Node([bench_bin, "send", "--display", endpoint, "--id", "1", "--width", str(w),
                        "--height", str(h), "--max-samples-per-second", str(args.hostile),
                        "--seconds", str(args.minutes * 60.0)],
                       os.path.join(args.output, "logs", "hostile.log"))
    t0 = time.monotonic()
    t0_wall = time.time()  # screenshots are placed in time by their files' modification times
    duration = args.minutes * 60.0
    readings, kills, exits = [], [], []
    # Process name -> [(t since its own start, KiB)]; for a sampler also the pixels of its
    # region and of the largest it has held (None before it has one) and whether that largest
    # region had settled (--region-settle).
    rss = {"display": []}
    largest = {}  # sampler key -> (pixels of the largest region it has held, t it got it)
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
                r = {"t": round(now, 1), "rss_kib": {}, "region_pixels": {}}
                st = get_stats(metrics_port)
                by_name = {x["name"]: x for x in st["samplers"]} if st else {}
                rss["display"].append((now, rss_kib(display.proc.pid)))
                r["rss_kib"]["display"] = rss["display"][-1][1]
                for i, s in enumerate(samplers):
                    key = f"sampler-{i + 1}.{incarnation[i]}"
                    x = by_name.get(f"soak-{i + 1}.{incarnation[i]}")
                    pixels, peak, settled = None, None, False
                    if x is not None and x["member"]:
                        x0, y0, x1, y1 = x["region"]
                        pixels = max(0, x1 - x0) * max(0, y1 - y0)
                        if pixels > largest.get(key, (0, 0))[0]:
                            largest[key] = (pixels, now)
                        peak = largest[key][0]
                        settled = now - largest[key][1] >= args.region_settle
                    rss.setdefault(key, []).append((now - (s.started - t0), rss_kib(s.proc.pid),
                                                    pixels, peak, settled))
                    r["rss_kib"][key] = rss[key][-1][1]
                    r["region_pixels"][key] = pixels
                if st:
                    d = st["display"]
                    r["store"] = [d["store_samples"], d["store_capacity"]]
                    r["members"] = d["members"]
                    r["rejected"] = d["rejected_sample_messages"] + d["rejected_control_messages"]
                    r["samples_per_second"] = sum(x["samples_per_second"] for x in st["samplers"]
                                                  if x["member"])
                    r["batches_dropped"] = sum(x["batches_dropped"] for x in st["samplers"])
                    r["sequence_gaps"] = sum(x["sequence_gaps"] for x in st["samplers"])
                    r["dropped_hostile_batches"] = (d["spoofed_batches"] +
                                                    d["unknown_sampler_batches"])
                readings.append(r)
            time.sleep(0.2)
    finally:
        for s in samplers:
            s.kill(signal.SIGTERM)
        if hostile:
            hostile.kill(signal.SIGTERM)
        display.kill(signal.SIGTERM)

    # Image error of every screenshot, in time order.
    # Times from the files (a starved display renders fewer frames than --fps a second).
    errors = []
    for f in sorted(os.listdir(shots)):
        if re.fullmatch(r"frame_(\d+)\.png", f):
            path = os.path.join(shots, f)
            e = rms_255(reference, path)
            if e is not None:
                errors.append((os.path.getmtime(path) - t0_wall, e))

    # Changes of membership: the kills, and the display's "lost" and "joined" lines (local
    # time of day, as the log writes it).
    changes = [k for k, _ in kills]
    day = time.localtime(t0_wall)
    with open(os.path.join(args.output, "logs", "display.log"), errors="replace") as fh:
        for ln in fh:
            m = re.match(r"(\d\d):(\d\d):(\d\d(?:\.\d+)?) \w+ sampler \d+ .*(lost:|joined:)", ln)
            if m:
                midnight = time.mktime(day[:3] + (0, 0, 0) + day[6:8] + (-1,))
                at = midnight + 3600 * int(m[1]) + 60 * int(m[2]) + float(m[3])
                if at < t0_wall - 43200:
                    at += 86400  # past midnight
                changes.append(at - t0_wall)

    def recovering_since(t):
        """Seconds since the last change of membership, if t lies in its recovery window."""
        since = [t - c for c in changes if 0 <= t - c < args.recovery]
        return min(since) if since else None

    failures = []
    print("\n# soak report")
    print(f"{args.samplers} samplers, {args.minutes:g} min, kill -9 every {args.kill_every:g} s "
          f"({len(kills)} kills), {args.size}, scene {os.path.basename(args.scene)}")
    med, dev = flatness(rss["display"], args.warmup)
    if med is None:
        failures.append("display: fewer than 3 RSS readings after warm-up")
    else:
        n = len([1 for t, k in rss["display"] if t >= args.warmup and k is not None])
        print(f"\ndisplay RSS after warm-up: median {med / 1024:.1f} MiB, largest deviation "
              f"{100 * dev:.1f}% over {n} readings")
        if dev > args.rss_tolerance:
            failures.append(f"display: RSS varies {100 * dev:.1f}% after warm-up "
                            f"(> {100 * args.rss_tolerance:.0f}%)")
    checked = {k: checked_sampler_readings(v, args.warmup) for k, v in rss.items()
               if k != "display"}
    checked = {k: v for k, v in checked.items() if len(v) >= 3}
    if not checked:
        failures.append("no sampler lived past warm-up with a settled region")
    else:
        fixed, per_pixel = fit_rss_model(checked)
        n = sum(len(v) for v in checked.values())
        print(f"sampler RSS model, fitted to {n} readings of {len(checked)} incarnations: a fixed "
              f"part per incarnation + {1024 * per_pixel:.0f} bytes per region pixel")
        print("\n| sampler | readings checked | region (px) | fixed part (MiB) | "
              "median RSS (MiB) | RSS spread | largest deviation from the model |")
        print("|---|---|---|---|---|---|---|")
        for key, v in checked.items():
            kib = [k for _, k in v]
            spread = (max(kib) - min(kib)) / statistics.median(kib)
            worst = max(abs(k - (fixed[key] + per_pixel * p)) / (fixed[key] + per_pixel * p)
                        for p, k in v)
            print(f"| {key} | {len(v)} | {min(p for p, _ in v)}-{max(p for p, _ in v)} | "
                  f"{fixed[key] / 1024:.1f} | {statistics.median(kib) / 1024:.1f} | "
                  f"{100 * spread:.1f}% | {100 * worst:.1f}% |")
            if worst > args.rss_tolerance:
                failures.append(f"{key}: RSS deviates {100 * worst:.1f}% from the model "
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
        if args.hostile > 0:
            print(f"hostile peer: {last['dropped_hostile_batches']} of its batches dropped and "
                  "counted by the display")
            if not last["dropped_hostile_batches"]:
                failures.append("the hostile peer's batches were not dropped and counted")
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
        print("\nimage RMS error vs the ideal render (0-255), per screenshot (* within "
              f"{args.recovery:g} s after a change of membership): " +
              ", ".join(f"{t:.0f}s {e:.2f}{'*' if recovering_since(t) is not None else ''}"
                        for t, e in errors))
        print(f"changes of membership: {len(changes)} ({len(kills)} kills, "
              f"{len(changes) - len(kills)} lost or joined lines in the display's log)")
        converged = [(t, e) for t, e in errors if t >= args.warmup] or [errors[-1]]
        steady = [e for t, e in converged if recovering_since(t) is None]
        recovering = [(t, e) for t, e in converged if recovering_since(t) is not None]
        if len(steady) < max(1, len(converged) / 2):
            failures.append(f"only {len(steady)} of {len(converged)} screenshots after warm-up lie "
                            "outside the recovery windows")
        if steady:
            med = statistics.median(steady)
            third = max(1, len(steady) // 3)
            early, late = statistics.median(steady[:third]), statistics.median(steady[-third:])
            print(f"after warm-up, outside the recovery windows ({len(steady)} screenshots): "
                  f"median {med:.2f}, worst {max(steady):.2f} (allowed {med + args.rms_bound:.2f}); "
                  f"median of the first third {early:.2f}, of the last third {late:.2f} "
                  f"(allowed rise {args.drift_bound:g})")
            if max(steady) > med + args.rms_bound:
                failures.append(f"image error {max(steady):.2f} outside a recovery window, "
                                f"more than {args.rms_bound:g} above the median {med:.2f}")
            if late > early + args.drift_bound:
                failures.append(f"image error drifted from {early:.2f} to {late:.2f}")
        if recovering:
            print(f"within {args.recovery:g} s after a change ({len(recovering)} screenshots): " +
                  ", ".join(f"{e:.2f} at {recovering_since(t):.1f} s" for t, e in recovering))
    else:
        failures.append("no screenshots")
    with open(os.path.join(args.output, "soak.json"), "w") as f:
        json.dump({"args": vars(args), "readings": readings, "kills": kills,
                   "membership_changes": sorted(changes), "errors": errors,
                   "rss": rss, "failures": failures}, f, indent=1)
    print("\nresult: " + ("PASS" if not failures else "FAIL\n  " + "\n  ".join(failures)))
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main())
