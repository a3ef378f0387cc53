"""The MLP's string pulling (polygons.mlp._mlp_pull) against its earlier form, bit for bit.

The kernel keeps VL's coordinates and the crawlers' offsets from VL in variables where it once read
them from ``cand`` for every candidate; the reference below is that earlier form, and both must
give the same candidates and polygons on outer contours and holes of random masks, on stacks
(the fast path's candidates) and on the slices of a ball.

The kernel also drops a last W that repeats the first by moving the candidates before the first W
up one place (and returning the list from one place later), where the reference moves the ones after
it down one place: the candidates returned must be the same, which the tests below check on lists
where the first W comes after zero, one or several other candidates.
"""

import numpy as np

from contourmesh._kernels import njit
from contourmesh.fastpath import _stack_candidates, _trace_runs, slice_runs
from contourmesh.polygons.mlp import _mlp_pull, mlp_candidates
from contourmesh.tracing import trace_contours


@njit(cache=False)
def _pull_reference(pts, cand, kind, m, colour):
    """polygons.mlp._mlp_pull before its loop kept VL's coordinates and the crawlers' offsets in
    variables: it read them from ``cand`` for every candidate."""
    # the last W may repeat the first W (cyclically consecutive): drop the later copy, the first
    # one, as above - the B/C candidates between the two copies (a convex corner is listed after
    # its diagonal W) must stay after the kept one, or a C is tested before its W is reached
    first = 0
    while first < m and kind[first] != 1:
        first += 1
    last = m - 1
    while last >= 0 and kind[last] != 1:
        last -= 1
    if last > first and cand[last, 0] == cand[first, 0] and cand[last, 1] == cand[first, 1]:
        for i in range(first, m - 1):
            cand[i, 0] = cand[i + 1, 0]
            cand[i, 1] = cand[i + 1, 1]
            kind[i] = kind[i + 1]
        m -= 1
    cand = cand[:m]
    kind = kind[:m]
    empty = np.empty((0, 2), np.int64)
    if colour == 0:
        return cand, kind, empty
    nnz = 0
    last = -1
    for i in range(m):
        if kind[i] != 0:
            nnz += 1
            last = i
    if nnz == 1:
        # a single point of I (or a single concave corner): the MLP is that point
        poly = np.empty((1, 2), np.int64)
        poly[0, 0] = cand[last, 0]
        poly[0, 1] = cand[last, 1]
        p = 1
    else:
        # ---- step 2: string pulling from a candidate that is certainly an MLP vertex, the
        # lowest-then-leftmost W (outer contour) or B (hole)
        s = -1
        for i in range(m):
            if kind[i] == colour:
                if s < 0 or cand[i, 1] < cand[s, 1] or (cand[i, 1] == cand[s, 1] and cand[i, 0] < cand[s, 0]):
                    s = i
        if s < 0:
            return cand, kind, empty
        # Candidates are visited in the unrolled order s, s+1, ..., s+m (the last one is s
        # again); vl, wc, bc are positions in that order.  W candidates lie on the left of the
        # path, B and C candidates on its right; C candidates are never vertices.
        out = np.empty(m + 1, np.int64)
        nv = 0
        out[nv] = s
        nv += 1
        vl = s
        wc = s
        bc = s
        k = s + 1
        # (positions lie in [s, s + m] with s < m: position p is candidate p or p - m, taken
        # with a comparison rather than an integer division)
        while k <= s + m:
            il = vl if vl < m else vl - m
            ik = k if k < m else k - m
            iw = wc if wc < m else wc - m
            ib = bc if bc < m else bc - m
            lx, ly = cand[il, 0], cand[il, 1]
            vx, vy = cand[ik, 0] - lx, cand[ik, 1] - ly
            wx, wy = cand[iw, 0] - lx, cand[iw, 1] - ly
            bx, by = cand[ib, 0] - lx, cand[ib, 1] - ly
            new_vertex = -1
            w_set = wx != 0 or wy != 0
            b_set = bx != 0 or by != 0
            kk = kind[ik]
            is_w = kk > 0
            if kk == 0:
                # a convex corner of the contour (the outer wall) must stay on the right of the path:
                # if it lies left of WC the path cannot go on straight and turns left at WC
                if w_set and wx * vy - wy * vx > 0:
                    new_vertex = wc
            elif vx == 0 and vy == 0:
                # back at VL's position: the path turned round at the pending crawler
                if is_w:
                    new_vertex = wc if w_set else (bc if b_set else -1)
                else:
                    new_vertex = bc if b_set else (wc if w_set else -1)
            elif is_w:
                # a W candidate must stay on the left: the free directions are clockwise of it
                if b_set and bx * vy - by * vx < 0:
                    new_vertex = bc  # right of BC: the cone is empty, the path turns right at BC
                elif w_set:
                    cw = wx * vy - wy * vx
                    if cw < 0:
                        wc = k  # a tighter left bound
                    elif cw == 0:
                        if wx * vx + wy * vy < wx * wx + wy * wy:
                            new_vertex = wc  # turns back along the ray: a U-turn at WC
                        else:
                            wc = k  # straight on through WC
                    elif k == s + m:
                        new_vertex = wc  # the closing vertex lies left of WC: turn left at WC
                else:
                    wc = k
            else:
                # a B candidate must stay on the right: the free directions are counter-clockwise of it
                if w_set and wx * vy - wy * vx > 0:
                    new_vertex = wc  # left of WC: the cone is empty, the path turns left at WC
                elif b_set:
                    cb = bx * vy - by * vx
                    if cb > 0:
                        bc = k  # a tighter right bound
                    elif cb == 0:
                        if bx * vx + by * vy < bx * bx + by * by:
                            new_vertex = bc  # turns back along the ray: a U-turn at BC
                        else:
                            bc = k
                    elif k == s + m:
                        new_vertex = bc  # the closing vertex lies right of BC: turn right at BC
                else:
                    bc = k
            if new_vertex >= 0:
                out[nv] = new_vertex if new_vertex < m else new_vertex - m
                nv += 1
                vl = new_vertex
                wc = vl
                bc = vl
                k = vl + 1
                continue
            k += 1
        # the path's vertices, without cyclically consecutive duplicates and vertices where it
        # goes straight on (one at a time, rescanning from the start after each removal)
        poly = np.empty((nv, 2), np.int64)
        for i in range(nv):
            poly[i, 0] = cand[out[i], 0]
            poly[i, 1] = cand[out[i], 1]
        p = nv
        changed = True
        while changed and p > 1:
            changed = False
            drop = -1
            for i in range(p):
                a = i - 1 if i > 0 else p - 1
                c = i + 1 if i + 1 < p else 0
                ax, ay = poly[a, 0], poly[a, 1]
                bx, by = poly[i, 0], poly[i, 1]
                cx, cy = poly[c, 0], poly[c, 1]
                if ax == bx and ay == by:
                    drop = i
                    break
                if p > 2:
                    ux, uy, vx, vy = bx - ax, by - ay, cx - bx, cy - by
                    if ux * vy - uy * vx == 0 and ux * vx + uy * vy > 0:
                        drop = i
                        break
            if drop >= 0:
                for i in range(drop, p - 1):
                    poly[i, 0] = poly[i + 1, 0]
                    poly[i, 1] = poly[i + 1, 1]
                p -= 1
                changed = True
    # ---- from the vertex nearest pts[0]
    best = 0
    bd = -1
    for i in range(p):
        dx = poly[i, 0] - pts[0, 0]
        dy = poly[i, 1] - pts[0, 1]
        d2 = dx * dx + dy * dy
        if bd < 0 or d2 < bd:
            bd = d2
            best = i
    out2 = np.empty((p, 2), np.int64)
    for i in range(p):
        k = i + best if i + best < p else i + best - p
        out2[i, 0] = poly[k, 0]
        out2[i, 1] = poly[k, 1]
    return cand, kind, out2


