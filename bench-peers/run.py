"""graftal beside its peers on the same inputs: medians, ratios, agreement.

    GRAFTAL=target/release/graftal python3 bench-peers/run.py [--runs N]
        [--only merge,glb,...] [--peers bmesh,libigl,qhull,...] [--with-occt] [--slow]
        [--baseline OLD_GRAFTAL]

Started by any python3, it sets up target/bench-peers/ (venv, Blender,
curvo) and goes on in the venv's python. Every tool call is its own
process; each round runs graftal, then every peer, then the next round.
The table goes to stdout and to target/bench-peers/results.md (medians and
counts per tool in results.json).
"""

import argparse
import json
import math
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
OUT = ROOT / "target" / "bench-peers"
VENV = OUT / "venv"
PYTHON = VENV / "bin" / "python"
INPUTS = OUT / "inputs"
MESHES = OUT / "out"
CURVO = OUT / "curvo-target" / "release" / "curvo-bench"
GRAFTAL = Path(os.environ.get("GRAFTAL", ROOT / "target" / "release" / "graftal")).resolve()
# The binary graftal's workload functions run: GRAFTAL, or the --baseline
# binary while its turn in a round lasts.
RUNNING = [GRAFTAL]
CRITERION = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target")) / "criterion"

PACKAGES = ["numpy", "scipy", "trimesh", "libigl", "cgal", "geomdl", "splinepy"]
MODULES = ["numpy", "scipy", "trimesh", "igl", "CGAL", "geomdl", "splinepy"]
PEERS = ["libigl", "trimesh", "cgal", "bmesh", "qhull", "geomdl", "splinepy", "occt", "curvo"]
DISTRIBUTIONS = {
    "trimesh": "trimesh",
    "libigl": "libigl",
    "cgal": "cgal",
    "geomdl": "geomdl",
    "splinepy": "splinepy",
    "occt": "cadquery-ocp",
    "qhull": "scipy",
}
# The hull workload's point sets (make_inputs.py's HULL_KINDS × HULL_SIZES).
HULL_SETS = [(kind, n) for kind in ("ball", "sphere") for n in (10_000, 100_000, 1_000_000)]
INPUT_FILES = ["soup.ply", "soup.npz", "selfx.ply", "selfx.npz", "selfx.off", "quads300.npz", "tri1m.npz"] + [
    f"{kind}{n}.{ext}" for kind, n in HULL_SETS for ext in ("ply", "npy")
]
# The subdivide workload: (cage, levels). `suzanne` is Blender's monkey
# (500 faces), written as OBJ by Blender into the inputs (not committed);
# `gridN` an N × N grid of 0.01 cells. Outputs from 7,872 to 1,000,000 faces.
SUBDIVIDE_CASES = [("suzanne", 2), ("suzanne", 3), ("suzanne", 4), ("suzanne", 5), ("grid250", 2)]
SUZANNE = "suzanne.obj"
# The bevel workload: (N, segments) on make_inputs.py's quad sphere of
# N × N cells a cube face (12 N² edges), every edge beveled by 0.1 / N
# (about a tenth of the shortest edge, 0.94 / N: no two new corners meet,
# nothing to clamp).
BEVEL_CASES = [(29, 1), (91, 1), (289, 1), (29, 3), (91, 3), (289, 3)]
INPUT_FILES += [f"qsphere{n}.{ext}" for n in sorted({n for n, _ in BEVEL_CASES}) for ext in ("ply", "npz")]


def bevel_width(n):
    return 0.1 / n


# ---------------------------------------------------------------- set-up


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=int, default=5, help="rounds per workload (default 5)")
    p.add_argument("--only", help="comma-separated workloads: " + ", ".join(WORKLOAD_NAMES))
    p.add_argument("--peers", help="comma-separated peers: " + ", ".join(PEERS))
    p.add_argument(
        "--with-occt",
        action="store_true",
        default=os.environ.get("BENCH_PEERS_OCCT") == "1",
        help="install and run OCP (cadquery-ocp, ~450 MB); or BENCH_PEERS_OCCT=1",
    )
    p.add_argument("--slow", action="store_true", help="also run geomdl at 1000² (about 16 s a call)")
    p.add_argument(
        "--baseline",
        type=Path,
        help="another graftal binary (an earlier build) run in the same rounds: a 'graftal before' column",
    )
    return p.parse_args()


def setup(args):
    """Venv, Blender and curvo; stdlib only, before the venv exists."""
    OUT.mkdir(parents=True, exist_ok=True)
    if not PYTHON.exists():
        subprocess.run([sys.executable, "-m", "venv", str(VENV)], check=True)
    install(PACKAGES, MODULES)
    if args.with_occt:
        install(["cadquery-ocp"], ["OCP"])
    if not shutil.which("blender"):
        print("installing Blender (apt-get install -y -qq blender)", file=sys.stderr)
        subprocess.run(["apt-get", "update", "-qq"])
        if subprocess.run(["apt-get", "install", "-y", "-qq", "blender"]).returncode != 0:
            print("NOTE: Blender did not install: no bmesh column", file=sys.stderr)
    build_curvo()


