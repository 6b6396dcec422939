#!/usr/bin/env python3
"""Step-time A/B of graftal binaries on one rule file, interleaved.

    python3 bench-peers/stepab.py RULE STEP ROUNDS BIN [BIN ...]

Each round runs every binary once as a one-variant batch (`--seeds 0..1
--timings`) and reads STEP's time from the manifest (`all`: the sum of
every step), so process start-up and the file write do not enter. Prints
the median and the minimum per binary. Standard library only.
"""

import json
import shutil
import statistics
import subprocess
import sys
import tempfile


def main():
    rule, step, rounds, bins = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
    times = {b: [] for b in bins}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(rounds):
            for b in bins:
                out = f"{tmp}/out"
                shutil.rmtree(out, ignore_errors=True)
                subprocess.run(
                    [b, "run", rule, "--seeds", "0..1", "-o", out + "/{seed}.ply", "--timings", "-q"],
                    check=True,
                    stdout=subprocess.DEVNULL,
                )
                with open(out + "/manifest.json") as f:
                    steps = json.load(f)["variants"][0]["steps"]
                ms = sum(s["time_ms"] for s in steps) if step == "all" else next(
                    s["time_ms"] for s in steps if s["name"] == step
                )
                times[b].append(ms)
    for b in bins:
        print(f"{statistics.median(times[b]):9.1f} ms  min {min(times[b]):9.1f}  {b}")


if __name__ == "__main__":
    main()
