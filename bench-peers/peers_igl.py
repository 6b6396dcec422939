"""libigl on the merge workload.

python peers_igl.py merge soup.npz
"""

import sys

import igl

from benchlib import emit, load, timed


def merge(path):
    verts, faces = load(path)
    seconds, (merged, _, _, new_faces) = timed(igl.remove_duplicate_vertices, verts, faces, 1e-4)
    emit(seconds, len(merged), len(new_faces))


if __name__ == "__main__":
    {"merge": merge}[sys.argv[1]](*sys.argv[2:])
