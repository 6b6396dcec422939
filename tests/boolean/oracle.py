"""graftal's `boolean` against manifold3d (Manifold's mesh booleans):

    python oracle.py GRAFTAL WORKDIR [FILTER]

Each case is two closed, outward-wound operands written as binary PLY
(a.ply, b.ply) and a rule file that imports A, imports B into the part
`cutter` and combines them with `boolean = { operation, with = "cutter" }`;
graftal writes the result as PLY, manifold3d computes the same operation on
the same float64 coordinates. Checked on graftal's output: every undirected
edge used exactly twice, once each way (closed, edge-manifold), and against
manifold: the signed volume (divergence theorem in float64, polygons fanned)
to 1e-9 relative, the number of edge-connected components and each one's
volume and genus (a cavity is a component of negative volume, as Manifold's
`decompose` gives it), and no two faces crossing (`graftal info`'s exact
search; solids of a touching case that meet along an edge or at a point,
each with its own vertices there, are excused).

The cases (deterministic, numpy's seeded RNG): 100 random pairs of cubes,
rotated boxes, UV spheres and icospheres, overlapping in general position,
disjoint or nested, the operation cycling through union, difference and
intersection; a rod drilled through a ball (genus 1) and a slab cutting
one in two; Blender's Suzanne, made by `blender -b` at test time and closed
by a voxel remesh (~21,000 triangles), turned at random against each kind
and against herself (15 cases; left out, with a note, where Blender is not
installed), and Suzanne as Blender makes her, open, refused with her 42
boundary edges counted. Then touching contacts, which graftal computes on its exact
path: hand-made pairs of axis-aligned cubes (touching faces, coplanar
faces, equal cubes), 100 random pairs of boxes on a lattice of 1/4
(stacked, flush, sharing faces, meeting along edges or at corners; their
exact volumes by inclusion-exclusion), and spheres cut at their equator
and meridian, resting on a box or on each other, equal, or inscribed in a
cube, a turned box and its copy sharing a face, a window cutter flush
with a wall. A refusal (exit non-zero, not a panic, naming the step
`boolean`) passes only for a touching case whose message says the
result's solids meet only along an edge. Components of no volume in
manifold's result (flat leftovers of faces two operands share) are not
compared. Before any
case the oracle checks itself: each operand closed, genus 0, its volume
equal to manifold's and, for boxes, to the exact one; manifold's three
volumes adding up (V(A u B) + V(A n B) = V(A) + V(B) to ~1e-15); and
graftal reading back the PLY the oracle writes. FILTER runs only the cases
whose name contains it; BOOLEAN_PAIRS (default 100) and BOOLEAN_SEED
(2024) make longer or other random runs (of both the general-position
and the lattice pairs). Exits 1 when a case fails.
"""

import importlib.metadata
import os
import shutil
import subprocess
import sys
import time

import numpy as np
import manifold3d

SEED = int(os.environ.get("BOOLEAN_SEED", "2024"))
PAIRS = int(os.environ.get("BOOLEAN_PAIRS", "100"))  # BOOLEAN_PAIRS=2000 for a longer local run
OPERATIONS = ("union", "difference", "intersection")
TIMEOUT = 60  # seconds a graftal run may take

# manifold3d >= 3.0 keeps positions in float64 and takes them as float64
# through Mesh64 (C++ MeshGL64); Mesh (MeshGL) takes float32. With Mesh64
# manifold sees exactly the coordinates graftal reads; its result is not
# exact (intersection points are rounded to double, and it merges within a
# tolerance of 1e-12 x the bounding box), so its volume is good to about
# 1e-12 relative and 1e-9 leaves room. Without Mesh64 (manifold3d < 3) the
# operands are rounded to float32 values before either side sees them, so
# both solve the same problem, but manifold then computes in float32: the
# error is reported and 1e-6 required.
WIDE = hasattr(manifold3d, "Mesh64")
REL = 1e-9 if WIDE else 1e-6

PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


# ---- operands: (vertices (n, 3) float64, faces: lists of vertex indices)

CUBE_QUADS = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]


def cube(lo, hi):
    """An axis-aligned box as six quads: exactly planar, so it stays quads."""
    verts = np.array([[(lo, hi)[i >> k & 1][k] for k in range(3)] for i in range(8)], float)
    return verts, [list(q) for q in CUBE_QUADS]


def rotation(rng):
    """A uniformly random rotation matrix (from a random unit quaternion)."""
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def fan(faces):
    """Triangles of polygons, each fanned from its first corner."""
    return [(f[0], f[k], f[k + 1]) for f in faces for k in range(1, len(f) - 1)]


