"""What the path leaves on the surface: scallop, cusp heights between lines, gouges.

Independent of the generator: it reads only the ToolPath (contact points, normals, moves,
line and patch ids) and evaluates the model's surface itself.

The tool as it moves: the ball centre runs linearly from path point to path point (what a
machine interpolating the tool tip does for a constant axis, and to first order otherwise),
so the swept volume is a chain of *capsules* (cylinder of radius r around each segment of
centres plus the balls at its ends). No densification error.

* Material left at a surface point p (normal n toward the tool): the distance along n from
  p to where the ray p + l n enters the swept volume, min over nearby capsules; negative
  when p lies inside the volume (then it measures the gouge along the normal). Capsules are
  cut into pieces no longer than ``piece``; a point's candidates are the ``K_NEAR`` pieces
  whose middles lie nearest to p + r n, where a touching ball's centre would be (scipy's
  cKDTree, or with the compiled kernels the same rows from a table of cells:
  :meth:`Swept.candidates`); a capsule the search misses can only make the height larger,
  never hide material.
* The surface is sampled on a (u, v) grid per patch with about ``spacing`` mm between
  samples. A grid cannot see the top of a cusp (a cusp is a sharp ridge: with a spacing d
  the sampled maximum can be low by about 2 h d / g), so every pair of neighbouring samples
  cut by different lines is refined: bisection on the parameter segment between them for
  the point where both lines leave the same height, i.e. the ridge. A ridge's bisection
  compares the capsules of its two owners among the nearest at the segment's ends and
  middle, asked once (tested against every capsule). The cusp heights are those ridge
  heights; between consecutive lines of one patch they give the cusp mean.
* Gouge: for ball centres at every path point, at the middle of every move on the surface
  (the chord) and along air moves, the distance to the surface (nearest grid samples, then
  Newton on the squared distance) compared with r.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from .. import compiled
from ..toolpath.path import Move, ToolPath

K_NEAR = 16
GRID_EPS = 1e-7
K_RIDGE = 10
ENTRY_ROWS = 4096
LINK_OWNER = 1 << 40
RIDGE_ROWS = 20000      # ridges refined at once (their candidates' data: at most 2.4 kB a ridge)
ENTRY_WORK = 10.0       # a capsule entry in numpy costs about as much as this many Viterbi elements
GRID_CHUNK = 262_144     # a surface grid is evaluated about this many samples at a time (whole rows of cells)
SPLIT_SAMPLES = 200_000  # a lone patch is shared among processes (_measure_patches' split) from this many samples
NEAR_CELL = 3.0         # the candidates' table: cells of this many capsule pieces on a side
NEAR_CELLS = 4_000_000  # at most this many cells (a large part: larger cells, ...
NEAR_COARSE = 4.0       # ... up to this many times the edge asked; larger, the kd-tree answers)
NEAR_WORK = 200.0       # a kd-tree query costs about as much as this many Viterbi elements
_NO_MASK = np.zeros((0, 0), bool)        # (compiled.capsule_entries' arguments it does not use)
_NO_LAM = np.zeros((0, 0))
_NO_ROWS = np.zeros(0)


@dataclass
class SurfaceGrid:
    """Samples of the model's surface: per patch a (nu, nv) grid, flattened in C order."""
    patch: np.ndarray
    uv: np.ndarray
    P: np.ndarray
    n: np.ndarray
    shapes: list                 # (patch, offset, nu, nv)
    spacing: float = 0.0

    def __len__(self) -> int:
        return len(self.P)


