"""Issue 16 (speed of the crossing test on real segmentations): the pairs decided without the general
test, by a vertex's star that projects one-to-one along a direction (``_star_certified``) or in the
plane where two faces' boxes only touch (``_touching_boxes``), must be exactly the pairs of the
general test (``_pairs(..., quick=False)``) by either broad phase: on our meshes, with heights nudged
off the planes as the repair does, off the dyadic grid, with crossings put in, on random sectioned
meshes and folded spheres; and the shortcuts must actually decide most pairs of our meshes."""

import numpy as np
import pytest
import trimesh
from numba import njit
from scipy import ndimage

import contourmesh
from contourmesh import intersect
from contourmesh.intersect import _as_mesh_arrays, _pairs, _star_certified, canonical_vertices, intersecting_pairs
from test_intersect import reference_pairs
from test_intersect_slabs import _random_sectioned, _sectioned


@pytest.fixture(autouse=True)
def stars_at_once(monkeypatch):
    """The stars certified at the first pair that reaches the tests (not after a mesh's worth of
    them, see ``_STAR_DELAY``), so that the small meshes here use them."""
    monkeypatch.setattr(intersect, "_STAR_DELAY", -10 ** 9)


def _both(V, F, methods=("grid", "slabs", "auto")):
    """The pairs with and without the shortcuts, by each broad phase that applies: equal."""
    Va, Fa = _as_mesh_arrays(V, F)
    canon = canonical_vertices(Va)
    out = None
    for method in methods:
        if method == "slabs" and not _sectioned(Va, Fa):
            continue
        quick = _pairs(Va, Fa, canon, 8, method)
        full = _pairs(Va, Fa, canon, 8, method, quick=False)
        assert np.array_equal(quick, full), (method, len(quick), len(full))
        if out is not None:
            assert np.array_equal(out, quick)
        out = quick
    return out


def _certified(V, F):
    Va, Fa = _as_mesh_arrays(V, F)
    canon = canonical_vertices(Va)
    return _star_certified(Va, canon[Fa])


def _volume(rng, t):
    if t % 3 == 0:
        v = ndimage.gaussian_filter(rng.random((9, 11, 12)), 1.2) > 0.5
    elif t % 3 == 1:
        v = rng.random((6, 7, 8)) < 0.3
    else:
        v = np.zeros((8, 9, 9), bool)
        for _ in range(3):
            z, y, x = rng.integers(0, 6, 3)
            v[z:z + rng.integers(1, 4), y:y + rng.integers(1, 5), x:x + rng.integers(1, 5)] = True
    return np.pad(v, 1)


def _nudged(rng, V, share=0.2, size=1e-3):
    """Some vertices moved slightly off their planes (and a few within them), as the repair moves
    them: off the dyadic grid, near every plane test."""
    W = V.copy()
    pick = rng.random(len(W)) < share
    W[pick, 2] += rng.choice([-1.0, 1.0], pick.sum()) * rng.uniform(1e-12, size, pick.sum())
    pick = rng.random(len(W)) < share / 4
    W[pick, :2] += rng.uniform(-size, size, (pick.sum(), 2))
    return W


@pytest.mark.parametrize("delay", [None, 100])
def test_our_meshes_same_pairs_with_and_without_the_shortcuts(delay, monkeypatch):
    if delay is not None:  # the stars only after some pairs were tested (the default's way)
        monkeypatch.setattr(intersect, "_STAR_DELAY", delay)
    rng = np.random.default_rng(3)
    certified = used = crossing = 0
    for t in range(15):
        v = _volume(rng, t)
        if not v.any():
            continue
        for kw in ({}, {"polygon": "none"}):
            m = contourmesh.mesh(v, **kw)
            V, F = m.vertices.copy(), m.faces.copy()
            assert len(_both(V, F)) == 0
            c = _certified(V, F)
            certified += int(c.sum())
            used += len(np.unique(F))
            # nudged heights (the lobster's case), off the dyadic grid, and crossings put in
            W = _nudged(rng, V)
            _both(W, F)
            _both(V * 0.3 + 0.17, F)
            for _ in range(2):
                X = W.copy()
                X[rng.integers(len(X))] += rng.uniform(-2, 2, 3)
                crossing += len(_both(X, F)) > 0
    # the shortcuts are not vacuous: most vertices of our meshes are certified, and crossings occur
    assert certified > 0.6 * used, (certified, used)
    assert crossing >= 10


