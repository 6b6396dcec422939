"""Write the peer benchmark's mesh inputs into DIR (run in the bench venv).

    python make_inputs.py DIR

Deterministic: the soup's jitter and the hull's random points come from
numpy's seeded RNG, the icospheres from trimesh.creation. Each mesh is
written as binary PLY (for graftal), .npz (for the Python peers) and, for
CGAL, OFF; the hull's point sets as PLY (vertices only) and .npy; the
bevel workload's quad spheres as PLY and .npz. The subdivide workload's
cage (Blender's Suzanne) is written by run.py through Blender, not here.
"""

import sys
from pathlib import Path

import numpy as np
import trimesh

SEED = 17
SOUP_CELLS, SOUP_SPACING, SOUP_JITTER = 408, 0.01, 1e-6
HULL_KINDS, HULL_SIZES = ("ball", "sphere"), (10_000, 100_000, 1_000_000)
# The bevel workload: quad spheres of N × N cells a cube face, 12 N² edges
# (10,092, 99,372 and 1,002,252).
BEVEL_SIZES = (29, 91, 289)


def grid(nx, ny, spacing):
    """Vertices (row-major, x fastest) and quads of an nx × ny cell grid."""
    xs, ys = np.meshgrid(np.arange(nx + 1) * spacing, np.arange(ny + 1) * spacing)
    verts = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    a = (j * (nx + 1) + i).ravel()
    quads = np.column_stack([a, a + 1, a + nx + 2, a + nx + 1])
    return verts, quads


def triangles(quads):
    return np.vstack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


def soup():
    """The merge workload: every triangle its own three jittered vertices."""
    verts, quads = grid(SOUP_CELLS, SOUP_CELLS, SOUP_SPACING)
    corners = verts[triangles(quads)].reshape(-1, 3)
    rng = np.random.default_rng(SEED)
    corners += rng.uniform(-SOUP_JITTER, SOUP_JITTER, corners.shape)
    return corners, np.arange(len(corners)).reshape(-1, 3)


def selfx():
    """Two overlapping icospheres: 102,400 triangles, 902 crossing pairs."""
    big = trimesh.creation.icosphere(subdivisions=6, radius=1.0)
    small = trimesh.creation.icosphere(subdivisions=5, radius=0.8)
    verts = np.vstack([big.vertices, small.vertices + [0.9, 0.0, 0.0]])
    faces = np.vstack([big.faces, small.faces + len(big.vertices)])
    return verts, faces


def hull_points(kind, n):
    """n points uniform in the unit ball (most inside the hull) or on the
    unit sphere (every one a hull vertex), as tests/qhull/hull.py draws them."""
    rng = np.random.default_rng([SEED, HULL_KINDS.index(kind), n])
    points = rng.normal(size=(n, 3))
    points /= np.linalg.norm(points, axis=1)[:, None]
    if kind == "ball":
        points *= (rng.random(n) ** (1 / 3))[:, None]
    return points


def quad_sphere(n):
    """A closed quad mesh: a cube's faces cut into n × n cells, pushed onto
    the unit sphere (6 n² + 2 vertices: 8 of valence 3, the rest 4;
    12 n² edges; 6 n² quads, outward). Its shortest edge is 0.47 · 2/n
    (at the cube's corners), its longest 2/n."""
    i, j = (c.ravel() for c in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
    faces = []
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3  # e_u × e_v = e_a: counter-clockwise seen from +a
        for side in (0, n):
            quad = []
            for ci, cj in corners:
                p = np.empty((len(i), 3), np.int64)
                p[:, a], p[:, u], p[:, v] = side, ci, cj
                quad.append(p)
            if side == 0:
                quad.reverse()
            faces.append(np.stack(quad, axis=1))
    lattice = np.concatenate(faces).reshape(-1, 3)
    points, index = np.unique(lattice, axis=0, return_inverse=True)
    verts = points * (2.0 / n) - 1.0
    return verts / np.linalg.norm(verts, axis=1)[:, None], index.reshape(-1, 4)


def write_ply(path, verts, faces):
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(verts)}\n"
        "property double x\nproperty double y\nproperty double z\n"
        f"element face {len(faces)}\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    corners = faces.shape[1]
    record = np.dtype([("n", "u1"), ("v", "<i4", corners)], align=False)
    packed = np.empty(len(faces), record)
    packed["n"], packed["v"] = corners, faces
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(np.ascontiguousarray(verts, "<f8").tobytes())
        f.write(packed.tobytes())


def write_off(path, verts, faces):
    with open(path, "w") as f:
        f.write(f"OFF\n{len(verts)} {len(faces)} 0\n")
        np.savetxt(f, verts, fmt="%.17g")
        np.savetxt(f, np.column_stack([np.full(len(faces), 3), faces]), fmt="%d")


def main(out):
    out.mkdir(parents=True, exist_ok=True)
    for name, (verts, faces) in {"soup": soup(), "selfx": selfx()}.items():
        write_ply(out / f"{name}.ply", verts, faces)
        np.savez(out / f"{name}.npz", vertices=verts, faces=faces)
    write_off(out / "selfx.off", *selfx())
    verts, quads = grid(300, 300, 0.01)
    np.savez(out / "quads300.npz", vertices=verts, faces=quads)
    verts, quads = grid(500, 1000, 0.01)
    np.savez(out / "tri1m.npz", vertices=verts, faces=triangles(quads))
    for kind in HULL_KINDS:
        for n in HULL_SIZES:
            points = hull_points(kind, n)
            write_ply(out / f"{kind}{n}.ply", points, np.empty((0, 3), int))
            np.save(out / f"{kind}{n}.npy", points)
    for n in BEVEL_SIZES:
        verts, quads = quad_sphere(n)
        write_ply(out / f"qsphere{n}.ply", verts, quads)
        np.savez(out / f"qsphere{n}.npz", vertices=verts, faces=quads)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
