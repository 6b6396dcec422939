"""graftal's `convex_hull` against qhull (scipy.spatial.ConvexHull):

    python hull.py GRAFTAL WORKDIR

Each point set is written as an OBJ of lone vertices; graftal imports it,
takes the hull and deletes the input. Checked against qhull on the same
points: the same hull vertices (the first of coincident points), volume
and area to 1e-12 relative, and in general position the same triangles
(`triangulate = true`); on degenerate sets (a lattice with duplicates, a
cylinder's rings) graftal's merged polygons are counted against what they
must be. Prints graftal's and qhull's times side by side (one process run
each, graftal's including its file reading and writing).
"""

import os
import subprocess
import sys
import time

import numpy as np
from scipy.spatial import ConvexHull

GRAFTAL, WORK = sys.argv[1], sys.argv[2]
REL = 1e-12


def point_sets():
    rng = np.random.default_rng(35)
    ball = rng.normal(size=(10000, 3))
    ball *= (rng.random(10000) ** (1 / 3) / np.linalg.norm(ball, axis=1))[:, None]
    sphere = rng.normal(size=(10000, 3))
    sphere /= np.linalg.norm(sphere, axis=1)[:, None]
    yield "ball-10000", ball, None
    yield "sphere-10000", sphere, None
    yield "cube-10000", rng.random((10000, 3)) * 2 - 1, None
    yield "gauss-100000", rng.normal(size=(100000, 3)), None
    g = np.arange(6, dtype=float)
    lattice = np.array([(x, y, z) for x in g for y in g for z in g])
    lattice = np.concatenate([lattice, lattice[::7]])  # duplicates
    yield "lattice-6", lattice, (8, 6)
    t = np.linspace(0, 2 * np.pi, 32, endpoint=False)
    ring = np.stack([np.cos(t), np.sin(t)], axis=1)
    rings = [np.column_stack([ring, np.full(32, z)]) for z in (-1.0, 0.0, 0.5, 1.0)]
    yield "cylinder-rings", np.concatenate(rings + [np.zeros((5, 3))]), (64, 34)


def graftal_hull(name, points, triangulate):
    obj = os.path.join(WORK, name + "-points.obj")
    with open(obj, "w") as f:
        for p in points:
            f.write("v %r %r %r\n" % (float(p[0]), float(p[1]), float(p[2])))
    rules = os.path.join(WORK, name + ".toml")
    with open(rules, "w") as f:
        f.write(
            '[start]\nimport = { path = "%s-points.obj" }\n\n'
            "[[step]]\nconvex_hull = { triangulate = %s }\n\n"
            '[[step]]\non = "vertices"\nselect = "faces == 0"\ndelete = {}\n'
            % (name, "true" if triangulate else "false")
        )
    out = os.path.join(WORK, name + ".obj")
    began = time.perf_counter()
    subprocess.run([GRAFTAL, "run", rules, "-o", out, "--quiet"], check=True)
    took = time.perf_counter() - began
    verts, faces = [], []
    with open(out) as f:
        for line in f:
            if line.startswith("v "):
                verts.append(tuple(float(x) for x in line.split()[1:4]))
            elif line.startswith("f "):
                faces.append([int(x.split("/")[0]) - 1 for x in line.split()[1:]])
    return verts, faces, took


def measure(verts, faces):
    v = np.array(verts)
    volume = area = 0.0
    for f in faces:
        for k in range(1, len(f) - 1):
            a, b, c = v[f[0]], v[f[k]], v[f[k + 1]]
            volume += np.dot(a, np.cross(b, c)) / 6
            area += np.linalg.norm(np.cross(b - a, c - a)) / 2
    return volume, area


failures = []
for name, points, expect in point_sets():
    first = {}
    for i, p in enumerate(points):
        first.setdefault(tuple(map(float, p)), i)
    began = time.perf_counter()
    hull = ConvexHull(points)
    qhull_took = time.perf_counter() - began
    theirs = sorted({first[tuple(map(float, points[i]))] for i in hull.vertices})
    for triangulate in (True, False):
        verts, faces, took = graftal_hull(name, points, triangulate)
        ours_idx = [first[v] for v in verts]
        ours = sorted(set(ours_idx))
        volume, area = measure(verts, faces)
        problems = []
        if ours != theirs:
            problems.append("vertices %d vs qhull %d" % (len(ours), len(theirs)))
        if abs(volume - hull.volume) > REL * hull.volume:
            problems.append("volume %.17g vs %.17g" % (volume, hull.volume))
        if abs(area - hull.area) > REL * hull.area:
            problems.append("area %.17g vs %.17g" % (area, hull.area))
        if triangulate and expect is None:
            ours_t = sorted(tuple(sorted(ours_idx[i] for i in f)) for f in faces)
            theirs_t = sorted(
                tuple(sorted(first[tuple(map(float, points[i]))] for i in s)) for s in hull.simplices
            )
            if ours_t != theirs_t:
                problems.append("triangles differ")
        if not triangulate and expect is not None and (len(ours), len(faces)) != expect:
            problems.append("%d vertices, %d faces; expected %s" % (len(ours), len(faces), expect))
        print(
            "%-16s %-11s %6d points: %5d hull vertices, %5d faces, volume %.6f; graftal %.3f s, qhull %.3f s %s"
            % (name, "triangles" if triangulate else "polygons", len(points), len(ours), len(faces),
               volume, took, qhull_took, "ok" if not problems else "MISMATCH: " + "; ".join(problems))
        )
        if problems:
            failures.append("%s (%s)" % (name, "triangles" if triangulate else "polygons"))

if failures:
    print("FAILED: " + ", ".join(failures))
    sys.exit(1)
print("PASS: every hull matches qhull")
