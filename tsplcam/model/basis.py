"""Polynomial bases evaluated for many parameters at once.

Bernstein polynomials (Bezier cells), uniform cubic B-splines (regular subdivision
patches), general B-spline basis functions by the Cox-de Boor recursion (T-spline blending
functions, B-spline faces), and the change from a piecewise polynomial to Bernstein
coefficients (Bezier extraction). Every function takes a parameter array of shape (n,)
and returns values for all parameters in one call.
"""
from __future__ import annotations

from functools import lru_cache
from math import comb

import numpy as np


def bernstein(p: int, t: np.ndarray, nderiv: int = 2) -> np.ndarray:
    """Bernstein basis of degree p and its derivatives, shape (n, nderiv+1, p+1).

    Derivative rule: d/dt B_{i,p} = p (B_{i-1,p-1} - B_{i,p-1}).
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    if p == 3 and nderiv == 2:
        return _bernstein3(t).transpose(2, 0, 1)
    n = len(t)
    out = np.zeros((n, nderiv + 1, p + 1))
    for d in range(nderiv + 1):
        q = p - d
        if q < 0:
            break
        # Bernstein values of degree q
        s = 1.0 - t
        vals = np.empty((n, q + 1))
        for i in range(q + 1):
            vals[:, i] = comb(q, i) * t ** i * s ** (q - i)
        # apply the derivative difference operator d times
        coef = _difference_operator(p, d)          # (p+1, q+1)
        out[:, d, :] = vals @ coef.T
    return out


def bernstein_rows(p: int, t: np.ndarray) -> np.ndarray:
    """The same values and first two derivatives point-minor, (3, p+1, n) contiguous: the
    layout BLAS products over many points want."""
    t = np.asarray(t, dtype=float).reshape(-1)
    if p == 3:
        return _bernstein3(t)
    return np.ascontiguousarray(bernstein(p, t).transpose(1, 2, 0))


def _bernstein3(t: np.ndarray) -> np.ndarray:
    """Cubic Bernstein basis with first and second derivatives, written out (the hot case),
    (3, 4, n). Every value is one fixed expression of t (the products 3 t^2, 3 s^2, 6 t s and
    18 t made once and used where the formulas repeat them; negating is exact): the same
    values point by point whatever else is in the call."""
    n = len(t)
    s = 1.0 - t
    t2, s2, ts = t * t, s * s, t * s
    out = np.empty((3, 4, n))
    tmp = np.empty(n)
    np.multiply(s2, s, out=out[0, 0])
    np.multiply(3.0, t, out=tmp)
    np.multiply(tmp, s2, out=out[0, 1])
    np.multiply(3.0, t2, out=out[1, 3])                 # 3 t^2
    np.multiply(out[1, 3], s, out=out[0, 2])
    np.multiply(t2, t, out=out[0, 3])
    np.multiply(3.0, s2, out=tmp)                       # 3 s^2
    np.negative(tmp, out=out[1, 0])                     # -3 s^2, exactly
    np.multiply(6.0, ts, out=ts)                        # 6 t s
    np.subtract(tmp, ts, out=out[1, 1])
    np.subtract(ts, out[1, 3], out=out[1, 2])
    np.multiply(6.0, s, out=out[2, 0])
    np.multiply(18.0, t, out=tmp)                       # 18 t
    np.subtract(tmp, 12.0, out=out[2, 1])
    np.subtract(6.0, tmp, out=out[2, 2])
    np.multiply(6.0, t, out=out[2, 3])
    return out


@lru_cache(maxsize=None)
def _difference_operator(p: int, d: int) -> np.ndarray:
    """Matrix D with d^d/dt^d B_p(t) = D @ B_{p-d}(t) (coefficients of the d-th derivative)."""
    m = np.eye(p + 1)
    deg = p
    for _ in range(d):
        nxt = np.zeros((p + 1, deg))
        # derivative of sum_i c_i B_{i,deg} = deg * sum_i (c_{i+1} - c_i) B_{i,deg-1}
        for i in range(deg):
            nxt[:, i] = deg * (m[:, i + 1] - m[:, i])
        m = nxt
        deg -= 1
    return m


# Uniform cubic B-spline segment on [0, 1] as a matrix on the monomials (1, t, t^2, t^3):
# N_i(t) = sum_k _UCB[i, k] t^k for the four functions that are non-zero on the segment.
_UCB = np.array([[1.0, -3.0, 3.0, -1.0],
                 [4.0, 0.0, -6.0, 3.0],
                 [1.0, 3.0, 3.0, -3.0],
                 [0.0, 0.0, 0.0, 1.0]]) / 6.0


def uniform_cubic(t: np.ndarray, nderiv: int = 2) -> np.ndarray:
    """The four uniform cubic B-spline functions on one segment, (n, nderiv+1, 4)."""
    t = np.asarray(t, dtype=float).reshape(-1)
    one = np.ones_like(t)
    zero = np.zeros_like(t)
    mono = [np.stack([one, t, t * t, t * t * t], axis=1),
            np.stack([zero, one, 2 * t, 3 * t * t], axis=1),
            np.stack([zero, zero, 2 * one, 6 * t], axis=1),
            np.stack([zero, zero, zero, 6 * one], axis=1)]
    return np.stack([m @ _UCB.T for m in mono[: nderiv + 1]], axis=1)


# Uniform cubic B-spline control polygon -> Bezier control polygon of the middle segment.
BSPLINE_TO_BEZIER = np.array([[1.0, 4.0, 1.0, 0.0],
                              [0.0, 4.0, 2.0, 0.0],
                              [0.0, 2.0, 4.0, 0.0],
                              [0.0, 1.0, 4.0, 1.0]]) / 6.0


def bspline_basis(knots: np.ndarray, p: int, x: np.ndarray, span: np.ndarray | None = None,
                  nderiv: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Non-zero B-spline basis functions (Cox-de Boor) of a knot vector, vectorised over x.

    Returns (span, values) with values of shape (n, nderiv+1, p+1): functions
    span-p .. span at each x. ``span`` may be given (for evaluating a piece at its end).
    The recursion is The NURBS Book's (Piegl and Tiller, A2.2/A2.3), written on arrays.
    """
    knots = np.asarray(knots, dtype=float)
    x = np.asarray(x, dtype=float).reshape(-1)
    n = len(x)
    if span is None:
        m = len(knots) - p - 1
        # x on a knot (or a rounding off it) takes the span to its right (or left): the basis
        # is continuous there, so either span gives the same values up to rounding
        span = np.searchsorted(knots, x, side="right") - 1
        span = np.clip(span, p, m - 1)
    span = np.asarray(span, dtype=int)
    # table of basis values of all degrees 0..p (ndu of A2.3), knot differences in the lower part
    ndu = np.zeros((n, p + 1, p + 1))
    ndu[:, 0, 0] = 1.0
    left = np.zeros((n, p + 1))
    right = np.zeros((n, p + 1))
    for j in range(1, p + 1):
        left[:, j] = x - knots[span + 1 - j]
        right[:, j] = knots[span + j] - x
        saved = np.zeros(n)
        for r in range(j):
            ndu[:, j, r] = right[:, r + 1] + left[:, j - r]
            # exact by construction: right + left is (k_b - x) + (x - k_a); for a repeated knot
            # k_a == k_b the two roundings are exact negatives and the sum is exactly 0
            with np.errstate(divide="ignore", invalid="ignore"):
                temp = np.where(ndu[:, j, r] != 0.0, ndu[:, r, j - 1] / ndu[:, j, r], 0.0)
            ndu[:, r, j] = saved + right[:, r + 1] * temp
            saved = left[:, j - r] * temp
        ndu[:, j, j] = saved
    out = np.zeros((n, nderiv + 1, p + 1))
    out[:, 0, :] = ndu[:, :, p]
    if nderiv == 0:
        return span, out
    for r in range(p + 1):
        a = np.zeros((n, 2, p + 1))
        a[:, 0, 0] = 1.0
        s1, s2 = 0, 1
        for k in range(1, nderiv + 1):
            d = np.zeros(n)
            rk, pk = r - k, p - k
            if r >= k:
                with np.errstate(divide="ignore", invalid="ignore"):
                    a[:, s2, 0] = np.where(ndu[:, pk + 1, rk] != 0,
                                           a[:, s1, 0] / ndu[:, pk + 1, rk], 0.0)
                d = a[:, s2, 0] * ndu[:, rk, pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                with np.errstate(divide="ignore", invalid="ignore"):
                    a[:, s2, j] = np.where(ndu[:, pk + 1, rk + j] != 0,
                                           (a[:, s1, j] - a[:, s1, j - 1]) / ndu[:, pk + 1, rk + j], 0.0)
                d = d + a[:, s2, j] * ndu[:, rk + j, pk]
            if r <= pk:
                with np.errstate(divide="ignore", invalid="ignore"):
                    a[:, s2, k] = np.where(ndu[:, pk + 1, r] != 0,
                                           -a[:, s1, k - 1] / ndu[:, pk + 1, r], 0.0)
                d = d + a[:, s2, k] * ndu[:, r, pk]
            out[:, k, r] = d
            s1, s2 = s2, s1
    fac = p
    for k in range(1, nderiv + 1):
        out[:, k, :] *= fac
        fac *= p - k
    return span, out


@lru_cache(maxsize=None)
def _bernstein_interpolation_inverse(p: int) -> np.ndarray:
    """Inverse of the Bernstein collocation matrix at p+1 equally spaced points of [0, 1]."""
    t = np.linspace(0.0, 1.0, p + 1)
    return np.linalg.inv(bernstein(p, t, 0)[:, 0, :])


def to_bernstein(p: int, values_at_nodes: np.ndarray) -> np.ndarray:
    """Bernstein coefficients of degree-p polynomials from their values at p+1 equally spaced
    points of [0, 1] (axis 0 of ``values_at_nodes``). Exact for polynomials of degree <= p."""
    return np.tensordot(_bernstein_interpolation_inverse(p), values_at_nodes, axes=(1, 0))


def bspline_bezier_extraction(knots: np.ndarray, p: int) -> tuple[np.ndarray, np.ndarray]:
    """Bezier extraction of a B-spline basis: for every non-empty knot span, the matrix C with
    B-spline functions (span-p..span) = C @ Bernstein(p) on that span.

    Returns (spans, C) with C of shape (nspans, p+1, p+1), computed by sampling each
    function at p+1 points of the span and converting to Bernstein form (exact up to
    rounding, no knot insertion bookkeeping).
    """
    knots = np.asarray(knots, dtype=float)
    m = len(knots) - p - 1
    spans = np.array([i for i in range(p, m) if knots[i + 1] > knots[i]], dtype=int)
    nodes = np.linspace(0.0, 1.0, p + 1)
    a = knots[spans][:, None]
    b = knots[spans + 1][:, None]
    x = (a + (b - a) * nodes[None, :]).reshape(-1)
    _, vals = bspline_basis(knots, p, x, span=np.repeat(spans, p + 1))
    vals = vals[:, 0, :].reshape(len(spans), p + 1, p + 1)      # (span, node, function)
    inv = _bernstein_interpolation_inverse(p)
    C = np.einsum("kn,snf->sfk", inv, vals)                      # (span, function, bernstein)
    return spans, C
