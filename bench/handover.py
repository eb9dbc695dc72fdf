#!/usr/bin/env python3
"""Region handover in the running service: dropped batches, gaps and recuts per minute.

Runs the README's main command (deploy/run-local.sh N, the built-in scene unless --scene) RUNS
times for SECONDS each and reads the display's log as bench/live.py does: after the warm-up,
the batches the samplers dropped, the gaps the display counted, and the recuts (region epochs)
it made, per minute, with the sample rate and refresh. Prints the runs and their medians.

  python3 bench/handover.py                              2 samplers, 3 runs of 63 s
  python3 bench/handover.py --runs 3 --seconds 63 --write bench/results/handover.md
  python3 bench/handover.py --worker-priority nice --worker-priority idle    both, alternating
"""
import argparse
import os
import statistics
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import live  # noqa: E402  (add_service_arguments, run_service, parse_log)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--build", default=os.path.join(live.ROOT, "build"))
    p.add_argument("--samplers", type=int, default=2)
    p.add_argument("--seconds", type=float, default=63.0)
    p.add_argument("--warmup", type=float, default=3.0, help="seconds left out at the start")
    p.add_argument("--runs", type=int, default=3)
    live.add_service_arguments(p, 7750)
    p.add_argument("--display-args", default="")
    p.add_argument("--worker-priority", action="append", default=[],
                   help="the samplers' tracing threads: idle, nice or normal (repeat to compare: "
                        "the runs alternate)")
    p.add_argument("--write", default="", help="also write the report to this file")
    args = p.parse_args()
    if args.seconds <= args.warmup + 2:
        sys.exit("handover.py: --seconds must exceed --warmup by more than 2")
    if args.scene:
        args.scene = os.path.abspath(args.scene)
    args.build = os.path.abspath(args.build)
    args.every = 0  # no images
    minutes = (args.seconds - args.warmup) / 60.0
    priorities = args.worker_priority or ["nice"]
    rows = {pr: [] for pr in priorities}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.runs):
            for pr in priorities:
                args.worker_priority = pr
                log = live.run_service(args, os.path.join(tmp, f"run{k}-{pr}"))
                _, f = live.parse_log(log, args.warmup)
                rows[pr].append({"dropped": f["dropped"] / minutes, "gaps": f["gaps"] / minutes,
                                 "recuts": f["recuts"] / minutes, "rate": f["rate"],
                                 "hz": f["hz"], "recon": f["reconstruct_ms"]})
                print(f"{pr} run {k + 1}: {rows[pr][-1]}", file=sys.stderr)
    scene = os.path.basename(args.scene) if args.scene else "built-in scene"
    cmd = (f"python3 bench/handover.py --samplers {args.samplers} --runs {args.runs} "
           f"--seconds {args.seconds:g} --warmup {args.warmup:g} --size {args.size}"
           + "".join(f" --worker-priority {pr}" for pr in args_priorities(priorities))
           + (f" --scene {os.path.relpath(args.scene, live.ROOT)}" if args.scene else "")
           + (f" --display-args '{args.display_args}'" if args.display_args else ""))
    lines = [f"# Region handover: {scene}, {args.size}, {args.samplers} sampler(s)", "",
             f"Command: `{cmd}`", "",
             f"Per minute after {args.warmup:g} s of warm-up, over {args.seconds - args.warmup:g} s"
             " a run; the samplers' tracing threads at each --worker-priority of run-local.sh "
             "(idle: SCHED_IDLE, nice: nice 10), runs alternating.", "",
             "| priority | run | dropped batches/min | gaps/min | recuts/min | samples/s | "
             "display Hz | reconstruct ms |",
             "|---|---|---|---|---|---|---|---|"]
    for pr in priorities:
        for k, r in enumerate(rows[pr]):
            lines.append(f"| {pr} | {k + 1} | {r['dropped']:.1f} | {r['gaps']:.1f} | "
                         f"{r['recuts']:.1f} | {r['rate'] / 1e3:.0f}K | {r['hz']:.1f} | "
                         f"{r['recon']:.1f} |")
        med = {key: statistics.median(r[key] for r in rows[pr]) for key in rows[pr][0]}
        lines.append(f"| {pr} | median | {med['dropped']:.1f} | {med['gaps']:.1f} | "
                     f"{med['recuts']:.1f} | {med['rate'] / 1e3:.0f}K | {med['hz']:.1f} | "
                     f"{med['recon']:.1f} |")
    live.publish(lines, args.write)


def args_priorities(priorities):
    """The --worker-priority flags worth writing: none for the default alone."""
    return [] if priorities == ["nice"] else priorities


if __name__ == "__main__":
    main()
