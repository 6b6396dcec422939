"""What the Blender oracle scripts share: a clean scene, a mesh written as
OBJ with exact coordinates, graftal run on a rule file, and a one-to-one
nearest match of two point sets. Imported by the scripts run inside
`blender -b` (tests/blender/run.sh skips files starting with "_")."""

import math
import os
import subprocess
import sys

import bpy

argv = sys.argv[sys.argv.index("--") + 1 :]
GRAFTAL, WORK = argv[0], argv[1]
os.makedirs(WORK, exist_ok=True)


def fresh():
    bpy.ops.object.select_all(action="SELECT")
    bpy.ops.object.delete()


def write_obj(me, path):
    with open(path, "w") as f:
        for v in me.vertices:
            f.write("v %r %r %r\n" % (v.co.x, v.co.y, v.co.z))
        for p in me.polygons:
            f.write("f " + " ".join(str(i + 1) for i in p.vertices) + "\n")


def match(ours, theirs):
    """A one-to-one match of OURS with THEIRS that pairs closest points
    first (so two shells passing within a cell of each other do not steal
    each other's points): (distance, index in THEIRS) for each point of
    OURS, or None when some point has no partner within a cell (1e-3)."""
    cell = 1e-3
    grid = {}
    for i, p in enumerate(theirs):
        grid.setdefault(tuple(math.floor(c / cell) for c in p), []).append(i)
    candidates = []
    for j, p in enumerate(ours):
        key = tuple(math.floor(c / cell) for c in p)
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    for i in grid.get((key[0] + dx, key[1] + dy, key[2] + dz), ()):
                        candidates.append((math.dist(p, theirs[i]), j, i))
    candidates.sort()
    ours_done, theirs_done = set(), set()
    pairs = []
    for d, j, i in candidates:
        if j in ours_done or i in theirs_done:
            continue
        ours_done.add(j)
        theirs_done.add(i)
        pairs.append((d, i))
    if len(ours_done) != len(ours):
        return None
    return pairs


def run_graftal(name, steps):
    """Runs a rule file that imports NAME-cage.obj (from WORK) then STEPS
    (TOML text); the output's vertices and its face count."""
    rules = os.path.join(WORK, name + ".toml")
    out = os.path.join(WORK, name + ".obj")
    with open(rules, "w") as f:
        f.write('[start]\nimport = { path = "%s-cage.obj" }\n' % name.rsplit("-L", 1)[0])
        f.write(steps)
    subprocess.run([GRAFTAL, "run", rules, "-o", out, "--quiet"], check=True)
    points, faces = [], 0
    with open(out) as f:
        for line in f:
            if line.startswith("v "):
                points.append(tuple(float(x) for x in line.split()[1:4]))
            elif line.startswith("f "):
                faces += 1
    return points, faces


def evaluated(obj):
    """The positions and face count of OBJ with its modifiers applied."""
    deps = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(deps)
    me = ev.to_mesh()
    points = [tuple(v.co) for v in me.vertices]
    faces = len(me.polygons)
    ev.to_mesh_clear()
    return points, faces


def report(label, ours, our_faces, theirs, their_faces, tolerance, failures):
    """Prints one case's line; records it in FAILURES when it differs.
    TOLERANCE: one distance, or a function of the index in THEIRS."""
    pairs = match(ours, theirs) if len(ours) == len(theirs) else None
    bound = tolerance if callable(tolerance) else (lambda i: tolerance)
    worst = None if pairs is None else max((d for d, _ in pairs), default=0.0)
    ok = (
        pairs is not None
        and all(d <= bound(i) for d, i in pairs)
        and our_faces == their_faces
    )
    print(
        "%-44s %6d vertices (Blender %6d), %6d faces (Blender %6d), max deviation %s %s"
        % (label, len(ours), len(theirs), our_faces, their_faces,
           "-" if worst is None else "%.2e" % worst, "ok" if ok else "MISMATCH")
    )
    if not ok:
        failures.append(label)
