"""Cell evaluators: the pieces a patch is made of.

A patch's domain (the unit square) is cut into rectangular cells. A cell is either a
rational Bezier piece (any degree; T-spline and B-spline faces after Bezier extraction,
regular subdivision faces after the B-spline-to-Bezier change of basis) or an
extraordinary cell: a subdivision face with one irregular corner, evaluated exactly by
subdividing its neighbourhood to the level where the point lies in a regular sub-patch
(Stam 1998's tiling, with the local subdivision matrix computed numerically for the
configuration at hand, see ``eigen.py``).

Every evaluator takes cell indices and local parameters (a, b) in [0, 1]^2 and returns
homogeneous values and derivatives coordinate-major, shape (6, 4, n): H, H_a, H_b, H_aa,
H_ab, H_bb of (w x, w y, w z, w). Points of one cell given one after another are
evaluated with one BLAS product per cell (the patch sorts them so).
"""
from __future__ import annotations

import numpy as np

# numpy's C functions without their Python dispatch wrappers: the same calls, a few
# microseconds less each on the many small arrays here
from ..npfast import where as _where, c_einsum as _einsum, concatenate as _concatenate

from .basis import BSPLINE_TO_BEZIER, bernstein, bernstein_rows, uniform_cubic

# derivative combinations in output order: (order in first variable, order in second)
DERIVS = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
# weights this close to 1 are rounding of unit weights (Bezier extraction sums to 1 in floats)
WEIGHT_ONE_TOL = 1e-13


def tensor_basis(bs: np.ndarray, bt: np.ndarray) -> np.ndarray:
    """Tensor-product basis values for the six derivative combinations.

    bs (n, 3, p+1), bt (n, 3, q+1) -> (n, 6, (q+1)*(p+1)), index j*(p+1)+i (i along s).
    """
    n = bs.shape[0]
    out = np.empty((n, 6, bt.shape[2] * bs.shape[2]))
    for k, (ds, dt) in enumerate(DERIVS):
        out[:, k, :] = (bt[:, dt, :, None] * bs[:, ds, None, :]).reshape(n, -1)
    return out


# (order in b, order in a) of DERIVS, to pick them from a 3 x 3 table of both
_DT = np.array([dt for _, dt in DERIVS])
_DS = np.array([ds for ds, _ in DERIVS])
# ``nd``, the derivative rows an evaluation makes: 6 (all) or 3 (position and first
# derivatives: DERIVS[:3] reads orders 0 and 1 of either parameter, ``_ORDERS[nd]`` of them)
_ORDERS = {6: 3, 3: 2}
# BezierCells.evaluate multiplies out all six derivatives in one call up to this many points;
# above, where that product outgrows the caches and costs more than the calls it saves, one
# derivative at a time (the same products and sums either way)
_STACKED_POINTS = 256


def bicubic_nets(X: np.ndarray, a: np.ndarray, b: np.ndarray, B: np.ndarray | None = None,
                 nd: int = 6) -> np.ndarray:
    """Bicubic Bezier pieces, one per point: nets X (n, C, 4 [j along b], 4 [i along a]) at
    (a, b) -> the six derivatives (6, C, n). Two batched 4 x 4 products per point (along a
    for all three orders, then along b), whatever the pieces: for points spread over many
    small pieces (sub-cells next to extraordinary points), where runs of one piece are short.
    ``B``: ``bernstein_rows(3, [a, b])`` when the caller made it (a view of a wider array
    does: the products' operands are strided either way, the same loop, the same sums).
    ``nd`` 3: the first three derivatives alone, (3, C, n) (orders 0 and 1: the same products'
    loop on fewer columns, each value the same sum)."""
    n = len(a)
    no = _ORDERS[nd]
    if B is None:
        B = bernstein_rows(3, _concatenate([a, b]))       # (3 [order], 4, 2n)
    bs = B[:no, :, :n].transpose(2, 1, 0)[:, None]          # (n, 1, 4 [i], no [order in a])
    bt = B[:no, :, n:].transpose(2, 0, 1)[:, None]          # (n, 1, no [order in b], 4 [j])
    R = np.matmul(bt, np.matmul(X, bs))                     # (n, C, no [b], no [a])
    return R[:, :, _DT[:nd], _DS[:nd]].transpose(2, 1, 0)


