"""Reference values for tests/oracle.rs, from geomdl 5.4.0 (the thesis's own library) and
splinepy 0.2.1. Run: python3 tests/oracle/gen.py > /tmp/oracle.txt; the numbers are pasted
into tests/oracle.rs (no runtime dependency)."""
import math
from geomdl import NURBS, BSpline, utilities, operations
import numpy as np
import splinepy

def peer():
    s = NURBS.Surface()
    s.degree_u = 3; s.degree_v = 3
    pts = []; w = []
    for i in range(10):
        for j in range(10):
            pts.append([i, j, 2*math.sin(0.7*i)*math.cos(0.5*j)])
            w.append(1 + 0.5*((i+j) % 3))
    s.ctrlpts_size_u = 10; s.ctrlpts_size_v = 10
    s.ctrlpts = pts; s.weights = w
    s.knotvector_u = utilities.generate_knot_vector(3, 10)
    s.knotvector_v = utilities.generate_knot_vector(3, 10)
    return s, pts, w

s, pts, w = peer()
print("# peer surface: u v | S | Su | Sv | Suu | Suv | Svv | normal")
for (u, v) in [(0.3, 0.6), (0.0, 0.0), (1.0, 1.0), (0.5, 0.5), (0.123, 0.987), (0.9, 0.05), (1/7, 3/7)]:
    d = s.derivatives(u, v, order=2)
    n = operations.normal(s, (u, v))[1]
    print("PEER", u, v, *d[0][0], *d[1][0], *d[0][1], *d[2][0], *d[1][1], *d[0][2], *n)

# splinepy cross-check of S(0.3, 0.6)
sp = splinepy.NURBS(degrees=[3, 3], knot_vectors=[s.knotvector_u, s.knotvector_v],
                    control_points=np.array(pts)[np.array([[i + 10*j for i in range(10)] for j in range(10)]).ravel()] if False else None,
                    weights=None) if False else None
# splinepy orders control points with the first parametric direction fastest.
cp = np.array([[i, j, 2*math.sin(0.7*i)*math.cos(0.5*j)] for j in range(10) for i in range(10)])
ww = np.array([[1 + 0.5*((i+j) % 3)] for j in range(10) for i in range(10)])
sp = splinepy.NURBS(degrees=[3, 3], knot_vectors=[s.knotvector_u, s.knotvector_v], control_points=cp, weights=ww)
print("SPLINEPY", *sp.evaluate([[0.3, 0.6]])[0])
# grid sums
for N in (100, 1000):
    g = np.linspace(0, 1, N)
    q = np.array([[a, b] for a in g for b in g])
    z = sp.evaluate(q)[:, 2].sum()
    print("ZSUM", N, repr(z))

# Example 1.1.5 (Listing 1.2)
b = BSpline.Surface()
b.degree_u = 3; b.degree_v = 2
cps = [[4, 7, 11], [6, 8, 11], [5, 5, 5], [6, 8, 11], [7, 10, 12], [6, 11, 3],
       [7, 5, 3], [7, 7, 3], [7, 11, 6], [9, 7, 3], [9, 9, 0], [9, 11, 5]]
b.set_ctrlpts(cps, 4, 3)
b.knotvector_u = utilities.generate_knot_vector(3, 4)
b.knotvector_v = utilities.generate_knot_vector(2, 3)
for (u, v) in [(0.0, 0.0), (0.25, 0.75), (0.5, 0.5), (1.0, 1.0), (0.8, 0.1)]:
    d = b.derivatives(u, v, order=2)
    print("EX115", u, v, *d[0][0], *d[1][0], *d[0][1], *d[2][0], *d[1][1], *d[0][2])
for (u, v) in [(0.25, 0.75), (0.5, 0.5)]:
    print("EX115N", u, v, *operations.normal(b, (u, v))[1])
b.sample_size = 25
b.evaluate()
print("EX115_SAMPLES", len(b.evalpts))

# Listing 1.1
c = BSpline.Curve(); c.degree = 2; c.ctrlpts = [[0, 0], [10, 15], [20, 0]]
c.knotvector = utilities.generate_knot_vector(2, 3)
for u in [0.0, 0.1, 0.5, 0.77, 1.0]:
    d = c.derivatives(u, order=2)
    print("L11", u, *d[0], *d[1], *d[2])

# Listing 1.5 (geomdl normalises the knots [0..9] to [0, 1])
n = NURBS.Curve(); n.degree = 2
n.ctrlpts = [[-3, 3], [-1, 5], [2, 7], [3, 0], [6, 0], [8, 4], [10, 2.5]]
n.knotvector = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]
print("L15KV", *n.knotvector)
for t in [2/9, 0.3, 0.5, 0.61, 7/9]:
    d = n.derivatives(t, order=2)
    print("L15", t, *d[0], *d[1], *d[2])
n.sample_size = 100
n.evaluate()
print("L15FIRST", *n.evalpts[0], "L15LAST", *n.evalpts[-1])
