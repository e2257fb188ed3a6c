"""Differential geometry of evaluated surface points, vectorised.

Formulas (docs/method.md sections 1.4-1.5, which correct shang2020 eq. (2)):
  S = B/W, S_u = (B_u - W_u S)/W, S_uu = (B_uu - 2 W_u S_u - W_uu S)/W,
  S_uv = (B_uv - W_uv S - W_u S_v - W_v S_u)/W;
  n = S_u x S_v / |S_u x S_v|; E = S_u.S_u, F = S_u.S_v, G = S_v.S_v;
  L = n.S_uu, M = n.S_uv, N = n.S_vv;
  normal curvature along (du, dv): (L du^2 + 2 M du dv + N dv^2) / (E du^2 + 2 F du dv + G dv^2).
Curvature signs follow the normal n: a sphere parametrised with outward n has k = -1/R.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..npfast import cross_rows, row_norms


def rational_from_homogeneous(H: np.ndarray) -> tuple[np.ndarray, ...]:
    """Euclidean position and partials from homogeneous ones.

    ``H`` has shape (6, 4, n): value, d/du, d/dv, d2/du2, d2/dudv, d2/dv2 of (wx, wy, wz, w),
    coordinate-major. Returns S, S_u, S_v, S_uu, S_uv, S_vv, each (3, n).
    """
    B = H[:, :3]
    W = H[:, 3:4]
    # exact test, and only a shortcut: weights that are 1 up to rounding take the rational
    # branch below, which gives the same surface
    if not np.any(W[1:]) and np.all(W[0] == 1.0):         # polynomial: nothing to divide
        return B[0], B[1], B[2], B[3], B[4], B[5]
    w = W[0]
    S = B[0] / w
    Su = (B[1] - W[1] * S) / w
    Sv = (B[2] - W[2] * S) / w
    Suu = (B[3] - 2.0 * W[1] * Su - W[3] * S) / w
    Suv = (B[4] - W[4] * S - W[1] * Sv - W[2] * Su) / w
    Svv = (B[5] - 2.0 * W[2] * Sv - W[5] * S) / w
    return S, Su, Sv, Suu, Suv, Svv


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


@dataclass
class SurfacePoints:
    """Points of a patch with their derivatives; derived quantities are computed on demand.

    All arrays have one row per point: P (n,3) position in mm, Pu ... Pvv the partial
    derivatives in the patch's (u, v) on the unit square.
    """
    P: np.ndarray
    Pu: np.ndarray
    Pv: np.ndarray
    Puu: np.ndarray
    Puv: np.ndarray
    Pvv: np.ndarray
    u: np.ndarray | None = None
    v: np.ndarray | None = None
    patch: int | None = None
    # replaced where an exact value is known (the limit normal at an extraordinary point)
    normal_override: np.ndarray | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.P)

    @cached_property
    def normal(self) -> np.ndarray:
        """Unit normal S_u x S_v / |S_u x S_v| (n, 3)."""
        if self.normal_override is not None:
            return self.normal_override
        # (np.cross's and np.linalg.norm's products and sums in their order, without their
        # axis handling: the same bits, two thirds of the time on a verification grid's rows)
        c = cross_rows(self.Pu, self.Pv)
        length = row_norms(c)[:, None]
        return c / np.where(length > 0.0, length, 1.0)

    @cached_property
    def first_form(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """First fundamental form (E, F, G) = (S_u.S_u, S_u.S_v, S_v.S_v)."""
        return _dot(self.Pu, self.Pu), _dot(self.Pu, self.Pv), _dot(self.Pv, self.Pv)

    @cached_property
    def second_form(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Second fundamental form (L, M, N) = (n.S_uu, n.S_uv, n.S_vv)."""
        return _dot(self.normal, self.Puu), _dot(self.normal, self.Puv), _dot(self.normal, self.Pvv)

    E = property(lambda self: self.first_form[0])
    F = property(lambda self: self.first_form[1])
    G = property(lambda self: self.first_form[2])
    L = property(lambda self: self.second_form[0])
    M = property(lambda self: self.second_form[1])
    N = property(lambda self: self.second_form[2])

    @cached_property
    def metric_det(self) -> np.ndarray:
        """EG - F^2 = |S_u x S_v|^2 (zero only where the parametrisation is singular)."""
        return np.einsum("ij,ij->i", *(2 * (np.cross(self.Pu, self.Pv),)))

    def _safe_det(self) -> np.ndarray:
        d = self.metric_det
        scale = np.maximum(self.E * self.G, 1e-300)
        return np.where(d > 1e-28 * scale, d, np.inf)

    @cached_property
    def gaussian_curvature(self) -> np.ndarray:
        return (self.L * self.N - self.M ** 2) / self._safe_det()

    @cached_property
    def mean_curvature(self) -> np.ndarray:
        return (self.E * self.N - 2.0 * self.F * self.M + self.G * self.L) / (2.0 * self._safe_det())

    @cached_property
    def principal_curvatures(self) -> tuple[np.ndarray, np.ndarray]:
        """(k1, k2) with k1 >= k2."""
        H = self.mean_curvature
        root = np.sqrt(np.maximum(H * H - self.gaussian_curvature, 0.0))
        return H + root, H - root

    @cached_property
    def principal_directions(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit tangent vectors (n, 3) of k1 and k2 (umbilics: along S_u)."""
        det = self._safe_det()
        E, F, G, L, M, N = self.E, self.F, self.G, self.L, self.M, self.N
        # shape operator W = I^-1 II acting on (du, dv)
        a = (G * L - F * M) / det
        b = (G * M - F * N) / det
        c = (E * M - F * L) / det
        d = (E * N - F * M) / det
        k1, _ = self.principal_curvatures
        x1 = np.stack([b, k1 - a], axis=1)
        x2 = np.stack([k1 - d, c], axis=1)
        n1 = np.linalg.norm(x1, axis=1)
        n2 = np.linalg.norm(x2, axis=1)
        x = np.where((n1 >= n2)[:, None], x1, x2)
        tiny = np.maximum(n1, n2) <= 1e-12 * (np.abs(a) + np.abs(d) + np.abs(b) + np.abs(c) + 1e-300)
        x[tiny] = [1.0, 0.0]
        d1 = x[:, :1] * self.Pu + x[:, 1:] * self.Pv
        d1 /= np.maximum(np.linalg.norm(d1, axis=1, keepdims=True), 1e-300)
        d2 = np.cross(self.normal, d1)
        return d1, d2

    def normal_curvature(self, du, dv) -> np.ndarray:
        """Normal curvature along the parameter direction (du, dv) (scalars or (n,) arrays)."""
        du = np.broadcast_to(np.asarray(du, float), self.E.shape)
        dv = np.broadcast_to(np.asarray(dv, float), self.E.shape)
        num = self.L * du * du + 2.0 * self.M * du * dv + self.N * dv * dv
        den = self.E * du * du + 2.0 * self.F * du * dv + self.G * dv * dv
        return num / np.where(den > 0.0, den, np.inf)

    def cross_curvature(self, along: str) -> np.ndarray:
        """Normal curvature across an isoparametric line, in the tangent plane.

        ``along='v'``: lines of constant u (feed along v); the cross direction is
        S_u - (F/G) S_v and k = (L G^2 - 2 M F G + N F^2) / (G (E G - F^2))
        (docs/method.md section 3.3). ``along='u'``: lines of constant v, symmetric formula.
        """
        E, F, G, L, M, N = self.E, self.F, self.G, self.L, self.M, self.N
        det = self._safe_det()
        if along == "v":
            return (L * G * G - 2.0 * M * F * G + N * F * F) / (np.where(G > 0, G, np.inf) * det)
        if along == "u":
            return (N * E * E - 2.0 * M * F * E + L * F * F) / (np.where(E > 0, E, np.inf) * det)
        raise ValueError("along must be 'u' or 'v'")

    def take(self, index) -> "SurfacePoints":
        """The rows ``index`` as a new SurfacePoints."""
        sub = lambda a: None if a is None else a[index]  # noqa: E731
        return SurfacePoints(self.P[index], self.Pu[index], self.Pv[index], self.Puu[index],
                             self.Puv[index], self.Pvv[index], sub(self.u), sub(self.v),
                             self.patch, sub(self.normal_override))