def divide_widths(H: np.ndarray, wu, wv) -> np.ndarray:
    """In place: derivatives (nd, C, n) with respect to a cell's (a, b) taken with respect to
    the patch's (u, v) = (wu a, wv b) + offset: first derivatives divided by the cell's widths,
    second ones by their products (each divided once: the same bits wherever it is done)."""
    H[1] /= wu
    H[2] /= wv
    if len(H) > 3:
        H[3] /= wu * wu
        H[4] /= wu * wv
        H[5] /= wv * wv
    return H


def scale_derivatives(H: np.ndarray, sa, sb) -> np.ndarray:
    """In place: derivatives (6, C, n) with respect to (a, b) taken with respect to (a / sa,
    b / sb), i.e. first derivatives times sa or sb, second ones times their products."""
    H[1] *= sa
    H[2] *= sb
    if len(H) > 3:
        H[3] *= sa * sa
        H[4] *= sa * sb
        H[5] *= sb * sb
    return H


class BezierCells:
    """Rational Bezier cells of one degree pair: ``ctrl`` (ncell, q+1, p+1, 4) homogeneous
    (w x, w y, w z, w), index [j, i] with i along the cell's first parameter a."""

    kind = "bezier"

    def __init__(self, ctrl: np.ndarray):
        self.ctrl = np.array(ctrl, dtype=float)
        self.q = self.ctrl.shape[1] - 1
        self.p = self.ctrl.shape[2] - 1
        # Bezier extraction of unit weights leaves them 1 only to rounding (1 - 1e-16): such
        # cells are polynomial, and are evaluated so (with weights exactly 1)
        self.rational = bool(np.any(np.abs(self.ctrl[..., 3] - 1.0) > WEIGHT_ONE_TOL))
        if not self.rational:
            # dividing out the weight also removes the extraction's rounding that the
            # coordinates share with it
            self.ctrl[..., :3] /= self.ctrl[..., 3:]
            self.ctrl[..., 3] = 1.0
        # coordinates that vary: polynomial cells (all weights 1) skip w
        self.nc = 4 if self.rational else 3
        # Polynomial cells are evaluated relative to their first control point: the derivative
        # bases sum to zero only up to rounding, and that rounding would otherwise be multiplied
        # by the coordinates' distance from the origin (the rational form cancels it through W).
        rel = self.ctrl[..., :self.nc].copy()
        self._origin = np.zeros((len(self.ctrl), self.nc))
        if not self.rational:
            self._origin = self.ctrl[:, 0, 0, :3].copy()
            rel -= self._origin[:, None, None, :]
        self._origin_t = np.ascontiguousarray(self._origin.T)        # (nc, cell): gathered per point
        # per cell, the ((q+1)*nc) x (p+1) matrix of the contraction along a: [j*nc + c, i]
        self._cj = np.ascontiguousarray(rel.transpose(0, 1, 3, 2).reshape(len(self.ctrl), -1, self.p + 1))

    def __len__(self) -> int:
        return len(self.ctrl)

    def evaluate(self, idx: np.ndarray, a: np.ndarray, b: np.ndarray, out: np.ndarray | None = None,
                 bases=None, nd: int = 6):
        """The contraction along a is one BLAS product per run of equal cell index and
        derivative order; the one along b a short sum over contiguous rows, for all runs and
        derivatives at once (the same products and sums, in the same order, as run by run:
        the same values, with a few array calls per run instead of some fifty).

        ``out``: a (6, 4, n) view to write into (a block of the patch's array); ``bases``:
        (bernstein_rows(p, a), bernstein_rows(q, b)) when the caller made them together with
        other points' (the values are point by point); ``nd`` 3: the position and first
        derivatives alone, (3, 4, n) (the same products for them, two orders along a)."""
        n = len(a)
        q1, nc = self.q + 1, self.nc
        no = _ORDERS[nd]
        if bases is not None:
            bs, bt = bases
        elif self.p == self.q:                          # one call for both (values point by point)
            B = bernstein_rows(self.p, _concatenate([a, b]))
            bs, bt = B[:, :, :n], B[:, :, n:]           # (3, p+1, n), (3, q+1, n)
        else:
            bs = bernstein_rows(self.p, a)
            bt = bernstein_rows(self.q, b)
        cuts = (idx[1:] != idx[:-1]).nonzero()[0] + 1
        cuts = cuts.tolist()
        starts, ends = [0] + cuts, cuts + [n]
        # T[d][j, c, point]: contraction along a for derivative order d; the three orders of a
        # run in one stacked product (numpy makes the same BLAS call per order: gemv for a run
        # of one point, gemm otherwise), written into T
        T = np.empty((no, q1 * nc, n))
        for s0, e0 in zip(starts, ends):
            if e0 - s0 == 1:
                # a run of one point as a product with two columns (the point twice): numpy
                # hands a one-column product to gemv, which rounds otherwise than gemm, and a
                # point's values would depend on whether others share its cell in the call
                T[:, :, s0] = np.matmul(self._cj[idx[s0]], bs[:no, :, (s0, s0)])[:, :, 0]
            else:
                np.matmul(self._cj[idx[s0]], bs[:no, :, s0:e0], out=T[:, :, s0:e0])
        T = T.reshape(no, q1, nc, n)
        if out is None:
            out = np.empty((nd, 4, n))
        if nc == 3:
            out[0, 3] = 1.0
            out[1:, 3] = 0.0
        o = out[:, :nc]
        if n <= _STACKED_POINTS:
            # all six derivatives at once: the same products, summed in the same order over j
            prod = bt[_DT[:nd]][:, :, None, :] * T[_DS[:nd]]    # (nd, q+1, nc, n)
            if q1 == 1:
                o[...] = prod[:, 0]
            else:
                np.add(prod[:, 0], prod[:, 1], out=o)
                for j in range(2, q1):
                    o += prod[:, j]
        else:
            # one derivative at a time, its q+1 products in one call
            prod = np.empty((q1, nc, n))
            for k, (ds, dt) in enumerate(DERIVS[:nd]):
                np.multiply(bt[dt][:, None, :], T[ds], out=prod)
                if q1 == 1:
                    o[k] = prod[0]
                    continue
                np.add(prod[0], prod[1], out=o[k])
                for j in range(2, q1):
                    o[k] += prod[j]
        out[0, :nc] += self._origin_t.take(idx, axis=1)
        return out, None, None

    def evaluate_tensor(self, cell: int, a: np.ndarray, b: np.ndarray, wa: float = 1.0,
                        wb: float = 1.0, out: np.ndarray | None = None) -> np.ndarray:
        """One cell on the tensor grid a x b: derivatives (6, nc, len(a), len(b)) taken with
        respect to a / wa and b / wb (the cell's widths in its patch); nc = 3 Euclidean
        coordinates for polynomial cells, 4 homogeneous ones (w x, w y, w z, w) for rational.

        Both contractions are BLAS products and the second one writes straight into ``out``
        (any view of that shape whose rows are contiguous, e.g. a block of the patch's grid),
        so a grid costs little more than writing its result. An ``out`` of 3 rows (or fewer)
        takes the position and first derivatives alone: the same products for them."""
        nc, p1, q1 = self.nc, self.p + 1, self.q + 1
        na, nb = len(a), len(b)
        bs = bernstein(self.p, a)                        # (na, 3, p+1)
        bt = bernstein(self.q, b)                        # (nb, 3, q+1)
        bs[:, 1] /= wa
        bs[:, 2] /= wa * wa
        bt[:, 1] /= wb
        bt[:, 2] /= wb * wb
        # along a, all three orders at once: T[d, c, i, j] = sum_k ctrl[j, k, c] bs[i, d, k]
        T = (self._cj[cell] @ bs.reshape(-1, p1).T).reshape(q1, nc, na, 3)
        T = np.ascontiguousarray(T.transpose(3, 1, 2, 0))            # (3, nc, na, q+1)
        btT = np.ascontiguousarray(bt.transpose(1, 2, 0))             # (3, q+1, nb)
        if out is None:
            out = np.empty((6, nc, na, nb))
        for k, (ds, dt) in enumerate(DERIVS[:len(out)]):
            np.matmul(T[ds], btT[dt], out=out[k])                     # (nc, na, nb)
        out[0] += self._origin[cell][:, None, None]
        return out

    @staticmethod
    def tensor_bases(values: np.ndarray, width: float = 1.0):
        """The bases :meth:`evaluate_tensor` makes along one parameter from its Bernstein values
        and derivatives ``values`` (n, 3, degree+1) (``basis.bernstein``; a grid's whole row or
        column of cells in one call, since they are made point by point) and the cell's width:
        (scaled to the width, (3 n, degree+1) transposed as the contraction along a takes them;
        (3, degree+1, n) as the one along b does)."""
        bs = values.copy()
        bs[:, 1] /= width
        bs[:, 2] /= width * width
        return bs.reshape(-1, bs.shape[2]).T, np.ascontiguousarray(bs.transpose(1, 2, 0))

    def tensor_positions(self, cell: int, a_basis, b_basis, out: np.ndarray) -> np.ndarray:
        """The positions alone (``out[0]`` of :meth:`evaluate_tensor`) of a polynomial cell on
        a tensor grid, into ``out`` ((3, na, nb), rows contiguous), from the bases
        :meth:`tensor_bases` gives for its a and b: the same BLAS products on the same arrays
        for them, so the same values bit for bit, without the five derivative products (a
        tessellation needs only the points)."""
        if self.rational:
            raise ValueError("tensor_positions is for polynomial cells (weights 1)")
        nc, q1 = self.nc, self.q + 1
        bsT, btT = a_basis, b_basis
        na = bsT.shape[1] // 3
        T = (self._cj[cell] @ bsT).reshape(q1, nc, na, 3)
        T0 = np.ascontiguousarray(T.transpose(3, 1, 2, 0)[0])        # (nc, na, q+1)
        np.matmul(T0, btT[0], out=out)
        out += self._origin[cell][:, None, None]
        return out


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



