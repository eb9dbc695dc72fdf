#!/usr/bin/env python3
"""A sampler's memory and start-up time against its threads, on a large static scene.

Writes a glTF of one static height field of 2 x N x N triangles (default N = 1000: 2 million),
and with --textures K also K squares, each with a 4096 x 4096 PNG texture of its own; serves it
from a headless display_node on loopback, and joins one sampler_node with --threads T for each
T, one run after the other (--repeats times). For each run it reads the sampler's peak resident
memory (its rusage), the display's (its VmHWM), and, from the sampler's log, the seconds from
the scene loaded to sampling started (the tracers' BVH builds); it prints the medians per T. The
threads of a sampler share one build of the scene's geometry (Tracer::ShareGeometry,
docs/sampler.md, "Threads"), so neither should grow with T; the display keeps no textures
(GltfLoadOptions::textures, docs/service.md).

  python3 bench/pool_memory.py [--build build] [--grid 1000] [--textures 0] [--threads 1,2,4]
                               [--repeats 3] [--sampler PATH]   (another build's sampler_node)
"""
import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from nodes import free_port  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LINE_TIME = re.compile(r"^(\d\d):(\d\d):(\d\d)\.(\d\d\d) ")


def png_gradient(width, height, seed):
    """The bytes of a width x height RGB PNG of a horizontal pattern (compresses well)."""
    import struct
    import zlib
    row = bytes([0]) + bytes(((x * 7 + seed * 31) & 255) for x in range(width * 3))

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data +
                struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    return (b"\x89PNG\r\n\x1a\n" +
            chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(row * height, 1)) + chunk(b"IEND", b""))


def write_grid(folder, n, textures=0):
    """A static n x n height field (2 n^2 triangles), `textures` squares each with a 4096 x 4096
    texture of its own, and a camera above them, as glTF + .bin + .png."""
    import array
    import json
    import math
    positions = array.array("f")
    for j in range(n + 1):
        for i in range(n + 1):
            x, z = i / n * 10 - 5, j / n * 10 - 5
            positions.extend((x, 0.3 * math.sin(3 * x) * math.cos(2 * z), z))
    indices = array.array("I")
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            indices.extend((a, a + n + 1, a + 1, a + 1, a + n + 1, a + n + 2))
    pb, ib = positions.tobytes(), indices.tobytes()
    square = array.array("f", [0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0,    # positions
                               0, 0, 1, 0, 1, 1, 0, 1]).tobytes()       # texture coordinates
    square_indices = array.array("I", [0, 1, 2, 0, 2, 3]).tobytes()
    with open(os.path.join(folder, "grid.bin"), "wb") as f:
        f.write(pb + ib + (square + square_indices if textures > 0 else b""))
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(pb) + len(ib), "uri": "grid.bin"}],
        "bufferViews": [{"buffer": 0, "byteLength": len(pb)},
                        {"buffer": 0, "byteOffset": len(pb), "byteLength": len(ib)}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": (n + 1) ** 2,
                       "type": "VEC3", "min": [-5, -0.3, -5], "max": [5, 0.3, 5]},
                      {"bufferView": 1, "componentType": 5125, "count": len(indices),
                       "type": "SCALAR"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
        "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0, 4, 9],
                                "rotation": [-0.2, 0, 0, 0.98]}],
        "scenes": [{"nodes": [0, 1]}],
        "scene": 0,
    }
    if textures > 0:
        doc["buffers"][0]["byteLength"] += len(square) + len(square_indices)
        at = len(pb) + len(ib)
        doc["bufferViews"] += [{"buffer": 0, "byteOffset": at, "byteLength": 48},
                               {"buffer": 0, "byteOffset": at + 48, "byteLength": 32},
                               {"buffer": 0, "byteOffset": at + 80, "byteLength": 24}]
        doc["accessors"] += [{"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC3",
                              "min": [0, 0, 0], "max": [1, 1, 0]},
                             {"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC2"},
                             {"bufferView": 4, "componentType": 5125, "count": 6,
                              "type": "SCALAR"}]
        doc["images"], doc["textures"], doc["materials"] = [], [], []
        for k in range(textures):
            with open(os.path.join(folder, f"texture{k}.png"), "wb") as f:
                f.write(png_gradient(4096, 4096, k))
            doc["images"].append({"uri": f"texture{k}.png"})
            doc["textures"].append({"source": k})
            doc["materials"].append({"pbrMetallicRoughness": {"baseColorTexture": {"index": k}}})
            doc["meshes"].append({"primitives": [{"attributes": {"POSITION": 2, "TEXCOORD_0": 3},
                                                  "indices": 4, "material": k}]})
            doc["nodes"].append({"mesh": len(doc["meshes"]) - 1,
                                 "translation": [1.2 * k - 2, 0.5, 0]})
            doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
    path = os.path.join(folder, "grid.gltf")
    with open(path, "w") as f:
        json.dump(doc, f)
    return path