def install(packages, modules):
    probe = subprocess.run([str(PYTHON), "-c", "import " + ", ".join(modules)], capture_output=True)
    if probe.returncode != 0:
        print("pip install " + " ".join(packages), file=sys.stderr)
        subprocess.run([str(PYTHON), "-m", "pip", "install", "-q", *packages], check=True)


def build_curvo():
    env = dict(os.environ, CARGO_TARGET_DIR=str(OUT / "curvo-target"))
    build = ["nice", "-n", "19", "cargo", "build", "--release", "--quiet"]
    if subprocess.run(build, cwd=HERE / "curvo", env=env).returncode != 0:
        print("NOTE: the curvo crate did not build: no curvo column", file=sys.stderr)


def make_inputs():
    if not all((INPUTS / f).exists() for f in INPUT_FILES):
        print("writing inputs to " + str(INPUTS), file=sys.stderr)
        subprocess.run([str(PYTHON), str(HERE / "make_inputs.py"), str(INPUTS)], check=True)
    if shutil.which("blender") and not (INPUTS / SUZANNE).exists():
        print("writing Blender's Suzanne to " + str(INPUTS / SUZANNE), file=sys.stderr)
        spawn(blender("suzanne", INPUTS / SUZANNE))
    for name, text in RULES.items():
        (INPUTS / f"{name}.toml").write_text(text)
    MESHES.mkdir(parents=True, exist_ok=True)


def available_peers(args):
    found = {"libigl", "trimesh", "cgal", "qhull", "geomdl", "splinepy"}
    if shutil.which("blender"):
        found.add("bmesh")
    if CURVO.exists():
        found.add("curvo")
    if args.with_occt and importable("OCP"):
        found.add("occt")
    wanted = set(args.peers.split(",")) if args.peers else set(PEERS)
    unknown = wanted - set(PEERS)
    if unknown:
        sys.exit("unknown peers: " + ", ".join(sorted(unknown)))
    return [p for p in PEERS if p in found & wanted]


def importable(module):
    return subprocess.run([str(PYTHON), "-c", "import " + module], capture_output=True).returncode == 0


# ---------------------------------------------------------------- rule files

GRID = "[start]\ngrid = {{ segments = [{nx}, {ny}], size = [{sx}, {sy}] }}\n"
STEP = '\n[[step]]\nname = "{name}"\n{body}\n'
HILL = """[nurbs.hill]
degree = 3
size = [10, 10]
points = ["i", "j", "2 * sin(0.7 * i) * cos(0.5 * j)"]
weights = "1 + 0.5 * ((i + j) % 3)"
"""


def grid_rule(n, m=None, *steps):
    m = m or n
    text = GRID.format(nx=n, ny=m, sx=n / 100, sy=m / 100)
    return text + "".join(STEP.format(name=name, body=body) for name, body in steps)


def subdivide_rule(cage, levels):
    step = ("subdivide", f"subdivide = {{ levels = {levels} }}")
    if cage.startswith("grid"):
        return grid_rule(int(cage[4:]), None, step)
    return f'[start]\nimport = {{ path = "{cage}.obj" }}\n' + STEP.format(name=step[0], body=step[1])


def hull_rule(kind, n):
    """The points as loose vertices, their hull, then the points deleted
    (the hull's vertices are new ones), so the counts are the hull's."""
    return (
        f'[start]\nimport = {{ path = "{kind}{n}.ply" }}\n'
        + STEP.format(name="hull", body="convex_hull = {}")
        + STEP.format(name="points", body='on = "vertices"\nselect = "faces == 0"\ndelete = {}')
    )


def bevel_rule(n, segments):
    body = (
        'on = "edges"\n'
        f"bevel = {{ width = {bevel_width(n)!r}, segments = {segments}, profile = 0.5, "
        'offset_type = "offset", clamp_overlap = false }'
    )
    return f'[start]\nimport = {{ path = "qsphere{n}.ply" }}\n' + STEP.format(name="bevel", body=body)


def uniform_rule(n):
    cells = f"[{n - 1}, {n - 1}]"
    return (
        HILL
        + f'\n[start]\nnurbs = {{ surface = "hill", mode = "uniform", cells = {cells}, per_patch = false }}\n'
    )


RULES = {
    "weld": '[start]\nimport = { path = "soup.ply", weld = 0.0001 }\n',
    "merge": '[start]\nimport = { path = "soup.ply" }\n'
    + STEP.format(name="merge", body="merge = { distance = 0.0001 }"),
    "inset": grid_rule(256, None, ("inset", "inset_region = { thickness = 0.001 }")),
    "grid": grid_rule(1000),
    "extrude": grid_rule(1000, None, ("extrude", "extrude_faces = { distance = 0.01 }")),
    "triangulate": grid_rule(300, None, ("triangulate", "triangulate = {}")),
    "mirror": grid_rule(
        256,
        None,
        ("move", "translate = { offset = [1.28, 0, 0] }"),
        ("mirror", 'on = "faces"\nmirror = { axis = "x", merge_distance = 0.00001 }'),
    ),
    "glb": grid_rule(500, 1000, ("triangulate", "triangulate = {}")),
    "uniform100": uniform_rule(100),
    "uniform1000": uniform_rule(1000),
    "adaptive": (ROOT / "rules" / "nurbs-surface.toml").read_text(),
    **{f"subdivide-{cage}-L{levels}": subdivide_rule(cage, levels) for cage, levels in SUBDIVIDE_CASES},
    **{f"hull-{kind}{n}": hull_rule(kind, n) for kind, n in HULL_SETS},
    **{f"bevel-qsphere{n}-S{segments}": bevel_rule(n, segments) for n, segments in BEVEL_CASES},
}