def _chain(Hst: np.ndarray, A: np.ndarray) -> np.ndarray:
    """Derivatives in (a, b) from derivatives in (s, t) = A (a, b) + o; Hst is (6, C, n),
    A per point (n, 2, 2)."""
    out = np.empty_like(Hst)
    out[0] = Hst[0]
    a00, a01, a10, a11 = A[:, 0, 0], A[:, 0, 1], A[:, 1, 0], A[:, 1, 1]
    Hs, Ht, Hss, Hst_, Htt = Hst[1], Hst[2], Hst[3], Hst[4], Hst[5]
    out[1] = a00 * Hs + a10 * Ht                      # d/da = ds/da d/ds + dt/da d/dt
    out[2] = a01 * Hs + a11 * Ht
    out[3] = a00 * a00 * Hss + 2 * a00 * a10 * Hst_ + a10 * a10 * Htt
    out[4] = a00 * a01 * Hss + (a00 * a11 + a10 * a01) * Hst_ + a10 * a11 * Htt
    out[5] = a01 * a01 * Hss + 2 * a01 * a11 * Hst_ + a11 * a11 * Htt
    return out


def _ring_coordinates(maps: np.ndarray, a: np.ndarray, b: np.ndarray, eps_level: int, max_level: int):
    """Where (a, b) falls in Stam's tiling of a face with its irregular vertex at (0, 0).

    Returns the per-point map matrices A, the vertex mask, the level n (point in
    [0, 2^(1-n)]^2 minus [0, 2^-n]^2), the sub-patch k (0: s' >= 1/2, t' < 1/2; 1: both
    >= 1/2; 2: s' < 1/2, t' >= 1/2) and the sub-patch's own parameters."""
    A = _MAP_A[maps]
    o = _MAP_O[maps]
    s = np.clip(A[:, 0, 0] * a + A[:, 0, 1] * b + o[:, 0], 0.0, 1.0)
    t = np.clip(A[:, 1, 0] * a + A[:, 1, 1] * b + o[:, 1], 0.0, 1.0)
    at_vertex = (s <= 0.0) & (t <= 0.0)
    eps = 2.0 ** -eps_level
    s = _where(at_vertex, eps, s)
    t = _where(at_vertex, eps, t)
    _, e = np.frexp(np.maximum(s, t))
    level = np.clip(1 - e, 1, max_level)
    scale = np.ldexp(1.0, level - 1)
    s1, t1 = np.minimum(s * scale, 1.0), np.minimum(t * scale, 1.0)
    k = _where(t1 < 0.5, 0, _where(s1 >= 0.5, 1, 2))
    sh = np.clip(_where(k == 2, 2 * s1, 2 * s1 - 1), 0.0, 1.0)
    th = np.clip(_where(k == 0, 2 * t1, 2 * t1 - 1), 0.0, 1.0)
    return A, at_vertex, level, k, sh, th