def seconds_of(line):
    m = LINE_TIME.match(line)
    return int(m[1]) * 3600 + int(m[2]) * 60 + int(m[3]) + int(m[4]) / 1000 if m else None


def peak_mb(pid):
    """A running process's peak resident memory (VmHWM), MB."""
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def one_run(args, scene, threads, folder):
    """(sampler's peak resident MB, display's, seconds from scene loaded to sampling)."""
    port = free_port()
    bind = f"tcp://127.0.0.1:{port}"
    display = subprocess.Popen(
        [os.path.join(args.build, "display_node/display_node"), scene, "--headless",
         "--bind", bind, "--size", "256x256", "--seconds", "600",
         "--output", os.path.join(folder, "display")],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(1.0)
        sampler = subprocess.Popen(
            [args.sampler or os.path.join(args.build, "sampler_node/sampler_node"), "--display", bind,
             "--threads", str(threads), "--cache", os.path.join(folder, "cache")],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        loaded = started = None
        deadline = time.time() + args.timeout
        for line in sampler.stdout:
            if "animation (loaded in" in line:
                loaded = seconds_of(line)
            elif "sampling region" in line:
                started = seconds_of(line)
                break
            if time.time() > deadline:
                break
        time.sleep(1.0)  # a second of sampling
        sampler.terminate()
        sampler.communicate(timeout=30)
        # The largest of the children waited for: the sampler alone (the display is waited for
        # below, and each run is a process of its own).
        peak_kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        if loaded is None or started is None:
            sys.exit(f"pool_memory.py: the sampler with {threads} threads did not start sampling")
        return peak_kb / 1024.0, peak_mb(display.pid), started - loaded
    finally:
        display.terminate()
        display.wait(timeout=30)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--grid", type=int, default=1000, help="N: 2 N^2 triangles")
    ap.add_argument("--textures", type=int, default=0,
                    help="K squares with a 4096 x 4096 texture each")
    ap.add_argument("--threads", default="1,2,4")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--sampler", default="",
                    help="another sampler_node to run (say, an earlier commit's build)")
    args = ap.parse_args()
    threads = [int(t) for t in args.threads.split(",")]
    with tempfile.TemporaryDirectory() as folder:
        scene = write_grid(folder, args.grid, args.textures)
        results = {t: [] for t in threads}
        for r in range(args.repeats):
            for t in threads:
                # Each run in its own process tree, so that ru_maxrss is this run's sampler.
                out = subprocess.run(
                    [sys.executable, __file__, "--one", str(t), scene, args.build, folder,
                     str(args.timeout), args.sampler], capture_output=True, text=True)
                if out.returncode != 0:
                    sys.exit(out.stdout + out.stderr)
                results[t].append(tuple(map(float, out.stdout.split())))
        textured = f", {args.textures} 4096 x 4096 textures" if args.textures else ""
        print(f"{2 * args.grid ** 2} static triangles{textured}, {args.repeats} runs per row, "
              "medians")
        print("| sampler threads | sampler's peak resident MB | display's | "
              "scene loaded to sampling, s |")
        print("|---|---|---|---|")
        for t in threads:
            sampler, display, s = (statistics.median(x[k] for x in results[t]) for k in range(3))
            print(f"| {t} | {sampler:.0f} | {display:.0f} | {s:.2f} |")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--one":
        t, scene, build, folder, timeout, sampler = sys.argv[2:8]
        ns = argparse.Namespace(build=build, timeout=float(timeout), sampler=sampler)
        print(*one_run(ns, scene, int(t), folder))
    else:
        main()