# ---------------------------------------------------------------- running tools


def spawn(argv):
    """Run argv to the end: wall seconds, stdout, peak RSS in MiB. Raises on failure."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        start = time.perf_counter()
        proc = subprocess.Popen(argv, stdout=out, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        if proc.returncode != 0:
            raise RuntimeError(f"{Path(argv[0]).name} exited {proc.returncode}: {err.read().strip()[-400:]}")
        return wall, out.read(), usage.ru_maxrss / 1024


def peer(argv):
    """A peer script's JSON line."""
    _, stdout, _ = spawn(argv)
    lines = [line for line in stdout.splitlines() if line.startswith("{")]
    if not lines:
        raise RuntimeError("no JSON line from " + " ".join(argv))
    return json.loads(lines[-1])


def venv_py(script, *args):
    return [str(PYTHON), str(HERE / script), *map(str, args)]


def blender(*args):
    site = next((VENV / "lib").glob("python3*/site-packages"))
    return [
        "blender",
        "-b",
        "--factory-startup",
        "--python-exit-code",
        "1",
        "--python",
        str(HERE / "bmesh_bench.py"),
        "--",
        str(site),
        *map(str, args),
    ]


def curvo(*args):
    return [str(CURVO), *map(str, args)]


def graftal_run(rule, ext=".ply", flags=()):
    """One run as a one-variant batch with --timings (its manifest records
    the step times and counts without the --stats mesh analysis, which on
    the 5M-face extrude costs ~100 s), one plain run (wall, RSS); `flags`
    go to both."""
    out = MESHES / f"{rule}{ext}"
    batch = MESHES / f"{rule}-batch"
    shutil.rmtree(batch, ignore_errors=True)
    rules = str(INPUTS / f"{rule}.toml")
    spawn([str(RUNNING[0]), "run", rules, *flags, "--seeds", "0..1", "-o", str(batch / ("{seed}" + ext)), "--timings", "-q"])
    variant = json.loads((batch / "manifest.json").read_text())["variants"][0]
    wall, _, rss = spawn([str(RUNNING[0]), "run", rules, *flags, "-o", str(out), "-q"])
    steps = {s["name"]: s for s in variant["steps"]}
    return variant["counts"], steps, wall, rss, out


def result(seconds, mesh=None, wall=None, **extra):
    counts = {"vertices": mesh["vertices"], "faces": mesh["faces"]} if mesh else {}
    return {"seconds": seconds, "wall": wall, **counts, **extra}


def step_seconds(step):
    return step["time_ms"] / 1000


# ---------------------------------------------------------------- graftal, per workload


def graftal_merge():
    mesh, steps, wall, _, _ = graftal_run("weld")
    weld = result(step_seconds(steps["start"]), mesh, wall)
    mesh, steps, wall, _, _ = graftal_run("merge")
    return {
        "merge": result(step_seconds(steps["merge"]), mesh, wall),
        "weld": weld,
        "import": result(step_seconds(steps["start"]), vertices=steps["start"]["created_vertices"]),
    }


def graftal_step(rule, step):
    def run():
        mesh, steps, wall, _, _ = graftal_run(rule)
        return {rule: result(step_seconds(steps[step]), mesh, wall)}

    return run


def graftal_glb():
    mesh, steps, wall, rss, out = graftal_run("glb", ".glb")
    write = wall - sum(step_seconds(s) for s in steps.values())
    return {"write": result(write, mesh, wall, bytes=out.stat().st_size, rss_mib=rss)}


def graftal_selfx():
    argv = [str(RUNNING[0]), "info", str(INPUTS / "selfx.ply"), "--json"]
    wall, stdout, _ = spawn(argv)
    info = json.loads(stdout)
    return {"selfx": result(None, info, wall, pairs=info["self_intersecting_face_pairs"])}


def graftal_nurbs_grid():
    found = {}
    for n in (100, 1000):
        mesh, steps, wall, _, out = graftal_run(f"uniform{n}")
        found[f"uniform{n}"] = result(
            step_seconds(steps["start"]), mesh, wall, sum_z=float(ply_vertices(out)[:, 2].sum())
        )
        found[f"points{n}"] = result(criterion_median(f"grid_points/{n}x{n}"))
    return found


def graftal_nurbs_adaptive():
    _, steps, wall, _, _ = graftal_run("adaptive")
    surface = steps["start"]["surface"]
    return {
        "adaptive": result(
            step_seconds(steps["start"]),
            wall=wall,
            vertices=surface["vertices"],
            faces=surface["triangles"],
            max_deviation=surface["max_deviation"],
        )
    }


