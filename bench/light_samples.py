#!/usr/bin/env python3
"""Light picking's trade (TracerOptions::light_samples, docs/sampler.md "Many lights"): speed
against error on a scene of many lights, in the tracer alone and in the running service.

Writes bench/many_lights_scene.py's scene for each light count, then
  - renders it with afr-render for each pair of light-sample count K (0: every light) and
    samples per pixel given, alternating over the repeats, and scores each image against the
    ideal renderer (16 spp, every light): the time of the render and its RMS error (0-255
    sRGB), so that renders of equal time can be compared;
  - runs the service (bench/live.py: 2 samplers and a headless display) on the scene of the most
    lights, with a still view and with a moving one (--views), with each K given in --live,
    alternating: the live RMS error of its images against the ideal and its samples/s.
Medians over the repeats, with the range.

  python3 bench/light_samples.py                  64 and 256 lights; live: every light and 8
                                                  picks, each with the preset's store (4 samples
                                                  a pixel) and one of 10
  python3 bench/light_samples.py --lights 16 --renders 0:1,2:1 --live '' --repeats 5
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
    p.add_argument("--lights", default="64,256", help="light counts of the scenes")
    p.add_argument("--renders", default="0:1,0:4,1:1,2:1,4:1,8:1,8:4,16:4",
                   help="afr-render's light samples:spp pairs")
    p.add_argument("--live", default="0,8,0/10,8/10",
                   help="the service's light-sample counts, on the scene of the most lights, "
                        "each as K or K/S, S the samples a pixel the display's store keeps "
                        "(--capacity S x W x H; the balanced preset's 4 without /S) ('' for none)")
    p.add_argument("--views", default="still,moving",
                   help="the service's views: still, and a camera sliding to the side and back")
    p.add_argument("--size", default="320x240")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--threads", type=int, default=2, help="afr-render's threads")
    p.add_argument("--seconds", type=float, default=14.0, help="each live run")
    p.add_argument("--write", default="", help="also write the report to this file")
    args = p.parse_args()
    light_counts = [int(n) for n in args.lights.split(",") if n]
    renders = [tuple(int(x) for x in pair.split(":")) for pair in args.renders.split(",") if pair]
    live_counts = [tuple(float(x) for x in (k.split("/") + [""])[:2] if x) for k in
                   args.live.split(",") if k]
    render = os.path.join(os.path.abspath(args.build), "bench", "afr-render")

    lines = [f"# Light picking: {args.lights} lights, {args.size}", "",
             f"Command: `python3 bench/light_samples.py --lights {args.lights} --renders "
             f"{args.renders} --live '{args.live}' --views {args.views} --size {args.size} "
             f"--repeats {args.repeats} "
             f"--threads {args.threads} --seconds {args.seconds:g}`", "",
             f"afr-render on {args.threads} threads, each image against the ideal (16 spp, every "
             "light); median [min, max] of the repeats, the renders alternating.", ""]
    with tempfile.TemporaryDirectory() as tmp:
        for n in light_counts if renders else []:
            scene = os.path.join(tmp, f"lights{n}.gltf")
            run([sys.executable, os.path.join(ROOT, "bench", "many_lights_scene.py"), scene,
                 "--lights", str(n)])
            seconds = {r: [] for r in renders}
            images = {r: [] for r in renders}
            for rep in range(args.repeats):
                for k, spp in renders:
                    image = os.path.join(tmp, f"n{n}-k{k}-s{spp}-{rep}.png")
                    log = run([render, scene, "-s", args.size, "--spp", str(spp), "-j",
                               str(args.threads), "--light-samples", str(k), "--seed",
                               str(rep + 1), "-o", image])
                    seconds[(k, spp)].append(float(re.search(r"spp: ([0-9.]+) s,", log).group(1)))
                    images[(k, spp)].append(image)
            # One ideal image for all (afr-render --compare renders it once per size).
            every = [image for r in renders for image in images[r]]
            out = run([render, scene, "--compare"] + every + ["--log", "warn", "-j",
                                                              str(args.threads)])
            rms = dict(re.findall(r"^(\S+) t=\S+ scene_time=\S+ rms=([0-9.]+)$", out, re.M))
            base = max(statistics.median(seconds[renders[0]]), 1e-3)
            lines += [f"**{n} lights**", "",
                      f"| light samples | spp | render s | time / first row | RMS error (0-255) |",
                      "|---|---|---|---|---|"]
            for r in renders:
                errors = [float(rms[image]) for image in images[r]]
                lines.append(f"| {r[0] if r[0] else 'every light'} | {r[1]} | "
                             f"{spread(seconds[r], '{:.3f}')} | "
                             f"{statistics.median(seconds[r]) / base:.2f} | "
                             f"{spread(errors, '{:.2f}')} |")
            lines.append("")

        if live_counts:
            n = max(light_counts)
            lines += [f"The service on the scene of {n} lights (bench/live.py: 2 samplers of 1 "
                      f"thread, a headless display at 256x192, {args.seconds:g} s a run): the "
                      "mean RMS error of its images after the warm-up against the ideal, and the "
                      "samples/s the display took.", "",
                      "| view | light samples | store, samples a pixel | live RMS error | samples/s |",
                      "|---|---|---|---|---|"]
            for view in [v for v in args.views.split(",") if v]:
                scene = os.path.join(tmp, f"lights{n}-{view}.gltf")
                run([sys.executable, os.path.join(ROOT, "bench", "many_lights_scene.py"), scene,
                     "--lights", str(n)] + (["--moving"] if view == "moving" else []))
                live = {k: [] for k in live_counts}
                rate = {k: [] for k in live_counts}
                for rep in range(args.repeats):
                    for k in live_counts:
                        store = ([f"--display-args=--capacity {round(k[1] * 256 * 192)}"]
                                 if len(k) > 1 else [])
                        out = run([sys.executable, os.path.join(ROOT, "bench", "live.py"),
                                   "--build", args.build, "--scene", scene, "--size", "256x192",
                                   "--seconds", str(args.seconds), "--every", "60",
                                   f"--sampler-args=--light-samples {int(k[0])}"] + store)
                        row = next(line for line in out.splitlines()
                                   if re.match(r"\| \d+ \| ", line))
                        cells = [c.strip() for c in row.strip("|").split("|")]
                        live[k].append(float(cells[1]))
                        rate[k].append(float(cells[4].rstrip("K")) * 1e3)
                for k in live_counts:
                    lines.append(f"| {view} | {int(k[0]) if k[0] else 'every light'} | "
                                 f"{k[1] if len(k) > 1 else 4:g} | "
                                 f"{spread(live[k], '{:.2f}')} | "
                                 f"{spread([x / 1e3 for x in rate[k]], '{:.0f}K')} |")
    print("\n".join(lines))
    if args.write:
        with open(args.write, "w") as f:
            f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
