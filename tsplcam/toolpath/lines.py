"""Where the isoparametric lines of one patch go: side steps under a scallop limit and
parity tuning (shang2020 section 3.5; docs/method.md sections 3.1-3.6).

Every patch is machined in a *line frame* (s, t): lines are s = const and run along t;
s = 0 is the start corner's side, s = 1 the far side. For crossfeed ``u`` (lines of
constant u), s is u or 1 - u and t is v; for crossfeed ``v`` the roles swap.

Side step, in two stages:

1. The paper's estimate: at samples of the current line, the exact side step for the
   cross curvature (:func:`~tsplcam.toolpath.sidestep.side_step`, docs/method.md 3.2), mapped
   to the parameter with ``ds = g sqrt(G)/sqrt(EG - F^2)`` (docs/method.md 3.4), minimum over the
   samples. This is first order in the parameter and blind to how the metric changes
   between the lines.
2. A correction on the real geometry (what this module adds): for a candidate next line
   the cusp between the two rows of balls is constructed in space (ball centres on both
   lines in the plane across the feed, the lower intersection of the two balls, its height
   above the surface through a second-order foot point), and the step is corrected by a
   secant on log(cusp)/log(step) until the largest cusp on the line is within
   [ACCEPT, 1] of the target. The samples avoid the line's very ends by 1e-5 in t, so a
   singular corner (an extraordinary point, where E G - F^2 = 0) is never sampled. The
   line ends are measured apart: where lines meet the patch edge at an angle, one line's
   end ball faces the next line's side and the edge keeps more material than the middle
   (:func:`cusp_heights`).

Lines are placed a batch at a time rather than one after the other: from the last placed
line, up to 32 further lines are predicted with the current correction factor (the first-order
step of the lines beyond extrapolated from those placed), all of them evaluated in one call,
their own first-order steps in one and all their gaps' cusps in two; the steps are kept up to
the first whose cusp misses the accept window, and that one is corrected by the secant from its
measured trial. The accept window is the same as one step at a time, so the lines meet the
same scallop condition; on the keycap job about two predicted steps in three are kept (623 of
952, parity trials included). A batch's gaps are measured ``STAGE`` at a time, and not past a
group with a miss (those gaps are never read). The secant's first candidate after a miss is
measured in one call with the gaps of the batch that follows if the secant takes it (it takes
the first candidate at 427 of 428 misses on four sample jobs); if it goes on,
that batch is dropped.

The target is SAFETY h (0.995 h) less what the chords between points may add
(:class:`Target`); what the generator cannot see between its samples is left to that
margin, and tsplcam.verify measures the result (on the sample models the largest scallop
came to 0.969-0.996 h before the margin, 0.971 h on the paper's keycap job after it).

Parity (section 3.5): the zigzag ends on the finish corner's side only for the right
parity of the line count; otherwise the scallop is lowered in steps of 0.1 h, bisecting
between the last two scallops when a step overshoots, until the count has the needed
parity. The trials the first one's count predicts are run together with the next one
(:meth:`Placer._lockstep`: one call for all their waiting lines, one for all their gaps; the
values of each line and gap are those of the trial alone); a trial run ahead is used only when
the tuning comes to it. Then (``balance``, an addition to the paper) the slack of the partial last gap is
spread over all gaps by scaling the line positions, and each gap's cusp is measured again;
if any would exceed the limit the unscaled positions are kept.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from .. import compiled

# numpy's C functions without their Python dispatch wrappers: the same calls, a few
# microseconds less each on the many small arrays here
from ..npfast import quiet as _quiet, where as _where, c_einsum as _einsum, concatenate as _concatenate
from ..npfast import cross_rows as _cross

from ..errors import GeometryError, InputError
from ..layout.layout import CORNER_NAMES, CORNER_UV
from .sidestep import parameter_step, side_step

EDGE_EPS = 1e-5          # samples stay this far (in t) from the line's ends
ACCEPT = 0.97            # accept a side step whose largest cusp is within [ACCEPT, 1] of the target
AIM = 0.99               # the secant aims here
FIT = 1.0 + 1e-9         # 'within the target' allows for rounding
SAFETY = 0.995           # of h: the target the side step aims under (see Target)
END_SAMPLES = 17         # edge samples between two line ends (twice: coarse, then fine)
MAX_SECANT = 10
_END_F = np.linspace(0.0, 1.0, END_SAMPLES)                  # along the edge between two line ends
_END_F2 = np.tile(_END_F, 2)                                  # both edges (t = 0, t = 1)
_END_T = np.repeat([0.0, 1.0], END_SAMPLES)                   # their t
_END_T6 = np.array([0.0, 1.0, EDGE_EPS, 1.0 - EDGE_EPS, 0.0, 1.0])   # line ends, just inside, line 1's ends
MAX_TUNING = 60
LOOKAHEAD = (4, 32)      # lines predicted per batch: after a miss, at most
STAGE = 16               # gaps of a batch measured per call (the rest only if all are kept)
_LINES, _RATIOS = "lines", "ratios"          # the requests of a trial (Placer._place_g)


@dataclass
class FrameGeom:
    """Surface geometry in the line frame (s, t), one row per point."""
    P: np.ndarray
    n: np.ndarray
    Ss: np.ndarray
    St: np.ndarray
    Sss: np.ndarray
    Sst: np.ndarray
    Stt: np.ndarray
    u: np.ndarray
    v: np.ndarray
    s: np.ndarray
    t: np.ndarray

    # E, F, G, L, M, N and det = E G - F^2: the fundamental forms, computed on first use
    # (the chord placement and the cusps' evaluations never read them on their whole rows)
    FORMS = ("E", "F", "G", "L", "M", "N", "det")

    def __getattr__(self, name):
        if name not in FrameGeom.FORMS:
            raise AttributeError(name)
        d = lambda a, b: _einsum("ij,ij->i", a, b)   # noqa: E731
        self.E, self.F, self.G = d(self.Ss, self.Ss), d(self.Ss, self.St), d(self.St, self.St)
        self.L, self.M, self.N = d(self.n, self.Sss), d(self.n, self.Sst), d(self.n, self.Stt)
        self.det = self.E * self.G - self.F ** 2
        return getattr(self, name)

    def rows(self, index) -> "FrameGeom":
        """The rows ``index`` (a slice or index array) as a FrameGeom (the fundamental forms
        are taken along, not computed again)."""
        out = object.__new__(FrameGeom)
        for k in ("P", "n", "Ss", "St", "Sss", "Sst", "Stt", "u", "v", "s", "t", "E", "F", "G", "L", "M", "N",
                  "det"):
            setattr(out, k, getattr(self, k)[index])
        return out

    @staticmethod
    def concat(parts: list) -> "FrameGeom":
        """The rows of several FrameGeoms one after the other."""
        out = object.__new__(FrameGeom)
        for k in ("P", "n", "Ss", "St", "Sss", "Sst", "Stt", "u", "v", "s", "t", "E", "F", "G", "L", "M", "N",
                  "det"):
            setattr(out, k, _concatenate([getattr(g, k) for g in parts]))
        return out

    def cross_curvature(self) -> np.ndarray:
        """Normal curvature across a line s = const, i.e. along S_s - (F/G) S_t
        (docs/method.md 3.3): (L G^2 - 2 M F G + N F^2) / (G (E G - F^2))."""
        with _quiet("divide", "invalid"):
            k = (self.L * self.G ** 2 - 2 * self.M * self.F * self.G + self.N * self.F ** 2) / (
                self.G * self.det)
        return _where((self.det > 0) & (self.G > 0), k, 0.0)

    def curve_curvature(self, along: str) -> tuple[np.ndarray, np.ndarray]:
        """(normal, geodesic) curvature of the iso-curve running along ``along`` ('t' or 's')."""
        d1, d2 = (self.St, self.Stt) if along == "t" else (self.Ss, self.Sss)
        sp2 = _einsum("ij,ij->i", d1, d1)
        kf = self._normal_curvature(d2, sp2)
        with _quiet("divide", "invalid"):
            ktot = _where(sp2 > 0, _norm3(_cross(d1, d2))[:, 0] / sp2 ** 1.5, 0.0)
        return kf, np.sqrt(np.maximum(ktot * ktot - kf * kf, 0.0))

    def normal_curvature(self, along: str) -> np.ndarray:
        """The normal curvature alone of :meth:`curve_curvature` (the same values)."""
        d1, d2 = (self.St, self.Stt) if along == "t" else (self.Ss, self.Sss)
        return self._normal_curvature(d2, _einsum("ij,ij->i", d1, d1))

    def _normal_curvature(self, d2, sp2):
        with _quiet("divide", "invalid"):
            return _where(sp2 > 0, _einsum("ij,ij->i", self.n, d2) / sp2, 0.0)

    def principal_max(self) -> np.ndarray:
        """Largest normal curvature (concave positive)."""
        with _quiet("divide", "invalid"):
            det = _where(self.det > 0, self.det, np.inf)
            K = (self.L * self.N - self.M ** 2) / det
            H = (self.E * self.N - 2 * self.F * self.M + self.G * self.L) / (2 * det)
        return H + np.sqrt(np.maximum(H * H - K, 0.0))


def _unit_normal(Pu: np.ndarray, Pv: np.ndarray) -> np.ndarray:
    """Pu x Pv / |Pu x Pv|: the same values as SurfacePoints.normal (the same products and
    sums). Where Pu and Pv are transposed coordinate-major rows (as ``Patch.evaluate`` gives
    them) the compiled ``unit_normals`` makes these operations point by point (the same bits;
    15 -> 6 us a thousand-point call, 9 -> 2 us a hundred-point one: the keycap path makes 350
    such calls)."""
    k = compiled.kernels()
    if k is not None and Pu.shape == Pv.shape and Pu.ndim == 2 and Pu.shape[1] == 3 and \
            Pu.T.flags.c_contiguous and Pv.T.flags.c_contiguous:
        out = np.empty(Pu.shape)
        k["unit_normals"](Pu.T, Pv.T, out)
        return out
    c = _cross(Pu, Pv)
    length = _norm3(c)
    return c / _where(length > 0.0, length, 1.0)


class LineFrame:
    """A patch seen in the (s, t) frame of one processing step."""

    def __init__(self, patch, crossfeed: str, start: int):
        if crossfeed not in ("u", "v"):
            raise InputError(f"crossfeed {crossfeed!r} is not 'u' or 'v'", item=patch.name)
        self.patch = patch
        self.crossfeed = crossfeed
        self.start = start
        cu, cv = CORNER_UV[start]
        # s runs from the start corner's side of the crossfeed parameter; t from its other side
        self.s_flip = bool(cu if crossfeed == "u" else cv)
        self.t0 = float(cv if crossfeed == "u" else cu)      # t of the start corner

    def uv(self, s, t) -> tuple[np.ndarray, np.ndarray]:
        s = np.asarray(s, float)
        t = np.asarray(t, float)
        a = 1.0 - s if self.s_flip else s
        return (a, t) if self.crossfeed == "u" else (t, a)

    def evaluate(self, s, t, second: bool = True) -> FrameGeom:
        """The geometry at (s, t); ``second`` False: for readers of the points, normals and
        first derivatives alone (the patch may leave Sss, Sst, Stt None: ``Patch.evaluate``;
        the rest are the same values)."""
        s = np.asarray(s, float)
        t = np.asarray(t, float)
        if s.shape != t.shape or s.ndim == 0:           # (equal shapes: broadcast_arrays' views)
            s, t = np.broadcast_arrays(np.atleast_1d(s), np.atleast_1d(t))
        s = np.minimum(np.maximum(s, 0.0), 1.0)
        t = np.minimum(np.maximum(t, 0.0), 1.0)
        u, v = self.uv(s, t)
        sp = self.patch.evaluate(u, v) if second else self.patch.evaluate(u, v, second=False)
        flip = (lambda x: x if x is None else -1.0 * x) if self.s_flip else (lambda x: x)   # noqa: E731
        if self.crossfeed == "u":
            Ss, St, Sss, Sst, Stt = flip(sp.Pu), sp.Pv, sp.Puu, flip(sp.Puv), sp.Pvv
        else:
            Ss, St, Sss, Sst, Stt = flip(sp.Pv), sp.Pu, sp.Pvv, flip(sp.Puv), sp.Puu
        normal = sp.normal_override if sp.normal_override is not None else _unit_normal(sp.Pu, sp.Pv)
        # s and t are this call's own arrays (made by the clamp above): no copies needed
        return FrameGeom(sp.P, normal, Ss, St, Sss, Sst, Stt, sp.u, sp.v, s, t)

    @property
    def cells_along(self) -> int:
        nu, nv = self.patch.shape
        return nv if self.crossfeed == "u" else nu

    def end_t(self, k: int) -> float:
        """t where line k (0-based) ends: lines alternate direction, the first leaves t0."""
        return 1.0 - self.t0 if k % 2 == 0 else self.t0

    def corner_of(self, s_side: int, t_value: float) -> int:
        """Patch corner at s = s_side (0/1), t = t_value (0/1)."""
        u, v = self.uv(float(s_side), float(t_value))
        for k, c in enumerate(CORNER_UV):
            if c[0] == round(float(u)) and c[1] == round(float(v)):
                return k
        raise AssertionError("not a corner")


def check_reachable(frame: LineFrame, geom: FrameGeom, r: float) -> None:
    """GeometryError when a concave curvature at the samples is 1/r or more: a ball of
    radius r cannot touch there without cutting the surface around (docs/method.md 3.2)."""
    k1 = geom.principal_max()
    bad = k1 * r >= 1.0 - 1e-9
    if bad.any():
        i = int(np.argmax(k1))
        p = frame.patch
        rho = 1.0 / k1[i]
        # below a micrometre the surface has a sharp concave edge or corner there (a crease):
        # no ball follows it, whatever its size
        what = (f"a ball that size gouges there (use a tool of radius below {rho:.4g} mm)" if rho >= 1e-3 else
                "a sharp concave edge or corner (a crease) that no ball can follow: round it in the model, or "
                "leave it to another operation")
        raise GeometryError(
            f"{p.name}: concave radius of curvature {rho:.4g} mm at (u, v) = "
            f"({geom.u[i]:.5f}, {geom.v[i]:.5f}) is not larger than the tool radius {r:g} mm; {what}")


def check_patch_reachable(frame: LineFrame, r: float, per_cell: int = 8) -> None:
    """The reachability check on a grid of the whole patch (corners excluded)."""
    nu, nv = frame.patch.shape
    gu = np.linspace(EDGE_EPS, 1 - EDGE_EPS, per_cell * nu + 1)
    gv = np.linspace(EDGE_EPS, 1 - EDGE_EPS, per_cell * nv + 1)
    U, V = np.meshgrid(gu, gv, indexing="ij")
    # in the patch's own frame: crossfeed u, start corner 0
    f0 = LineFrame(frame.patch, "u", 0)
    check_reachable(frame, f0.evaluate(U.ravel(), V.ravel()), r)


@dataclass
class Target:
    """The scallop a gap may leave, per sample: ``SAFETY`` h minus what the chords may add
    (the chord of the ball-centre path runs outside the surface by up to ``undercut`` where
    the line is concave along the feed, and the cusp rises with it).

    SAFETY covers what the samples along a line cannot see; measured by tsplcam.verify on
    the sample models (keycap, mold, head at several r and h) the largest scallop came to
    0.969-0.996 h without it."""
    r: float
    h: float
    undercut: float
    max_step: float

    def at(self, geom: FrameGeom) -> np.ndarray:
        kf = geom.normal_curvature("t")
        shrink = np.maximum(1.0 - self.r * kf, 1e-12)          # centre path / contact path
        kc = np.maximum(kf, 0.0) / shrink
        sag = np.minimum(self.undercut, kc * (self.max_step * shrink) ** 2 / 8.0)
        return SAFETY * self.h - sag

    def scaled(self, factor: float) -> "Target":
        return Target(self.r, self.h * factor, self.undercut, self.max_step)


def _sum3(x: np.ndarray) -> np.ndarray:
    """np.sum(x, axis=-1) of 3-vectors: the reduction's own sums, ((0 + x0) + x1) + x2, as two
    additions and one of 0.0 (it turns -0.0 into 0.0, as the reduction's start does; any other
    value it leaves): the same values, without numpy's reduction loop per row, which costs
    several times the additions on the thousands of rows a call here has."""
    out = x[..., 0] + x[..., 1]
    out += x[..., 2]
    out += 0.0
    return out


def _norm3(x: np.ndarray) -> np.ndarray:
    """np.linalg.norm(x, axis=-1, keepdims=True) for real x: the same squares and sums (as
    :func:`_sum3`; a sum of squares is never -0.0, so without its 0.0)."""
    q = x * x
    out = q[..., 0] + q[..., 1]
    out += q[..., 2]
    return np.sqrt(out)[..., None]


def _coords_first(x: np.ndarray) -> np.ndarray:
    """A view of (..., 3) with the coordinate axis first, (3, ...)."""
    return x.transpose((x.ndim - 1,) + tuple(range(x.ndim - 1)))


def _dot3(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """:func:`_sum3` of x * y for coordinate-first arrays (3, ...): the same products and
    sums, over whole rows of points."""
    q = x * y
    out = q[0] + q[1]
    out += q[2]
    out += 0.0
    return out


def _capsule_entry(p, n, a, b, r, seg=None):
    """Distance along the unit normals n from points p to where they enter the capsule of
    radius r around segment a-b (inf if they miss); arrays broadcast over leading axes.
    ``seg``: :func:`_capsule_segments` of (a, b), when the caller measures the same capsules
    again.

    Worked coordinate-first (views): each product and sum runs over contiguous rows of
    points rather than every third number, the same operations on the same values as
    point-major (:func:`_sum3` of the products)."""
    L, eh, ends = _capsule_segments(a, b) if seg is None else seg
    p, n, a, eh, ends = (_coords_first(x) for x in (p, n, a, eh, ends))
    w = p - a
    dn = _dot3(n, eh)
    wn = _dot3(w, eh)
    dp = n - dn * eh
    wp = w - wn * eh
    A = _dot3(dp, dp)
    B = _dot3(wp, dp)
    C = _dot3(wp, wp) - r * r
    disc = B * B - A * C
    lam = (-B - np.sqrt(_where(disc >= 0, disc, np.nan))) / A
    ax = wn + lam * dn
    # (where disc < 0, lam and so ax are nan: ax >= 0 is false there)
    out = _where((A > 1e-14) & (ax >= 0) & (ax <= L), lam, np.inf)
    # the two end spheres at once
    wc = p[:, None] - ends
    bb = _dot3(n[:, None], wc)
    cc = _dot3(wc, wc) - r * r
    d = bb * bb - cc
    hit = d >= 0
    cap = _where(hit, -bb - np.sqrt(_where(hit, d, 0.0)), np.inf)
    return np.minimum(np.minimum(out, cap[0]), cap[1])


def _capsule_segments(a, b):
    """What :func:`_capsule_entry` needs of the segments a-b alone: their lengths, unit
    directions and both ends stacked (2, ...)."""
    e = b - a
    L = np.sqrt(_sum3(e * e))
    eh = e / np.maximum(L, 1e-300)[..., None]
    ends = np.empty((2,) + e.shape)
    ends[0], ends[1] = a, b
    return L, eh, ends


def cusp_heights(frame: LineFrame, g1: FrameGeom, ds: float, r: float) -> tuple[np.ndarray, np.ndarray]:
    """Heights of the cusps between the balls on line s1 (geometry ``g1`` at its samples) and
    those on line s1 + ds: (one per sample, the two line ends). inf where the balls do not
    meet; nan for a sample whose partner would lie beyond the line's end (the end value
    covers that stretch).

    Along the lines: the partner of each ball is taken in the plane through its centre
    across the feed, to first order t2 = t - (F - r M)/(G - r N) ds (the centre path
    c = S + r n has c_s.S_t = F - r M and c_t.S_t = G - r N). The cusp q is the
    intersection of the two spheres nearest the surface; its height is measured from the
    surface point found by one Gauss-Newton step from the mid parameter and the second
    fundamental form there.

    At the ends the lines stop at the patch edge, and where the parametrisation is skew one
    line's end ball faces the other line's side, which leaves more material on the edge
    than between the lines. There the height is measured directly: at points of the edge
    between the two end balls, the entry along the normal into each line's tube, taken as a
    straight capsule from its end ball along the line; the peak is where the two entries
    are equal, bracketed on 17 samples, bracketed again on 17 inside, and interpolated.
    """
    with _quiet("divide", "invalid"):
        h, ends = cusp_heights_many(frame, g1, np.array([ds], float), r)
    return h[0], ends[0]


def cusp_heights_many(frame: LineFrame, g1: FrameGeom, ds: np.ndarray, r: float):
    """:func:`cusp_heights` for G gaps at once: ``g1`` the samples of G lines one after the
    other (the same number on each), ``ds`` (G,) the steps to their next lines. Returns the
    heights (G, m) and the ends (G, 2); two surface evaluations whatever G is."""
    with _quiet("divide", "invalid"):
        return _cusp_heights(frame, g1, np.asarray(ds, float), r)


_max_reduce = np.maximum.reduce


@lru_cache(maxsize=64)
def _end_t(G: int) -> np.ndarray:
    """np.tile(_END_T, G), made once per G (read-only)."""
    out = np.tile(_END_T, G)
    out.flags.writeable = False
    return out


def _cusp_heights(frame, g1, ds, r):
    G = len(ds)
    m = len(g1.t) // G
    rs = lambda a: a.reshape((G, -1) + a.shape[1:])          # noqa: E731  rows per gap
    s1 = g1.s[::m]
    t1 = rs(g1.t)
    shift = rs(-(g1.F - r * g1.M) / (g1.G - r * g1.N))
    shift = _where(np.isfinite(shift), shift, 0.0)
    t2 = t1 + shift * ds[:, None]
    beyond = (t2 < 0.0) | (t2 > 1.0)
    t2 = np.minimum(np.maximum(t2, 0.0), 1.0)
    s2 = np.minimum(s1 + ds, 1.0)
    f = _END_F
    k_end = END_SAMPLES
    # two evaluations per gap block. The first reads positions and normals alone (second
    # False: the same values as with the second derivatives): the partners on line 2 (m),
    # line 2 at its ends and just inside them (4), line 1 at its ends (2), the edges between
    # the ends (2 k). The second, after the ends' coarse pass: the mid points of the cusps
    # (m), whose second fundamental form the foot point reads, and the edge points of the
    # fine pass (2 k)
    B = m + 6 + 2 * k_end
    S = np.empty((G, B))
    T = np.empty((G, B))
    S[:, :m + 4] = s2[:, None]
    S[:, m + 4:m + 6] = s1[:, None]
    S[:, m + 6:] = s1[:, None] + _END_F2[None, :] * (s2 - s1)[:, None]
    T[:, :m] = t2
    T[:, m:m + 6] = _END_T6
    T[:, m + 6:] = _END_T
    ga = frame.evaluate(S.ravel(), T.ravel(), second=False)
    P, n, St = rs(ga.P), rs(ga.n), rs(ga.St)
    gP, gn = P[:, :m + 6], n[:, :m + 6]
    c2all = gP + r * gn
    # the ends: material along the edge between the two end balls, each line's tube taken
    # as a straight capsule from its end ball along the line (into the patch)
    St1 = rs(g1.St)
    tin = np.empty((G, 2, 2, 3))                  # (gap, line, end): into the patch along t
    tin[:, 0, 0] = St1[:, 0]
    np.negative(St1[:, -1], out=tin[:, 0, 1])
    tin[:, 1, 0] = St[:, m + 2]
    np.negative(St[:, m + 3], out=tin[:, 1, 1])
    tin /= np.maximum(_norm3(tin), 1e-300)
    # both lines' capsules at once: (gap, line, end, 1, 3)
    ca = np.empty((G, 2, 2, 1, 3))
    ca[:, 0, :, 0], ca[:, 1, :, 0] = c2all[:, m + 4:m + 6], c2all[:, m:m + 2]
    cb = ca + 4 * r * tin[:, :, :, None, :]
    seg = _capsule_segments(ca, cb)               # the same capsules in both passes
    ends = np.zeros((G, 2))
    lo = np.zeros((G, 2))
    width = np.ones((G, 2))
    kern = compiled.kernels()
    ends, lo, width = _end_pass(P, n, m + 6, ca, cb, r, seg, ends, lo, width, kern)
    ff = lo[..., None] + width[..., None] * f                  # (G, 2, k)
    S = np.empty((G, m + 2 * k_end))
    T = np.empty((G, m + 2 * k_end))
    S[:, :m] = (0.5 * (s1 + s2))[:, None]
    S[:, m:] = s1[:, None] + np.minimum(np.maximum(ff, 0), 1).reshape(G, -1) * (s2 - s1)[:, None]
    T[:, :m] = 0.5 * (t1 + t2)
    T[:, m:] = _END_T
    gb = frame.evaluate(S.ravel(), T.ravel())
    Pb, nb = rs(gb.P), rs(gb.n)
    ends, _, _ = _end_pass(Pb, nb, m, ca, cb, r, seg, ends, lo, width, kern)
    mid = [rs(getattr(gb, k))[:, :m] for k in ("Ss", "St", "Sss", "Sst", "Stt")]
    height = _cusp_foot(rs(g1.P), rs(g1.n), P[:, :m], n[:, :m], Pb[:, :m], nb[:, :m], *mid, beyond, r, kern)
    return height, ends


def _cusp_foot(P1, N1, P2, N2, mP, mn, mSs, mSt, mSss, mSst, mStt, beyond, r, kern=None):
    """The cusps of :func:`_cusp_heights` (G, m): between the balls on line 1 (surface points
    P1, normals N1) and their partners on line 2 (P2, N2), measured from the mid points (mP,
    mn, derivatives mSs .. mStt); inf where the balls do not meet, nan ``beyond``. All (G, m,
    3). ``kern``: the compiled kernels, whose ``cusp_foot`` makes these operations point by
    point in their order, each dot product summed as einsum sums it here (:func:`_sum_orders`):
    the same bits."""
    G, m = beyond.shape
    if kern is not None and N1.strides[-1] == N1.itemsize and N2.strides[-1] == N2.itemsize:
        c = np.ascontiguousarray
        height = np.empty((G, m))
        kern["cusp_foot"](c(P1), c(N1), c(P2), c(N2), c(mP), c(mn), c(mSs), c(mSt), c(mSss), c(mSst), c(mStt),
                          c(beyond), float(r), _sum_orders(mn, mSs, mSt, mSss, mSst, mStt), height)
        return height
    # the fundamental forms at the mid points alone, on a copy of their rows where the rows
    # are not one array (a form is made row by row: the same values as on all the call's
    # points, for a third of the work)
    fn, fSs, fSt, fSss, fSst, fStt = (x.reshape(-1, 3) for x in (mn, mSs, mSt, mSss, mSst, mStt))
    mE, mF, mG = _einsum("ij,ij->i", fSs, fSs), _einsum("ij,ij->i", fSs, fSt), _einsum("ij,ij->i", fSt, fSt)
    mL, mM, mN = _einsum("ij,ij->i", fn, fSss), _einsum("ij,ij->i", fn, fSst), _einsum("ij,ij->i", fn, fStt)
    mE, mF, mG, mL, mM, mN = (x.reshape(G, m) for x in (mE, mF, mG, mL, mM, mN))
    c1 = P1 + r * N1
    c2 = P2 + r * N2
    w = c2 - c1
    d2 = _einsum("gij,gij->gi", w, w)
    meet = d2 < 4 * r * r
    down = -(N1 + N2)
    down -= (_einsum("gij,gij->gi", down, w) / _where(d2 > 0, d2, 1.0))[..., None] * w
    down /= np.maximum(_norm3(down), 1e-300)
    q = 0.5 * (c1 + c2) + np.sqrt(np.maximum(r * r - 0.25 * d2, 0.0))[..., None] * down
    rel = q - mP
    # Gauss-Newton foot offset (ds, dt): (J^T J) x = J^T rel
    ra, rb = _einsum("gij,gij->gi", mSs, rel), _einsum("gij,gij->gi", mSt, rel)
    det = mE * mG - mF * mF
    x = _where(det > 0, (mG * ra - mF * rb) / det, 0.0)
    y = _where(det > 0, (mE * rb - mF * ra) / det, 0.0)
    height = _einsum("gij,gij->gi", mn, rel) - 0.5 * (mL * x * x + 2 * mM * x * y + mN * y * y)
    height = _where(meet, height, np.inf)
    return _where(beyond, np.nan, height)


def _sum_orders(mn, mSs, mSt, mSss, mSst, mStt) -> np.ndarray:
    """Per dot product of :func:`_cusp_foot`'s numpy form (the forms E, F, G, L, M, N, then
    Ss.rel, St.rel, n.rel) whether einsum sums the three products (x0 + x2) + x1 (its paired
    loop, where both operands' coordinates lie next to each other in memory) rather than
    x0 + x1 + x2 in order (both onto +0): numpy 1.24's choice on every call of the sample
    models' paths. The forms' operands are the rows reshaped into one array (a copy, with its
    coordinates together, unless the rows are one array already: :func:`_rows_together`); the
    vectors rel (and w, down, whose sums are paired) are fresh arrays whose coordinates lie
    together where the normals' do, which the kernel's caller asks."""
    fn, fSs, fSt, fSss, fSst, fStt = (_rows_together(x) for x in (mn, mSs, mSt, mSss, mSst, mStt))
    near = lambda x: x.strides[-1] == x.itemsize             # noqa: E731
    return np.array([fSs, fSs and fSt, fSt, fn and fSss, fn and fSst, fn and fStt,
                     near(mSs), near(mSt), near(mn)], bool)


def _rows_together(x: np.ndarray) -> bool:
    """Whether ``x.reshape(-1, 3)`` of x (G, m, 3) has its coordinates next to each other:
    a copy does (the rows cannot be one array's without it), a view where x's do."""
    G, m = x.shape[:2]
    view = G == 1 or m == 1 or x.strides[0] == m * x.strides[1]
    return x.strides[-1] == x.itemsize if view else True


def _end_pass(P, n, off, ca, cb, r, seg, ends, lo, width, kern=None):
    """One pass of :func:`_cusp_heights` along the edges between the line ends (a coarse one,
    then one inside the bracket of the crossing): P[:, off:], n[:, off:] (G, 2 k, 3) the edge
    points and normals (k = END_SAMPLES on each edge), ca, cb (G, line, end, 1, 3) the lines'
    end capsules, ``seg`` their :func:`_capsule_segments`; returns the ends so far (G, 2) and
    the bracket for the next pass (lo, width). ``kern``: the compiled kernels, whose
    ``cusp_ends`` makes the same operations in the same order (the same bits), updating
    ends, lo and width in place."""
    G = len(ends)
    k_end = END_SAMPLES
    if kern is not None:
        L, eh, caps = seg
        kern["cusp_ends"](np.ascontiguousarray(P), np.ascontiguousarray(n), off, k_end, caps[0].reshape(G, 2, 2, 3),
                          caps[1].reshape(G, 2, 2, 3), eh.reshape(G, 2, 2, 3), L.reshape(G, 2, 2), float(r),
                          ends, lo, width)
        return ends, lo, width
    eP, en = P[:, off:], n[:, off:]
    gi, li = np.arange(G)[:, None], np.arange(2)[None, :]
    take = lambda a, i: a[gi, li, i]          # noqa: E731  a[g, l, i[g, l]]
    h = _capsule_entry(eP.reshape(G, 1, 2, -1, 3), en.reshape(G, 1, 2, -1, 3), ca, cb, r, seg)
    h1, h2 = h[:, 0], h[:, 1]                                        # (G, 2, k)
    # the material peaks where the two tubes leave the same height (line 1's lower near
    # its end, line 2's near the other): bracket that crossing and interpolate, since a
    # cusp is a corner that samples alone would cut short
    d = h1 - h2
    up = d >= 0
    k = up.argmax(axis=2)
    k = _where(up.any(axis=2), k, k_end - 1)
    k = np.minimum(np.maximum(k, 1), k_end - 1)
    d0, d1 = take(d, k - 1), take(d, k)
    x = np.minimum(np.maximum(d0 / (d0 - d1), 0.0), 1.0)
    hk0, hk1 = take(h1, k - 1), take(h1, k)
    cross = hk0 + x * (hk1 - hk0)
    low = np.minimum(h1, h2)
    peak = _max_reduce(low, axis=2)          # np.max's reduction, without its wrapper
    ok = np.isfinite(cross) & (d0 < 0) & (d1 >= 0)
    ends = np.maximum(ends, _where(ok, np.maximum(cross, take(low, k)), peak))
    step = width / (k_end - 1)
    lo = np.minimum(np.maximum(lo + step * (k - 1), 0.0), 1.0)
    return ends, lo, step


@dataclass
class LinePlacement:
    """Line positions s_k (0 = first line, 1 = last) of one patch and how they were found."""
    s: np.ndarray
    scallop: float                       # the scallop limit the positions were made for
    ratio: np.ndarray                    # largest cusp / target per gap (as placed)
    trials: list = field(default_factory=list)   # (scallop, line count) of every trial
    balanced: float = 1.0                # factor the positions were scaled by (1: not)

    @property
    def count(self) -> int:
        return len(self.s)


class Placer:
    """Steps across one patch (:meth:`place`) and tunes the parity (:meth:`tuned`)."""

    def __init__(self, frame: LineFrame, target: Target, samples: int | None = None):
        self.frame = frame
        self.target = target
        m = samples or (16 * frame.cells_along + 1)
        self.t = np.linspace(EDGE_EPS, 1.0 - EDGE_EPS, max(int(m), 9))
        self.r = target.r
        self.evaluations = 0
        self._lines: dict[float, FrameGeom] = {}
        # per (line s, target): the target per sample and the first-order step, which the
        # batches, the secant and the next batch's start all ask for
        self._targets: dict[tuple, np.ndarray] = {}
        self._first: dict[tuple, float] = {}

    def line(self, s: float) -> FrameGeom:
        g = self._lines.get(s)
        if g is None:
            self.lines([s])
            g = self._lines[s]
        return g

    def lines(self, S) -> list:
        """The geometry of the lines at ``S`` (one evaluation for those not seen yet), each
        checked for reach."""
        new = [x for x in dict.fromkeys(float(x) for x in S) if x not in self._lines]
        if new:
            self._evaluate_lines(new)
        return [self._lines[float(x)] for x in S]

    def _evaluate_lines(self, new: list) -> None:
        """Evaluates the lines ``new`` (s values not seen yet) in one call, checks their reach
        and keeps them."""
        m = len(self.t)
        g = self.frame.evaluate(np.repeat(new, m), np.tile(self.t, len(new)))
        check_reachable(self.frame, g, self.r)
        for k, x in enumerate(new):
            self._lines[x] = g.rows(slice(k * m, (k + 1) * m))

    # A trial (:meth:`place`) is written as a generator: its two costly kinds of work, new
    # lines and gaps' cusps, are yielded as requests ((_LINES, s values) or (_RATIOS, g1, ds,
    # target)) and answered by a driver. :meth:`_drive` answers each as its own call (what a
    # trial alone does); :meth:`_lockstep` runs several trials' generators at once and answers
    # their waiting requests of one kind in one call (the lines in one evaluation, the gaps
    # in one cusp measurement), which gives each line and gap the same values as alone (each
    # is made point by point and gap by gap) and saves the calls' fixed costs.

    def _lines_g(self, S):
        """:meth:`lines` as a step of a trial."""
        new = [x for x in dict.fromkeys(float(x) for x in S) if x not in self._lines]
        if new:
            yield _LINES, new
        return [self._lines[float(x)] for x in S]

    def _line_g(self, s: float):
        """:meth:`line` as a step of a trial."""
        g = self._lines.get(s)
        if g is None:
            yield _LINES, [float(s)]
            g = self._lines[s]
        return g

    def _drive(self, gen):
        """The value of a trial's generator, each request answered by its own call."""
        try:
            req = next(gen)
            while True:
                if req[0] is _LINES:
                    new = [x for x in req[1] if x not in self._lines]
                    try:
                        if new:
                            self._evaluate_lines(new)
                    except GeometryError as e:       # raised where the trial asked (it may catch)
                        req = gen.throw(e)
                        continue
                    req = gen.send(None)
                else:
                    req = gen.send(self.ratios(req[1], req[2], req[3]))
        except StopIteration as stop:
            return stop.value

    def _lockstep(self, gens: list) -> list:
        """The generators of several trials run at once: each round answers the requests of
        the kind most of them wait on (the gaps on a tie) in one call. Returns per generator
        (True, value) or (False, the exception it raised)."""
        out = [None] * len(gens)
        wait = {}

        def advance(i, value=None, exc=None):
            try:
                wait[i] = gens[i].send(value) if exc is None else gens[i].throw(exc)
            except StopIteration as stop:
                wait.pop(i, None)
                out[i] = (True, stop.value)
            except Exception as e:                   # noqa: BLE001  kept for whoever reads it
                wait.pop(i, None)
                out[i] = (False, e)

        for i in range(len(gens)):
            advance(i)
        while wait:
            lines = [i for i, req in wait.items() if req[0] is _LINES]
            gaps = [i for i, req in wait.items() if req[0] is _RATIOS]
            if len(lines) > len(gaps):
                new = [x for x in dict.fromkeys(x for i in lines for x in wait[i][1]) if x not in self._lines]
                try:
                    if new:
                        self._evaluate_lines(new)
                except GeometryError:
                    # which trials' lines are out of reach: each request again on its own
                    for i in lines:
                        new = [x for x in wait[i][1] if x not in self._lines]
                        try:
                            if new:
                                self._evaluate_lines(new)
                        except GeometryError as e:
                            advance(i, exc=e)
                        else:
                            advance(i)
                    continue
                for i in lines:
                    advance(i)
            elif len(gaps) == 1:
                i = gaps[0]
                req = wait[i]
                advance(i, self.ratios(req[1], req[2], req[3]))
            else:
                reqs = [wait[i] for i in gaps]
                G = [len(req[2]) for req in reqs]
                R = self.ratios(FrameGeom.concat([req[1] for req in reqs]),
                                _concatenate([np.asarray(req[2], float) for req in reqs]),
                                _concatenate([np.asarray(req[3], float).ravel() for req in reqs]))
                start = 0
                for i, g in zip(gaps, G):
                    advance(i, R[start:start + g])
                    start += g
        return out

    def ratio(self, g1: FrameGeom, ds: float, target_h: np.ndarray) -> float:
        """Largest cusp / target between line g1 and the line ds further."""
        return float(self.ratios(g1, np.array([ds]), target_h)[0])

    def ratios(self, g1: FrameGeom, ds: np.ndarray, target_h: np.ndarray) -> np.ndarray:
        """Largest cusp / target of G gaps at once: ``g1`` the samples of the G lines one
        after the other, ``ds`` (G,) the steps to their next lines, ``target_h`` per sample."""
        G = len(ds)
        self.evaluations += 2 * G
        h, ends = cusp_heights_many(self.frame, g1, ds, self.r)
        th = np.asarray(target_h, float).reshape(G, -1)
        rs = h / th
        with _quiet("invalid"):
            inner = _where(np.isnan(rs).all(axis=1), 0.0,
                             np.nanmax(_where(np.isnan(rs), -np.inf, rs), axis=1))
        return np.maximum(inner, np.maximum(ends[:, 0] / th[:, 0], ends[:, 1] / th[:, -1]))

    def first_order(self, g1: FrameGeom, target_h: np.ndarray) -> float:
        g = side_step(self.r, target_h, g1.cross_curvature())
        ds = parameter_step(g, g1.E, g1.F, g1.G)
        return float(np.min(ds))

    def target_at(self, s: float, target: Target) -> np.ndarray:
        """``target.at`` the samples of line s (computed once per line and target)."""
        return self._drive(self._target_at_g(s, target))

    def _target_at_g(self, s: float, target: Target):
        key = (float(s), target.h, target.undercut, target.max_step)
        th = self._targets.get(key)
        if th is None:
            g = yield from self._line_g(s)
            th = self._targets[key] = target.at(g)
        return th

    def first_order_at(self, s: float, target: Target) -> float:
        """:meth:`first_order` of line s (computed once per line and target)."""
        return self._drive(self._first_order_at_g(s, target))

    def _first_order_at_g(self, s: float, target: Target):
        key = (float(s), target.h, target.undercut, target.max_step)
        d0 = self._first.get(key)
        if d0 is None:
            g = yield from self._line_g(s)
            th = yield from self._target_at_g(s, target)
            d0 = self._first[key] = self.first_order(g, th)
        return d0

    def _secant_g(self, s: float, guess_factor: float, target: Target, first=None, known=None):
        """(ds, ratio, estimate of the uncapped step, correction factor) from line s, as a step
        of a trial, and the batch measured ahead (None if not); ``first``: a trial (ds, ratio)
        already measured, where the secant starts.
        ``known``: the (s values, first-order steps) of the placed lines when the trial goes on
        with a batch after this step (``first`` given): the secant's first candidate is then
        measured together with that batch's gaps (:meth:`_measure_ahead_g`)."""
        ahead = None
        g1 = yield from self._line_g(s)
        th = yield from self._target_at_g(s, target)
        d0 = yield from self._first_order_at_g(s, target)
        if not np.isfinite(d0) or d0 <= 0:
            raise GeometryError(f"{self.frame.patch.name}: no side step from the line at s = {s:.6f}")
        cap = 1.0 - s
        d = min(d0 * guess_factor, cap) if first is None else first[0]
        lo, lo_r, hi = 0.0, 0.0, np.inf
        hist = []
        for it in range(MAX_SECANT):
            if it == 0 and first is not None:
                R = first[1]
            elif it == 1 and known is not None and d < cap * (1 - 1e-12) and s + d < 1.0 - 1e-12:
                R, ahead = yield from self._measure_ahead_g(s, g1, th, d, d0, target, known)
            else:
                R = float((yield _RATIOS, g1, np.array([d]), th)[0])
            hist.append((d, R))
            if R <= FIT:
                if d > lo:
                    lo, lo_r = d, R
                if d >= cap * (1 - 1e-12):
                    full = cap * (AIM / R) ** 0.5 if R > 0 else np.inf
                    return (cap, R, max(full, cap), d / d0), None
                if R >= ACCEPT:
                    return (d, R, d, d / d0), ahead
            else:
                hi = min(hi, d)
            if len(hist) >= 2 and hist[-1][0] != hist[-2][0] and hist[-1][1] > 0 and hist[-2][1] > 0 \
                    and np.isfinite(hist[-1][1]) and np.isfinite(hist[-2][1]):
                p = np.log(hist[-1][1] / hist[-2][1]) / np.log(hist[-1][0] / hist[-2][0])
                p = float(min(max(p, 1.0), 4.0)) if np.isfinite(p) else 2.0
            else:
                p = 2.0
            nd = d * (AIM / R) ** (1.0 / p) if np.isfinite(R) and R > 0 else 0.5 * d
            if not lo < nd < hi:
                nd = np.sqrt(lo * hi) if lo > 0 and np.isfinite(hi) else (0.5 * d if nd >= hi else 2 * d)
            d = min(nd, cap)
        if lo > 0:
            return (lo, lo_r, lo, lo / d0), None
        d = min(hist[-1][0], cap)
        for _ in range(60):                      # nothing fitted: shrink until it does
            d *= 0.5
            R = float((yield _RATIOS, g1, np.array([d]), th)[0])
            if R <= FIT:
                return (d, R, d, d / d0), None
        raise GeometryError(f"{self.frame.patch.name}: the side step from the line at s = {s:.6f} "
                            f"does not converge (scallop {target.h:g} mm)")

    def _measure_ahead_g(self, s: float, g1: FrameGeom, th: np.ndarray, d: float, d0: float, target: Target,
                         known: tuple):
        """The cusp ratio of the secant's candidate step d from line s, measured in one call
        with the gaps of the batch the trial makes next if the secant takes d (almost always:
        the first candidate; the batch from s + d at the factor d / d0, its first-order steps
        extrapolated from ``known`` and s + d). Returns (ratio, the batch as :meth:`_run` gives
        it) when the secant takes d, else (ratio, None): then the batch's lines stay evaluated
        (the same lines whenever asked for) and its gaps are dropped. A line out of reach
        there ends the look ahead, and is met again if the trial comes to it."""
        s1 = s + d
        run = None
        try:
            d01 = yield from self._first_order_at_g(s1, target)
            if np.isfinite(d01) and d01 > 0:
                ks, kd = known
                if not ks or s1 > ks[-1]:
                    ks, kd = ks + [s1], kd + [d01]
                run = self._run_g(s1, float(min(max(d / d0, 0.25), 4.0)), target, LOOKAHEAD[0], (ks, kd))
                req = next(run)
                while req[0] is _LINES:
                    yield req
                    req = run.send(None)
        except GeometryError:
            if run is not None:
                run.close()
            run = None
        if run is None:
            return float((yield _RATIOS, g1, np.array([d]), th)[0]), None
        both = yield (_RATIOS, FrameGeom.concat([g1, req[1]]), _concatenate([np.array([d]), req[2]]),
                      _concatenate([np.asarray(th, float).ravel(), req[3]]))
        R = float(both[0])
        if not ACCEPT <= R <= FIT:                   # the secant goes on: the batch is not made
            run.close()
            return R, None
        try:
            req = run.send(both[1:])
            while True:
                req = run.send((yield req))
        except StopIteration as stop:
            return R, stop.value

    def _run(self, s: float, factor: float, target: Target, count: int, known: tuple):
        """Up to ``count`` steps from line s predicted at once (module doc): each the current
        correction factor times the first-order step, at the lines beyond s extrapolated from
        the exact first-order steps ``known`` (s values, steps) of the lines placed so far.
        All predicted lines in one evaluation, all their gaps in two. Returns the steps and
        their ratios up to and including the first that misses [ACCEPT, FIT] (or the last):
        the gaps are measured STAGE at a time, and those after a stage with a miss are not."""
        return self._drive(self._run_g(s, factor, target, count, known))

    def _run_g(self, s: float, factor: float, target: Target, count: int, known: tuple):
        ks, kd = known
        S, D = [s], []
        cur = s
        for j in range(count):
            if j == 0:
                d0 = kd[-1]
            elif len(ks) >= 2 and ks[-1] > ks[-2]:
                slope = (kd[-1] - kd[-2]) / (ks[-1] - ks[-2])
                d0 = min(max(kd[-1] + slope * (cur - ks[-1]), 0.5 * kd[-1]), 2.0 * kd[-1])
            else:
                d0 = kd[-1]
            d = min(d0 * factor, 1.0 - cur)
            D.append(d)
            cur = cur + d
            if cur >= 1.0 - 1e-12:
                break
            S.append(cur)
        # measured a stage at a time: the gaps past the first miss are never read
        geoms, th, R = [], [], []
        for a in range(0, len(D), STAGE):
            b = min(a + STAGE, len(D))
            # (the last stage with the line after the batch's last gap, where the next starts)
            part = yield from self._lines_g(S[a:] if b == len(D) else S[a:b])
            geoms += part
            g1 = FrameGeom.concat(part[:b - a]) if b - a > 1 else part[0]
            tha = target.at(g1).reshape(b - a, -1)
            for x, row in zip(S[a:b], tha):      # per sample, the same values as line by line
                self._targets.setdefault((float(x), target.h, target.undercut, target.max_step), row)
            if b - a > 1 or a > 0:
                # the first-order steps of the predicted lines in one go (place asks for each
                # line it keeps): the same values per sample, and the same least per line
                g = side_step(self.r, tha.ravel(), g1.cross_curvature())
                least = np.min(parameter_step(g, g1.E, g1.F, g1.G).reshape(b - a, -1), axis=1)
                for x, d0 in zip(S[a:b][1 if a == 0 else 0:], least[1 if a == 0 else 0:].tolist()):
                    self._first.setdefault((float(x), target.h, target.undercut, target.max_step), d0)
            Ra = yield _RATIOS, g1, np.array(D[a:b]), tha.ravel()
            th.append(tha)
            R.append(Ra)
            if b < len(D) and not ((ACCEPT <= Ra) & (Ra <= FIT)).all():
                break
        R = R[0] if len(R) == 1 else _concatenate(R)
        th = th[0] if len(th) == 1 else _concatenate(th)
        return S, D, R, geoms, th

    def place(self, target: Target) -> tuple[np.ndarray, np.ndarray, float]:
        """Line positions for ``target``, their gap ratios, and the estimated uncapped last step.

        Lines are placed a batch at a time (:meth:`_run`): the predicted steps are kept up to
        the first whose cusp misses [ACCEPT, FIT] of the target; that one is corrected by the
        secant (:meth:`_secant_g`) from the measured trial, and the next batch starts after it."""
        return self._drive(self._place_g(target))

    def _place_g(self, target: Target):
        s = 0.0
        pos, ratios = [0.0], []
        factor = 1.0
        full = np.nan
        ks, kd = [], []                            # exact first-order steps at placed lines
        count = LOOKAHEAD[0]
        ahead = None                               # the batch measured with the last secant
        while True:
            d0 = yield from self._first_order_at_g(s, target)
            if not np.isfinite(d0) or d0 <= 0:
                raise GeometryError(f"{self.frame.patch.name}: no side step from the line at s = {s:.6f}")
            if not ks or s > ks[-1]:
                ks.append(s), kd.append(d0)
            if ahead is not None:
                S, D, R, geoms, th = ahead
                ahead = None
            else:
                S, D, R, geoms, th = yield from self._run_g(s, factor, target, count, (ks, kd))
            done = False
            missed = None
            for j, (d, r_) in enumerate(zip(D, R)):
                last = S[j] + d >= 1.0 - 1e-12
                if last and r_ <= FIT:
                    cap = 1.0 - S[j]
                    full = max(cap * (AIM / r_) ** 0.5 if r_ > 0 else np.inf, cap)
                    ratios.append(float(r_))
                    pos.append(1.0)
                    done = True
                    break
                if last or not ACCEPT <= r_ <= FIT:
                    missed = j
                    break
                ratios.append(float(r_))
                pos.append(S[j + 1])
                if S[j + 1] > ks[-1]:
                    ks.append(S[j + 1])
                    kd.append((yield from self._first_order_at_g(S[j + 1], target)))
            if done:
                break
            if missed is None:
                s = S[-1]
                count = min(2 * count, LOOKAHEAD[1])
            else:
                s = S[missed]
                (d, r_, full, f), ahead = yield from self._secant_g(s, factor, target, (D[missed], float(R[missed])),
                                                                    (ks, kd))
                factor = float(min(max(f, 0.25), 4.0))
                count = LOOKAHEAD[0]
                ratios.append(r_)
                if s + d >= 1.0 - 1e-12:
                    pos.append(1.0)
                    break
                s = s + d
                pos.append(s)
            if len(pos) > 200000:
                raise GeometryError(f"{self.frame.patch.name}: more than 200000 lines: scallop "
                                    f"{target.h:g} mm is too small for this patch")
        return np.array(pos), np.array(ratios), full

    def balance(self, pos: np.ndarray, full: float, target: Target):
        """Scale the positions so the last gap is as full as the others (see module doc);
        returns (positions, ratios, factor) or None when a gap would exceed the limit."""
        if len(pos) < 3 or not np.isfinite(full):
            return None
        c = 1.0 / (pos[-2] + full)
        if c >= 0.999:
            return None
        new = np.append(pos[:-1] * c, 1.0)
        # every gap at once: the lines in one evaluation, their cusps in two
        m = len(self.t)
        G = len(new) - 1
        g1 = self.frame.evaluate(np.repeat(new[:-1], m), np.tile(self.t, G))
        ratios = self.ratios(g1, np.diff(new), target.at(g1))
        if ratios.max() > FIT:
            return None
        return new, ratios, c

    def tuned(self, parity: int | None, balance: bool = True) -> LinePlacement:
        """Positions whose count has the given parity (0 even, 1 odd; None: any), by the
        paper's scallop tuning.

        The trials are the paper's, in its order (:func:`_tuning_next`); a trial the count
        of the first predicts to be needed after the next one is run together with it
        (:meth:`_lockstep`, :func:`_tuning_ahead`) and used only if the tuning comes to it."""
        h = self.target.h
        trials = []
        results = []                                      # (factor, result) of every trial
        ahead_of = {}                                     # factor -> (ok, result) run ahead

        def run(factor, ahead=()):
            tg = self.target.scaled(factor)
            if factor in ahead_of:
                ok, res = ahead_of.pop(factor)
                if not ok:
                    raise res
                pos, ratios, full = res
            elif any(f not in ahead_of for f in ahead):
                fs = [factor] + [f for f in ahead if f not in ahead_of]
                got = self._lockstep([self._place_g(self.target.scaled(f)) for f in fs])
                ahead_of.update(zip(fs[1:], got[1:]))
                ok, res = got[0]
                if not ok:
                    raise res
                pos, ratios, full = res
            else:
                pos, ratios, full = self.place(tg)
            trials.append((h * factor, len(pos)))
            results.append((factor, (pos, ratios, full, tg)))
            return results[-1][1]

        best = run(1.0)
        n0 = len(best[0])
        if parity is not None and n0 % 2 != parity:
            found = None
            gaps0 = _gaps(best[0], best[2])
            state = ("down", 1, 1.0, None)
            while True:
                f = _tuning_next(state)
                if f is None:
                    break
                res = run(f, _tuning_ahead(state, n0, gaps0))
                state = _tuning_after(state, f, len(res[0]), n0)
                if state is None:
                    found = res
                    break
            if found is None:
                # the count jumped over n0 + 1 (the accepted steps move in steps too): take
                # the largest scallop whose count has the needed parity (not the first trial's)
                ok = [(f, res) for f, res in results if len(res[0]) % 2 == parity]
                if not ok:
                    raise GeometryError(f"{self.frame.patch.name}: scallop tuning found no line "
                                        f"count of the needed parity down to 0.1 h")
                found = max(ok, key=lambda x: x[0])[1]
            best = found
        pos, ratios, full, tg = best
        out = LinePlacement(pos, tg.h, ratios, trials)
        if balance:
            b = self.balance(pos, full, tg)
            if b is not None:
                out.s, out.ratio, out.balanced = b
        return out


# The parity tuning (section 3.5) as states: ("down", j, hi, None) before the descent's trial
# j (h (1 - 0.1 j)), ("bisect", k, hi, lo) before bisection step k between the last scallop
# with n0 lines or fewer (hi) and an overshoot (lo).

def _tuning_next(state) -> float | None:
    """The factor of h the tuning tries next in ``state``; None when it has no more."""
    phase, j, hi_f, lo_f = state
    if phase == "down":
        return 1.0 - 0.1 * j if j < 10 else None
    if j >= MAX_TUNING or hi_f - lo_f < 1e-6:
        return None
    return 0.5 * (hi_f + lo_f)


def _tuning_after(state, f: float, n: int, n0: int):
    """The state after trial ``f`` gave ``n`` lines (None: n0 + 1, found)."""
    if n == n0 + 1:
        return None
    phase, j, hi_f, lo_f = state
    if phase == "down":
        return ("bisect", 0, hi_f, f) if n > n0 + 1 else ("down", j + 1, f, None)
    return ("bisect", j + 1, f, lo_f) if n <= n0 else ("bisect", j + 1, hi_f, f)


AHEAD_MARGIN = 0.75      # gaps the predicted count must clear a decision by to run a trial ahead
AHEAD_POWER = 0.55       # the count of gaps goes as the scallop to the power -AHEAD_POWER
AHEAD_MAX = 3            # trials run ahead of the next at most


def _gaps(pos: np.ndarray, full: float) -> float:
    """A trial's count of gaps as a real number: the last one as the part of the uncapped step
    it uses."""
    n = len(pos)
    if n < 3 or not np.isfinite(full) or full <= 0:
        return float(n - 1)
    return (n - 2) + min((1.0 - float(pos[-2])) / full, 1.0)


def _tuning_ahead(state, n0: int, gaps0: float) -> tuple:
    """The factors the tuning would try after the next one if each trial's count were the one
    the first trial predicts (``gaps0`` / f^AHEAD_POWER gaps), as long as the prediction
    clears its decision by AHEAD_MARGIN (at most AHEAD_MAX). Whatever runs ahead only saves
    calls: the tuning's path is decided by the counts it measures. (On the sample models, six
    jobs, the prediction gave the measured count of 37 of 40 tuning trials, one line too many
    in the others.)"""
    out = []
    f = _tuning_next(state)
    while f is not None and len(out) < AHEAD_MAX:
        x = gaps0 * f ** -AHEAD_POWER
        if x > n0 + AHEAD_MARGIN:
            n = n0 + 2                           # an overshoot
        elif x <= n0 - 1 - AHEAD_MARGIN:
            n = n0                               # still n0 lines or fewer
        else:
            break                                # n0 + 1 (the tuning ends) or too close to call
        state = _tuning_after(state, f, n, n0)
        f = _tuning_next(state)
        if f is not None:
            out.append(f)
    return tuple(out)


def parity_for(frame: LineFrame, finish: int | None) -> int | None:
    """Needed parity of the line count so the zigzag ends at corner ``finish`` (None: any).

    Raises InputError when the finish is not on the far side of the crossfeed."""
    if finish is None:
        return None
    fu, fv = CORNER_UV[finish]
    fs = fu if frame.crossfeed == "u" else fv
    if frame.s_flip:
        fs = 1 - fs
    ft = fv if frame.crossfeed == "u" else fu
    if fs != 1:
        raise InputError(f"finish corner {CORNER_NAMES[finish]} is on the start corner's side "
                         f"{'u' if frame.crossfeed == 'u' else 'v'} = "
                         f"{int(CORNER_UV[frame.start][0 if frame.crossfeed == 'u' else 1])}; "
                         f"crossfeed {frame.crossfeed} cannot reach it", item=frame.patch.name)
    # line k ends at t0 for odd k: the last line (n - 1) ends at 1 - t0 when n is odd
    return 1 if ft != frame.t0 else 0          # exact: both are corner coordinates, 0.0 or 1.0
