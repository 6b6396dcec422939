"""graftal's `bevel` against Blender's `bmesh.ops.bevel`, run inside Blender:

    blender -b --factory-startup --python-exit-code 1 \
        --python tests/blender/bevel.py -- GRAFTAL WORKDIR

Cages made with Blender's primitives (cube, cylinder with n-gon caps,
octahedron-like cone apexes of valence 4 and 8, an open grid whose bevels
reach its boundary), written as OBJ; the same edges (or vertices) are
chosen in Blender by a Python predicate and in graftal by the same
condition as a `select` expression. Both bevel with the same width, offset
type, segments and profile; vertices are matched one to one, face counts
must be equal, each point within TOLERANCE (Blender computes in f32).

Where the definitions differ the script says so and checks less (the
last field of a case: which points are compared, within what, and why):
- with 3 or more segments, a corner where every edge is beveled is filled
  by Blender's subdivision ("adj" pattern) and by graftal's Coons patch:
  only the points on the cube's faces and on the bands' end profiles are
  compared; with an odd count Blender's corner mesh also moves the end
  profiles off the circle (by 1.9e-4 at 3 segments; a vertex bevel's arcs
  in the faces by 5e-3), graftal's stay on it; the centres of vertex
  bevels' corner patches differ too (Blender's 0.94951 on a unit corner cut
  0.3 deep with 2 segments, graftal's 0.93660 on the superellipsoid);
- where a non-beveled edge lies between two beveled ones that run nearly
  straight through a vertex of a bent surface, Blender puts the new point
  where the two offset lines come closest (off the surface, 2.3e-3 above
  it on the grid, and not symmetric: y = 0.500479 against -0.499913);
  graftal keeps it on the edge, where both offset lines reach it on
  average: only the counts and the points away from those vertices are
  compared.
"""

import math
import os
import sys

import bmesh
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import WORK, fresh, match, report, run_graftal, write_obj  # noqa: E402

# f32 positions of size ~1.
TOLERANCE = 2e-6


def cage(kind):
    fresh()
    if kind == "cube":
        bpy.ops.mesh.primitive_cube_add(size=2)
    elif kind == "box":
        bpy.ops.mesh.primitive_cube_add(size=2)
        bpy.context.active_object.data.transform(
            __import__("mathutils").Matrix.Diagonal((1.5, 1.0, 0.6, 1.0))
        )
    elif kind == "cylinder":
        bpy.ops.mesh.primitive_cylinder_add(vertices=8, radius=1, depth=2)
    elif kind == "cone4":
        bpy.ops.mesh.primitive_cone_add(vertices=4, radius1=1, depth=1.5)
    elif kind == "cone8":
        bpy.ops.mesh.primitive_cone_add(vertices=8, radius1=1, depth=1.2)
    elif kind == "grid":
        bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=2)
        # Lift the middle so that the bevels have an angle to work on.
        for v in bpy.context.active_object.data.vertices:
            v.co.z = 0.3 * math.cos(v.co.x * 1.3) * math.cos(v.co.y * 1.1)
    return bpy.context.active_object


def blender_bevel(obj, pick, width, offset_type, segments, profile, vertices, clamp):
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    if vertices:
        geom = [v for v in bm.verts if pick(tuple(v.co))]
    else:
        geom = [
            e for e in bm.edges
            if pick(tuple((a + b) / 2 for a, b in zip(e.verts[0].co, e.verts[1].co)))
        ]
    bmesh.ops.bevel(
        bm,
        geom=geom,
        offset=width,
        offset_type=offset_type.upper(),
        profile_type="SUPERELLIPSE",
        segments=segments,
        profile=profile,
        affect="VERTICES" if vertices else "EDGES",
        clamp_overlap=clamp,
        material=-1,
        loop_slide=False,
        mark_seam=False,
        mark_sharp=False,
        harden_normals=False,
        face_strength_mode="NONE",
        miter_outer="SHARP",
        miter_inner="SHARP",
        spread=0.1,
        vmesh_method="ADJ",
    )
    points = [tuple(v.co) for v in bm.verts]
    faces = len(bm.faces)
    bm.free()
    return points, faces