def graftal_subdivide():
    found = {}
    for cage, levels in SUBDIVIDE_CASES:
        key = f"subdivide-{cage}-L{levels}"
        mesh, steps, wall, _, out = graftal_run(key)
        found[key] = result(
            step_seconds(steps["subdivide"]), mesh, wall, sum_abs=float(abs(ply_vertices(out)).sum())
        )
    return found


def graftal_hull():
    found = {}
    for kind, n in HULL_SETS:
        mesh, steps, wall, _, _ = graftal_run(f"hull-{kind}{n}")
        found[f"hull-{kind}{n}"] = result(step_seconds(steps["hull"]), mesh, wall)
    return found


def graftal_bevel():
    """--max-primitives: the bevel step's growth bound, (segments + 1)² · 8
    per selected edge and vertex, is 48M at 1,002,252 edges and 1 segment
    (it makes 6M), past the default limit of 50M with the input."""
    found = {}
    for n, segments in BEVEL_CASES:
        key = f"bevel-qsphere{n}-S{segments}"
        mesh, steps, wall, _, out = graftal_run(key, flags=("--max-primitives", "400000000"))
        found[key] = result(
            step_seconds(steps["bevel"]), mesh, wall, sum_abs=float(abs(ply_vertices(out)).sum())
        )
    return found


def criterion_median(bench_id):
    path = CRITERION / bench_id / "new" / "estimates.json"
    if not path.exists():
        return None
    return json.loads(path.read_text())["median"]["point_estimate"] / 1e9


def ply_vertices(path):
    """The vertex block of a binary little-endian PLY whose vertex properties are scalars."""
    import numpy as np

    types = {"float": "<f4", "double": "<f8", "int": "<i4", "uint": "<u4", "uchar": "u1"}
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().splitlines()
    count = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    start = header.index(f"element vertex {count}") + 1
    props = []
    for line in header[start:]:
        if not line.startswith("property"):
            break
        props.append((line.split()[2], types[line.split()[1]]))
    verts = np.frombuffer(data, np.dtype(props), count, end)
    return np.column_stack([verts["x"], verts["y"], verts["z"]])


# ---------------------------------------------------------------- workloads


@dataclass
class Row:
    label: str
    key: str  # which graftal result
    peers: dict = field(default_factory=dict)  # column -> argv
    check: tuple = ("vertices", "faces")  # fields every tool must agree on
    expect: dict = field(default_factory=dict)  # field -> the right answer
    show: tuple = ()  # fields for the outputs table (default: check)
    unchecked: tuple = ()  # peers timed and shown but not held to check (inexact by design)


@dataclass
class Workload:
    name: str
    title: str
    graftal: object
    rows: list


