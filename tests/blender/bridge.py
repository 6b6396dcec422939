"""graftal's `bridge_loops` against Blender's `bmesh.ops.bridge_loops`, run
inside Blender:

    blender -b --factory-startup --python-exit-code 1 \
        --python tests/blender/bridge.py -- GRAFTAL WORKDIR

Each cage (loops of wire edges, some bounding faces) is written as OBJ in
Blender's own vertex and edge order, so both programs list the loops alike.
Cases: parallel circles turned against each other (the best rotation
matters), `twist`, open polylines listed against each other, unequal
counts (8 vs 12, 6 vs 9), three loops chained (listed out of order),
loops bounding faces (the faces' winding decides the band's), and
`segments` against the "Bridge Edge Loops" operator's linear cuts.

Checked: vertices matched one to one within TOLERANCE; with equal counts,
every face of graftal's band is one of Blender's, corners in the same
cyclic order (the same winding).

Where graftal differs on purpose:
- unequal counts: both pair the shorter loop's repeated vertices the same
  way (Blender's `BM_edgeloop_expand`), which gives quads and triangles;
  Blender then triangulates the band and flips diagonals ("beautify"),
  graftal keeps the quads. Checked: the same vertices, graftal's
  triangles are Blender's, each quad is two of Blender's triangles or
  their flipped diagonal (the same four corners), and 2·quads + triangles
  equals Blender's face count;
- `twist`: Blender turns to the `twist_offset`-th *last* vertex, so its
  −1 is no turn and its 1 turns two places; graftal's `twist = t` turns t
  places, Blender's `twist_offset = t − 1` (`len` for t = 1). The script
  checks that Blender's −1 and 0 agree, to catch a fix upstream.
"""

import math
import os
import subprocess
import sys
from math import cos, sin, tau

import bmesh
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import GRAFTAL, WORK, fresh, match  # noqa: E402

TOLERANCE = 1e-6  # the cage is exact in both; Blender stores f32.


def circle(n, radius, z, phase=0.0, start=0, reverse=False):
    pts = [
        (radius * cos(phase + tau * i / n), radius * sin(phase + tau * i / n), z)
        for i in range(n)
    ]
    pts = pts[start:] + pts[:start]
    if reverse:
        pts.reverse()
    return pts, True


def polyline(points, reverse=False):
    pts = list(points)
    if reverse:
        pts.reverse()
    return pts, False


def cage(loops, caps=()):
    """Vertices, edges (index pairs) and faces of LOOPS (lists of points,
    closed or not); CAPS: indices of closed loops to fill with a face,
    +i wound as listed, -i-1 wound against."""
    verts, edges, faces, starts = [], [], [], []
    for pts, closed in loops:
        base = len(verts)
        starts.append(base)
        verts.extend(pts)
        n = len(pts)
        for i in range(n - 1):
            edges.append((base + i, base + i + 1))
        if closed:
            edges.append((base + n - 1, base))
    for c in caps:
        k = c if c >= 0 else -c - 1
        pts, _ = loops[k]
        ring = [starts[k] + i for i in range(len(pts))]
        faces.append(ring if c >= 0 else ring[::-1])
    return verts, edges, faces


def blender_bridge(verts, edges, faces, twist):
    bm = bmesh.new()
    vs = [bm.verts.new(p) for p in verts]
    es = [bm.edges.new((vs[a], vs[b])) for a, b in edges]
    for ring in faces:
        bm.faces.new([vs[i] for i in ring])
    bmesh.ops.bridge_loops(bm, edges=es, twist_offset=twist)
    bm.verts.index_update()
    points = [tuple(v.co) for v in bm.verts]
    out = [[v.index for v in f.verts] for f in bm.faces]
    bm.free()
    return points, out


def blender_cuts(verts, edges, faces, cuts):
    """The "Bridge Edge Loops" operator with `number_cuts`, linear."""
    fresh()
    me = bpy.data.meshes.new("cage")
    me.from_pydata(verts, edges, faces)
    obj = bpy.data.objects.new("cage", me)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_mode(type="EDGE")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.mesh.bridge_edge_loops(number_cuts=cuts, interpolation="LINEAR", smoothness=0.0)
    bpy.ops.object.mode_set(mode="OBJECT")
    points = [tuple(v.co) for v in me.vertices]
    out = [list(p.vertices) for p in me.polygons]
    return points, out


def write_cage(name, verts, edges, faces):
    with open(os.path.join(WORK, name + "-cage.obj"), "w") as f:
        for p in verts:
            f.write("v %r %r %r\n" % p)
        for a, b in edges:
            f.write("l %d %d\n" % (a + 1, b + 1))
        for ring in faces:
            f.write("f " + " ".join(str(i + 1) for i in ring) + "\n")