def surface_grid(model, spacing: float, patches=None, region=None) -> SurfaceGrid:
    """A grid on each patch (all, or ``patches``) with about ``spacing`` mm between samples;
    ``region`` (u0, u1, v0, v1) restricts every patch's grid to a box of its (u, v)."""
    pp, uvs, Ps, ns, shapes = [], [], [], [], []
    offset = 0
    u0, u1, v0, v1 = region if region is not None else (0.0, 1.0, 0.0, 1.0)
    for p in (model.patches if patches is None else [model.patches[i] for i in patches]):
        # side lengths as polylines through a coarse grid: parametric derivatives are
        # singular at extraordinary corners and would size the grid absurdly
        g = np.linspace(0, 1, 17)
        P = p.evaluate_grid(g, g).P.reshape(17, 17, 3)
        su = float(np.linalg.norm(np.diff(P, axis=0), axis=2).sum(axis=0).max()) * (u1 - u0)
        sv = float(np.linalg.norm(np.diff(P, axis=1), axis=2).sum(axis=1).max()) * (v1 - v0)
        nu = max(2, int(np.ceil(su / spacing)) + 1)
        nv = max(2, int(np.ceil(sv / spacing)) + 1)
        # a hair inside the patch: exactly at an extraordinary corner the second derivatives
        # are singular (the Newton projection starts from these samples)
        gu = np.clip(np.linspace(u0, u1, nu), GRID_EPS, 1 - GRID_EPS)
        gv = np.clip(np.linspace(v0, v1, nv), GRID_EPS, 1 - GRID_EPS)
        # (P coordinate-major, as the grid's evaluation and its concatenation give it)
        uv, P, n = np.empty((nu * nv, 2)), np.empty((3, nu * nv)).T, np.empty((nu * nv, 3))
        for a, b in _cell_rows(p, gu, GRID_CHUNK // nv):
            # whole rows of cells at a time: the same blocks as the whole grid's, so the same
            # values; the temporaries a few MB, used again (the whole grid's, some 400 MB on
            # tjunction_mold's 2.4 M samples, were memory touched for the first time: in its
            # default job 0.62 -> 0.08 s; alone 0.64-0.93 -> 0.10 s, figure4's patches
            # 0.49-0.80 -> 0.43-0.44 s, head's 1.58-3.53 -> 1.34-1.67 s)
            sp = p.evaluate_grid(gu[a:b], gv, second=False)
            rows = slice(a * nv, b * nv)
            uv[rows, 0], uv[rows, 1] = sp.u, sp.v
            P[rows], n[rows] = sp.P, sp.normal
        pp.append(np.full(nu * nv, p.index))
        uvs.append(uv)
        Ps.append(P)
        ns.append(n)
        shapes.append((p.index, offset, nu, nv))
        offset += nu * nv
    one = (lambda x: x[0]) if len(pp) == 1 else np.concatenate          # noqa: E731
    return SurfaceGrid(one(pp), one(uvs), one(Ps), one(ns), shapes, spacing)


def _cell_rows(patch, gu: np.ndarray, most: int):
    """(first, end) of runs of ``gu``'s values that fill whole rows of the patch's cells, each
    of about ``most`` values or fewer (one row of cells at least)."""
    iu = np.clip(np.searchsorted(patch.ubreaks, gu, side="right") - 1, 0, len(patch.ubreaks) - 2)
    starts = np.concatenate([[0], np.flatnonzero(np.diff(iu)) + 1, [len(gu)]])
    a = 0
    for k in range(1, len(starts)):
        if k == len(starts) - 1 or starts[k + 1] - a > most:
            yield a, int(starts[k])
            a = int(starts[k])


class Swept:
    """The swept volume of a ball of radius r along the path's centres, as capsule pieces."""

    def __init__(self, path: ToolPath, piece: float):
        self.path = path
        r = path.tool_radius
        C = path.center
        self.r = r
        mv = path.move[1:]
        owner = np.where((mv == Move.CUT) & (path.line[1:] >= 0), path.line[1:],
                         LINK_OWNER + np.arange(1, len(path)))
        a, b = C[:-1], C[1:]
        length = np.linalg.norm(b - a, axis=1)
        k = np.maximum(1, np.ceil(length / piece).astype(int))
        idx = np.repeat(np.arange(len(a)), k)
        j = np.concatenate([np.arange(m) for m in k]) if len(k) else np.zeros(0, int)
        kk = k[idx]
        self.a = a[idx] + (b[idx] - a[idx]) * (j / kk)[:, None]
        self.b = a[idx] + (b[idx] - a[idx]) * ((j + 1) / kk)[:, None]
        self.owner = owner[idx]
        if len(C) == 1:                    # a single point: one ball
            self.a, self.b, self.owner = C.copy(), C.copy(), np.array([LINK_OWNER])
        # the capsules' middles, for the candidates' search (made here, before the measuring
        # processes fork)
        self.near = _Nearest(0.5 * (self.a + self.b), edge=NEAR_CELL * piece)
        self.near.prepare()
        # each capsule's length and unit axis, once (entry() reads them per candidate)
        e = self.b - self.a
        self.length = np.linalg.norm(e, axis=1)
        self.unit = e / np.where(self.length > 0, self.length, 1.0)[:, None]
        # the capsules' start, unit axis and end by component (contiguous: entry() gathers them)
        self._soa = tuple(tuple(np.ascontiguousarray(x[:, c]) for c in range(3))
                          for x in (self.a, self.unit, self.b))
        self.a, self.unit, self.b, self.length = (np.ascontiguousarray(x, float)
                                                  for x in (self.a, self.unit, self.b, self.length))

    def candidates(self, p: np.ndarray, n: np.ndarray, k: int = K_NEAR):
        """The ``k`` capsules whose middles lie nearest to p + r n, nearest first (rows of
        capsule indices), as scipy's kd-tree gives them (:class:`_Nearest`)."""
        return self.near.query(p + self.r * n, min(k, len(self.a)), dist=False)[1]

    def entry(self, p: np.ndarray, n: np.ndarray, idx: np.ndarray | None = None, caps=None) -> np.ndarray:
        """Distance along n from p to the entry into each candidate capsule (Q, k); inf when
        the ray misses; negative when p is inside. The candidates: capsule indices ``idx``
        (Q, k), or ``caps``, their data as :meth:`gather` gives it (a caller asking about the
        same candidates again gathers them once). With the compiled kernels
        (``compiled.capsule_entries``: the same operations, the same bits) from ``idx``,
        else in numpy ``ENTRY_ROWS`` points at a time (the (rows, k) temporaries then stay
        in the processor's cache)."""
        if idx is not None:
            k = compiled.kernels(work=ENTRY_WORK * idx.size)
            if k is not None:
                lam = np.empty(idx.shape)
                self._kernel(k, p, n, idx, _NO_MASK, _NO_MASK, lam, _NO_ROWS, _NO_ROWS)
                return lam
        if len(p) > ENTRY_ROWS:
            return np.concatenate([self._entry(p[s:s + ENTRY_ROWS], n[s:s + ENTRY_ROWS],
                                               self.gather(idx[s:s + ENTRY_ROWS]) if caps is None
                                               else tuple(c[s:s + ENTRY_ROWS] for c in caps))
                                   for s in range(0, len(p), ENTRY_ROWS)])
        return self._entry(p, n, self.gather(idx) if caps is None else caps)

    def _kernel(self, k, p, n, idx, of_a, of_b, lam, low_a, low_b) -> None:
        """``compiled.capsule_entries`` of points p, n and candidates idx."""
        k["capsule_entries"](np.ascontiguousarray(p, float), np.ascontiguousarray(n, float),
                             np.ascontiguousarray(idx, np.int64), self.length, self.a, self.unit, self.b,
                             float(self.r), of_a, of_b, lam, low_a, low_b)

    def gather(self, idx: np.ndarray) -> tuple:
        """The data :meth:`entry` reads of capsules ``idx`` (Q, k): length, then start, unit
        axis and end, each by component, as (Q, k) arrays."""
        return (self.length[idx],) + tuple(x[idx] for part in self._soa for x in part)

    def _entry(self, p: np.ndarray, n: np.ndarray, caps: tuple) -> np.ndarray:
        # component by component on (Q, k) arrays (a third less time than (Q, k, 3) einsums);
        # each dot product summed (x + z) + y, the order numpy 1.24's einsum summed three
        # terms in, so the figures stay those it gave (a last-bit change can move a tie
        # between two capsules' owners, and with it which sample pairs are refined)
        r = self.r
        L, ax, ay, az, ex, ey, ez, bx, by, bz = caps
        px, py, pz = (p[:, c:c + 1] for c in range(3))
        nx, ny, nz = (n[:, c:c + 1] for c in range(3))
        wx, wy, wz = px - ax, py - ay, pz - az
        dn = nx * ex + nz * ez + ny * ey
        wn = wx * ex + wz * ez + wy * ey
        dpx, dpy, dpz = nx - dn * ex, ny - dn * ey, nz - dn * ez
        wpx, wpy, wpz = wx - wn * ex, wy - wn * ey, wz - wn * ez
        A = dpx * dpx + dpz * dpz + dpy * dpy
        B = wpx * dpx + wpz * dpz + wpy * dpy
        Cc = (wpx * wpx + wpz * wpz + wpy * wpy) - r * r
        disc = B * B - A * Cc
        with np.errstate(invalid="ignore", divide="ignore"):
            lam = (-B - np.sqrt(np.where(disc >= 0, disc, np.nan))) / A
        axial = wn + lam * dn
        lam = np.where((disc >= 0) & (A > 1e-14) & (axial >= 0) & (axial <= L) & (L > 0), lam, np.inf)
        for cx, cy, cz in ((wx, wy, wz), (px - bx, py - by, pz - bz)):      # the balls at both ends
            bb = nx * cx + nz * cz + ny * cy
            cc = (cx * cx + cz * cz + cy * cy) - r * r
            d = bb * bb - cc
            with np.errstate(invalid="ignore"):
                ls = -bb - np.sqrt(np.where(d >= 0, d, np.nan))
            lam = np.minimum(lam, np.where(d >= 0, ls, np.inf))
        return lam

    def height(self, p: np.ndarray, n: np.ndarray, chunk: int = 20000, keep: int = 0):
        """(height, owner of the lowest capsule) of material at points p with normals n; with
        ``keep``, also each point's ``keep`` nearest capsules (int32, (len(p), keep): the first
        of its candidates, which the kd-tree gives nearest first)."""
        out = np.empty(len(p))
        own = np.empty(len(p), np.int64)
        near = np.empty((len(p), min(keep, K_NEAR, len(self.a))), np.int32) if keep else None
        for s in range(0, len(p), chunk):
            e = slice(s, s + chunk)
            idx = self.candidates(p[e], n[e])
            lam = self.entry(p[e], n[e], idx)
            j = np.argmin(lam, axis=1)
            out[e] = lam[np.arange(len(j)), j]
            own[e] = self.owner[idx[np.arange(len(j)), j]]
            if keep:
                near[e] = idx[:, :near.shape[1]]
        return (out, own, near) if keep else (out, own)

    def ridge_candidates(self, points, A, B, known=()):
        """The candidates of ridges' bisections: per row, the capsules of owner A or B among
        the ``K_RIDGE`` nearest at each of ``points`` ((p, n) pairs, the same rows), asked once
        at a ridge's ends and middle rather than at every step (its points lie between them, a
        few hundredths of a mm apart); ``known``: more rows of nearest capsules found before
        (the ends' own, kept by :meth:`height`: grid samples). Returns what :meth:`heights_among` reads: the
        candidates (Q, w), and whether each is owner A's and owner B's (the padding neither's);
        the candidates as capsule indices where the kernels measure them, else their
        :meth:`gather` (made once for the bisection's steps)."""
        idx = np.concatenate([np.asarray(x, np.int64) for x in known]
                             + [self.candidates(p, n, K_RIDGE) for p, n in points], axis=1)
        own = self.owner[idx]
        keep = (own == A[:, None]) | (own == B[:, None])
        big = len(self.a)
        s = np.sort(np.where(keep, idx, big), axis=1)
        s[:, 1:][s[:, 1:] == s[:, :-1]] = big              # each capsule once
        s.sort(axis=1)
        w = max(1, int(np.count_nonzero(s < big, axis=1).max())) if len(s) else 1
        s = s[:, :w]
        real = s < big
        idx = np.where(real, s, 0)
        own = np.where(real, self.owner[idx], -1)
        if compiled.kernels(work=ENTRY_WORK * idx.size * 12) is not None:
            return idx, own == A[:, None], own == B[:, None]
        return self.gather(idx), own == A[:, None], own == B[:, None]

    def heights_among(self, p, n, candidates):
        """Heights at p of the material left by owner A and by owner B alone over
        ``candidates`` (:meth:`ridge_candidates`); inf where no candidate of that owner is
        hit."""
        caps, of_a, of_b = candidates
        k = compiled.kernels() if isinstance(caps, np.ndarray) else None     # (capsule indices)
        if k is not None:
            low_a, low_b = np.empty(len(p)), np.empty(len(p))
            self._kernel(k, p, n, caps, np.ascontiguousarray(of_a), np.ascontiguousarray(of_b), _NO_LAM, low_a, low_b)
            return low_a, low_b
        lam = self.entry(p, n, caps=self.gather(caps) if isinstance(caps, np.ndarray) else caps)
        return np.where(of_a, lam, np.inf).min(axis=1), np.where(of_b, lam, np.inf).min(axis=1)


@dataclass
class HeightSamples:
    """Every material height :func:`measure` found, for maps: the grid samples and the
    refined ridge points, each with its patch and (u, v); heights in mm (negative inside the
    swept volume; samples no ball comes near are left out)."""
    patch: np.ndarray            # (n,) int
    uv: np.ndarray               # (n, 2)
    height: np.ndarray           # (n,) mm
    ridge: np.ndarray            # (n,) bool: a refined cusp ridge, not a grid sample

    def __len__(self) -> int:
        return len(self.height)


@dataclass
class ScallopReport:
    """Measured on the surface (mm). ``max_scallop`` is the largest material height found
    (grid and ridges); ``cusp_*`` are ridge heights between consecutive lines of a patch;
    ``mean_material`` is the mean height over the grid (about h/3 for an ideal path)."""
    max_scallop: float
    max_at: tuple
    mean_material: float
    cusp_mean: float
    cusp_max: float
    cusps: int
    ridges: int
    samples: int
    uncovered: int               # grid samples no ball comes near (material height > r)
    gouge_points: float          # deepest the surface enters a ball at a path point
    gouge_chords: float          # ... at the middle of a move on the surface
    gouge_air: float             # ... along air moves (retract, rapid, approach)
    gouge_at: tuple
    spacing: float
    cusp_heights: np.ndarray = field(default=None, repr=False)
    heights: HeightSamples | None = field(default=None, repr=False)   # with measure(heights=True)

    def as_dict(self) -> dict:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__ if k not in ("cusp_heights", "heights")}
        return d