def workloads(args):
    soup, selfx = INPUTS / "soup.npz", INPUTS / "selfx.npz"
    merge_peers = {
        "libigl": venv_py("peers_igl.py", "merge", soup),
        "trimesh": venv_py("peers_trimesh.py", "merge", soup),
        "bmesh": blender("merge", soup),
    }
    soup_counts = {"vertices": 167281, "faces": 332928}
    return [
        Workload(
            "merge",
            "1. soup merge, 998,784 → 167,281 vertices at 1e-4",
            graftal_merge,
            [
                Row(
                    "`merge` step (import without weld, then merge)", "merge", merge_peers, expect=soup_counts
                ),
                Row("`import` with `weld = 1e-4` (import step)", "weld", merge_peers, expect=soup_counts),
                Row(
                    "`import` without weld (import step; no merge)",
                    "import",
                    check=("vertices",),
                    expect={"vertices": 998784},
                ),
            ],
        ),
        Workload(
            "inset",
            "2. inset_region, 256² quads, thickness 0.001 (0.1 cell)",
            graftal_step("inset", "inset"),
            [
                Row("`inset_region` step", "inset", {"bmesh": blender("inset", 256, 0.001)}),
            ],
        ),
        Workload(
            "grid",
            "3. grid 1000² (1M quads)",
            graftal_step("grid", "start"),
            [
                Row(
                    "`[start] grid` / `create_grid`",
                    "grid",
                    {"bmesh": blender("grid", 1000)},
                    expect={"vertices": 1002001, "faces": 1000000},
                ),
            ],
        ),
        Workload(
            "extrude",
            "4. extrude 1M faces individually",
            graftal_step("extrude", "extrude"),
            [
                Row(
                    "`extrude_faces` step (bmesh: `extrude_discrete_faces`, not moved)",
                    "extrude",
                    {"bmesh": blender("extrude", 1000)},
                    expect={"vertices": 5002001, "faces": 5000000},
                ),
            ],
        ),
        Workload(
            "triangulate",
            "5. triangulate 90k quads (300²)",
            graftal_step("triangulate", "triangulate"),
            [
                Row(
                    "`triangulate` step",
                    "triangulate",
                    {
                        "trimesh": venv_py("peers_trimesh.py", "triangulate", INPUTS / "quads300.npz"),
                        "bmesh": blender("triangulate", 300),
                    },
                    expect={"vertices": 90601, "faces": 180000},
                ),
            ],
        ),
        Workload(
            "mirror",
            "6. mirror 256² = 65,536 faces across their border, seam merged (1e-5)",
            graftal_step("mirror", "mirror"),
            [
                Row(
                    "`mirror` step",
                    "mirror",
                    {"bmesh": blender("mirror", 256)},
                    expect={"vertices": 131841, "faces": 131072},
                ),
            ],
        ),
        Workload(
            "glb",
            "7. GLB of 1M triangles (500×1000 grid, triangulated)",
            graftal_glb,
            [
                Row(
                    "GLB write, the same content: positions, normals, indices, 24 MB "
                    "(graftal: whole process − its step times; trimesh `include_normals=True`)",
                    "write",
                    {
                        "trimesh": venv_py(
                            "peers_trimesh.py",
                            "glb-normals",
                            INPUTS / "tri1m.npz",
                            MESHES / "trimesh-normals.glb",
                        )
                    },
                    expect={"vertices": 501501, "faces": 1000000},
                ),
                Row(
                    "GLB write, trimesh's default: no normals, 18 MB (graftal: the same 24 MB run)",
                    "write",
                    {
                        "trimesh": venv_py(
                            "peers_trimesh.py", "glb", INPUTS / "tri1m.npz", MESHES / "trimesh.glb"
                        )
                    },
                    expect={"vertices": 501501, "faces": 1000000},
                ),
            ],
        ),
        Workload(
            "selfx",
            "8. self-intersection, 102,400 triangles (two icospheres)",
            graftal_selfx,
            [
                Row(
                    "all pairs (graftal: `info`, whole process)",
                    "selfx",
                    {
                        "cgal": venv_py("peers_cgal.py", "pairs", INPUTS / "selfx.off"),
                        "bmesh": blender("selfx", selfx),
                    },
                    check=("pairs",),
                    expect={"pairs": 902},
                ),
                Row(
                    "any pair? (CGAL `does_self_intersect`; graftal `info` finds all)",
                    "selfx",
                    {"cgal": venv_py("peers_cgal.py", "any", INPUTS / "selfx.off")},
                    check=(),
                    show=("pairs",),
                ),
            ],
        ),
        Workload(
            "nurbs-grid",
            "9. NURBS 10×10 bicubic, N × N points",
            graftal_nurbs_grid,
            nurbs_grid_rows(args.slow),
        ),
        Workload(
            "nurbs-adaptive",
            "10. NURBS adaptive at 1e-3 (counts differ by design)",
            graftal_nurbs_adaptive,
            [
                Row(
                    "graftal adaptive (sagitta) / curvo norm tolerance / OCCT deflection",
                    "adaptive",
                    {"curvo": curvo("adaptive", 1e-3), "occt": venv_py("peers_nurbs.py", "occt-mesh", 0.001)},
                    check=(),
                    show=("vertices", "faces"),
                ),
            ],
        ),
        Workload(
            "subdivide",
            "11. subdivide, Catmull–Clark (Blender: the subdivision-surface modifier applied, OpenSubdiv)",
            graftal_subdivide,
            subdivide_rows(),
        ),
        Workload(
            "hull",
            "12. convex hull of random points",
            graftal_hull,
            hull_rows(),
        ),
        Workload(
            "bevel",
            "13. bevel every edge of a quad sphere (offset 0.1 / N, profile 0.5, no clamping)",
            graftal_bevel,
            bevel_rows(),
        ),
    ]


# Suzanne's 500 faces have 1,968 corners: level 1 makes a quad per corner,
# every further level four of each.
SUZANNE_CORNERS = 1968


def subdivide_rows():
    rows = []
    for cage, levels in SUBDIVIDE_CASES:
        if cage == "suzanne":
            label = f"Suzanne (500 faces), level {levels}"
            expect = {"faces": SUZANNE_CORNERS * 4 ** (levels - 1)}
        else:
            n = int(cage[4:]) * 2**levels
            label = f"grid {cage[4:]}², level {levels} (open: boundary Keep Corners)"
            expect = {"vertices": (n + 1) ** 2, "faces": n * n}
        cage_arg = INPUTS / SUZANNE if cage == "suzanne" else cage
        rows.append(
            Row(
                f"`subdivide` step, {label}",
                f"subdivide-{cage}-L{levels}",
                {"bmesh": blender("subdivide", cage_arg, levels)},
                check=("vertices", "faces", "sum_abs"),
                expect=expect,
            )
        )
    return rows