EVERY = (lambda p: True, "true")
WIDTH = 0.25


def on_cube_faces_or_profiles(p):
    """On a face of the size-2 cube, or on a band's end profile (one
    coordinate at the band's end, the other two on its quarter circle)."""
    inner = 1 - WIDTH
    if any(abs(abs(c) - 1) < 1e-6 for c in p):
        return True
    for i in range(3):
        if abs(abs(p[i]) - inner) < 1e-6:
            a, b = (abs(p[j]) - inner for j in range(3) if j != i)
            if abs(math.hypot(a, b) - WIDTH) < 1e-6:
                return True
    return False


# A vertex bevel's arcs lie in the cube's faces; its corner patches differ.
ON_FACES = (lambda p: any(abs(abs(c) - 1) < 1e-6 for c in p), TOLERANCE)
# With an odd count Blender's corner mesh moves the faces' arcs off the
# circle (0.84725, 0.95549 where the circle has 0.85, 0.95981): only the
# points on the cube's edges (where the cuts start) are compared.
ON_FACES_ODD = (lambda p: sum(abs(abs(c) - 1) < 1e-6 for c in p) >= 2, TOLERANCE)
CORNERS_EVEN = (on_cube_faces_or_profiles, TOLERANCE)
CORNERS_ODD = (on_cube_faces_or_profiles, 2e-4)
# The grid's boundary vertices and the bands' points off its interior
# vertices (where Blender's meet leaves the surface).
GRID_AWAY = (lambda p: abs(abs(p[1]) - 1) < 1e-6, TOLERANCE)
# (label, cage, (predicate, select expression), width, type, segments,
#  profile, vertices, clamp, partial: None (every point) or (which, tolerance))
CASES = [
    ("cube-all-offset-s1", "cube", EVERY, 0.2, "offset", 1, 0.5, False, False, None),
    ("cube-all-width-s1", "cube", EVERY, 0.2, "width", 1, 0.5, False, False, None),
    ("cube-all-depth-s1", "cube", EVERY, 0.2, "depth", 1, 0.5, False, False, None),
    ("cube-all-percent-s1", "cube", EVERY, 20.0, "percent", 1, 0.5, False, False, None),
    ("box-all-percent-s1", "box", EVERY, 15.0, "percent", 1, 0.5, False, False, None),
    ("cube-all-s2", "cube", EVERY, 0.25, "offset", 2, 0.5, False, False, None),
    ("cube-all-p0.25-s2", "cube", EVERY, 0.25, "offset", 2, 0.25, False, False, None),
    ("cube-all-p1-s2", "cube", EVERY, 0.25, "offset", 2, 1.0, False, False, None),
    ("cube-verts-s2", "cube", EVERY, 0.3, "offset", 2, 0.5, True, False, ON_FACES),
    ("cube-verts-s4", "cube", EVERY, 0.3, "offset", 4, 0.5, True, False, ON_FACES),
    ("cube-verts-s3", "cube", EVERY, 0.3, "offset", 3, 0.5, True, False, ON_FACES_ODD),
    ("cylinder-verts-percent-s1", "cylinder", EVERY, 25.0, "percent", 1, 0.5, True, False, None),
    ("cube-all-s3", "cube", EVERY, WIDTH, "offset", 3, 0.5, False, False, CORNERS_ODD),
    ("cube-all-s4", "cube", EVERY, WIDTH, "offset", 4, 0.5, False, False, CORNERS_EVEN),
    ("cube-all-s5", "cube", EVERY, WIDTH, "offset", 5, 0.5, False, False, CORNERS_ODD),
    ("box-all-s1", "box", EVERY, 0.15, "offset", 1, 0.5, False, False, None),
    ("cube-top-ring-s1", "cube", (lambda p: p[2] > 0.5, "center.z > 0.5"), 0.3, "offset", 1, 0.5, False, False, None),
    ("cube-top-ring-s3", "cube", (lambda p: p[2] > 0.5, "center.z > 0.5"), 0.3, "offset", 3, 0.5, False, False, None),
    ("cube-one-edge-s1", "cube", (lambda p: p[0] > 0.5 and p[1] > 0.5, "center.x > 0.5 && center.y > 0.5"), 0.3, "offset", 1, 0.5, False, False, None),
    ("cube-one-edge-s4", "cube", (lambda p: p[0] > 0.5 and p[1] > 0.5, "center.x > 0.5 && center.y > 0.5"), 0.3, "offset", 4, 0.5, False, False, None),
    ("cube-one-edge-p0.25-s3", "cube", (lambda p: p[0] > 0.5 and p[1] > 0.5, "center.x > 0.5 && center.y > 0.5"), 0.3, "offset", 3, 0.25, False, False, None),
    ("cube-one-edge-p0.8-s5", "cube", (lambda p: p[0] > 0.5 and p[1] > 0.5, "center.x > 0.5 && center.y > 0.5"), 0.3, "offset", 5, 0.8, False, False, None),
    ("cylinder-caps-s1", "cylinder", (lambda p: abs(p[2]) > 0.5, "abs(center.z) > 0.5"), 0.1, "offset", 1, 0.5, False, False, None),
    ("cylinder-caps-s2", "cylinder", (lambda p: abs(p[2]) > 0.5, "abs(center.z) > 0.5"), 0.1, "offset", 2, 0.5, False, False, None),
    ("cone4-all-s1", "cone4", EVERY, 0.1, "offset", 1, 0.5, False, False, None),
    ("cone8-apex-s1", "cone8", (lambda p: p[2] > -0.55, "center.z > -0.55"), 0.1, "offset", 1, 0.5, False, False, None),
    ("grid-inner-s1", "grid", (lambda p: abs(p[0]) < 0.01, "abs(center.x) < 0.01"), 0.1, "offset", 1, 0.5, False, False, GRID_AWAY),
    ("cube-verts-s1", "cube", EVERY, 0.3, "offset", 1, 0.5, True, False, None),
    ("cube-clamped-s1", "cube", EVERY, 1.5, "offset", 1, 0.5, False, True, None),
]