def run_graftal(name, args):
    rules = os.path.join(WORK, name + ".toml")
    out = os.path.join(WORK, name + ".obj")
    with open(rules, "w") as f:
        f.write('[start]\nimport = { path = "%s-cage.obj" }\n' % name)
        f.write('\n[[step]]\non = "edges"\nbridge_loops = %s\n' % args)
    subprocess.run([GRAFTAL, "run", rules, "-o", out, "--quiet"], check=True)
    points, faces = [], []
    with open(out) as f:
        for line in f:
            if line.startswith("v "):
                points.append(tuple(float(x) for x in line.split()[1:4]))
            elif line.startswith("f "):
                faces.append([int(w.split("/")[0]) - 1 for w in line.split()[1:]])
    return points, faces


def cyclic(ring):
    """A face's corners from its least index, the order kept."""
    k = ring.index(min(ring))
    return tuple(ring[k:] + ring[:k])


def nearest(ours, theirs):
    """For each of OURS, the index of the nearest of THEIRS (the cages are
    small and their points far apart: the one-to-one `match` holds)."""
    return [min(range(len(theirs)), key=lambda i: math.dist(p, theirs[i])) for p in ours]


def compare(label, ours, our_faces, theirs, their_faces, caps, exact, failures):
    pairs = match(ours, theirs) if len(ours) == len(theirs) else None
    problems = []
    worst = None
    if pairs is None:
        problems.append("vertices do not match one to one")
    else:
        worst = max(d for d, _ in pairs)
        if worst > TOLERANCE:
            problems.append("a vertex is %.2e away" % worst)
        # `match` lists its pairs closest first: index them by our vertex.
        to_theirs = nearest(ours, theirs)
        # graftal writes vertices in its own order: map them to Blender's.
        mapped = [cyclic([to_theirs[i] for i in f]) for f in our_faces]
        band = [f for f in mapped if f not in {cyclic(c) for c in caps}]
        blender = [cyclic(f) for f in their_faces]
        their_band = [f for f in blender if f not in {cyclic(c) for c in caps}]
        if exact:
            if sorted(band) != sorted(their_band):
                missing = set(band) ^ set(their_band)
                problems.append("faces differ: %s" % sorted(missing)[:4])
        else:
            tris = {f for f in their_band if len(f) == 3}
            edges_of = lambda f: {frozenset((f[i], f[(i + 1) % len(f)])) for i in range(len(f))}  # noqa: E731
            their_edges = set().union(*(edges_of(f) for f in their_band)) if their_band else set()
            quads = [f for f in band if len(f) == 4]
            if 2 * len(quads) + (len(band) - len(quads)) != len(their_band):
                problems.append("%d quads, %d faces: Blender %d triangles" % (len(quads), len(band), len(their_band)))
            for f in band:
                if len(f) == 3 and f not in tris:
                    problems.append("triangle %s is not Blender's" % (f,))
                    break
                # Each side of a graftal face is a side of Blender's band.
                if not edges_of(f) <= their_edges:
                    problems.append("face %s has a side Blender's band lacks" % (f,))
                    break
            # Winding: no side of a graftal face runs only against
            # Blender's band (Blender's uses inner sides both ways).
            directed = {(f[i], f[(i + 1) % len(f)]) for f in their_band for i in range(len(f))}
            for f in band:
                for i in range(len(f)):
                    side = (f[i], f[(i + 1) % len(f)])
                    if side not in directed:
                        problems.append("face %s wound against Blender's" % (f,))
                        break
                else:
                    continue
                break
    print(
        "%-34s %4d vertices (Blender %4d), %4d faces (Blender %4d), max deviation %s %s"
        % (label, len(ours), len(theirs), len(our_faces), len(their_faces),
           "-" if worst is None else "%.2e" % worst, "ok" if not problems else "MISMATCH: " + "; ".join(problems))
    )
    if problems:
        failures.append(label)


def blender_twist(t, n):
    return n if t == 1 else t - 1


