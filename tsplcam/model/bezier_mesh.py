"""Rational Bezier elements (a T-spline's Bezier extraction, ``.iga``) grouped into patches.

A Bezier extraction file lists elements, not a T-mesh: which elements meet, where the
T-junctions and the extraordinary points are, is recovered here from the geometry.

1. **Bezier mesh.** Element corners (the corner control points) are merged within a
   tolerance (``TOL_REL`` times the model's size) into vertices. A vertex that lies inside
   another element's side (closest point on the rational side curve within the tolerance)
   is a T-junction there; it splits that side into segments. Two element sides sharing a
   segment are neighbours; a segment with one element is on the open boundary. Elements
   with the same corners and centre as an earlier one are duplicates and dropped.
2. **Vertices.** Around an interior vertex the elements cover 90 degrees per corner and
   180 per side passing through (in the parameter plane): four corners is regular, two
   corners and a side a T-junction, any other corner count an extraordinary point (EP) of
   that valence. A boundary vertex with two corners is regular, otherwise a patch corner
   (valence 1) or a boundary EP (valence 3 and more).
3. **Patch boundaries** (shang2020 section 2.2, traced by ``decompose.trace_lines``): lines from
   every EP and boundary corner, straight through regular vertices and along the bar of
   T-junctions, to the next such point or the boundary. A line that reaches a T-junction
   by its stem continues straight through the element across (which is split there
   exactly by Bezier subdivision), so that every patch is a rectangle with whole-edge
   neighbours. Closed regions with no point to start from are cut at a seed vertex.
4. **Patch parameters.** Between the lines, elements form rectangles: each element gets
   an orientation in the patch (one of the eight symmetries of the square) and its sides'
   vertical / horizontal lines become unknown coordinates. The file carries no knot
   intervals, so they are chosen: a T-junction at parameter tau of an element's side sits
   at tau of that side's patch interval (exact constraint: it keeps the patch's
   parametrisation continuous); across every shared edge the two elements' widths
   transverse to it are in the ratio of the surface's transverse derivatives there,
   w_e / w_f = |dP/ds_e| / |dP/ds_f| (least squares), which makes the patch
   parametrisation C1 wherever the T-spline is (it recovers the true knot intervals up
   to scale) and as smooth as possible elsewhere. Each patch's ``knot_size`` comes from
   the same ratios across patch boundaries, in units of a mean knot interval of 1. The
   surface is exactly the file's either way: only the parametrisation is chosen.
5. **Cells.** A patch's cell grid is the union of its elements' lines; an element that
   spans several grid cells is cut into exact sub-elements (Bezier subdivision), one per
   cell, grouped by degree into ``BezierCells``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from .basis import bernstein, to_bernstein
from .cells import BezierCells
from .components import components, groups, merge_points
from .decompose import region_frames, trace_lines
from .diffgeom import rational_from_homogeneous
from .model import ExtraordinaryPoint, Model
from .patch import EdgeNeighbour, Patch

TOL_REL = 1e-7          # points closer than this times the model's size are one point
EP_WEIGHT = 1e-3        # weight of width-ratio rows at elements touching an extraordinary point
_SAMPLES = 33           # samples per side curve to start the closest-point search


# -- data -------------------------------------------------------------------------------
@dataclass
class Piece:
    """An element, or a part of one cut along a patch boundary: homogeneous control points
    (q+1, p+1, 4) [j, i] (i along s), its element and its box (s0, s1, t0, t1) there."""
    ctrl: np.ndarray
    element: int
    box: tuple = (0.0, 1.0, 0.0, 1.0)


@dataclass
class ElementPlace:
    """Where a piece of element ``element`` (its (s, t) box ``box``) sits: patch ``patch``,
    rectangle ``uv`` = (u0, u1, v0, v1); ``swap``: the element's s runs along v;
    ``flip_u`` / ``flip_v``: u / v decrease along the element parameter that runs there."""
    element: int
    box: tuple
    patch: int
    uv: tuple
    swap: bool
    flip_u: bool
    flip_v: bool

    def contains(self, s, t) -> np.ndarray:
        s0, s1, t0, t1 = self.box
        s, t = np.asarray(s, float), np.asarray(t, float)
        return (s >= s0 - 1e-12) & (s <= s1 + 1e-12) & (t >= t0 - 1e-12) & (t <= t1 + 1e-12)

    def uv_of(self, s, t) -> tuple[np.ndarray, np.ndarray]:
        """Patch (u, v) of the element's (s, t) (inside ``box``)."""
        s0, s1, t0, t1 = self.box
        a = (np.asarray(s, float) - s0) / (s1 - s0)
        b = (np.asarray(t, float) - t0) / (t1 - t0)
        x, y = (b, a) if self.swap else (a, b)
        if self.flip_u:
            x = 1.0 - x
        if self.flip_v:
            y = 1.0 - y
        u0, u1, v0, v1 = self.uv
        return u0 + x * (u1 - u0), v0 + y * (v1 - v0)


@dataclass
class MeshInfo:
    """What the recovery found, for people and tests."""
    vertices: np.ndarray                       # (n, 3) merged element corners
    t_junctions: list = field(default_factory=list)     # vertex ids
    duplicates: list = field(default_factory=list)      # (dropped element, kept element)
    splits: int = 0                            # element cuts along patch boundaries
    seeds: list = field(default_factory=list)  # points where closed regions were cut
    ratio_rms: float = 0.0                     # rms log width-ratio misfit away from EPs (0 = C1)


# -- geometry helpers -------------------------------------------------------------------
def _euclid(H: np.ndarray) -> np.ndarray:
    return H[..., :3] / H[..., 3:4]


def side_control(Q: np.ndarray, m: int) -> np.ndarray:
    """Homogeneous control points of side m of a net Q [j, i], from corner m to corner m+1
    (corners (0,0), (1,0), (1,1), (0,1) in (s, t); side 0 t=0, 1 s=1, 2 t=1, 3 s=0)."""
    if m == 0:
        return Q[0, :]
    if m == 1:
        return Q[:, -1]
    if m == 2:
        return Q[-1, ::-1]
    return Q[::-1, 0]


def side_st(m: int, tau):
    """Element (s, t) of the point at fraction tau along side m."""
    tau = np.asarray(tau, float)
    one, zero = np.ones_like(tau), np.zeros_like(tau)
    return [(tau, zero), (one, tau), (1 - tau, one), (zero, 1 - tau)][m]