def _evaluate_at(model, pat, uv):
    P = np.empty((len(pat), 3))
    Nn = np.empty((len(pat), 3))
    for p in np.unique(pat):
        sel = pat == p
        # (positions and normals: no second derivatives, the same values)
        sp = model.patches[p].evaluate(uv[sel, 0], uv[sel, 1], second=False)
        P[sel], Nn[sel] = sp.P, sp.normal
    return P, Nn


def _refine_ridges(sw: Swept, model, grid: SurfaceGrid, i, j, A, B, ends: tuple, iterations: int = 11):
    """Ridge heights between grid samples i (lowest capsule of owner A) and j (owner B):
    bisection on f = h_A - h_B along the parameter segment, then the crossing of the two
    height profiles interpolated linearly inside the last bracket (each profile is smooth
    there; only their minimum has the corner). ``ends``: the ``K_RIDGE`` nearest capsules
    of samples i and j, as :meth:`Swept.height` kept them (the middle's are asked here)."""
    pat = grid.patch[i]
    ua, ub = grid.uv[i].copy(), grid.uv[j].copy()
    Pa, Na = _evaluate_at(model, pat, ua)
    Pb, Nb = _evaluate_at(model, pat, ub)
    um = 0.5 * (ua + ub)
    Pm, Nm = _evaluate_at(model, pat, um)
    near = sw.ridge_candidates(((Pm, Nm),), A, B, known=ends)
    a_a, b_a = sw.heights_among(Pa, Na, near)
    a_b, b_b = sw.heights_among(Pb, Nb, near)
    for it in range(iterations):
        if it:
            um = 0.5 * (ua + ub)
            Pm, Nm = _evaluate_at(model, pat, um)
        la, lb = sw.heights_among(Pm, Nm, near)
        left = la <= lb                         # A still lower at the middle: ridge nearer j
        ua = np.where(left[:, None], um, ua)
        ub = np.where(left[:, None], ub, um)
        a_a, b_a = np.where(left, la, a_a), np.where(left, lb, b_a)
        a_b, b_b = np.where(left, a_b, la), np.where(left, b_b, lb)
    with np.errstate(invalid="ignore", divide="ignore"):
        fa, fb = a_a - b_a, a_b - b_b           # fa <= 0 <= fb
        x = np.clip(fa / (fa - fb), 0.0, 1.0)
        h_lin = 0.5 * ((a_a + x * (a_b - a_a)) + (b_a + x * (b_b - b_a)))
    fallback = np.maximum(np.minimum(a_a, b_a), np.minimum(a_b, b_b))
    ok = np.isfinite(h_lin) & np.isfinite(fa) & np.isfinite(fb) & (fb > fa)
    h = np.where(ok, h_lin, fallback)
    where = ua + np.where(ok, x, 0.5)[:, None] * (ub - ua)
    return h, where


