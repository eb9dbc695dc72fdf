#!/usr/bin/env python3
"""Live accuracy: what the running service shows, against the ideal renderer.

Runs the service on this machine (deploy/run-local.sh: N samplers and a headless display)
with an image every K frames, renders the ideal image of each image's display time
(afr-render --loop --compare: 16 spp, the nodes' wrap of display time over the animation) and
reports the RMS error (0-255 sRGB, afr-eval's metric) after a warm-up, with the sample rate,
refresh rate, drops, gaps and recuts the display logged over the same span. With --eval it
runs afr-eval on the same scene, size and span at the measured sample rate (occlusion rays
free, since the service's rate counts samples, not rays; one refresh of latency) and puts its
adaptive and framed 60 Hz figures beside the live one.

  python3 bench/live.py                                  built-in scene, 2 samplers, 20 s
  python3 bench/live.py --samplers 1 --seconds 30 --eval
  python3 bench/live.py --scene kitchen.glb --eval --write bench/results/live-kitchen.md
"""
import argparse
import csv
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def add_service_arguments(p, port):
    """The options of the service run_service starts: scene, size, preset, backend, port."""
    p.add_argument("--scene", default="", help="glTF scene (default: the built-in scene)")
    p.add_argument("--size", default="256x256")
    p.add_argument("--preset", default="balanced")
    p.add_argument("--backend", default="auto")
    p.add_argument("--port", type=int, default=port)


def publish(lines, path):
    """Prints a report's lines, and writes them to `path` too unless it is empty."""
    report = "\n".join(lines) + "\n"
    print(report)
    if path:
        with open(path, "w") as f:
            f.write(report)


def run_service(args, out):
    cmd = [os.path.join(ROOT, "deploy", "run-local.sh"), str(args.samplers),
           "--seconds", str(args.seconds), "--every", str(args.every), "--output", out,
           "--size", args.size, "--port", str(args.port), "--metrics-port", str(args.port + 2000),
           "--build", args.build, "--preset", args.preset, "--backend", args.backend]
    if args.scene:
        cmd += ["--scene", args.scene]
    if args.display_args:
        cmd += ["--display-args", args.display_args]
    if getattr(args, "sampler_args", ""):
        cmd += ["--sampler-args", args.sampler_args]
    if getattr(args, "worker_priority", ""):
        cmd += ["--worker-priority", args.worker_priority]
    done = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True)
    if done.returncode != 0:
        sys.exit(f"live.py: the service failed ({' '.join(cmd)}):\n{done.stdout[-3000:]}")
    with open(os.path.join(out, "logs", "display.log")) as f:
        return f.read()


WROTE = re.compile(r"wrote (\S+)\.png \(t=([0-9.]+)s\)")
STATS = re.compile(r"info t=([0-9.]+)s (\d+) sampler\(s\) \| display ([0-9.]+) Hz.*?"
                   r"reconstruct mean ([0-9.]+) ms.*?latency p50 ([0-9.]+) ms")
SAMPLER = re.compile(r"#(\d+) ([0-9.]+) k/s dropped (\d+) gaps (\d+)")
EPOCH = re.compile(r"\d\d:\d\d:\d\d\.\d+ info region epoch (\d+):")
SESSION_START = re.compile(r"^(\d\d):(\d\d):(\d\d\.\d+) info display session")
CLOCK = re.compile(r"^(\d\d):(\d\d):(\d\d\.\d+) ")


def seconds_of(m):
    return int(m.group(1)) * 3600 + int(m.group(2)) * 60 + float(m.group(3))