def box(half, rot):
    """A box turned by rot, as triangles (rotated quads are not exactly
    planar, and how to split them is not the question here)."""
    verts, quads = cube(-np.asarray(half), np.asarray(half))
    return verts @ rot.T, [list(t) for t in fan(quads)]


def uv_sphere(segments=16, rings=8):
    """Unit UV sphere: poles on ±Z, rings - 1 rings of `segments` vertices."""
    theta = np.pi * np.arange(1, rings) / rings
    phi = 2 * np.pi * np.arange(segments) / segments
    ring = np.stack([np.outer(np.sin(theta), np.cos(phi)), np.outer(np.sin(theta), np.sin(phi)),
                     np.outer(np.cos(theta), np.ones(segments))], axis=-1).reshape(-1, 3)
    verts = np.vstack([[0, 0, 1], ring, [0, 0, -1]])
    south = len(verts) - 1
    faces = []
    for j in range(segments):
        k = (j + 1) % segments
        faces.append([0, 1 + j, 1 + k])
        for r in range(rings - 2):
            a, b = 1 + r * segments + j, 1 + r * segments + k
            faces += [[a, a + segments, b + segments], [a, b + segments, b]]
        base = 1 + (rings - 2) * segments
        faces.append([south, base + k, base + j])
    return verts, faces