def measure(path: ToolPath, model, scallop: float | None = None, spacing: float | None = None,
            patches=None, region=None, piece: float | None = None, progress=None,
            heights: bool = False, when_idle=None) -> ScallopReport:
    """Scallop, cusps and gouges of ``path`` on ``model`` (see the module doc).

    ``scallop``: the limit the path was made for (default: the path's settings); it sets
    the default grid ``spacing`` (a quarter of the flat side step) and capsule ``piece``
    length. ``patches`` / ``region`` restrict the sampled surface (tests on parts of a model).
    The surface is measured one patch at a time, in forked processes where more than one
    is allowed (:func:`~tsplcam.toolpath.parallel.map_pieces`; the same figures: each patch's
    are its own, gathered in patch order), so memory stays bounded by the largest patches'
    grids, one per process, however big the model; ``progress(done, total)`` is called
    after each. A model of one patch (a T-spline with T-junctions) has that patch's samples
    and ridges shared among the processes instead, each measured as alone: the same figures
    (tjunction_mold's one patch of 2,448,180 samples: 10.9 -> 5.7 s).
    ``heights``: keep every sample's height in the report (:class:`HeightSamples`, for maps).
    ``when_idle``: work for this process's core once no patch is left for it while a worker
    still measures one (``map_pieces``' ``when_idle``; not called with one process).
    """
    r = path.tool_radius
    if scallop is None:
        scallop = float(path.info.get("settings", {}).get("scallop", 0.01 * r))
    g = np.sqrt(8.0 * r * scallop)
    spacing = spacing or 0.25 * g
    piece = piece or 0.5 * g
    sw = Swept(path, piece)
    # each line's patch (where the line first appears; -1 for numbers no line has), to tell
    # consecutive lines of one patch
    sel = path.line >= 0
    lines, first = np.unique(path.line[sel], return_index=True)
    line_patch = np.full(int(lines[-1]) + 1 if len(lines) else 0, -1, np.int64)
    line_patch[lines] = path.patch[sel][first]
    todo = list(range(len(model.patches)) if patches is None else patches)
    from ..toolpath.parallel import map_pieces, worker_count
    # the patches with the most path points (about the largest grids) first: the processes
    # end together
    on = path.patch[path.patch >= 0]
    size = np.bincount(on, minlength=len(model.patches))[np.asarray(todo, int)] if len(todo) else np.zeros(0, int)
    # one patch (a T-spline with T-junctions): its samples and ridges are shared among the
    # processes instead (_measure_patches' split); only then, as the patches of a larger model
    # are measured in the workers, whose own forks would put more processes than cores to work
    split = worker_count(None, 2) if len(todo) == 1 else 1
    parts = [x for x in map_pieces(_patch_piece, (sw, model, spacing, region, line_patch, r, heights, todo, split,
                                                  when_idle),
                                   len(todo), worker_count(None, len(todo)), order=np.argsort(-size, kind="stable"),
                                   tick=progress, when_idle=when_idle) if x is not None]
    samples = sum(x["samples"] for x in parts)
    uncovered = sum(x["uncovered"] for x in parts)
    cusp = np.concatenate([x["cusp"] for x in parts]) if parts else np.zeros(0)
    best = max(parts, key=lambda x: x["hmax"]) if parts else None
    hmax = best["hmax"] if best is not None and uncovered == 0 else float("inf")
    at = best["at"] if best is not None else (-1, np.nan, np.nan)
    nfin = sum(x["finite"] for x in parts)
    mean_material = sum(x["material_sum"] for x in parts) / nfin if nfin else np.nan
    gouge = max(((x["gouge"]) for x in parts), key=lambda t: max(t[0], t[1], t[2]), default=(0.0, 0.0, 0.0, None))
    gp, gc, ga, gat = gouge
    return ScallopReport(
        max_scallop=hmax, max_at=at, mean_material=float(mean_material),
        cusp_mean=float(cusp.mean()) if len(cusp) else np.nan, cusp_max=float(cusp.max()) if len(cusp) else np.nan,
        cusps=int(len(cusp)), ridges=sum(x["ridges"] for x in parts), samples=samples, uncovered=uncovered,
        gouge_points=gp, gouge_chords=gc, gouge_air=ga, gouge_at=gat, spacing=float(spacing),
        cusp_heights=cusp, heights=_height_samples(parts) if heights else None)


