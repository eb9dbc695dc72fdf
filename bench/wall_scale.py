#!/usr/bin/env python3
"""Display-wall scale measurements (docs/wall.md): runs a lead display_node, its followers and
sampler_nodes on loopback for each configuration, and prints per display node: the virtual
display and its cell, samples/s and bytes/s received, the store's capacity N, reconstruction
time, resident memory (VmRSS at half time and at the end, peak VmHWM) and the memory model's
prediction (180 MiB + 160 B per stored sample + 86 B per computed pixel, docs/wall.md); per
sampler node its resident memory, and in all the samples/s the samplers report. With two or
more configurations that differ in size it also prints the samplers' memory per pixel of the
image (they own it all between them): the slope of their summed peak RSS between the sizes.

  python3 bench/wall_scale.py [--build build] [--seconds 12] [--samplers 2] [--cap 100000]
                              [--configs 1024:2x2,4096:1x1,4096:2x2,8192:2x2] [--preset fast]
                              [--fps 1] [--capacity N] [--sampler-args '--b 1 --fill-step 16']

Each configuration is SIZE:GRID (a square virtual display of SIZE pixels a side, GRID cells).
The samplers are capped so every configuration gets the same sample stream rate.

The 8192 x 8192 wall over 4 display nodes (docs/wall.md, "8192^2"):

  python3 bench/wall_scale.py --wall-8192

Samplers' bytes per region pixel (docs/wall.md; add --sampler-args '--b 1 --fill-step 16' for
b = 1):

  python3 bench/wall_scale.py --configs 1024:1x1,2048:1x1 --samplers 1 --capacity 100000
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from nodes import free_port  # noqa: E402


def stats(port):
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/stats", timeout=2) as r:
            return json.loads(r.read())
    except Exception:
        return None


def status_kib(pid, field):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except OSError:
        pass
    return 0


def hwm_kib(pid):
    return status_kib(pid, "VmHWM")


def rss_kib(pid):
    return status_kib(pid, "VmRSS")


def model_mib(n, cell, size, margin):
    """docs/wall.md's fit: 180 MiB + 160 B per stored sample + 100 B per computed pixel (the
    cell plus the margin, inside the virtual display)."""
    x0, y0, x1, y1 = cell
    w = min(size, x1 + margin) - max(0, x0 - margin)
    h = min(size, y1 + margin) - max(0, y0 - margin)
    return 180 + (160 * n + 100 * w * h) / 2**20


def run(cfg, a, tmp):
    size, grid = cfg.split(":")
    size = int(size)
    cols, rows = (int(v) for v in grid.split("x"))
    disp = os.path.join(a.build, "display_node", "display_node")
    samp = os.path.join(a.build, "sampler_node", "sampler_node")
    lead_port = free_port()
    lead = f"tcp://127.0.0.1:{lead_port}"
    # Few frames: on a 2-core machine four CPU reconstructors at full rate would starve the
    # samplers and the ingest threads that are measured here.
    common = ["--headless", "--backend", "cpu", "--fps", str(a.fps), "--stats-interval", "1",
              "--output", "", "--capacity", str(a.capacity)]
    procs = []  # (name, Popen, metrics port)
    log = open(os.path.join(a.logs or tmp, "log.txt"), "a")
    procs.append(("0,0", subprocess.Popen(
        [disp, "--bind", lead, "--size", f"{size}x{size}", "--wall", grid, "--preset", a.preset,
         "--metrics-port", str(lead_port + 3), "--member-timeout", str(a.member_timeout)] + common,
        stdout=log, stderr=log), lead_port + 3))
    time.sleep(0.5)
    for r in range(rows):
        for c in range(cols):
            if (c, r) == (0, 0):
                continue
            p = free_port()
            procs.append((f"{c},{r}", subprocess.Popen(
                [disp, "--follow", lead, "--cell", f"{c},{r}", "--bind", f"tcp://127.0.0.1:{p}",
                 "--metrics-port", str(p + 3)] + common, stdout=log, stderr=log), p + 3))
    samplers = [subprocess.Popen(
        [samp, "--display", lead, "--cache", os.path.join(tmp, "cache"),
         "--max-samples-per-second", str(a.cap)] + a.sampler_args.split(), stdout=log, stderr=log)
        for _ in range(a.samplers)]
    # Received samples and bytes over the second half of the run, from the counters.
    def totals():
        out = {}
        for name, _, port in procs:
            s = stats(port)
            if s is not None:
                out[name] = (sum(m["samples"] for m in s["samplers"]),
                             sum(m["bytes"] for m in s["samplers"]), time.monotonic(), s)
        return out
    time.sleep(a.seconds / 2)
    first = totals()
    half_rss = {p.pid: rss_kib(p.pid) for _, p, _ in procs}
    half_rss.update({p.pid: rss_kib(p.pid) for p in samplers})
    time.sleep(a.seconds / 2)
    last = totals()
    rows_out = []
    for name, p, port in procs:
        rss = (half_rss[p.pid], rss_kib(p.pid))
        if name not in first or name not in last:
            gone = f" (exited {p.returncode})" if p.poll() is not None else " (no stats)"
            rows_out.append((cfg, name + gone, None, hwm_kib(p.pid), rss, 0, 0, (0, 0, 0)))
            continue
        dt = last[name][2] - first[name][2]
        # What the node exchanged with its peers (coverage and strays, docs/wall.md "Seams").
        x0 = first[name][3]["display"]["wall"].get("exchange", {})
        x1 = last[name][3]["display"]["wall"].get("exchange", {})
        exchange = ((x1.get("bytes_out", 0) - x0.get("bytes_out", 0)) / dt,
                    (x1.get("strays_in", 0) - x0.get("strays_in", 0)) / dt,
                    x1.get("dropped_out", 0))
        rows_out.append((cfg, name, last[name][3], hwm_kib(p.pid), rss,
                         (last[name][0] - first[name][0]) / dt,
                         (last[name][1] - first[name][1]) / dt, exchange))
    # What the samplers say they trace, summed (from the lead, which hears every sampler).
    lead_stats = last.get("0,0", (0, 0, 0, None))[3]
    traced = sum(m["reported_samples_per_second"] for m in lead_stats["samplers"]) \
        if lead_stats else 0
    for i, p in enumerate(samplers):
        rows_out.append((cfg, f"sampler {i + 1}", None, hwm_kib(p.pid),
                         (half_rss[p.pid], rss_kib(p.pid)), traced, 0, (0, 0, 0)))
        p.terminate()
    for _, p, _ in procs:
        p.terminate()
    for p in samplers + [p for _, p, _ in procs]:
        try:
            p.wait(20)
        except subprocess.TimeoutExpired:
            p.kill()
    return rows_out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default="build")
    ap.add_argument("--seconds", type=float, default=None, help="run time per configuration "
                    "(12 s; 60 s with --wall-8192), measured over its second half")
    ap.add_argument("--samplers", type=int, default=2)
    ap.add_argument("--cap", type=int, default=100000)
    ap.add_argument("--preset", default="fast")
    ap.add_argument("--fps", type=float, default=1.0)
    ap.add_argument("--capacity", type=int, default=0,
                    help="samples each display node keeps (0: the preset's)")
    ap.add_argument("--sampler-args", default="",
                    help="extra sampler_node flags, e.g. '--b 1 --fill-step 8' for large images")
    ap.add_argument("--configs", default="1024:2x2,4096:1x1,4096:2x2,8192:2x2")
    ap.add_argument("--member-timeout", type=float, default=0.5,
                    help="seconds without a word before the lead drops a sampler")
    ap.add_argument("--logs", default="",
                    help="a folder to keep the nodes' log in (log.txt), instead of a temporary one")
    ap.add_argument("--model-margin", type=int, default=99,
                    help="the wall's margin for the memory model (99 px: the presets' splats)")
    ap.add_argument("--wall-8192", action="store_true",
                    help="the 8192 x 8192 wall of docs/wall.md: 4 display nodes (2x2, "
                    "N = 10^6 each, a frame every 5 s, members dropped after 60 s), 2 uncapped samplers "
                    "at b = 1, 60 s")
    a = ap.parse_args()
    if a.wall_8192:
        # A CPU reconstruction of a 4195^2 node takes seconds: four of them at 1 Hz would
        # leave the samplers nothing on this machine.
        a.configs, a.samplers, a.capacity = "8192:2x2", 2, 1000000
        a.seconds = a.seconds or 60.0
        a.sampler_args = a.sampler_args or "--b 1 --fill-step 16 --display-timeout 60"
        a.cap, a.fps = 0, 0.2
        # On this loaded 2-core machine nodes go unheard for seconds while four CPU
        # reconstructions of 4195^2 pixels run (10-20 s each): with the default 0.5 s, or even
        # 5 s, the lead drops samplers and display nodes, the samplers give up on the lead
        # (1.5 s) and join again, and every recut rebuilds the samplers.
        a.member_timeout = max(a.member_timeout, 60.0)
    a.seconds = a.seconds or 12.0
    print("| virtual display | grid | node (cell) | cell px | N (samples kept) | samples/s in | "
          "MB/s in | exchange MB/s out | strays/s in | exchange dropped | reconstruct ms | "
          "RSS MiB half / end | peak RSS MiB | model MiB |")
    print("|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    samplers_by_size = {}
    with tempfile.TemporaryDirectory() as tmp:
        for cfg in a.configs.split(","):
            for c, name, s, hwm, rss, sps, bps, (xbps, strays, dropped) in run(cfg, a, tmp):
                size, grid = c.split(":")
                rss_text = f"{rss[0] / 1024:.0f} / {rss[1] / 1024:.0f}"
                if s is None:
                    if name.startswith("sampler"):
                        samplers_by_size.setdefault(int(size), []).append(hwm * 1024)
                        print(f"| {size}^2 | {grid} | {name} | - | - | {sps / 1e3:.0f} k traced "
                              f"by all | - | - | - | - | - | {rss_text} | {hwm / 1024:.0f} | - |",
                              flush=True)
                    else:
                        print(f"| {size}^2 | {grid} | {name} | - | - | - | - | - | - | - | - | "
                              f"{rss_text} | {hwm / 1024:.0f} | - |", flush=True)
                    continue
                d = s["display"]
                cell = d["wall"]["cell"]
                # A follower reports no capacity of its own: it stores what --capacity says.
                n = d["store_capacity"] or a.capacity
                model = model_mib(n, cell, int(size), a.model_margin)
                print(f"| {size}^2 | {grid} | {name} | {cell[2] - cell[0]}x{cell[3] - cell[1]} | "
                      f"{d['store_capacity']} | {sps / 1e3:.0f} k | {bps / 1e6:.1f} | "
                      f"{xbps / 1e6:.2f} | {strays / 1e3:.1f} k | {dropped} | "
                      f"{d['reconstruct_ms_mean']:.0f} | {rss_text} | {hwm / 1024:.0f} | "
                      f"{model:.0f} |", flush=True)
    sizes = sorted(samplers_by_size)
    if len(sizes) >= 2:
        lo, hi = sizes[0], sizes[-1]
        slope = (sum(samplers_by_size[hi]) - sum(samplers_by_size[lo])) / (hi * hi - lo * lo)
        print(f"\nsamplers: {slope:.0f} B per pixel of the image (slope of their summed peak RSS "
              f"between {lo}^2 and {hi}^2)")

if __name__ == "__main__":
    sys.exit(main())
