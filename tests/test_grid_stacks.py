"""Grid contour stacks (integer points on the pixel centres) with several contours per section: they
mesh the grid points their contours bound, like the volume those points make, and a torus lying flat
(an outer contour and its hole in every section) meshes as its shape does."""

import warnings

import numpy as np
import pytest

import contourmesh
from contourmesh.digitize import outer_jordan_stack
from contourmesh.shapes import Sphere, Torus
from contourmesh.tracing import trace_contours
from contourmesh.types import ContourStack, Section


def _grid_stack(vol):
    """The contour stack of a volume ``[z, y, x]``: each slice's 4-contours through its grid points."""
    secs = []
    for k in range(vol.shape[0]):
        if vol[k].any():
            cs, ps = trace_contours(vol[k])
            secs.append(Section(z=float(k), contours=tuple(np.asarray(c, dtype=np.int64) for c in cs),
                                parents=tuple(int(p) for p in ps)))
    return ContourStack(sections=tuple(secs), spacing=(1.0, 1.0), origin=(0.0, 0.0))


def _two_balls(r=7.0):
    z, y, x = np.mgrid[:20, :20, :40]
    return ((x - 9.6) ** 2 + (y - 9.8) ** 2 + (z - 9.7) ** 2 < r * r) | \
        ((x - 29.3) ** 2 + (y - 9.6) ** 2 + (z - 9.9) ** 2 < r * r)


@pytest.mark.parametrize("triangulation", ["wiederhold", "optimal"])
def test_islands_mesh_the_grid_points_they_bound(triangulation):
    vol = _two_balls()
    stack = _grid_stack(vol)
    assert max(len(s.contours) for s in stack.sections) == 2
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no fallback warning: this is the route for such stacks
        m = contourmesh.mesh(stack, triangulation=triangulation)
    assert m.meta["route"] == "volume"
    ref = contourmesh.mesh(vol, triangulation=triangulation)
    chk = m.checks()
    assert chk["ok"] and chk["components"] == 2 and chk["self_intersections"] == 0
    # the same digital object as the volume: the same surface (the raster of the contours at their
    # own grid points took each boundary half a pixel out: +8 % on a torus of tube radius 5)
    assert m.area == pytest.approx(ref.area, rel=1e-9)
    assert m.volume == pytest.approx(ref.volume, rel=1e-9)
    true = 2 * Sphere(7.0).area
    assert abs(m.area / true - 1) < 0.08  # a coarse ball (r = 7 voxels)


@pytest.mark.parametrize("size", [20, 40])
def test_a_flat_torus_stack_meshes_like_its_shape(size):
    t = Torus(size * 0.75, size * 0.25, center=(0.3, 0.1, 0.2))
    stack = outer_jordan_stack(t)
    assert all(len(s.contours) == 2 for s in stack.sections)
    m = contourmesh.mesh(stack, triangulation="wiederhold")
    shape = contourmesh.mesh(t, triangulation="wiederhold")
    assert m.meta["route"] == "stack" == shape.meta["route"]
    assert m.area == pytest.approx(shape.area, rel=1e-12)
    assert abs(m.area / t.area - 1) < 0.015
