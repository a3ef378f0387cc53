"""Bands whose volume agrees with the rules over the two rings' areas (the contours route's guard).

Between two rings drawn at heights ``z0 < z1`` (areas ``A0``, ``A1``), the solid bounded by a band
and the two rings' planes has volume ``h/6 (A0 + A1 + 4 Am)`` (Simpson's rule is exact for it:
every band triangle is ruled between the planes), where ``Am`` is the area of the band's mid
section, the polygon of its rungs' midpoints.  The rules a planning system reports lie on
either side of the ideal join: the trapezoid rule (``Am = (A0 + A1) / 2``) and the frustum rule
(``Am = ((sqrt(A0) + sqrt(A1)) / 2)^2``).  The paper's band and the least-area band pick their
rungs by local coordinates or by area; where a thin ring slides between sections (a scar, a
border strip) they cut across the ring and pinch its mid section: the volume falls well below
both rules.

:func:`faithful_band` keeps a band whose volume lies within the rules' interval (a small slack
allowed) and otherwise looks for the band that minimises ``area - mu * Am`` (a dynamic
programme over the same annular paths as the least-area band,
:mod:`contourmesh.bands.optimal`, with its exclusion of double cones), with the Lagrange
weight ``mu`` bisected until the volume enters the interval.  ``mu = 0`` is the least-area band;
a larger ``mu`` favours fuller mid sections (rungs that follow the ring rather than cut
across it).  The first band in the interval that does not cross itself is taken; if none is
found, the candidate closest to the interval that does not cross itself, if it is closer than
the original band.
"""

from __future__ import annotations

import numpy as np

from .._kernels import njit
from .optimal import N_LAYERS, _annulus_dp, _best_start, _trace_back
from .wiederhold import edges_to_faces, oriented_pair

__all__ = ["band_volume", "rule_interval", "faithful_band", "FaithfulBands"]


def band_volume(lo: np.ndarray, hi: np.ndarray, f: np.ndarray) -> float:
    """Signed volume of the solid bounded by the band ``f`` (outward faces indexing
    ``vstack([lo, hi])``) and the planes of ``lo`` and ``hi``: positive for outer rings
    (counter-clockwise), negative for holes (divergence theorem with the field ``(0, 0, z - z0)``)."""
    P = np.concatenate([lo, hi])
    z0 = float(lo[0, 2])
    t = P[f]
    a = 0.5 * ((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1])
               - (t[:, 2, 0] - t[:, 0, 0]) * (t[:, 1, 1] - t[:, 0, 1]))
    zbar = t[:, :, 2].mean(axis=1) - z0
    return float(np.sum(zbar * a) + (float(hi[0, 2]) - z0) * _shoelace(hi[:, :2]))


def _shoelace(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def rule_interval(a0: float, a1: float, h: float) -> tuple[float, float]:
    """``(lo, hi)``: the frustum and trapezoid volumes of signed areas ``a0``, ``a1`` one ``h`` apart
    (same sign: both outer rings or both holes), ordered."""
    s = 1.0 if a0 + a1 >= 0 else -1.0
    b0, b1 = abs(a0), abs(a1)
    trap = s * h * (b0 + b1) / 2
    fru = s * h / 3 * (b0 + b1 + np.sqrt(b0 * b1))
    return min(trap, fru), max(trap, fru)


@njit(cache=True)
def _costs(c1, c2, mu, sign):
    """Step costs ``area - mu * sign * (mid-section shoelace term)`` of the annular DP
    (see :func:`contourmesh.bands.optimal._step_areas` for the two step kinds)."""
    n = c1.shape[0]
    m = c2.shape[0]
    A1 = np.empty((n, m))
    A2 = np.empty((n, m))
    for i in range(n):
        i1 = (i + 1) % n
        for j in range(m):
            j1 = (j + 1) % m
            for kind in range(2):
                p = c1[i]
                if kind == 0:
                    q, r = c1[i1], c2[j]
                else:
                    q, r = c2[j1], c2[j]
                ux, uy, uz = q[0] - p[0], q[1] - p[1], q[2] - p[2]
                vx, vy, vz = r[0] - p[0], r[1] - p[1], r[2] - p[2]
                cx, cy, cz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
                area = 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)
                # the mid-section edge of this step: from rung (i, j) to the next rung
                ax, ay = 0.5 * (c1[i, 0] + c2[j, 0]), 0.5 * (c1[i, 1] + c2[j, 1])
                if kind == 0:
                    bx, by = 0.5 * (c1[i1, 0] + c2[j, 0]), 0.5 * (c1[i1, 1] + c2[j, 1])
                else:
                    bx, by = 0.5 * (c1[i, 0] + c2[j1, 0]), 0.5 * (c1[i, 1] + c2[j1, 1])
                mid = 0.5 * (ax * by - bx * ay)
                if kind == 0:
                    A1[i, j] = area - mu * sign * mid
                else:
                    A2[i, j] = area - mu * sign * mid
    return A1, A2