def bevel_rows():
    """Every edge beveled, so every vertex is a corner patch: its valence
    in vertices (one a band end), one face for it at 1 segment. At 1
    segment the positions are Blender's (the sums agree to 1e-6); at 3 the
    corner patches' interiors differ by design (graftal's Coons patch on
    the superellipsoid, Blender's subdivision): the same counts, sums
    shown only."""
    rows = []
    for n, segments in BEVEL_CASES:
        edges, faces, verts = 12 * n * n, 6 * n * n, 6 * n * n + 2
        expect = {"vertices": 2 * edges, "faces": faces + edges + verts} if segments == 1 else {}
        rows.append(
            Row(
                f"`bevel` step, {edges:,} edges ({n}² cells a face), {segments} segment{'s' * (segments > 1)}",
                f"bevel-qsphere{n}-S{segments}",
                {"bmesh": blender("bevel", INPUTS / f"qsphere{n}.npz", repr(bevel_width(n)), segments)},
                check=("vertices", "faces", "sum_abs") if segments == 1 else ("vertices", "faces"),
                show=("vertices", "faces", "sum_abs"),
                expect=expect,
            )
        )
    return rows


def hull_rows():
    rows = []
    for kind, n in HULL_SETS:
        where = "in the unit ball" if kind == "ball" else "on the unit sphere (all extreme)"
        rows.append(
            Row(
                f"`convex_hull` step, {n:,} points {where}",
                f"hull-{kind}{n}",
                {
                    "qhull": venv_py("peers_scipy.py", "hull", INPUTS / f"{kind}{n}.npy"),
                    "bmesh": blender("hull", INPUTS / f"{kind}{n}.npy"),
                },
                expect={"vertices": n} if kind == "sphere" else {},
                unchecked=("bmesh",),
            )
        )
    return rows


S_03_06 = [3.0497846, 5.1406050, -1.2761698]
SUM_Z = {100: 9.705, 1000: 1016.447}


def nurbs_grid_rows(slow):
    rows = []
    for n in (100, 1000):
        samplers = {"geomdl": venv_py("peers_nurbs.py", "geomdl", n)} if n == 100 or slow else {}
        samplers |= {t: venv_py("peers_nurbs.py", t, n) for t in ("splinepy", "occt")}
        samplers["curvo"] = curvo("sample", n)
        check = {"vertices": n * n, "sum_z": SUM_Z[n]}
        rows.append(
            Row(
                f"{n}² points (graftal: criterion `grid_points/{n}x{n}`)",
                f"points{n}",
                samplers,
                check=("vertices", "sum_z", "point"),
                expect=check | {"point": S_03_06},
            )
        )
        rows.append(
            Row(
                f'{n}² uniform tessellation (graftal `mode = "uniform"` step)',
                f"uniform{n}",
                {"curvo": curvo("tessellate", n)},
                check=("vertices", "faces", "sum_z"),
                expect=check | {"faces": 2 * (n - 1) ** 2},
            )
        )
    return rows


WORKLOAD_NAMES = [
    "merge",
    "inset",
    "grid",
    "extrude",
    "triangulate",
    "mirror",
    "glb",
    "selfx",
    "nurbs-grid",
    "nurbs-adaptive",
    "subdivide",
    "hull",
    "bevel",
]


# ---------------------------------------------------------------- measuring


def attempt(fn, *args):
    try:
        return fn(*args)
    except (RuntimeError, subprocess.TimeoutExpired, OSError, KeyError, ValueError) as err:
        print(f"  ERROR: {err}", file=sys.stderr)
        return {"error": str(err)}


def measure(workload, peers, runs, baseline=None):
    """Interleaved rounds: graftal (then the baseline graftal), then each
    distinct peer call, then the next round."""
    graftal_rounds, baseline_rounds, peer_rounds = [], [], []
    for r in range(runs):
        print(f"  round {r + 1}/{runs}: graftal", file=sys.stderr)
        graftal_rounds.append(attempt(workload.graftal))
        if baseline:
            print(f"  round {r + 1}/{runs}: graftal before ({baseline.name})", file=sys.stderr)
            RUNNING[0] = baseline
            try:
                baseline_rounds.append(attempt(workload.graftal))
            finally:
                RUNNING[0] = GRAFTAL
        calls = {}
        for row in workload.rows:
            for name, argv in row.peers.items():
                if name in peers and tuple(argv) not in calls:
                    what = " ".join(Path(a).name for a in argv[-3:])
                    print(f"  round {r + 1}/{runs}: {name} {what}", file=sys.stderr)
                    calls[tuple(argv)] = attempt(peer, argv)
        peer_rounds.append(calls)
    return graftal_rounds, baseline_rounds, peer_rounds


def summarise(row, peers, graftal_rounds, baseline_rounds, peer_rounds):
    """Per tool: median seconds (and wall), the last round's counts."""
    tools = {"graftal": [g.get(row.key, g) for g in graftal_rounds]}
    if baseline_rounds:
        tools[BEFORE] = [g.get(row.key, g) for g in baseline_rounds]
    for name, argv in row.peers.items():
        if name in peers:
            tools[name] = [calls[tuple(argv)] for calls in peer_rounds]
    return {name: collapse(results) for name, results in tools.items()}


def collapse(results):
    import numpy as np  # here and in ply_vertices: the set-up stage runs before the venv exists

    good = [r for r in results if "error" not in r]
    if not good:
        return {"error": results[-1]["error"]}
    merged = dict(good[-1])
    for key in ("seconds", "wall"):
        values = [r[key] for r in good if r.get(key) is not None]
        merged[key] = float(np.median(values)) if values else None
    return merged


