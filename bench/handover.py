#!/usr/bin/env python3
"""Region handover in the running service: dropped batches, gaps and recuts per minute.

Runs the README's main command (deploy/run-local.sh N, the built-in scene unless --scene) RUNS
times for SECONDS each and reads the display's log as bench/live.py does: after the warm-up,
the batches the samplers dropped, the gaps the display counted, and the recuts (region epochs)
it made, per minute, with the sample rate and refresh. Prints the runs and their medians.

  python3 bench/handover.py                              2 samplers, 3 runs of 63 s
  python3 bench/handover.py --runs 3 --seconds 63 --write bench/results/handover.md
"""
import argparse
import os
import statistics
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import live  # noqa: E402  (run_service, parse_log)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--build", default=os.path.join(live.ROOT, "build"))
    p.add_argument("--samplers", type=int, default=2)
    p.add_argument("--seconds", type=float, default=63.0)
    p.add_argument("--warmup", type=float, default=3.0, help="seconds left out at the start")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--scene", default="", help="glTF scene (default: the built-in scene)")
    p.add_argument("--size", default="256x256")
    p.add_argument("--preset", default="balanced")
    p.add_argument("--backend", default="auto")
    p.add_argument("--port", type=int, default=7750)
    p.add_argument("--display-args", default="")
    p.add_argument("--write", default="", help="also write the report to this file")
    args = p.parse_args()
    if args.seconds <= args.warmup + 2:
        sys.exit("handover.py: --seconds must exceed --warmup by more than 2")
    if args.scene:
        args.scene = os.path.abspath(args.scene)
    args.build = os.path.abspath(args.build)
    args.every = 0  # no images
    minutes = (args.seconds - args.warmup) / 60.0
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.runs):
            log = live.run_service(args, os.path.join(tmp, f"run{k}"))
            _, f = live.parse_log(log, args.warmup)
            rows.append({"dropped": f["dropped"] / minutes, "gaps": f["gaps"] / minutes,
                         "recuts": f["recuts"] / minutes, "rate": f["rate"], "hz": f["hz"]})
            print(f"run {k + 1}: {rows[-1]}", file=sys.stderr)
    scene = os.path.basename(args.scene) if args.scene else "built-in scene"
    cmd = (f"python3 bench/handover.py --samplers {args.samplers} --runs {args.runs} "
           f"--seconds {args.seconds:g} --warmup {args.warmup:g} --size {args.size}"
           + (f" --scene {os.path.relpath(args.scene, live.ROOT)}" if args.scene else "")
           + (f" --display-args '{args.display_args}'" if args.display_args else ""))
    lines = [f"# Region handover: {scene}, {args.size}, {args.samplers} sampler(s)", "",
             f"Command: `{cmd}`", "",
             f"Per minute after {args.warmup:g} s of warm-up, over {args.seconds - args.warmup:g} s"
             " a run.", "",
             "| run | dropped batches/min | gaps/min | recuts/min | samples/s | display Hz |",
             "|---|---|---|---|---|---|"]
    for k, r in enumerate(rows):
        lines.append(f"| {k + 1} | {r['dropped']:.1f} | {r['gaps']:.1f} | {r['recuts']:.1f} | "
                     f"{r['rate'] / 1e3:.0f}K | {r['hz']:.1f} |")
    med = {key: statistics.median(r[key] for r in rows) for key in rows[0]}
    lines.append(f"| median | {med['dropped']:.1f} | {med['gaps']:.1f} | {med['recuts']:.1f} | "
                 f"{med['rate'] / 1e3:.0f}K | {med['hz']:.1f} |")
    report = "\n".join(lines) + "\n"
    print(report)
    if args.write:
        with open(args.write, "w") as f:
            f.write(report)


if __name__ == "__main__":
    main()
