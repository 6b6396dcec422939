"""geomdl, splinepy and OCP (OCCT) on the NURBS workload: degree 3 × 3,
10 × 10 control points P_ij = (i, j, 2 sin 0.7i cos 0.5j), weights
1 + 0.5 ((i + j) mod 3), clamped uniform knots.

    python peers_nurbs.py geomdl|splinepy|occt N   # N × N points over [0,1]²
    python peers_nurbs.py occt-mesh TOL            # BRepMesh_IncrementalMesh

Each line carries sum_z (sum of z over the points) and point (S(0.3, 0.6)).
"""

import math
import sys

import numpy as np

from benchlib import emit, timed

DEGREE, SIZE = 3, 10


def net():
    """Control points (i along u is the slower index) and weights."""
    pts = [(i, j, 2 * math.sin(0.7 * i) * math.cos(0.5 * j)) for i in range(SIZE) for j in range(SIZE)]
    weights = [1 + 0.5 * ((i + j) % 3) for i in range(SIZE) for j in range(SIZE)]
    return pts, weights


def knots():
    spans = SIZE - DEGREE
    return [0.0] * DEGREE + [s / spans for s in range(spans + 1)] + [1.0] * DEGREE


def geomdl(n):
    from geomdl import NURBS

    surf = NURBS.Surface()
    surf.degree_u = surf.degree_v = DEGREE
    pts, weights = net()
    surf.ctrlpts_size_u = surf.ctrlpts_size_v = SIZE
    surf.ctrlpts = [list(p) for p in pts]
    surf.weights = weights
    surf.knotvector_u = surf.knotvector_v = knots()

    def sample():
        surf.sample_size = n
        surf.evaluate()
        return surf.evalpts

    seconds, points = timed(sample)
    emit(seconds, len(points), sum_z=sum(p[2] for p in points), point=surf.evaluate_single((0.3, 0.6)))


def splinepy(n):
    import splinepy as sp

    pts, weights = net()
    # splinepy orders control points with u fastest: transpose the net.
    order = [i * SIZE + j for j in range(SIZE) for i in range(SIZE)]
    surf = sp.NURBS(
        degrees=[DEGREE, DEGREE],
        knot_vectors=[knots(), knots()],
        control_points=np.array(pts)[order],
        weights=np.array(weights)[order].reshape(-1, 1),
    )
    seconds, points = timed(surf.sample, [n, n])
    emit(seconds, len(points), sum_z=float(points[:, 2].sum()), point=surf.evaluate([[0.3, 0.6]])[0].tolist())


def occt_surface():
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt
    from OCP.OCP.collections import Array1_double, Array1_int, Array2_double, Array2_gp_Pnt

    pts, weights = net()
    poles, wts = Array2_gp_Pnt(1, SIZE, 1, SIZE), Array2_double(1, SIZE, 1, SIZE)
    for k, (p, w) in enumerate(zip(pts, weights, strict=True)):
        poles.SetValue(k // SIZE + 1, k % SIZE + 1, gp_Pnt(*p))
        wts.SetValue(k // SIZE + 1, k % SIZE + 1, w)
    distinct = sorted(set(knots()))
    values, mults = Array1_double(1, len(distinct)), Array1_int(1, len(distinct))
    for k, u in enumerate(distinct, 1):
        values.SetValue(k, u)
        mults.SetValue(k, knots().count(u))
    return Geom_BSplineSurface(poles, wts, values, values, mults, mults, DEGREE, DEGREE)


def occt(n):
    surf = occt_surface()
    ts = [k / (n - 1) for k in range(n)]

    def sample():
        return [surf.Value(u, v) for u in ts for v in ts]

    seconds, points = timed(sample)
    p = surf.Value(0.3, 0.6)
    emit(seconds, len(points), sum_z=sum(q.Z() for q in points), point=[p.X(), p.Y(), p.Z()])


def occt_mesh(tol):
    from OCP.BRep import BRep_Tool
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.TopLoc import TopLoc_Location

    face = BRepBuilderAPI_MakeFace(occt_surface(), 1e-6).Face()
    seconds, _ = timed(BRepMesh_IncrementalMesh, face, float(tol), False, 0.1)
    mesh = BRep_Tool.Triangulation_s(face, TopLoc_Location())
    emit(seconds, mesh.NbNodes(), mesh.NbTriangles())


if __name__ == "__main__":
    tool, arg = sys.argv[1:]
    if tool == "occt-mesh":
        occt_mesh(arg)
    else:
        {"geomdl": geomdl, "splinepy": splinepy, "occt": occt}[tool](int(arg))