def icosphere(subdivisions):
    """Unit icosphere: an icosahedron, each triangle cut in four
    `subdivisions` times, the new points pushed onto the sphere."""
    t = (1 + 5 ** 0.5) / 2
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
             (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    verts = [np.array(v, float) / np.linalg.norm(v) for v in verts]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(subdivisions):
        middle, finer = {}, []

        def mid(a, b):
            key = min(a, b), max(a, b)
            if key not in middle:
                p = verts[a] + verts[b]
                verts.append(p / np.linalg.norm(p))
                middle[key] = len(verts) - 1
            return middle[key]

        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            finer += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = finer
    return np.array(verts), [list(f) for f in faces]


# A lower bound of each unit sphere's inradius (the nearest face plane from
# the centre), with margin: the UV sphere's is 0.963, the icosphere's 0.934.
KINDS = ("cube", "box", "uvsphere", "icosphere")
INNER = {"uvsphere": 0.9, "icosphere": 0.75}


def random_operand(rng, kind, size, centre):
    """(vertices, faces, circumradius, inradius, exact volume or None)."""
    if kind == "cube":
        half = size * rng.uniform(0.5, 1.0)
        verts, faces = cube(centre - half, centre + half)
        return verts, faces, half * 3 ** 0.5, half, (2 * half) ** 3
    if kind == "box":
        half = size * rng.uniform(0.3, 1.0, 3)
        verts, faces = box(half, rotation(rng))
        return verts + centre, faces, np.linalg.norm(half), half.min(), 8 * half.prod()
    verts, faces = uv_sphere() if kind == "uvsphere" else icosphere(1)
    r = size * rng.uniform(0.6, 1.0)
    return verts @ rotation(rng).T * r + centre, faces, r, INNER[kind] * r, None


def random_pairs(rng):
    """PAIRS cases: 80 % overlapping in general position, 10 % disjoint,
    10 % one operand inside the other (either way round)."""
    for i in range(PAIRS):
        operation = OPERATIONS[i % 3]
        ka, kb = rng.choice(KINDS), rng.choice(KINDS)
        how = "disjoint" if i % 10 == 4 else "nested" if i % 10 == 7 else "overlap"
        ca = rng.uniform(-3, 3, 3)
        a = random_operand(rng, ka, rng.uniform(0.5, 2), ca)
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        if how == "disjoint":
            b = random_operand(rng, kb, rng.uniform(0.5, 2), ca)
            shift = direction * (a[2] + b[2]) * rng.uniform(1.05, 1.5)
            b = (b[0] + shift,) + b[1:]
        elif how == "nested":
            outer = a
            inner = random_operand(rng, kb, 1.0, np.zeros(3))
            scale = outer[3] * rng.uniform(0.3, 0.7) / inner[2]
            offset = direction * outer[3] * rng.uniform(0, 0.2)
            exact = None if inner[4] is None else inner[4] * scale ** 3
            b = (inner[0] * scale + ca + offset, inner[1], inner[2] * scale, inner[3] * scale, exact)
            if rng.random() < 0.5:  # the small one first
                a, b, ka, kb = b, a, kb, ka
        else:
            # Draw B's distance until the two overlap by 5-95 % of the
            # smaller (manifold tells): neither empty nor nested.
            size_b = rng.uniform(0.5, 2)
            while True:
                b = random_operand(rng, kb, size_b, ca)
                shift = direction * (a[2] + b[2]) * rng.uniform(0.1, 0.9)
                b = (b[0] + shift,) + b[1:]
                both = manifold_of(a[0], a[1]) ^ manifold_of(b[0], b[1])
                share = mesh_volume(both) / min(abs(volume(a[0], a[1])), abs(volume(b[0], b[1])))
                if 0.05 < share < 0.95:
                    break
                direction = rng.normal(size=3)
                direction /= np.linalg.norm(direction)
        yield "r%03d-%s-%s-%s" % (i, ka, kb, how), operation, a, b


def shaped_pairs(rng):
    """Placed by hand, still in general position: a rod drilled through a
    ball (difference of genus 1) and a slab through one (two pieces)."""
    ball = uv_sphere()[0] @ rotation(rng).T, uv_sphere()[1]
    q, r = np.linalg.qr(np.eye(3) * 0.9 + rotation(rng) * 0.1)
    tilt = q * np.sign(np.diag(r))  # a rotation near the identity
    for name, half in (("drill", (0.3, 0.25, 2.0)), ("slab", (2.0, 1.8, 0.2))):
        rod = box(np.array(half), tilt)
        shift = rng.uniform(-0.1, 0.1, 3)
        a = ball + (1.0, 1.0, None)
        b = (rod[0] + shift, rod[1], 1.0, 1.0, 8 * np.prod(half))
        for operation in OPERATIONS:
            yield "g-" + name, operation, a, b


def degenerate_pairs():
    """Axis-aligned unit cubes with coincident faces, and the exact volumes
    of union, difference and intersection."""
    unit = cube((0, 0, 0), (1, 1, 1))
    yield "touching", unit, cube((1, 0, 0), (2, 1, 1)), (2, 1, 0)
    yield "touching-part", unit, cube((1, 0.25, 0.25), (2, 0.75, 1.25)), (1.5, 1, 0)
    yield "stack", unit, cube((0.25, 0.25, 1), (1.25, 1.25, 2)), (2, 1, 0)
    yield "coplanar-top", unit, cube((0.5, 0.5, 0.5), (1.5, 1.5, 1)), (1.375, 0.875, 0.125)
    yield "equal", unit, cube((0, 0, 0), (1, 1, 1)), (1, 0, 1)
    yield "half-shift", unit, cube((0.5, 0, 0), (1.5, 1, 1)), (1.5, 0.5, 0.5)


def lattice_pairs(rng):
    """PAIRS axis-aligned boxes with corners on a lattice of 1/4: faces
    that touch, stack, overlap in one plane or coincide, edges that meet
    edges; the exact volumes by inclusion-exclusion."""
    for i in range(PAIRS):
        lo = rng.integers(0, 5, (2, 3)) / 4
        hi = lo + rng.integers(1, 5, (2, 3)) / 4
        a, b = cube(lo[0], hi[0]), cube(lo[1], hi[1])
        va, vb = np.prod(hi - lo, axis=1)
        vi = np.prod(np.clip(np.minimum(hi[0], hi[1]) - np.maximum(lo[0], lo[1]), 0, None))
        operation = OPERATIONS[i % 3]
        exact = {"union": va + vb - vi, "difference": va - vi, "intersection": vi}[operation]
        yield "l%03d" % i, operation, a + (None, None, va), b + (None, None, vb), exact


SUZANNE_SCRIPT = """
import bpy, bmesh, sys
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_monkey_add()
obj = bpy.context.active_object
out = sys.argv[-1]
if out.endswith("open.txt"):
    bm = bmesh.new()
    bm.from_mesh(obj.data)
else:
    # Suzanne is open (42 boundary edges round her eyes): a voxel remesh
    # closes her into one surface of genus 0, triangulated here so that
    # both sides solve the same triangles.
    m = obj.modifiers.new("r", "REMESH")
    m.mode = "VOXEL"
    m.voxel_size = 0.04
    bpy.ops.object.modifier_apply(modifier="r")
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
with open(out, "w") as f:
    for v in bm.verts:
        f.write("v %r %r %r\\n" % tuple(v.co))
    for t in bm.faces:
        f.write("f " + " ".join(str(v.index) for v in t.verts) + "\\n")
"""


def suzanne(kind="closed"):
    """Blender's Suzanne, made by `blender -b` now: closed (voxel remesh,
    ~21,000 triangles) or as Blender makes her (open); None without
    Blender."""
    if shutil.which("blender") is None:
        return None
    script = os.path.join(WORK, "suzanne.py")
    with open(script, "w") as f:
        f.write(SUZANNE_SCRIPT)
    out = os.path.join(WORK, "suzanne-%s.txt" % kind)
    run = subprocess.run(["blender", "-b", "--factory-startup", "--python", script, "--", out],
                         capture_output=True, text=True, timeout=300)
    if run.returncode != 0 or not os.path.exists(out):
        sys.exit("blender could not make Suzanne:\n" + run.stdout[-2000:] + run.stderr[-2000:])
    verts, faces = [], []
    for line in open(out):
        tag, *rest = line.split()
        (verts if tag == "v" else faces).append([float(x) for x in rest] if tag == "v" else [int(x) for x in rest])
    return np.array(verts), faces


def suzanne_pairs(rng, monkey):
    """Suzanne (closed) turned at random against a cube, a rotated box, a
    UV sphere, an icosphere or another Suzanne, overlapping by 5-95 % of the
    smaller, the operation cycling."""
    verts, faces = monkey
    radius = np.linalg.norm(verts, axis=1).max()
    kinds = ("cube", "box", "uvsphere", "icosphere", "suzanne")
    for i in range(15):
        kb = kinds[i % len(kinds)]
        a = (verts @ rotation(rng).T, faces, radius, 0.1 * radius, None)
        while True:
            if kb == "suzanne":
                b = (verts @ rotation(rng).T, faces, radius, 0.1 * radius, None)
            else:
                b = random_operand(rng, kb, rng.uniform(0.5, 1.2), np.zeros(3))
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            b = (b[0] + direction * (a[2] + b[2]) * rng.uniform(0.1, 0.7),) + b[1:]
            both = manifold_of(a[0], a[1]) ^ manifold_of(b[0], b[1])
            share = mesh_volume(both) / min(abs(volume(a[0], a[1])), abs(volume(b[0], b[1])))
            if 0.05 < share < 0.95:
                break
        yield "s%02d-suzanne-%s" % (i, kb), OPERATIONS[i % 3], a, b


def snapped(verts):
    """Coordinates within 1e-12 of an integer put on it (cos(pi/2) is 6e-17
    in floating point, so a UV sphere's equator is not quite z = 0)."""
    near = np.round(verts)
    return np.where(np.abs(verts - near) < 1e-12, near, verts)


def contact_pairs(rng):
    """Touching contacts other than boxes on a lattice: a UV sphere cut at
    its equator and through its poles' meridian plane (its vertices on the
    cutter's face, its edges in it), a sphere resting its pole on a box (and
    on another sphere's), equal spheres, a sphere touching the six faces of
    the cube around it at its poles and equator, a
    turned box and its copy sharing a face (each fanned its own way), and a
    window cutter flush with both faces of a wall."""
    ball = snapped(uv_sphere()[0]), uv_sphere()[1]
    half_space = cube((-2, -2, 0), (2, 2, 2))
    yield "equator", ball, half_space
    yield "meridian", ball, cube((0, -2, -2), (2, 2, 2))
    yield "pole", ball, cube((-0.5, -0.5, 1), (0.5, 0.5, 2))
    yield "pole-sunk", ball, cube((-0.5, -0.5, 0.875), (0.5, 0.5, 2))
    yield "poles-touching", ball, (ball[0] + (0, 0, 2), ball[1])
    yield "equal-balls", ball, ball
    yield "inscribed", ball, cube((-1, -1, -1), (1, 1, 1))
    turned, faces = box(np.array([0.5, 0.4, 0.3]), rotation(rng))
    # B: A's x = +0.5 face shared, its other four corners that face
    # moved on by A's extent along x (the same shape turned the same way).
    plus = turned[[1, 3, 5, 7]]
    copy = turned.copy()
    copy[[0, 2, 4, 6]] = plus + (plus - turned[[0, 2, 4, 6]])
    copy[[1, 3, 5, 7]] = plus
    # Mirrored, so wound the other way: the shared face's two triangles
    # are A's reversed. (Fanned from its other corner, the face's rounded
    # corners are not coplanar: the two triangulations bound a sliver
    # tetrahedron of ~1e-17 between the boxes, exactly a gap, so graftal's
    # union is two solids touching along its edges where manifold fuses
    # them; tests/modelling.rs keeps that case.)
    yield "shared-face", (turned, faces), (copy, [t[::-1] for t in faces])
    yield "flush-window", cube((0, 0, 0), (4, 1, 3)), cube((1, 0, 1), (3, 1, 2))


# ---- measuring meshes


def volume(verts, faces, origin=None):
    """Signed volume (divergence theorem, polygons fanned), float64."""
    tris = np.array(fan(faces), dtype=np.int64).reshape(-1, 3)
    v = np.asarray(verts, float) - (0 if origin is None else origin)
    a, b, c = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]
    return float(np.sum(np.einsum("ij,ij->i", a, np.cross(b, c)))) / 6