def _curve(H: np.ndarray, tau: np.ndarray):
    """Point, first and second derivative of rational curves H (n, d+1, 4) at tau (n,)."""
    d = H.shape[1] - 1
    B = bernstein(d, tau, 2)                               # (n, 3, d+1)
    h = np.einsum("nki,nic->knc", B, H)
    w = h[..., 3:4]
    C = h[0, :, :3] / w[0]
    C1 = (h[1, :, :3] - w[1] * C) / w[0]
    C2 = (h[2, :, :3] - 2.0 * w[1] * C1 - w[2] * C) / w[0]
    return C, C1, C2


def _sub_matrix(p: int, a: float, b: float) -> np.ndarray:
    """M with (Bernstein coefficients on [a, b]) = M @ (coefficients on [0, 1]), degree p."""
    x = a + (b - a) * np.linspace(0.0, 1.0, p + 1)
    return to_bernstein(p, bernstein(p, x, 0)[:, 0, :])


def sub_net(Q: np.ndarray, box) -> np.ndarray:
    """Control net of the restriction of Bezier net Q [j, i] to (s0, s1, t0, t1) (exact)."""
    s0, s1, t0, t1 = box
    q, p = Q.shape[0] - 1, Q.shape[1] - 1
    if (s0, s1, t0, t1) == (0.0, 1.0, 0.0, 1.0):   # exact, a shortcut: any other box is exact too
        return Q.copy()
    return np.einsum("ja,ib,abc->jic", _sub_matrix(q, t0, t1), _sub_matrix(p, s0, s1), Q)


class _Elements:
    """Evaluation of pieces at their own (s, t), grouped by degree."""

    def __init__(self, pieces: list[Piece]):
        keys = sorted({p.ctrl.shape for p in pieces})
        self.gid = np.array([keys.index(p.ctrl.shape) for p in pieces], int)
        self.local = np.zeros(len(pieces), int)
        self.cells = []
        for g in range(len(keys)):
            members = np.nonzero(self.gid == g)[0]
            self.local[members] = np.arange(len(members))
            self.cells.append(BezierCells(np.array([pieces[e].ctrl for e in members])))

    def evaluate(self, e, s, t):
        """P, Ps, Pt (n, 3) of pieces e at their own (s, t)."""
        e = np.asarray(e, int)
        s, t = np.broadcast_to(np.asarray(s, float), e.shape), np.broadcast_to(np.asarray(t, float), e.shape)
        out = np.empty((3, len(e), 3))
        for g, cells in enumerate(self.cells):
            sel = np.nonzero(self.gid[e] == g)[0]
            if len(sel) == 0:
                continue
            order = sel[np.argsort(self.local[e[sel]], kind="stable")]
            H, _, _ = cells.evaluate(self.local[e[order]], s[order], t[order])
            S = rational_from_homogeneous(H)
            for d in range(3):
                out[d, order] = S[d].T
        return out[0], out[1], out[2]


def _key(a: int, b: int) -> tuple[int, int]:
    return (a, b) if a < b else (b, a)


