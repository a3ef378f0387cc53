"""Issue 16: kernels of the manifold repair whose helpers were written out into their loops (or
made to count no references), against their former forms kept here, bit for bit, on random
meshes and on the lobster's builds (skipped without the shared data).

Numba counted the arrays of an inlined helper in and out on every call where the calling kernel
allocates, and an array swapped for a grown copy inside a loop is counted on every pass; the
former forms below are those, compiled here as they were."""

import numpy as np
import pytest
from numba import njit

import contourmesh
from contourmesh import repair


@njit(nogil=True, inline="always")
def _star_append_reference(j, t, ent_face, ent_next, head, tail, nent):
    """The former helper of :func:`_neck_cycles_reference` (face ``t`` appended to neck ``j``'s star)."""
    if nent == ent_face.shape[0]:
        ent_face = repair._grown1(ent_face)
        ent_next = repair._grown1(ent_next)
    ent_face[nent] = t
    ent_next[nent] = -1
    if tail[j] >= 0:
        ent_next[tail[j]] = nent
    else:
        head[j] = nent
    tail[j] = nent
    return ent_face, ent_next, nent + 1


@njit(nogil=True)
def _neck_cycles_reference(Fo, necks, n_v):
    """``repair._neck_cycles`` before (e41b861): the stars appended by the inlined helper, the
    arrays grown where they fill, inside the loops."""
    _grown1 = repair._grown1
    k = necks.shape[0]
    n_old = Fo.shape[0]
    pos = np.full(n_v, -1, np.int64)
    for j in range(k):
        pos[necks[j]] = j
    cap = max(16, 2 * n_old)
    faces = np.empty(3 * cap, np.int64)
    alive = np.ones(cap, np.bool_)
    ent_face = np.empty(cap, np.int64)
    ent_next = np.empty(cap, np.int64)
    head = np.full(k, -1, np.int64)
    tail = np.full(k, -1, np.int64)
    nent = 0
    nf = 0
    cyc = np.empty(max(16, n_old), np.int64)
    cyc_at = np.zeros(2 * k + 1, np.int64)
    ncyc = 0
    for t in range(n_old):
        for d in range(3):
            faces[3 * t + d] = Fo[t, d]
    nf = n_old
    for t in range(n_old):
        for d in range(3):
            v = Fo[t, d]
            j = pos[v]
            if j >= 0:
                ent_face, ent_next, nent = _star_append_reference(j, t, ent_face, ent_next, head, tail, nent)
    lx = np.empty(16, np.int64)
    ly = np.empty(16, np.int64)
    for j in range(k):
        c = necks[j]
        nl = 0
        e = head[j]
        while e >= 0:
            t = ent_face[e]
            e = ent_next[e]
            if not alive[t]:
                continue
            i = 0 if faces[3 * t] == c else 1 if faces[3 * t + 1] == c else 2
            x = faces[3 * t + (i + 1) % 3]
            y = faces[3 * t + (i + 2) % 3]
            for q in range(nl):
                if lx[q] == x:
                    return np.int64(1), cyc, cyc_at, alive[:n_old].copy(), faces[3 * n_old:3 * nf].reshape(-1, 3).copy(), alive[n_old:nf].copy()
            if nl == lx.shape[0]:
                lx = _grown1(lx)
                ly = _grown1(ly)
            lx[nl] = x
            ly[nl] = y
            nl += 1
        seen = np.zeros(nl, np.bool_)
        ncycles = 0
        for q0 in range(nl):
            if seen[q0]:
                continue
            ncycles += 1
            if ncycles > 2:
                return np.int64(2), cyc, cyc_at, alive[:n_old].copy(), faces[3 * n_old:3 * nf].reshape(-1, 3).copy(), alive[n_old:nf].copy()
            x0 = lx[q0]
            q = q0
            steps = 0
            while True:
                seen[q] = True
                if ncyc == cyc.shape[0]:
                    cyc = _grown1(cyc)
                cyc[ncyc] = lx[q]
                ncyc += 1
                x = ly[q]
                if x == x0:
                    break
                q = -1
                for q2 in range(nl):
                    if lx[q2] == x:
                        q = q2
                        break
                steps += 1
                if q < 0 or steps > nl:
                    return np.int64(3), cyc, cyc_at, alive[:n_old].copy(), faces[3 * n_old:3 * nf].reshape(-1, 3).copy(), alive[n_old:nf].copy()
            cyc_at[2 * j + ncycles] = ncyc
        if ncycles != 2:
            return np.int64(2), cyc, cyc_at, alive[:n_old].copy(), faces[3 * n_old:3 * nf].reshape(-1, 3).copy(), alive[n_old:nf].copy()
        e = head[j]
        while e >= 0:
            alive[ent_face[e]] = False
            e = ent_next[e]
        for h in range(2):
            c0, c1 = cyc_at[2 * j + h], cyc_at[2 * j + h + 1]
            m = c1 - c0
            for t in range(m):
                p, p1 = c0 + t, c0 + (t + 1) % m
                for w in range(2):
                    if nf == alive.shape[0]:
                        faces = _grown1(faces)
                        alive = _grown1(alive)
                    if w == 0:
                        faces[3 * nf], faces[3 * nf + 1], faces[3 * nf + 2] = n_v + p, cyc[p], cyc[p1]
                    else:
                        faces[3 * nf], faces[3 * nf + 1], faces[3 * nf + 2] = n_v + p, cyc[p1], n_v + p1
                    alive[nf] = True
                    for d in range(3):
                        v = faces[3 * nf + d]
                        if v < n_v and pos[v] > j:
                            ent_face, ent_next, nent = _star_append_reference(pos[v], nf, ent_face, ent_next, head, tail, nent)
                    nf += 1
    return np.int64(0), cyc[:ncyc].copy(), cyc_at, alive[:n_old].copy(), faces[3 * n_old:3 * nf].reshape(-1, 3).copy(), alive[n_old:nf].copy()


