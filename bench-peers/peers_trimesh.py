"""trimesh on the mesh workloads.

python peers_trimesh.py merge soup.npz
python peers_trimesh.py triangulate quads300.npz
python peers_trimesh.py glb tri1m.npz OUT.glb
"""

import os
import sys

import trimesh

from benchlib import emit, load, timed


def merge(path):
    """Rounding to 4 digits and hashing: not a true distance test."""
    mesh = trimesh.Trimesh(*load(path), process=False)
    seconds, _ = timed(mesh.merge_vertices, digits_vertex=4)
    emit(seconds, len(mesh.vertices), len(mesh.faces))


def triangulate(path):
    verts, quads = load(path)
    seconds, tris = timed(trimesh.geometry.triangulate_quads, quads)
    emit(seconds, len(verts), len(tris))


def glb(path, out):
    mesh = trimesh.Trimesh(*load(path), process=False)
    seconds, _ = timed(mesh.export, out, file_type="glb")
    emit(seconds, len(mesh.vertices), len(mesh.faces), bytes=os.path.getsize(out))


if __name__ == "__main__":
    {"merge": merge, "triangulate": triangulate, "glb": glb}[sys.argv[1]](*sys.argv[2:])