@pytest.mark.parametrize("flat_share", [0.0, 0.3])
def test_random_sectioned_meshes_same_pairs(flat_share):
    rng = np.random.default_rng(17)
    hits = 0
    for _ in range(40):
        V, F = _random_sectioned(rng, int(rng.integers(2, 6)), 30, 40, flat_share)
        hits += len(_both(V, F)) > 0
        _both(_nudged(rng, V, 0.3, 0.2), F)
    assert hits >= 20


def test_folded_spheres_and_grids_match_the_exact_reference():
    # closed fans that fold (jittered spheres) and meshes on a coarse grid (touching boxes
    # everywhere): the shortcuts' answers against the rational reference
    rng = np.random.default_rng(23)
    for it in range(6):
        s = trimesh.creation.icosphere(1)
        V = s.vertices + rng.normal(0, 0.2 if it % 2 else 0.05, s.vertices.shape)
        got = _both(V, s.faces)
        assert set(map(tuple, got.tolist())) == reference_pairs(V, s.faces)
        G = np.round(s.vertices * 2) / 2  # snapped: coplanar, collinear and touching cases
        got = _both(G, s.faces)
        assert set(map(tuple, got.tolist())) == reference_pairs(G, s.faces)


def _fan(link, apex=(0.0, 0.0, 0.0)):
    """Faces (p, a_i, a_i+1) around the vertex p = 0 over the closed link polygon ``link``."""
    V = np.vstack([apex, link]).astype(float)
    n = len(link)
    F = np.array([[0, 1 + i, 1 + (i + 1) % n] for i in range(n)])
    return V, F


def test_star_certificate_on_hand_made_fans():
    ring = [[1, 0, 0], [1, 1, 0], [0, 1, 0], [-1, 1, 0], [-1, 0, 0], [-1, -1, 0], [0, -1, 0], [1, -1, 0]]
    V, F = _fan(ring)  # a flat grid vertex: sides along one line in opposite directions
    assert _certified(V, F)[0] == 1
    V, F = _fan(ring[::-1])  # the other orientation
    assert _certified(V, F)[0] == 1
    V, F = _fan(ring, apex=(0, 0, 1e-9))  # nudged off the plane: a cone, still one-to-one
    assert _certified(V, F)[0] == 1
    # a cube corner (three faces at right angles: no coordinate plane sees them one-to-one)
    corner = [[1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1], [1, 0, 1]]
    V, F = _fan(corner)
    assert _certified(V, F)[0] == 1
    # a link that winds twice around p (a pentagram): every sector turns the same way, but the
    # faces overlap; not certified, and the pairs are found
    ang = np.deg2rad(np.arange(5) * 144.0)
    star = np.c_[np.cos(ang), np.sin(ang), np.full(5, -1.0)]
    V, F = _fan(star)
    assert _certified(V, F)[0] == 0
    got = _both(V, F, ("grid",))
    assert len(got) > 0 and set(map(tuple, got.tolist())) == reference_pairs(V, F)
    # a fold: one face turned over
    V, F = _fan(ring)
    V[2] = [-0.5, -0.2, 0.0]
    assert _certified(V, F)[0] == 0
    assert set(map(tuple, _both(V, F, ("grid",)).tolist())) == reference_pairs(V, F)
    # two fans glued at p (a non-manifold vertex): no single cycle, not certified
    V1, F1 = _fan(ring)
    V2, F2 = _fan(ring, apex=(0, 0, 0))
    V = np.vstack([V1, V2[1:] + [0, 0, 1]])
    F = np.vstack([F1, np.where(F2 == 0, 0, F2 + 8)])
    assert _certified(V, F)[0] == 0


@pytest.mark.parametrize("other, hit", [
    ([[2, 1, 0], [3, 0, 1], [3, 2, -1]], True),      # a corner on the other's edge, boxes touch at x = 2
    ([[2, 2.5, 0], [3, 0, 1], [3, 2, -1]], False),    # the corner beside it: apart
    ([[2, 0.5, -1], [2, 0.5, 1], [3, 0, 0]], True),   # an edge across the other's edge, in x = 2
    ([[2, 1.5, 0.5], [2, 2.5, 0.5], [3, 0, 0]], False),  # an edge in x = 2 beside the other's edge
    ([[2.0000000000000004, 1, 0], [3, 0, 1], [3, 2, -1]], False),  # an ulp away
])
def test_faces_whose_boxes_touch(other, hit):
    V = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0]] + other, float)
    F = np.array([[0, 1, 2], [3, 4, 5]])
    for perm in ([0, 1, 2], [2, 0, 1], [1, 2, 0]):  # the touching plane across each axis
        got = _both(V[:, perm], F, ("grid",))
        assert (len(got) == 1) is hit
        assert set(map(tuple, got.tolist())) == reference_pairs(V[:, perm], F)


