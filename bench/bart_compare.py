#!/usr/bin/env python3
"""afr's renders of BART frames beside BART's own images (docs/aff2gltf.md, "Compared with
BART's own images"). For each case of CASES: convert the AFF scene with aff2gltf (once, into
--out), render the reference's frame with afr-render at the reference's size (times --scale),
and report the RMS difference (0-255 over the sRGB codes of R, G and B, afr-eval's metric), the
mean difference per channel, the mean absolute difference in a 4 x 4 grid of the image, and the
RMS of the two neighbouring frames (a check of which frame the reference shows). Writes
BART | afr | |difference| x 4 side by side as a PNG and the figures as markdown.

  python3 bench/bart_compare.py [--build build] [--out out/bart-compare] [--spp 16]
                                [--scale 1] [--scenes ../shared/scenes] [--write-results]

Needs the built aff2gltf and afr-render, OpenImageIO's oiiotool, and BART's scenes (read only,
never copied into the repository). Images travel as binary PPM between oiiotool and this script,
so only the standard library is needed.
"""
import argparse
import datetime
import os
import shlex
import shutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# One row per BART reference image. `aff` and `reference` are relative to --scenes. `number` is
# the frame number in the image's name; BART numbers its images from 1, so the frame index k of
# `a START END NFRAMES` is number - 1 (the RMS of the neighbours, reported with each case, shows
# it). The animation range and the resolution are read from the root AFF file.
CASES = [
    {
        "name": "bart-robots-457",
        "aff": "bart-robots/aff/Robot.aff",
        "reference": "bart-robots/results/Robot457.jpg",
        "number": 457,
    },
]

GRID = 4  # cells per side of the grid of mean absolute differences
DIFF_GAIN = 2  # amplification of |afr - BART| in the picture


class Missing(Exception):
    pass


def run(cmd, log):
    log.append(cmd)
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"bart_compare: {shlex.join(cmd)} failed ({done.returncode}):\n"
                 f"{done.stdout}{done.stderr}")
    return done.stdout + done.stderr


# ---- AFF header ----

def aff_header(path):
    """(start, end, frames) of `a` and (width, height) of `resolution` in the root AFF file."""
    animation = resolution = None
    with open(path, encoding="latin-1") as f:
        for line in f:
            words = line.split()
            if not words or words[0][0] in "#%":
                continue
            if words[0] == "a" and len(words) >= 4:
                animation = (float(words[1]), float(words[2]), int(words[3]))
            elif words[0] == "resolution" and len(words) >= 3:
                resolution = (int(words[1]), int(words[2]))
    if animation is None or resolution is None:
        raise Missing(f"{path}: no `a` line or no `resolution` in the root file")
    return animation, resolution


def frame_time(animation, k):
    """Time of frame k (from 0) of `a START END NFRAMES` (aff-format.md, section 3)."""
    start, end, frames = animation
    return start + k * (end - start) / (frames - 1)


# ---- Images (binary PPM, 8 bits) ----

def read_ppm(path):
    with open(path, "rb") as f:
        data = f.read()
    fields, pos = [], 0
    while len(fields) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        end = pos
        while not data[end:end + 1].isspace():
            end += 1
        fields.append(data[pos:end])
        pos = end
    if fields[0] != b"P6" or int(fields[3]) != 255:
        raise ValueError(f"{path}: not an 8-bit binary PPM")
    w, h = int(fields[1]), int(fields[2])
    pixels = data[pos + 1:pos + 1 + w * h * 3]
    if len(pixels) != w * h * 3:
        raise ValueError(f"{path}: truncated")
    return w, h, pixels


def write_ppm(path, w, h, pixels):
    with open(path, "wb") as f:
        f.write(b"P6\n%d %d\n255\n" % (w, h))
        f.write(bytes(pixels))


def to_ppm(src, dst, size, log):
    """src as an 8-bit RGB PPM of `size` (resized when it differs)."""
    cmd = ["oiiotool", src, "--ch", "R,G,B"]
    cmd += ["--resize", f"{size[0]}x{size[1]}"]
    run(cmd + ["-d", "uint8", "-o", dst], log)


