#!/usr/bin/env python3
"""Liveness figures of the running service (docs/service.md, "Liveness"): how soon a dead node
is noticed, whether a stopped one is wrongly dropped, and how soon samplers are back after a
display restart. Runs display_node and sampler_node as built (use a Release build) on loopback:

  kill -9 of a sampler       seconds from the kill to the display's "lost" log line
  kill -9 of a wall node     seconds from the kill to the lead's "lost" log line (2 x 1 wall)
  SIGSTOP of a sampler       for 0.2 ... 1.2 s, then SIGCONT: in how many trials it was dropped
  display restart            seconds from the new display's bind (its "display session" line)
                             to the second sampler's join, and to its region (a join waits for
                             its cut up to the display's --join-interval)

Each figure is the median (and range) over --trials runs. With --load N, N busy processes run
beside the nodes throughout (a loaded machine). With --write, the table also goes to
bench/results/liveness.md (liveness-loadN.md with --load N) with the command and commit.

  python3 bench/liveness.py [--build build] [--trials 5] [--load 0] [--write]
"""
import argparse
import datetime
import os
import random
import re
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from nodes import free_port  # noqa: E402


def time_of_day():
    now = datetime.datetime.now()
    return now.hour * 3600 + now.minute * 60 + now.second + now.microsecond / 1e6


LINE_TIME = re.compile(r"^(\d\d):(\d\d):(\d\d)\.(\d\d\d) ")


def log_time(path, needle, nth=1):
    """Time of day of the nth line of the log holding `needle`, or None."""
    seen = 0
    with open(path, errors="replace") as f:
        for line in f:
            if needle in line:
                seen += 1
                if seen == nth:
                    m = LINE_TIME.match(line)
                    if m:
                        h, mi, s, ms = (int(g) for g in m.groups())
                        return h * 3600 + mi * 60 + s + ms / 1000
    return None


def wait_for(path, needle, timeout, nth=1):
    end = time.time() + timeout
    while time.time() < end:
        if log_time(path, needle, nth) is not None:
            return True
        time.sleep(0.01)
    return False


class Nodes:
    """Processes of one trial, each logging to a file in `folder`; all killed at the end."""

    def __init__(self, build, folder):
        self.build, self.folder, self.procs = build, folder, []

    def start(self, name, argv):
        log = os.path.join(self.folder, name + ".log")
        p = subprocess.Popen(argv, stdout=open(log, "w"), stderr=subprocess.STDOUT)
        self.procs.append(p)
        return p, log

    def display(self, name, port, extra=()):
        return self.start(name, [os.path.join(self.build, "display_node/display_node"),
                                 "--headless", "--bind", f"tcp://127.0.0.1:{port}",
                                 "--metrics-port", "0", "--backend", "cpu", "--output", "",
                                 "--size", "64x64", "--fps", "20", *extra])

    def sampler(self, name, port):
        return self.start(name, [os.path.join(self.build, "sampler_node/sampler_node"),
                                 "--display", f"tcp://127.0.0.1:{port}",
                                 "--cache", os.path.join(self.folder, "cache"),
                                 "--max-samples-per-second", "50000"])

    def close(self):
        for p in self.procs:
            if p.poll() is None:
                p.kill()
                p.wait()


def trial_kill_sampler(nodes, port):
    _, dlog = nodes.display("display", port)
    nodes.sampler("s1", port)
    s2, _ = nodes.sampler("s2", port)
    if not wait_for(dlog, " joined: ", 10, nth=2):
        return None
    time.sleep(1.0 + random.random() * 0.2)  # a history, and a kill at any phase of a heartbeat
    s2.kill()
    killed = time_of_day()
    if not wait_for(dlog, "lost: no word for", 10):
        return None
    return log_time(dlog, "lost: no word for") - killed


def trial_kill_wall_node(nodes, port):
    _, llog = nodes.display("lead", port, ["--wall", "2x1"])
    time.sleep(0.3)
    follower, _ = nodes.start("follower", [
        os.path.join(nodes.build, "display_node/display_node"), "--headless", "--follow",
        f"tcp://127.0.0.1:{port}", "--cell", "1,0", "--bind", f"tcp://127.0.0.1:{free_port()}",
        "--metrics-port", "0", "--backend", "cpu", "--output", "", "--fps", "20"])
    if not wait_for(llog, "joined the wall", 10):
        return None
    time.sleep(1.0 + random.random() * 0.2)
    follower.kill()
    killed = time_of_day()
    if not wait_for(llog, "lost: no word for", 10):
        return None
    return log_time(llog, "lost: no word for") - killed


