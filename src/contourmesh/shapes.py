"""Analytic test solids: implicit form, exact area and volume, and an exact inside test.

The solids are those of the experiments in Wiederhold & Villafuerte (2009), section 6 and
Figures 4-5 (sphere, spheroid / ellipsoid, truncated cone, truncated one-sheet hyperboloid,
truncated paraboloid), plus a torus (two contours per slice, a hole-free genus-1 surface).

Every shape is defined in *local* coordinates ``q`` by one or more polynomial inequalities
``g(q) < 0`` (the curved surface) and ``g(q) <= 0`` (the flat end planes of truncated shapes),
and placed in the world by ``p = rotation @ q + center``, i.e. ``q = rotation.T @ (p - center)``.
The solid is exactly that set for the float64 numbers given (a float rotation matrix that is
orthogonal only to rounding is used as given).

Exactness
---------
The inside test used for digitization never depends on floating-point luck.  The constraint
polynomials are built symbolically with :class:`fractions.Fraction` coefficients (every float64
parameter is an exact binary rational), composed with the placement, so each constraint becomes an
exact polynomial in the world coordinates (or in the integer grid indices ``(i, j, k)`` of a grid
of spacing ``h``).  It is first evaluated in float64, vectorised; every point whose value lies
within ``1e-9`` times a bound on the magnitude of the summed terms (several million times the
worst rounding error) is re-evaluated exactly in integer / rational arithmetic.  This is the
classic *filtered predicate* of exact computational geometry (as in CGAL or DGtal's integer
predicates).

Conventions
-----------
Truncated shapes are solids of revolution about the local z axis cut by two planes; their end
planes are *closed* (a point on an end disc belongs to the solid for the exact test), so a slice
that falls exactly on an end plane contains the end disc.  The curved surface is *strict* by
default (a point on it is outside), which gives the paper's outer Jordan digitization.

* ``Sphere(r)``: ``x^2 + y^2 + z^2 < r^2``.
* ``Ellipsoid(a, b, c)``: ``x^2/a^2 + y^2/b^2 + z^2/c^2 < 1``; the paper's spheroid (Table 2) is
  ``Ellipsoid(a, b, b)`` = ``Spheroid(a, b)`` (axis of revolution along x).
* ``Cone(r0, r1, height)``: radius ``r0`` at ``z = 0`` to ``r1`` at ``z = height``.
* ``Hyperboloid(a, c, height)``: ``(x^2 + y^2)/a^2 - z^2/c^2 < 1`` for ``|z| <= height/2``.
* ``Paraboloid(a, height)``: ``(x^2 + y^2)/a^2 < z <= height`` (apex at the origin).
* ``Torus(R, r)``: tube radius ``r`` around the circle of radius ``R > r`` in the plane ``z = 0``.
"""

from __future__ import annotations

import math
from fractions import Fraction
from functools import reduce

import numpy as np

__all__ = [
    "Shape",
    "Sphere",
    "Ellipsoid",
    "Spheroid",
    "Cone",
    "Hyperboloid",
    "Paraboloid",
    "Torus",
    "SHAPES",
    "parse_shape_spec",
    "rotation_from_euler",
    "spheroid_area",
    "ellipsoid_area",
    "ellipsoid_area_quad",
]

#: Relative width of the band around 0 in which a float evaluation is not trusted (see module doc).
FILTER_REL = 1e-9
_QUAD_TOL = 1e-10


# ----------------------------------------------------------------------------------------------
# A tiny exact polynomial type (3 variables, Fraction coefficients)
# ----------------------------------------------------------------------------------------------
class _Poly:
    """Sparse polynomial in three variables with exact :class:`~fractions.Fraction` coefficients.

    ``terms`` maps exponent triples ``(a, b, c)`` to coefficients of ``v0^a v1^b v2^c``.  It supports
    ``+ - *`` and integer powers with other polynomials and numbers, which is all the shapes need to
    state their constraints once and have them composed with the placement symbolically.
    """

    __slots__ = ("terms",)

    def __init__(self, terms=None):
        self.terms = {e: Fraction(c) for e, c in (terms or {}).items() if c != 0}

    @staticmethod
    def var(index: int) -> "_Poly":
        e = [0, 0, 0]
        e[index] = 1
        return _Poly({tuple(e): 1})

    @staticmethod
    def _lift(other) -> "_Poly":
        if isinstance(other, _Poly):
            return other
        return _Poly({(0, 0, 0): Fraction(other)})

    def __add__(self, other):
        other = _Poly._lift(other)
        out = dict(self.terms)
        for e, c in other.terms.items():
            out[e] = out.get(e, 0) + c
        return _Poly(out)

    __radd__ = __add__

    def __neg__(self):
        return _Poly({e: -c for e, c in self.terms.items()})

    def __sub__(self, other):
        return self + (-_Poly._lift(other))

    def __rsub__(self, other):
        return _Poly._lift(other) - self

    def __mul__(self, other):
        other = _Poly._lift(other)
        out: dict = {}
        for e1, c1 in self.terms.items():
            for e2, c2 in other.terms.items():
                e = (e1[0] + e2[0], e1[1] + e2[1], e1[2] + e2[2])
                out[e] = out.get(e, 0) + c1 * c2
        return _Poly(out)

    __rmul__ = __mul__

    def __pow__(self, n: int):
        if not isinstance(n, int) or n < 0:
            raise ValueError("only non-negative integer powers")
        out = _Poly({(0, 0, 0): 1})
        for _ in range(n):
            out = out * self
        return out

    def in_slice(self, k: int) -> dict:
        """Exact coefficients ``{(a, b): C}`` of the polynomial in ``(v0, v1)`` with ``v2 = k``."""
        out: dict = {}
        for (a, b, c), coef in self.terms.items():
            out[(a, b)] = out.get((a, b), 0) + coef * Fraction(k) ** c
        return {e: c for e, c in out.items() if c != 0}

    def max_abs_coef(self) -> float:
        return max((abs(float(c)) for c in self.terms.values()), default=0.0)