_MAP_A = np.stack([m[0] for m in SQUARE_MAPS])
_MAP_O = np.stack([m[1] for m in SQUARE_MAPS])
_ORDER = np.array([ds + dt for ds, dt in DERIVS])


def _subpatch_coefficients(mats: np.ndarray, k: np.ndarray, sh: np.ndarray, th: np.ndarray) -> np.ndarray:
    """b(s', t')^T M_k for every point: basis of the six derivatives times one of three
    (16, K) matrices, (n, 6, K)."""
    basis = tensor_basis(uniform_cubic(sh), uniform_cubic(th))        # (n, 6, 16)
    coeff = np.empty((len(k), 6, mats.shape[2]))
    for kk in range(3):
        sel = np.nonzero(k == kk)[0]
        if len(sel):
            coeff[sel] = (basis[sel].reshape(-1, 16) @ mats[kk]).reshape(len(sel), 6, -1)
    return coeff


def _per_cell_product(coeff: np.ndarray, key: np.ndarray, mats: np.ndarray) -> np.ndarray:
    """out[:, :, i] = coeff[i] @ mats[key[i]] for (n, 6, K) coefficients and (*, K, 4) matrices,
    as one BLAS product per run of equal keys (sorted first), coordinate-major (6, 4, n)."""
    n, nd, K = coeff.shape
    order = np.argsort(key, kind="stable")
    skey = key[order]
    cuts = np.flatnonzero(skey[1:] != skey[:-1]) + 1
    out = np.empty((n, nd, mats.shape[2]))
    for s0, e0 in zip(_concatenate([[0], cuts]).tolist(), _concatenate([cuts, [n]]).tolist()):
        rows = order[s0:e0]
        out[rows] = (coeff[rows].reshape(-1, K) @ mats[skey[s0]]).reshape(e0 - s0, nd, -1)
    return out.transpose(1, 2, 0)


