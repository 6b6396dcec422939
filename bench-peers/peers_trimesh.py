"""trimesh on the mesh workloads.

python peers_trimesh.py merge soup.npz
python peers_trimesh.py triangulate quads300.npz
python peers_trimesh.py glb tri1m.npz OUT.glb
python peers_trimesh.py glb-normals tri1m.npz OUT.glb
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
    """trimesh's default GLB: positions and indices, no normals (18 MB)."""
    mesh = trimesh.Trimesh(*load(path), process=False)
    seconds, _ = timed(mesh.export, out, file_type="glb")
    emit(seconds, len(mesh.vertices), len(mesh.faces), bytes=os.path.getsize(out))


def glb_normals(path, out):
    """The file graftal writes: positions, normals and indices (24 MB).
    The vertex normals are computed (and cached) before the clock starts,
    as graftal's stored face normals are made by its steps."""
    mesh = trimesh.Trimesh(*load(path), process=False)
    _ = mesh.vertex_normals
    seconds, _ = timed(mesh.export, out, file_type="glb", include_normals=True)
    emit(seconds, len(mesh.vertices), len(mesh.faces), bytes=os.path.getsize(out))


if __name__ == "__main__":
    {"merge": merge, "triangulate": triangulate, "glb": glb, "glb-normals": glb_normals}[sys.argv[1]](*sys.argv[2:])
