#!/usr/bin/env python3
"""What a first-touched page costs on this machine.

    python3 bench-peers/fault_cost.py [MEGABYTES] [ROUNDS]

Maps anonymous memory and writes one byte per 4 KiB page, so every write
takes a page fault (the kernel allocates and zeroes the page); prints the
median time per page over the rounds. Much of a large step's time is
this: the records it makes and the buffers it fills are memory touched
for the first time (issue 38's notes compare each row's fresh memory with
its time). Standard library only.
"""

import mmap
import statistics
import sys
import time

PAGE = 4096


def main():
    megabytes = int(sys.argv[1]) if len(sys.argv) > 1 else 100
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    size = megabytes << 20
    per_page = []
    for _ in range(rounds):
        memory = mmap.mmap(-1, size)
        start = time.perf_counter()
        for offset in range(0, size, PAGE):
            memory[offset] = 1
        per_page.append((time.perf_counter() - start) / (size // PAGE))
        memory.close()
    # The loop itself, without faults: the same writes to pages already touched.
    memory = mmap.mmap(-1, size)
    for offset in range(0, size, PAGE):
        memory[offset] = 1
    start = time.perf_counter()
    for offset in range(0, size, PAGE):
        memory[offset] = 2
    loop = (time.perf_counter() - start) / (size // PAGE)
    memory.close()
    fault = statistics.median(per_page) - loop
    print(
        f"{fault * 1e6:.2f} µs per first-touched 4 KiB page "
        f"({fault * 1e9 / PAGE:.2f} ns per byte; median of {rounds} rounds of {megabytes} MiB, "
        f"loop overhead {loop * 1e9:.0f} ns subtracted)"
    )


if __name__ == "__main__":
    main()
