"""Metrics of an oriented tool path (docs/post.md section 5.2): collisions, clearance, smoothness,
rotary travel and machining time.

* collisions: poses whose flutes, shank or holder touch the workpiece, asked of fcl with
  the tool as primitives (``CollisionChecker.collides_exact``: Cylinder / Convex; a pose
  the broad phase or the circumscribed tool mesh, which contains them, clears is clear for
  them too), and ball gouges (the shrunk-ball check); both must be 0.
* smallest clearance: fcl distance between the tool parts that keep the clearance (shank
  and holder; the flutes cut, so next to the contact they come as close as the tilt puts
  them) and the tessellated workpiece, plus the margin the checker grew them by. Computed
  exactly only on the poses that come closest: the smallest clearance of a few poses spread
  along the path bounds it, or the smallest of the growths 0.05, 0.1, 0.2 ... mm at which some
  pose touches is found; the growth is bisected until a few dozen touch, and fcl.distance runs
  on those. A pose's figure is at most its true distance: measured to the parts grown by
  the margin in every direction (boxed at the rims, up to 0.41 of the margin beyond the true
  offset), and from below a bottom another solid covers too (the shank's on the flutes),
  where the growths do not grow (the flutes rule there), so a pose nearest the workpiece from
  below it need not touch at a growth above its clearance and can be left out of the
  bisection: on the keycap tilted 20 deg the search gives 1.42795 mm where fcl.distance at
  every pose gives 1.42766 mm (tests/verify/test_verify_clearance.py keeps that known-failing
  case); the gauge (:class:`ClearanceGauge`) measures above such a bottom only when asked.
* angular change per block ``arccos(K_i . K_i+1)``: largest and mean over cutting blocks;
  total variation; per mm.
* rotary travel for an A/C table machine: ``sum |dA| + |dC|`` with the machine poses of
  tsplcam.post (branch choice and C unwinding by its dynamic programme), or, without a
  machine, with A = acos(Kz), C = atan2(Kx, -Ky) (ISO A/C, docs/post.md section 1) unwound.
* time: with a machine, tsplcam.post.timing.estimate (per-axis velocity and acceleration
  limits on the machine's joint moves, tip length over feed as each block's minimum);
  without one, the simple model ``t_i = max(L_i / F, |dA_i| / vA, |dC_i| / vC)``.
  Average axis speed = axis travel / total time, as xu2013 section 7.3 reports it.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass, field

import numpy as np

from ..numerics import components
from ..toolpath.path import Move, ToolPath

DEG = np.pi / 180.0


def _angle(a, b):
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.einsum("...i,...i->...", a, b))


@dataclass
class OrientationMetrics:
    points: int
    collisions: int                  # tool parts touching (fcl primitives)
    gouges: int                      # ball deeper than the gouge tolerance
    min_clearance: float             # mm, tool parts to workpiece
    min_clearance_point: int
    max_step_deg: float              # cutting blocks
    mean_step_deg: float
    total_variation_deg: float
    max_step_per_mm: float           # deg/mm
    rotary_travel_deg: float         # sum |dA| + |dC|
    tilt_travel_deg: float
    c_travel_deg: float
    time_s: float
    feed_time_s: float               # path length over feed alone
    average_linear_speed: float      # mm/min, mean of X, Y, Z travel / time
    average_rotary_speed: float      # deg/min, mean of A, C
    machine: str = "simple A/C model"
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}

    def summary(self) -> str:
        return (f"{self.points} points: collisions {self.collisions}, gouges {self.gouges}, smallest "
                f"clearance {self.min_clearance:.3f} mm; axis step max {self.max_step_deg:.2f} deg, mean "
                f"{self.mean_step_deg:.3f} deg, total {self.total_variation_deg:.0f} deg; rotary travel "
                f"{self.rotary_travel_deg:.0f} deg (A {self.tilt_travel_deg:.0f}, C {self.c_travel_deg:.0f}); "
                f"time {self.time_s:.1f} s (feed alone {self.feed_time_s:.1f} s), average axis speed "
                f"{self.average_linear_speed:.0f} mm/min, {self.average_rotary_speed:.0f} deg/min "
                f"[{self.machine}]")


# the growths (mm) the smallest clearance asks at. An ask of every pose at a growth where many
# touch costs the most (the broad phase proves none of them touching: fcl is asked, and the
# side pass first tries every one with balls that large): figure4's job (74,774 poses,
# clearance 1.61 mm) asked 10 mm after 5 mm, where 46k touched: 17.6 s of the search's
# 16-22 s. With levels 1 mm apart from 2 to 8 mm it first touches at 7 mm: 11-13 s, the
# smallest clearance 1.614524 mm at another pose, 1e-5 mm below the 1.614534 mm of the
# coarser bracket's picks (the bisection's picks are the poses that touch at its last
# growths; poses within its 1e-4 mm can come out either way). Searches that touch at 0.5 mm
# (the keycap's, the molds') do not ask above it: the same figures.
CLEARANCE_LEVELS = (0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 10.0, 14.0, 20.0)
# poses touching beyond which min_clearance's bisection narrows by a spread quarter of this
# many first
SAMPLED = 4096


def min_clearance(checker, centers, axes, levels=CLEARANCE_LEVELS, exact: int = 40, first: int = 3,
                  scouts: int = 32):
    """(smallest clearance in mm, index of the pose) over the poses, see the module: of the
    parts that keep the clearance (every part but the flutes, :meth:`clearance_parts`), the
    distance plus the margin they were grown by.

    The smallest growth among ``levels`` at which some pose touches is found, the growth is
    bisected between it and the level below among the touching poses until at most ``exact``
    are left (the closest pose touches at every growth above its clearance), and fcl.distance
    runs on those only: each distance query costs tens of ms against a fine workpiece mesh.
    A pose that touches at some growth touches at every larger one, so every pose is asked
    only at ``levels[first]`` (and above while none touches there), and below a growth where
    poses touched only those poses, about the parts the broad phase could not clear there;
    the bisection's first step is taken before the level below is asked (whatever touches
    there touches at the step), so that level is asked of fewer poses.

    ``scouts`` poses spread along the path go first. Where some touch at ``levels[first]``,
    the smallest clearance among those bounds the answer (:func:`_bounded`): every pose is
    asked at that growth only, and the growth is bisected below it among the poses touching
    there (keycap: 14.7k poses asked once at 0.30 mm, 13 touch; the descent asked 14.7k at
    0.5 and 5.5k, 1.5k, 1.5k, 1.5k below). Else (:func:`_scouted`): the lowest level at
    which one touches is asked of every pose instead of ``levels[first]``, and the levels
    above of the poses touching there only; where more than ``exact`` of those touch at every
    level above, the search stands where the descent from ``levels[first]`` would stand, with
    the same poses (the same answer, from about half the collision queries), else it runs
    that descent. Where no scout touches at ``levels[first]``, they go up the levels first
    (:func:`_ascended`): every pose is asked at the level below the first at which a scout
    touches, and at that one where none touches below (else only those touching go further
    down), and the search stands where the ascent over every pose would (figure4: 4.7 -> 2.8
    s)."""
    C = np.asarray(centers, float)
    A = np.asarray(axes, float)
    levels = sorted(levels)
    only, margin = checker.clearance_parts()
    start = min(first, len(levels) - 1)
    pick, lo, hi, steps = None, 0.0, None, 20
    bound = _bounded(checker, C, A, levels[start], only, scouts) if scouts else None
    got = _scouted(checker, C, A, levels, start, only, exact, scouts) if scouts and bound is None else None
    if bound is not None:
        pick, parts, hi, lo = bound
        top, j = hi, -1                           # no level to descend: bisect below the bound
    elif got is not None:
        pick, parts, j = got
        hi = top = levels[j]
    elif (up := _ascended(checker, C, A, levels, start, only, scouts) if scouts else None) is not None:
        pick, parts, j = up
        hi = top = levels[j]
        lo = levels[j - 1] if j > start else 0.0
    else:
        for i in range(start, len(levels)):
            hit, parts = checker.collides_parts(C, A, levels[i], only=only)
            if hit.any():
                pick, hi, parts, top, j = np.nonzero(hit)[0], levels[i], parts[hit], levels[i], i
                break
            lo = levels[i]

    def touching(sel, masks, g):
        return checker.collides_parts(C[sel], A[sel], g, parts=(top, masks), only=only)[0]

    def narrow(sel, masks, lo, hi, steps=None):
        """Bisect the growth between lo (none of ``sel`` touches) and hi (some do) among the
        poses ``sel`` touching at hi, until at most ``exact`` are left, the bracket is 1e-4 mm,
        or after ``steps`` halvings: (poses, masks, lo, hi)."""
        k = 0
        while len(sel) > exact and hi - lo >= 1e-4 and (steps is None or k < steps):
            mid = 0.5 * (lo + hi)
            hit = touching(sel, masks, mid)
            if hit.any():
                sel, masks, hi = sel[hit], masks[hit], mid
            else:
                lo = mid
            k += 1
        return sel, masks, lo, hi

    if pick is not None and j <= start:
        while j > 0:
            below = levels[j - 1]
            if len(pick) > exact and hi - below >= 1e-4:
                mid = 0.5 * (below + hi)
                at_mid = touching(pick, parts, mid)
                if not at_mid.any():                      # then none touches below either
                    lo, steps = mid, steps - 1
                    break
                p2, m2 = pick[at_mid], parts[at_mid]
                at_below = touching(p2, m2, below)
                if not at_below.any():
                    lo, hi, pick, parts, steps = below, mid, p2, m2, steps - 1
                    break
                pick, parts, hi = p2[at_below], m2[at_below], below
            else:
                at_below = touching(pick, parts, below)
                if not at_below.any():
                    lo = below
                    break
                pick, parts, hi = pick[at_below], parts[at_below], below
            j -= 1
    if pick is None:
        pick = np.arange(len(C))[:: max(1, len(C) // 200)]
    else:
        for _ in range(steps):
            if len(pick) <= exact or hi - lo < 1e-4:
                break
            if len(pick) > SAMPLED:
                # many poses touch: a spread sample of them is bisected first, and every pose
                # asked at the growth where the sample's closest touch (no pose lies closer
                # than the closest of all), so the bisection goes on among those
                row = np.linspace(0, len(pick) - 1, SAMPLED // 4).astype(int)
                s_hi = narrow(pick[row], parts[row], lo, hi)[3]
                if s_hi < hi:
                    hit = touching(pick, parts, s_hi)
                    pick, parts, hi = pick[hit], parts[hit], s_hi
                    continue
            pick, parts, lo, hi = narrow(pick, parts, lo, hi, steps=1)
    if len(pick) > 400:
        pick = pick[np.linspace(0, len(pick) - 1, 400).astype(int)]
    d = _smallest_of(checker, C[pick], A[pick], only, hi) + margin
    k = int(np.argmin(d))
    return float(d[k]), int(pick[k])


def _smallest_of(checker, C, A, only: int, touch: float | None) -> np.ndarray:
    """:meth:`clearance_of` the poses (``smallest``): all touch at growth ``touch`` (None:
    not known), so their smallest distance lies within :meth:`touching_bound` of it, and a
    part farther is not measured (the same smallest value and first pose)."""
    below = np.inf if touch is None else checker.touching_bound(touch)
    d = checker.clearance_of(C, A, only, smallest=True, below=below)
    if np.isfinite(below) and not np.isfinite(d).any():      # (the bound is a proof: not expected)
        d = checker.clearance_of(C, A, only, smallest=True)
    return d


def _scout_rows(n: int, scouts: int) -> np.ndarray:
    """The rows of the ``scouts`` poses spread evenly along a path of ``n`` poses."""
    return np.unique(np.linspace(0, n - 1, min(scouts, n)).astype(int))


def _bounded(checker, C, A, level: float, only: int, scouts: int, slack: float = 1e-4):
    """(poses touching, their part masks, growth, a growth at which none touches, or 0) at the
    smallest clearance of the ``scouts`` poses spread along the path that touch at ``level``
    (measured, :meth:`clearance_of`) and ``slack`` more: every pose at most as far touches
    there (the grown tool mesh contains the grown primitives), the closest among them, so
    :func:`min_clearance` bisects below that growth instead of descending the levels. None
    where no scout touches at ``level`` or their clearance is not below it."""
    s = _scout_rows(len(C), scouts)
    hit, _ = checker.collides_parts(C[s], A[s], level, only=only)
    if not hit.any():
        return None
    near = s[hit]
    d = _smallest_of(checker, C[near], A[near], only, level)
    g = float(d.min()) + slack
    if not g < level:
        return None
    k = near[[int(np.argmin(d))]]                  # the closest scout
    below = 0.0
    if checker.collides_parts(C[k], A[k], g, only=only)[0].any():
        hit, parts = checker.collides_parts(C, A, g, only=only)
        if not hit.any():                         # (the scout touches: not expected)
            return None
    else:
        # the closest scout measured nearer than it touches: a distance to a part's covered
        # bottom, which the growths do not grow (below it the flutes rule; see the module), so
        # that distance bounds nothing. The smallest growth at which one of these scouts
        # touches (bisected between there and ``level``) bounds instead; every pose is asked
        # between the two, bisecting up from the middle, until some touch: few do that near
        # the nearest (the keycap's cone-bound axes: none at the scout's 0.3026 mm, 5 at
        # 0.3218, 1,059 at the scouts' 0.3409, where asking every pose at both and narrowing
        # took 0.11 s more)
        lo, hi = g, level
        while hi - lo >= 10 * slack:                 # (an upper bound: 1e-3 mm will do)
            mid = 0.5 * (lo + hi)
            if checker.collides_parts(C[near], A[near], mid, only=only)[0].any():
                hi = mid
            else:
                lo = mid
        if not hi < level:
            return None
        low, top = g, hi
        while True:
            g = top if top - low < 2 * slack else 0.5 * (low + top)
            hit, parts = checker.collides_parts(C, A, g, only=only)
            if hit.any() or g == top:
                break
            low = below = g                      # (none touches there)
        if not hit.any():                         # (a scout touches at the top: not expected)
            return None
    return np.nonzero(hit)[0], parts[hit], g, below


def _ascended(checker, C, A, levels, start: int, only: int, scouts: int):
    """Where :func:`min_clearance`'s ascent over every pose from ``levels[start]`` stops,
    found by its scouts: (poses touching, their part masks, level index) or None. The
    ``scouts`` poses spread along the path are asked at ``levels[start]`` and up until one
    touches, at level k. Every pose is asked at the level below k; where none touches there,
    the ascent stops at k (every pose asked there); else only the poses touching there are
    asked at the levels below it, down to the last at which some touch (a pose that touches at
    some growth touches at every larger one, so those are the poses every pose's ask there
    gives; their part masks come from asks of fewer poses, which only spares fcl questions).
    None where no scout touches at any level. figure4 (74,774 poses, its clearance found at
    7 mm): the scouts first touch at 7 mm, so every pose is asked at 6 and 7 mm only, not at
    0.5, 1, 2, 3, 4 and 5 mm as well (about 2 s of collision queries, fcl's nearly all: the
    broad phase proves no pose clear there)."""
    s = _scout_rows(len(C), scouts)
    for k in range(start, len(levels)):
        if checker.collides_parts(C[s], A[s], levels[k], only=only)[0].any():
            break
    else:
        return None
    if k > start:
        hit, parts = checker.collides_parts(C, A, levels[k - 1], only=only)
        if hit.any():
            pick, parts, k = np.nonzero(hit)[0], parts[hit], k - 1
            while k > start:
                below, masks = checker.collides_parts(C[pick], A[pick], levels[k - 1], only=only)
                if not below.any():
                    break
                pick, parts, k = pick[below], masks[below], k - 1
            return pick, parts, k
    hit, parts = checker.collides_parts(C, A, levels[k], only=only)
    return np.nonzero(hit)[0], parts[hit], k


def _descent(levels, start: int, stop: int) -> list:
    """The growths :func:`min_clearance`'s descent asks from ``levels[start]`` down to
    ``levels[stop]`` while more than ``exact`` poses touch at each: the start, and per level
    below the step halfway to it (where the levels are 1e-4 apart or more) and the level."""
    out = [levels[start]]
    for j in range(start, stop, -1):
        if levels[j] - levels[j - 1] >= 1e-4:
            out.append(0.5 * (levels[j - 1] + levels[j]))
        out.append(levels[j - 1])
    return out


def _scouted(checker, C, A, levels, start: int, only: int, exact: int, scouts: int):
    """Where :func:`min_clearance`'s descent from ``levels[start]`` would stand, found from
    below: (poses touching, their part masks, level index) or None. The ``scouts`` poses
    spread along the path are asked at ``levels[start]`` and the levels below it while one
    touches; at the lowest such level below the start every pose is asked, and the poses
    touching there are asked at every growth the descent asks above it (a pose that stops
    touching on the way down is not among the descent's). More than ``exact`` left: the
    descent, which goes on while more than ``exact`` touch (their superset), stands there with
    exactly these poses; else None (the caller descends from the start)."""
    s = _scout_rows(len(C), scouts)
    low = None
    for j in range(start, -1, -1):
        if not checker.collides_parts(C[s], A[s], levels[j], only=only)[0].any():
            break
        low = j
    if low is None or low == start:
        return None
    hit, parts = checker.collides_parts(C, A, levels[low], only=only)
    pick = np.nonzero(hit)[0]
    parts = parts[hit]
    for g in _descent(levels, start, low)[:-1]:
        if len(pick) <= exact:
            break
        keep = checker.collides_parts(C[pick], A[pick], g, only=only)[0]
        pick, parts = pick[keep], parts[keep]
    if len(pick) <= exact:
        return None
    return pick, parts, low


def clearance_levels(top: float = 10.0, step: float = 0.01, ratio: float = 1.02) -> np.ndarray:
    """Growths (mm) :func:`clearance_profile` tries: every ``step`` up to 0.5 mm, then
    geometric by ``ratio`` up to ``top``."""
    fine = np.arange(0.0, 0.5, step)
    coarse = 0.5 * ratio ** np.arange(int(np.ceil(np.log(top / 0.5) / np.log(ratio))) + 1)
    return np.unique(np.concatenate([fine, np.minimum(coarse, top)]))


def offset_profile(part, grow: float, max_angle: float = 15.0, bottom: bool = True):
    """The (radius, height) profile of a tool part (a frustum about the axis) grown by ``grow``
    mm in every direction, i.e. of its Minkowski sum with a ball: from the axis at the bottom
    to the axis at the top, the corners rounded by arcs drawn as circumscribed polylines of
    at most ``max_angle`` degrees a segment. A body of revolution is closest to a point in the
    point's meridian plane, so offsetting the profile offsets the solid; the polyline contains
    the arcs and strays from them by at most ``grow * (1 / cos(max_angle / 2) - 1)``.
    ``bottom`` False: only the points at or above the part's bottom (a bottom another solid of
    the tool covers, :meth:`~tsplcam.orientation.tool.Tool.exposed_ends`: below it that
    solid's distance counts, as in the checker), the profile cut flat there."""
    if grow <= 0:
        return np.array([0.0, part.r0, part.r1, 0.0]), np.array([part.z0, part.z0, part.z1, part.z1])
    normal = -np.arctan2(part.r1 - part.r0, part.z1 - part.z0)     # the side's outward normal
    r, z = [0.0], [part.z0 - grow]
    for (cr, cz), a0, a1 in (((part.r0, part.z0), -0.5 * np.pi, normal), ((part.r1, part.z1), normal, 0.5 * np.pi)):
        n = max(1, int(np.ceil(np.degrees(a1 - a0) / max_angle)))
        step = (a1 - a0) / n
        mid = a0 + (np.arange(n) + 0.5) * step                     # tangents at a0, a0 + step, ... meet here
        ends = np.array([a0, a1])
        g = grow / np.cos(0.5 * step)
        r += [cr + grow * np.cos(ends[0]), *(cr + g * np.cos(mid)), cr + grow * np.cos(ends[1])]
        z += [cz + grow * np.sin(ends[0]), *(cz + g * np.sin(mid)), cz + grow * np.sin(ends[1])]
    r.append(0.0)
    z.append(part.z1 + grow)
    if bottom:
        return np.array(r), np.array(z)
    return _above(np.array(r), np.array(z), part.z0)


def _above(r: np.ndarray, z: np.ndarray, z0: float):
    """The profile (from the axis to the axis, closed along it) cut to ``z >= z0``: the
    polygon clipped by the half-plane (its edges crossing ``z0`` cut there), from the axis
    at ``z0`` to the axis at the top."""
    pts = list(zip(r.tolist(), z.tolist()))
    out, start = [], None
    for (ra, za), (rb, zb) in zip(pts, pts[1:]):                  # (the axis edge adds nothing)
        if za >= z0:
            out.append((ra, za))
        if (za >= z0) != (zb >= z0):
            t = (z0 - za) / (zb - za)
            start = len(out) if start is None else start            # the first point on the cut
            out.append((ra + t * (rb - ra), z0))
    out.append(pts[-1])
    body = [(0.0, z0)]
    for p in out[start:]:
        if abs(p[0] - body[-1][0]) + abs(p[1] - body[-1][1]) > 1e-12:   # (an arc's end on the cut)
            body.append(p)
    rr, zz = (np.array(c, float) for c in zip(*body))
    return rr, zz


def revolved_mesh(profiles, polygon_tolerance: float = 0.01):
    """Closed triangle meshes (vertices, triangles) of profiles (radius, height) revolved about
    +z, one per profile, joined: each ring a polygon circumscribing its circle within
    ``polygon_tolerance``, the first and last profile points on the axis."""
    from ..orientation.collision import polygon_segments
    V, T = [], []
    base = 0
    for r, z in profiles:
        r, z = np.asarray(r, float), np.asarray(z, float)
        n = polygon_segments(float(r.max()), polygon_tolerance)
        a = np.arange(n) * 2.0 * np.pi / n
        ring = np.column_stack([np.cos(a), np.sin(a)]) / np.cos(np.pi / n)
        m = len(r) - 2                                             # rings
        rings = np.concatenate([(ring[None, :, :] * r[1:-1, None, None]).reshape(-1, 2),
                                np.repeat(z[1:-1], n)[:, None]], axis=1)
        pts = np.vstack([[0.0, 0.0, z[0]], rings, [0.0, 0.0, z[-1]]])
        k = np.arange(n)
        k1 = (k + 1) % n
        tri = [np.column_stack([np.zeros(n, int), 1 + k1, 1 + k])]
        for i in range(m - 1):
            lo, hi = 1 + i * n, 1 + (i + 1) * n
            tri += [np.column_stack([lo + k, lo + k1, hi + k1]), np.column_stack([lo + k, hi + k1, hi + k])]
        top = 1 + m * n
        tri.append(np.column_stack([np.full(n, top), 1 + (m - 1) * n + k, 1 + (m - 1) * n + k1]))
        V.append(pts)
        T.append(np.concatenate(tri) + base)
        base += len(pts)
    return np.concatenate(V), np.concatenate(T)


# Grown tools of the clearance gauges, per checker (built once, kept while the checker lives).
_GROWN = weakref.WeakKeyDictionary()


class ClearanceGauge:
    """Distances between some tool parts and a checker's workpiece (its triangles: model,
    stock, fixtures), for plots along a path.

    ``parts``: names of the tool parts measured (default every part but the flutes: the shank
    and holder). :meth:`measure` grows the parts (:func:`offset_profile`) and brackets each
    pose's distance by bisection over the growths of :func:`clearance_levels`: about eight BVH
    collision queries a pose instead of one fcl distance query (tens of ms) a pose. The grown
    tools are built once per growth and kept with the checker, so later calls and later gauges
    on the same checker are cheaper. The distance is to each part's whole solid; ``covered``:
    below a part's bottom that another solid of the tool covers (the shank's on flutes as
    wide, :meth:`~tsplcam.orientation.tool.Tool.exposed_ends`) nothing is measured, as the
    checker keeps the clearance only above it (below it the flutes, which cut, rule). The
    report draws whole solids: measured above the bottom only, a shank a millimetre over a
    flat top read more than 10 mm on the keycap (the top of the flutes is what is near)."""

    def __init__(self, checker, parts=None, top: float = 10.0, step: float = 0.01, ratio: float = 1.02,
                 covered: bool = False):
        import fcl

        from ..orientation.collision import _bvh
        names = [p.name for p in checker.tool.parts()]
        keep = [(p, lo) for p, (lo, _) in zip(checker.tool.parts(), checker.tool.exposed_ends())
                if (p.name in parts if parts is not None else p.name != "flutes")]
        self.parts = [p for p, _ in keep]
        self._bottoms = [lo or not covered for _, lo in keep]
        if not self.parts:
            raise ValueError(f"no tool part named {parts!r} (parts: {names})")
        self.levels = clearance_levels(top, step, ratio)
        self.polygon_tolerance = checker.polygon_tolerance
        # the checker's own workpiece object (its BVH takes seconds to build on big models),
        # else one built from its triangles
        self._wp = getattr(checker, "_wp", None)
        if self._wp is None:
            mesh = checker.mesh
            self._wp = fcl.CollisionObject(_bvh(mesh.vertices, mesh.triangles), fcl.Transform())
        self._req = fcl.CollisionRequest()
        self._tools = _GROWN.setdefault(checker, {})
        self._key = (tuple(self.parts), tuple(self._bottoms))

    def _tool(self, m: int):
        g = float(self.levels[m])
        key = (self._key, g)
        if key not in self._tools:
            import fcl

            from ..orientation.collision import _bvh
            # as fine as the bracket needs: polygons within the checker's tolerance or 1 % of the
            # growth, arcs within 0.005 mm or 1 % of it
            arc = 2.0 * np.degrees(np.arccos(g / (g + max(0.005, 0.01 * g)))) if g > 0 else 15.0
            V, T = revolved_mesh([offset_profile(p, g, max_angle=float(np.clip(arc, 15.0, 60.0)), bottom=lo)
                                  for p, lo in zip(self.parts, self._bottoms)],
                                 max(self.polygon_tolerance, 0.01 * g))
            self._tools[key] = fcl.CollisionObject(_bvh(V, T), fcl.Transform())
        return self._tools[key]

    def _collides(self, C, Q, idx, m: int) -> np.ndarray:
        import fcl
        obj, wp, req = self._tool(m), self._wp, self._req
        hit = np.zeros(len(idx), bool)
        for j, i in enumerate(idx.tolist()):
            obj.setQuatRotation(Q[i])
            obj.setTranslation(C[i])
            hit[j] = fcl.collide(obj, wp, req, fcl.CollisionResult()) > 0
        return hit

    def measure(self, centers, axes) -> np.ndarray:
        """Distance (mm) per pose (ball centre, unit axis), inf beyond the top level: the
        middle of the bracket, so within ``step / 2`` below 0.5 mm and ``(ratio - 1) / 2`` of the
        value above, less at most the polygon tolerance (circumscribed polygons: the checker's,
        or 1 % of the growth when larger) and the corner arcs of :func:`offset_profile`
        (0.005 mm or 1 % of the growth). No margin is added: the distance itself."""
        from ..orientation.collision import axis_quaternions
        C = np.asarray(centers, float).reshape(-1, 3)
        Q = axis_quaternions(np.asarray(axes, float).reshape(-1, 3))
        k = len(self.levels)
        lo = np.full(len(C), -1)
        hi = np.full(len(C), k)
        while True:
            act = np.nonzero(hi - lo > 1)[0]
            if len(act) == 0:
                break
            mid = (lo[act] + hi[act]) // 2
            for m in np.unique(mid):
                sel = act[mid == m]
                hit = self._collides(C, Q, sel, int(m))
                hi[sel[hit]] = m
                lo[sel[~hit]] = m
        out = np.full(len(C), np.inf)
        got = hi < k
        out[got] = 0.5 * (self.levels[np.maximum(lo[got], 0)] + self.levels[hi[got]])
        return out


def clearance_profile(checker, centers, axes, parts=None, top: float = 10.0, step: float = 0.01,
                      ratio: float = 1.02, covered: bool = False) -> np.ndarray:
    """Distance (mm) of every pose between the tool parts (default: shank and holder) and the
    checker's workpiece, inf beyond ``top``; see :class:`ClearanceGauge`."""
    return ClearanceGauge(checker, parts, top, step, ratio, covered).measure(centers, axes)


def _simple_ac(axis):
    """ISO A/C angles (deg) (docs/post.md section 1), C unwound, held through the pole."""
    kx, ky, kz = components(axis)        # (contiguous: the same ufunc code whatever the heap)
    A = np.degrees(np.arctan2(np.hypot(kx, ky), kz))
    C = np.degrees(np.arctan2(kx, -ky))
    pole = A < 1e-6
    if pole.all():
        C = np.zeros(len(kx))
    else:
        good = np.nonzero(~pole)[0]
        C = C[good[np.clip(np.searchsorted(good, np.arange(len(kx))), 0, len(good) - 1)]]
    dC = np.diff(C)
    dC = (dC + 180.0) % 360.0 - 180.0
    C = C[0] + np.concatenate([[0.0], np.cumsum(dC)])
    return A, C


def orientation_metrics(path: ToolPath, checker=None, machine=None, v_rotary=(5400.0, 9000.0),
                        clearance: bool = True, gouges: int | None = None,
                        measured=None, joints=None) -> OrientationMetrics:
    """Metrics of ``path`` (its axes). ``checker``: the CollisionChecker the path was oriented
    with (None skips collisions and clearance); ``machine``: a tsplcam.post Machine (or name)
    for joints and time; ``v_rotary``: (A, C) deg/min of the simple model; ``gouges``: the
    ball gouges where the caller counted them with this checker already (they depend on the
    ball centres alone, not on the axes: ``orient`` refuses a path with any);
    ``measured``: a callable giving :func:`min_clearance` of the path's poses measured
    elsewhere (the job's forked process), asked after the joints and time, which it overlaps;
    errors come in the order of the measurements here (collisions, clearance, joints);
    ``joints``: the machine poses of the path's points where the caller has them already, as
    :func:`~tsplcam.post.kinematics.solve_joints` gives them here (the post's, by
    :func:`~tsplcam.post.post.metrics_solution`), not solved again."""
    n = len(path)
    K = path.axis
    collisions = 0
    gouges = 0 if checker is None else gouges
    clr, clr_at = float("nan"), -1
    clear = checker is not None and clearance
    if checker is not None:
        collisions = int(checker.collides_exact(path.center, K).sum())
        gouges = int(checker.ball_gouges(path.center).sum()) if gouges is None else int(gouges)
        if clear and measured is None:
            clr, clr_at = min_clearance(checker, path.center, K)
    if clear and measured is not None:
        try:
            out = _motion_metrics(path, machine, v_rotary, joints)
        except Exception:
            measured()                   # the clearance's error, if any, comes first
            raise
        clr, clr_at = measured()
    else:
        out = _motion_metrics(path, machine, v_rotary, joints)
    return OrientationMetrics(points=n, collisions=collisions, gouges=gouges, min_clearance=clr,
                              min_clearance_point=clr_at, **out)


def _motion_metrics(path: ToolPath, machine, v_rotary, joints=None) -> dict:
    """The axes' steps, travels, time and speeds of :func:`orientation_metrics` (the fields of
    :class:`OrientationMetrics` after the collisions and the clearance); ``joints``: the
    JointSolution of the path's points with its tips, where the caller has it."""
    K = path.axis
    step = _angle(K[1:], K[:-1]) / DEG
    cut = path.move[1:] == Move.CUT
    ds = np.linalg.norm(np.diff(path.contact, axis=0), axis=1)
    sc = step[cut] if cut.any() else step
    with np.errstate(divide="ignore", invalid="ignore"):
        per_mm = np.where(ds[cut] > 1e-9, step[cut] / ds[cut], 0.0) if cut.any() else np.zeros(1)
    length = np.linalg.norm(np.diff(path.tip, axis=0), axis=1)
    feed_time = float(length.sum() / path.feed * 60.0)
    extra = {}
    if machine is not None:
        from ..post.kinematics import solve_joints
        from ..post.machine import load_machine
        from ..post.timing import estimate
        if isinstance(machine, str):
            machine = load_machine(machine)
        if joints is None:
            sol, tip = solve_joints(machine, path.tip, K, radius=path.tool_radius, patch=path.patch, uv=path.uv,
                                    move=path.move)
        else:
            sol, tip = joints, joints.tip
        # joints and tips to 1e-6 mm or deg, far below what a program writes: the time
        # estimate's junction speeds and maxima would carry the inverse kinematics' last bits
        # (which follow the floating-point path taken) into the report's figures
        J = np.round(sol.joints, 6)
        tip = np.round(tip, 6)
        t_min = np.linalg.norm(np.diff(tip, axis=0), axis=1) / path.feed * 60.0
        rep = estimate(J, t_min, machine.max_velocity, machine.max_acceleration,
                       axis_names=machine.axis_names, cut=cut)
        At, Ct = rep.travel[3], rep.travel[4]
        time_s = rep.total_s
        lin = float(rep.average_speed[:3].mean())
        rot = float(rep.average_speed[3:].mean())
        name = machine.name
        extra = {"axis_travel": dict(zip(machine.axis_names, map(float, rep.travel))),
                 "axis_average_speed": dict(zip(machine.axis_names, map(float, rep.average_speed))),
                 "branch_flips": sol.flips, "singular_points": int(sol.singular.sum())}
    else:
        A, C = _simple_ac(K)
        dA, dC = np.abs(np.diff(A)), np.abs(np.diff(C))
        t = np.maximum(np.maximum(length / path.feed, dA / v_rotary[0]), dC / v_rotary[1]) * 60.0
        time_s = float(t.sum())
        At, Ct = float(dA.sum()), float(dC.sum())
        tip = path.tip
        lin = float(np.abs(np.diff(tip, axis=0)).sum(axis=0).mean() / time_s * 60.0) if time_s > 0 else 0.0
        rot = float((At + Ct) / 2 / time_s * 60.0) if time_s > 0 else 0.0
        name = "simple A/C model"
    return dict(
        max_step_deg=float(sc.max()) if len(sc) else 0.0, mean_step_deg=float(sc.mean()) if len(sc) else 0.0,
        total_variation_deg=float(step.sum()), max_step_per_mm=float(per_mm.max()) if len(per_mm) else 0.0,
        rotary_travel_deg=float(At + Ct), tilt_travel_deg=float(At), c_travel_deg=float(Ct),
        time_s=float(time_s), feed_time_s=feed_time, average_linear_speed=lin, average_rotary_speed=rot,
        machine=name, extra=extra)


def machine_motion(posted, toolpath=None) -> dict:
    """What the machine does with a posted program (tsplcam.post PostResult), the figures the
    job's report lists: estimated time against length/feed, rotary travel and C per mm of
    path, the largest change of the tool axis between neighbouring cutting points, branch
    flips, pole points, the largest C step and how many C steps above 10 deg the machine makes
    while the tip moves less than 0.1 mm, and the retract-reorient-approach sequences the
    post inserted."""
    mo = posted.motion
    J = mo.joints
    info = posted.solution.info
    dtip = np.linalg.norm(np.diff(mo.tip, axis=0), axis=1)
    dA = np.abs(np.diff(J[:, 3]))
    dC = np.abs(np.diff(J[:, 4]))
    feed_rows = ~mo.rapid[1:]
    out = {"machine": posted.machine.name, "dialect": posted.dialect,
           "time_s": float(posted.time.total_s), "length_feed_time_s": float(posted.time.feed_only_s),
           "time_ratio": float(posted.time.total_s / posted.time.feed_only_s) if posted.time.feed_only_s else 0.0,
           # travel over the feed blocks as posted (the joints the program writes: the
           # inverse kinematics' own values carry their last bits, which vary with the heap)
           "tilt_travel_deg": round(float(dA[feed_rows].sum()), 6), "c_travel_deg": round(float(dC[feed_rows].sum()), 6),
           "branch_flips": int(info["branch_flips"]), "pole_points": int(info["singular_points"]),
           "max_c_step_deg": float(dC[feed_rows].max()) if feed_rows.any() else 0.0,
           "c_steps_over_10_deg_within_0_1_mm": int(np.count_nonzero(feed_rows & (dC > 10.0) & (dtip < 0.1))),
           "reorientations": int(posted.reorientations)}
    if toolpath is not None:
        K = toolpath.axis
        cut = toolpath.move[1:] == Move.CUT
        step = _angle(K[1:], K[:-1]) / DEG
        length = float(np.linalg.norm(np.diff(toolpath.tip, axis=0), axis=1).sum())
        out["path_length_mm"] = length
        out["c_deg_per_mm"] = out["c_travel_deg"] / length if length > 0 else 0.0
        out["max_axis_step_deg"] = float(step[cut].max()) if cut.any() else 0.0
    return out