def _lcm_den(coefs) -> int:
    return reduce(lambda x, y: x * y // math.gcd(x, y), (c.denominator for c in coefs), 1)


# ----------------------------------------------------------------------------------------------
# Exact evaluation of a polynomial over a slice of the integer grid
# ----------------------------------------------------------------------------------------------
def _sign_on_grid(coefs2: dict, ii: np.ndarray, jj: np.ndarray, closed: bool) -> np.ndarray:
    """Exact test ``g(i, j) < 0`` (``<= 0`` if ``closed``) on the grid ``jj x ii``.

    ``coefs2`` are exact coefficients ``{(a, b): Fraction}`` of ``g = sum C_ab i^a j^b``.  Float64
    first (filtered), then exact Python-integer evaluation of the undecided points.

    Returns a bool array of shape ``(len(jj), len(ii))``.
    """
    ni, nj = len(ii), len(jj)
    if not coefs2:  # g == 0 identically
        return np.full((nj, ni), closed, dtype=bool)
    if set(coefs2) == {(0, 0)}:  # constant over the slice: decide once, exactly
        c = coefs2[(0, 0)]
        return np.full((nj, ni), (c <= 0) if closed else (c < 0), dtype=bool)
    fi = ii.astype(np.float64)
    fj = jj.astype(np.float64)
    amax = max(abs(float(ii[0])), abs(float(ii[-1]))) if ni else 0.0
    bmax = max(abs(float(jj[0])), abs(float(jj[-1]))) if nj else 0.0
    deg_j = max(b for _, b in coefs2)
    # g = sum_b j^b * row_b(i),  row_b(i) = sum_a C_ab i^a   (float64)
    val = np.zeros((nj, ni), dtype=np.float64)
    mag = 0.0
    for b in range(deg_j + 1):
        row = np.zeros(ni, dtype=np.float64)
        have = False
        for (a, bb), c in coefs2.items():
            if bb != b:
                continue
            cf = float(c)
            row += cf * fi**a
            mag += abs(cf) * amax**a * bmax**b
            have = True
        if have:
            val += (fj**b)[:, None] * row[None, :]
    tol = FILTER_REL * mag
    out = val < 0 if not closed else val <= 0
    unsure = np.abs(val) <= tol
    if unsure.any():
        jy, ix = np.nonzero(unsure)
        den = _lcm_den(coefs2.values())
        icoef = [(a, b, int(c * den)) for (a, b), c in coefs2.items()]
        xs = ii[ix].astype(object)
        ys = jj[jy].astype(object)
        exact = np.zeros(len(ix), dtype=object)
        for a, b, c in icoef:
            exact = exact + c * (xs**a) * (ys**b)
        out[jy, ix] = np.array([(v <= 0) if closed else (v < 0) for v in exact], dtype=bool)
    return out


def _poly_eval_exact(poly: _Poly, x, y, z) -> Fraction:
    x, y, z = Fraction(x), Fraction(y), Fraction(z)
    return sum((c * x**a * y**b * z**cc for (a, b, cc), c in poly.terms.items()), Fraction(0))


# ----------------------------------------------------------------------------------------------
# Placement helpers
# ----------------------------------------------------------------------------------------------
def rotation_from_euler(x_deg: float = 0.0, y_deg: float = 0.0, z_deg: float = 0.0) -> np.ndarray:
    """Rotation matrix ``Rz @ Ry @ Rx`` (rotate about x first, then y, then z; angles in degrees)."""
    ax, ay, az = np.radians([x_deg, y_deg, z_deg])
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _check_size(name: str, value, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"shape parameter {name} must be a number; got {value!r}") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        need = "non-negative" if allow_zero else "positive"
        raise ValueError(f"shape parameter {name} must be a finite {need} number; got {value!r}")
    return v


def _check_center(center) -> np.ndarray:
    c = np.asarray(center, dtype=np.float64)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ValueError(f"center must be 3 finite numbers (x, y, z); got {center!r}")
    return c


def _check_rotation(rotation):
    if rotation is None:
        return None
    r = np.asarray(rotation, dtype=np.float64)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ValueError(f"rotation must be a 3x3 matrix of finite numbers or None; got shape {r.shape}")
    err = float(np.abs(r.T @ r - np.eye(3)).max())
    if err > 1e-9 or np.linalg.det(r) <= 0:
        raise ValueError(
            f"rotation must be a proper rotation matrix (R.T @ R = I within 1e-9, det +1); "
            f"got orthogonality error {err:.3g} and det {np.linalg.det(r):.6g}"
        )
    if np.array_equal(r, np.eye(3)):
        return None
    return r


# ----------------------------------------------------------------------------------------------
# Base class
# ----------------------------------------------------------------------------------------------
class Shape:
    """A placed analytic solid (see the module docstring for conventions).

    Subclasses define ``name``, ``_param_names``, :meth:`_constraints`, :meth:`_local_bounds`,
    ``area``, ``volume`` and the quadrature checks :meth:`area_quad`, :meth:`volume_quad`.
    """

    name = "shape"
    _param_names: tuple = ()

    def __init__(self, *, center=(0.0, 0.0, 0.0), rotation=None):
        self.center = _check_center(center)
        self.rotation = _check_rotation(rotation)
        self._grid_cache: dict = {}
        self._world_cache = None

    # --- description ----------------------------------------------------------------------
    @property
    def params(self) -> dict:
        """The size parameters (constructor keywords), as floats."""
        return {k: getattr(self, k) for k in self._param_names}

    @property
    def spec(self) -> str:
        """A spec string that :func:`parse_shape_spec` turns back into this shape."""
        parts = [f"{k}={v!r}" for k, v in self.params.items()]
        if np.any(self.center != 0):
            parts.append("center=" + ";".join(repr(float(v)) for v in self.center))
        if self.rotation is not None:
            parts.append("rotation=" + ";".join(repr(float(v)) for v in self.rotation.ravel()))
        return f"{self.name}:" + ",".join(parts)

    def describe(self) -> dict:
        """Name, parameters and placement, for ``ContourStack.meta`` and result tables."""
        return {
            "name": self.name,
            "params": self.params,
            "center": [float(v) for v in self.center],
            "rotation": None if self.rotation is None else self.rotation.tolist(),
        }

    def __repr__(self) -> str:
        p = ", ".join(f"{k}={v:g}" for k, v in self.params.items())
        extra = ""
        if np.any(self.center != 0):
            extra += f", center={tuple(float(v) for v in self.center)}"
        if self.rotation is not None:
            extra += ", rotation=<3x3>"
        return f"{type(self).__name__}({p}{extra})"

    # --- to be provided by subclasses ----------------------------------------------------
    def _constraints(self, qx, qy, qz) -> list:
        """``[(g, is_surface), ...]``: inside iff every ``g < 0`` (surface) / ``g <= 0`` (end plane)."""
        raise NotImplementedError

    def _local_bounds(self) -> np.ndarray:
        raise NotImplementedError

    @property
    def area(self) -> float:
        raise NotImplementedError

    @property
    def volume(self) -> float:
        raise NotImplementedError

    # --- placement ------------------------------------------------------------------------
    def _local_vars(self, scale: Fraction):
        """Local coordinates ``q = R^T (scale * v - c)`` as exact linear polynomials in ``v``."""
        v = [_Poly.var(0), _Poly.var(1), _Poly.var(2)]
        c = [Fraction(float(t)) for t in self.center]
        d = [scale * v[m] - c[m] for m in range(3)]
        if self.rotation is None:
            return d
        r = [[Fraction(float(self.rotation[m, l])) for l in range(3)] for m in range(3)]
        return [sum((r[m][l] * d[m] for m in range(3)), _Poly()) for l in range(3)]

    def grid_constraints(self, h: float = 1.0) -> list:
        """Constraints as exact polynomials in the grid indices ``(i, j, k)`` of points ``h*(i, j, k)``.

        Returns
        -------
        list of (_Poly, bool)
            ``(g, is_surface)`` pairs; a grid point is inside iff every surface ``g < 0``
            (``<= 0`` when not strict) and every end-plane ``g <= 0``.
        """
        key = float(h)
        if key not in self._grid_cache:
            q = self._local_vars(Fraction(key))
            self._grid_cache[key] = self._constraints(*q)
        return self._grid_cache[key]

    @property
    def bounds(self) -> np.ndarray:
        """Axis-aligned box ``[[xmin, ymin, zmin], [xmax, ymax, zmax]]`` containing the placed solid.

        Tight for unrotated shapes, ellipsoids and tori; for rotated truncated shapes it is the
        box of the rotated enclosing cylinder (still a superset).
        """
        lo, hi = self._local_bounds()
        if self.rotation is None:
            return np.array([lo + self.center, hi + self.center])
        mid = 0.5 * (lo + hi)
        half = 0.5 * (hi - lo)
        ext = np.abs(self.rotation) @ half
        c = self.rotation @ mid + self.center
        return np.array([c - ext, c + ext])

    # --- inside tests ---------------------------------------------------------------------
    def _world_constraints(self):
        if self._world_cache is None:
            q = self._local_vars(Fraction(1))
            cons = self._constraints(*q)
            self._world_cache = [
                (g, surf, [(e, float(c)) for e, c in g.terms.items()], g.max_abs_coef()) for g, surf in cons
            ]
        return self._world_cache

    def inside(self, x, y, z) -> np.ndarray:
        """Float64 implicit value, vectorised: ``< 0`` strictly inside, ``> 0`` outside (for plots).

        The value is the maximum over the constraints, each scaled by its largest coefficient.
        Use :meth:`contains` for a decision that must be right on the boundary.
        """
        x, y, z = np.broadcast_arrays(*(np.asarray(t, dtype=np.float64) for t in (x, y, z)))
        out = np.full(x.shape, -np.inf)
        for _, _, fterms, scale in self._world_constraints():
            val = np.zeros(x.shape)
            for (a, b, c), cf in fterms:
                val += cf * x**a * y**b * z**c
            out = np.maximum(out, val / scale)
        return out

    def contains(self, x, y, z, *, strict: bool = True) -> np.ndarray:
        """Exact inside test for float64 points (vectorised, filtered, exact fallback).

        Parameters
        ----------
        x, y, z : array_like
            World coordinates (broadcast together).
        strict : bool
            ``True``: points on the curved surface are outside (the open solid; end planes of
            truncated shapes are closed).  ``False``: the closed solid.

        Returns
        -------
        numpy.ndarray of bool
        """
        x, y, z = np.broadcast_arrays(*(np.asarray(t, dtype=np.float64) for t in (x, y, z)))
        shape = x.shape
        x, y, z = x.ravel(), y.ravel(), z.ravel()
        res = np.ones(x.shape, dtype=bool)
        for g, surf, fterms, _ in self._world_constraints():
            closed = not (surf and strict)
            val = np.zeros(x.shape)
            mag = np.zeros(x.shape)
            for (a, b, c), cf in fterms:
                t = cf * x**a * y**b * z**c
                val += t
                mag += np.abs(t)
            ok = val <= 0 if closed else val < 0
            for n in np.flatnonzero(np.abs(val) <= FILTER_REL * mag):
                v = _poly_eval_exact(g, x[n], y[n], z[n])
                ok[n] = (v <= 0) if closed else (v < 0)
            res &= ok
        return res.reshape(shape)

    def slice_mask(self, k: int, i_range, j_range, h: float = 1.0, *, strict: bool = True) -> np.ndarray:
        """Exact inside test of the grid points ``(i h, j h, k h)`` of one slice.

        Parameters
        ----------
        k : int
            Slice index (plane ``z = k h``).
        i_range, j_range : (int, int)
            Half-open index ranges ``[i0, i1)`` (x) and ``[j0, j1)`` (y).
        h : float
            Grid spacing.
        strict : bool
            See :meth:`contains`.

        Returns
        -------
        numpy.ndarray of bool, shape ``(j1 - j0, i1 - i0)``
            Indexed ``[y, x]``; True where the grid point is inside.
        """
        ii = np.arange(int(i_range[0]), int(i_range[1]), dtype=np.int64)
        jj = np.arange(int(j_range[0]), int(j_range[1]), dtype=np.int64)
        mask = np.ones((len(jj), len(ii)), dtype=bool)
        for g, surf in self.grid_constraints(h):
            mask &= _sign_on_grid(g.in_slice(int(k)), ii, jj, closed=not (surf and strict))
            if not mask.any():
                break
        return mask

    # --- checks by quadrature -------------------------------------------------------------
    def area_quad(self) -> float:
        """Surface area by adaptive quadrature (``scipy.integrate.quad``, 1e-10 relative)."""
        raise NotImplementedError

    def volume_quad(self) -> float:
        """Volume by adaptive quadrature (``scipy.integrate.quad``, 1e-10 relative)."""
        raise NotImplementedError


def _quad(f, a, b) -> float:
    from scipy.integrate import quad

    val, _ = quad(f, a, b, epsabs=0.0, epsrel=_QUAD_TOL, limit=200)
    return float(val)


# ----------------------------------------------------------------------------------------------
# Ellipsoids
# ----------------------------------------------------------------------------------------------
def spheroid_area(a: float, b: float) -> float:
    """Area of the spheroid ``x^2/a^2 + (y^2 + z^2)/b^2 = 1`` (paper, section 6, after Tee 2005).

    With ``delta = 1 - b^2/a^2``: prolate (``a > b``) ``2 pi b (a asin(sqrt d)/sqrt d + b)``,
    sphere ``4 pi a^2``, oblate (``a < b``) ``2 pi b (a asinh(sqrt(-d))/sqrt(-d) + b)``.
    """
    a, b = float(a), float(b)
    delta = 1.0 - b * b / (a * a)
    if delta > 0:
        s = math.sqrt(delta)
        return 2 * math.pi * b * (a * math.asin(s) / s + b)
    if delta < 0:
        s = math.sqrt(-delta)
        return 2 * math.pi * b * (a * math.asinh(s) / s + b)
    return 4 * math.pi * a * a


def ellipsoid_area(a: float, b: float, c: float) -> float:
    """Area of the ellipsoid with semi-axes ``a, b, c`` (Legendre's elliptic-integral form).

    With the axes sorted ``A >= B >= C``, ``phi = acos(C/A)`` and ``m = A^2 (B^2 - C^2) / (B^2 (A^2 - C^2))``:
    ``S = 2 pi C^2 + 2 pi A B / sin(phi) * (E(phi|m) sin^2 phi + F(phi|m) cos^2 phi)``,
    with ``F``, ``E`` the incomplete elliptic integrals ``scipy.special.ellipkinc`` / ``ellipeinc``.
    """
    from scipy.special import ellipeinc, ellipkinc

    A, B, C = sorted((float(a), float(b), float(c)), reverse=True)
    if A == C:
        return 4 * math.pi * A * A
    phi = math.acos(C / A)
    m = (A * A * (B * B - C * C)) / (B * B * (A * A - C * C))
    m = min(max(m, 0.0), 1.0)
    s, co = math.sin(phi), math.cos(phi)
    return 2 * math.pi * C * C + 2 * math.pi * A * B / s * (
        float(ellipeinc(phi, m)) * s * s + float(ellipkinc(phi, m)) * co * co
    )


def ellipsoid_area_quad(a: float, b: float, c: float) -> float:
    """Ellipsoid area by nested adaptive quadrature of the parametric area element (one octant x 8).

    ``dS = sin t sqrt(b^2 c^2 sin^2 t cos^2 p + a^2 c^2 sin^2 t sin^2 p + a^2 b^2 cos^2 t) dt dp``.
    """
    a, b, c = float(a), float(b), float(c)

    def inner(p):
        cp2, sp2 = math.cos(p) ** 2, math.sin(p) ** 2

        def f(t):
            st, ct = math.sin(t), math.cos(t)
            return st * math.sqrt(st * st * (b * b * c * c * cp2 + a * a * c * c * sp2) + a * a * b * b * ct * ct)

        return _quad(f, 0.0, math.pi / 2)

    return 8.0 * _quad(inner, 0.0, math.pi / 2)


class Ellipsoid(Shape):
    """Ellipsoid ``x^2/a^2 + y^2/b^2 + z^2/c^2 < 1`` (local axes), placed by ``center``/``rotation``.

    ``Ellipsoid(a, b, b)`` is the paper's spheroid (Table 2), axis of revolution along x.
    """

    name = "ellipsoid"
    _param_names = ("a", "b", "c")

    def __init__(self, a, b, c, *, center=(0.0, 0.0, 0.0), rotation=None):
        self.a = _check_size("a", a)
        self.b = _check_size("b", b)
        self.c = _check_size("c", c)
        super().__init__(center=center, rotation=rotation)

    def _semi_axes(self):
        return self.a, self.b, self.c

    def _constraints(self, qx, qy, qz):
        a2, b2, c2 = (Fraction(t) ** 2 for t in self._semi_axes())
        return [(b2 * c2 * qx * qx + a2 * c2 * qy * qy + a2 * b2 * qz * qz - a2 * b2 * c2, True)]

    def _local_bounds(self):
        s = np.array(self._semi_axes(), dtype=np.float64)
        return -s, s

    @property
    def bounds(self) -> np.ndarray:
        s = np.array(self._semi_axes(), dtype=np.float64)
        if self.rotation is None:
            ext = s
        else:  # exact extent of a rotated ellipsoid along world axis i: |row_i(R) * s|
            ext = np.sqrt(((self.rotation * s[None, :]) ** 2).sum(axis=1))
        return np.array([self.center - ext, self.center + ext])

    @property
    def area(self) -> float:
        a, b, c = self._semi_axes()
        if b == c:
            return spheroid_area(a, b)
        return ellipsoid_area(a, b, c)

    @property
    def volume(self) -> float:
        a, b, c = self._semi_axes()
        return 4.0 / 3.0 * math.pi * a * b * c

    def area_quad(self) -> float:
        return ellipsoid_area_quad(*self._semi_axes())

    def section_area(self, z: float) -> float:
        """Exact area of the cross-section by the plane at world height ``z`` (0 outside).

        The section of an ellipsoid ``x^T M x < 1`` by a horizontal plane is an ellipse: with the
        plane's 2x2 block ``A`` of ``M`` and the off-plane column ``b``, its area is
        ``pi (1 - w^2 q) / sqrt(det A)``, ``w`` the height above the centre and
        ``q = M_zz - b^T A^-1 b``.
        """
        R = self.rotation if self.rotation is not None else np.eye(3)
        M = R @ np.diag([self.a ** -2, self.b ** -2, self.c ** -2]) @ R.T
        A, b = M[:2, :2], M[:2, 2]
        q = M[2, 2] - b @ np.linalg.solve(A, b)
        w = float(z) - float(self.center[2])
        return max(0.0, math.pi * (1.0 - w * w * q) / math.sqrt(np.linalg.det(A)))

    def volume_quad(self) -> float:
        a, b, c = self._semi_axes()
        return _quad(lambda z: math.pi * a * b * (1.0 - (z / c) ** 2), -c, c)


class Spheroid(Ellipsoid):
    """The paper's spheroid ``x^2/a^2 + (y^2 + z^2)/b^2 < 1`` (= ``Ellipsoid(a, b, b)``).

    Prolate for ``a > b``, oblate for ``a < b``; its area is the closed form of section 6.
    """

    name = "spheroid"
    _param_names = ("a", "b")

    def __init__(self, a, b, *, center=(0.0, 0.0, 0.0), rotation=None):
        super().__init__(a, b, b, center=center, rotation=rotation)


class Sphere(Ellipsoid):
    """Sphere ``x^2 + y^2 + z^2 < r^2`` (paper, Table 1)."""

    name = "sphere"
    _param_names = ("r",)

    def __init__(self, r, *, center=(0.0, 0.0, 0.0), rotation=None):
        r = _check_size("r", r)
        self.r = r
        super().__init__(r, r, r, center=center, rotation=rotation)

    def _constraints(self, qx, qy, qz):
        r = Fraction(self.r)
        return [(qx * qx + qy * qy + qz * qz - r * r, True)]

    @property
    def area(self) -> float:
        return 4.0 * math.pi * self.r**2

    @property
    def volume(self) -> float:
        return 4.0 / 3.0 * math.pi * self.r**3


# ----------------------------------------------------------------------------------------------
# Truncated solids of revolution about the local z axis (paper, Figures 4-5)
# ----------------------------------------------------------------------------------------------
class _Revolution(Shape):
    """Solid of revolution ``x^2 + y^2 < rho(z)^2`` for ``z0 <= z <= z1``, with flat end discs."""

    z0 = 0.0
    z1 = 0.0

    def _rho2(self, z: float) -> float:
        raise NotImplementedError

    def _lateral_density(self, z: float) -> float:
        """``2 pi rho sqrt(1 + rho'^2) = 2 pi sqrt(rho^2 + (rho rho')^2)``, the area per unit height."""
        raise NotImplementedError

    def _rho_max(self) -> float:
        return math.sqrt(max(self._rho2(self.z0), self._rho2(self.z1)))

    def _local_bounds(self):
        rm = self._rho_max()
        return np.array([-rm, -rm, self.z0]), np.array([rm, rm, self.z1])

    def _discs(self) -> float:
        return math.pi * (self._rho2(self.z0) + self._rho2(self.z1))

    def area_quad(self) -> float:
        return _quad(self._lateral_density, self.z0, self.z1) + self._discs()

    def volume_quad(self) -> float:
        return _quad(lambda z: math.pi * self._rho2(z), self.z0, self.z1)


class Cone(_Revolution):
    """Truncated cone: radius ``r0`` at ``z = 0`` to ``r1`` at ``z = height`` (``r1 = 0``: full cone).

    Area = lateral ``pi (r0 + r1) sqrt((r1 - r0)^2 + height^2)`` + the end discs.
    """

    name = "cone"
    _param_names = ("r0", "r1", "height")

    def __init__(self, r0, r1, height, *, center=(0.0, 0.0, 0.0), rotation=None):
        self.r0 = _check_size("r0", r0)
        self.r1 = _check_size("r1", r1, allow_zero=True)
        self.height = _check_size("height", height)
        self.z0, self.z1 = 0.0, self.height
        super().__init__(center=center, rotation=rotation)

    def _rho(self, z):
        return self.r0 + (self.r1 - self.r0) * z / self.height

    def _rho2(self, z):
        return self._rho(z) ** 2

    def _lateral_density(self, z):
        slope = (self.r1 - self.r0) / self.height
        return 2 * math.pi * self._rho(z) * math.sqrt(1 + slope * slope)

    def _constraints(self, qx, qy, qz):
        r0, r1, H = Fraction(self.r0), Fraction(self.r1), Fraction(self.height)
        # x^2 + y^2 < rho(z)^2 with H rho(z) = r0 H + (r1 - r0) z  (rho >= 0 on the slab)
        lateral = H * H * (qx * qx + qy * qy) - (r0 * H + (r1 - r0) * qz) ** 2
        return [(lateral, True), (-qz, False), (qz - H, False)]

    @property
    def area(self) -> float:
        lateral = math.pi * (self.r0 + self.r1) * math.hypot(self.r1 - self.r0, self.height)
        return lateral + math.pi * (self.r0**2 + self.r1**2)

    @property
    def volume(self) -> float:
        return math.pi * self.height * (self.r0**2 + self.r0 * self.r1 + self.r1**2) / 3.0


class Hyperboloid(_Revolution):
    """Truncated one-sheet hyperboloid ``(x^2 + y^2)/a^2 - z^2/c^2 < 1`` for ``|z| <= height/2``."""

    name = "hyperboloid"
    _param_names = ("a", "c", "height")

    def __init__(self, a, c, height, *, center=(0.0, 0.0, 0.0), rotation=None):
        self.a = _check_size("a", a)
        self.c = _check_size("c", c)
        self.height = _check_size("height", height)
        self.z0, self.z1 = -0.5 * self.height, 0.5 * self.height
        super().__init__(center=center, rotation=rotation)

    def _rho2(self, z):
        return self.a**2 * (1.0 + (z / self.c) ** 2)

    def _lateral_density(self, z):
        a, c = self.a, self.c
        rr = a * a * z / (c * c)  # rho rho'
        return 2 * math.pi * math.sqrt(self._rho2(z) + rr * rr)

    def _constraints(self, qx, qy, qz):
        a2, c2, t = Fraction(self.a) ** 2, Fraction(self.c) ** 2, Fraction(self.height) / 2
        lateral = c2 * (qx * qx + qy * qy) - a2 * qz * qz - a2 * c2
        return [(lateral, True), (-qz - t, False), (qz - t, False)]

    @property
    def area(self) -> float:
        # lateral = 2 pi * int_{-t}^{t} sqrt(A + k z^2) dz, A = a^2, k = a^2 (a^2 + c^2) / c^4
        a, c, t = self.a, self.c, 0.5 * self.height
        A = a * a
        k = a * a * (a * a + c * c) / c**4
        lateral = 2 * math.pi * (t * math.sqrt(A + k * t * t) + A / math.sqrt(k) * math.asinh(t * math.sqrt(k / A)))
        return lateral + self._discs()

    @property
    def volume(self) -> float:
        H = self.height
        return math.pi * self.a**2 * (H + H**3 / (12.0 * self.c**2))


class Paraboloid(_Revolution):
    """Truncated paraboloid ``(x^2 + y^2)/a^2 < z <= height`` (apex at the origin, top disc closed)."""

    name = "paraboloid"
    _param_names = ("a", "height")

    def __init__(self, a, height, *, center=(0.0, 0.0, 0.0), rotation=None):
        self.a = _check_size("a", a)
        self.height = _check_size("height", height)
        self.z0, self.z1 = 0.0, self.height
        super().__init__(center=center, rotation=rotation)

    def _rho2(self, z):
        return self.a**2 * z

    def _lateral_density(self, z):
        # rho rho' = a^2 / 2
        return 2 * math.pi * math.sqrt(self.a**2 * z + self.a**4 / 4.0)

    def _constraints(self, qx, qy, qz):
        a2, H = Fraction(self.a) ** 2, Fraction(self.height)
        return [(qx * qx + qy * qy - a2 * qz, True), (qz - H, False)]

    @property
    def area(self) -> float:
        a2, H = self.a**2, self.height
        lateral = 4 * math.pi / (3 * a2) * ((a2 * H + a2 * a2 / 4.0) ** 1.5 - a2**3 / 8.0)
        return lateral + math.pi * a2 * H

    @property
    def volume(self) -> float:
        return 0.5 * math.pi * self.a**2 * self.height**2


class Torus(Shape):
    """Torus around the local z axis: ``(x^2+y^2+z^2+R^2-r^2)^2 < 4 R^2 (x^2+y^2)``, ``R > r > 0``.

    Area ``4 pi^2 R r``, volume ``2 pi^2 R r^2`` (Pappus).
    """

    name = "torus"
    _param_names = ("R", "r")

    def __init__(self, R, r, *, center=(0.0, 0.0, 0.0), rotation=None):
        self.R = _check_size("R", R)
        self.r = _check_size("r", r)
        if not self.R > self.r:
            raise ValueError(f"torus needs R > r (a ring torus); got R={self.R!r}, r={self.r!r}")
        super().__init__(center=center, rotation=rotation)

    def _constraints(self, qx, qy, qz):
        R2, r2 = Fraction(self.R) ** 2, Fraction(self.r) ** 2
        rho2 = qx * qx + qy * qy
        s = rho2 + qz * qz + (R2 - r2)
        return [(s * s - 4 * R2 * rho2, True)]

    def _local_bounds(self):
        e = self.R + self.r
        return np.array([-e, -e, -self.r]), np.array([e, e, self.r])

    @property
    def bounds(self) -> np.ndarray:
        if self.rotation is None:
            return super().bounds
        # torus = circle(R) + ball(r): extent along world axis i is R sqrt(1 - u_i^2) + r
        u = self.rotation[:, 2]
        ext = self.R * np.sqrt(np.clip(1.0 - u * u, 0.0, None)) + self.r
        return np.array([self.center - ext, self.center + ext])

    @property
    def area(self) -> float:
        return 4.0 * math.pi**2 * self.R * self.r

    @property
    def volume(self) -> float:
        return 2.0 * math.pi**2 * self.R * self.r**2

    def area_quad(self) -> float:
        # surface of revolution of the circle (R + r cos t, r sin t): dS = 2 pi (R + r cos t) r dt
        R, r = self.R, self.r
        return _quad(lambda t: 2 * math.pi * (R + r * math.cos(t)) * r, 0.0, 2 * math.pi)

    def volume_quad(self) -> float:
        R, r = self.R, self.r

        def section(z):  # annulus between R -/+ sqrt(r^2 - z^2)
            w = math.sqrt(max(r * r - z * z, 0.0))
            return math.pi * ((R + w) ** 2 - (R - w) ** 2)

        return _quad(section, -r, r)


# ----------------------------------------------------------------------------------------------
# Registry and spec strings
# ----------------------------------------------------------------------------------------------
SHAPES = {
    "sphere": Sphere,
    "ellipsoid": Ellipsoid,
    "spheroid": Spheroid,
    "cone": Cone,
    "hyperboloid": Hyperboloid,
    "paraboloid": Paraboloid,
    "torus": Torus,
}


def _parse_numbers(key: str, text: str, counts) -> list:
    parts = [p for p in text.replace(" ", "").split(";")]
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise ValueError(f"shape spec: {key}= expects numbers separated by ';'; got {text!r}") from None
    if len(vals) not in counts:
        want = " or ".join(str(c) for c in counts)
        raise ValueError(f"shape spec: {key}= expects {want} numbers separated by ';'; got {len(vals)} in {text!r}")
    if not all(math.isfinite(v) for v in vals):
        raise ValueError(f"shape spec: {key}= expects finite numbers; got {text!r}")
    return vals


def parse_shape_spec(spec: str) -> Shape:
    """Build a shape from a spec string ``name:key=value,key=value,...``.

    Examples: ``"sphere:r=40"``, ``"ellipsoid:a=30,b=20,c=10"``, ``"spheroid:a=10,b=6"``,
    ``"torus:R=30,r=9"``, ``"cone:r0=20,r1=10,height=30"``, ``"hyperboloid:a=10,c=8,height=30"``,
    ``"paraboloid:a=5,height=20"``.  Placement keys: ``center=x;y;z`` and ``rotation=`` either three
    Euler angles in degrees ``ax;ay;az`` (see :func:`rotation_from_euler`) or nine matrix entries
    (row-major).  Keys are case-sensitive (the torus has ``R`` and ``r``).

    Raises
    ------
    ValueError
        For an unknown shape name or key, a missing parameter, a bad number or a non-positive size.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError(f"shape spec must be a non-empty string like 'sphere:r=40'; got {spec!r}")
    name, _, rest = spec.strip().partition(":")
    name = name.strip().lower()
    if name not in SHAPES:
        raise ValueError(f"unknown shape {name!r} in spec {spec!r}; known shapes: {', '.join(SHAPES)}")
    cls = SHAPES[name]
    allowed = cls._param_names
    kwargs: dict = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, val = item.partition("=")
        key, val = key.strip(), val.strip()
        if not eq or not key or not val:
            raise ValueError(f"shape spec: expected key=value, got {item!r} in {spec!r}")
        if key in kwargs:
            raise ValueError(f"shape spec: {key!r} given twice in {spec!r}")
        if key == "center":
            kwargs[key] = _parse_numbers(key, val, (3,))
        elif key == "rotation":
            v = _parse_numbers(key, val, (3, 9))
            kwargs[key] = rotation_from_euler(*v) if len(v) == 3 else np.array(v).reshape(3, 3)
        elif key in allowed:
            try:
                kwargs[key] = float(val)
            except ValueError:
                raise ValueError(f"shape spec: {key}= expects a number; got {val!r} in {spec!r}") from None
        else:
            raise ValueError(
                f"shape spec: unknown key {key!r} for {name}; expected {', '.join(allowed)}, center, rotation"
            )
    missing = [k for k in allowed if k not in kwargs]
    if missing:
        raise ValueError(f"shape spec {spec!r}: missing {', '.join(missing)} (a {name} needs {', '.join(allowed)})")
    return cls(**kwargs)
