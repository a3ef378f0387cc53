"""The exact area sums rotate each face to start at its lexicographically smallest corner
(``contourmesh.measure._lex_first``, now without branches): the same rotation as the branching form
kept here, on ties, signed zeros, infinities and NaNs."""

import math

import numpy as np

from contourmesh.measure import _lex_first, _lex_less, _size_totals, face_terms


def _lex_less_ref(v, i, j):
    for t in range(3):
        if v[i, t] != v[j, t]:
            return bool(v[i, t] < v[j, t])
    return False


def _lex_first_ref(v, p, q, r):
    if _lex_less_ref(v, q, p) and not _lex_less_ref(v, r, q):
        return q, r, p
    if _lex_less_ref(v, r, p) and _lex_less_ref(v, r, q):
        return r, p, q
    return p, q, r


def test_rotation_equals_the_branching_form():
    rng = np.random.default_rng(4)
    special = np.array([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 0.5])
    for trial in range(4):
        n = 40
        if trial < 2:  # few distinct values: ties in the first and second coordinates
            v = rng.integers(0, 3, (n, 3)).astype(float)
        else:
            v = special[rng.integers(0, len(special), (n, 3))]
        for p in range(n):
            for q in range(0, n, 3):
                r = (p * 7 + q * 3 + trial) % n
                assert bool(_lex_less(v, p, q)) == _lex_less_ref(v, p, q)
                assert tuple(int(x) for x in _lex_first(v, p, q, r)) == _lex_first_ref(v, p, q, r), (trial, p, q, r)


def test_size_sums_equal_fsum_of_face_terms():
    rng = np.random.default_rng(8)
    v = rng.integers(0, 5, (60, 3)).astype(float) / 4
    f = rng.integers(0, 60, (300, 3))
    size, wall, _ = face_terms(v, f)
    assert _size_totals(v, f) == (math.fsum(size), math.fsum(size[wall]))
