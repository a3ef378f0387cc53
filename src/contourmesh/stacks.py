"""Contour stacks from drawn rings: grouping by height, nesting (even-odd) and orientation.

:func:`stack_from_rings` turns rings read from a file (or drawn in code) into a
:class:`~contourmesh.types.ContourStack`: rings within ``z_tol`` of each other form a section,
each ring is cleaned (repeated points, a duplicated closing point), its parent is the smallest
ring that contains it, and rings are oriented so that outer rings have positive area and holes
negative.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import warn_external
from .geometry import points_in_rings, shoelace_area
from .types import ContourStack, Section

__all__ = ["stack_from_rings", "check_stack", "Z_TOLERANCE"]


Z_TOLERANCE = 1e-3


def _clean_ring(ring: np.ndarray) -> np.ndarray:
    """Drop consecutive repeated points and a repeated closing point."""
    if len(ring) == 0:
        return ring
    keep = np.ones(len(ring), dtype=bool)
    keep[1:] = np.any(ring[1:] != ring[:-1], axis=1)
    r = ring[keep]
    while len(r) > 1 and np.all(r[-1] == r[0]):
        r = r[:-1]
    return r


def _reverse_keep_start(r: np.ndarray) -> np.ndarray:
    return np.concatenate([r[:1], r[:0:-1]])


def _nest_section(rings: list) -> tuple[tuple, tuple]:
    """Holes by even-odd nesting; outer rings positive, holes negative; parents of holes.

    Ring ``i`` lies inside ring ``j`` when ``|area j| > |area i|`` and most of ``i``'s points are
    inside ``j`` (even-odd test).  A ring inside an odd number of others is a hole; its parent is
    the smallest ring containing it.
    """

    n = len(rings)
    areas = np.array([abs(shoelace_area(r)) for r in rings])
    inside = np.zeros((n, n), dtype=bool)  # inside[i, j]: ring i lies inside ring j
    lo = np.array([r.min(0) for r in rings]) if n else np.zeros((0, 2))
    hi = np.array([r.max(0) for r in rings]) if n else np.zeros((0, 2))
    for i in range(n):
        for j in range(n):
            if i == j or areas[j] <= areas[i]:
                continue
            # a ring inside another lies within its bounding box (up to a shared boundary)
            if np.any(lo[i] < lo[j] - 1e-9) or np.any(hi[i] > hi[j] + 1e-9):
                continue
            inside[i, j] = points_in_rings(rings[i], rings[j]).mean() > 0.5
    depth = inside.sum(1)
    contours, parents = [], []
    for i in range(n):
        r = rings[i]
        hole = depth[i] % 2 == 1
        if hole:
            cands = np.flatnonzero(inside[i])
            parents.append(int(cands[np.argmin(areas[cands])]))
        else:
            parents.append(-1)
        a = shoelace_area(r)
        if (a < 0) != hole:
            r = _reverse_keep_start(r)
        contours.append(r)
    return tuple(contours), tuple(parents)


def stack_from_rings(slices, *, z_tol: float = Z_TOLERANCE, meta: dict | None = None, source: str = "input") -> ContourStack:
    """Build a ContourStack from rings at heights: grouping, cleaning, nesting, orientation.

    Parameters
    ----------
    slices : iterable of (z, rings)
        ``rings`` a sequence of ``(k, 2)`` array-likes of physical ``(x, y)`` points, closed
        implicitly (a repeated closing point is dropped), either winding.
    z_tol : float
        Heights that differ by at most this much (chained) are one section; the section's height
        is their mean.  Slices may come in any order; sections come out sorted.
    meta : dict, optional
        Stored in ``ContourStack.meta``.
    source : str
        Named in error and warning messages.

    Returns
    -------
    ContourStack
        float64 rings, ``spacing = (1, 1)``, ``origin = (0, 0)``; per section, rings in input
        order, holes (inside an odd number of others) with negative shoelace area and their
        ``parents`` set to the smallest enclosing ring, outer rings with positive area.

    Raises
    ------
    ValueError
        Non-finite heights or coordinates, rings that are not ``(k, 2)``, or no ring left.

    Warns
    -----
    UserWarning
        Rings with fewer than 3 distinct points, or enclosing no area, are dropped, naming the
        slice and the count.
    """
    items = []
    for s, (z, rings) in enumerate(slices):
        try:
            zf = float(z)
        except (TypeError, ValueError):
            raise ValueError(f"{source}: slice {s}: expected a number for z; found {z!r}") from None
        if not math.isfinite(zf):
            raise ValueError(f"{source}: slice {s}: z must be finite; found {z!r}")
        for r, ring in enumerate(rings):
            try:
                arr = np.asarray(ring, dtype=np.float64)
            except (TypeError, ValueError):
                raise ValueError(f"{source}: slice {s} (z={zf:g}) ring {r}: expected a list of [x, y] pairs") from None
            if arr.size == 0:
                arr = arr.reshape(0, 2)
            if arr.ndim != 2 or arr.shape[1] != 2:
                raise ValueError(f"{source}: slice {s} (z={zf:g}) ring {r}: expected a (k, 2) list of [x, y] "
                                 f"points; found shape {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{source}: slice {s} (z={zf:g}) ring {r} holds NaN or infinite coordinates")
            items.append((zf, s, r, arr))
    if not items:
        raise ValueError(f"{source}: no contour found; expected at least one ring")
    items.sort(key=lambda t: t[0])
    groups, cur = [], [items[0]]
    for it in items[1:]:
        if it[0] - cur[-1][0] <= z_tol:
            cur.append(it)
        else:
            groups.append(cur)
            cur = [it]
    groups.append(cur)
    sections = []
    dropped_total = 0
    for g in groups:
        z = float(np.mean([it[0] for it in g]))
        g = sorted(g, key=lambda t: (t[1], t[2]))
        rings, dropped = [], 0
        for _, _, _, arr in g:
            r = _clean_ring(arr)
            if len(r) < 3 or shoelace_area(r) == 0.0:
                dropped += 1
                continue
            rings.append(r)
        if dropped:
            dropped_total += dropped
            warn_external(f"{source}: slice z={z:g}: dropped {dropped} contour(s) with fewer than 3 distinct points "
                          "or no enclosed area")
        if not rings:
            continue
        contours, parents = _nest_section(rings)
        sections.append(Section(z, contours, parents))
    if not sections:
        raise ValueError(f"{source}: no contour with 3 or more distinct points; nothing to mesh")
    m = dict(meta or {})
    m.setdefault("dropped_contours", dropped_total)
    return ContourStack(tuple(sections), spacing=(1.0, 1.0), origin=(0.0, 0.0), meta=m)


def check_stack(stack, what: str = "contour stack") -> np.ndarray:
    """The section heights of a ContourStack, after checking that there is at least one section and
    that the heights are finite and strictly increasing (the one stack validator)."""
    if not isinstance(stack, ContourStack):
        raise TypeError(f"expected a ContourStack; got {type(stack).__name__}")
    if len(stack.sections) == 0:
        raise ValueError(f"the {what} is empty: no section holds a contour")
    zs = stack.z
    if not np.all(np.isfinite(zs)):
        bad = int(np.flatnonzero(~np.isfinite(zs))[0])
        raise ValueError(f"section heights must be finite numbers; found z[{bad}]={zs[bad]}")
    if len(zs) > 1 and not np.all(np.diff(zs) > 0):
        bad = int(np.flatnonzero(np.diff(zs) <= 0)[0])
        raise ValueError(f"section heights must be strictly increasing; found z[{bad}]={zs[bad]} >= "
                         f"z[{bad + 1}]={zs[bad + 1]}")
    return zs
