"""graftal's `subdivide` against Blender's subdivision-surface modifier
(OpenSubdiv), run inside Blender:

    blender -b --factory-startup --python-exit-code 1 \
        --python tests/blender/subdivide.py -- GRAFTAL WORKDIR

For each cage (Blender's cube, its Suzanne, an open grid, a cube with
semi-sharp creases, a triangulated cube, an n-gon prism; both boundary
rules on the grid; the simple scheme on Suzanne) and each level 1-3,
it writes the cage as OBJ, runs `graftal run` on a rule file that imports
it (and creases the same edges, selected by the same condition), and
compares graftal's vertices with the modifier's (limit surface off,
boundary "Keep Corners" or "All", creases on): the same count, and every vertex of
each within TOLERANCE of one of the other (a one-to-one match through a
spatial hash). Blender keeps positions in f32 and OpenSubdiv's CPU
evaluator adds in f32, so the bar is f32 rounding, not 1e-9: graftal works
in f64 and is the more exact of the two. Prints the largest deviation of
each case; exits 1 on any mismatch.
"""

import os
import sys

import bmesh
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import WORK, evaluated, fresh, report, run_graftal, write_obj  # noqa: E402

# f32 rounding of coordinates of size ~1 through three levels of f32 sums.
TOLERANCE = 2e-6


def cage(kind):
    """A new object of the cage `kind`; its crease predicate (or None)."""
    fresh()
    crease = None
    if kind in ("cube", "creased-cube", "triangulated-cube"):
        bpy.ops.mesh.primitive_cube_add(size=2)
    elif kind == "suzanne":
        bpy.ops.mesh.primitive_monkey_add()
    elif kind == "grid":
        bpy.ops.mesh.primitive_grid_add(x_subdivisions=5, y_subdivisions=4, size=2)
    elif kind == "ngon-prism":
        bpy.ops.mesh.primitive_cylinder_add(vertices=7, radius=1, depth=1)
    obj = bpy.context.active_object
    me = obj.data
    bm = bmesh.new()
    bm.from_mesh(me)
    if kind == "creased-cube":
        # The top face's four edges at crease 0.6 (sharpness 10 * 0.36 =
        # 3.6: sharp for three levels, blended in the fourth) and one
        # vertical edge at 0.3 (0.9: blended at once).
        layer = bm.edges.layers.crease.verify()
        for e in bm.edges:
            zs = [v.co.z for v in e.verts]
            xs = [v.co.x for v in e.verts]
            ys = [v.co.y for v in e.verts]
            if min(zs) > 0.99:
                e[layer] = 0.6
            elif min(xs) > 0.99 and min(ys) > 0.99:
                e[layer] = 0.3
        crease = [
            ("center.z > 0.99", 10 * 0.6 * 0.6),
            ("center.x > 0.99 && center.y > 0.99 && abs(center.z) < 0.5", 10 * 0.3 * 0.3),
        ]
    if kind == "triangulated-cube":
        bmesh.ops.triangulate(bm, faces=bm.faces[:])
    bm.to_mesh(me)
    bm.free()
    return obj, crease


def blender_points(obj, levels, kind, boundary):
    mod = obj.modifiers.new("subsurf", "SUBSURF")
    mod.subdivision_type = "SIMPLE" if kind == "simple" else "CATMULL_CLARK"
    mod.levels = levels
    mod.render_levels = levels
    mod.use_limit_surface = False
    mod.boundary_smooth = "ALL" if boundary == "smooth" else "PRESERVE_CORNERS"
    mod.use_creases = True
    points, faces = evaluated(obj)
    obj.modifiers.remove(mod)
    return points, faces


failures = []
cases = [
    ("cube", "catmull_clark", "keep_corners"),
    ("suzanne", "catmull_clark", "keep_corners"),
    ("grid", "catmull_clark", "keep_corners"),
    ("grid", "catmull_clark", "smooth"),
    ("creased-cube", "catmull_clark", "keep_corners"),
    ("triangulated-cube", "catmull_clark", "keep_corners"),
    ("ngon-prism", "catmull_clark", "keep_corners"),
    ("suzanne", "simple", "keep_corners"),
]
for kind, scheme, boundary in cases:
    for levels in (1, 2, 3):
        obj, crease = cage(kind)
        base = "%s-%s-%s" % (kind, scheme, boundary)
        write_obj(obj.data, os.path.join(WORK, base + "-cage.obj"))
        theirs, their_faces = blender_points(obj, levels, scheme, boundary)
        steps = "".join(
            '\n[[step]]\non = "edges"\nselect = "%s"\ncrease = { sharpness = %r }\n' % c
            for c in crease or []
        )
        steps += '\n[[step]]\nsubdivide = { levels = %d, scheme = "%s", boundary = "%s" }\n' % (
            levels, scheme, boundary)
        ours, our_faces = run_graftal("%s-L%d" % (base, levels), steps)
        label = "%s level %d" % (base, levels)
        report(label, ours, our_faces, theirs, their_faces, TOLERANCE, failures)

if failures:
    print("FAILED: " + ", ".join(failures))
    sys.exit(1)
print("PASS: every case matches Blender's subdivision-surface modifier")