failures = []
for label, kind, (pick, expression), width, offset_type, segments, profile, vertices, clamp, partial in CASES:
    obj = cage(kind)
    write_obj(obj.data, os.path.join(WORK, label + "-cage.obj"))
    theirs, their_faces = blender_bevel(obj, pick, width, offset_type, segments, profile, vertices, clamp)
    steps = (
        '\n[[step]]\non = "%s"\nselect = "%s"\nbevel = { width = %r, offset_type = "%s", '
        "segments = %d, profile = %r, clamp_overlap = %s }\n"
        % ("vertices" if vertices else "edges", expression, width, offset_type, segments, profile,
           "true" if clamp else "false")
    )
    ours, our_faces = run_graftal(label, steps)
    if partial is None:
        report(label, ours, our_faces, theirs, their_faces, TOLERANCE, failures)
        continue
    which, tolerance = partial
    ours_known = [p for p in ours if which(p)]
    theirs_known = [p for p in theirs if which(p)]
    pairs = match(ours_known, theirs_known) if len(ours_known) == len(theirs_known) else None
    worst = None if pairs is None else max(d for d, _ in pairs)
    ok = pairs is not None and worst <= tolerance and our_faces == their_faces and len(ours) == len(theirs)
    print(
        "%-44s %6d vertices (Blender %6d), %6d faces (Blender %6d), %d points compared "
        "(the rest differ by design), max deviation %s %s"
        % (label, len(ours), len(theirs), our_faces, their_faces, len(theirs_known),
           "-" if worst is None else "%.2e" % worst, "ok" if ok else "MISMATCH")
    )
    if not ok:
        failures.append(label)
        if pairs is not None:
            for d, i in sorted(pairs, reverse=True)[:4]:
                print("    worst: Blender", theirs_known[i], d)

if failures:
    print("FAILED: " + ", ".join(failures))
    sys.exit(1)
print("PASS: every case matches Blender's bevel")
