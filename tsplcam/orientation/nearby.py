"""The workpiece's triangles near a few tool poses, as an fcl BVH of their own.

fcl answers a question about a tool placed somewhere from the triangles near it: a triangle
farther from the tool's solids than they reach (grown for the question) can neither touch them
nor be the nearest. So where fcl is asked about a few poses only (the keycap job asks it about
the smallest clearance's 10-20 closest poses and nothing else), a BVH over the triangles
within reach of those poses answers as the workpiece's whole BVH does, and costs a fraction
to build (the keycap: 38,482 triangles, the whole BVH 0.08 s; its smallest clearance's
questions take three BVHs of 842, 5,538 and 1,140 of them, 15 ms).

A question's reach is given as frustums about segments: each solid's axis and its radii at
both ends, held by its circumscribed polygons (the gouge check's ball: a segment of length 0),
grown by what the question asks about. The triangles are found from the broad phase's samples
(:class:`~tsplcam.orientation.broadphase.BroadPhase`): every point of a triangle lies within
``e = sqrt(e2)`` of one of the triangle's own samples (its corners and the points of its
subdivision), so a triangle that reaches into a frustum has a sample within ``e`` of it, which
lies within the widest radius plus ``e`` of the segment: balls along the segment find it, and of
what they find only the samples within ``e`` of the frustum itself are kept.

The last few BVHs are kept: a question whose triangles one of them holds is answered from it
(a BVH over more triangles than needed answers the same), else a BVH is built over its own.
Where the frustums are many, the triangles near them a large share of the workpiece's, or the
balls would meet too many samples, the caller takes the whole BVH instead
(:meth:`NearWorkpiece.obj` gives None).
"""
from __future__ import annotations

import itertools

import numpy as np

try:                                   # python-fcl: the orientation stage's dependency
    import fcl
except ImportError:                    # pragma: no cover - reported when a checker is built
    fcl = None

#: at most this many frustums per question (more: the whole BVH)
MAX_FRUSTUMS = 512
#: the triangles kept near the poses: at most this share of the workpiece's (more: the whole
#: BVH, which a build over that many would cost about as much as)
MAX_SHARE = 0.25
#: at most this many samples met in the balls that find a question's triangles, per triangle
#: of the workpiece (more: the whole BVH)
MAX_MET = 2.0
#: balls counted at a time (:meth:`NearWorkpiece.triangles`)
COUNT_ROWS = 64
#: BVHs kept for later questions (each over the triangles one question needed: a later one
#: within those is answered from it; growing one BVH for every new question built the
#: keycap's 5-6k triangles three times over)
KEEP = 4


class _Rows(np.ndarray):
    """Float64 rows whose ``astype`` is the row itself: python-fcl's ``addSubModel`` copies
    every vertex by ``astype(float64)`` before reading its three values (the keycap's 20k
    vertices: 14.7 -> 11.9 ms the call); the values read are the same."""

    def astype(self, dtype, *args, **kwargs):
        return self if np.dtype(dtype) == self.dtype else np.asarray(self).astype(dtype, *args, **kwargs)


def bvh_model(V: np.ndarray, T: np.ndarray):
    """fcl's BVH (OBBRSS) of the triangle mesh (V, T)."""
    m = fcl.BVHModel()
    m.beginModel(len(T), len(V))
    m.addSubModel(np.ascontiguousarray(V, float).view(_Rows), np.ascontiguousarray(T, np.int64))
    m.endModel()
    return m