def compare(ref, afr):
    """Figures of afr against BART: RMS (0-255), mean afr - BART per channel, GRID x GRID mean
    absolute differences (rows top to bottom), and the amplified difference image."""
    w, h, a = ref
    w2, h2, b = afr
    assert (w, h) == (w2, h2)
    sum_sq = 0
    signed = [0, 0, 0]
    cells = [[0] * GRID for _ in range(GRID)]
    counts = [[0] * GRID for _ in range(GRID)]
    diff = bytearray(len(a))
    for y in range(h):
        gy = y * GRID // h
        row = y * w * 3
        for x in range(w):
            gx = x * GRID // w
            i = row + x * 3
            cell = 0
            for c in range(3):
                d = b[i + c] - a[i + c]
                sum_sq += d * d
                signed[c] += d
                cell += abs(d)
                diff[i + c] = min(255, abs(d) * DIFF_GAIN)
            cells[gy][gx] += cell
            counts[gy][gx] += 3
    n = w * h
    return {
        "rms": (sum_sq / (3 * n)) ** 0.5,
        "mean_signed": [s / n for s in signed],
        "grid": [[cells[r][c] / counts[r][c] for c in range(GRID)] for r in range(GRID)],
        "diff": diff,
    }


def rms_only(ref, afr):
    a, b = ref[2], afr[2]
    return (sum((p - q) * (p - q) for p, q in zip(a, b)) / len(a)) ** 0.5


# ---- One case ----

def run_case(case, args, log):
    scenes = args.scenes
    aff = os.path.join(scenes, case["aff"])
    reference = os.path.join(scenes, case["reference"])
    for path, what in ((aff, "BART scene"), (reference, "BART reference image")):
        if not os.path.isfile(path):
            raise Missing(f"{what} {path} is missing (BART's scenes are read from --scenes "
                          f"{scenes})")
    animation, resolution = aff_header(aff)
    size = (max(1, round(resolution[0] * args.scale)), max(1, round(resolution[1] * args.scale)))

    work = os.path.join(args.out, case["name"])
    os.makedirs(work, exist_ok=True)
    gltf = os.path.join(args.out, "scenes", os.path.splitext(os.path.basename(aff))[0],
                        "scene.gltf")
    convert = [args.aff2gltf, aff, "-o", gltf]
    if os.path.isfile(gltf):
        log.append(convert)  # converted by an earlier run
    else:
        os.makedirs(os.path.dirname(gltf), exist_ok=True)
        run(convert, log)

    ref_ppm = os.path.join(work, "bart.ppm")
    to_ppm(reference, ref_ppm, size, log)
    ref = read_ppm(ref_ppm)

    k = case["number"] - 1
    frames = []  # (k, time, rms, image path)
    for kk in (k - 1, k, k + 1):
        t = frame_time(animation, kk)
        png = os.path.join(work, f"afr-k{kk}.png")
        run([args.render, gltf, "--time", repr(t), "--size", f"{size[0]}x{size[1]}", "--spp",
             str(args.spp), "-o", png], log)
        ppm = os.path.join(work, f"afr-k{kk}.ppm")
        to_ppm(png, ppm, size, log)
        frames.append((kk, t, rms_only(ref, read_ppm(ppm)), ppm))

    afr = read_ppm(frames[1][3])
    figures = compare(ref, afr)
    diff_ppm = os.path.join(work, "diff.ppm")
    write_ppm(diff_ppm, size[0], size[1], figures["diff"])
    side = os.path.join(work, "side-by-side.png")
    run(["oiiotool", ref_ppm, frames[1][3], diff_ppm, "--mosaic", "3x1", "-o", side], log)
    return {
        "case": case, "aff": aff, "reference": reference, "animation": animation,
        "resolution": resolution, "size": size, "k": k, "time": frames[1][1],
        "frames": frames, "figures": figures, "side": side, "gltf": gltf,
    }


# ---- Report ----

