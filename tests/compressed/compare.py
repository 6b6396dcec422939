"""Compressed glTF from real tools, read by graftal, against the original.

For each example: graftal writes `orig.glb`; gltfpack rewrites it with its
defaults (quantised: KHR_mesh_quantization), with -c and with -cc
(EXT_meshopt_compression, -cc with filters); gltf-pipeline -d rewrites it
with Draco (KHR_draco_mesh_compression). `graftal convert` reads each and
writes ASCII PLY. Checked, per file:

* the extension the tool was asked for is required by the file;
* the triangle count is the original's;
* every decoded vertex lies within the quantisation step of an original
  vertex and every original vertex within it of a decoded one (the step is
  the model's extent over 2^bits - 1, bits 14 for gltfpack's positions, 11
  for gltf-pipeline's; half a step per axis, so sqrt(3)/2 of it in space);
* meshopt compression is lossless: -c and -cc decode to exactly the
  vertices of the quantised-only file;
* a decoded file converted to GLB and converted again changes no byte.

Prints one line per file with the largest distance found, and exits 1 on
the first mismatch. Pure standard library (a hash grid for the nearest
vertex), so it needs no virtual environment.
"""
import json
import math
import struct
import subprocess
import sys
from pathlib import Path

EXAMPLES = ["chair", "cottage", "pn-cube", "vase", "teapot", "knobs", "sdf-bracket"]


def run(*args):
    r = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"FAILED: {' '.join(map(str, args))}\n{r.stdout}{r.stderr}")
    return r


def required_extensions(glb):
    data = glb.read_bytes()
    length = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20 : 20 + length])
    return set(doc.get("extensionsRequired", []))


def read_ply(path):
    lines = path.read_text().split("\n")
    end = lines.index("end_header")
    count = lambda name: next(
        int(l.split()[2]) for l in lines[:end] if l.startswith(f"element {name} ")
    )
    vertices = [tuple(map(float, l.split()[:3])) for l in lines[end + 1 : end + 1 + count("vertex")]]
    faces = count("face")
    triangles = sum(
        int(l.split()[0]) - 2 for l in lines[end + 1 + count("vertex") : end + 1 + count("vertex") + faces]
    )
    return vertices, triangles


def farthest(points, others, cell):
    """The largest distance from a point of `points` to its nearest in `others`."""
    grid = {}
    for q in others:
        grid.setdefault(tuple(math.floor(c / cell) for c in q), []).append(q)
    worst = 0.0
    for p in points:
        key = tuple(math.floor(c / cell) for c in p)
        best = math.inf
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    for q in grid.get((key[0] + dx, key[1] + dy, key[2] + dz), ()):
                        best = min(best, math.dist(p, q))
        worst = max(worst, best)
    return worst


