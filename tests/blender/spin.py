"""graftal's `spin` against Blender's `bmesh.ops.spin`, run inside Blender:

    blender -b --factory-startup --python-exit-code 1 \
        --python tests/blender/spin.py -- GRAFTAL WORKDIR

Profiles (an open polyline off the axis, a vase profile touching the axis
at both ends, lone vertices), angles (full turns, 90, -135 degrees), axes
and centres. Blender spins with `use_merge` at a full turn; where the
profile touches the axis its copies are merged by `remove_doubles` (what
graftal does by construction). Vertices matched one to one, face counts
equal, within TOLERANCE (Blender rotates in f32, step after step).
"""

import math
import os
import sys

import bmesh
from mathutils import Matrix, Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import WORK, report, run_graftal  # noqa: E402

TOLERANCE = 2e-6

PROFILES = {
    "polyline": ([(1.0, 0.0, -1.0), (1.3, 0.0, -0.5), (0.8, 0.0, 0.2), (1.1, 0.0, 0.9)], True),
    "vase": ([(0.0, 0.0, -1.0), (0.9, 0.0, -0.8), (0.5, 0.0, 0.4), (0.7, 0.0, 0.8), (0.0, 0.0, 1.0)], True),
    "points": ([(1.0, 0.0, 0.0), (0.5, 0.5, 0.3)], False),
}


def blender_spin(points, with_edges, angle, steps, axis, center):
    bm = bmesh.new()
    verts = [bm.verts.new(p) for p in points]
    edges = [bm.edges.new((a, b)) for a, b in zip(verts, verts[1:])] if with_edges else []
    full = abs(angle) == 360
    bmesh.ops.spin(
        bm,
        geom=verts + edges,
        cent=Vector(center),
        axis=Vector(axis),
        dvec=Vector((0, 0, 0)),
        angle=math.radians(angle),
        space=Matrix.Identity(4),
        steps=steps,
        use_merge=full,
        use_normal_flip=False,
        use_duplicate=False,
    )
    # graftal keeps a profile vertex on the axis single (a pole).
    bmesh.ops.remove_doubles(bm, verts=bm.verts[:], dist=1e-6)
    points = [tuple(v.co) for v in bm.verts]
    faces = len(bm.faces)
    bm.free()
    return points, faces


failures = []
cases = [
    ("polyline", 360, 16, (0, 0, 1), (0, 0, 0)),
    ("polyline", 90, 5, (0, 0, 1), (0, 0, 0)),
    ("polyline", -135, 7, (0, 0, 1), (0, 0, 0)),
    ("polyline", 200, 9, (1, 1, 0.5), (0.2, -0.3, 0.1)),
    ("vase", 360, 24, (0, 0, 1), (0, 0, 0)),
    ("vase", 180, 6, (0, 0, 1), (0, 0, 0)),
    ("points", 360, 12, (0, 0, 1), (0, 0, 0)),
    ("points", 75, 3, (0, 1, 0), (0, 0, 0.5)),
]
for kind, angle, steps, axis, center in cases:
    points, with_edges = PROFILES[kind]
    base = "%s-a%g-s%d-axis%g_%g_%g" % (kind, angle, steps, *axis)
    with open(os.path.join(WORK, base + "-cage.obj"), "w") as f:
        for p in points:
            f.write("v %r %r %r\n" % p)
        if with_edges:
            for i in range(1, len(points)):
                f.write("l %d %d\n" % (i, i + 1))
    theirs, their_faces = blender_spin(points, with_edges, angle, steps, axis, center)
    on = "edges" if with_edges else "vertices"
    steps_toml = (
        '\n[[step]]\non = "%s"\nspin = { angle = %r, steps = %d, axis = [%r, %r, %r], '
        "center = [%r, %r, %r] }\n" % (on, float(angle), steps, *map(float, axis), *map(float, center))
    )
    ours, our_faces = run_graftal(base, steps_toml)
    report(base, ours, our_faces, theirs, their_faces, TOLERANCE, failures)

if failures:
    print("FAILED: " + ", ".join(failures))
    sys.exit(1)
print("PASS: every case matches Blender's spin")