@njit(cache=True)
def _best_edges(A1, A2, starts):
    """The cheapest annular path over the start points ``starts`` of ``C(1)``: ``(edges, s)``."""
    n, m = A1.shape
    D2 = np.empty((2, N_LAYERS, m + 1))
    best_s = _best_start(A1, A2, starts, D2)
    if best_s < 0:
        return np.empty((n + m, 2), dtype=np.int64), best_s
    steps = np.empty((n + 1, m + 1), dtype=np.int8)
    _annulus_dp(A1, A2, best_s, D2, steps, np.bool_(True))
    return _trace_back(steps, n, m), best_s


#: Work (``starts * n * m``) of one dynamic programme; beyond it the start points are thinned.
_DP_WORK = 1e6
#: After the first programme (the least-area band), the start points within this many of its best one.
_WINDOW = 3
#: The first programme's start points away from the original band's: at most this many, evenly spread.
_SPREAD = 8


def _lagrange_band(lo, hi, mu, starts, sign):
    """``(faces, s)``: the band minimising ``area - mu * sign * Am`` over the start points ``starts``."""
    c1, c2, swapped = oriented_pair(lo, hi)
    A1, A2 = _costs(np.ascontiguousarray(c1), np.ascontiguousarray(c2), float(mu), float(sign))
    E, s = _best_edges(A1, A2, starts)
    if s < 0:
        return None, -1
    return edges_to_faces(E, len(c1), len(c2), int(s), 0, len(lo), swapped), int(s)


