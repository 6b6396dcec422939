"""What every peer script shares: timing one call and the JSON line it prints."""

import json
import time

import numpy as np


def load(path):
    """Vertices and faces of an .npz written by make_inputs.py."""
    data = np.load(path)
    return data["vertices"], data["faces"]


def timed(fn, *args, **kwargs):
    """(seconds, result) of one call, by time.perf_counter()."""
    start = time.perf_counter()
    result = fn(*args, **kwargs)
    return time.perf_counter() - start, result


def emit(seconds, vertices=None, faces=None, pairs=None, **extra):
    """The one line a peer script prints: the driver reads it."""
    print(
        json.dumps({"seconds": seconds, "vertices": vertices, "faces": faces, "pairs": pairs, **extra}),
        flush=True,
    )
