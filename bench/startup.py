#!/usr/bin/env python3
"""The display's first seconds: how long its slowest images take while the store fills.

Runs the README's main command (deploy/run-local.sh N, the built-in scene unless --scene) RUNS
times per build for SECONDS each, with a stats line every 0.25 s, and reads from the display's
log, over the first SPAN seconds: the slowest image (the largest reconstruction p99 of a stats
interval: a quarter second holds few images, so that is its slowest), the images shown, and the
time until the refresh first reaches 80% of its median over the rest of the run. With several
--build folders the runs alternate between them (build 1, build 2, build 1, ...), so that a
loaded machine weighs on each alike; each build's medians are printed side by side.

  python3 bench/startup.py                                     this build, 5 runs
  python3 bench/startup.py --build build-before --build build --write bench/results/startup.md

A build folder configured from another worktree (git worktree add ../afr-before COMMIT; cmake
-S ../afr-before -B build-before -G Ninja -DCMAKE_BUILD_TYPE=Release) runs that commit's nodes.
"""
import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import live  # noqa: E402  (add_service_arguments, run_service, ROOT)

STATS = re.compile(r"info t=([0-9.]+)s \d+ sampler\(s\) \| display ([0-9.]+) Hz.*?"
                   r"reconstruct mean ([0-9.]+) ms p99 ([0-9.]+) ms")
INTERVAL = 0.25


def startup_figures(log, span):
    """(slowest image ms, images shown, seconds to steady refresh) over the first span s."""
    lines = []
    for line in log.splitlines():
        m = STATS.search(line)
        if m and "stopping" not in line:
            lines.append((float(m.group(1)), float(m.group(2)), float(m.group(4))))
    early = [x for x in lines if x[0] <= span + 1e-6]
    late = [x for x in lines if x[0] > span]
    if not early or not late:
        sys.exit("startup.py: too few stats lines (a longer --seconds?)")
    slowest = max(p99 for _, _, p99 in early)
    # Each line's rate is over the time since the line before it.
    shown, before = 0.0, 0.0
    for t, hz, _ in early:
        shown += hz * (t - before)
        before = t
    steady = statistics.median(hz for _, hz, _ in late)
    reached = next((t for t, hz, _ in lines if hz >= 0.8 * steady), float("nan"))
    return slowest, shown, reached


def describe(build):
    """The commit a build folder was configured from, as git describes its source tree."""
    try:
        with open(os.path.join(build, "CMakeCache.txt")) as f:
            src = next(line.split("=", 1)[1].strip() for line in f
                       if line.startswith("CMAKE_HOME_DIRECTORY"))
        rev = subprocess.run(["git", "-C", src, "describe", "--always", "--dirty"],
                             stdout=subprocess.PIPE, text=True, check=True).stdout.strip()
        return rev
    except (OSError, StopIteration, subprocess.CalledProcessError):
        return "?"


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--build", action="append", default=[],
                   help="build folder (repeat to compare; default: build)")
    p.add_argument("--samplers", type=int, default=2)
    p.add_argument("--seconds", type=float, default=6.0)
    p.add_argument("--span", type=float, default=3.0, help="the first seconds judged")
    p.add_argument("--runs", type=int, default=5, help="runs per build")
    live.add_service_arguments(p, 7850)
    p.add_argument("--write", default="", help="also write the report to this file")
    args = p.parse_args()
    if args.seconds < args.span + 2:
        sys.exit("startup.py: --seconds must exceed --span by 2 or more")
    builds = [os.path.abspath(b) for b in (args.build or [os.path.join(live.ROOT, "build")])]
    if args.scene:
        args.scene = os.path.abspath(args.scene)
    args.every = 0
    args.display_args = f"--stats-interval {INTERVAL}"
    results = {b: [] for b in builds}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.runs):
            for i, b in enumerate(builds):
                args.build = b
                log = live.run_service(args, os.path.join(tmp, f"run{k}-{i}"))
                results[b].append(startup_figures(log, args.span))
                print(f"{os.path.basename(b)} run {k + 1}: {results[b][-1]}", file=sys.stderr)
    scene = os.path.basename(args.scene) if args.scene else "built-in scene"
    cmd = (f"python3 bench/startup.py --runs {args.runs} --samplers {args.samplers} "
           f"--seconds {args.seconds:g} --span {args.span:g} --size {args.size}"
           + "".join(f" --build {os.path.relpath(b, live.ROOT)}" for b in builds)
           + (f" --scene {os.path.relpath(args.scene, live.ROOT)}" if args.scene else ""))
    lines = [f"# The display's first {args.span:g} s: {scene}, {args.size}, "
             f"{args.samplers} sampler(s)", "", f"Command: `{cmd}`", "",
             f"Runs alternate between the builds; each cell is the median of {args.runs} runs "
             "(lowest-highest). Slowest image: the largest reconstruction p99 of a 0.25 s stats "
             "interval; steady: the first stats line whose refresh reaches 80% of the median "
             "refresh after the span.", "",
             "| build (commit) | slowest image ms | images shown | s to steady refresh |",
             "|---|---|---|---|"]
    for b in builds:
        cols = list(zip(*results[b]))
        cells = [f"{statistics.median(c):.{d}f} ({min(c):.{d}f}-{max(c):.{d}f})"
                 for c, d in zip(cols, (0, 0, 2))]
        lines.append(f"| {os.path.relpath(b, live.ROOT)} ({describe(b)}) | " + " | ".join(cells)
                     + " |")
    live.publish(lines, args.write)


if __name__ == "__main__":
    main()
