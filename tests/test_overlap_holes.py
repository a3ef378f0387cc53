"""The overlap's structure for the joins (:func:`contourmesh.tracing.overlap_holes`: its
4-components, its padded background's 8-components with ``ndimage.label``'s numbers, the components
that reach the outside) from runs, against the pixel form it replaced (a raster union-find over
every pixel, kept here): the same four values, bit for bit, on random masks of many densities,
thin lines and rings, and on every overlap the mesher tests on the shared volumes."""

import numpy as np
from numba import njit

from contourmesh import tracing
from contourmesh.tracing import _join, _root


@njit(nogil=True)
def _label_raster(m, conn8, lab):
    """``scipy.ndimage.label`` of a 2D boolean mask, 4-connected (``conn8 == 0``) or 8-connected:
    ``lab`` (int64, the mask's shape) gets the labels 1 .. n, numbered in raster order of each
    component's first pixel, 0 elsewhere; returns n.

    One raster pass gives each pixel a provisional label (a neighbour's, or a new one) and joins
    the labels of neighbours that meet there (union-find, the lower label the root); provisional
    labels are made in raster order, so each component's root is the label of its first pixel,
    and numbering the roots in order gives ``ndimage.label``'s numbers.  Of the neighbours above
    and to the left only those that may still be apart are joined: 8-connected, a pixel above
    touches the left and upper-left ones already."""
    h, w = m.shape
    parent = np.empty(h * w // 2 + 2, np.int64)
    nprov = 0
    for y in range(h):
        for x in range(w):
            if not m[y, x]:
                lab[y, x] = 0
                continue
            up = lab[y - 1, x] if y > 0 else 0
            left = lab[y, x - 1] if x > 0 else 0
            if conn8 == 0:
                if up and left:
                    cur = _join(parent, up, left) if up != left else up
                elif up:
                    cur = up
                elif left:
                    cur = left
                else:
                    nprov += 1
                    parent[nprov] = nprov
                    cur = nprov
            else:
                ul = lab[y - 1, x - 1] if y > 0 and x > 0 else 0
                ur = lab[y - 1, x + 1] if y > 0 and x < w - 1 else 0
                if up:
                    cur = up
                elif ur:
                    cur = ur
                    if ul and ul != ur:
                        cur = _join(parent, ur, ul)
                    elif left and left != ur:
                        cur = _join(parent, ur, left)
                elif ul:
                    cur = ul
                elif left:
                    cur = left
                else:
                    nprov += 1
                    parent[nprov] = nprov
                    cur = nprov
            lab[y, x] = cur
    final = np.zeros(nprov + 1, np.int64)
    n = 0
    for q in range(1, nprov + 1):
        r = _root(parent, q)
        if r == q:
            n += 1
            final[q] = n
        else:
            final[q] = final[r]
    for y in range(h):
        for x in range(w):
            if lab[y, x]:
                lab[y, x] = final[lab[y, x]]
    return n


@njit(nogil=True)
def _pixel_form(o, one):
    """:func:`tracing.overlap_holes` pixel by pixel: both labellings by a raster union-find (:func:`_label_raster`)."""
    h, w = o.shape
    olab = np.empty((h, w), np.int64)
    no = _label_raster(o, one - one, olab)
    bg = np.ones((h + 2, w + 2), np.bool_)
    for y in range(h):
        for x in range(w):
            bg[y + 1, x + 1] = not o[y, x]
    blab = np.empty((h + 2, w + 2), np.int64)
    nbl = _label_raster(bg, one, blab)
    ext = blab[0, 0]
    # the overlaps that touch the outside (a pixel of it among their pixels' 8-neighbours)
    seen = np.zeros(no + 1, np.bool_)
    n_seen = 0
    for y in range(h):
        for x in range(w):
            if not o[y, x] or seen[olab[y, x]]:
                continue
            near = False
            for dy in range(3):
                for dx in range(3):
                    if blab[y + dy, x + dx] == ext:
                        near = True
            if near:
                seen[olab[y, x]] = True
                n_seen += 1
    return no, blab, nbl, n_seen


def _same(a, b):
    return (int(a[0]), int(a[2]), int(a[3])) == (int(b[0]), int(b[2]), int(b[3])) and \
        a[1].dtype == b[1].dtype == np.int64 and a[1].shape == b[1].shape and np.array_equal(a[1], b[1])


def _check(o):
    o = np.ascontiguousarray(o, dtype=bool)
    got = tracing.overlap_holes(o)
    assert _same(got, _pixel_form(o, np.int64(1)))
    return got


def test_random_overlaps_equal_the_pixel_form():
    rng = np.random.default_rng(41)
    inside, holes = set(), set()
    for _ in range(1500):
        h, w = (int(v) for v in rng.integers(1, 34, 2))
        n, _, nb, n_out = _check(rng.random((h, w)) < rng.uniform(0.03, 0.97))
        inside.add(n_out < n)
        holes.add(nb > 1)
    assert inside == holes == {True, False}


def test_lines_rings_and_diagonals_equal_the_pixel_form():
    yy, xx = np.mgrid[:23, :29]
    r = np.maximum(abs(yy - 11), abs(xx - 14))
    masks = [r % 4 < 2, r % 3 == 0, (yy + xx) % 2 == 0, (yy - xx) % 3 == 0, np.ones((5, 7), bool),
             np.zeros((4, 3), bool), np.ones((1, 1), bool), np.zeros((1, 1), bool), xx == 7, yy == 3]
    for m in masks:
        _check(m)
        _check(m.T)


def test_the_meshers_overlaps_equal_the_pixel_form(shared_data, monkeypatch):
    """Every overlap the general mesher tests while meshing parts of the shared volumes (those its
    bridge plans read from runs made as masks), and the labels read off its runs at every pixel."""
    import contourmesh
    from contourmesh import volumes
    from contourmesh.io import read_volume

    seen = []
    real = tracing.overlap_hole_labels

    def spy(o, ys, xs):  # (the band joins' overlaps with holes, read at the holes' pixels)
        seen.append(np.array(o, dtype=bool))
        return real(o, ys, xs)

    real_plan = volumes._bridge_plan

    def spy_plan(A, B, ga, gb):  # (the plans read the overlap from runs: its mask made here)
        sl = [A.objects[a] for a in ga] + [B.objects[b] for b in gb]
        box = np.s_[min(s[0].start for s in sl):max(s[0].stop for s in sl),
                    min(s[1].start for s in sl):max(s[1].stop for s in sl)]
        seen.append(tracing.label_mask(A.labels[box], A.n, ga) & tracing.label_mask(B.labels[box], B.n, gb))
        return real_plan(A, B, ga, gb)

    monkeypatch.setattr(volumes, "overlap_hole_labels", spy)
    monkeypatch.setattr(volumes, "_bridge_plan", spy_plan)
    lobster, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz")
    liver = np.asarray(z["volume"] if "volume" in z.files else z["mask"]) > 0
    for vol in (lobster[15:40], liver[200:230]):
        contourmesh.mesh(vol)
    assert len(seen) > 20
    for o in seen:
        n, blab, nb, n_out = _check(o)
        ys, xs = np.nonzero(np.ones(blab.shape, bool))
        got = tracing.overlap_hole_labels(o, ys, xs)  # (and read at every pixel: the painted labels)
        assert (int(got[0]), int(got[2]), int(got[3]), int(got[4])) == (int(n), int(nb), int(n_out), int(blab[0, 0]))
        assert np.array_equal(got[1], blab[ys, xs])
