"""Gauss digitization of closed meshes (contourmesh.voxelize)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from contourmesh.voxelize import voxelize_mesh


def centres(vol, spacing, origin):
    """Physical (x, y, z) of every voxel centre, as three [z, y, x] arrays."""
    h = spacing[0]
    z, y, x = np.meshgrid(*(origin[2 - a] + h * np.arange(vol.shape[a]) for a in range(3)), indexing="ij")
    return x, y, z


@pytest.mark.parametrize("n", [16, 40, 80])
def test_icosphere_volume_and_shape(n):
    s = trimesh.creation.icosphere(subdivisions=4)
    vol, spacing, origin = voxelize_mesh(s.vertices, s.faces, n)
    h = spacing[0]
    assert spacing == (h, h, h) and h == pytest.approx(2.0 / n)
    assert vol.shape == (n + 2, n + 2, n + 2) and vol.dtype == bool
    assert not vol[0].any() and not vol[-1].any() and not vol[:, 0].any() and not vol[:, :, -1].any()
    assert abs(vol.sum() * h**3 / s.volume - 1) < 4.0 / n  # Gauss digitization: O(h) volume error
    # every voxel centre clearly inside / outside the faceted sphere is classified as such
    x, y, z = centres(vol, spacing, origin)
    r = np.sqrt(x * x + y * y + z * z)
    assert vol[r < 0.99 - 1e-9].all()  # the icosphere (subdiv 4) lies within 0.2 % of the unit sphere
    assert not vol[r > 1.0].any()
    from skimage.measure import euler_number

    assert euler_number(vol, connectivity=3) == 1


def test_torus_genus_and_volume():
    t = trimesh.creation.torus(major_radius=1.0, minor_radius=0.4, major_sections=64, minor_sections=32)
    vol, spacing, _ = voxelize_mesh(t.vertices, t.faces, 60)
    from skimage.measure import euler_number

    assert euler_number(vol, connectivity=3) == 0  # one component, one tunnel
    assert abs(vol.sum() * spacing[0] ** 3 / t.volume - 1) < 0.02


def octahedron(scale=1.0):
    v = scale * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    f = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return v, np.array(f)


@pytest.mark.parametrize("n", [3, 5, 7, 9, 10, 16])
def test_rays_through_vertices_and_edges(n):
    # Odd n puts a column exactly through the apexes (0, 0) and columns through the projected edges
    # on the x and y axes: the symbolic tie rule must still count each crossing once.
    v, f = octahedron()
    vol, spacing, origin = voxelize_mesh(v, f, n)
    x, y, z = centres(vol, spacing, origin)
    d = np.abs(x) + np.abs(y) + np.abs(z)
    clear = ~np.isclose(d, 1.0)
    np.testing.assert_array_equal(vol[clear], (d < 1)[clear])
    assert vol.any()


def test_box_with_diagonals_on_sample_columns():
    # The box's faces are split by diagonals through the sample columns (+-0.25, +-0.25): all 4^3 in.
    b = trimesh.creation.box(extents=(2, 2, 2))
    vol, spacing, origin = voxelize_mesh(b.vertices, b.faces, 4)
    assert vol.sum() == 64 and vol[1:-1, 1:-1, 1:-1].all()
    assert spacing == (0.5, 0.5, 0.5) and origin == (-1.25, -1.25, -1.25)


def test_translation_invariance_in_whole_voxels():
    s = trimesh.creation.icosphere(subdivisions=3)
    a, sp, oa = voxelize_mesh(s.vertices, s.faces, 20)
    b, _, ob = voxelize_mesh(s.vertices + np.array([3 * sp[0], -7 * sp[0], 0.0]), s.faces, 20)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(np.subtract(ob, oa), [3 * sp[0], -7 * sp[0], 0.0], atol=1e-12)


def test_seams_are_merged_and_open_meshes_refused():
    s = trimesh.creation.icosphere(subdivisions=2)
    # unshare every vertex (a "seamed" file): merged by position, so still voxelizable
    v = s.vertices[s.faces.ravel()]
    f = np.arange(len(v)).reshape(-1, 3)
    a, _, _ = voxelize_mesh(v, f, 12)
    b, _, _ = voxelize_mesh(s.vertices, s.faces, 12)
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="not watertight"):
        voxelize_mesh(s.vertices, s.faces[1:], 12)


@pytest.mark.parametrize(
    "args, match",
    [
        ((np.zeros((5, 2)), np.zeros((4, 3), int), 8), "vertices"),
        ((np.zeros((6, 3)), np.zeros((4, 3)), 8), "integer"),
        ((np.zeros((6, 3)), np.full((4, 3), 9), 8), "outside"),
        ((octahedron()[0], octahedron()[1], 0), "n must be"),
        ((octahedron()[0], octahedron()[1], 2.5), "n must be"),
    ],
)
def test_input_validation(args, match):
    with pytest.raises(ValueError, match=match):
        voxelize_mesh(*args)


def test_real_mesh_bunny(shared_data):
    path = shared_data / "meshes" / "libigl-tutorial-data" / "bunny.off"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    from contourmesh.compare.inputs import load_closed_mesh

    v, f = load_closed_mesh(path)
    tm = trimesh.Trimesh(v, f, process=False)
    vol, spacing, _ = voxelize_mesh(v, f, 64)
    assert abs(vol.sum() * spacing[0] ** 3 / tm.volume - 1) < 0.03
    from skimage.measure import euler_number

    assert euler_number(vol, connectivity=3) == 1
