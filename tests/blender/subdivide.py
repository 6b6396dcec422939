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

import math
import os
import subprocess
import sys

import bmesh
import bpy

# f32 rounding of coordinates of size ~1 through three levels of f32 sums.
TOLERANCE = 2e-6

argv = sys.argv[sys.argv.index("--") + 1 :]
GRAFTAL, WORK = argv[0], argv[1]
os.makedirs(WORK, exist_ok=True)


def fresh():
    bpy.ops.object.select_all(action="SELECT")
    bpy.ops.object.delete()


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


def write_obj(me, path):
    with open(path, "w") as f:
        for v in me.vertices:
            f.write("v %r %r %r\n" % (v.co.x, v.co.y, v.co.z))
        for p in me.polygons:
            f.write("f " + " ".join(str(i + 1) for i in p.vertices) + "\n")


def blender_points(obj, levels, kind, boundary):
    mod = obj.modifiers.new("subsurf", "SUBSURF")
    mod.subdivision_type = "SIMPLE" if kind == "simple" else "CATMULL_CLARK"
    mod.levels = levels
    mod.render_levels = levels
    mod.use_limit_surface = False
    mod.boundary_smooth = "ALL" if boundary == "smooth" else "PRESERVE_CORNERS"
    mod.use_creases = True
    deps = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(deps)
    me = evaluated.to_mesh()
    points = [tuple(v.co) for v in me.vertices]
    faces = len(me.polygons)
    evaluated.to_mesh_clear()
    obj.modifiers.remove(mod)
    return points, faces


def graftal_points(name, levels, scheme, boundary, crease):
    rules = os.path.join(WORK, name + ".toml")
    out = os.path.join(WORK, name + ".obj")
    with open(rules, "w") as f:
        f.write('[start]\nimport = { path = "%s-cage.obj" }\n' % name.rsplit("-L", 1)[0])
        for where, sharpness in crease or []:
            f.write(
                '\n[[step]]\non = "edges"\nselect = "%s"\ncrease = { sharpness = %r }\n'
                % (where, sharpness)
            )
        f.write(
            '\n[[step]]\nsubdivide = { levels = %d, scheme = "%s", boundary = "%s" }\n'
            % (levels, scheme, boundary)
        )
    subprocess.run([GRAFTAL, "run", rules, "-o", out, "--quiet"], check=True)
    points, faces = [], 0
    with open(out) as f:
        for line in f:
            if line.startswith("v "):
                points.append(tuple(float(x) for x in line.split()[1:4]))
            elif line.startswith("f "):
                faces += 1
    return points, faces


def match(ours, theirs):
    """The largest distance of a one-to-one nearest match, or None."""
    cell = 1e-3
    grid = {}
    for i, p in enumerate(theirs):
        grid.setdefault(tuple(math.floor(c / cell) for c in p), []).append(i)
    used = set()
    worst = 0.0
    for p in ours:
        key = tuple(math.floor(c / cell) for c in p)
        best, best_d = None, None
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    for i in grid.get((key[0] + dx, key[1] + dy, key[2] + dz), ()):
                        if i in used:
                            continue
                        d = math.dist(p, theirs[i])
                        if best_d is None or d < best_d:
                            best, best_d = i, d
        if best is None:
            return None
        used.add(best)
        worst = max(worst, best_d)
    return worst


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
        ours, our_faces = graftal_points(
            "%s-L%d" % (base, levels), levels, scheme, boundary, crease
        )
        worst = match(ours, theirs) if len(ours) == len(theirs) else None
        ok = worst is not None and worst <= TOLERANCE and our_faces == their_faces
        print(
            "%-44s level %d: %6d vertices (Blender %6d), %6d faces (Blender %6d), max deviation %s %s"
            % (base, levels, len(ours), len(theirs), our_faces, their_faces,
               "-" if worst is None else "%.2e" % worst, "ok" if ok else "MISMATCH")
        )
        if not ok:
            failures.append("%s level %d" % (base, levels))

if failures:
    print("FAILED: " + ", ".join(failures))
    sys.exit(1)
print("PASS: every case matches Blender's subdivision-surface modifier")
