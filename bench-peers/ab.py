#!/usr/bin/env python3
"""Whole-process A/B timings of two graftal binaries, interleaved.

    python3 bench-peers/ab.py BEFORE AFTER [--rounds 7] [--only grid,extrude,glb,batch]

Runs each workload with BEFORE then AFTER in every round (so both see the
same machine state, hour and load), checks that both wrote the same bytes,
and prints the median wall time of each and their ratio. The
workloads are the ones issue 34 names: a 1000² grid, a million faces
extruded one by one, a GLB of a million triangles (also as PLY, STL and
OBJ: glb-ply, glb-stl, glb-obj), a 1,000-variant batch; and the suite's
soup import with weld and merge (weld, merge: run `make bench-peers` once
first, which writes the soup).
Standard library only; outputs go to a temporary folder (tmpfs when
/dev/shm exists, so disk speed does not enter).
"""

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

INPUTS = ROOT / "target" / "bench-peers" / "inputs"
GRID = "[start]\ngrid = {{ segments = [{n}, {m}], size = [{n}, {m}] }}\n"
TRIANGLES = GRID.format(n=500, m=1000) + "[[step]]\ntriangulate = {}\n"

WORKLOADS = {
    "grid": (GRID.format(n=1000, m=1000), "out.ply", []),
    "extrude": (
        GRID.format(n=1000, m=1000) + "[[step]]\nextrude_faces = { distance = 0.01 }\n",
        "out.ply",
        [],
    ),
    "glb": (TRIANGLES, "out.glb", []),
    # The same million triangles through the other streamed writers (issue 38).
    "glb-ply": (TRIANGLES, "out.ply", []),
    "glb-stl": (TRIANGLES, "out.stl", []),
    "glb-obj": (TRIANGLES, "out.obj", []),
    "batch": (
        ROOT / "rules" / "house.toml",
        "b/{seed}.glb",
        ["--seeds", "0..1000", "-j2", "-q"],
    ),
    # The suite's soup of a million corners (`make bench-peers` writes it
    # first): imported and welded, or imported and then merged.
    "weld": (INPUTS / "weld.toml", "out.ply", []),
    "merge": (INPUTS / "merge.toml", "out.ply", []),
}


def run(binary, workload, scratch):
    text, output, extra = WORKLOADS[workload]
    if isinstance(text, Path):
        rules = str(text)
    else:
        rules = str(scratch / f"{workload}.toml")
        Path(rules).write_text(text)
    out = scratch / "out"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir()
    args = [binary, "run", rules, "-o", str(out / output)] + extra
    start = time.perf_counter()
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    files = {}
    for path in sorted(out.rglob("*")):
        if path.is_file() and not path.name.startswith("manifest"):
            files[str(path.relative_to(out))] = path.read_bytes()
    return wall, files


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("before")
    p.add_argument("after")
    p.add_argument("--rounds", type=int, default=7)
    # By default every workload whose rule file is there (the soup's are
    # written by `make bench-peers`).
    present = [w for w, (text, _, _) in WORKLOADS.items() if not isinstance(text, Path) or text.exists()]
    p.add_argument("--only", default=",".join(present))
    args = p.parse_args()
    base = "/dev/shm" if os.path.isdir("/dev/shm") else None
    with tempfile.TemporaryDirectory(dir=base) as tmp:
        scratch = Path(tmp)
        rows = []
        for workload in args.only.split(","):
            times = {"before": [], "after": []}
            reference = None
            for _ in range(args.rounds):
                for label, binary in (("before", args.before), ("after", args.after)):
                    wall, files = run(binary, workload, scratch)
                    times[label].append(wall)
                    if reference is None:
                        reference = files
                    elif files != reference:
                        sys.exit(f"{workload}: {label} wrote other bytes")
            b, a = statistics.median(times["before"]), statistics.median(times["after"])
            rows.append((workload, b, a, b / a))
            print(
                f"{workload:8} before {b * 1e3:8.1f} ms  after {a * 1e3:8.1f} ms  "
                f"before/after {b / a:5.2f}  (medians of {args.rounds}; outputs identical)",
                flush=True,
            )
        print()
        print("| workload | before | after | before / after |")
        print("|---|---|---|---|")
        for w, b, a, r in rows:
            print(f"| {w} | {b * 1e3:.0f} ms | {a * 1e3:.0f} ms | {r:.2f} |")


if __name__ == "__main__":
    main()