def parse_log(log, warmup):
    """Screenshots after the warm-up, and the steady stats lines' figures."""
    shots = [(path, float(t)) for path, t in WROTE.findall(log)
             if not path.endswith("final") and float(t) >= warmup]
    rates, hz, recon, latency = [], [], [], []
    drops = {}
    for line in log.splitlines():
        m = STATS.search(line)
        if not m or "stopping" in line:
            continue
        per = SAMPLER.findall(line)
        drops_now = {sid: (int(d), int(g)) for sid, _, d, g in per}
        if float(m.group(1)) < warmup:
            drops = drops_now  # the counts at the end of the warm-up: subtracted below
            continue
        rates.append(sum(float(k) for _, k, _, _ in per) * 1e3)
        hz.append(float(m.group(3)))
        recon.append(float(m.group(4)))
        latency.append(float(m.group(5)))
        last = drops_now
    if not rates:
        sys.exit("live.py: no stats line after the warm-up (a longer --seconds?)")
    dropped = sum(d - drops.get(s, (0, 0))[0] for s, (d, _) in last.items())
    gaps = sum(g - drops.get(s, (0, 0))[1] for s, (_, g) in last.items())
    # Recuts after the warm-up: region epochs logged later than the session's start + warm-up.
    start = None
    recuts = set()
    for line in log.splitlines():
        s = SESSION_START.match(line)
        if s and start is None:
            start = seconds_of(s)
        e = EPOCH.search(line)
        c = CLOCK.match(line)
        if e and c and start is not None and seconds_of(c) - start >= warmup:
            recuts.add(int(e.group(1)))
    return shots, {
        "rate": statistics.mean(rates), "hz": statistics.mean(hz),
        "reconstruct_ms": statistics.mean(recon), "latency_ms": statistics.mean(latency),
        "dropped": dropped, "gaps": gaps, "recuts": len(recuts)}


def live_errors(args, shots):
    render = os.path.join(args.build, "bench", "afr-render")
    errors = []
    for path, t in shots:
        cmd = [render] + ([args.scene] if args.scene else []) + [
            "--loop", "--time", f"{t:.6f}", "--compare", path + ".png", "--log", "warn"]
        done = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True, check=False)
        m = re.search(r"scene_time=([0-9.]+) rms=([0-9.]+)", done.stdout)
        if done.returncode != 0 or not m:
            sys.exit(f"live.py: {' '.join(cmd)} failed:\n{done.stdout}")
        errors.append((t, float(m.group(1)), float(m.group(2))))
    return errors


