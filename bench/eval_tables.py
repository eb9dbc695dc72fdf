#!/usr/bin/env python3
"""The evaluation's tables in docs/results.md, made from afr-eval's outputs.

afr-eval writes, into its --out folder, cells.csv (one line per table cell: the mean, lowest
and highest mean RMS over the seeds) and run.json (the command, the commit, the set-up and the
wall time of the run). This script turns them into the tables of docs/results.md, each headed by
the command and commit that made it, and replaces the text between the markers

    <!-- eval_tables.py NAME: begin -->
    <!-- eval_tables.py NAME: end -->

in the document (--write), or prints the tables (default). Tables:

    targets  from --table DIR: the issue's targets at one rate (--rate, default 400K) on every
             animation of the run; a target that compares two methods is met only where the
             difference exceeds the spread over the seeds (the ranges do not overlap).
    timing   from --timing DIR (repeatable): the wall time of full Table 1 runs, one row each;
             the 30-minute target counts the whole run, with the ideal frames (9 spp) read
             from a warm cache, and is for at least the paper's 5 methods (PAPER_METHODS).
    full     from the first --timing DIR: the targets on that run (20 s of each animation).
    scenes   from --scene DIR (repeatable): the same targets on scenes beyond the kitchen
             and the built-in scene (afr-eval --scene runs), one table per run.
    gpu-display  from --gpu-display DIR (repeatable): the same targets from runs at a GPU
             display's latency (afr-eval --latency 0.25), one table per run.

    python3 bench/eval_tables.py --table out/eval/table-256 --timing out/eval/table1-timing
    python3 bench/eval_tables.py --table out/eval/table-256 --timing out/eval/table1-timing \\
        --write docs/results.md

bench/refresh_results.sh results-doc runs the second command.
"""
import argparse
import csv
import json
import os
import re
import sys

TARGET_MINUTES = 30.0


def fail(message):
    sys.exit(f"eval_tables.py: {message}")


def parse_rate(text):
    scale = {"K": 1e3, "k": 1e3, "M": 1e6, "m": 1e6}.get(text[-1:], 1.0)
    try:
        return float(text[:-1] if scale != 1.0 else text) * scale
    except ValueError:
        fail(f"rate '{text}': expected e.g. 400K or 1.6M")


def rate_label(rate):
    return f"{rate / 1e6:.3g}M" if rate >= 1e6 else f"{rate / 1e3:.3g}K"


def read_run(folder):
    """run.json and cells.csv of an afr-eval output folder."""
    meta_path, cells_path = os.path.join(folder, "run.json"), os.path.join(folder, "cells.csv")
    for path in (meta_path, cells_path):
        if not os.path.isfile(path):
            fail(f"{path}: missing (run afr-eval with --out {folder} first)")
    with open(meta_path) as f:
        meta = json.load(f)
    cells = {}
    with open(cells_path) as f:
        for row in csv.DictReader(f):
            key = (row["animation"], row["method"], float(row["rate"]))
            cells[key] = {k: float(row[k]) for k in ("runs", "mean_rms", "min_rms", "max_rms")}
    return meta, cells


def provenance(meta):
    text = (f"Made by `{meta['command']}` at commit {meta['commit']}: {meta['setup']}; "
            f"{meta['minutes']:.1f} minutes.")
    still = still_note(meta)
    return text + (f" **{still}.**" if still else "")


def still_note(meta):
    """Which animations' windows run past their keys (older run.json files do not say)."""
    parts = [f"{a['name']}: {a['still_frames']} of the frames after its animation ends at "
             f"{a['duration']:g} s" for a in meta["animations"] if a.get("still_frames", 0) > 0]
    return ("Still scenes in the window (" + "; ".join(parts) + ")") if parts else ""


def cell(cells, animation, method, rate):
    """The cell of a method at a rate; full-res-60hz has one fixed rate per animation."""
    if method == "full-res-60hz":
        for (a, m, _), c in cells.items():
            if a == animation and m == method:
                return c
        return None
    return cells.get((animation, method, rate))


def fmt_cell(c):
    if c["runs"] <= 1:
        return f"{c['mean_rms']:.1f}"
    return f"{c['mean_rms']:.1f} ({c['min_rms']:.1f}-{c['max_rms']:.1f})"