class NearWorkpiece:
    """BVHs over the triangles of (V, T) near given frustums, from the broad phase ``broad``
    (its samples' tree, their triangles, its sample spacing)."""

    def __init__(self, V: np.ndarray, T: np.ndarray, broad):
        self.V, self.T, self.broad = V, T, broad
        self.kept = []                           # (triangle mask, fcl object), newest last
        self.builds = 0                          # BVHs built (for tests and benchmarks)

    def triangles(self, P0: np.ndarray, P1: np.ndarray, R0: np.ndarray, R1: np.ndarray) -> np.ndarray | None:
        """Mask of the triangles that may reach into the frustums about the segments P0-P1 of
        radii R0 at P0 and R1 at P1 (a superset: every triangle that does); None where finding
        them would cost about as much as the whole BVH (:data:`MAX_MET`)."""
        b = self.broad
        e = float(np.sqrt(b.e2))
        R0, R1 = np.asarray(R0, float), np.asarray(R1, float)
        Rc = np.maximum(R0, R1) + e
        D = P1 - P0
        L = np.sqrt(np.einsum("ij,ij->i", D, D))
        # balls along each segment, at most ``Rc`` apart: a point within Rc of the segment
        # lies within sqrt(Rc^2 + (s/2)^2) of the nearest ball's centre (s their spacing)
        cnt = np.ceil(L / np.maximum(Rc, 1e-9)).astype(np.int64) + 1
        seg = np.repeat(np.arange(len(P0)), cnt)
        first = np.repeat(np.cumsum(cnt) - cnt, cnt)
        t = (np.arange(len(seg)) - first) / np.maximum(cnt[seg] - 1, 1)
        X = P0[seg] + t[:, None] * D[seg]
        s = L[seg] / np.maximum(cnt[seg] - 1, 1)
        r = np.sqrt(Rc[seg] ** 2 + 0.25 * s * s) * (1.0 + 1e-9) + 1e-9
        # counted first (a tenth of the lists' time), a few balls at a time: the samples met in
        # the balls cost about a tenth of a triangle's share of the whole BVH each, so beyond
        # ``MAX_MET`` per triangle of the workpiece the whole BVH is built (keycap_mold's first
        # fcl batches of the search: its holders' wide balls meet 0.6-1.4 M samples, 0.06-0.14 s
        # to list, 4-13 ms to count all; the first 64 balls tell)
        met, most = 0, MAX_MET * len(self.T)
        for a in range(0, len(X), COUNT_ROWS):
            met += int(b.tree.ref.query_ball_point(X[a:a + COUNT_ROWS], r[a:a + COUNT_ROWS],
                                                   return_length=True).sum())
            if met > most:
                return None
        lists = b.tree.ref.query_ball_point(X, r, return_sorted=False)
        found = np.fromiter(map(len, lists), np.int64, len(lists))
        js = np.fromiter(itertools.chain.from_iterable(lists), np.int64, int(found.sum()))
        # only the samples within ``e`` of the frustum itself (the balls bulge past its ends and
        # its side, a holder's far beyond: the samples near it lie in the thin shell between the
        # solid and its growth): ``e`` along the axis past either end, and across it ``e`` beyond
        # the frustum's widest radius within ``e`` along the axis
        c = seg[np.repeat(np.arange(len(X)), found)]
        w = b.samples[js] - P0[c]
        Lc = L[c]
        z = np.einsum("ij,ij->i", w, D[c]) / np.maximum(Lc, 1e-300)     # along the axis
        rho2 = np.einsum("ij,ij->i", w, w) - z * z
        tol = 1e-9 * (1.0 + Rc[c] + Lc)
        lo = np.clip(z - e, 0.0, Lc) / np.maximum(Lc, 1e-300)
        hi = np.clip(z + e, 0.0, Lc) / np.maximum(Lc, 1e-300)
        r0, r1 = R0[c], R1[c]
        wide = np.maximum(r0 + (r1 - r0) * lo, r0 + (r1 - r0) * hi) + e + tol
        keep = (z >= -e - tol) & (z <= Lc + e + tol) & (rho2 <= wide * wide)
        js = np.unique(js[keep])
        out = np.zeros(len(self.T), bool)
        if len(js):
            out[b._triangles_of(js)[1]] = True
        return out

    def obj(self, P0: np.ndarray, P1: np.ndarray, R0: np.ndarray, R1: np.ndarray):
        """The fcl object of a BVH holding every triangle that reaches into the frustums
        (:meth:`triangles`), or None where they are more than :data:`MAX_FRUSTUMS` or their
        triangles with those kept more than :data:`MAX_SHARE` of the workpiece's."""
        if len(P0) > MAX_FRUSTUMS:
            return None
        want = self.triangles(np.asarray(P0, float).reshape(-1, 3), np.asarray(P1, float).reshape(-1, 3),
                              R0, R1)
        if want is None:
            return None
        for mask, obj in reversed(self.kept):
            if not (want & ~mask).any():
                return obj
        if want.sum() > MAX_SHARE * len(self.T):
            return None
        if not want.any():
            want[0] = True                       # (fcl's BVH holds a triangle: one far away)
        tri = self.T[want]
        vid, inv = np.unique(tri, return_inverse=True)
        obj = fcl.CollisionObject(bvh_model(self.V[vid], inv.reshape(-1, 3)), fcl.Transform())
        self.kept = self.kept[-(KEEP - 1):] + [(want, obj)]
        self.builds += 1
        return obj
