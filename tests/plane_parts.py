"""Test helpers shared by the plane-check tests (``contourmesh.intersect._plane_embedded`` and
its relatives): the boxes of a plane's parts, as the slab phase lays them out."""

import numpy as np

from contourmesh._kernels import njit


@njit(cache=False)
def part_boxes(V, pu, pw):
    """The x and y ranges ``(xlo, xhi, ylo, yhi)`` of the parts ``pu[e] - pw[e]`` (points of
    ``V``), one entry per part."""
    ne = len(pu)
    xlo = np.empty(ne)
    xhi = np.empty(ne)
    ylo = np.empty(ne)
    yhi = np.empty(ne)
    for e in range(ne):
        xlo[e] = min(V[pu[e], 0], V[pw[e], 0])
        xhi[e] = max(V[pu[e], 0], V[pw[e], 0])
        ylo[e] = min(V[pu[e], 1], V[pw[e], 1])
        yhi[e] = max(V[pu[e], 1], V[pw[e], 1])
    return xlo, xhi, ylo, yhi