def compare(a, b):
    """'lower', 'higher' or 'within spread': ranges over the seeds that do not overlap."""
    if a["max_rms"] < b["min_rms"]:
        return "lower"
    if a["min_rms"] > b["max_rms"]:
        return "higher"
    return "within spread"


def targets_table(meta, cells, rate, animations):
    if not animations:
        animations = []
        for a in meta["animations"]:
            if a["name"] not in animations:
                animations.append(a["name"])
    rows = []  # (target, [(text, met or None)])

    def need(animation, method):
        c = cell(cells, animation, method, rate)
        if c is None:
            fail(f"no {method} at {rate_label(rate)} on {animation} in the run")
        return c

    ratio_row, below = [], {m: [] for m in ("framed-60hz", "framed-full-res")}
    fr60_row, taa_row = [], []
    for an in animations:
        ad, fl = need(an, "adaptive"), need(an, "frameless")
        worst = ad["max_rms"] / fl["min_rms"]
        ratio_row.append((f"{fmt_cell(ad)} / {fmt_cell(fl)} = {ad['mean_rms'] / fl['mean_rms']:.2f}"
                          f" (at worst {worst:.2f})", worst <= 0.6))
        for m in below:
            other = need(an, m)
            word = compare(ad, other)
            below[m].append((f"{ad['mean_rms']:.1f} vs {fmt_cell(other)}: {word}", word == "lower"))
        fr60 = need(an, "full-res-60hz")
        worst = ad["max_rms"] / fr60["min_rms"]
        fr60_row.append((f"{ad['mean_rms'] / fr60['mean_rms']:.2f} (at worst {worst:.2f})",
                         worst <= 1.25))
        taa = cell(cells, an, "framed-taa", rate)
        taa_row.append((f"{ad['mean_rms']:.1f} vs {fmt_cell(taa)}: {compare(ad, taa)}"
                        if taa else "-", None))
    rows.append(("adaptive / traditional frameless <= 0.6", ratio_row))
    rows.append(("adaptive below framed 60 Hz", below["framed-60hz"]))
    rows.append(("adaptive below framed full res", below["framed-full-res"]))
    rows.append(("adaptive <= 1.25 x full res 60 Hz", fr60_row))
    rows.append(("adaptive vs framed 60 Hz + TAA (report)", taa_row))

    out = [provenance(meta), "",
           f"Mean RMS (0-255) at {rate_label(rate)} rays/s, mean (lowest-highest run) over the "
           "seeds; a comparison is met only where the ranges do not overlap, a ratio at its worst "
           "end (highest adaptive run over the lowest run of the other).", "",
           "| target | " + " | ".join(animations) + " | met |",
           "|---|" + "---|" * len(animations) + "---|"]
    for target, cols in rows:
        verdicts = [met for _, met in cols if met is not None]
        met = "" if not verdicts else ("yes" if all(verdicts) else "no")
        out.append(f"| {target} | " + " | ".join(text for text, _ in cols) + f" | {met} |")
    return "\n".join(out)


# The methods of the paper's Table 1 (400K 60Hz, 400K Full Res, traditional frameless,
# adaptive, Full Res 60Hz), and the two afr-eval adds: adaptive without reprojection (the
# paper's Figure 8) and framed 60 Hz + TAA (a modern framed baseline).
PAPER_METHODS = {"framed-60hz", "framed-full-res", "frameless", "adaptive", "full-res-60hz"}
EVERY_METHOD = PAPER_METHODS | {"adaptive-no-reproj", "framed-taa"}


