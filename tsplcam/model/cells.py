"""Cell evaluators: the pieces a patch is made of.

A patch's domain (the unit square) is cut into rectangular cells. A cell is either a
rational Bezier piece (any degree; T-spline and B-spline faces after Bezier extraction,
regular subdivision faces after the B-spline-to-Bezier change of basis) or an
extraordinary cell: a subdivision face with one irregular corner, evaluated exactly by the
eigen-decomposition of its local subdivision matrix (Stam 1998, generalised: the matrix is
computed numerically for the configuration at hand, see ``eigen.py``).

Every evaluator takes cell indices and local parameters (a, b) in [0, 1]^2 and returns
homogeneous values and derivatives, shape (6, n, 4): H, H_a, H_b, H_aa, H_ab, H_bb.
"""
from __future__ import annotations

import numpy as np

from .basis import bernstein, uniform_cubic

# derivative combinations in output order: (order in first variable, order in second)
DERIVS = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))


def tensor_basis(bs: np.ndarray, bt: np.ndarray) -> np.ndarray:
    """Tensor-product basis values for the six derivative combinations.

    bs (n, 3, p+1), bt (n, 3, q+1) -> (n, 6, (q+1)*(p+1)), index j*(p+1)+i (i along s).
    """
    n = bs.shape[0]
    out = np.empty((n, 6, bt.shape[2] * bs.shape[2]))
    for k, (ds, dt) in enumerate(DERIVS):
        out[:, k, :] = (bt[:, dt, :, None] * bs[:, ds, None, :]).reshape(n, -1)
    return out


class BezierCells:
    """Rational Bezier cells of one degree pair: ``ctrl`` (ncell, q+1, p+1, 4) homogeneous
    (w x, w y, w z, w), index [j, i] with i along the cell's first parameter a."""

    kind = "bezier"

    def __init__(self, ctrl: np.ndarray):
        self.ctrl = np.ascontiguousarray(ctrl, dtype=float)
        self.q = self.ctrl.shape[1] - 1
        self.p = self.ctrl.shape[2] - 1

    def __len__(self) -> int:
        return len(self.ctrl)

    def evaluate(self, idx: np.ndarray, a: np.ndarray, b: np.ndarray):
        bs = bernstein(self.p, a)                     # (n, 3, p+1)
        bt = bernstein(self.q, b)                     # (n, 3, q+1)
        C = self.ctrl[idx]                            # (n, q+1, p+1, 4)
        # contract along a first: T[n, da, j, c]
        T = np.einsum("nai,njic->najc", bs, C, optimize=False)
        H = np.empty((6, len(a), 4))
        for k, (ds, dt) in enumerate(DERIVS):
            H[k] = np.einsum("nj,njc->nc", bt[:, dt, :], T[:, ds], optimize=False)
        return H, None, None


# The eight symmetries of the unit square, as (A, o) with (s, t) = A (a, b) + o.
SQUARE_MAPS = []
for _swap in (False, True):
    for _fa in (False, True):
        for _fb in (False, True):
            A = np.array([[0.0, 1.0], [1.0, 0.0]]) if _swap else np.eye(2)
            A = A @ np.diag([-1.0 if _fa else 1.0, -1.0 if _fb else 1.0])
            o = np.array([1.0 if A[0].sum() < 0 else 0.0, 1.0 if A[1].sum() < 0 else 0.0])
            SQUARE_MAPS.append((A, o))
del _swap, _fa, _fb


def square_map_index(A: np.ndarray) -> int:
    for k, (B, _) in enumerate(SQUARE_MAPS):
        if np.array_equal(A, B):
            return k
    raise ValueError("not a symmetry of the square")


def _chain(Hst: np.ndarray, A: np.ndarray) -> np.ndarray:
    """Derivatives in (a, b) from derivatives in (s, t) = A (a, b) + o (A per point, (n,2,2))."""
    out = np.empty_like(Hst)
    out[0] = Hst[0]
    a00, a01, a10, a11 = (A[:, 0, 0, None], A[:, 0, 1, None], A[:, 1, 0, None], A[:, 1, 1, None])
    Hs, Ht, Hss, Hst_, Htt = Hst[1], Hst[2], Hst[3], Hst[4], Hst[5]
    out[1] = a00 * Hs + a10 * Ht                      # d/da = ds/da d/ds + dt/da d/dt
    out[2] = a01 * Hs + a11 * Ht
    out[3] = a00 * a00 * Hss + 2 * a00 * a10 * Hst_ + a10 * a10 * Htt
    out[4] = a00 * a01 * Hss + (a00 * a11 + a10 * a01) * Hst_ + a10 * a11 * Htt
    out[5] = a01 * a01 * Hss + 2 * a01 * a11 * Hst_ + a11 * a11 * Htt
    return out


