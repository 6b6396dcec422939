"""graftal's `solidify` against Blender's solidify modifier in its simple
("Extrude") mode, run inside Blender:

    blender -b --factory-startup --python-exit-code 1 \
        --python tests/blender/solidify.py -- GRAFTAL WORKDIR

Sheets: a flat 4 x 4 grid, an open cylinder, a hemisphere and Suzanne
(open, curved, with n-gon-free but uneven corners), each with offsets -1, 0
and 1, with and without even thickness, and a negative thickness. The cage
is written as OBJ, graftal runs `solidify` on it, and the vertices are
matched one to one with the modifier's (rim on, high-quality normals off):
the same count, each within TOLERANCE (Blender computes in f32).
"""

import math
import os
import sys

import bmesh
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import WORK, evaluated, fresh, report, run_graftal, write_obj  # noqa: E402

# f32 normals and positions of size ~1, times a thickness of ~0.1-0.3.
TOLERANCE = 2e-6


def even_tolerance(cage, theirs, thickness):
    """With even thickness a vertex whose faces are nearly perpendicular to
    its normal moves by `thickness / cos`, and Blender's f32 error in cos
    grows to an error ~ 1 / cos^2 in the position (Suzanne's ears: cos
    0.00255 moves a vertex 124 thicknesses, where f32 and f64 differ by
    2.7e-5 of it). The bound grows with the square of how far the vertex
    moved, in thicknesses; vertices that move by at most the thickness keep
    TOLERANCE. Blender's result lists one shell, then the other, each in
    the cage's order."""
    n = len(cage)

    def bound(i):
        factor = max(1.0, math.dist(theirs[i], cage[i % n]) / abs(thickness))
        return TOLERANCE * factor * factor

    return bound


def sheet(kind):
    fresh()
    if kind == "grid":
        bpy.ops.mesh.primitive_grid_add(x_subdivisions=5, y_subdivisions=5, size=2)
    elif kind == "open-cylinder":
        bpy.ops.mesh.primitive_cylinder_add(vertices=12, radius=1, depth=2, end_fill_type="NOTHING")
    elif kind == "hemisphere":
        bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8, radius=1)
    elif kind == "suzanne":
        bpy.ops.mesh.primitive_monkey_add()
    obj = bpy.context.active_object
    if kind == "hemisphere":
        bm = bmesh.new()
        bm.from_mesh(obj.data)
        below = [v for v in bm.verts if v.co.z < -1e-6]
        bmesh.ops.delete(bm, geom=below, context="VERTS")
        bm.to_mesh(obj.data)
        bm.free()
    return obj


failures = []
cases = []
for kind in ("grid", "open-cylinder", "hemisphere", "suzanne"):
    for offset in (-1.0, 0.0, 1.0):
        for even in (False, True):
            cases.append((kind, 0.2, offset, even))
cases.append(("hemisphere", -0.15, -1.0, True))
cases.append(("suzanne", -0.15, 0.5, False))
for kind, thickness, offset, even in cases:
    obj = sheet(kind)
    base = "%s-t%g-o%g-%s" % (kind, thickness, offset, "even" if even else "plain")
    write_obj(obj.data, os.path.join(WORK, base + "-cage.obj"))
    cage = [tuple(v.co) for v in obj.data.vertices]
    mod = obj.modifiers.new("solidify", "SOLIDIFY")
    mod.solidify_mode = "EXTRUDE"
    mod.thickness = thickness
    mod.offset = offset
    mod.use_even_offset = even
    mod.use_quality_normals = False
    mod.use_rim = True
    mod.use_rim_only = False
    mod.use_flip_normals = False
    theirs, their_faces = evaluated(obj)
    steps = '\n[[step]]\nsolidify = { thickness = %r, offset = %r, even = %s }\n' % (
        thickness, offset, "true" if even else "false")
    ours, our_faces = run_graftal(base, steps)
    bound = even_tolerance(cage, theirs, thickness) if even else TOLERANCE
    report(base, ours, our_faces, theirs, their_faces, bound, failures)

if failures:
    print("FAILED: " + ", ".join(failures))
    sys.exit(1)
print("PASS: every case matches Blender's solidify modifier")