def timing_row(meta):
    warm = meta["ideal_rendered"] == 0
    spp_ok = meta["ideal_spp"] == 9
    names = ", ".join(a["name"] for a in meta["animations"])
    methods = set(meta.get("methods", []))
    # A full Table 1: 20 s of each kitchen animation, the methods at 100K, 400K, 800K.
    still = still_note(meta)
    window = (meta["seconds"] >= 20 and {"bart", "toycar", "interactive"} <= set(names.split(", "))
              and {1e5, 4e5, 8e5} <= set(meta.get("rates", [])) and not still)
    if methods >= EVERY_METHOD:
        scope = f"every method of afr-eval ({len(methods)})"
    elif methods >= PAPER_METHODS:
        scope = "the paper's Table 1 (its 5 methods)"
    else:
        scope = None
    full = window and scope is not None
    met = meta["minutes"] <= TARGET_MINUTES and warm and spp_ok and full
    why = []
    if not full:
        why.append("not a full Table 1 (20 s of bart, toycar and interactive while they move, "
                   "at least the paper's 5 methods at 100K, 400K and 800K)")
    if not warm:
        why.append(f"{meta['ideal_rendered']} ideal frames were rendered, not read from the cache")
    if not spp_ok:
        why.append(f"ideal frames at {meta['ideal_spp']} spp, not 9")
    measured = (f"{meta['minutes']:.1f} minutes in all ({meta['ideal_minutes']:.1f} of them "
                f"rendering ideal frames; {meta['ideal_cached']} read from the cache); "
                f"{meta['cpu_minutes']:.1f} CPU minutes")
    return (f"| {scope or 'a partial run'}: {names}, {meta['seconds']:g} s each, "
            f"{len(methods)} methods ({', '.join(sorted(methods))}) at "
            f"{', '.join(rate_label(r) for r in meta.get('rates', []))}, {meta['seeds']} "
            f"seed(s); commit {meta['commit']} | {measured} | "
            + ("yes" if met else "no" + (f" ({'; '.join(why)})" if why else "")) + " |")


def timing_table(metas):
    """One row per timed run (--timing, repeatable), each under its command."""
    out = [f"- `{m['command']}` at commit {m['commit']}: {m['setup']}." for m in metas]
    out += ["", f"Target: a full Table-1 run in {TARGET_MINUTES:g} minutes, the whole run "
            "counted, ideal frames at 9 spp from a warm cache.", "",
            "| run | measured | met |", "|---|---|---|"]
    out += [timing_row(m) for m in metas]
    return "\n".join(out)


def replace_block(text, name, body, path):
    begin, end = f"<!-- eval_tables.py {name}: begin -->", f"<!-- eval_tables.py {name}: end -->"
    pattern = re.compile(re.escape(begin) + r".*?" + re.escape(end), re.S)
    if not pattern.search(text):
        fail(f"{path}: no '{begin}' ... '{end}' markers")
    return pattern.sub(lambda _: f"{begin}\n{body}\n{end}", text, count=1)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--table", help="afr-eval output folder of the Table 1 run")
    parser.add_argument("--timing", action="append", default=[],
                        help="afr-eval output folder of a timed Table 1 run (repeatable; the "
                        "first also gives the 20 s targets table)")
    parser.add_argument("--scene", action="append", default=[],
                        help="afr-eval output folder of a --scene run (repeatable)")
    parser.add_argument("--gpu-display", action="append", default=[],
                        help="afr-eval output folder of a run at a GPU display's latency "
                        "(repeatable)")
    parser.add_argument("--rate", default="400K", help="rate of the targets table")
    parser.add_argument("--animations", default="",
                        help="animations of the targets table (default: all of the run)")
    parser.add_argument("--write", metavar="DOC", help="replace the tables' blocks in DOC")
    args = parser.parse_args()
    if not args.table and not args.timing and not args.scene and not args.gpu_display:
        fail("nothing to do: give --table, --timing, --scene and/or --gpu-display")
    tables = {}
    if args.table:
        meta, cells = read_run(args.table)
        animations = [a for a in args.animations.split(",") if a]
        tables["targets"] = targets_table(meta, cells, parse_rate(args.rate), animations)
    for block, folders in (("scenes", args.scene), ("gpu-display", args.gpu_display)):
        if folders:
            tables[block] = "\n\n".join(
                targets_table(*read_run(folder), parse_rate(args.rate), []) for folder in folders)
    if args.timing:
        runs = [read_run(folder) for folder in args.timing]
        meta, cells = runs[0]
        tables["full"] = targets_table(meta, cells, parse_rate(args.rate), [])
        tables["timing"] = timing_table([m for m, _ in runs])
    if not args.write:
        for name, body in tables.items():
            print(f"## {name}\n\n{body}\n")
        return
    with open(args.write) as f:
        text = f.read()
    for name, body in tables.items():
        text = replace_block(text, name, body, args.write)
    with open(args.write + ".tmp", "w") as f:
        f.write(text)
    os.replace(args.write + ".tmp", args.write)
    print(f"eval_tables.py: {', '.join(tables)} written into {args.write}", file=sys.stderr)


if __name__ == "__main__":
    main()