def _height_samples(parts) -> HeightSamples:
    kept = [x["heights"] for x in parts]
    if not kept:
        return HeightSamples(np.zeros(0, int), np.zeros((0, 2)), np.zeros(0), np.zeros(0, bool))
    return HeightSamples(*(np.concatenate([k[i] for k in kept]) for i in range(4)))


def _patch_piece(sw: "Swept", model, spacing: float, region, line_patch: np.ndarray, r: float, keep: bool,
                 todo: list, split: int, when_idle, i: int):
    """:func:`_measure_patches` of the i-th patch of ``todo`` (a piece of ``map_pieces``)."""
    return _measure_patches(sw, model, spacing, [todo[i]], region, line_patch, r, keep, split, when_idle)


def _grid_rows(sw: "Swept", model, grid: SurfaceGrid, cuts: np.ndarray, i: int):
    """A piece of ``map_pieces`` over a grid: 0 its :func:`gouges`, i > 0 :meth:`Swept.height`
    of samples ``cuts[i - 1]`` to ``cuts[i]``."""
    if i == 0:
        return gouges(sw.path, model, grid)
    e = slice(int(cuts[i - 1]), int(cuts[i]))
    return sw.height(grid.P[e], grid.n[e], keep=K_RIDGE)


def _ridge_rows(sw: "Swept", model, grid: SurfaceGrid, pairs: np.ndarray, ra: np.ndarray, rb: np.ndarray,
                near: np.ndarray, i: int):
    """:func:`_refine_ridges` of the i-th ``RIDGE_ROWS`` of ``pairs`` (a piece of ``map_pieces``)."""
    e = slice(i * RIDGE_ROWS, (i + 1) * RIDGE_ROWS)
    return _refine_ridges(sw, model, grid, pairs[e, 0], pairs[e, 1], ra[e], rb[e],
                          (near[pairs[e, 0]], near[pairs[e, 1]]))