def test_real_mesh_sample_pairs_unchanged():
    # the public function: the same answer as the general test on a mesh with crossings
    rng = np.random.default_rng(5)
    m = contourmesh.mesh(_volume(rng, 0))
    V = _nudged(rng, m.vertices, 0.3)
    V[rng.integers(len(V), size=3)] += 1.5
    full = _pairs(*_as_mesh_arrays(V, m.faces), canonical_vertices(V), 8, "auto", quick=False)
    assert np.array_equal(intersecting_pairs(V, m.faces), full)


# The slab sweep's two coordinate rules in their plain form (see the note before
# ``intersect._slab_hit``): the references its rows of corner ranges are checked against.
@njit(cache=False)
def _ends_apart(V, F, lev, k, i, j):
    """Faces i and j, each with its corners on the heights ``k`` and ``k + 1`` only, lie apart
    along x or y on both planes, the same face first."""
    bxi0, bxi1, byi0, byi1, txi0, txi1, tyi0, tyi1 = intersect._corner_ranges(V, F, lev, i, k)
    bxj0, bxj1, byj0, byj1, txj0, txj1, tyj0, tyj1 = intersect._corner_ranges(V, F, lev, j, k)
    return ((bxi1 < bxj0 and txi1 < txj0) or (bxj1 < bxi0 and txj1 < txi0)
            or (byi1 < byj0 and tyi1 < tyj0) or (byj1 < byi0 and tyj1 < tyi0))


@njit(cache=False)
def _apart_but_corner(V, F, lev, i, j, p):
    """Faces i and j with one common corner p lie apart beside it: along x or y, one face's
    corners on the other plane strictly before the other's, and on p's plane the first face's
    other corners strictly before p, the second's strictly after it."""
    lp = lev[p]
    for c in range(2):
        pc = V[p, c]
        i0lo = np.inf
        i0hi = -np.inf
        i1lo = np.inf
        i1hi = -np.inf
        j0lo = np.inf
        j0hi = -np.inf
        j1lo = np.inf
        j1hi = -np.inf
        for q in range(3):
            v = F[i, q]
            if v != p:
                if lev[v] == lp:
                    i0lo = min(i0lo, V[v, c])
                    i0hi = max(i0hi, V[v, c])
                else:
                    i1lo = min(i1lo, V[v, c])
                    i1hi = max(i1hi, V[v, c])
            w = F[j, q]
            if w != p:
                if lev[w] == lp:
                    j0lo = min(j0lo, V[w, c])
                    j0hi = max(j0hi, V[w, c])
                else:
                    j1lo = min(j1lo, V[w, c])
                    j1hi = max(j1hi, V[w, c])
        if i1hi < j1lo and i0hi < pc and pc < j0lo:
            return True
        if j1hi < i1lo and j0hi < pc and pc < i0lo:
            return True
    return False