def trial_stop_sampler(nodes, port, seconds):
    _, dlog = nodes.display("display", port)
    s1, _ = nodes.sampler("s1", port)
    nodes.sampler("s2", port)
    if not wait_for(dlog, " joined: ", 10, nth=2):
        return None
    time.sleep(1.0 + random.random() * 0.2)
    s1.send_signal(19)  # SIGSTOP
    time.sleep(seconds)
    s1.send_signal(18)  # SIGCONT
    time.sleep(1.0)
    return 1.0 if log_time(dlog, "lost: no word for") is not None else 0.0


def second_joined(log):
    """The id of the second sampler that joined the display whose log this is."""
    return re.findall(r"sampler (\d+) joined: ", open(log, errors="replace").read())[1]


def restart(nodes, port):
    """A display with two samplers, killed and started again: the new display's log, once both
    samplers have joined it and each has a region (None when they did not within 10 s)."""
    d, dlog = nodes.display("display1", port)
    nodes.sampler("s1", port)
    nodes.sampler("s2", port)
    if not wait_for(dlog, " joined: ", 10, nth=2):
        return None
    time.sleep(1.5)
    d.kill()
    d.wait()
    _, d2log = nodes.display("display2", port)
    if not wait_for(d2log, " joined: ", 10, nth=2):
        return None
    second = second_joined(d2log)
    if not wait_for(d2log, f"sampler {second} (", 10):  # its region line
        return None
    return d2log


def trial_restart_join(nodes, port):
    d2log = restart(nodes, port)
    if d2log is None:
        return None
    return log_time(d2log, " joined: ", 2) - log_time(d2log, "display session")


def trial_restart_region(nodes, port):
    d2log = restart(nodes, port)
    if d2log is None:
        return None
    return log_time(d2log, f"sampler {second_joined(d2log)} (") - log_time(d2log, "display session")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default="build")
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--load", type=int, default=0, help="busy processes beside the nodes")
    ap.add_argument("--write", action="store_true", help="also write bench/results/liveness.md")
    a = ap.parse_args()
    if a.trials < 1 or a.load < 0:
        sys.exit("liveness.py: --trials must be >= 1 and --load >= 0")

    burners = [subprocess.Popen(["/bin/sh", "-c", "while :; do :; done"]) for _ in range(a.load)]
    rows = []

    def run(label, fn, *args, kind="seconds"):
        values, failed = [], 0
        for _ in range(a.trials):
            with tempfile.TemporaryDirectory(prefix="afr-liveness-") as folder:
                nodes = Nodes(a.build, folder)
                try:
                    v = fn(nodes, free_port(), *args)
                finally:
                    nodes.close()
            if v is None:
                failed += 1
            else:
                values.append(v)
        if kind == "seconds" and values:
            cell = (f"{statistics.median(values):.3f} s ({min(values):.3f} - {max(values):.3f})")
        elif values:
            cell = f"dropped in {int(sum(values))} of {len(values)}"
        else:
            cell = "no result"
        if failed:
            cell += f", {failed} trial(s) did not complete"
        rows.append((label, cell))
        print(f"| {label} | {cell} |", flush=True)

    try:
        print(f"| event ({a.trials} trials, {a.load} busy processes beside) | median (range) |")
        print("|---|---|")
        run("kill -9 of a sampler: display's loss line", trial_kill_sampler)
        run("kill -9 of a wall node: lead's loss line", trial_kill_wall_node)
        for s in (0.2, 0.4, 0.6, 0.8, 1.2):
            run(f"sampler stopped {s:.1f} s (SIGSTOP/SIGCONT)", trial_stop_sampler, s,
                kind="count")
        run("display restart: bind to both samplers joined", trial_restart_join)
        run("display restart: bind to both samplers with a region", trial_restart_region)
    finally:
        for b in burners:
            b.kill()

    if a.write:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True).stdout.strip()
        name = "liveness.md" if a.load == 0 else f"liveness-load{a.load}.md"
        path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", name)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "w") as f:
            f.write("# Liveness of the running service\n\n")
            f.write(f"Generated by `python3 bench/liveness.py --trials {a.trials} --load {a.load}"
                    f" --write` at commit {commit}, {datetime.date.today()}, on "
                    f"{os.cpu_count()} cores. Release build.\n\n")
            f.write(f"| event ({a.trials} trials, {a.load} busy processes beside) | "
                    "median (range) |\n|---|---|\n")
            for label, cell in rows:
                f.write(f"| {label} | {cell} |\n")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
