"""CGAL (the `cgal` SWIG wheel) on the self-intersection workload.

python peers_cgal.py pairs selfx.off   # self_intersections: every pair
python peers_cgal.py any selfx.off     # does_self_intersect: yes or no
"""

import sys

import CGAL.CGAL_Polygon_mesh_processing as pmp
from CGAL.CGAL_Polyhedron_3 import Polyhedron_3

from benchlib import emit, timed


def pairs(path):
    mesh = Polyhedron_3(path)
    found = []
    seconds, _ = timed(pmp.self_intersections, mesh, found)
    emit(seconds, mesh.size_of_vertices(), mesh.size_of_facets(), len(found))


def any_pair(path):
    mesh = Polyhedron_3(path)
    seconds, hit = timed(pmp.does_self_intersect, mesh)
    emit(seconds, mesh.size_of_vertices(), mesh.size_of_facets(), intersects=hit)


if __name__ == "__main__":
    {"pairs": pairs, "any": any_pair}[sys.argv[1]](*sys.argv[2:])