def _same_cycles(Fo, necks, n_v):
    """Both forms on one input: the same status, and where it is 0 the same arrays (an error's
    ``cyc`` is the work array, left unread by the caller: its other arrays are compared)."""
    want = _neck_cycles_reference(Fo, necks, n_v)
    got = repair._neck_cycles(Fo, necks, n_v)
    assert got[0] == want[0]
    for k, (a, b) in enumerate(zip(got[1:], want[1:])):
        if k == 0 and want[0] != 0:
            continue
        assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)
    return int(want[0])


def _cones(rng, n_necks, sides, chained):
    """Faces of ``n_necks`` double cones (two fans of ``sides[j]`` faces round one apex each), in a
    random order; with ``chained`` a later neck's ring goes through an earlier neck's apex, so that
    an earlier neck's fan faces join its star."""
    F = []
    nv = 0
    apexes = []
    for j in range(n_necks):
        c = nv
        nv += 1
        apexes.append(c)
        for _ in range(2):
            m = int(sides[j])
            ring = list(range(nv, nv + m))
            nv += m
            if chained and j > 0 and rng.random() < 0.7:
                ring[0] = apexes[int(rng.integers(j))]
            for t in range(m):
                F.append((c, ring[t], ring[(t + 1) % m]))
    F = np.array(F, dtype=np.int64)
    return F[rng.permutation(len(F))], np.array(apexes, dtype=np.int64), nv


def test_neck_cycles_equal_their_former_form_on_cones():
    """``_neck_cycles`` (stars appended in the loop, arrays grown before each neck's loops) against
    its former form: double cones of 3 to 40 sides (links longer than the first work arrays,
    star lists and fan faces past their first capacity), chained necks, and broken stars (a face
    dropped, a face repeated, a third cone) for the error statuses."""
    rng = np.random.default_rng(198)
    statuses = set()
    for trial in range(600):
        n_necks = int(rng.integers(1, 12))
        sides = rng.integers(3, 41 if trial % 3 == 0 else 9, n_necks)
        F, necks, nv = _cones(rng, n_necks, sides, chained=trial % 2 == 1)
        kind = trial % 5
        if kind == 1 and len(F) > 4:  # (a link not closed)
            F = np.delete(F, int(rng.integers(len(F))), axis=0)
        elif kind == 2:  # (a half-edge twice: a link entry repeated)
            F = np.concatenate([F, F[int(rng.integers(len(F)))][None]])
        elif kind == 3:  # (a third cone at one apex)
            c = int(necks[int(rng.integers(n_necks))])
            F = np.concatenate([F, np.array([[c, nv, nv + 1], [c, nv + 1, nv + 2], [c, nv + 2, nv]])])
            nv += 3
        statuses.add(_same_cycles(np.ascontiguousarray(F), necks, np.int64(nv + int(rng.integers(0, 3)))))
    assert statuses == {0, 1, 2, 3}


@pytest.fixture(scope="module")
def lobster_inputs(shared_data):
    """The inputs of ``_neck_steps`` and ``_split_faces`` in the lobster's build (threshold 60,
    padded, as the benchmarks mesh it)."""
    from contourmesh.io import read_volume

    vol, sp, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    seen = {"_neck_steps": [], "_split_faces": []}

    def keeper(name):
        real = getattr(repair, name)

        def keep(*a):
            seen[name].append(tuple(x.copy() if isinstance(x, np.ndarray) else x for x in a))
            return real(*a)

        return keep

    with pytest.MonkeyPatch.context() as mp:
        for name in seen:
            mp.setattr(repair, name, keeper(name))
        contourmesh.mesh(np.pad(vol, 1), spacing=tuple(sp))
    return seen


def test_neck_cycles_equal_their_former_form_on_the_lobster(lobster_inputs):
    """The same on the necks of the lobster's build (the faces at its necks, as ``_neck_steps``
    hands them over)."""
    assert lobster_inputs["_neck_steps"]
    for F, necks, n_v in lobster_inputs["_neck_steps"]:
        mark = np.zeros(n_v, np.bool_)
        mark[necks] = True
        Fo = np.ascontiguousarray(F[repair._rows_touching(F, mark)])
        assert len(necks) > 100 and _same_cycles(Fo, necks, n_v) == 0


def test_split_faces_equal_the_python_loop_on_the_lobster(lobster_inputs):
    """``_split_faces`` (its set additions and edge look-ups plain calls that count no
    references) against the Python loop it stands for, on the lobster's four-face edges."""
    assert lobster_inputs["_split_faces"]
    for Fw, sw, work, hit, m, nv, base in lobster_inputs["_split_faces"]:
        done, added, sides, made = repair._split_faces(Fw, sw, work, hit, m, nv, base)
        want = repair._split_faces_py(Fw, sw, work, hit, int(m), int(nv), int(base))
        assert done and len(made) > 100
        for a, b in zip((added, sides, made), want):
            assert a.dtype == b.dtype and np.array_equal(a, b)
