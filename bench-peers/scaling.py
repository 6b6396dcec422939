"""Time per element of graftal's operators from 10^4 to 10^6 elements, and
memory per G3 primitive (issue 17, "Scaling").

    GRAFTAL=target/release/graftal python3 bench-peers/scaling.py [--runs 3] [--only weld,grid] [--out FILE]

Standard library only (no venv, no peers). Each workload is a rule file
written into target/bench-scaling/ and run at three sizes; a step's time
comes from a one-variant batch manifest (`--seeds 0..1 --timings`), which
records step times without the `--stats` mesh analysis. Rounds are
interleaved across sizes and the median is reported, with the ratio of the
largest to the smallest per-element time ("flat" means within 1.5x).
Peak RSS comes from wait4 on each run without --timings noise.
"""

import argparse
import json
import os
import random
import struct
import shutil
import statistics
import subprocess
import sys
from array import array
from pathlib import Path

# The peer suite's rule templates and process runner (standard library).
from run import STEP, grid_rule, spawn

ROOT = Path(__file__).resolve().parent.parent
WORK = ROOT / "target" / "bench-scaling"
GRAFTAL = Path(os.environ.get("GRAFTAL", ROOT / "target" / "release" / "graftal"))
SIZES = (10_000, 100_000, 1_000_000)


def side(elements, per_cell=1):
    """Grid side whose n^2 cells make about `elements / per_cell`."""
    return max(2, round((elements / per_cell) ** 0.5))


def grid_workload(body_steps, measured, per_cell=1, count="faces"):
    """A grid of about `elements` cells, then `body_steps`; the time of step `measured`."""

    def make(elements):
        n = side(elements, per_cell)
        text = grid_rule(n, None, *body_steps)
        return text, {"faces": n * n, "triangles": 2 * n * n}[count]

    return make, measured


def write_soup(path, n):
    """The merge workload of make_inputs.py at side n, in the standard
    library: an n x n grid of spacing 0.01 exploded into triangles (one
    vertex per corner), each vertex jittered by U(+-1e-6), seeded."""
    rng = random.Random(17)
    corners = array("d")
    for j in range(n):
        for i in range(n):
            a, b, c, d = (i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)
            for x, y in (a, b, c, a, c, d):
                corners.extend(
                    (x * 0.01 + rng.uniform(-1e-6, 1e-6), y * 0.01 + rng.uniform(-1e-6, 1e-6), rng.uniform(-1e-6, 1e-6))
                )
    triangles = 2 * n * n
    faces = bytearray()
    for t in range(triangles):
        faces += struct.pack("<B3i", 3, 3 * t, 3 * t + 1, 3 * t + 2)
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {3 * triangles}\n"
        "property double x\nproperty double y\nproperty double z\n"
        f"element face {triangles}\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    if sys.byteorder != "little":
        corners.byteswap()
    path.write_bytes(header.encode() + corners.tobytes() + bytes(faces))


def soup_workload(weld):
    """Import of a jittered soup of about `elements` triangles: welded at
    import (1e-4), or imported as is and then merged by a `merge` step."""

    def make(elements):
        n = side(elements, 2)
        soup = WORK / f"soup-{n}.ply"
        if not soup.exists():
            # In a child process: a child's peak RSS (wait4) includes the
            # parent's at fork, so the driver itself stays small.
            subprocess.run([sys.executable, __file__, "--write-soup", str(soup), str(n)], check=True)
        if weld:
            text = f'[start]\nimport = {{ path = "{soup.name}", weld = 0.0001 }}\n'
        else:
            text = f'[start]\nimport = {{ path = "{soup.name}" }}\n' + STEP.format(
                name="merge", body="merge = { distance = 0.0001 }"
            )
        return text, 2 * n * n

    return make, "start" if weld else "merge"


def synthetic(elements):
    """benches/synthetic.toml, about 28 n^2 primitives."""
    n = side(elements, 28)
    text = (ROOT / "benches" / "synthetic.toml").read_text().replace("n = 8", f"n = {n}", 1)
    return text, None  # counted from the result: every primitive it made