def test_faces_whose_ends_are_apart_do_not_meet():
    """The rule "ends apart" (two faces of one slab whose corners are strictly apart along x or y on
    both planes, the same face first) decides only pairs that do not intersect by the exact
    rational rule, on a coarse grid (corners level with each other, touching cases) and off it;
    and it decides many of them (else the slab sweep gains nothing)."""

    @njit
    def apart(V, F, lev, i, j):  # (the signature the slab sweep compiles: no literal level)
        return _ends_apart(V, F, lev, lev[0] * 0, i, j)

    rng = np.random.default_rng(41)
    decided = 0
    for it in range(40):
        n = 16
        V = np.c_[rng.integers(0, 5, (n, 2)) * 0.5, np.repeat([0.0, 1.0], n // 2)]
        if it % 2:
            V[:, :2] += rng.normal(0, 0.1, (n, 2))
        lev = (V[:, 2] > 0).astype(np.int64)
        F = []
        while len(F) < 12:
            f = rng.choice(n, 3, replace=False)
            if len(set(lev[f])) == 2:
                F.append(f)
        F = np.array(F, dtype=np.int64)
        ref = reference_pairs(V, F)
        for i in range(len(F)):
            for j in range(i + 1, len(F)):
                got = apart(V, F, lev, np.int64(i), np.int64(j))
                if got:
                    assert (i, j) not in ref
                    decided += 1
                assert got == apart(V, F, lev, np.int64(j), np.int64(i))
    assert decided > 200  # (of 2640 pairs; random faces of one slab overlap much more than a band's)


def test_faces_with_one_common_corner_apart_meet_only_there():
    """The rule "apart but at a corner" (two faces of one slab with one common corner p, apart along x or y
    on the other plane, and on p's plane each face's other corners strictly on its own side of p)
    decides only pairs that meet only at p by the exact rational rule (a common point elsewhere,
    or along a ray from p, is a crossing), on a coarse grid and off it; and it decides many."""

    @njit
    def apart(V, F, lev, i, j, p):
        return _apart_but_corner(V, F, lev, i, j, p)

    rng = np.random.default_rng(43)
    decided = crossing = 0
    for it in range(60):
        n = 12
        V = np.c_[rng.integers(0, 5, (n, 2)) * 0.5, np.repeat([0.0, 1.0], n // 2)]
        if it % 2:
            V[:, :2] += rng.normal(0, 0.1, (n, 2))
        lev = (V[:, 2] > 0).astype(np.int64)
        for _ in range(30):
            p = int(rng.integers(n))
            rest = [v for v in range(n) if v != p]
            a, b, c, d = rng.choice(rest, 4, replace=False)
            F = np.array([[p, a, b], [p, c, d]], dtype=np.int64)
            if len(set(lev[F[0]])) != 2 or len(set(lev[F[1]])) != 2:
                continue
            hit = len(reference_pairs(V, F)) > 0
            crossing += hit
            got = apart(V, F, lev, np.int64(0), np.int64(1), np.int64(p))
            assert got == apart(V, F, lev, np.int64(1), np.int64(0), np.int64(p))
            if got:
                assert not hit
                decided += 1
    assert decided > 100 and crossing > 50


def test_apart_but_corner_on_the_sweeps_ranges_is_the_rule():
    """The slab sweep decides the rule "apart but at a corner" on its rows of corner ranges
    (``_apart_but_corner_w``): the same answer on every pair of faces with one common corner, the
    corner on either plane, on a coarse grid (coordinates level with p) and off it."""

    @njit
    def both(V, F, lev, W, p):
        return (_apart_but_corner(V, F, lev, np.int64(0), np.int64(1), p),
                intersect._apart_but_corner_w(W, np.int64(0), np.int64(1), V[p, 0], V[p, 1], lev[p] == 0))

    def rows(V, F, lev):
        W = np.empty((2, 13))
        for r, f in enumerate(F):
            bot, top = V[f[lev[f] == 0], :2], V[f[lev[f] == 1], :2]
            W[r, :4] = V[f, 0].min(), V[f, 0].max(), V[f, 1].min(), V[f, 1].max()
            W[r, 4:8] = bot[:, 0].min(), bot[:, 0].max(), bot[:, 1].min(), bot[:, 1].max()
            W[r, 8:12] = top[:, 0].min(), top[:, 0].max(), top[:, 1].min(), top[:, 1].max()
            W[r, 12] = len(bot)
        return W

    rng = np.random.default_rng(44)
    decided = tried = 0
    for it in range(60):
        n = 12
        V = np.c_[rng.integers(0, 4, (n, 2)) * 0.5, np.repeat([0.0, 1.0], n // 2)]
        if it % 2:
            V[:, :2] += rng.normal(0, 0.1, (n, 2))
        lev = (V[:, 2] > 0).astype(np.int64)
        for _ in range(40):
            p = int(rng.integers(n))
            a, b, c, d = rng.choice([v for v in range(n) if v != p], 4, replace=False)
            F = np.array([[p, a, b], [p, c, d]], dtype=np.int64)
            if len(set(lev[F[0]])) != 2 or len(set(lev[F[1]])) != 2:
                continue
            want, got = both(V, F, lev, rows(V, F, lev), np.int64(p))
            assert want == got, (V[F], p)
            decided += want
            tried += 1
    assert decided > 100 and tried > 1000
