#!/usr/bin/env python3
"""bench/eval_tables.py on constructed afr-eval outputs (the ctest eval_tables).

Two runs of one animation, written as afr-eval writes them (run.json, cells.csv): in one every
target is met, in the other adaptive's range overlaps framed 60 Hz's and its worst run is above
0.6 of traditional frameless. The script must judge each target by the spread (the ranges, the
ratio at its worst end), put both runs' tables between the gpu-display markers of a document
and leave the rest of it as it was, and refuse a document without the markers, naming them.
"""
import csv
import json
import os
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCRIPT = os.path.join(ROOT, "bench", "eval_tables.py")
PAPER_METHODS = ["framed-60hz", "framed-full-res", "frameless", "adaptive", "full-res-60hz"]
EVERY_METHOD = PAPER_METHODS + ["adaptive-no-reproj", "framed-taa"]
FIELDS = ["animation", "method", "rate", "runs", "mean_rms", "min_rms", "max_rms"]


def write_run(folder, commit, cells, **more):
    """An afr-eval output folder: run.json and cells.csv; cells: method -> (mean, min, max);
    more: run.json fields added or replaced."""
    os.makedirs(folder)
    meta = {"command": f"afr-eval --latency 0.25 --out {folder}", "commit": commit,
            "setup": "64x64, test set-up", "minutes": 1.5, "animations": [{"name": "anim"}]}
    meta.update(more)
    with open(os.path.join(folder, "run.json"), "w") as f:
        json.dump(meta, f)
    with open(os.path.join(folder, "cells.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(FIELDS)
        for animation in meta["animations"]:
            for method, (mean, lo, hi) in cells.items():
                rate = 4e6 if method == "full-res-60hz" else 4e5
                runs = 1 if lo == hi else 3
                w.writerow([animation["name"], method, rate, runs, mean, lo, hi])


def run(*args):
    return subprocess.run([sys.executable, SCRIPT, *args], capture_output=True, text=True)


class EvalTablesTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.addCleanup(self.tmp.cleanup)
        d = self.tmp.name
        self.met = os.path.join(d, "met")
        write_run(self.met, "aaaaaaa", {
            "adaptive": (10.0, 9.8, 10.2), "frameless": (20.0, 19.9, 20.1),
            "framed-60hz": (12.0, 12.0, 12.0), "framed-full-res": (30.0, 29.0, 31.0),
            "full-res-60hz": (9.0, 9.0, 9.0), "framed-taa": (11.0, 10.9, 11.1)})
        self.unmet = os.path.join(d, "unmet")
        # Mean ratio 0.59, worst end 12.5 / 19.9 = 0.63; 12.5 overlaps framed 60 Hz's 12.2.
        write_run(self.unmet, "bbbbbbb", {
            "adaptive": (11.8, 11.1, 12.5), "frameless": (20.0, 19.9, 20.1),
            "framed-60hz": (12.2, 12.2, 12.2), "framed-full-res": (30.0, 29.0, 31.0),
            "full-res-60hz": (9.0, 9.0, 9.0), "framed-taa": (11.0, 10.9, 11.1)})

    def rows(self, table):
        return {line.split(" | ")[0].lstrip("| "): line for line in table.splitlines()
                if line.startswith("| ")}

    def test_targets_are_judged_by_the_spread(self):
        r = run("--gpu-display", self.met, "--gpu-display", self.unmet)
        self.assertEqual(r.returncode, 0, r.stderr)
        met_part, unmet_part = r.stdout.split("Made by ")[1:3]
        self.assertIn("at commit aaaaaaa", met_part)
        self.assertIn("at commit bbbbbbb", unmet_part)
        met, unmet = self.rows(met_part), self.rows(unmet_part)
        ratio = "adaptive / traditional frameless <= 0.6"
        self.assertIn("= 0.50 (at worst 0.51)", met[ratio])
        self.assertTrue(met[ratio].endswith("| yes |"), met[ratio])
        self.assertIn("= 0.59 (at worst 0.63)", unmet[ratio])
        self.assertTrue(unmet[ratio].endswith("| no |"), unmet[ratio])
        below = "adaptive below framed 60 Hz"
        self.assertIn("10.0 vs 12.0: lower", met[below])
        self.assertTrue(met[below].endswith("| yes |"))
        self.assertIn("11.8 vs 12.2: within spread", unmet[below])
        self.assertTrue(unmet[below].endswith("| no |"))
        # 10.2 / 9.0 at worst: within 1.25 x full res 60 Hz.
        self.assertTrue(met["adaptive <= 1.25 x full res 60 Hz"].endswith("| yes |"))

    def test_the_tables_replace_only_the_marked_block(self):
        doc = os.path.join(self.tmp.name, "results.md")
        before = "# Results\n\nText above.\n\n"
        after = "\n\nText below.\n"
        with open(doc, "w") as f:
            f.write(before + "<!-- eval_tables.py gpu-display: begin -->\nold table\n"
                    "<!-- eval_tables.py gpu-display: end -->" + after)
        r = run("--gpu-display", self.met, "--write", doc)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(doc) as f:
            text = f.read()
        self.assertTrue(text.startswith(before), text)
        self.assertTrue(text.endswith(after), text)
        self.assertNotIn("old table", text)
        self.assertIn("at commit aaaaaaa", text)

    def test_a_timed_run_ending_on_a_still_scene_is_not_a_full_table(self):
        cells = {"adaptive": (10.0, 9.8, 10.2), "frameless": (20.0, 19.9, 20.1),
                 "framed-60hz": (12.0, 12.0, 12.0), "framed-full-res": (30.0, 29.0, 31.0),
                 "full-res-60hz": (9.0, 9.0, 9.0), "framed-taa": (11.0, 10.9, 11.1)}
        timing = {"seconds": 20, "rates": [1e5, 4e5, 8e5], "methods": EVERY_METHOD, "seeds": 3,
                  "ideal_spp": 9, "ideal_rendered": 0, "ideal_cached": 3600,
                  "ideal_minutes": 0.0, "cpu_minutes": 40.0, "minutes": 20.0}
        names = ("bart", "toycar", "interactive")
        moving = os.path.join(self.tmp.name, "moving")
        write_run(moving, "ccccccc", cells, **timing, animations=[
            {"name": n, "duration": 20, "still_frames": 0} for n in names])
        still = os.path.join(self.tmp.name, "still")
        write_run(still, "ddddddd", cells, **timing, animations=[
            {"name": n, "duration": 20, "still_frames": 510 if n == "bart" else 0}
            for n in names])
        r = run("--timing", moving)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertNotIn("Still scenes", r.stdout)
        self.assertIn("| yes |", r.stdout.split("## timing")[1])
        r = run("--timing", still)
        self.assertEqual(r.returncode, 0, r.stderr)
        full, timed = r.stdout.split("## timing")
        self.assertIn("Still scenes in the window (bart: 510 of the frames after its animation "
                      "ends at 20 s)", full)
        self.assertIn("| no (not a full Table 1", timed)

    def test_each_timed_run_is_a_row_judged_by_its_methods_and_minutes(self):
        cells = {"adaptive": (10.0, 9.8, 10.2), "frameless": (20.0, 19.9, 20.1),
                 "framed-60hz": (12.0, 12.0, 12.0), "framed-full-res": (30.0, 29.0, 31.0),
                 "full-res-60hz": (9.0, 9.0, 9.0), "framed-taa": (11.0, 10.9, 11.1)}
        common = {"seconds": 20, "rates": [1e5, 4e5, 8e5], "seeds": 3, "ideal_spp": 9,
                  "ideal_rendered": 0, "ideal_cached": 3600, "ideal_minutes": 0.0,
                  "cpu_minutes": 50.0, "animations": [
                      {"name": n, "duration": 20, "still_frames": 0}
                      for n in ("bart", "toycar", "interactive")]}
        every = os.path.join(self.tmp.name, "every")
        write_run(every, "eeeeeee", cells, **common, methods=EVERY_METHOD, minutes=36.0)
        paper = os.path.join(self.tmp.name, "paper")
        write_run(paper, "fffffff", cells, **common, methods=PAPER_METHODS, minutes=24.0)
        partial = os.path.join(self.tmp.name, "partial")
        write_run(partial, "9999999", cells, **common, methods=["adaptive", "frameless"],
                  minutes=10.0)
        r = run("--timing", every, "--timing", paper, "--timing", partial)
        self.assertEqual(r.returncode, 0, r.stderr)
        full, timed = r.stdout.split("## timing")
        self.assertIn("at commit eeeeeee", full)  # the first run gives the 20 s targets
        self.assertNotIn("at commit fffffff", full)
        rows = [line for line in timed.splitlines() if line.startswith("| ") and "commit" in line]
        self.assertEqual(len(rows), 3, timed)
        self.assertIn("every method of afr-eval (7)", rows[0])
        self.assertIn("36.0 minutes", rows[0])
        self.assertTrue(rows[0].endswith("| no |"), rows[0])  # over 30 minutes
        self.assertIn("the paper's Table 1 (its 5 methods)", rows[1])
        self.assertTrue(rows[1].endswith("| yes |"), rows[1])
        self.assertIn("a partial run", rows[2])
        self.assertIn("| no (not a full Table 1", rows[2])  # fast, but not a Table 1

    def test_a_document_without_the_markers_is_refused_by_name(self):
        doc = os.path.join(self.tmp.name, "plain.md")
        with open(doc, "w") as f:
            f.write("# Results\n")
        r = run("--gpu-display", self.met, "--write", doc)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("no '<!-- eval_tables.py gpu-display: begin -->'", r.stderr)
        with open(doc) as f:
            self.assertEqual(f.read(), "# Results\n")


if __name__ == "__main__":
    unittest.main()
