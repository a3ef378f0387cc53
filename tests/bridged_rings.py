"""Test helpers shared by the bridged-band tests: random rings and the bands a bridged join
makes between them."""

import numpy as np


def circle(rs, n, cx, r0, z):
    """``n`` points of a noisy circle of radius about ``r0`` round ``(cx, 0)`` at height ``z``, in
    counter-clockwise order."""
    t = np.sort(rs.uniform(0, 2 * np.pi, n))
    r = r0 * (1 + 0.1 * rs.standard_normal(n))
    return np.c_[cx + r * np.cos(t), r * np.sin(t), np.full(n, z)]


def bridged_band(rs, A, B, up):
    """A band as a bridged join has it: below, the rings ``A`` and ``B`` bridged into one (A's
    rightmost point to B's leftmost; the bridge's ends visited twice, each one vertex), or ``A``
    alone (three times in ten); above, the ring ``up``.  ``(P, na, ids)``: the band's points (the
    lower ring's ``na`` first) and their vertex ids."""
    n1, n2 = len(A), len(B)
    V = np.concatenate([A, B, up])
    if rs.random() < 0.7:
        a, b = int(np.argmax(A[:, 0])), int(np.argmin(B[:, 0]))
        tour = np.r_[np.arange(a + 1), n1 + (b + np.arange(n2 + 1)) % n2, a + np.arange(n1 - a) % n1]
    else:
        tour = np.arange(n1)
    top = n1 + n2 + np.arange(len(up))
    ids = np.r_[tour, top].astype(np.int64)
    return V[ids], len(tour), ids
