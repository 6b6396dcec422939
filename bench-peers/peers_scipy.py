"""scipy (qhull) on the convex hull workload.

python peers_scipy.py hull points.npy   # scipy.spatial.ConvexHull, qhull's default options
"""

import sys

import numpy as np
from scipy.spatial import ConvexHull

from benchlib import emit, timed


def hull(path):
    """Vertices: qhull's extreme points; faces: its triangles (random points
    are in general position, so graftal's merged faces are triangles too)."""
    points = np.load(path)
    seconds, found = timed(ConvexHull, points)
    emit(seconds, len(found.vertices), len(found.simplices))


if __name__ == "__main__":
    {"hull": hull}[sys.argv[1]](*sys.argv[2:])