@njit(cache=False)
def _both(pts, cand, kind, colour):
    m = np.int64(len(kind))
    c1, k1, p1 = _mlp_pull(pts, cand.copy(), kind.copy(), m, colour)
    c2, k2, p2 = _pull_reference(pts, cand.copy(), kind.copy(), m, colour)
    return c1, k1, p1, c2, k2, p2


def _same(pts, cand, kind, colour):
    c1, k1, p1, c2, k2, p2 = _both(np.ascontiguousarray(pts, np.int64), np.ascontiguousarray(cand, np.int64),
                                   np.ascontiguousarray(kind, np.int64), np.int64(colour))
    assert np.array_equal(c1, c2) and np.array_equal(k1, k2)
    assert p1.shape == p2.shape and np.array_equal(p1, p2)
    return len(p1)


def _random_masks(rng, count):
    for trial in range(count):
        h, w = int(rng.integers(1, 30)), int(rng.integers(1, 30))
        density = rng.uniform(0.2, 0.9)
        m = rng.random((h, w)) < density
        if trial % 3 == 0:  # blobs: a coarse random image scaled up
            small = rng.random((h // 3 + 1, w // 3 + 1)) < density
            m = np.kron(small, np.ones((3, 3), bool))[:h, :w] & (rng.random((h, w)) < 0.95)
        yield m


def test_pull_equals_the_reference_on_contours_and_holes():
    rng = np.random.default_rng(128)
    outer = holes = vertices = 0
    for m in _random_masks(rng, 600):
        if not m.any():
            continue
        contours, parents = trace_contours(m)
        for c, parent in zip(contours, parents):
            cand, kind = mlp_candidates(c)
            if len(kind) == 0:
                continue
            colour = 1 if parent < 0 else -1
            vertices += _same(c, cand, kind, colour)
            _same(c, cand, kind, -colour)  # the other colour too: other starts, other paths
            _same(c, cand, kind, 0)
            outer += parent < 0
            holes += parent >= 0
    assert outer > 500 and holes > 200 and vertices > 5000, (outer, holes, vertices)


def _ball_slices(n, r):
    c = (n - 1) / 2
    yy, xx = np.ogrid[:n, :n]
    d2 = (xx - c) ** 2 + (yy - c) ** 2
    for k in range(n):
        rr = r * r - (k - c) ** 2
        if rr >= 0:
            yield d2 <= rr


@njit(cache=False)
def _stack(ry, rx0, rx1):
    """The contour and candidates the fast path makes for a stack (empty if not a stack)."""
    # (runs in int32, as the fast path packs them: int64 runs would compile the fast path's
    # kernels a second time in this process, which tests/test_fastpath.py's one-signature check
    # then finds, whichever file runs first)
    ry, rx0, rx1 = ry.astype(np.int32), rx0.astype(np.int32), rx1.astype(np.int32)
    order = np.arange(len(ry))
    t0, t1 = np.int64(0), np.int64(len(ry))
    cc = _trace_runs(ry, rx0, rx1, order, t0, t1)
    _, cand, kind, mc = _stack_candidates(ry, rx0, rx1, order, t0, t1)
    if len(cc) == 0:
        return cc, np.empty((0, 2), np.int64), np.empty(0, np.int64)
    return cc, cand[:mc], kind[:mc]


def test_pull_equals_the_reference_on_stacks():
    # the fast path's stacks (one run per row): its candidates from the intervals, then both pulls
    rng = np.random.default_rng(1280)
    masks = list(_ball_slices(97, 45.3)) + list(_ball_slices(40, 17.0))
    for _ in range(300):
        h, w = int(rng.integers(1, 20)), int(rng.integers(1, 40))
        m = np.zeros((h, w), bool)
        x = int(rng.integers(0, w))
        for y in range(int(rng.integers(0, h)), h):
            a = int(np.clip(x + rng.integers(-4, 5), 0, w - 1))
            b = int(rng.integers(a + 1, min(w, a + int(rng.integers(1, 12))) + 1))
            m[y, a:b] = True
            x = a if rng.random() < 0.5 else b - 1
        masks.append(m)
    done = 0
    for m in masks:
        ry, rx0, rx1, _ = slice_runs(m)
        if len(ry) == 0:
            continue
        cc, cand, kind = _stack(ry, rx0, rx1)
        if len(cc) == 0:
            continue
        _same(cc, cand, kind, 1)
        done += 1
    assert done > 200, done


def test_pull_equals_the_reference_where_the_first_w_is_dropped():
    # the candidates of random contours and of the ball's slices started at other places of the
    # contour (rotated lists) with the first W repeated at the end (as the candidates of a contour
    # whose walk starts before that W are made), the first W after t = 0, 1 or more B/C
    # candidates: the dropped W and the moved candidates must give the same lists and polygons
    rng = np.random.default_rng(1390)
    lists = []
    for m in _random_masks(rng, 300):
        if not m.any():
            continue
        contours, parents = trace_contours(m)
        for c, parent in zip(contours, parents):
            cand, kind = mlp_candidates(c)
            if (kind == 1).sum() > 1:
                lists.append((c, cand, kind, 1 if parent < 0 else -1))
    for m in list(_ball_slices(61, 28.7))[::3]:
        ry, rx0, rx1, _ = slice_runs(m)
        cc, cand, kind = _stack(ry, rx0, rx1)
        if len(cc):
            lists.append((cc, cand[:-1], kind[:-1], 1))  # (the repeated W at the end left off)
    made = {}
    for c, cand, kind, colour in lists:
        n = len(kind)
        w = np.flatnonzero(kind == 1)
        for j in rng.choice(w, size=min(3, len(w)), replace=False):
            gap = 0  # the B/C candidates just before W j (cyclically)
            while kind[(j - gap - 1) % n] != 1:
                gap += 1
            t = int(rng.integers(0, gap + 1))
            rc, rk = np.roll(cand, t - j, axis=0), np.roll(kind, t - j)
            assert rk[t] == 1 and not (rk[:t] == 1).any()
            rc, rk = np.vstack([rc, rc[t:t + 1]]), np.append(rk, 1)
            made[min(t, 2)] = made.get(min(t, 2), 0) + 1
            for col in (colour, -colour, 0):
                _same(c, rc, rk, col)
    assert min(made.get(key, 0) for key in (0, 1, 2)) > 20, made


def test_pull_leaves_the_candidates_it_returns_equal_to_the_reference_on_the_stacks_of_a_ball():
    # every slice of a ball repeats its first W at the end (the case the kernel now handles by
    # moving the candidates before it): candidates and polygons as the reference gives them
    done = 0
    for m in _ball_slices(81, 38.2):
        ry, rx0, rx1, _ = slice_runs(m)
        cc, cand, kind = _stack(ry, rx0, rx1)
        if len(cc) == 0:
            continue
        w = np.flatnonzero(kind == 1)
        done += len(w) > 1 and bool((cand[w[-1]] == cand[w[0]]).all())
        for col in (1, -1, 0):
            _same(cc, cand, kind, col)
    assert done > 50, done