def close(a, b, tol):
    if isinstance(a, list):
        return all(close(x, y, tol) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) or isinstance(b, float):
        return math.isclose(a, b, rel_tol=1e-6, abs_tol=tol)
    return a == b


def disagreements(row, tools):
    """Lines naming each field on which the tools differ or miss the right answer."""
    found = []
    for fld in row.check:
        values = {
            name: t[fld] for name, t in tools.items() if t.get(fld) is not None and name not in row.unchecked
        }
        got = ", ".join(f"{n} {v}" for n, v in values.items())
        if fld in row.expect:
            if any(not close(v, row.expect[fld], 1e-3) for v in values.values()):
                found.append(f"{fld}: expected {row.expect[fld]}, got {got}")
        elif any(not close(v, next(iter(values.values())), 1e-6) for v in values.values()):
            found.append(f"{fld}: {got}")
    return found


# ---------------------------------------------------------------- report


def seconds(value):
    return "–" if value is None else f"{value:.3g} s"


def count(value):
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.6f}"
    if isinstance(value, list):
        return "(" + ", ".join(f"{v:.7f}" for v in value) + ")"
    return f"{value:,}"


def cell(tool):
    if tool is None:
        return "–"
    if "error" in tool:
        return "error"
    return seconds(tool["seconds"])


BEFORE = "graftal before"


def speedup(tools):
    """Baseline over graftal, on the step (else the whole process)."""
    if BEFORE not in tools:
        return None
    now, then = tools["graftal"], tools[BEFORE]
    for key in ("seconds", "wall"):
        if now.get(key) and then.get(key):
            return f"{then[key] / now[key]:.2f}"
    return "–"


def ratio(tools, peers, unchecked=()):
    """Best peer / graftal, among the peers whose outputs are checked."""
    graftal = tools["graftal"]
    mine = graftal.get("seconds") if graftal.get("seconds") is not None else graftal.get("wall")
    timed = [
        (tools[p]["seconds"], p)
        for p in peers
        if p in tools and p not in unchecked and tools[p].get("seconds")
    ]
    if not mine or not timed:
        return "–"
    best, name = min(timed)
    return f"{best / mine:.2f} ({name})"


def outputs(row, tools):
    fields = row.show or row.check
    parts = []
    for name, tool in tools.items():
        shown = [f"{f} {count(tool[f])}" for f in fields if tool.get(f) is not None]
        if "intersects" in tool:
            shown.append("intersects " + count(tool["intersects"]))
        if shown:
            parts.append(f"{name}: " + ", ".join(shown))
    return "; ".join(parts)


def machine(peers):
    cpu = next(
        (
            line.split(":", 1)[1].strip()
            for line in Path("/proc/cpuinfo").read_text().splitlines()
            if line.startswith("model name")
        ),
        platform.processor(),
    )
    mem = int(re.search(r"MemTotal:\s+(\d+)", Path("/proc/meminfo").read_text()).group(1)) / 2**20
    release = re.search(r'PRETTY_NAME="([^"]+)"', Path("/etc/os-release").read_text()).group(1)
    versions = [
        subprocess.run([str(GRAFTAL), "--version"], capture_output=True, text=True).stdout.strip(),
        f"Python {platform.python_version()}",
        f"numpy {metadata.version('numpy')}",
    ]
    versions += [
        f"{DISTRIBUTIONS[p]} {metadata.version(DISTRIBUTIONS[p])}" for p in peers if p in DISTRIBUTIONS
    ]
    if "bmesh" in peers:
        versions.append(
            subprocess.run(["blender", "--version"], capture_output=True, text=True).stdout.splitlines()[0]
        )
    if "curvo" in peers:
        versions.append(
            "curvo "
            + re.search(
                r'name = "curvo"\nversion = "([^"]+)"', (HERE / "curvo" / "Cargo.lock").read_text()
            ).group(1)
        )
    nproc = subprocess.run(["nproc"], capture_output=True, text=True).stdout.strip()
    return [
        f"Machine: nproc {nproc}, {cpu}, {mem:.1f} GiB RAM, {release}, kernel {platform.release()}.",
        f"Load average at start: {os.getloadavg()[0]:.2f}.",
        f"Command: `GRAFTAL={GRAFTAL} python3 bench-peers/run.py {' '.join(sys.argv[1:])}`.",
        "Versions: " + "; ".join(versions) + ".",
    ]


