"""What the machine charges before any computing: first touches of fresh
memory and writing a file. Standard library only.

    python3 bench-peers/floor.py [--runs 5] [--dir target/bench-peers]

graftal's big kernel operators write their new records once, front to back,
into memory the process has just obtained; a 4 KiB page costs a fault on
its first write, in which the OS allocates and zeroes it. This measures
that cost on anonymous memory of the sizes the issue-17 workloads write
(records: vertex 32 B, edge 28 B, loop 28 B, face 32 B; and, beside
triangulate's, the index array trimesh writes for the same triangles), touching one byte
a page twice: the first pass pays the faults, the second only the loop, and
the difference is the faults. It also times writing a 24 MB file (the
1M-triangle GLB) beside renaming it over an existing one, as graftal's
staged writes do. Medians of --runs.
"""

import argparse
import mmap
import os
import statistics
import time
from pathlib import Path

PAGE = 4096
MB = 1 << 20

# Bytes of kernel records each workload writes: (verts, edges, loops, faces).
RECORDS = {"vertex": 32, "edge": 28, "loop": 28, "face": 32}
WORKLOADS = {
    "grid 1000² (1,002,001 v, 2,002,000 e, 4M loops, 1M f)": (1_002_001, 2_002_000, 4_000_000, 1_000_000),
    "extrude 1M faces (4M v, 8M e, 20M loops, 5M f new)": (4_000_000, 8_000_000, 20_000_000, 5_000_000),
    "triangulate 300² (90k e, 180k loops, 90k f new)": (0, 90_000, 180_000, 90_000),
}
# Fresh bytes a peer writes for the same result: trimesh's triangulated
# 300² grid, 180k triangles of three int64 indices.
PEER_WRITES = {"trimesh triangulate_quads 300² (180k × 3 int64)": 180_000 * 3 * 8}


def record_bytes(counts):
    v, e, l, f = counts
    return v * RECORDS["vertex"] + e * RECORDS["edge"] + l * RECORDS["loop"] + f * RECORDS["face"]


def first_touch_ms(size):
    """Milliseconds the faults of `size` fresh bytes cost (first pass − second pass)."""
    pages = size // PAGE
    # Private, like the heap (a plain mmap(-1, n) is shared memory, dearer).
    with mmap.mmap(-1, pages * PAGE, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS) as m:
        passes = []
        for _ in range(2):
            start = time.perf_counter()
            for i in range(0, pages * PAGE, PAGE):
                m[i] = 1
            passes.append(time.perf_counter() - start)
    return (passes[0] - passes[1]) * 1e3


def file_write_ms(directory, size):
    data = os.urandom(size)
    target = directory / "floor-test.bin"
    temp = directory / ".floor-test.tmp"
    start = time.perf_counter()
    with open(temp, "wb") as f:
        f.write(data)
    written = time.perf_counter()
    os.replace(temp, target)
    renamed = time.perf_counter()
    return (written - start) * 1e3, (renamed - written) * 1e3


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--dir", type=Path, default=Path(__file__).resolve().parent.parent / "target" / "bench-peers")
    args = p.parse_args()
    args.dir.mkdir(parents=True, exist_ok=True)

    print("| fresh memory written once | bytes | first-touch faults (median) | per 4 KiB page |")
    print("|---|---|---|---|")
    sizes = [(name, record_bytes(counts)) for name, counts in WORKLOADS.items()]
    for name, size in sizes + list(PEER_WRITES.items()):
        ms = statistics.median(first_touch_ms(size) for _ in range(args.runs))
        print(f"| {name} | {size / MB:.1f} MiB | {ms:.0f} ms | {ms * 1e3 / (size / PAGE):.2f} µs |")
    writes = [file_write_ms(args.dir, 24_037_000) for _ in range(args.runs)]
    print()
    print(
        f"24 MB file: write {statistics.median(w for w, _ in writes):.1f} ms, "
        f"rename over the previous one {statistics.median(r for _, r in writes):.1f} ms (medians)"
    )
    (args.dir / "floor-test.bin").unlink(missing_ok=True)


if __name__ == "__main__":
    main()