def main():
    graftal, tools, rules, work = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3]), Path(sys.argv[4])
    checked = 0
    for name in EXAMPLES:
        d = work / name
        d.mkdir()
        orig = d / "orig.glb"
        run(graftal, "run", rules / f"{name}.toml", "-o", orig, "-q")
        run(graftal, "convert", orig, d / "orig.ply", "--ascii")
        reference, triangles = read_ply(d / "orig.ply")
        extent = max(
            max(v[k] for v in reference) - min(v[k] for v in reference) for k in range(3)
        )
        made = {
            "q": ([tools / "gltfpack", "-i", orig, "-o", d / "q.glb"], {"KHR_mesh_quantization"}, 14),
            "c": ([tools / "gltfpack", "-i", orig, "-o", d / "c.glb", "-c"], {"EXT_meshopt_compression"}, 14),
            "cc": ([tools / "gltfpack", "-i", orig, "-o", d / "cc.glb", "-cc"], {"EXT_meshopt_compression"}, 14),
            "d": ([tools / "gltf-pipeline", "-i", orig, "-o", d / "d.glb", "-d"], {"KHR_draco_mesh_compression"}, 11),
        }
        decoded = {}
        for tag, (command, extensions, bits) in made.items():
            run(*command)
            glb = d / f"{tag}.glb"
            found = required_extensions(glb)
            if not extensions <= found:
                sys.exit(f"{name} {tag}: expected {extensions} required, found {found}")
            run(graftal, "convert", glb, d / f"{tag}.ply", "--ascii")
            vertices, count = read_ply(d / f"{tag}.ply")
            if count != triangles:
                sys.exit(f"{name} {tag}: {count} triangles, the original has {triangles}")
            step = extent / (2**bits - 1)
            bound = math.sqrt(3) / 2 * step * 1.001 + 1e-12
            distance = max(
                farthest(vertices, reference, bound), farthest(reference, vertices, bound)
            )
            if distance > bound:
                sys.exit(f"{name} {tag}: a vertex moved {distance:.3e}, more than the step bound {bound:.3e}")
            decoded[tag] = sorted(set(vertices))
            # Reading it and writing GLB is a fixed point from then on.
            run(graftal, "convert", glb, d / f"{tag}-1.glb")
            run(graftal, "convert", d / f"{tag}-1.glb", d / f"{tag}-2.glb")
            if (d / f"{tag}-1.glb").read_bytes() != (d / f"{tag}-2.glb").read_bytes():
                sys.exit(f"{name} {tag}: converting the decoded GLB again changed bytes")
            print(
                f"{name:12} {tag:2}: {count} triangles, {len(vertices)} vertices "
                f"(original {len(reference)}), farthest {distance:.2e} <= {bound:.2e} "
                f"({glb.stat().st_size} bytes, original {orig.stat().st_size})"
            )
            checked += 1
        for tag in ("c", "cc"):
            if decoded[tag] != decoded["q"]:
                sys.exit(f"{name} {tag}: meshopt decoding differs from the quantised-only file")
        # Without filters the codec is lossless for every attribute: the
        # normals and UVs (as OBJ prints them, in any order) are the
        # quantised-only file's.
        looks = {}
        for tag in ("q", "c"):
            run(graftal, "convert", d / f"{tag}.glb", d / f"{tag}.obj")
            text = (d / f"{tag}.obj").read_text().split("\n")
            looks[tag] = sorted(l for l in text if l.startswith(("vn ", "vt ")))
        if looks["c"] != looks["q"]:
            sys.exit(f"{name} c: normals or UVs differ from the quantised-only file")
    checked += blender_files(graftal, work)
    print(f"ok: {checked} files from {len(EXAMPLES)} examples read within their quantisation step")


def blender_files(graftal, work):
    """Blender's exporter (when `blender` is installed: CI installs it for
    `make test-blender` first): its GLB of each example holds the same
    triangles at the same f32 positions; with Draco (only where Blender was
    built with its Draco library) within Draco's default 14-bit step."""
    import shutil

    blender = shutil.which("blender")
    if blender is None:
        print("blender: not installed, its exporter not checked")
        return 0
    here = Path(__file__).parent
    # A failing script fails the run (Blender exits 0 on a Python error by
    # default, which left only a missing file to report).
    r = run(blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python", here / "blender_export.py", "--", work)
    draco = "DRACO yes" in r.stdout
    print(f"blender: exporter's Draco library {'found' if draco else 'missing (Debian builds Blender without it)'}")
    checked = 0
    for name in EXAMPLES:
        d = work / name
        reference, triangles = read_ply(d / "orig.ply")
        extent = max(max(v[k] for v in reference) - min(v[k] for v in reference) for k in range(3))
        for tag, bound in [("blender", 1e-6)] + ([("blender-draco", math.sqrt(3) / 2 * extent / (2**14 - 1) * 1.001)] if draco else []):
            run(graftal, "convert", d / f"{tag}.glb", d / f"{tag}.ply", "--ascii")
            vertices, count = read_ply(d / f"{tag}.ply")
            if count != triangles:
                sys.exit(f"{name} {tag}: {count} triangles, the original has {triangles}")
            distance = max(farthest(vertices, reference, bound), farthest(reference, vertices, bound))
            if distance > bound:
                sys.exit(f"{name} {tag}: a vertex moved {distance:.3e}, more than {bound:.3e}")
            print(f"{name:12} {tag}: {count} triangles, {len(vertices)} vertices, farthest {distance:.2e} <= {bound:.2e}")
            checked += 1
    return checked


main()