class LevelCells:
    """Subdivision faces with one irregular corner, all of one configuration (one scheme),
    evaluated by subdividing to the regular level: the control points of every level are
    precomputed per cell as d_m = A^m (C0 - L) (``SubdivisionScheme.levels``), and a point
    at level n is the regular sub-patch k of level n, b(s', t')^T S_k (d_(n-1) + L). Iterating
    on the difference from the limit point L keeps full relative precision at every level;
    unlike powers of an eigenbasis (Stam 1998), it needs no eigenvectors (none exist where A
    is defective, as at some boundary vertices, and they are ill-conditioned near such
    configurations). Below 2^-MAX_LEVEL the point is the limit point. The sub-patches of the
    first NET_LEVELS levels are kept as Bezier nets (``_cache_nets``), so that most points cost
    one gather and one bicubic evaluation; ``evaluate_levels`` is the configuration route.

    ``C0`` (ncell, K, 4): the cells' homogeneous control points in configuration order;
    ``maps`` (ncell,) index of SQUARE_MAPS taking the cell's local (a, b) to the face frame
    (s, t) in which the irregular vertex sits at (0, 0)."""

    kind = "levels"
    EPS_LEVEL = 50
    MAX_LEVEL = 60
    # levels whose sub-patches are kept as Bezier nets (points within 2^-NET_LEVELS of a
    # cell's width from the irregular vertex go through the configuration of their level)
    NET_LEVELS = 24

    def __init__(self, scheme, C0: np.ndarray, maps: np.ndarray):
        self.scheme = scheme
        self.maps = np.asarray(maps, dtype=int)
        pairs = [scheme.levels(c, self.MAX_LEVEL) for c in C0]
        self.limit = np.array([L for L, _ in pairs])                # (ncell, 4)
        self.d = np.array([d for _, d in pairs])                    # (ncell, M, K, 4)
        self.limit_normal = np.array([scheme.limit_normal(c) for c in C0]).reshape(-1, 3)
        self._cache_nets()

    def __len__(self) -> int:
        return len(self.d)

    def _cache_nets(self):
        """The Bezier nets of every regular sub-patch of levels 1 .. NET_LEVELS, in each cell's
        own (a, b) frame: nets[(cell * NET_LEVELS + level - 1) * 3 + key] (4, 4 [j along b],
        4 [i along a], homogeneous differences from the limit), key = pa + 2 qa - 1 for the
        sub-cell (pa, qa) in {(1, 0), (0, 1), (1, 1)} counted from the irregular corner in
        units of the level's width 2^-level. A point is then one gather and one Bezier
        evaluation (``bicubic_nets``), as in a plain Bezier cell. The values at the irregular
        vertex itself (``_vertex``, (6, 4, cell)) are the same for every point there.

        Per cell: the irregular corner (ca, cb) in (a, b) (``_corner``, (2, cell)), and whether
        the face frame (s, t) swaps a and b (``_swap``: the sub-patch a point past the deepest
        level is clamped to is named in the face frame)."""
        ncell = len(self.d)
        ncoord = self.d.shape[-1]
        # B-spline sub-patch stencils -> Bezier nets of the same sub-patches: (3, 16, K)
        Sb = _einsum("ab,kbK->kaK", np.kron(BSPLINE_TO_BEZIER, BSPLINE_TO_BEZIER), self.scheme.S)
        face = _einsum("kaK,cmKx->cmkxa", Sb, self.d[:, :self.NET_LEVELS])   # (cell, level, k, x, 16)
        face = face.reshape(ncell, -1, 3, ncoord, 4, 4)                  # [.., t index, s index]
        nets = np.empty((ncell, face.shape[1], 3, ncoord, 4, 4))
        frame = np.zeros((ncell, 3), dtype=int)
        grid = np.stack(np.meshgrid(np.arange(4), np.arange(4), indexing="xy"), axis=-1)  # [j, i] -> (i, j)
        for c, m in enumerate(self.maps):
            A, o = SQUARE_MAPS[m]
            st = np.rint(grid @ A.T + 3 * o).astype(int)       # net index (I, J) in the face frame
            corner = np.rint(-A.T @ o).astype(int)              # where (s, t) = (0, 0)
            swap = bool(abs(A[0, 1]) > 0.5)
            frame[c] = (corner[0], corner[1], swap)
            for pa, qa in ((1, 0), (0, 1), (1, 1)):
                ps, qs = (qa, pa) if swap else (pa, qa)
                k = {(1, 0): 0, (1, 1): 1, (0, 1): 2}[(ps, qs)]   # Stam's sub-patch order
                nets[c, :, pa + 2 * qa - 1] = face[c, :, k][..., st[..., 1], st[..., 0]]
        self.nets = np.ascontiguousarray(nets.reshape(-1, ncoord, 4, 4))
        self._corner = np.ascontiguousarray(frame[:, :2].T, dtype=float)     # (2, cell)
        self._swap = frame[:, 2].astype(bool)
        self._vertex = self._evaluate(np.arange(ncell), self._corner[0], self._corner[1])[0]

    def _evaluate(self, idx, a, b):
        A, at_vertex, level, k, sh, th = _ring_coordinates(self.maps[idx], a, b, self.EPS_LEVEL,
                                                           self.MAX_LEVEL)
        coeff = _subpatch_coefficients(self.scheme.S, k, sh, th)
        coeff *= np.ldexp(1.0, np.multiply.outer(level, _ORDER))[:, :, None]
        M = self.MAX_LEVEL
        H = _per_cell_product(coeff, idx * M + (level - 1), self.d.reshape(-1, *self.d.shape[2:]))
        H[0] += self.limit[idx].T
        H = _chain(H, A)
        if at_vertex.any():
            H[0][:, at_vertex] = self.limit[idx[at_vertex]].T
        return H, at_vertex, level

    def _evaluate_nets(self, idx, a, b, out=None, B=None):
        """As ``_evaluate`` from the cached nets (``_cache_nets``); ``deep`` marks the points
        below level NET_LEVELS, which it leaves unset. ``out``, ``B``: as for
        :meth:`_net_values`."""
        return self._net_values(idx, self._net_params(idx, a, b), out, B)

    def _net_params(self, idx, a, b):
        """The first half of :meth:`_evaluate_nets`: where the points fall among the cached
        nets, (E, key, scale, at_vertex, deep) with E (2, n) the sub-cells' own (a, b). Both
        parameters as one (2, n) array: half the array calls (batches are often a hundred
        points)."""
        n = len(a)
        corner = self._corner[:, idx]                   # (2, n)
        E = np.empty((2, n))
        E[0], E[1] = a, b
        np.maximum(E, 0.0, out=E)                       # in the cell, as _ring_coordinates
        np.minimum(E, 1.0, out=E)
        E -= corner
        np.abs(E, out=E)                                # distances from the irregular corner
        mx = np.maximum(E[0], E[1])
        at_vertex = mx <= 0.0
        _, e = np.frexp(mx)
        level = np.minimum(np.maximum(1 - e, 1), self.MAX_LEVEL)
        # (at the vertex mx is 0, e 0 and the level 1: never deep)
        deep = level > self.NET_LEVELS
        scale = np.ldexp(1.0, level)
        E *= scale
        pq = E >= 1.0                                   # the sub-cell (pa, qa) of the level
        # below the deepest level: the sub-patch (1, 0) of the face frame, as _ring_coordinates
        low = ~(pq[0] | pq[1])
        if low.any():
            swap = self._swap[idx]
            pq[0] |= low & ~swap
            pq[1] |= low & swap
        E -= pq
        np.maximum(E, 0.0, out=E)
        np.minimum(E, 1.0, out=E)
        E -= corner                                     # the sub-cell's own (a, b): |corner - E|
        np.abs(E, out=E)
        key = (idx * self.NET_LEVELS + np.minimum(level, self.NET_LEVELS) - 1) * 3 + pq[0] + 2 * pq[1] - 1
        return E, key, scale, at_vertex, deep

    def _nets_xyz(self) -> np.ndarray:
        """The nets' x, y, z rows alone, contiguous (made once per nets array): what a
        polynomial patch reads of them (their weight rows are 0 there)."""
        cached = getattr(self, "_xyz", None)
        if cached is None or cached[0] is not self.nets:
            cached = self._xyz = (self.nets, np.ascontiguousarray(self.nets[:, :3]))
        return cached[1]

    def _net_values(self, idx, params, out=None, B=None, nd: int = 6, nc: int = 4):
        """The second half of :meth:`_evaluate_nets`: (H, at_vertex, deep) from the
        parameters of :meth:`_net_params`. ``out``: a (6, 4, n) view to write H into;
        ``B``: ``bernstein_rows(3, [E[0], E[1]])`` made by the caller (with other points');
        ``nd``: 6 derivative rows or the first 3 (``bicubic_nets``); ``nc`` 3: for a
        polynomial patch, which reads no weight row: the x, y, z rows alone from the nets
        (each coordinate its own products: the same values), the weight rows written 1 and 0
        (as polynomial Bezier cells write them)."""
        E, key, scale, at_vertex, deep = params
        nets = self.nets if nc == 4 else LevelCells._nets_xyz(self)
        R = bicubic_nets(nets[key], E[0], E[1], B, nd)
        if out is None and nc == 4:
            H = scale_derivatives(R, scale, scale)
            H[0] += self.limit[idx].T
        else:
            # scale_derivatives and the limit's sum written into out as they read R (the same
            # products and sums, one pass instead of a copy and six)
            H = np.empty((nd, 4, len(idx))) if out is None else out
            np.add(R[0], self.limit[idx].T[:nc], out=H[0, :nc])
            np.multiply(R[1], scale, out=H[1, :nc])
            np.multiply(R[2], scale, out=H[2, :nc])
            if nd > 3:
                ss = scale * scale
                np.multiply(R[3], ss, out=H[3, :nc])
                np.multiply(R[4], ss, out=H[4, :nc])
                np.multiply(R[5], ss, out=H[5, :nc])
            if nc == 3:
                H[0, 3] = 1.0
                H[1:, 3] = 0.0
        if at_vertex.any():
            H[:, :, at_vertex] = self._vertex[:nd, :, idx[at_vertex]]
        return H, at_vertex, deep

    def evaluate(self, idx: np.ndarray, a: np.ndarray, b: np.ndarray, out=None, nd: int = 6, nc: int = 4):
        """From the cached nets; the few points below level NET_LEVELS through the
        configuration of their level. ``out``: a (nd, 4, n) view to write into; ``nd`` 3:
        the position and first derivatives alone; ``nc``: as for ``_net_values``."""
        return self.finish(self.prepare(idx, a, b), out, nd=nd, nc=nc)

    def prepare(self, idx, a, b):
        """:meth:`evaluate` in two halves, so that a patch makes the Bernstein values of the
        sub-cells' parameters together with its Bezier cells' (``finish`` takes them)."""
        return idx, a, b, LevelCells._net_params(self, idx, a, b)

    def finish(self, prepared, out=None, B=None, nd: int = 6, nc: int = 4):
        idx, a, b, params = prepared
        H, at_vertex, deep = LevelCells._net_values(self, idx, params, out, B, nd, nc)
        if deep.any():
            H[:, :, deep] = self._evaluate(idx[deep], a[deep], b[deep])[0][:nd]
        return H, at_vertex, self._ep_normal(idx, at_vertex)

    def evaluate_levels(self, idx: np.ndarray, a: np.ndarray, b: np.ndarray):
        """As ``evaluate``, every point from the configuration of its level (the reference
        the cached nets are tested against)."""
        H, at_vertex, _ = self._evaluate(idx, a, b)
        return H, at_vertex, self._ep_normal(idx, at_vertex)

    def _ep_normal(self, idx, at_vertex):
        if not at_vertex.any():
            return None
        ep_normal = np.zeros((len(idx), 3))
        ep_normal[at_vertex] = self.limit_normal[idx[at_vertex]]
        return ep_normal