def examine(verts, faces, origin=None):
    """(problems, components): the ways the mesh is not closed and
    edge-manifold, and each edge-connected component's (volume, genus),
    sorted. The genus counts a vertex once per fan of faces around it (its
    umbrellas), as a vertex-manifold mesh would repeat it."""
    problems = []
    starts, source, target = [], [], []
    for f in faces:
        starts.append(len(source))
        if len(f) < 3 or any(not 0 <= i < len(verts) for i in f):
            problems.append("bad face %s" % (list(f),))
            return problems, []
        for k in range(len(f)):
            a, b = int(f[k]), int(f[(k + 1) % len(f)])
            if a == b:
                problems.append("face with a repeated corner %d" % a)
            source.append(a)
            target.append(b)
    starts.append(len(source))
    face_of = np.repeat(np.arange(len(faces)), np.diff(starts))
    nxt = np.arange(len(source)) + 1
    nxt[np.array(starts[1:], int) - 1] = starts[:-1]
    directed = {}
    for h, e in enumerate(zip(source, target)):
        if e in directed:
            problems.append("edge %d-%d used twice the same way" % e)
        directed[e] = h
    opposite = [directed.get((b, a)) for a, b in zip(source, target)]
    open_edges = sum(o is None for o in opposite)
    if open_edges:
        problems.append("%d edges used once (or twice the same way)" % open_edges)
    if problems:
        return problems[:3], []

    def find(parent, i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    faces_parent = list(range(len(faces)))
    corners = list(range(len(source)))
    for h, o in enumerate(opposite):
        faces_parent[find(faces_parent, face_of[h])] = find(faces_parent, face_of[o])
        # The corner at h's source and the one across the edge (after o).
        corners[find(corners, h)] = find(corners, int(nxt[o]))
    component = np.array([find(faces_parent, int(face_of[h])) for h in range(len(source))])
    umbrella = np.array([find(corners, h) for h in range(len(source))])
    results = []
    for c in np.unique(component):
        mine = component == c
        members = [faces[i] for i in np.unique(face_of[mine])]
        chi = len(np.unique(umbrella[mine])) - mine.sum() // 2 + len(members)
        if chi % 2:
            return ["Euler characteristic %d is odd" % chi], []
        results.append((volume(verts, members, origin), int(1 - chi // 2)))
    return problems, sorted(results)


# ---- manifold3d


def manifold_of(verts, faces):
    tris = np.array(fan(faces)).reshape(-1, 3)
    if WIDE:
        mesh = manifold3d.Mesh64(vert_properties=np.ascontiguousarray(verts, np.float64),
                                 tri_verts=np.ascontiguousarray(tris, np.uint64))
    else:
        mesh = manifold3d.Mesh(vert_properties=np.ascontiguousarray(verts, np.float32),
                               tri_verts=np.ascontiguousarray(tris, np.uint32))
    solid = manifold3d.Manifold(mesh)
    if solid.status() != manifold3d.Error.NoError:
        raise RuntimeError("manifold3d refuses an operand: %s" % solid.status())
    return solid


def mesh_arrays(solid):
    mesh = solid.to_mesh64() if WIDE else solid.to_mesh()
    return np.asarray(mesh.vert_properties, float)[:, :3], np.asarray(mesh.tri_verts, np.int64)


def mesh_volume(solid, origin=None):
    verts, tris = mesh_arrays(solid)
    return volume(verts, tris, origin) if len(tris) else 0.0


def oracle(operation, a, b, origin):
    """manifold's result: (volume, components as examine gives them)."""
    x, y = manifold_of(a[0], a[1]), manifold_of(b[0], b[1])
    solid = {"union": x + y, "difference": x - y, "intersection": x ^ y}[operation]
    if solid.status() != manifold3d.Error.NoError:
        raise RuntimeError("manifold3d fails: %s" % solid.status())
    verts, tris = mesh_arrays(solid)
    problems, components = examine(verts, [list(t) for t in tris], origin)
    pieces = solid.decompose()
    assert not problems and len(components) == len(pieces), "manifold's own result: %s" % problems
    assert sorted(p.genus() for p in pieces) == sorted(g for _, g in components)
    # Touching contacts can leave manifold a flat component of no volume
    # (the faces two operands share, folded onto each other): not a solid,
    # and not part of the exact result, so not compared.
    size = max(np.ptp(np.vstack([a[0], b[0]]), axis=0))
    components = [(v, g) for v, g in components if abs(v) > 1e-12 * size ** 3]
    return sum(v for v, _ in components), components


# ---- PLY


def write_ply(path, verts, faces):
    """Binary little-endian PLY: double x, y, z; faces as uchar-counted int lists."""
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        "element vertex %d\nproperty double x\nproperty double y\nproperty double z\n"
        "element face %d\nproperty list uchar int vertex_indices\nend_header\n"
        % (len(verts), len(faces))
    )
    body = bytearray(np.ascontiguousarray(verts, "<f8").tobytes())
    for f in faces:
        body += np.array([len(f)], "u1").tobytes() + np.asarray(f, "<i4").tobytes()
    with open(path, "wb") as out:
        out.write(header.encode() + bytes(body))


def read_ply(path):
    """(vertices (n, 3) float64, faces) of a PLY file: any format, any
    element and property layout, only x, y, z and the face lists kept."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header") + len(b"end_header")
    end = data.index(b"\n", end) + 1
    fmt, elements = None, []
    for line in data[:end].decode("ascii").splitlines():
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            fmt = words[1]
        elif words[0] == "element":
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property":
            if words[1] == "list":
                elements[-1][2].append((words[4], PLY_TYPES[words[2]], PLY_TYPES[words[3]]))
            else:
                elements[-1][2].append((words[2], None, PLY_TYPES[words[1]]))
    if fmt == "ascii":
        tokens, at = data[end:].split(), 0
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        at = end
    verts, faces = np.zeros((0, 3)), []
    for name, count, props in elements:
        if fmt != "ascii" and all(kind is None for _, kind, _ in props):
            # Fixed-size records: read them all at once.
            dtype = np.dtype([(p, order + t) for p, _, t in props])
            rows = np.frombuffer(data, dtype, count, at)
            at += dtype.itemsize * count
            if name == "vertex":
                verts = np.column_stack([rows[c].astype(float) for c in "xyz"])
            continue
        values = {p: [] for p, _, _ in props}
        for _ in range(count):
            for p, kind, t in props:
                if fmt == "ascii":
                    n = int(tokens[at]) if kind else 1
                    row = [float(x) for x in tokens[at + (1 if kind else 0):at + (1 if kind else 0) + n]]
                    at += n + (1 if kind else 0)
                    values[p].append(row if kind else row[0])
                    continue
                if kind:
                    n = int(np.frombuffer(data, order + kind, 1, at)[0])
                    at += np.dtype(kind).itemsize
                    values[p].append(np.frombuffer(data, order + t, n, at).tolist())
                    at += np.dtype(t).itemsize * n
                else:
                    values[p].append(np.frombuffer(data, order + t, 1, at)[0])
                    at += np.dtype(t).itemsize
        if name == "vertex":
            verts = np.column_stack([np.array(values[c], float) for c in "xyz"]).reshape(-1, 3)
        elif name == "face":
            key = "vertex_indices" if "vertex_indices" in values else "vertex_index"
            faces = [[int(i) for i in f] for f in values[key]]
    return verts, faces


# ---- graftal

RULES = """[start]
import = { path = "a.ply" }

[[step]]
name = "cutter"
import = { path = "b.ply" }
part = "cutter"

[[step]]
name = "boolean"
boolean = { operation = "%s", with = "cutter" }
"""


def graftal(folder, rules):
    """Run graftal on folder/case.toml: (mesh or None, error message or None,
    refused: it exited with an error naming the step `boolean`)."""
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "case.toml"), "w") as f:
        f.write(rules)
    out = os.path.join(folder, "out.ply")
    if os.path.exists(out):
        os.remove(out)
    try:
        run = subprocess.run([GRAFTAL, "run", "case.toml", "-o", "out.ply", "--quiet"], cwd=folder,
                             capture_output=True, text=True, timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        return None, "graftal ran over %d s" % TIMEOUT, False
    except OSError as e:
        sys.exit("cannot run %s: %s" % (GRAFTAL, e))
    message = (run.stderr.strip().splitlines() or ["(nothing on stderr)"])[0]
    if run.returncode != 0:
        # 101 is a Rust panic, negative a signal: crashes, never refusals.
        refused = run.returncode > 0 and run.returncode != 101 and "step `boolean`" in run.stderr
        return None, "exit %d: %s" % (run.returncode, message), refused
    try:
        return read_ply(out), None, False
    except (OSError, ValueError, KeyError, IndexError) as e:
        return None, "unreadable output: %r" % e, False


def self_intersections(path):
    """The face pairs `graftal info` finds crossing (exact, excusing shared
    vertices and edges), or None."""
    run = subprocess.run([GRAFTAL, "info", path], capture_output=True, text=True, timeout=TIMEOUT)
    for line in run.stdout.splitlines():
        if line.startswith("self-intersections:"):
            return int(line.split()[1])
    return None


def compare(name, operation, a, b, degenerate):
    """Run one case; return its status: "ok", "refused" or "FAIL"."""
    origin = (a[0].mean(axis=0) + b[0].mean(axis=0)) / 2
    expected, theirs = oracle(operation, a, b, origin)
    folder = os.path.join(WORK, name + "-" + operation)
    os.makedirs(folder, exist_ok=True)
    write_ply(os.path.join(folder, "a.ply"), a[0], a[1])
    write_ply(os.path.join(folder, "b.ply"), b[0], b[1])
    mesh, error, refused = graftal(folder, RULES % operation)
    label = "%-34s %-12s" % (name, operation)
    if mesh is None:
        if "unknown key `boolean`" in (error or ""):
            print(label + " graftal has no `boolean` operator: " + error)
            sys.exit(1)
        # Where the exact result's solids (or a solid and a cavity) meet
        # only along an edge, it is not a manifold surface: refused.
        ok = degenerate and refused and "meet only along an edge" in error
        print("%s graftal %-20s manifold %-20.15g %s" % (label, "refused" if refused else "failed",
                                                         expected, ("refused: " if ok else "FAIL: ") + error))
        return "refused" if ok else "FAIL"
    problems, ours = examine(mesh[0], mesh[1], origin)
    try:
        got = volume(mesh[0], mesh[1], origin)
    except IndexError:  # a face names a vertex that is not there (examine says)
        got = float("nan")
    # Relative to manifold's volume, or to the operands' for an empty result.
    scale = max(abs(expected), 1e-3 * min(abs(volume(*a[:2])), abs(volume(*b[:2]))))
    rel = abs(got - expected) / scale
    if not rel <= REL:
        problems.append("volume off by %.1e" % rel)
    if not problems:
        genus, their_genus = sorted(g for _, g in ours), sorted(g for _, g in theirs)
        if len(ours) != len(theirs):
            problems.append("%d components, manifold %d" % (len(ours), len(theirs)))
        elif genus != their_genus:
            problems.append("genus %s, manifold %s" % (genus, their_genus))
        elif any(abs(u - v) > REL * scale for (u, _), (v, _) in zip(ours, theirs)):
            problems.append("component volumes %s, manifold %s" % (
                ["%.9g" % v for v, _ in ours], ["%.9g" % v for v, _ in theirs]))
    if not problems:
        crossing = self_intersections(os.path.join(folder, "out.ply"))
        # Solids that touch along an edge or at a point get their own
        # vertices there (as manifold's do): their faces meet without
        # sharing vertices, which the search counts. Anywhere else, none.
        touching = len(np.unique(mesh[0], axis=0)) < len(mesh[0])
        if crossing is None:
            problems.append("graftal info gave no self-intersection count")
        elif crossing > 0 and not (degenerate and touching):
            problems.append("%d self-intersecting face pairs" % crossing)
    print("%s graftal %-20.15g manifold %-20.15g rel %.1e  %s" % (
        label, got, expected, rel, "ok" if not problems else "FAIL: " + "; ".join(problems)))
    return "FAIL" if problems else "ok"


def self_check(cases):
    """The oracle's own measures on the operands: closed, one component of
    genus 0, volume equal to manifold's and, where known, to the exact one;
    manifold's three results consistent with each other; and graftal reads
    a.ply back as written (import, then PLY out)."""
    pairs = {name: (a, b) for name, _, a, b, _ in cases}
    worst = 0.0
    for name, (a, b) in pairs.items():
        for verts, faces, _, _, exact in (a, b):
            problems, components = examine(verts, faces)
            own = volume(verts, faces)
            theirs = mesh_volume(manifold_of(verts, faces))
            worst = max(worst, abs(own - theirs) / own)
            assert not problems and [g for _, g in components] == [0], (name, problems, components)
            assert own > 0 and abs(own - theirs) <= 1e-12 * own, (name, own, theirs)
            # (rounded to float32, the operands are not quite the boxes drawn)
            assert exact is None or not WIDE or abs(own - exact) <= 1e-12 * exact, (name, own, exact)
    # manifold against itself: V(A u B) + V(A n B) = V(A) + V(B), V(A - B) + V(A n B) = V(A).
    sums = 0.0
    for a, b in pairs.values():
        origin = (a[0].mean(axis=0) + b[0].mean(axis=0)) / 2
        x, y = manifold_of(a[0], a[1]), manifold_of(b[0], b[1])
        u, d, i = (mesh_volume(s, origin) for s in (x + y, x - y, x ^ y))
        va, vb = volume(a[0], a[1], origin), volume(b[0], b[1], origin)
        sums = max(sums, max(abs(u + i - va - vb), abs(d + i - va)) / max(va, vb))
    assert sums <= REL / 10, ("manifold's volumes do not add up", sums)
    print("oracle self-check: %d operands closed, genus 0, volume = manifold's to %.1e%s; "
          "manifold's union, difference and intersection add up to %.1e"
          % (2 * len(pairs), worst, "" if WIDE else " (float32 Mesh)", sums))
    name, _, a, _, _ = cases[0]
    folder = os.path.join(WORK, "read-back")
    os.makedirs(folder, exist_ok=True)
    write_ply(os.path.join(folder, "a.ply"), a[0], a[1])
    mesh, error, _ = graftal(folder, RULES.split("\n\n")[0] + "\n")
    if mesh is None or sorted(map(tuple, mesh[0].tolist())) != sorted(map(tuple, a[0].tolist())) \
            or abs(volume(*mesh) - volume(a[0], a[1])) > 1e-12 * volume(a[0], a[1]):
        print("graftal does not read back %s's operand as written: %s" % (name, error or "it differs"))
        sys.exit(1)


def main():
    rng = np.random.default_rng(SEED)
    # (name, operation, A, B, the exact result's volume for hand-made cases)
    cases = [(n, op, a, b, None) for n, op, a, b in random_pairs(rng)]
    cases += [(n, op, a, b, None) for n, op, a, b in shaped_pairs(rng)]
    monkey = suzanne() if "suzanne" in ONLY or not ONLY else None
    if monkey is not None:
        # Its own generator: the other cases draw the same with or without it.
        cases += [(n, op, a, b, None) for n, op, a, b in suzanne_pairs(np.random.default_rng(SEED + 1), monkey)]
    elif not ONLY:
        print("no blender on PATH: the Suzanne cases are left out (make test-blender installs it)")
    for name, a, b, exact in degenerate_pairs():
        a, b = (s + (None, None, np.ptp(s[0], axis=0).prod()) for s in (a, b))
        for operation, v in zip(OPERATIONS, exact):
            cases.append(("degenerate-" + name, operation, a, b, v))
    cases += [("degenerate-" + n, op, a, b, v) for n, op, a, b, v in lattice_pairs(rng)]
    for name, a, b in contact_pairs(rng):
        for operation in OPERATIONS:
            cases.append(("degenerate-" + name, operation, a + (None, None, None), b + (None, None, None),
                          None))
    if not WIDE:  # the same float32 coordinates on both sides
        cases = [(n, op, (a[0].astype(np.float32).astype(float),) + a[1:],
                  (b[0].astype(np.float32).astype(float),) + b[1:], d) for n, op, a, b, d in cases]
    self_check(cases)
    if monkey is not None:
        # Suzanne as Blender makes her is open: refused, naming the selection
        # and counting her boundary edges.
        verts, faces = suzanne("open")
        folder = os.path.join(WORK, "open-suzanne")
        os.makedirs(folder, exist_ok=True)
        write_ply(os.path.join(folder, "a.ply"), verts, faces)
        box = cube((-0.5, -0.5, -0.5), (0.5, 0.5, 0.5))
        write_ply(os.path.join(folder, "b.ply"), box[0], box[1])
        _, error, refused = graftal(folder, RULES % "union")
        if not (refused and "the selection is not a closed shell" in error and "42 boundary edges" in error):
            print("open Suzanne: expected a refusal counting 42 boundary edges, got %s" % error)
            sys.exit(1)
        print("open Suzanne refused: %s" % error.split("boolean: ")[-1])
    print("manifold3d %s (%s input), volumes to %g relative"
          % (importlib.metadata.version("manifold3d"), "float64 Mesh64" if WIDE else "float32 Mesh", REL))
    began, tally, failures = time.perf_counter(), {}, []
    for name, operation, a, b, exact in cases:
        if ONLY not in name:
            continue
        if exact is not None:  # hand-made: manifold must agree with the exact value
            total, _ = oracle(operation, a, b, None)
            assert abs(total - exact) <= 1e-12, (name, operation, total, exact)
        status = compare(name, operation, a, b, name.startswith("degenerate-"))
        tally[status] = tally.get(status, 0) + 1
        if status == "FAIL":
            failures.append("%s %s" % (name, operation))
    print("%d cases in %.1f s: %s" % (sum(tally.values()), time.perf_counter() - began,
                                      ", ".join("%d %s" % (n, s) for s, n in sorted(tally.items()))))
    if failures:
        print("FAILED: " + ", ".join(failures))
        sys.exit(1)
    print("PASS: every boolean matches manifold3d%s" % (
        " (%d touching cases refused: solids meeting along an edge)" % tally["refused"] if "refused" in tally else ""))


if __name__ == "__main__":
    GRAFTAL, WORK = sys.argv[1], sys.argv[2]
    ONLY = sys.argv[3] if len(sys.argv) > 3 else ""
    main()
