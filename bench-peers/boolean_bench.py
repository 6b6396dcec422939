"""graftal's `boolean` beside manifold3d and Blender's exact boolean (issue 36).

    target/boolean-venv/bin/python bench-peers/boolean_bench.py GRAFTAL WORKDIR [--blender] [--runs N] [--levels 3,4,5,6,7]

(`make test-boolean` makes the venv.) Workload: the difference of two
icospheres of radius 1, the second turned and moved by (0.6, 0.3, 0.2) so
the surfaces cross in general position, at subdivision levels 3-7 (1,280
to 327,680 triangles each; 2,560 to 655,360 in all). graftal runs a rule
file importing both as PLY (the second into the part `cutter`) with and
without the `boolean` step: its step time is the difference of the whole
processes' medians (the import and the PLY write are in both). manifold3d:
`(A - B).to_mesh64()` on prebuilt Manifolds (the operation alone, as
manifold evaluates lazily). Blender 3.4 (`--blender`, up to level 6): the
Boolean modifier, solver EXACT, applied, timed inside Blender. The
volumes must agree to 1e-9 relative (Blender's is shown: it rounds to
float32). Median of N runs (default 3). `--levels 8` adds the 10⁶ row
(2,621,440 triangles in all; making the icospheres takes a minute).
"""

import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
import manifold3d

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests", "boolean"))
from oracle import icosphere, manifold_of, mesh_arrays, read_ply, volume, write_ply  # noqa: E402

LEVELS = (3, 4, 5, 6, 7)
TURN = np.array([[0.936, -0.352, 0.0], [0.352, 0.936, 0.0], [0.0, 0.0, 1.0]])
TURN /= np.linalg.norm(TURN, axis=1)[:, None]
OFFSET = np.array([0.6, 0.3, 0.2])

RULES = """[start]
import = {{ path = "a.ply" }}

[[step]]
name = "cutter"
import = {{ path = "b.ply" }}
part = "cutter"
{boolean}"""
BOOLEAN = '\n[[step]]\nname = "cut"\nboolean = { operation = "difference", with = "cutter" }\n'

BLENDER = r"""
import bpy, sys, time, struct
a_path, b_path = sys.argv[-2], sys.argv[-1]
def load(path, name):
    with open(path, 'rb') as f:
        data = f.read()
    head, body = data.split(b'end_header\n', 1)
    lines = head.decode().split('\n')
    nv = int([l for l in lines if l.startswith('element vertex')][0].split()[-1])
    nf = int([l for l in lines if l.startswith('element face')][0].split()[-1])
    flat = struct.unpack('<%dd' % (3 * nv), body[:nv * 24])
    verts = [flat[3 * i:3 * i + 3] for i in range(nv)]
    faces = [struct.unpack_from('<3i', body, nv * 24 + 13 * k + 1) for k in range(nf)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj
a, b = load(a_path, 'A'), load(b_path, 'B')
m = a.modifiers.new('bool', 'BOOLEAN')
m.operation = 'DIFFERENCE'
m.solver = 'EXACT'
m.object = b
bpy.context.view_layer.objects.active = a
t = time.perf_counter()
bpy.ops.object.modifier_apply(modifier='bool')
t = time.perf_counter() - t
me = a.data
v = [x.co[:] for x in me.vertices]
vol = 0.0
for p in me.polygons:
    r = [v[i] for i in p.vertices]
    for k in range(1, len(r) - 1):
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = r[0], r[k], r[k + 1]
        vol += (ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)) / 6
print('RESULT', t, len(me.polygons), vol)
"""


def timed(argv, cwd):
    t = time.perf_counter()
    subprocess.run(argv, cwd=cwd, check=True, capture_output=True)
    return time.perf_counter() - t


def main():
    graftal, work = os.path.abspath(sys.argv[1]), sys.argv[2]
    runs = int(sys.argv[sys.argv.index("--runs") + 1]) if "--runs" in sys.argv else 3
    with_blender = "--blender" in sys.argv
    levels = LEVELS
    if "--levels" in sys.argv:
        levels = tuple(int(x) for x in sys.argv[sys.argv.index("--levels") + 1].split(","))
    os.makedirs(work, exist_ok=True)
    print("| triangles (A + B) | graftal whole process | graftal import + write only | graftal step | manifold3d | Blender exact | manifold / graftal step | volumes |")
    print("|---|---|---|---|---|---|---|---|")
    for level in levels:
        verts, faces = icosphere(level)
        faces = np.array(faces)
        b = verts @ TURN.T + OFFSET
        folder = os.path.join(work, "L%d" % level)
        os.makedirs(folder, exist_ok=True)
        write_ply(os.path.join(folder, "a.ply"), verts, faces)
        write_ply(os.path.join(folder, "b.ply"), b, faces)
        with open(os.path.join(folder, "cut.toml"), "w") as f:
            f.write(RULES.format(boolean=BOOLEAN))
        with open(os.path.join(folder, "plain.toml"), "w") as f:
            f.write(RULES.format(boolean=""))
        whole, plain, peer, blend = [], [], [], None
        x, y = manifold_of(verts, faces), manifold_of(b, faces)
        for _ in range(runs):
            whole.append(timed([graftal, "run", "cut.toml", "-o", "cut.ply", "--quiet"], folder))
            plain.append(timed([graftal, "run", "plain.toml", "-o", "plain.ply", "--quiet"], folder))
            t = time.perf_counter()
            result = (x - y).to_mesh64()
            peer.append(time.perf_counter() - t)
        mv, mt = mesh_arrays(x - y)
        gv, gf = read_ply(os.path.join(folder, "cut.ply"))
        vg, vm = volume(gv, gf), volume(mv, mt)
        rel = abs(vg - vm) / abs(vm)
        if with_blender and level <= 6:
            script = os.path.join(folder, "blender.py")
            with open(script, "w") as f:
                f.write(BLENDER)
            out = subprocess.run(["blender", "-b", "--factory-startup", "--python", script, "--",
                                  os.path.join(folder, "a.ply"), os.path.join(folder, "b.ply")],
                                 capture_output=True, text=True, check=True).stdout
            line = [l for l in out.splitlines() if l.startswith("RESULT")][0].split()
            blend = (float(line[1]), float(line[3]))
        g, p, m = statistics.median(whole), statistics.median(plain), statistics.median(peer)
        step = max(g - p, 1e-6)
        print("| {:,} | {:.3f} s | {:.3f} s | {:.3f} s | {:.3f} s | {} | {:.2f} | graftal {:.12f}, manifold {:.12f} (rel {:.1e}){} |".format(
            2 * len(faces), g, p, step, m,
            "%.2f s" % blend[0] if blend else "–", m / step, vg, vm, rel,
            ", Blender %.6f" % blend[1] if blend else ""))
        sys.stdout.flush()
        assert rel < 1e-9, "volumes differ"
        del result


if __name__ == "__main__":
    main()
