"""Blender's bmesh on the mesh workloads, run headless:

    blender -b --factory-startup --python bench-peers/bmesh_bench.py -- SITE OP ARGS

SITE is the bench venv's site-packages (Debian's Blender has no numpy).
OP ARGS is one of: merge soup.npz | selfx selfx.npz | grid N | inset N T |
extrude N | triangulate N | mirror N | subdivide CAGE LEVELS | hull POINTS.npy |
bevel MESH.npz WIDTH SEGMENTS | suzanne OUT.obj (writes the subdivide
workload's cage, untimed). Grids have N × N cells of 0.01 (bmesh's `size`
is half the extent); CAGE is an OBJ or `gridN`. Blender stores float32
coordinates.
"""

import os
import sys

SPACING = 0.01


def args():
    return sys.argv[sys.argv.index("--") + 1 :]


sys.path[:0] = [args()[0], os.path.dirname(os.path.abspath(__file__))]

import bmesh  # noqa: E402
import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils.bvhtree import BVHTree  # noqa: E402

from benchlib import emit, load, timed  # noqa: E402


def from_arrays(verts, faces):
    """A bmesh of faces of one size (triangles, quads) through a Mesh's
    foreach_set (fast, untimed)."""
    me = bpy.data.meshes.new("input")
    me.vertices.add(len(verts))
    me.vertices.foreach_set("co", verts.astype(np.float32).ravel())
    me.loops.add(faces.size)
    me.loops.foreach_set("vertex_index", faces.astype(np.int32).ravel())
    me.polygons.add(len(faces))
    corners = faces.shape[1]
    me.polygons.foreach_set("loop_start", np.arange(0, faces.size, corners, dtype=np.int32))
    me.polygons.foreach_set("loop_total", np.full(len(faces), corners, dtype=np.int32))
    me.update()
    bm = bmesh.new()
    bm.from_mesh(me)
    return bm


def grid(n):
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=n, y_segments=n, size=n * SPACING / 2)
    return bm


def report(seconds, bm, **extra):
    emit(seconds, len(bm.verts), len(bm.faces), **extra)


def merge(path):
    bm = from_arrays(*load(path))
    seconds, _ = timed(bmesh.ops.remove_doubles, bm, verts=bm.verts[:], dist=1e-4)
    report(seconds, bm)


def selfx(path):
    """BVH overlap with itself gives each pair twice, in both orders. It also
    reports some neighbours that only share a vertex: counted apart."""
    bm = from_arrays(*load(path))

    def overlap():
        tree = BVHTree.FromBMesh(bm)
        return tree.overlap(tree)

    seconds, found = timed(overlap)
    pairs = {(min(a, b), max(a, b)) for a, b in found if a != b}
    bm.faces.ensure_lookup_table()
    sharing = sum(1 for a, b in pairs if set(bm.faces[a].verts) & set(bm.faces[b].verts))
    report(seconds, bm, pairs=len(pairs), sharing_vertex=sharing)


def create(n):
    bm = bmesh.new()
    seconds, _ = timed(
        bmesh.ops.create_grid, bm, x_segments=int(n), y_segments=int(n), size=int(n) * SPACING / 2
    )
    report(seconds, bm)


def inset(n, thickness):
    bm = grid(int(n))
    seconds, _ = timed(
        bmesh.ops.inset_region,
        bm,
        faces=bm.faces[:],
        thickness=float(thickness),
        use_boundary=True,
        use_even_offset=True,
    )
    report(seconds, bm)


def extrude(n):
    """Geometry only: graftal's step also moves the new faces by its distance."""
    bm = grid(int(n))
    seconds, _ = timed(bmesh.ops.extrude_discrete_faces, bm, faces=bm.faces[:])
    report(seconds, bm)


def triangulate(n):
    bm = grid(int(n))
    seconds, _ = timed(bmesh.ops.triangulate, bm, faces=bm.faces[:])
    report(seconds, bm)


def mirror(n):
    """Mirror across x = 0, the grid's left border, welding the seam."""
    bm = grid(int(n))
    bmesh.ops.translate(bm, verts=bm.verts[:], vec=(int(n) * SPACING / 2, 0, 0))
    geom = bm.verts[:] + bm.edges[:] + bm.faces[:]
    seconds, _ = timed(bmesh.ops.mirror, bm, geom=geom, axis="X", merge_dist=1e-5)
    report(seconds, bm)


