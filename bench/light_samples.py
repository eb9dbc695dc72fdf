#!/usr/bin/env python3
"""Light picking's trade (TracerOptions::light_samples, docs/sampler.md "Many lights"): speed
against error on a scene of many lights, in the tracer alone and in the running service.

Writes bench/many_lights_scene.py's scene (N lights), then
  - renders it with afr-render at 1 spp for each light-sample count K (0: every light),
    alternating the counts over the repeats, and scores each image against the ideal renderer
    (16 spp, every light): the time of the render and its RMS error (0-255 sRGB);
  - runs the service (bench/live.py: 2 samplers and a headless display) with each K given in
    --live, alternating: the live RMS error of its images against the ideal and its samples/s.
Medians over the repeats, with the range.

  python3 bench/light_samples.py                          64 lights, K = 0 1 2 4 8, live 0 and 2
  python3 bench/light_samples.py --lights 16 --repeats 5 --write bench/results/light-samples.md
"""
import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(cmd):
    done = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True)
    if done.returncode != 0:
        sys.exit(f"light_samples.py: {' '.join(cmd)} failed:\n{done.stdout[-3000:]}")
    return done.stdout


def spread(values, fmt):
    return f"{fmt.format(statistics.median(values))} [{fmt.format(min(values))}, " \
           f"{fmt.format(max(values))}]"


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--lights", type=int, default=64)
    p.add_argument("--counts", default="0,1,2,4,8", help="light-sample counts for afr-render")
    p.add_argument("--live", default="0,2", help="light-sample counts for the service ('' none)")
    p.add_argument("--size", default="320x240")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--threads", type=int, default=2, help="afr-render's threads")
    p.add_argument("--seconds", type=float, default=14.0, help="each live run")
    p.add_argument("--write", default="", help="also write the report to this file")
    args = p.parse_args()
    counts = [int(k) for k in args.counts.split(",") if k]
    live_counts = [int(k) for k in args.live.split(",") if k]
    render = os.path.join(os.path.abspath(args.build), "bench", "afr-render")

    with tempfile.TemporaryDirectory() as tmp:
        scene = os.path.join(tmp, f"lights{args.lights}.gltf")
        run([sys.executable, os.path.join(ROOT, "bench", "many_lights_scene.py"), scene,
             "--lights", str(args.lights)])
        seconds = {k: [] for k in counts}
        errors = {k: [] for k in counts}
        for r in range(args.repeats):
            for k in counts:
                image = os.path.join(tmp, f"k{k}-{r}.png")
                log = run([render, scene, "-s", args.size, "--spp", "1", "-j", str(args.threads),
                           "--light-samples", str(k), "--seed", str(r + 1), "-o", image])
                seconds[k].append(float(re.search(r"spp: ([0-9.]+) s,", log).group(1)))
                out = run([render, scene, "--compare", image, "--log", "warn"])
                errors[k].append(float(re.search(r"rms=([0-9.]+)", out).group(1)))
        base = statistics.median(seconds[counts[0]])
        lines = [f"# Light picking: {args.lights} lights, {args.size}", "",
                 f"Command: `python3 bench/light_samples.py --lights {args.lights} --counts "
                 f"{args.counts} --live '{args.live}' --size {args.size} --repeats "
                 f"{args.repeats} --threads {args.threads} --seconds {args.seconds:g}`", "",
                 f"afr-render at 1 spp on {args.threads} threads, each image against the ideal "
                 "(16 spp, every light); median [min, max] of the repeats, the counts alternating.",
                 "",
                 f"| light samples | render s | time / K = {counts[0]} | RMS error (0-255) |",
                 "|---|---|---|---|"]
        for k in counts:
            lines.append(f"| {k if k else 'every light'} | {spread(seconds[k], '{:.3f}')} | "
                         f"{statistics.median(seconds[k]) / base:.2f} | "
                         f"{spread(errors[k], '{:.2f}')} |")

        if live_counts:
            live = {k: [] for k in live_counts}
            rate = {k: [] for k in live_counts}
            for r in range(args.repeats):
                for k in live_counts:
                    out = run([sys.executable, os.path.join(ROOT, "bench", "live.py"),
                               "--build", args.build, "--scene", scene, "--size", "256x192",
                               "--seconds", str(args.seconds), "--every", "60",
                               "--sampler-args", f"--light-samples {k}"])
                    row = next(line for line in out.splitlines() if re.match(r"\| \d+ \| ", line))
                    cells = [c.strip() for c in row.strip("|").split("|")]
                    live[k].append(float(cells[1]))
                    rate[k].append(float(cells[4].rstrip("K")) * 1e3)
            lines += ["", "The service (bench/live.py: 2 samplers of 1 thread, a headless display "
                      f"at 256x192, {args.seconds:g} s a run): the mean RMS error of its images "
                      "after the warm-up against the ideal, and the samples/s the display took.",
                      "", "| light samples | live RMS error | samples/s |", "|---|---|---|"]
            for k in live_counts:
                lines.append(f"| {k if k else 'every light'} | {spread(live[k], '{:.2f}')} | "
                             f"{spread([x / 1e3 for x in rate[k]], '{:.0f}K')} |")
        print("\n".join(lines))
        if args.write:
            with open(args.write, "w") as f:
                f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