# -- the Bezier mesh --------------------------------------------------------------------
class _Mesh:
    """Vertices, T-junctions, shared segments and vertex kinds of a list of pieces."""

    def __init__(self, pieces: list[Piece], tol: float, where):
        self.pieces = pieces
        self.tol = tol
        self.where = where                      # piece -> (text, line) for messages
        n = len(pieces)
        corners = np.array([[_euclid(side_control(p.ctrl, m)[0]) for m in range(4)] for p in pieces])
        ids, self.vpos = merge_points(corners.reshape(-1, 3), tol)
        self.corners = ids.reshape(n, 4)
        for e in range(n):
            if len(set(self.corners[e].tolist())) < 4:
                raise self.error(e, "two of its corners are one point (a collapsed side): degenerate "
                                    "elements are not supported")
        self._sides()
        self._t_junctions()
        self._segments()
        self._check_shared_parametrisation()
        self._classify()

    def error(self, e: int, message: str) -> InputError:
        text, path, line = self.where(e)
        return InputError(f"{text}: {message}", path=path, line=line)

    def point_text(self, v: int) -> str:
        return "(" + ", ".join(f"{x:.6g}" for x in self.vpos[v]) + ")"

    # sides as rational curves, grouped by degree
    def _sides(self):
        self.side_deg = np.array([[p.ctrl.shape[1] - 1, p.ctrl.shape[0] - 1] * 2 for p in self.pieces],
                                 int).reshape(-1)            # side id 4 e + m
        self.side_groups = {}
        for d in np.unique(self.side_deg):
            sids = np.nonzero(self.side_deg == d)[0]
            H = np.array([side_control(self.pieces[s // 4].ctrl, s % 4) for s in sids])
            self.side_groups[int(d)] = (sids, H)
        self.side_row = np.zeros(len(self.side_deg), int)
        for d, (sids, _) in self.side_groups.items():
            self.side_row[sids] = np.arange(len(sids))

    def side_points(self, sids, tau, nderiv: bool = False):
        """Points (and first, second derivatives) of sides ``sids`` at ``tau``."""
        sids = np.asarray(sids, int)
        tau = np.asarray(tau, float)
        out = np.empty((3, len(sids), 3))
        for d, (_, H) in self.side_groups.items():
            sel = np.nonzero(self.side_deg[sids] == d)[0]
            if len(sel):
                C = _curve(H[self.side_row[sids[sel]]], tau[sel])
                for k in range(3):
                    out[k, sel] = C[k]
        return out if nderiv else out[0]

    def _t_junctions(self):
        """Vertices inside element sides: closest point on the rational side within tol."""
        n = len(self.pieces)
        tree = cKDTree(self.vpos)
        found = [[[] for _ in range(4)] for _ in range(n)]
        tg = np.linspace(0.0, 1.0, _SAMPLES)
        for d, (sids, H) in self.side_groups.items():
            E = _euclid(H)
            lo, hi = E.min(axis=1), E.max(axis=1)
            lists = tree.query_ball_point((lo + hi) / 2, np.linalg.norm(hi - lo, axis=1) / 2 + self.tol)
            cs, cv = [], []
            for r, lst in enumerate(lists):
                e, m = divmod(int(sids[r]), 4)
                ends = (self.corners[e, m], self.corners[e, (m + 1) % 4])
                for v in lst:
                    if v != ends[0] and v != ends[1]:
                        cs.append(r)
                        cv.append(v)
            if not cs:
                continue
            cs, cv = np.array(cs), np.array(cv)
            ns = len(sids)
            G = _curve(np.repeat(H, _SAMPLES, axis=0), np.tile(tg, ns))[0].reshape(ns, _SAMPLES, 3)
            X = self.vpos[cv]
            tau = tg[np.argmin(((G[cs] - X[:, None, :]) ** 2).sum(-1), axis=1)]
            Hc = H[cs]
            for _ in range(12):
                C, C1, C2 = _curve(Hc, tau)
                r_ = C - X
                g = np.einsum("ij,ij->i", r_, C1)
                gp = np.einsum("ij,ij->i", C1, C1) + np.einsum("ij,ij->i", r_, C2)
                step = np.where(gp > 0, g / np.where(gp > 0, gp, 1.0), 0.0)
                tau = np.clip(tau - step, 0.0, 1.0)
            dist = np.linalg.norm(_curve(Hc, tau)[0] - X, axis=1)
            for r, v, t, dd in zip(cs, cv, tau, dist):
                if dd <= self.tol and 0.0 < t < 1.0:
                    e, m = divmod(int(sids[r]), 4)
                    found[e][m].append((float(t), int(v)))
        self.side_verts, self.side_tau = [], []
        for e in range(n):
            sv, st = [], []
            for m in range(4):
                pts = sorted(found[e][m])
                sv.append([int(self.corners[e, m])] + [v for _, v in pts] + [int(self.corners[e, (m + 1) % 4])])
                st.append([0.0] + [t for t, _ in pts] + [1.0])
            self.side_verts.append(sv)
            self.side_tau.append(st)

    def _segments(self):
        self.seg_users: dict[tuple[int, int], list[tuple[int, int, int]]] = {}
        for e, sides in enumerate(self.side_verts):
            for m, verts in enumerate(sides):
                for k in range(len(verts) - 1):
                    a, b = verts[k], verts[k + 1]
                    if a == b:
                        raise self.error(e, f"two points on its side {m} coincide at {self.point_text(a)}")
                    self.seg_users.setdefault(_key(a, b), []).append((e, m, k))
        for key, users in self.seg_users.items():
            if len(users) > 2:
                names = ", ".join(self.where(u[0])[0] for u in users)
                raise self.error(users[0][0], f"{names} all meet along the edge from "
                                              f"{self.point_text(key[0])} to {self.point_text(key[1])} "
                                              f"(overlapping or non-manifold elements)")

    def seg_key(self, e: int, m: int, k: int) -> tuple[int, int]:
        v = self.side_verts[e][m]
        return _key(v[k], v[k + 1])

    def reversed_pair(self, ue, uf) -> bool:
        """Whether two users of one segment run it in opposite directions (the usual case)."""
        (e, m, k), (f, mf, kf) = ue, uf
        return self.side_verts[e][m][k] == self.side_verts[f][mf][kf + 1]

    def shared_pairs(self):
        return [(key, u[0], u[1]) for key, u in self.seg_users.items() if len(u) == 2]

    def _check_shared_parametrisation(self):
        """Both elements of a shared segment must trace it with the same parameter (up to an
        affine map): else no continuous patch parametrisation exists across it."""
        pairs = self.shared_pairs()
        if not pairs:
            return
        sig = np.array([0.25, 0.5, 0.75])
        se, te, sf, tf = [], [], [], []
        for _, (e, m, k), (f, mf, kf) in pairs:
            ta, tb = self.side_tau[e][m][k], self.side_tau[e][m][k + 1]
            fa, fb = self.side_tau[f][mf][kf], self.side_tau[f][mf][kf + 1]
            if self.reversed_pair((e, m, k), (f, mf, kf)):
                fa, fb = fb, fa
            se.append(4 * e + m)
            sf.append(4 * f + mf)
            te.append(ta + sig * (tb - ta))
            tf.append(fa + sig * (fb - fa))
        Pe = self.side_points(np.repeat(se, 3), np.concatenate(te))
        Pf = self.side_points(np.repeat(sf, 3), np.concatenate(tf))
        gap = np.linalg.norm(Pe - Pf, axis=1).reshape(-1, 3).max(axis=1)
        bad = np.nonzero(gap > 10 * self.tol)[0]
        if len(bad):
            i = int(bad[np.argmax(gap[bad])])
            _, (e, _, _), (f, _, _) = pairs[i]
            raise self.error(e, f"it shares an edge with {self.where(f)[0]} but the two trace it "
                                f"differently (points {gap[i]:.3g} apart at equal parameters): "
                                f"the elements are not a watertight Bezier extraction")

    def _classify(self):
        nv = len(self.vpos)
        self.corner_uses = [[] for _ in range(nv)]
        self.side_uses = [[] for _ in range(nv)]
        self.v_segs = [[] for _ in range(nv)]
        for e in range(len(self.pieces)):
            for c in range(4):
                self.corner_uses[self.corners[e, c]].append((e, c))
            for m in range(4):
                for k in range(1, len(self.side_verts[e][m]) - 1):
                    self.side_uses[self.side_verts[e][m][k]].append((e, m, k))
        self.boundary = np.zeros(nv, bool)
        for key, users in self.seg_users.items():
            self.v_segs[key[0]].append(key)
            self.v_segs[key[1]].append(key)
            if len(users) == 1:
                self.boundary[list(key)] = True
        self.kind = []
        self.valence = np.array([len(c) for c in self.corner_uses])
        for v in range(nv):
            nc, ns = len(self.corner_uses[v]), len(self.side_uses[v])
            if self.boundary[v]:
                if ns:
                    raise self.error(self.side_uses[v][0][0], f"the boundary point {self.point_text(v)} "
                                                              f"lies inside its side (unsupported junction)")
                self.kind.append("boundary" if nc == 2 else "boundary-corner" if nc == 1 else "boundary-ep")
                continue
            if ns == 0:
                kind, nseg = ("regular", 4) if nc == 4 else ("ep", nc)
            elif ns == 1 and nc == 2:
                kind, nseg = "t", 3
            else:
                raise self.error(self.side_uses[v][0][0] if ns else self.corner_uses[v][0][0],
                                 f"at {self.point_text(v)} {nc} elements have a corner and {ns} pass "
                                 f"through: only T-junctions and extraordinary points are supported")
            if len(self.v_segs[v]) != nseg:
                raise self.error(self.corner_uses[v][0][0], f"the elements around {self.point_text(v)} "
                                                            f"do not close up ({len(self.v_segs[v])} edges "
                                                            f"for {nc} corners)")
            self.kind.append(kind)
        self.singular = {v for v in range(nv) if self.kind[v] in ("ep", "boundary-corner", "boundary-ep")}


# -- patch boundaries -------------------------------------------------------------------
def _trace(mesh: _Mesh, singular: set) -> tuple[set, dict]:
    """Segments on patch boundaries (``decompose.trace_lines``), and the cuts needed where a
    line meets a T-junction by its stem: {piece: (side, tau)}."""
    traced = {key for key, users in mesh.seg_users.items() if len(users) == 1}
    splits: dict[int, tuple[int, float]] = {}
    elements_of = {key: {u[0] for u in users} for key, users in mesh.seg_users.items()}

    def line(v: int, key):
        """The steps of a line from v along segment ``key``: straight through regular
        vertices, along the bar of T-junctions; ("stem", piece, side, tau) where it meets a
        T-junction by its stem."""
        while True:
            w = key[1] if key[0] == v else key[0]
            yield ("edge", v, w)
            yield ("vertex", w, None if mesh.boundary[w] else key)
            if mesh.kind[w] == "regular":
                nxt = [k for k in mesh.v_segs[w] if k != key and not (elements_of[k] & elements_of[key])]
                if len(nxt) != 1:
                    raise mesh.error(mesh.corner_uses[w][0][0], f"no straight continuation at "
                                                                f"{mesh.point_text(w)}")
                v, key = w, nxt[0]
            else:                                   # T-junction
                e, m, k = mesh.side_uses[w][0]
                verts = mesh.side_verts[e][m]
                bars = [_key(verts[k - 1], verts[k]), _key(verts[k], verts[k + 1])]
                if key not in bars:
                    yield ("stem", e, m, mesh.side_tau[e][m][k])
                    return
                v, key = w, bars[1 - bars.index(key)]

    def walks(v: int):
        return (line(v, key) for key in mesh.v_segs[v] if len(mesh.seg_users[key]) == 2)

    def on_stem(step) -> bool:
        _, e, m, tau = step
        splits.setdefault(e, (m, tau))
        return False

    trace_lines(singular, walks, traced, on_stem)
    return traced, splits


def _split(pieces: list[Piece], splits: dict, nets: list[np.ndarray]) -> list[Piece]:
    """Cut pieces across side m at fraction tau (the line continuing a T-junction's stem)."""
    out = []
    for e, pc in enumerate(pieces):
        if e not in splits:
            out.append(pc)
            continue
        m, tau = splits[e]
        s0, s1, t0, t1 = pc.box
        if m in (0, 2):
            x = tau if m == 0 else 1.0 - tau
            cut = s0 + x * (s1 - s0)
            boxes = [(s0, cut, t0, t1), (cut, s1, t0, t1)]
        else:
            x = tau if m == 1 else 1.0 - tau
            cut = t0 + x * (t1 - t0)
            boxes = [(s0, s1, t0, cut), (s0, s1, cut, t1)]
        for b in boxes:
            out.append(Piece(sub_net(nets[pc.element], b), pc.element, b))
    return out


def _components(mesh: _Mesh, traced: set) -> list[list[int]]:
    joined = [(users[0][0], users[1][0]) for key, users in mesh.seg_users.items()
              if len(users) == 2 and key not in traced]
    parts = groups(components(len(mesh.pieces), joined))
    return sorted(parts, key=lambda g: min(mesh.pieces[e].element for e in g))


@dataclass
class _Region:
    """A rectangle of pieces: ``side_dir[e][m]`` = patch edge (0 bottom, 1 right, 2 top,
    3 left) that side m of piece e faces; per piece its line classes (left, right, bottom,
    top); instance ids of the side points ``inst[e][m]`` and their U and V classes."""
    pieces: list[int]
    side_dir: dict
    box: dict                 # piece -> [L, R, B, T] class ids
    uclass: dict              # instance -> U class
    vclass: dict
    nu: int
    nv: int
    outer: tuple              # classes of the left, right, bottom, top boundary


class _NotRectangle(Exception):
    pass


def _frames(mesh: _Mesh, comp: list[int], traced: set) -> dict:
    """The patch edge each side of each piece faces (``decompose.region_frames``): a
    neighbour across a segment faces the other way there, turning the same way round
    when the two run the segment in opposite directions, else mirrored."""
    def steps(e, de):
        he = 1 if de[1] == (de[0] + 1) % 4 else -1
        for m in range(4):
            for k in range(len(mesh.side_verts[e][m]) - 1):
                key = mesh.seg_key(e, m, k)
                users = mesh.seg_users[key]
                if key in traced or len(users) != 2:
                    continue
                other = users[1] if users[0] == (e, m, k) else users[0]
                f, mf, _ = other
                hf = he if mesh.reversed_pair((e, m, k), other) else -he
                d0 = (de[m] + 2) % 4
                yield f, [(d0 + hf * ((j - mf) % 4)) % 4 for j in range(4)]

    side_dir = region_frames(comp[0], [0, 1, 2, 3], steps)
    if side_dir is None:
        raise _NotRectangle
    return side_dir


def _region(mesh: _Mesh, comp: list[int], traced: set, inst: list, joined: list) -> _Region:
    side_dir = _frames(mesh, comp, traced)
    along_u, along_v = list(joined), list(joined)       # points on one vertical / horizontal line
    for e in comp:
        for m in range(4):
            ids = inst[e][m]
            pairs = along_u if side_dir[e][m] in (1, 3) else along_v
            pairs.extend((ids[0], i) for i in ids[1:])
    n = sum(len(ids) for sides in inst for ids in sides)
    line_u, line_v = components(n, along_u), components(n, along_v)
    members = [i for e in comp for m in range(4) for i in inst[e][m]]
    ucls, vcls = {}, {}
    uclass = {i: ucls.setdefault(line_u[i], len(ucls)) for i in members}
    vclass = {i: vcls.setdefault(line_v[i], len(vcls)) for i in members}
    box, outer = {}, [set(), set(), set(), set()]
    for e in comp:
        cls = [None] * 4
        for m in range(4):
            d = side_dir[e][m]
            cls[(3, 1, 0, 2).index(d)] = (uclass if d in (1, 3) else vclass)[inst[e][m][0]]
            keys = [mesh.seg_key(e, m, k) for k in range(len(mesh.side_verts[e][m]) - 1)]
            on = [k in traced or len(mesh.seg_users[k]) == 1 for k in keys]
            if any(on) != all(on):
                raise _NotRectangle
            if all(on):
                outer[(3, 1, 0, 2).index(d)].add(cls[(3, 1, 0, 2).index(d)])
        if cls[0] == cls[1] or cls[2] == cls[3]:
            raise _NotRectangle
        box[e] = cls
    if any(len(o) != 1 for o in outer):
        raise _NotRectangle
    for lo, hi, n in ((0, 1, len(ucls)), (2, 3, len(vcls))):
        # the lines must be ordered: no cycle from left to right (a closed band)
        succ = [[] for _ in range(n)]
        indeg = np.zeros(n, int)
        for e in comp:
            succ[box[e][lo]].append(box[e][hi])
            indeg[box[e][hi]] += 1
        stack = [c for c in range(n) if indeg[c] == 0]
        seen = 0
        while stack:
            c = stack.pop()
            seen += 1
            for d in succ[c]:
                indeg[d] -= 1
                if indeg[d] == 0:
                    stack.append(d)
        if seen != n:
            raise _NotRectangle
    return _Region(comp, side_dir, box, uclass, vclass, len(ucls), len(vcls),
                   tuple(next(iter(o)) for o in outer))


def _instances(mesh: _Mesh, traced: set):
    """Ids of every side point of every piece (corners shared by the two sides), joined
    across the segments inside patches: one id per point of a patch."""
    inst, n = [], 0
    for e in range(len(mesh.pieces)):
        corner = [n, n + 1, n + 2, n + 3]
        n += 4
        sides = []
        for m in range(4):
            mid = len(mesh.side_verts[e][m]) - 2
            sides.append([corner[m]] + list(range(n, n + mid)) + [corner[(m + 1) % 4]])
            n += mid
        inst.append(sides)
    joined = []
    for key, users in mesh.seg_users.items():
        if len(users) != 2 or key in traced:
            continue
        (e, m, k), (f, mf, kf) = users
        if mesh.reversed_pair(users[0], users[1]):
            joined += [(inst[e][m][k], inst[f][mf][kf + 1]), (inst[e][m][k + 1], inst[f][mf][kf])]
        else:
            joined += [(inst[e][m][k], inst[f][mf][kf]), (inst[e][m][k + 1], inst[f][mf][kf + 1])]
    return inst, joined


# -- patch parameters -------------------------------------------------------------------
def _transverse(mesh: _Mesh, elements: _Elements, pairs) -> np.ndarray:
    """|dP/d(transverse element parameter)| of both elements at each shared segment's middle,
    (npairs, 2)."""
    e_all, s_all, t_all, m_all = [], [], [], []
    for _, *users in pairs:
        for (e, m, k) in users:
            tau = 0.5 * (mesh.side_tau[e][m][k] + mesh.side_tau[e][m][k + 1])
            s, t = side_st(m, tau)
            e_all.append(e)
            s_all.append(float(s))
            t_all.append(float(t))
            m_all.append(m)
    _, Ps, Pt = elements.evaluate(np.array(e_all), np.array(s_all), np.array(t_all))
    m_all = np.array(m_all)
    d = np.where(np.isin(m_all, (0, 2)), np.linalg.norm(Pt, axis=1), np.linalg.norm(Ps, axis=1))
    return d.reshape(-1, 2)


def _solve_lines(n: int, hard: list, soft: list, lo: int, hi: int) -> np.ndarray | None:
    """Line coordinates x (n,) with x[lo] = 0, x[hi] = 1 and the exact rows ``hard``
    ({col: coef}, rhs) satisfied, the rows ``soft`` in least squares (null-space method)."""
    from scipy.linalg import null_space
    A = np.zeros((len(hard) + 2, n))
    b = np.zeros(len(hard) + 2)
    for r, (row, rhs) in enumerate(hard):
        for c, a in row.items():
            A[r, c] += a
        b[r] = rhs
    A[-2, lo], A[-1, hi], b[-1] = 1.0, 1.0, 1.0
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    if np.abs(A @ x - b).max() > 1e-9:
        return None
    Z = null_space(A, rcond=1e-12)
    if Z.shape[1] and soft:
        R = np.zeros((len(soft), n))
        for r, (row, _) in enumerate(soft):
            for c, a in row.items():
                R[r, c] += a
        y = np.linalg.lstsq(R @ Z, -(R @ x), rcond=1e-12)[0]
        x = x + Z @ y
    return x


def _region_lines(mesh: _Mesh, reg: _Region, inst, pair_rows, d, wt, use_ratio: bool):
    """Normalised line coordinates (xu, xv) of a region, or None when they do not tile."""
    out = []
    for axis, (lo, hi), cls, across in ((0, (0, 1), reg.uclass, (1, 3)), (1, (2, 3), reg.vclass, (0, 2))):
        n = reg.nu if axis == 0 else reg.nv
        hard, soft = [], []
        for e in reg.pieces:
            for m in range(4):
                if reg.side_dir[e][m] in across:
                    continue                        # sides along this axis carry T-junctions
                ids, taus = inst[e][m], mesh.side_tau[e][m]
                for k in range(1, len(ids) - 1):
                    row = {}
                    for c, a in ((cls[ids[k]], 1.0), (cls[ids[0]], -(1.0 - taus[k])), (cls[ids[-1]], -taus[k])):
                        row[c] = row.get(c, 0.0) + a
                    hard.append((row, 0.0))
        for i, (e, m, f, mf) in pair_rows:
            if reg.side_dir[e][m] not in across:
                continue
            de, df = (d[i] if use_ratio else (1.0, 1.0))
            be, bf = reg.box[e], reg.box[f]
            row = {}
            for c, a in ((be[hi], df), (be[lo], -df), (bf[hi], -de), (bf[lo], de)):
                row[c] = row.get(c, 0.0) + wt[i] * a / (de + df)
            soft.append((row, 0.0))
        x = _solve_lines(n, hard, soft, reg.outer[lo], reg.outer[hi])
        if x is None:
            return None
        out.append(x)
    xu, xv = out
    w = np.array([xu[reg.box[e][1]] - xu[reg.box[e][0]] for e in reg.pieces])
    h = np.array([xv[reg.box[e][3]] - xv[reg.box[e][2]] for e in reg.pieces])
    if w.min() <= 1e-9 or h.min() <= 1e-9 or xu.min() < -1e-9 or xu.max() > 1 + 1e-9 \
            or xv.min() < -1e-9 or xv.max() > 1 + 1e-9 or abs((w * h).sum() - 1.0) > 1e-9:
        return None
    return xu, xv


def _scales(regions, lines, cross_rows, d, wt) -> np.ndarray:
    """Knot sizes (npatch, 2): each patch's extent in u and v in knot units.

    Exact: two patches sharing an edge have the same extent along it (the parametrisation
    runs on across the edge without a jump in speed along it), and the mean knot interval
    of every connected part is 1. Least squares: the transverse width ratios across patch
    edges match the derivative ratios (as inside patches). A weak pull towards each
    patch's own mean interval of 1 fixes what these leave free."""
    from scipy.linalg import null_space
    npatch = len(regions)
    wsum = np.zeros((npatch, 2))
    count = np.zeros(npatch)
    for r, (reg, (xu, xv)) in enumerate(zip(regions, lines)):
        wsum[r, 0] = sum(xu[reg.box[e][1]] - xu[reg.box[e][0]] for e in reg.pieces)
        wsum[r, 1] = sum(xv[reg.box[e][3]] - xv[reg.box[e][2]] for e in reg.pieces)
        count[r] = len(reg.pieces)
    s0 = (count[:, None] / wsum).reshape(-1)
    same, joined, rows = [], [], []        # (patch, axis) nodes with one extent; joined patches
    for i, (ra, ea, ma, rb, eb, mb) in cross_rows:
        wa, axa = _width(regions[ra], lines[ra], ea, ma)
        wb, axb = _width(regions[rb], lines[rb], eb, mb)
        same.append((2 * ra + 1 - axa, 2 * rb + 1 - axb))
        joined.append((ra, rb))
        rows.append((2 * ra + axa, wa, 2 * rb + axb, wb, d[i], wt[i]))
    col = components(2 * npatch, same)
    n = int(col.max()) + 1
    soft, rhs = [], []
    for ka, wa, kb, wb, (da, db), w in rows:
        row = np.zeros(n)
        row[col[ka]] += w * wa * db / (da + db)
        row[col[kb]] -= w * wb * da / (da + db)
        soft.append(row)
        rhs.append(0.0)
    lam = 1e-3
    for k in range(2 * npatch):
        row = np.zeros(n)
        row[col[k]] = lam / s0[k]
        soft.append(row)
        rhs.append(lam)
    part = components(npatch, joined)
    A = np.zeros((int(part.max()) + 1, n))
    b = np.zeros(len(A))
    for r in range(npatch):
        g = part[r]
        A[g, col[2 * r]] += wsum[r, 0]
        A[g, col[2 * r + 1]] += wsum[r, 1]
        b[g] += 2 * count[r]
    R, rhs = np.array(soft), np.array(rhs)
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    Z = null_space(A)
    if Z.shape[1]:
        x = x + Z @ np.linalg.lstsq(R @ Z, rhs - R @ x, rcond=None)[0]
    sigma = x[col].reshape(npatch, 2)
    if np.any(sigma <= 0):
        return s0.reshape(npatch, 2)
    return sigma


def _width(reg: _Region, lines, e: int, m: int):
    """Normalised width of piece e across its side m, and the axis (0 u, 1 v) it is along."""
    xu, xv = lines
    b = reg.box[e]
    if reg.side_dir[e][m] in (1, 3):
        return xu[b[1]] - xu[b[0]], 0
    return xv[b[3]] - xv[b[2]], 1


def _orient(Q: np.ndarray, side_dir) -> tuple[np.ndarray, bool, bool, bool]:
    """The net re-indexed [v, u] in the patch frame, and (swap, flip_u, flip_v)."""
    d1, d2 = side_dir[1], side_dir[2]              # the sides s = 1 and t = 1 face these edges
    swap = d1 in (0, 2)
    arr = Q.transpose(1, 0, 2) if swap else Q
    flip_u = (d2 == 3) if swap else (d1 == 3)
    flip_v = (d1 == 0) if swap else (d2 == 0)
    if flip_u:
        arr = arr[:, ::-1]
    if flip_v:
        arr = arr[::-1]
    return np.ascontiguousarray(arr), swap, flip_u, flip_v


def bezier_model(nets, source: str | None = None, labels=None, kind: str = "bezier",
                 name: str | None = None, tol_rel: float = TOL_REL) -> Model:
    """A Model from rational Bezier elements: ``nets`` is a list of homogeneous control nets
    (q+1, p+1, 4) [j, i] (i along the element's s; degrees may differ per element);
    ``labels[e]`` = (name, line) locates element e in ``source`` for error messages.

    Besides the Model's own fields: ``model.elements`` (ElementPlace per element or piece of
    one: where it sits in which patch), ``model.mesh_info`` (MeshInfo: merged vertices,
    T-junctions, dropped duplicates, cuts, seeds, parametrisation misfit) and
    ``model.node_vertex`` (the mesh_info vertex of every node)."""
    nets = [np.asarray(Q, float) for Q in nets]
    labels = labels or [(f"element {e}", None) for e in range(len(nets))]
    if not nets:
        raise InputError("no elements", path=source)
    for e, Q in enumerate(nets):
        if Q.ndim != 3 or Q.shape[2] != 4 or Q.shape[0] < 2 or Q.shape[1] < 2:
            raise InputError(f"{labels[e][0]}: control net of shape {Q.shape}", path=source, line=labels[e][1])
        if not np.all(np.isfinite(Q)) or not np.all(Q[..., 3] > 0):
            raise InputError(f"{labels[e][0]}: a control point is not finite or has weight <= 0",
                             path=source, line=labels[e][1])
    allp = np.concatenate([_euclid(Q).reshape(-1, 3) for Q in nets])
    size = float(np.linalg.norm(allp.max(axis=0) - allp.min(axis=0)))
    if size == 0:
        raise InputError("all control points are one point", path=source)
    tol = tol_rel * size
    pieces = [Piece(Q, e) for e, Q in enumerate(nets)]

    def where(e):
        text, line = labels[pieces_now[e].element]
        if pieces_now[e].box != (0.0, 1.0, 0.0, 1.0):   # exact: the default of an uncut piece
            text += " (part)"
        return text, source, line

    pieces_now = pieces
    pieces, duplicates = _drop_duplicates(pieces, tol)
    info = MeshInfo(np.zeros((0, 3)), duplicates=duplicates)
    seeds: list[np.ndarray] = []
    for _ in range(4 * len(nets) + 16):
        pieces_now = pieces
        mesh = _Mesh(pieces, tol, where)
        singular = set(mesh.singular)
        for x in seeds:
            singular.add(int(np.argmin(np.linalg.norm(mesh.vpos - x, axis=1))))
        traced, splits = _trace(mesh, singular)
        if splits:
            pieces = _split(pieces, splits, nets)
            info.splits += len(splits)
            continue
        comps = _components(mesh, traced)
        inst, joined = _instances(mesh, traced)
        regions, bad = [], None
        for comp in comps:
            try:
                regions.append(_region(mesh, comp, traced, inst, joined))
            except _NotRectangle:
                bad = comp
                break
        if bad is None:
            break
        verts = sorted({int(v) for e in bad for v in mesh.corners[e]} - singular,
                       key=lambda v: tuple(np.round(mesh.vpos[v], 9)))
        verts = [v for v in verts if not mesh.boundary[v]] or verts
        if not verts:
            raise mesh.error(bad[0], "cannot group the elements around it into four-sided patches")
        seeds.append(mesh.vpos[verts[0]].copy())
        info.seeds.append(mesh.vpos[verts[0]].copy())
    else:
        raise InputError("cannot group the elements into four-sided patches", path=source)
    info.vertices = mesh.vpos
    info.t_junctions = [v for v in range(len(mesh.vpos)) if mesh.kind[v] == "t"]
    return _build(mesh, regions, inst, traced, info, source, kind, name, pieces, nets, labels)


def _drop_duplicates(pieces: list[Piece], tol: float):
    """Elements with the same four corners and centre as an earlier one are dropped."""
    corners = np.array([[_euclid(side_control(p.ctrl, m)[0]) for m in range(4)] for p in pieces])
    ids, _ = merge_points(corners.reshape(-1, 3), tol)
    ids = ids.reshape(len(pieces), 4)
    centre = []
    for p in pieces:
        q, pp = p.ctrl.shape[0] - 1, p.ctrl.shape[1] - 1
        h = np.einsum("j,i,jic->c", bernstein(q, [0.5], 0)[0, 0], bernstein(pp, [0.5], 0)[0, 0], p.ctrl)
        centre.append(h[:3] / h[3])
    seen: dict[tuple, list[int]] = {}
    keep, dups = [], []
    for e, p in enumerate(pieces):
        key = tuple(sorted(ids[e].tolist()))
        hit = next((f for f in seen.get(key, []) if np.linalg.norm(centre[f] - centre[e]) <= tol), None)
        if hit is None:
            seen.setdefault(key, []).append(e)
            keep.append(p)
        else:
            dups.append((p.element, pieces[hit].element))
    return keep, dups


def _build(mesh, regions, inst, traced, info, source, kind, name, pieces, nets, labels) -> Model:
    elements = _Elements(pieces)
    region_of = {}
    for r, reg in enumerate(regions):
        for e in reg.pieces:
            region_of[e] = r
    pairs = mesh.shared_pairs()
    d = _transverse(mesh, elements, pairs) if pairs else np.zeros((0, 2))
    # next to extraordinary points no parametrisation is C1: there the derivative ratios
    # only break ties, the rest of the surface sets the widths
    ep = np.array([k == "ep" for k in mesh.kind] + [False])
    # one of two literals: ``wt != 1.0`` in _ratio_rms is exact by construction
    wt = np.array([EP_WEIGHT if ep[mesh.corners[[e, f]]].any() else 1.0
                   for _, (e, _, _), (f, _, _) in pairs])
    inner = {r: [] for r in range(len(regions))}
    cross = []
    for i, (key, (e, m, _), (f, mf, _)) in enumerate(pairs):
        if key in traced:
            cross.append((i, (region_of[e], e, m, region_of[f], f, mf)))
        else:
            inner[region_of[e]].append((i, (e, m, f, mf)))
    lines = []
    for r, reg in enumerate(regions):
        got = _region_lines(mesh, reg, inst, inner[r], d, wt, True)
        if got is None:
            got = _region_lines(mesh, reg, inst, inner[r], d, wt, False)
        if got is None:
            raise mesh.error(reg.pieces[0], "the elements of its patch cannot be given rectangles "
                                            "that tile a square (inconsistent T-junctions)")
        lines.append(got)
    sigma = _scales(regions, lines, cross, d, wt)
    info.ratio_rms = _ratio_rms(regions, lines, sigma, inner, cross, d, wt)

    patches, places, corner_vertex = [], [], []
    for r, (reg, (xu, xv)) in enumerate(zip(regions, lines)):
        patch, pl = _patch(r, reg, xu, xv, pieces, nets, sigma[r])
        patches.append(patch)
        places.extend(pl)
        corner_vertex.append(_corner_vertices(mesh, reg))
    verts = sorted({v for cv in corner_vertex for v in cv})
    node_of = {v: i for i, v in enumerate(verts)}
    for patch, cv in zip(patches, corner_vertex):
        patch.corner_nodes = np.array([node_of[v] for v in cv])
    _neighbours(mesh, regions, lines, inst, traced, patches)
    eps = []
    for v in range(len(mesh.vpos)):
        if mesh.kind[v] in ("ep", "boundary-ep") and v in node_of:
            eps.append(ExtraordinaryPoint(node_of[v], int(mesh.valence[v]), mesh.vpos[v].copy(),
                                          mesh.kind[v] == "boundary-ep"))
    model = Model(patches, mesh.vpos[verts], eps, kind, source, name=name)
    model.elements = places
    model.mesh_info = info
    model.node_vertex = np.array(verts)
    return model


def _ratio_rms(regions, lines, sigma, inner, cross, d, wt) -> float:
    """Rms of log(w_e |dP_f| / (w_f |dP_e|)) over shared edges away from extraordinary points:
    0 where the chosen parametrisation is C1."""
    logs = []
    for r, rows in inner.items():
        for i, (e, m, f, mf) in rows:
            if wt[i] != 1.0:
                continue
            we, ax = _width(regions[r], lines[r], e, m)
            wf, bx = _width(regions[r], lines[r], f, mf)
            logs.append(np.log((we * sigma[r, ax] * d[i][1]) / (wf * sigma[r, bx] * d[i][0])))
    for i, (ra, ea, ma, rb, eb, mb) in cross:
        if wt[i] != 1.0:
            continue
        wa, ax = _width(regions[ra], lines[ra], ea, ma)
        wb, bx = _width(regions[rb], lines[rb], eb, mb)
        logs.append(np.log((wa * sigma[ra, ax] * d[i][1]) / (wb * sigma[rb, bx] * d[i][0])))
    return float(np.sqrt(np.mean(np.square(logs)))) if logs else 0.0


def _patch(r: int, reg: _Region, xu, xv, pieces, nets, knot_size):
    used_u = sorted({float(xu[reg.box[e][k]]) for e in reg.pieces for k in (0, 1)})
    used_v = sorted({float(xv[reg.box[e][k]]) for e in reg.pieces for k in (2, 3)})
    ub = _unique(used_u)
    vb = _unique(used_v)
    ub[0], ub[-1], vb[0], vb[-1] = 0.0, 1.0, 0.0, 1.0
    nu, nv = len(ub) - 1, len(vb) - 1
    group = np.full((nu, nv), -1)
    local = np.zeros((nu, nv), int)
    by_shape: dict[tuple, list] = {}
    places = []
    for e in reg.pieces:
        L, R, B, T = reg.box[e]
        u0, u1, v0, v1 = xu[L], xu[R], xv[B], xv[T]
        arr, swap, fu, fv = _orient(pieces[e].ctrl, reg.side_dir[e])
        pc = pieces[e]
        places.append(ElementPlace(pc.element, pc.box, r, (float(u0), float(u1), float(v0), float(v1)),
                                   swap, fu, fv))
        iu0, iu1 = _span(ub, u0, u1)
        iv0, iv1 = _span(vb, v0, v1)
        for iu in range(iu0, iu1):
            for iv in range(iv0, iv1):
                if group[iu, iv] != -1:
                    raise InputError(f"patch {r}: elements overlap in its parameter square (internal)")
                box = ((ub[iu] - u0) / (u1 - u0), (ub[iu + 1] - u0) / (u1 - u0),
                       (vb[iv] - v0) / (v1 - v0), (vb[iv + 1] - v0) / (v1 - v0))
                box = tuple(min(1.0, max(0.0, float(x))) for x in box)
                sub = sub_net(arr, box)
                lst = by_shape.setdefault(sub.shape, [])
                group[iu, iv] = list(by_shape).index(sub.shape)
                local[iu, iv] = len(lst)
                lst.append(sub)
    if (group < 0).any():
        raise InputError(f"patch {r}: its elements leave a gap in its parameter square (internal)")
    groups = [BezierCells(np.array(v)) for v in by_shape.values()]
    patch = Patch(r, ub, vb, group, local, groups, name=f"patch {r}", knot_size=tuple(knot_size))
    return patch, places


def _unique(vals, eps: float = 1e-10) -> np.ndarray:
    out = [vals[0]]
    for x in vals[1:]:
        if x - out[-1] > eps:
            out.append(x)
    return np.array(out)


def _span(breaks: np.ndarray, a: float, b: float) -> tuple[int, int]:
    i0 = int(np.argmin(np.abs(breaks - a)))
    i1 = int(np.argmin(np.abs(breaks - b)))
    return i0, i1


def _corner_vertices(mesh: _Mesh, reg: _Region) -> list[int]:
    out = []
    for k, (ci, cj) in enumerate(((0, 2), (1, 2), (1, 3), (0, 3))):
        want = (reg.outer[ci], reg.outer[cj])
        e = next((e for e in reg.pieces if (reg.box[e][ci], reg.box[e][cj]) == want), None)
        if e is None:
            raise mesh.error(reg.pieces[0], "its patch has no element at one of its corners")
        m1 = reg.side_dir[e].index((k - 1) % 4)
        m2 = reg.side_dir[e].index(k)
        corner = m2 if m2 == (m1 + 1) % 4 else m1
        out.append(int(mesh.corners[e, corner]))
    return out


def _neighbours(mesh, regions, lines, inst, traced, patches) -> None:
    region_of = {e: r for r, reg in enumerate(regions) for e in reg.pieces}

    def along(r, edge, i):
        reg, (xu, xv) = regions[r], lines[r]
        x = xu[reg.uclass[i]] if edge in (0, 2) else xv[reg.vclass[i]]
        return x if edge in (0, 1) else -x

    for r, reg in enumerate(regions):
        for edge in range(4):
            across, none, sample = set(), 0, None
            for e in reg.pieces:
                m = reg.side_dir[e].index(edge)
                if reg.box[e][(3, 1, 0, 2).index(edge)] != reg.outer[(3, 1, 0, 2).index(edge)]:
                    continue
                for k in range(len(mesh.side_verts[e][m]) - 1):
                    users = mesh.seg_users[mesh.seg_key(e, m, k)]
                    if len(users) == 1:
                        none += 1
                        continue
                    other = users[1] if users[0] == (e, m, k) else users[0]
                    f, mf, kf = other
                    rf = region_of[f]
                    across.add((rf, regions[rf].side_dir[f][mf]))
                    sample = ((e, m, k), other)
            if not across:
                continue
            if none or len(across) != 1:
                raise mesh.error(reg.pieces[0], f"patch {r}'s edge {edge} is not one whole edge of a "
                                                f"neighbouring patch")
            rb, eb = across.pop()
            (e, m, k), (f, mf, kf) = sample
            a, b = inst[e][m][k], inst[e][m][k + 1]
            if mesh.reversed_pair((e, m, k), (f, mf, kf)):
                af, bf = inst[f][mf][kf + 1], inst[f][mf][kf]
            else:
                af, bf = inst[f][mf][kf], inst[f][mf][kf + 1]
            runs_a = along(r, edge, b) > along(r, edge, a)
            runs_b = along(rb, eb, bf) > along(rb, eb, af)
            patches[r].neighbours[edge] = EdgeNeighbour(rb, eb, bool(runs_a != runs_b))
