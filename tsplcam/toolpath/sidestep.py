"""Side step, cusp height and forward step of a ball-end mill, vectorised.

Sign convention (docs/method.md sections 1.5 and 3.2): curvatures are normal
curvatures with the surface normal pointing *to the tool side*; convex is negative
(a sphere machined from outside, outward normal: k = -1/R), concave positive.

* :func:`side_step` -- exact side step on a surface of constant cross curvature
  (docs/method.md 3.2). Both exact cases, convex and concave, reduce to one stable formula:
  in the triangle (centre of curvature, ball centre, cusp) the law of cosines gives
  ``sin^2(theta/4) = (2 r h - h^2) / (4 rho^2 (1 - r k)(1 - h k))``, ``g = rho theta``, i.e.
  ``g = 4 X asin(|k| X) / (|k| X)`` with ``X = sqrt((2 r h - h^2) / (4 (1 - r k)(1 - h k)))``.
  At k = 0 it is the flat ``g = 2 sqrt(2 r h - h^2)``. (The paper's ``sqrt(8 h r R/(R + s r))``
  is its first-order form.)
* :func:`cusp_height` -- the inverse: the scallop left by two balls whose *centres* are a
  distance ``w`` apart on a surface of curvature k (exact on a circle).
* :func:`parameter_step` -- docs/method.md 3.4 (replacing the paper's garbled eq. (6)):
  the distance between iso-lines s and s + ds is ``|S_s x S_t| / |S_t| ds``, so
  ``ds = g sqrt(G) / sqrt(E G - F^2)`` for lines of constant s (feed along t).
* :func:`forward_step` -- docs/method.md 3.7: the chord of the *ball-centre* path between two
  contact points a distance L apart sags ``L^2 |k_f| (1 - r k_f) / 8``; a lateral (geodesic)
  curvature k_g of the line adds ``L^2 |k_g| (1 - r k_f) / 8`` sideways.
"""
from __future__ import annotations

import numpy as np

# numpy's C functions without their Python dispatch wrappers: the same calls, a few
# microseconds less each on the many small arrays here
from ..npfast import quiet as _quiet, where as _where


def side_step(r: float, h, k) -> np.ndarray:
    """Side step g (mm, along the surface) for scallop ``h`` with a ball of radius ``r`` on a
    surface of cross curvature ``k`` (1/mm, tool-side normal). ``h`` and ``k`` broadcast.

    Requires ``r k < 1`` (a concave radius larger than the ball); the caller refuses the rest.
    Where the formula has no solution (a concave radius barely above r: any step leaves less
    than h) the step is capped at a quarter turn, ``g = rho pi / 2``.
    """
    h = np.asarray(h, float)
    k = np.asarray(k, float)
    X = np.sqrt(np.maximum(2.0 * r * h - h * h, 0.0) / (4.0 * (1.0 - r * k) * (1.0 - h * k)))
    ak = np.abs(k)
    z = ak * X
    zmax = np.sin(np.pi / 8)                        # theta = 4 asin(z) <= pi / 2
    zc = np.minimum(z, zmax)
    with _quiet("invalid", "divide"):
        asinc = _where(zc > 1e-6, np.arcsin(zc) / _where(zc > 0, zc, 1.0), 1.0 + zc * zc / 6.0)
        capped = 0.5 * np.pi / _where(ak > 0, ak, 1.0)
    return _where(z > zmax, capped, 4.0 * X * asinc)


def cusp_height(r: float, w, k) -> np.ndarray:
    """Scallop height between two ball positions whose *centres* are ``w`` apart (mm), on a
    surface of cross curvature ``k`` (tool-side normal); exact for a circular section.

    The centres lie on a circle of radius ``(1 - r k)/|k|`` about the centre of curvature and
    the cusp is the balls' intersection nearest the surface; written without cancellation:
    ``r - sqrt(r^2 - w^2/4) + (w^2/4) k / ((1 - r k) + sqrt((1 - r k)^2 - k^2 w^2/4))``.
    NaN where ``w >= 2 r`` (the balls do not meet).
    """
    w = np.asarray(w, float)
    k = np.asarray(k, float)
    q = 0.25 * w * w
    depth = np.sqrt(_where(q < r * r, r * r - q, np.nan))
    a = 1.0 - r * k
    return r - depth + q * k / (a + np.sqrt(np.maximum(a * a - k * k * q, 0.0)))


def first_order_side_step(r: float, h, k) -> np.ndarray:
    """The paper's eq. (5), the first-order approximation ``sqrt(8 h r R / (R + s r))``
    (docs/method.md 3.2), written with the signed curvature: ``sqrt(8 h r / (1 - r k))``."""
    return np.sqrt(8.0 * np.asarray(h, float) * r / (1.0 - r * np.asarray(k, float)))


def parameter_step(g, E, F, G) -> np.ndarray:
    """Parameter step ``ds`` across lines of constant s for a side step g in space
    (docs/method.md 3.4): ``g sqrt(G) / sqrt(E G - F^2)`` with E, F, G in (s, t)."""
    det = np.asarray(E) * np.asarray(G) - np.asarray(F) ** 2
    with _quiet("divide", "invalid"):
        return _where(det > 0, np.asarray(g) * np.sqrt(np.asarray(G) / _where(det > 0, det, 1.0)),
                        np.inf)


def forward_step(r: float, tol, k_f, k_g=0.0) -> np.ndarray:
    """Contact-point step L (mm) along a line whose ball-centre chord deviates at most ``tol``
    (docs/method.md 3.7): ``sqrt(8 tol / (kappa (1 - r k_f)))`` with kappa the larger of |k_f|
    and |k_g|; infinite on a straight flat line."""
    k_f = np.asarray(k_f, float)
    kappa = np.maximum(np.abs(k_f), np.abs(np.asarray(k_g, float)))
    den = kappa * np.maximum(1.0 - r * k_f, 1e-12)
    with _quiet("divide"):
        return _where(den > 0, np.sqrt(8.0 * np.asarray(tol, float) / _where(den > 0, den, 1.0)), np.inf)