def report(args, peers, results, notes):
    before = ["graftal before: step", "before / now"] if args.baseline else []
    columns = ["graftal step", "graftal whole process"] + before + peers
    lines = [
        "# graftal and its peers",
        "",
        *machine(peers),
        "",
        f"Median of {args.runs} interleaved rounds. Peers: the operation alone (input loaded first). "
        "graftal: the step's `time_ms` from a one-variant batch manifest (`--seeds 0..1 --timings`), and the whole process "
        "(a second, plain run). Ratio: best peer / graftal (step, else whole process; peers whose counts "
        "are not checked are left out); "
        "above 1 means graftal is faster. ⚠ marks a row whose tools disagree."
        + (
            f" graftal before: `{args.baseline}`, run in the same rounds right after graftal;"
            " before / now above 1 means graftal got faster."
            if args.baseline
            else ""
        ),
        "",
        "| workload | " + " | ".join(columns) + " | best peer / graftal |",
        "|---" * (len(columns) + 2) + "|",
    ]
    details = ["", "## Outputs", "", "| workload | counts per tool |", "|---|---|"]
    for workload, row, tools, bad in results:
        flag = " ⚠" if bad else ""
        graftal = tools["graftal"]
        cells = [cell(graftal), "error" if "error" in graftal else seconds(graftal.get("wall"))]
        if args.baseline:
            then = tools.get(BEFORE)
            cells += [cell(then) if then and then.get("seconds") is not None else seconds(then and then.get("wall")), speedup(tools)]
        cells += [cell(tools.get(p)) if p in row.peers else "–" for p in peers]
        label = f"{workload.title}: {row.label}{flag}"
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {ratio(tools, peers, row.unchecked)} |")
        details.append(f"| {label} | {outputs(row, tools)} |")
    text = "\n".join(lines + details + ["", "## Notes", ""] + [f"- {n}" for n in notes]) + "\n"
    print(text)
    (OUT / "results.md").write_text(text)
    raw = [{"workload": w.title, "row": r.label, "tools": t, "disagreements": b} for w, r, t, b in results]
    (OUT / "results.json").write_text(json.dumps(raw, indent=1) + "\n")


def notes_for(row, tools):
    notes = []
    for name, tool in tools.items():
        if "error" in tool:
            notes.append(f"{row.label}: {name} failed: {tool['error']}")
        if tool.get("bytes"):
            rss = f", peak RSS {tool['rss_mib']:.0f} MiB" if tool.get("rss_mib") else ""
            notes.append(f"{row.label}: {name} wrote {tool['bytes']:,} bytes{rss}")
        if tool.get("max_deviation") is not None:
            notes.append(f"{row.label}: {name} max_deviation {tool['max_deviation']:.3g}")
        if tool.get("sharing_vertex"):
            notes.append(
                f"{row.label}: {name}'s {tool['pairs']} pairs include {tool['sharing_vertex']} "
                "neighbours that share a vertex; without them "
                f"{tool['pairs'] - tool['sharing_vertex']}"
            )
        if name == "graftal" and row.key.startswith("points") and tool.get("seconds") is None:
            notes.append(
                f"{row.label}: no criterion estimate under {CRITERION}: "
                "run `cargo bench --bench nurbs -- grid_points` first"
            )
    return notes


def skipped_notes(args, peers, chosen):
    notes = [] if "bmesh" in peers else ["Blender is not installed: no bmesh column."]
    if "geomdl" in peers and "nurbs-grid" in chosen and not args.slow:
        notes.append("geomdl at 1000² is left out (about 16 s a call): run with --slow to include it.")
    if "hull" in chosen and "bmesh" in peers:
        notes.append(
            "convex hull: bmesh's counts are shown, not checked: it rounds the points to float32 and "
            "drops points nearly coplanar with their neighbours, so it finds fewer hull vertices "
            "than the exact hulls (graftal's, qhull's) on dense sets."
        )
    if "subdivide" in chosen and not shutil.which("blender"):
        notes.append("subdivide: without Blender there is no Suzanne cage (it is written by Blender): its rows fail.")
    if not args.with_occt:
        notes.append("OCP (OCCT) is left out: run with --with-occt or BENCH_PEERS_OCCT=1.")
    return notes


def main():
    args = parse_args()
    if Path(sys.prefix).resolve() != VENV.resolve():
        setup(args)
        os.execv(str(PYTHON), [str(PYTHON), __file__, *sys.argv[1:]])
    if not GRAFTAL.exists():
        sys.exit(f"no graftal binary at {GRAFTAL}: build it or set GRAFTAL")
    baseline = args.baseline.resolve() if args.baseline else None
    if baseline and not baseline.exists():
        sys.exit(f"no baseline binary at {baseline}")
    make_inputs()
    peers = available_peers(args)
    chosen = args.only.split(",") if args.only else WORKLOAD_NAMES
    unknown = set(chosen) - set(WORKLOAD_NAMES)
    if unknown:
        sys.exit("unknown workloads: " + ", ".join(sorted(unknown)))
    results, notes = [], skipped_notes(args, peers, chosen)
    for workload in workloads(args):
        if workload.name not in chosen:
            continue
        print(f"{workload.title}", file=sys.stderr)
        graftal_rounds, baseline_rounds, peer_rounds = measure(workload, peers, args.runs, baseline)
        for row in workload.rows:
            tools = summarise(row, peers, graftal_rounds, baseline_rounds, peer_rounds)
            bad = disagreements(row, tools)
            for line in bad:
                print(f"!!! DISAGREEMENT in {workload.title}: {row.label}: {line}", file=sys.stderr)
            notes += [f"DISAGREEMENT, {row.label}: {line}" for line in bad] + notes_for(row, tools)
            results.append((workload, row, tools, bad))
    report(args, peers, results, notes)


if __name__ == "__main__":
    main()