failures = []
wave = [(x * 0.5, 0.1 * (x % 2), 0.0) for x in range(5)]
shifted = [(x * 0.45 + 0.1, 1.2, 0.3 - 0.05 * x) for x in range(5)]
cases = [
    # label, loops, caps, graftal twist, segments
    ("circles-8-turned", [circle(8, 1.0, 0.0), circle(8, 1.1, 1.5, 0.35, start=3)], (), 0, 1),
    ("circles-8-reversed", [circle(8, 1.0, 0.0), circle(8, 1.0, 1.5, -0.3, start=5, reverse=True)], (), 0, 1),
    ("circles-8-twist1", [circle(8, 1.0, 0.0), circle(8, 1.1, 1.5, 0.35, start=3)], (), 1, 1),
    ("circles-8-twist-1", [circle(8, 1.0, 0.0), circle(8, 1.1, 1.5, 0.35, start=3)], (), -1, 1),
    ("circles-8-twist3", [circle(8, 1.0, 0.0), circle(8, 1.1, 1.5, 0.35, start=3)], (), 3, 1),
    ("tilted-6", [circle(6, 1.0, 0.0), ([(x + 0.3, y * 0.8, z + 2.0 + 0.4 * x) for x, y, z in circle(6, 1.0, 0.0, 0.2)[0]], True)], (), 0, 1),
    ("polylines", [polyline(wave), polyline(shifted, reverse=True)], (), 0, 1),
    ("polylines-4-vs-7", [polyline(wave[:4]), polyline([(x * 0.3, 1.0, 0.2) for x in range(7)], reverse=True)], (), 0, 1),
    ("unequal-8-12", [circle(8, 1.0, 0.0), circle(12, 1.5, 1.0, 0.1, start=2)], (), 0, 1),
    ("unequal-12-8", [circle(12, 1.5, 1.0, 0.1, start=5), circle(8, 1.0, 0.0, 0.05)], (), 0, 1),
    ("unequal-6-9", [circle(6, 1.0, 0.0, 0.2), circle(9, 1.2, 1.0, reverse=True)], (), 0, 1),
    ("unequal-3-8", [circle(3, 0.5, 0.0), circle(8, 1.2, 1.0, 0.1)], (), 0, 1),
    ("three-chained", [circle(8, 1.0, 0.0), circle(8, 1.0, 2.0, 0.2, start=4), circle(8, 1.3, 1.0, 0.1, start=1)], (), 0, 1),
    ("capped-6", [circle(6, 1.0, 0.0), circle(6, 1.0, 1.0, 0.1, start=2)], (-1, 1), 0, 1),
    ("capped-inward-6", [circle(6, 1.0, 0.0), circle(6, 1.0, 1.0, 0.1, start=2)], (0, -2), 0, 1),
    ("segments-3", [circle(8, 1.0, 0.0), circle(8, 1.1, 1.5, 0.35, start=3)], (), 0, 3),
]
for label, loops, caps, twist, segments in cases:
    verts, edges, faces = cage(loops, caps)
    write_cage(label, verts, edges, faces)
    n = max(len(p) for p, _ in loops)
    if segments == 1:
        theirs, their_faces = blender_bridge(verts, edges, faces, blender_twist(twist, n) if twist else 0)
    else:
        theirs, their_faces = blender_cuts(verts, edges, faces, segments - 1)
    ours, our_faces = run_graftal(label, "{ twist = %d, segments = %d }" % (twist, segments))
    exact = len({len(p) for p, _ in loops}) == 1
    compare(label, ours, our_faces, theirs, their_faces, faces, exact, failures)

# A control: a pairing one place off must be seen as a mismatch, also
# where only the looser checks of unequal counts apply.
for label, loops in [
    ("control-equal", [circle(8, 1.0, 0.0), circle(8, 1.1, 1.5, 0.35, start=3)]),
    ("control-unequal", [circle(8, 1.0, 0.0), circle(12, 1.5, 1.0, 0.1, start=2)]),
]:
    verts, edges, faces = cage(loops)
    write_cage(label, verts, edges, faces)
    theirs, their_faces = blender_bridge(verts, edges, faces, 0)
    ours, our_faces = run_graftal(label, "{ twist = 1 }")
    caught = []
    compare(label + " (twist 1: must differ)", ours, our_faces, theirs, their_faces, faces,
            len({len(p) for p, _ in loops}) == 1, caught)
    if not caught:
        print("%s: a turned pairing went unnoticed" % label)
        failures.append(label)

# Blender's quirk the twist mapping rests on: its −1 is no turn.
verts, edges, faces = cage([circle(8, 1.0, 0.0), circle(8, 1.1, 1.5, 0.35, start=3)])
zero = blender_bridge(verts, edges, faces, 0)[1]
minus = blender_bridge(verts, edges, faces, -1)[1]
if sorted(map(cyclic, zero)) != sorted(map(cyclic, minus)):
    print("Blender's twist_offset = -1 now differs from 0: revisit blender_twist")
    failures.append("twist-quirk")

if failures:
    print("FAILED: " + ", ".join(failures))
    sys.exit(1)
print("PASS: every case matches Blender's bridge_loops")