def write_obj(me, path):
    """Exact coordinates (repr of the float32 values), 1-based faces."""
    with open(path, "w") as f:
        for v in me.vertices:
            f.write("v %r %r %r\n" % tuple(v.co))
        for p in me.polygons:
            f.write("f " + " ".join(str(i + 1) for i in p.vertices) + "\n")


def suzanne(out):
    """Blender's monkey (500 faces, 507 vertices) as OBJ: the subdivide cage."""
    bpy.ops.mesh.primitive_monkey_add()
    write_obj(bpy.context.active_object.data, out)


def read_obj(path):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append(tuple(float(x) for x in line.split()[1:4]))
            elif line.startswith("f "):
                faces.append([int(x.split("/")[0]) - 1 for x in line.split()[1:]])
    return verts, faces


def subdivide(cage, levels):
    """The subdivision-surface modifier (OpenSubdiv, Catmull–Clark) applied:
    limit surface off, boundary "Keep Corners", as graftal's default. CAGE
    is an OBJ or `gridN` (bmesh's grid of N × N cells). Timed: the modifier
    apply (evaluation and the write-back into the object's mesh)."""
    me = bpy.data.meshes.new("cage")
    if cage.startswith("grid"):
        bm = grid(int(cage[4:]))
        bm.to_mesh(me)
        bm.free()
    else:
        verts, faces = read_obj(cage)
        me.from_pydata(verts, [], faces)
    me.update()
    obj = bpy.data.objects.new("cage", me)
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    mod = obj.modifiers.new("subsurf", "SUBSURF")
    mod.subdivision_type = "CATMULL_CLARK"
    mod.levels = int(levels)
    mod.use_limit_surface = False
    mod.boundary_smooth = "PRESERVE_CORNERS"
    seconds, _ = timed(bpy.ops.object.modifier_apply, modifier=mod.name)
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    emit(seconds, len(me.vertices), len(me.polygons), sum_abs=float(np.abs(co.astype(np.float64)).sum()))


def hull(path):
    """`bmesh.ops.convex_hull` of loose vertices; the points it leaves
    inside or unused are deleted after the timing, so the counts are the
    hull's (its faces are triangles)."""
    points = np.load(path)
    me = bpy.data.meshes.new("points")
    me.vertices.add(len(points))
    me.vertices.foreach_set("co", points.astype(np.float32).ravel())
    bm = bmesh.new()
    bm.from_mesh(me)
    seconds, out = timed(bmesh.ops.convex_hull, bm, input=bm.verts[:])
    inside = list({v for v in out["geom_interior"] + out["geom_unused"] if isinstance(v, bmesh.types.BMVert)})
    bmesh.ops.delete(bm, geom=inside, context="VERTS")
    report(seconds, bm)


def bevel(path, width, segments):
    """`bmesh.ops.bevel` of every edge, as graftal's `bevel` step: offset
    type "offset", superellipse profile 0.5, no clamping, sharp miters,
    the "adj" corner mesh. Sums |x| + |y| + |z| over the vertices."""
    bm = from_arrays(*load(path))
    edges = bm.edges[:]
    seconds, _ = timed(
        bmesh.ops.bevel,
        bm,
        geom=edges,
        offset=float(width),
        offset_type="OFFSET",
        profile_type="SUPERELLIPSE",
        segments=int(segments),
        profile=0.5,
        affect="EDGES",
        clamp_overlap=False,
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
    me = bpy.data.meshes.new("beveled")
    bm.to_mesh(me)
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    report(seconds, bm, sum_abs=float(np.abs(co.astype(np.float64)).sum()))


OPS = {
    "merge": merge,
    "selfx": selfx,
    "grid": create,
    "inset": inset,
    "extrude": extrude,
    "triangulate": triangulate,
    "mirror": mirror,
    "suzanne": suzanne,
    "subdivide": subdivide,
    "hull": hull,
    "bevel": bevel,
}

if __name__ == "__main__":
    OPS[args()[1]](*args()[2:])