def simulated(args, rate, first, seconds, out):
    """afr-eval's adaptive and framed 60 Hz at the live rate: {method: (mean, min, max)}."""
    cmd = [os.path.join(args.build, "bench", "afr-eval"), "--rates", str(int(round(rate))),
           "--methods", "adaptive,framed-60hz", "--size", args.size, "--seeds", str(args.seeds),
           "--start", f"{first:.3f}", "--seconds", f"{seconds:.3f}",
           "--occlusion-ray-cost", "0", "--preset", args.preset,
           "--no-plots", "--no-progress", "-o", out]
    cmd += ["--scene", args.scene] if args.scene else ["--animations", "builtin"]
    done = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True)
    if done.returncode != 0:
        sys.exit(f"live.py: {' '.join(cmd)} failed:\n{done.stdout[-3000:]}")
    result = {}
    with open(os.path.join(out, "cells.csv")) as f:
        for row in csv.DictReader(f):
            result[row["method"]] = (float(row["mean_rms"]), float(row["min_rms"]),
                                     float(row["max_rms"]))
    return result, " ".join(os.path.relpath(c, ROOT) if c.startswith(ROOT) else c for c in cmd)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--samplers", type=int, default=2)
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--warmup", type=float, default=3.0, help="seconds left out at the start")
    p.add_argument("--every", type=int, default=15, help="an image every K display frames")
    add_service_arguments(p, 7700)
    p.add_argument("--display-args", default="",
                   help="more display_node options, e.g. '--recut-interval 10'")
    p.add_argument("--sampler-args", default="",
                   help="more sampler_node options, e.g. '--light-samples 2'")
    p.add_argument("--worker-priority", default="nice",
                   help="the samplers' tracing threads (run-local.sh): idle, nice or normal")
    p.add_argument("--eval", action="store_true", help="afr-eval at the measured rate beside")
    p.add_argument("--seeds", type=int, default=3, help="afr-eval's seeds")
    p.add_argument("--eval-seconds", type=float, default=0.0,
                   help="afr-eval over only the first S seconds of the images' span (its ideal "
                        "frames, 60 a second, dominate the time on a heavy scene; 0: all)")
    p.add_argument("--out", default="", help="folder for the run (default: a temporary one)")
    p.add_argument("--write", default="", help="also write the report to this file")
    args = p.parse_args()
    if args.seconds <= args.warmup + 2:
        sys.exit("live.py: --seconds must exceed --warmup by more than 2")
    if args.scene:
        args.scene = os.path.abspath(args.scene)
    args.build = os.path.abspath(args.build)

    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.abspath(args.out) if args.out else os.path.join(tmp, "run")
        log = run_service(args, out)
        shots, figures = parse_log(log, args.warmup)
        if not shots:
            sys.exit("live.py: no images after the warm-up (a smaller --every?)")
        errors = live_errors(args, shots)
        rms = [e for _, _, e in errors]
        scene = os.path.basename(args.scene) if args.scene else "built-in scene"
        lines = [
            f"# Live accuracy: {scene}, {args.size}, {args.samplers} sampler(s)", "",
            f"Command: `python3 bench/live.py --samplers {args.samplers} --seconds {args.seconds:g}"
            f" --warmup {args.warmup:g} --every {args.every} --size {args.size}"
            + (f" --scene {os.path.relpath(args.scene, ROOT)}" if args.scene else "")
            + (f" --display-args '{args.display_args}'" if args.display_args else "")
            + (f" --sampler-args '{args.sampler_args}'" if args.sampler_args else "")
            + (f" --worker-priority {args.worker_priority}"
               if args.worker_priority != "nice" else "")
            + (" --eval" if args.eval else "")
            + (f" --seeds {args.seeds}" if args.eval else "")
            + (f" --eval-seconds {args.eval_seconds:g}" if args.eval_seconds > 0 else "") + "`", "",
            f"After {args.warmup:g} s of warm-up, {len(rms)} images of the running service "
            f"against the ideal renderer (16 spp) at their display times.", "",
            "| images | live RMS mean | min | max | samples/s | display Hz | reconstruct ms | "
            "latency p50 ms | dropped | gaps | recuts |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
            f"| {len(rms)} | {statistics.mean(rms):.1f} | {min(rms):.1f} | {max(rms):.1f} | "
            f"{figures['rate'] / 1e3:.0f}K | {figures['hz']:.1f} | "
            f"{figures['reconstruct_ms']:.1f} | {figures['latency_ms']:.1f} | "
            f"{figures['dropped']} | {figures['gaps']} | {figures['recuts']} |", "",
            "Per image (display time, error): "
            + ", ".join(f"{t:.2f} s {e:.1f}" for t, _, e in errors)]
        if args.eval:
            # The scene times the images showed (display time wrapped over the animation).
            # (On the 60 Hz frame grid, so that afr-eval's cached ideal frames serve every run.)
            first = math.floor(min(u for _, u, _ in errors) * 60.0) / 60.0
            span = math.ceil((max(u for _, u, _ in errors) - first) * 60.0 + 1.0) / 60.0
            if args.eval_seconds > 0:
                span = min(span, args.eval_seconds)
            sim, command = simulated(args, figures["rate"], first, min(span, 60.0),
                                     os.path.join(tmp, "eval"))
            # The live images inside afr-eval's span (all of them unless --eval-seconds cut it).
            inside = [e for _, u, e in errors if first <= u < first + span]
            live = statistics.mean(inside or rms)
            adaptive, framed = sim.get("adaptive"), sim.get("framed-60hz")
            lines += ["", f"afr-eval at the live rate ({figures['rate'] / 1e3:.0f}K samples/s, "
                      f"{args.seeds} seeds, mean [min, max]; scene time {first:.2f} s + "
                      f"{span:.2f} s): `{command}`", "",
                      "| live images in the span | live | afr-eval adaptive | live / adaptive | "
                      "afr-eval framed 60 Hz |",
                      "|---|---|---|---|---|",
                      f"| {len(inside)} | {live:.1f} | {adaptive[0]:.1f} [{adaptive[1]:.1f}, {adaptive[2]:.1f}] | "
                      f"{live / adaptive[0]:.2f} | {framed[0]:.1f} [{framed[1]:.1f}, "
                      f"{framed[2]:.1f}] |"]
        publish(lines, args.write)


if __name__ == "__main__":
    main()