WORKLOADS = {
    "grid (`[start] grid`), per face": grid_workload([], "start"),
    "extrude_faces, per input face": grid_workload(
        [("extrude", "extrude_faces = { distance = 0.01 }")], "extrude"
    ),
    "triangulate, per input quad": grid_workload([("triangulate", "triangulate = {}")], "triangulate"),
    "inset_region, per face": grid_workload([("inset", "inset_region = { thickness = 0.001 }")], "inset"),
    "mirror with seam merge, per input face": grid_workload(
        [
            ("move", "translate = { offset = [1.28, 0, 0] }"),
            ("mirror", 'on = "faces"\nmirror = { axis = "x", merge_distance = 0.00001 }'),
        ],
        "mirror",
    ),
    "import of a jittered soup, weld 1e-4, per triangle": soup_workload(True),
    "merge step (1e-4) on an imported soup, per triangle": soup_workload(False),
    "G3 synthetic grammar (all steps), per primitive": (synthetic, None),
}


def measure(rule, measured):
    """(step seconds, primitives of the result, peak RSS bytes) of one run."""
    out = WORK / "out"
    shutil.rmtree(out, ignore_errors=True)
    spawn([str(GRAFTAL), "run", str(rule), "--seeds", "0..1", "-o", str(out / "{seed}.ply"), "--timings", "-q"])
    variant = json.loads((out / "manifest.json").read_text())["variants"][0]
    steps = variant["steps"]
    seconds = (
        sum(s["time_ms"] for s in steps) if measured is None else next(s["time_ms"] for s in steps if s["name"] == measured)
    ) / 1000
    primitives = sum(variant["counts"].values())
    _, _, rss_mib = spawn([str(GRAFTAL), "run", str(rule), "-o", str(WORK / "rss.obj"), "-q"])
    return seconds, primitives, rss_mib * 2**20


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--out", type=Path, default=WORK / "scaling.md")
    parser.add_argument("--only", help="comma-separated words; run the workloads whose title contains one")
    parser.add_argument("--write-soup", nargs=2, metavar=("PATH", "N"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.write_soup:
        write_soup(Path(args.write_soup[0]), int(args.write_soup[1]))
        return
    if not GRAFTAL.exists():
        sys.exit(f"no graftal at {GRAFTAL}: cargo build --release, or set GRAFTAL")
    WORK.mkdir(parents=True, exist_ok=True)
    rows = []
    words = args.only.split(",") if args.only else None
    for index, (title, (make, measured)) in enumerate(WORKLOADS.items()):
        if words and not any(w in title for w in words):
            continue
        cases = []
        for elements in SIZES:
            text, count = make(elements)
            rule = WORK / f"workload{index}-{elements}.toml"
            rule.write_text(text)
            cases.append((rule, count))
        times = [[] for _ in cases]
        facts = [None] * len(cases)
        for _ in range(args.runs):
            for k, (rule, _) in enumerate(cases):
                seconds, primitives, rss = measure(rule, measured)
                times[k].append(seconds)
                facts[k] = (primitives, rss)
        per = []
        for k, (rule, count) in enumerate(cases):
            primitives, rss = facts[k]
            elements = count if count is not None else primitives
            per.append((statistics.median(times[k]) / elements * 1e9, elements, primitives, rss))
        ratio = max(p[0] for p in per) / min(p[0] for p in per)
        rows.append((title, per, ratio))
        print(f"{title}: " + ", ".join(f"{e:,} → {ns:.0f} ns" for ns, e, _, _ in per) + f"; ratio {ratio:.2f}", flush=True)
    lines = [
        "# graftal: time per element from 10^4 to 10^6",
        "",
        f"Command: `GRAFTAL={GRAFTAL} python3 bench-peers/scaling.py --runs {args.runs}`; "
        f"nproc {os.cpu_count()}; median of {args.runs} interleaved rounds; step time from the batch manifest "
        "(`--seeds 0..1 --timings`). RSS: whole process writing OBJ, divided by the result's vertices + edges + faces.",
        "",
        "| workload | ~10⁴ | ~10⁵ | ~10⁶ | largest / smallest | flat (≤ 1.5×) | RSS per primitive at ~10⁶ |",
        "|---|---|---|---|---|---|---|",
    ]
    for title, per, ratio in rows:
        cells = [f"{ns:.0f} ns ({e:,})" for ns, e, _, _ in per]
        _, _, primitives, rss = per[-1]
        lines.append(
            f"| {title} | {' | '.join(cells)} | {ratio:.2f} | {'yes' if ratio <= 1.5 else 'no'} | {rss / primitives:.0f} B |"
        )
    args.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