def _measure_patches(sw: "Swept", model, spacing: float, patches, region, line_patch: np.ndarray, r: float,
                     keep: bool = False, split: int = 1, when_idle=None):
    """The figures of one grid (one patch), to be aggregated by :func:`measure`. ``split``:
    processes to share the samples' heights and the ridges among (each sample and each ridge
    measured as alone, the results in their order: the same figures), for a grid of
    ``SPLIT_SAMPLES`` or more; ``when_idle`` then as :func:`measure`'s."""
    from ..toolpath.parallel import map_pieces
    grid = surface_grid(model, spacing, patches, region)
    if len(grid) == 0:
        return None
    split = split if len(grid) >= SPLIT_SAMPLES else 1
    # (each sample's nearest capsules kept: a ridge's ends are samples)
    gouge = None
    if split > 1:
        # the gouge check beside the samples' heights, which come in a few pieces
        cuts = np.linspace(0, len(grid), 2 * split + 1).astype(np.int64)
        got = map_pieces(_grid_rows, (sw, model, grid, cuts), len(cuts), split)
        gouge, got = got[0], got[1:]
        hgt, own, near = (np.concatenate([g[k] for g in got]) for k in range(3))
    else:
        hgt, own, near = sw.height(grid.P, grid.n, keep=K_RIDGE)
    uncovered = int(np.count_nonzero(~(hgt <= r)))
    # neighbouring grid samples cut by different capsule owners: refine their ridge
    pairs = []
    for pidx, off, nu, nv in grid.shapes:
        ids = off + np.arange(nu * nv).reshape(nu, nv)
        pairs.append(np.column_stack([ids[:-1, :].ravel(), ids[1:, :].ravel()]))
        pairs.append(np.column_stack([ids[:, :-1].ravel(), ids[:, 1:].ravel()]))
    pairs = np.concatenate(pairs)
    ok = (own[pairs[:, 0]] != own[pairs[:, 1]]) & np.isfinite(hgt[pairs[:, 0]]) & np.isfinite(hgt[pairs[:, 1]])
    pairs = pairs[ok]
    ridge_h = np.zeros(0)
    ridge_uv = np.zeros((0, 2))
    ra = rb = np.zeros(0, np.int64)
    if len(pairs):
        ra, rb = own[pairs[:, 0]], own[pairs[:, 1]]
        chunks = -(-len(pairs) // RIDGE_ROWS)
        got = map_pieces(_ridge_rows, (sw, model, grid, pairs, ra, rb, near), chunks, split if chunks > 1 else 1,
                         when_idle=when_idle)
        ridge_h = np.concatenate([hh for hh, _ in got])
        ridge_uv = np.concatenate([ww for _, ww in got])
    lp, lq = _owner_patch(ra, line_patch, -2), _owner_patch(rb, line_patch, -3)
    neighbours = (np.abs(ra - rb) == 1) & (ra < LINK_OWNER) & (rb < LINK_OWNER) & (lp == lq) & (lp >= 0)
    cusp = ridge_h[neighbours & np.isfinite(ridge_h)]
    all_h = np.concatenate([hgt[np.isfinite(hgt)], ridge_h[np.isfinite(ridge_h)]])
    hmax, at = -np.inf, (-1, np.nan, np.nan)
    if len(all_h):
        k = int(np.argmax(all_h))
        nfin = int(np.count_nonzero(np.isfinite(hgt)))
        if k < nfin:
            gi = np.nonzero(np.isfinite(hgt))[0][k]
            at = (int(grid.patch[gi]), float(grid.uv[gi, 0]), float(grid.uv[gi, 1]))
        else:
            ri = np.nonzero(np.isfinite(ridge_h))[0][k - nfin]
            gi = pairs[ri, 0]
            at = (int(grid.patch[gi]), float(ridge_uv[ri, 0]), float(ridge_uv[ri, 1]))
        hmax = float(all_h[k])
    finite = hgt[np.isfinite(hgt)]
    kept = None
    if keep:
        g, rf = np.isfinite(hgt), np.isfinite(ridge_h)
        rp = grid.patch[pairs[:, 0]] if len(pairs) else np.zeros(0, int)
        kept = (np.concatenate([grid.patch[g], rp[rf]]), np.concatenate([grid.uv[g], ridge_uv[rf]]),
                np.concatenate([hgt[g], ridge_h[rf]]),
                np.concatenate([np.zeros(int(g.sum()), bool), np.ones(int(rf.sum()), bool)]))
    return {"heights": kept, "samples": len(grid), "uncovered": uncovered, "cusp": cusp, "hmax": hmax, "at": at,
            "finite": len(finite), "material_sum": float(np.sum(np.maximum(finite, 0.0))),
            "ridges": int(len(ridge_h)), "gouge": gouges(sw.path, model, grid) if gouge is None else gouge}


def _owner_patch(owner: np.ndarray, line_patch: np.ndarray, link: int) -> np.ndarray:
    """The patch of each capsule owner that is a line (-1 for a line of no patch), ``link``
    for the owners that are links."""
    out = np.full(len(owner), link, np.int64)
    is_line = owner < LINK_OWNER
    o = owner[is_line]
    known = o < len(line_patch)
    out[is_line] = np.where(known, line_patch[np.where(known, o, 0)] if len(line_patch) else -1, -1)
    return out


def project(model, patch: np.ndarray, uv: np.ndarray, x: np.ndarray, iterations: int = 5):
    """Closest points to x on the given patches by Newton on |S(u, v) - x|^2 from uv
    (clamped to the unit square). Returns (distance, uv)."""
    uv = uv.copy()
    d = np.full(len(x), np.inf)
    for p in np.unique(patch):
        sel = np.nonzero(patch == p)[0]
        w = uv[sel]
        for _ in range(iterations):
            sp = model.patches[p].evaluate(w[:, 0], w[:, 1])
            e = sp.P - x[sel]
            gu = np.einsum("ij,ij->i", e, sp.Pu)
            gv = np.einsum("ij,ij->i", e, sp.Pv)
            huu = sp.E + np.einsum("ij,ij->i", e, sp.Puu)
            huv = sp.F + np.einsum("ij,ij->i", e, sp.Puv)
            hvv = sp.G + np.einsum("ij,ij->i", e, sp.Pvv)
            det = huu * hvv - huv * huv
            good = det > 1e-14 * np.maximum(huu * hvv, 1e-300)
            # Newton where the Hessian is positive, gradient descent scaled by the metric otherwise
            du = np.where(good, -(hvv * gu - huv * gv) / np.where(good, det, 1.0), -gu / np.maximum(sp.E, 1e-300))
            dv = np.where(good, -(huu * gv - huv * gu) / np.where(good, det, 1.0), -gv / np.maximum(sp.G, 1e-300))
            w = np.clip(w + np.column_stack([du, dv]), GRID_EPS, 1.0 - GRID_EPS)
        sp = model.patches[p].evaluate(w[:, 0], w[:, 1])
        d[sel] = np.linalg.norm(sp.P - x[sel], axis=1)
        uv[sel] = w
    return d, uv


class _Nearest:
    """The points P nearest to query points (within ``ub``), as ``cKDTree(P).query(x, k,
    distance_upper_bound=ub)`` gives them: with the kernels, ``compiled.k_nearest`` on a table of
    cells of ``edge`` (default ``ub``; the same neighbours, order and distances bit for bit, the
    tree asked for the rows where two of the k + 1 nearest tie), else, and where the table's
    cell cap would make its cells more than ``NEAR_COARSE`` times as large as asked (a large
    part: tjunction_mold's capsule queries take 3.9 s with cells 4 times the edge asked, 6.5 s
    with 6 times, the tree 4.9 s), the tree. tjunction_mold's 3.1 M capsule queries 4.4 -> 1.8
    s; its gouge check, 138,499 centres over 2.4 M grid samples: the tree 0.45 s to build and
    1.15 s to ask, the table 0.17 s and 0.34 s (and the tree still, for the 5 rows that tie)."""

    def __init__(self, P: np.ndarray, ub: float = np.inf, edge: float | None = None):
        self.P, self.ub = np.ascontiguousarray(P, float), float(ub)
        self.edge = self.ub if edge is None else float(edge)
        self.cells = None                 # the table, made at its first use (False: none)

    @cached_property
    def tree(self) -> cKDTree:
        return cKDTree(self.P)

    def prepare(self) -> None:
        """Make now what this process's queries will ask (the table where it has the kernels,
        else the tree), e.g. before processes that query are forked."""
        if compiled.loaded() is None or not self._table():
            self.tree

    def _table(self):
        if self.cells is None:
            self.cells = (len(self.P) > 0 and compiled.cell_table(
                self.P, self.edge, NEAR_CELLS, NEAR_COARSE * self.edge)) or False
        return self.cells

    def query(self, x: np.ndarray, k: int, dist: bool = True):
        """(distances (len(x), k) or None without ``dist``, indices (len(x), k)), inf and
        len(P) where fewer lie within ``ub``."""
        kern = compiled.kernels(work=NEAR_WORK * len(x)) if k < len(self.P) else None
        if kern is None or not self._table():
            d, j = self.tree.query(x, k=k, distance_upper_bound=self.ub)
            return (d.reshape(len(x), k) if dist else None), j.reshape(len(x), k)
        origin, h, shape, start, items, pts = self.cells
        d = np.empty((len(x), k)) if dist else _NO_LAM
        j = np.empty((len(x), k), np.int64)
        tie = np.empty(len(x), bool)
        kern["k_nearest"](np.ascontiguousarray(x, float), pts, items, start, origin, h, shape, int(k), self.ub, j,
                          d, tie)
        t = np.nonzero(tie)[0]
        if len(t):
            dt, jt = self.tree.query(x[t], k=k, distance_upper_bound=self.ub)
            j[t] = jt.reshape(len(t), k)
            if dist:
                d[t] = dt.reshape(len(t), k)
        return (d if dist else None), j


def gouges(path: ToolPath, model, grid: SurfaceGrid, k: int = 2):
    """(at points, at chord middles, along air moves, where) deepest surface penetration
    into the ball, >= 0 (mm)."""
    r = path.tool_radius
    C = path.center
    on = path.patch >= 0
    surf = on[1:] & on[:-1]
    mids = 0.5 * (C[1:] + C[:-1])[surf]
    air_seg = np.nonzero(~surf)[0]
    air = []
    for i in air_seg:
        L = np.linalg.norm(C[i + 1] - C[i])
        m = max(1, int(np.ceil(L / (0.25 * r))))
        f = np.arange(1, m) / m
        air.append(C[i] + (C[i + 1] - C[i]) * f[:, None])
    air = np.concatenate(air) if air else np.zeros((0, 3))
    samples = _Nearest(grid.P, r + 2.0 * grid.spacing)
    out = []
    where = (-1, np.nan, np.nan)
    worst = -np.inf
    for X in (C, mids, air):
        if len(X) == 0:
            out.append(0.0)
            continue
        kk = min(k, len(grid.P))
        # only samples within r + 2 spacing can be refined (below), and a centre farther from
        # every sample is farther than r from this patch: the tree need not look farther
        # (a search far from the samples visits most of the tree); such rows get inf
        dist, idx = samples.query(X, kk)
        idx = np.minimum(idx.reshape(len(X), kk), len(grid.P) - 1)
        dist = dist.reshape(len(X), kk)
        best = dist[:, 0].copy()
        best_uv = grid.uv[idx[:, 0]].copy()
        best_p = grid.patch[idx[:, 0]].copy()
        # a surface point within r has a grid sample within r + spacing: only those need Newton
        for j in range(kk):
            near = np.nonzero(dist[:, j] < r + 2.0 * grid.spacing)[0]
            if len(near) == 0:
                continue
            d, uv = project(model, grid.patch[idx[near, j]], grid.uv[idx[near, j]], X[near])
            better = d < best[near]
            sel = near[better]
            best[sel] = d[better]
            best_uv[sel] = uv[better]
            best_p[sel] = grid.patch[idx[sel, j]]
        pen = r - best
        i = int(np.argmax(pen))
        out.append(max(0.0, float(pen[i])))
        if pen[i] > worst:
            worst = pen[i]
            where = (int(best_p[i]), float(best_uv[i, 0]), float(best_uv[i, 1]))
    return out[0], out[1], out[2], where