class EigenCells:
    """Subdivision faces with one irregular corner, all of one configuration (one scheme).

    ``hat`` (ncell, K, 4): the cells' homogeneous control points projected on the scheme's
    eigenvectors (V^-1 C0). ``maps`` (ncell,) index of SQUARE_MAPS taking the cell's local
    (a, b) to the face frame (s, t) in which the irregular vertex sits at (0, 0).
    """

    kind = "eigen"
    EPS_LEVEL = 40       # derivatives at the irregular vertex itself are taken at (2^-40, 2^-40)

    def __init__(self, scheme, hat: np.ndarray, maps: np.ndarray):
        self.scheme = scheme
        self.hat = np.ascontiguousarray(hat, dtype=float)
        self.maps = np.asarray(maps, dtype=int)
        self.limit_normal = np.array([scheme.limit_normal(h) for h in self.hat]).reshape(-1, 3)

    def __len__(self) -> int:
        return len(self.hat)

    def evaluate(self, idx: np.ndarray, a: np.ndarray, b: np.ndarray):
        sch = self.scheme
        A = np.stack([SQUARE_MAPS[m][0] for m in range(8)])[self.maps[idx]]   # (n,2,2)
        o = np.stack([SQUARE_MAPS[m][1] for m in range(8)])[self.maps[idx]]   # (n,2)
        s = A[:, 0, 0] * a + A[:, 0, 1] * b + o[:, 0]
        t = A[:, 1, 0] * a + A[:, 1, 1] * b + o[:, 1]
        s = np.clip(s, 0.0, 1.0)
        t = np.clip(t, 0.0, 1.0)
        at_vertex = (s <= 0.0) & (t <= 0.0)
        eps = 2.0 ** -self.EPS_LEVEL
        s = np.where(at_vertex, eps, s)
        t = np.where(at_vertex, eps, t)
        m = np.maximum(s, t)
        _, e = np.frexp(m)
        level = np.maximum(1, 1 - e)                  # m in [2^-level, 2^(1-level))
        scale = np.ldexp(1.0, level - 1)
        s1, t1 = s * scale, t * scale                 # in [0,1]^2 minus [0,1/2)^2
        k = np.where(t1 < 0.5, 0, np.where(s1 >= 0.5, 1, 2))
        sh = np.where(k == 2, 2 * s1, 2 * s1 - 1)
        th = np.where(k == 0, 2 * t1, 2 * t1 - 1)
        basis = tensor_basis(uniform_cubic(sh), uniform_cubic(th))        # (n, 6, 16)
        n = len(a)
        coeff = np.empty((n, 6, sch.K))
        for kk in range(3):
            sel = np.nonzero(k == kk)[0]
            if len(sel):
                coeff[sel] = (basis[sel].reshape(-1, 16) @ sch.phi[kk]).reshape(len(sel), 6, sch.K)
        # powers of the eigenvalues and the 2^level scale of each derivative
        lam_pow = np.exp(np.multiply.outer(level - 1, sch.log_abs_lam)) * sch.sign_lam ** (level - 1)[:, None]
        lam_pow[:, sch.zero_lam] = np.where((level - 1)[:, None] == 0, 1.0, 0.0)
        coeff *= lam_pow[:, None, :]
        order = np.array([ds + dt for ds, dt in DERIVS])
        coeff *= np.ldexp(1.0, np.multiply.outer(level, order))[:, :, None]
        coeff[:, 1:, sch.dominant] = 0.0              # the limit point does not move
        H = np.einsum("ndk,nkc->dnc", coeff, self.hat[idx], optimize=False)
        H = _chain(H, A)
        ep_normal = None
        if at_vertex.any():
            H[0, at_vertex] = self.hat[idx[at_vertex], sch.dominant]
            ep_normal = np.zeros((n, 3))
            ep_normal[at_vertex] = self.limit_normal[idx[at_vertex]]
        return H, at_vertex, ep_normal