def report(r, args):
    case, fig = r["case"], r["figures"]
    start, end, nframes = r["animation"]
    lines = [
        f"## {case['name']}: {os.path.basename(r['reference'])} against afr-render",
        "",
        f"BART's `{case['reference']}` ({r['resolution'][0]} x {r['resolution'][1]} JPEG) and "
        f"afr-render's frame of `{case['aff']}` (converted by aff2gltf) at k = {r['k']} of "
        f"`a {start:g} {end:g} {nframes}`, t = {r['time']:.6f} s; both at "
        f"{r['size'][0]} x {r['size'][1]}, afr at {args.spp} samples per pixel.",
        "",
        f"**RMS afr - BART: {fig['rms']:.1f}** (0-255, sRGB codes of R, G, B). Mean afr - BART "
        "per channel (R, G, B): " + ", ".join(f"{v:+.1f}" for v in fig["mean_signed"]) + ".",
        "",
        "The frame the image shows (RMS against the frame before and after; the image's number "
        f"is {case['number']}):",
        "",
        "| k | t (s) | RMS |",
        "|---:|---:|---:|",
    ]
    for kk, t, rms, _ in r["frames"]:
        mark = " (k = number - 1)" if kk == r["k"] else ""
        lines.append(f"| {kk}{mark} | {t:.6f} | {rms:.1f} |")
    lines += [
        "",
        f"Mean absolute difference (0-255) in a {GRID} x {GRID} grid, image rows top to bottom:",
        "",
        "| | " + " | ".join(f"x{c + 1}" for c in range(GRID)) + " |",
        "|---|" + "---:|" * GRID,
    ]
    for row, cells in enumerate(fig["grid"]):
        lines.append(f"| y{row + 1} | " + " | ".join(f"{v:.1f}" for v in cells) + " |")
    lines += ["", f"Picture: BART | afr | |afr - BART| x {DIFF_GAIN}, `{r['side']}`.", ""]
    return "\n".join(lines)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--build", default="build", help="build folder (default build)")
    p.add_argument("--out", default="out/bart-compare", help="work folder (default "
                   "out/bart-compare)")
    p.add_argument("--scenes", default="../shared/scenes",
                   help="BART's scenes, read only, relative to the repository root (default "
                   "../shared/scenes)")
    p.add_argument("--spp", type=int, default=16, help="afr-render samples per pixel "
                   "(default 16)")
    p.add_argument("--scale", type=float, default=1.0, help="render at this fraction of the "
                   "reference's size; the reference is resized to match (default 1)")
    p.add_argument("--write-results", action="store_true", help="also write "
                   "bench/results/<case>.md and docs/img/<case>.png")
    args = p.parse_args()
    if not 0.0 < args.scale <= 1.0:
        p.error("--scale must be in (0, 1]")

    os.chdir(ROOT)
    args.aff2gltf = os.path.join(args.build, "tools", "aff2gltf", "aff2gltf")
    args.render = os.path.join(args.build, "bench", "afr-render")
    missing = [path for path in (args.aff2gltf, args.render) if not os.access(path, os.X_OK)]
    if missing:
        sys.exit("bart_compare: missing " + ", ".join(missing) + f" (build them in {args.build}"
                 ", or pass --build DIR)")
    if shutil.which("oiiotool") is None:
        sys.exit("bart_compare: oiiotool (OpenImageIO's tool) is not on PATH")
    if not os.path.isdir(args.scenes):
        sys.exit(f"bart_compare: BART's scenes folder {args.scenes} is missing (pass --scenes)")

    command = "python3 bench/bart_compare.py " + shlex.join(sys.argv[1:])
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip() or "unknown"
    for case in CASES:
        log = []
        try:
            r = run_case(case, args, log)
        except Missing as e:
            sys.exit(f"bart_compare: {e}")
        body = report(r, args)
        print(body)
        header = [
            f"# BART's {os.path.basename(r['reference'])} beside afr-render",
            "",
            "How far afr's render of a BART frame is from BART's own image, and where; "
            "docs/aff2gltf.md (\"Compared with BART's own images\") says why.",
            "",
            f"- Command: `{command.strip()}`",
            f"- Run with the binaries of `{args.build}` at commit {commit}, "
            f"{datetime.date.today().isoformat()}, {os.cpu_count()} cores.",
            "- Steps: " + "; ".join(f"`{shlex.join(c)}`" for c in log if c[0] != "oiiotool"
                                    or "--mosaic" in c) + ".",
            "",
        ]
        text = "\n".join(header) + "\n" + body
        with open(os.path.join(args.out, case["name"], "result.md"), "w") as f:
            f.write(text)
        if args.write_results:
            results = os.path.join("bench", "results", case["name"] + ".md")
            picture = os.path.join("docs", "img", case["name"] + ".png")
            text = text.replace(f"`{r['side']}`", f"[{picture}](../../{picture})")
            with open(results, "w") as f:
                f.write(text)
            # The docs' copy is half size: three 800 x 600 panels are 2400 pixels wide.
            half = f"{r['size'][0] * 3 // 2}x{r['size'][1] // 2}"
            run(["oiiotool", r["side"], "--resize", half, "-o", picture], log)
            print(f"wrote {results} and {picture}")


if __name__ == "__main__":
    main()