def faithful_band(lo: np.ndarray, hi: np.ndarray, f: np.ndarray, *, slack: float = 2e-3,
                  crosses=None, max_steps: int = 14):
    """``(faces, replaced)``: ``f`` when its volume lies within the rules' interval for the rings
    ``lo``, ``hi`` (``(n, 3)``, ``(m, 3)``, at two heights, oriented as the mesher's rings), widened by
    ``slack`` of the interval's magnitude; otherwise the Lagrangian band closest to the interval
    (module docstring).  ``crosses(P, faces)``, when given, rejects candidates whose faces cross."""
    h = float(hi[0, 2] - lo[0, 2])
    n, m = len(lo), len(hi)
    if h == 0.0 or min(n, m) < 3:
        return f, False
    a0, a1 = _shoelace(lo[:, :2]), _shoelace(hi[:, :2])
    if a0 == 0.0 or a1 == 0.0 or (a0 > 0) != (a1 > 0):
        return f, False
    vlo, vhi = rule_interval(a0, a1, h)
    tol = slack * max(abs(vlo), abs(vhi))

    def miss(v):  # how far outside the widened interval (0 inside), signed by the side
        return (v - (vhi + tol)) if v > vhi + tol else ((v - (vlo - tol)) if v < vlo - tol else 0.0)

    v = band_volume(lo, hi, f)
    if miss(v) == 0.0:
        return f, False
    # "more volume" is more negative for holes: mu > 0 always fills the ring's own inside
    sign = 1.0 if a0 > 0 else -1.0
    k1 = min(n, m)
    step = max(1, int(np.ceil(k1 * n * m / _DP_WORK)))
    off = n + m  # centre the rings: the shoelace terms are then small
    centre = np.r_[np.concatenate([lo, hi])[:, :2].mean(axis=0), 0.0]
    lo_c, hi_c = lo - centre, hi - centre
    # the start points of the original band's rungs at the larger ring's first point, those near them,
    # and a coarse spread of at most _SPREAD others (the best start moves little from the original's)
    c1_is_lo = n <= m
    at = n if c1_is_lo else 0  # the first point of C(2) in vstack([lo, hi])
    touching = f[(f == at).any(axis=1)].ravel()
    starts_own = (touching[touching < n] if c1_is_lo else touching[touching >= n] - n).astype(np.int64)
    around = (starts_own[:, None] + np.arange(-_WINDOW, _WINDOW + 1)[None, :]).ravel() % k1
    starts = np.arange(0, k1, max(step, -(-k1 // _SPREAD)), dtype=np.int64)
    starts = np.unique(np.r_[starts, around, starts_own]).astype(np.int64)
    P = np.concatenate([lo, hi])
    best, best_miss = f, abs(miss(v))
    cache = {}

    near = [None]  # after the first programme: start points near its best one (they move little with mu)

    def attempt(mu):
        if mu not in cache:
            g, s = _lagrange_band(lo_c, hi_c, mu, starts if near[0] is None else near[0], sign)
            if near[0] is None and s >= 0 and len(starts) > 2 * _WINDOW + 1:
                near[0] = np.unique(np.r_[np.arange(s - _WINDOW, s + _WINDOW + 1) % k1, starts_own]).astype(np.int64)
            cache[mu] = (g, None if g is None else band_volume(lo, hi, g))
        return cache[mu]

    def consider(g, vg):
        nonlocal best, best_miss
        if g is None or len(g) != off:
            return False
        d = abs(miss(vg))
        if d < best_miss and (crosses is None or not crosses(P, g)):
            best, best_miss = g, d
            return d == 0.0
        return False

    # the weight's direction: more volume (mu > 0) when below the interval, less (mu < 0) above
    direction = 1.0 if sign * miss(v) < 0 else -1.0
    lo_mu, hi_mu = 0.0, None
    g0, v0 = attempt(0.0)
    if consider(g0, v0):
        return best, True
    if g0 is not None and sign * direction * miss(v0) > 0:
        hi_mu = 0.0  # the least-area band already overshoots to the other side (rare)
    mu = 0.25
    steps = 0
    while hi_mu is None and steps < max_steps:  # grow the weight until the volume passes the interval
        g, vg = attempt(direction * mu)
        steps += 1
        if consider(g, vg):
            return best, True
        if g is not None and sign * direction * miss(vg) >= 0:
            hi_mu = mu
            break
        lo_mu, mu = mu, mu * 2
    if hi_mu is None:
        return best, best is not f
    while steps < max_steps and hi_mu - lo_mu > 1e-4:  # bisect between the two sides
        mu = 0.5 * (lo_mu + hi_mu)
        g, vg = attempt(direction * mu)
        steps += 1
        if consider(g, vg):
            return best, True
        if g is None or sign * direction * miss(vg) < 0:
            lo_mu = mu
        else:
            hi_mu = mu
    return best, best is not f


class FaithfulBands:
    """A band guard for :func:`contourmesh.volumes.volume_to_mesh` (``band_guard``): every band made
    between two rings at different heights goes through :func:`faithful_band`; counts the bands
    it replaced (``replaced``) and those it checked (``checked``).  With ``record=True`` it keeps the
    corner coordinates of the faces of every band it returns (:meth:`faces`)."""

    def __init__(self, slack: float = 2e-3, record: bool = False):
        from . import _band_crosses

        self.slack = slack
        self._crosses = _band_crosses
        self.checked = 0
        self.replaced = 0
        self._record = [] if record else None

    def faces(self) -> np.ndarray:
        """``(n, 3, 3)``: the corners of the faces of the bands returned (``record=True``)."""
        if not self._record:
            return np.zeros((0, 3, 3))
        return np.concatenate(self._record)

    def __call__(self, lo: np.ndarray, hi: np.ndarray, f: np.ndarray) -> np.ndarray:
        if lo[0, 2] == hi[0, 2]:
            return f
        self.checked += 1
        g, replaced = faithful_band(lo, hi, f, slack=self.slack, crosses=self._crosses)
        self.replaced += bool(replaced)
        if self._record is not None:
            self._record.append(np.concatenate([lo, hi])[g])
        return g
