#!/usr/bin/env python3
"""Stitches a display wall's cell images into the image of the whole virtual display.

Each cell COLUMN,ROW of a COLUMNSxROWS grid over a WxH display covers the pixels
[c*W/cols, (c+1)*W/cols) x [r*H/rows, (r+1)*H/rows) (integer division, display_node's rule),
and its node wrote DIR/cell-C-R/STEM.png (run-wall.sh's folders). A cell whose image is missing
(a dead node) is drawn dark gray and named on stderr; the others are stitched all the same.

    deploy/wall_stitch.py --grid 2x2 --size 512x512 --cells out/wall --stem snapshot_000001 \\
        -o out/wall/wall.png

Exits 0 when every cell was there, 3 when some were missing (the image is written), 1 on an
error (no oiiotool, no cell at all).
"""
import argparse
import os
import re
import shutil
import subprocess
import sys


def pair(text, sep, what):
    m = re.fullmatch(r"(\d+)" + sep + r"(\d+)", text)
    if not m or int(m.group(1)) < 1 or int(m.group(2)) < 1:
        raise argparse.ArgumentTypeError(f"{what} must be A{sep}B with A, B >= 1, got '{text}'")
    return int(m.group(1)), int(m.group(2))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--grid", required=True, type=lambda t: pair(t, "x", "--grid"))
    p.add_argument("--size", required=True, type=lambda t: pair(t, "x", "--size"))
    p.add_argument("--cells", required=True, help="folder with cell-C-R/ subfolders")
    p.add_argument("--stem", required=True, help="image name without .png (final, snapshot_000001)")
    p.add_argument("-o", "--output", required=True)
    a = p.parse_args()
    if not shutil.which("oiiotool"):
        sys.exit("wall_stitch: oiiotool (Debian package openimageio-tools) is not installed")
    (cols, rows), (width, height) = a.grid, a.size
    # A dark gray canvas, then each cell pasted at its origin (oiiotool: FG BG --paste +X+Y).
    cmd = ["oiiotool", "--pattern", "constant:color=0.1,0.1,0.1", f"{width}x{height}", "3"]
    missing = []
    for r in range(rows):
        for c in range(cols):
            x0, y0 = c * width // cols, r * height // rows
            image = os.path.join(a.cells, f"cell-{c}-{r}", a.stem + ".png")
            if os.path.isfile(image):
                cmd += [image, "--ch", "R,G,B", "--paste", f"+{x0}+{y0}"]
            else:
                missing.append(f"{c},{r}")
    if len(missing) == cols * rows:
        sys.exit(f"wall_stitch: no cell has {a.stem}.png under {a.cells}")
    cmd += ["-d", "uint8", "-o", a.output]
    subprocess.run(cmd, check=True)
    if missing:
        print(f"wall_stitch: {a.output}: cell(s) {' '.join(missing)} missing (drawn dark gray)",
              file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
