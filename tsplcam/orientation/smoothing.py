"""Tool-axis smoothing judged where the machine feels it: in the rotary axes' joint space.

The smooth strategy (orient.orient_smooth, after xu2013) minimises along the path

    J = sum_i  L / ds_i * (dtheta_i^2 + w dphi_i^2)                      velocity
      + sum_i  L * ds_i * (l_t^2 k_theta,i^2 + w l_p^2 k_phi,i^2)          acceleration
      + sum_i  dev_i^2 * ds_i / L                                          tilt where needed
      + tau sum_i |dphi_i|                                                 rotary travel

over collision-free axes inside the admissible cone. ``theta``, ``phi`` are the signed tilt
and the rotary angle of the machine's pose (orientation.rotary: joint values are affine in
them, and the sign of theta is the branch), ``ds_i`` the contact spacing, ``k`` second
derivatives along the path (rad/mm^2), ``dev_i`` the angle to the preferred (target) axis
and ``L`` the smoothing length: a needed tilt spreads over about L mm on each side (a
membrane under tension; xu2013 eq. (22)). The weights come from the machine:
``w = rotary_weight * (v_theta / v_phi)^2`` counts rotary motion in tilt-axis time, so the
velocity term is the time integral of (axis speed / its limit)^2, scaled; ``l = F v / a``
(feed F, axis limits v, a) is the path length over which an axis reaches full speed, which
puts (axis acceleration / its limit)^2 on the same scale. Without a machine a virtual A/C
table with equal axis speeds stands in. With ``rotary_weight`` 0 the change of the tool
axis direction replaces the rotary term (``beta``). The travel term (``tau``, the
programme's only: the polish would hold C in the grid's steps) makes C move only where the
cones and collisions make it; :func:`forced_rotary_travel` measures how much that is.

Two stages:

* a Viterbi dynamic programme (orientation.viterbi) over joint-space candidates
  (:func:`meridian_grid`): M rotary values ``phi_k`` (the candidate resolution apart), each
  with the tilt on its meridian that is admissible and nearest the preferred axis. The cone
  around the normal (|lead|, |tilt| limits) and a control's cone are convex, so with phi
  held their intersection with the meridian is one interval of theta, in closed form
  (:func:`theta_interval`). Holding C is a state (the same k), a pole pass with C still is
  the tilt crossing zero on one meridian, a C half-turn is a walk over the k: the programme
  chooses the branch once per region, not per point. Its transition cost is exact in joint
  space and one M x M array operation per point (:func:`joint_transitions`). Collisions are
  checked lazily (:func:`joint_programme`): the chosen poses are checked, and around a
  colliding one the meridians are searched for the collision-free tilt nearest the
  preferred axis (:func:`resolve_meridians`), at anchor points first, whose findings the
  points between take over.
* a continuous polish of the chosen poses (:func:`smooth_joints`): alternately the rotary
  values solve their banded quadratic problem within the interval where the tilt stays
  admissible (and, from what the programme learnt, collision-free: :func:`free_tilts`),
  and the tilts solve theirs on their admissible arcs (:meth:`_Banded.solve_box`, exact
  active set); the moved poses are then checked, a colliding one goes only as far as the
  checks allow and is held there. Near the pole this holds C still: C moves only where an
  obstacle or the cone demands a tilt direction, never because the axis passes close to the
  C axis. ``pole_tilt`` > 0 keeps every axis at least that far from the pole instead.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scipy.linalg import solveh_banded

from ..numerics import component, components
from .. import compiled
from .rotary import DEG, Rotary, angle_between
from .viterbi import from_blocks, viterbi


@dataclass
class SmoothingCost:
    """Weights of J (see the module): smoothing length L (mm), rotary weight ``w`` (in
    tilt-axis units), acceleration lengths ``l_theta``, ``l_phi`` (mm), weight ``alpha`` of
    the joint terms and ``beta`` of the tool-axis direction change (used when C is not
    weighed)."""
    length: float
    rotary: Rotary
    w: float = 1.0
    l_theta: float = 0.0
    l_phi: float = 0.0
    alpha: float = 1.0
    beta: float = 0.0
    feed: float = 0.0            # mm/s: > 0 weighs moves beyond an axis's speed at this feed more
    travel: float = 0.0          # weight of the rotary travel |dphi| (rad) in the programme
    over: float = 4.0            # how much more (the polish, iteratively reweighted)

    @staticmethod
    def build(rotary: Rotary | None, length: float, rotary_weight: float = 1.0,
              acceleration_weight: float = 1.0, feed: float = 1000.0) -> "SmoothingCost":
        """Joint-space weights for a machine's rotary axes; without one (``rotary`` None) a
        virtual A/C table with equal axis speeds and no acceleration terms."""
        if rotary is None:
            return SmoothingCost(length, Rotary())
        f = feed / 60.0                                        # mm/s
        lt = f * rotary.v_theta / rotary.a_theta * np.sqrt(acceleration_weight)
        lp = f * rotary.v_phi / rotary.a_phi * np.sqrt(acceleration_weight)
        return SmoothingCost(length, rotary, w=rotary_weight * rotary.weight, l_theta=lt, l_phi=lp, feed=f)


# --- the discrete programme --------------------------------------------------------------------

@dataclass
class MeridianGrid:
    """Joint-space candidates: rotary values ``phi_k = 2 pi k / M`` and, per point and k, the
    signed tilt on that meridian: the admissible one nearest the preferred axis (``theta``
    (n, M)), inside ``[lo, hi]``; ``ok`` where the meridian meets the admissible cone."""
    phi: np.ndarray
    theta: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    pref: np.ndarray            # (n, M) tilt of the preferred axis's projection on the meridian
    ok: np.ndarray
    start: np.ndarray = None    # the tilts before any collision check
    raised: np.ndarray = None   # the checks moved the tilt away from the preferred axis


def meridian_grid(rot: Rotary, pref, normal, constraints, M: int, pole_tilt: float = 0.0,
                  rows: int = 1024) -> MeridianGrid:
    n = len(pref)
    phis = 2 * np.pi * np.arange(M) / M
    # the meridians of the M rotary values, once (rot.meridian of the (n, M) grid computes
    # the same elements n times over); rot.best_theta's arctan2 of the dot products, taken by
    # _meridian_dots. ``rows`` points at a time: every step is element by element, and the
    # temporaries of (rows, M) stay in the cache (keycap: 14.7k x 36, 4 MB an array)
    m = rot.meridian(phis)
    normal, pref = np.asarray(normal, float), np.asarray(pref, float)
    th, lo, hi, tp = (np.empty((n, M)) for _ in range(4))
    for a in range(0, n, rows):
        s = slice(a, min(a + rows, n))
        nr, pr = normal[s], pref[s]
        cons = [(h[s], np.asarray(b, float)[s]) for h, b in constraints]
        l, u = theta_interval(rot, np.broadcast_to(phis, (len(nr), M)), cons,
                              np.arctan2(_meridian_dots(nr, m), nr[:, 2:3]), m)
        l = np.maximum(l, rot.theta_lo, out=lo[s])
        u = np.minimum(u, rot.theta_hi, out=hi[s])
        np.clip(np.arctan2(_meridian_dots(pr, m), pr[:, 2:3], out=tp[s]), l, u, out=th[s])
    if pole_tilt > 0:
        near = np.abs(th) < pole_tilt
        up = np.where(hi >= pole_tilt, np.maximum(lo, pole_tilt), np.inf)
        dn = np.where(lo <= -pole_tilt, np.minimum(hi, -pole_tilt), -np.inf)
        pick = np.where(np.abs(up - th) <= np.abs(dn - th), up, dn)
        th = np.where(near, pick, th)
    ok = (lo <= hi) & np.isfinite(th)
    th[~ok] = 0.0
    return MeridianGrid(phis, th, lo, hi, tp, ok, th.copy(), np.zeros(th.shape, bool))


IN_PLACE = (0.1, 10.0 * DEG)
TRANSITION_CACHE = 128e6      # bytes of transition blocks kept between the programme's rounds
STEPS_ROWS = 2048              # points per joint_steps call (their cos and sin made for it)


def joint_transitions(grid: MeridianGrid, cost: SmoothingCost, ds: np.ndarray, max_step: float,
                      free_step: np.ndarray, air=None):
    """The transition cost ``i -> (M, M)`` between the grid's poses (see the module):
    ``L / ds * (alpha (dtheta^2 + w dphi^2) + beta |dK|^2)``, moves of the tool axis above
    ``max_step`` forbidden except into points where ``free_step``, and rotary steps above
    ``IN_PLACE`` forbidden on blocks shorter than it except into points where ``air``
    (retracts, rapids). Reads ``grid.theta`` when called (the lazy collision checks update it).
    With the compiled kernels loaded the Viterbi computes each transition in its kernel
    (``steps``, the same operations in the same order: the same bits) and no block is made;
    the numpy blocks are the reference and the path without numba. There a block is kept (up
    to ``TRANSITION_CACHE`` bytes) with the tilts it was made from and given again while they
    are unchanged: the programme's later rounds change the tilts of a few stretches only
    (keycap_mold: two blocks in three come back unchanged), and the same element-wise
    arithmetic on the same tilts gives the same bits."""
    phis = grid.phi
    dphi = np.pi - np.mod(np.pi - (phis[None, :] - phis[:, None]), 2 * np.pi)
    D2 = cost.w * dphi ** 2
    D1 = cost.travel * np.abs(dphi)
    cosD = np.cos(dphi)
    cmax = np.cos(max_step)
    alpha, beta, L = cost.alpha, cost.beta, cost.length
    TH = grid.theta
    swing = np.abs(dphi) > IN_PLACE[1] + 1e-9
    air = np.zeros(len(TH), bool) if air is None else air
    # per point i (the move into it): L / ds, the tool-axis step limit applies, a rotary
    # swing is forbidden (a short block that is not in the air); one rule for both forms
    n = len(TH)
    lds = np.ascontiguousarray(L / ds[:n - 1], float)
    hard = np.ascontiguousarray(~free_step[:n], bool)
    short_at = np.zeros(n, bool)
    short_at[1:] = (ds[:n - 1] < IN_PLACE[0]) & ~air[1:n]

    kept: dict = {}
    room = [TRANSITION_CACHE]

    def block(i0: int, i1: int) -> np.ndarray:
        """The transitions into points i0 .. i1 - 1, (i1 - i0, M, M), element for element
        the same arithmetic as one point at a time (kept ones while their tilts stand)."""
        old = kept.get((i0, i1))
        if old is not None and np.array_equal(old[0], TH[i0 - 1:i1]):
            return old[1]
        t = _block(i0, i1)
        if old is not None or room[0] >= t.nbytes:
            if old is None:
                room[0] -= t.nbytes
            kept[(i0, i1)] = (TH[i0 - 1:i1].copy(), t)
        return t

    def _block(i0: int, i1: int) -> np.ndarray:
        a, b = TH[i0 - 1:i1 - 1], TH[i0:i1]
        dots = np.cos(a)[:, :, None] * np.cos(b)[:, None, :]
        dots += (np.sin(a)[:, :, None] * np.sin(b)[:, None, :]) * cosD
        dt = a[:, :, None] - b[:, None, :]
        dt *= dt
        dt += D2
        t = np.multiply(alpha, dt, out=dt)
        if beta:
            t += beta * (2.0 - 2.0 * dots)
        t *= lds[i0 - 1:i1 - 1][:, None, None]
        if cost.travel:
            t += D1
        np.copyto(t, np.inf, where=hard[i0:i1, None, None] & (dots < cmax - 1e-12))
        short = short_at[i0:i1]
        if short.any():
            np.copyto(t, np.inf, where=short[:, None, None] & swing[None])
        return t

    mats = [np.ascontiguousarray(x, float) for x in (D2, D1, cosD)]
    swing_c = np.ascontiguousarray(swing, bool)

    def steps(k, acc, node, i0: int, i1: int, tie: float, back) -> int:
        """The Viterbi steps into points i0 .. i1 - 1 in the compiled kernel, each transition
        computed where it is used (no block is made): the same operations as :func:`_block`,
        with numpy's cos and sin of the current tilts (numba's may differ in the last bit)."""
        th = np.ascontiguousarray(TH, float)
        for a in range(i0, i1, STEPS_ROWS):
            b = min(i1, a + STEPS_ROWS)
            s = slice(a - 1, b)
            t = th[s]
            broke = k["joint_steps"](acc, node[s], 1, b - a + 1, t, np.cos(t), np.sin(t), *mats, swing_c,
                                     float(alpha), float(beta), float(cost.travel), lds[a - 1:b - 1], hard[s],
                                     short_at[s], float(cmax - 1e-12), tie, back[s])
            if broke >= 0:
                return broke + a - 1
        return -1
    return from_blocks(block, steps)


def resolve_meridians(checker, C, rot: Rotary, grid: MeridianGrid, status, pts, ks, step: float,
                      count: int = 12, refine: int = 3, tick=None):
    """For the states (pts, ks) whose pose collides or is not yet known: the collision-free
    tilt on the same meridian nearest the preferred one, among the current tilt and ``count``
    tilts ``step`` apart further from the preferred axis inside the admissible arc (closer
    tilts of this meridian are the other side of the pole: meridian k + M/2), tried nearest first (one
    batch of checks per rank, only for the states still open); a state with none is
    excluded (status 2), else free (status 0) at the tilt found, refined by ``refine``
    bisections toward the last colliding one. Returns the checks made."""
    if len(pts) == 0:
        return 0
    th0 = grid.theta[pts, ks]
    # away from the preferred axis only: the other side of the pole is the meridian k + M/2
    away = np.where(th0 >= grid.pref[pts, ks], 1.0, -1.0)
    T = th0[:, None] + away[:, None] * step * np.arange(count + 1)[None, :]
    inside = (T >= grid.lo[pts, ks][:, None] - 1e-12) & (T <= grid.hi[pts, ks][:, None] + 1e-12)
    key = np.where(inside, np.abs(T - grid.pref[pts, ks][:, None]), np.inf)
    order = np.argsort(key, axis=1, kind="stable")
    T = np.take_along_axis(T, order, 1)
    inside = np.take_along_axis(inside, order, 1)
    found = np.full(len(pts), np.nan)
    near = np.full(len(pts), np.nan)           # the last colliding tilt before the free one
    checks = 0
    for rank in range(T.shape[1]):
        open_ = np.nonzero(np.isnan(found) & inside[:, rank])[0]
        if len(open_) == 0:
            if not (np.isnan(found) & inside[:, rank:].any(axis=1)).any():
                break
            continue
        hit = checker.collides(C[pts[open_]], rot.axis(T[open_, rank], grid.phi[ks[open_]]))
        checks += len(open_)
        found[open_[~hit]] = T[open_[~hit], rank]
        near[open_[hit]] = T[open_[hit], rank]
        if tick is not None:
            tick()
    # the boundary between the last colliding and the first free tilt, by bisection
    q = np.nonzero(~np.isnan(found) & ~np.isnan(near))[0]
    a, b = near[q], found[q]
    for _ in range(refine):
        if len(q) == 0:
            break
        mid = 0.5 * (a + b)
        hit = checker.collides(C[pts[q]], rot.axis(mid, grid.phi[ks[q]]))
        checks += len(q)
        a, b = np.where(hit, mid, a), np.where(hit, b, mid)
    found[q] = b
    ok = ~np.isnan(found)
    grid.raised[pts[ok], ks[ok]] = ~np.isnan(near[ok]) | (found[ok] != th0[ok])
    grid.theta[pts[ok], ks[ok]] = found[ok]
    status[pts, ks] = np.where(ok, 0, 2)
    return checks


class NoPath(Exception):
    """The programme found no allowed sequence: ``point`` has no collision-free pose
    (``where = "point"``) or no pair of poses joins ``point`` and ``point + 1``."""

    def __init__(self, point: int, kind: str):
        super().__init__(kind)
        self.point, self.kind = point, kind


def joint_programme(checker, C, grid: MeridianGrid, cost: SmoothingCost, pref, ds, half, max_step: float,
                    free_step, step: float, anchor: int = 4, window: int = 1, k_window: int = 1,
                    max_rounds: int = 200, air=None, tick=None):
    """The Viterbi programme over the grid's poses with lazy collision checks.

    The programme runs on poses not known to collide, the chosen ones are checked, and around
    a colliding one the anchors (every ``anchor``-th point) of its stretch get all their
    rotary positions searched (:func:`resolve_meridians`); the points between take from
    them what is likely (a position excluded at both anchors is left out, one free at an
    anchor starts from the anchor's extra tilt), and the colliding pose's own neighbourhood
    is searched. The loop ends when every chosen pose is checked free: the sequence is then
    optimal over the poses known free. Returns ``(states, rounds, checks, status)``; raises
    :class:`NoPath`."""
    n, M = grid.theta.shape
    rot = cost.rotary
    tick = tick or (lambda: None)
    trans = joint_transitions(grid, cost, ds, max_step, free_step, air)
    status = np.where(grid.ok, np.int8(-1), np.int8(2))   # -1 unknown, 0 free, 2 excluded, 3 likely excluded
    theta_init = grid.theta.copy()
    anchored = np.zeros(n, bool)
    rounds = checks = 0
    kw = np.arange(-window, window + 1)
    kk = np.arange(-k_window, k_window + 1)

    def resolve(pj, pk):
        keep = (status[pj, pk] == -1) | (status[pj, pk] == 3)
        pj, pk = pj[keep], pk[keep]
        status[pj, pk] = -1
        made = 0
        moved = np.nonzero(grid.theta[pj, pk] != theta_init[pj, pk])[0]
        if len(moved):
            # a tilt taken from an anchor is tried first; where it collides the meridian is
            # searched from its own first tilt (the search goes away from the preferred axis
            # only, so from the anchor's tilt it would miss a free window nearer)
            mj, mk = pj[moved], pk[moved]
            hit = checker.collides(C[mj], rot.axis(grid.theta[mj, mk], grid.phi[mk]))
            made += len(mj)
            status[mj[~hit], mk[~hit]] = 0
            grid.raised[mj[~hit], mk[~hit]] = False
            grid.theta[mj[hit], mk[hit]] = theta_init[mj[hit], mk[hit]]
            left = np.ones(len(pj), bool)
            left[moved[~hit]] = False
            pj, pk = pj[left], pk[left]
        return made + resolve_meridians(checker, C, rot, grid, status, pj, pk, step, tick=tick)

    dev = seen = None
    while True:
        rounds += 1
        tick()
        if dev is None:
            dev = _deviation(rot, grid.theta, grid.phi, pref)
        else:
            # each pose's deviation from the preferred axis again where its tilt changed (the
            # same element-wise operations on those elements: the same bits)
            i, k = np.nonzero(grid.theta != seen)
            if len(i):
                dev[i, k] = angle_between(rot.axis(grid.theta[i, k], grid.phi[k]), pref[i])
        seen = grid.theta.copy()
        node = np.square(dev)                   # (dev ** 2: numpy squares)
        node *= half[:, None]
        node[status > 0] = np.inf               # excluded or likely excluded (statuses -1, 0, 2, 3)
        states, broke = viterbi(node, trans)
        if states is None:
            i = max(broke, 0)
            pts = np.array([j for j in (i, i + 1) if j < n])
            pj, pk = np.nonzero((status[pts] == -1) | (status[pts] == 3))
            if len(pj):
                checks += resolve(pts[pj], pk)
                continue
            j = next((j for j in pts if not (status[j] == 0).any()), None)
            raise NoPath(j, "point") if j is not None else NoPath(i, "pair")
        cols = np.arange(n)
        unknown = np.nonzero(status[cols, states] == -1)[0]
        if len(unknown) == 0:
            return states, rounds, checks, status
        ax = rot.axis(grid.theta[unknown, states[unknown]], grid.phi[states[unknown]])
        hit = checker.collides(C[unknown], ax)
        checks += len(unknown)
        status[unknown[~hit], states[unknown[~hit]]] = 0
        bad = unknown[hit]
        if len(bad) == 0:
            # every chosen pose is now known free: the node costs of the states did not change
            # (unknown and free cost the same), so the programme would choose them again
            return states, rounds, checks, status
        if len(bad):
            # anchors of the stretches around colliding poses: every rotary position
            lo_a = (bad // anchor) * anchor
            hi_a = np.minimum(lo_a + anchor, n - 1)
            anc = np.unique(np.concatenate([lo_a, hi_a]))
            anc = anc[~anchored[anc]]
            if len(anc):
                pj, pk = np.nonzero(status[anc] == -1)
                checks += resolve(anc[pj], pk)
                anchored[anc] = True
                # the points between two anchors: what both anchors say
                starts = np.unique(lo_a)
                ends = np.minimum(starts + anchor, n - 1)
                span = np.arange(1, anchor)
                P = starts[:, None] + span[None, :]
                A0 = np.broadcast_to(starts[:, None], P.shape)
                A1 = np.broadcast_to(ends[:, None], P.shape)
                inside = P < A1
                P, A0, A1 = P[inside], A0[inside], A1[inside]
                und = status[P] == -1                                   # (p, M)
                ex0, ex1 = status[A0] == 2, status[A1] == 2
                d0 = np.where(status[A0] == 0, grid.theta[A0] - theta_init[A0], 0.0)
                d1 = np.where(status[A1] == 0, grid.theta[A1] - theta_init[A1], 0.0)
                d = np.where(np.abs(d0) >= np.abs(d1), d0, d1)
                st = status[P]
                st[und & ex0 & ex1] = 3
                status[P] = st
                th = np.clip(theta_init[P] + d, grid.lo[P], grid.hi[P])
                grid.theta[P] = np.where(und & ~(ex0 & ex1), th, grid.theta[P])
            # and the colliding poses' own neighbourhood
            pj = np.clip(bad[:, None, None] + kw[None, :, None], 0, n - 1)
            pk = np.mod(states[bad][:, None, None] + kk[None, None, :], M)
            pj, pk = (v.ravel() for v in np.broadcast_arrays(pj, pk))
            key = np.unique(pj * M + pk)
            checks += resolve(key // M, key % M)
        if rounds >= max_rounds:                                  # pragma: no cover
            raise NoPath(0, "rounds")


def _deviation(rot: Rotary, theta: np.ndarray, phis: np.ndarray, pref: np.ndarray, rows: int = 1024) -> np.ndarray:
    """``angle_between(rot.axis(theta, phis[None, :]), pref[:, None, :])`` (n, M): each
    pose's angle to the point's preferred axis, with the same bits. Where every preferred
    axis lies along the C axis (x = y = 0), ``rows`` points at a time without (n, M, 3)
    arrays and without the terms that are +-0: the axis is ``(s m_x, s m_y, c)`` up to the
    sign of a zero (``c * 0.0 + s m`` adds +-0; the meridians' z is 0), the cross product's
    components are ``(s m_y) b_z``, ``-(s m_x) b_z`` and +-0, so its squared length is
    ``((s m_y) b_z)^2 + ((s m_x) b_z)^2`` exactly (a zero's sign squares away), and einsum's
    dot product is ``c b_z + 0.0`` whatever order it sums in (it starts from +0, never -0).
    A third of the passes over the grid (keycap 14.7k x 36)."""
    pref = np.asarray(pref, float)
    if pref[:, :2].any():
        return angle_between(rot.axis(theta, phis[None, :]), pref[:, None, :])
    n = len(theta)
    m = rot.meridian(phis)
    out = np.empty(theta.shape)
    for a in range(0, n, rows):
        s = slice(a, min(a + rows, n))
        t = theta[s]
        c, sn = np.cos(t), np.sin(t)
        bz = pref[s, 2:3]
        x = sn * m[:, 1]                                # the cross product's x: (s m_y) b_z
        x *= bz
        x *= x
        y = sn * m[:, 0]                                # ... and y: -(s m_x) b_z
        y *= bz
        y *= y
        x += y
        c *= bz                                         # the dot product
        c += 0.0
        np.arctan2(np.sqrt(x, out=x), c, out=out[s])
    return out


def free_tilts(grid: MeridianGrid, status) -> np.ndarray | None:
    """What the programme learnt about collisions, as the polish's constraint: per point and
    grid azimuth ``phi_k`` the smallest tilt from the C axis toward it that the checks found
    collision-free where they had to raise it, ``inf`` where every admissible tilt collides,
    0 where no check said anything (the cone is the polish's own constraint) (n, M). Only for
    a preferred axis along the C axis, where the free tilts of a meridian start at a bound and
    go outward (None otherwise: the polish then learns from its own checks alone)."""
    if np.abs(grid.pref).max() > 1e-9:
        return None
    n, M = grid.theta.shape
    A = np.zeros((n, M))
    raised = (status == 0) & grid.raised
    blocked = grid.ok & (status == 2)
    v = grid.theta
    rows = np.broadcast_to(np.arange(n)[:, None], (n, M))
    cols = np.broadcast_to(np.arange(M)[None, :], (n, M))
    pos, neg = raised & (v >= 0), raised & (v < 0)
    np.maximum.at(A, (rows[pos], cols[pos]), v[pos])
    np.maximum.at(A, (rows[neg], (cols[neg] + M // 2) % M), -v[neg])
    # every tilt of a blocked meridian collides: toward its side from the start tilt on
    s0 = grid.start
    bp, bn = blocked & (s0 >= 0), blocked & (s0 < 0)
    A[rows[bp], cols[bp]] = np.inf
    A[rows[bn], (cols[bn] + M // 2) % M] = np.inf
    return A


def _tilt_table(A, az, M):
    """Conservative smallest free tilt toward azimuths ``az`` (n,): the larger of the two
    grid azimuths around it."""
    f = np.mod(az, 2 * np.pi) / (2 * np.pi) * M
    k0 = np.floor(f).astype(int) % M
    r = np.arange(len(az))
    return np.maximum(A[r, k0], A[r, (k0 + 1) % M])


def _azimuth_window(A, az, tilt, M):
    """How far (rad, left and right) the azimuth of a pose at ``tilt`` may turn from ``az``
    through grid azimuths whose free tilt is at most ``tilt``. The cells beside each point's
    are read as windows of the row twice over (views, no index arrays)."""
    n = len(az)
    d = 2 * np.pi / M
    f = np.mod(az, 2 * np.pi) / d
    rf = np.rint(f)
    c = rf.astype(int) % M
    off = (f - rf) * d                              # az minus the centre of cell c
    ok = A <= tilt[:, None] + 1e-12
    h = M // 2
    windows = np.lib.stride_tricks.sliding_window_view(np.concatenate([ok, ok], axis=1), h, axis=1)
    rows = np.arange(n)
    right = windows[rows, c + 1]                    # cells c + 1 .. c + h
    left = windows[rows, c + M - h][:, ::-1]        # cells c - 1 .. c - h
    run_r = np.where(right.all(1), h, np.argmin(right, 1))
    run_l = np.where(left.all(1), h, np.argmin(left, 1))
    here = ok[rows, c]
    return (np.where(here, np.maximum(0.0, run_l * d + off), 0.0),
            np.where(here, np.maximum(0.0, run_r * d - off), 0.0))


# --- admissible arcs on a meridian -----------------------------------------------------------

def cone_halfspaces(normal, feed, lead_max: float, tilt_max: float):
    """The lead/tilt limits around the normal as half-spaces ``h . a >= 0`` (list of (n,3)):
    ``|a.f| <= tan(lead_max) a.n`` and ``|a.s| <= tan(tilt_max) a.n`` (s = n x f)."""
    side = np.cross(normal, feed)
    tl = np.tan(min(lead_max, 89.9 * DEG))
    tt = np.tan(min(tilt_max, 89.9 * DEG))
    return [tl * normal - feed, tl * normal + feed, tt * normal - side, tt * normal + side]


_HALF_PI = float(np.arccos(np.clip(np.zeros(1), -1.0, 1.0))[0])    # arccos(+0), as theta_interval takes it


def _meridian_dots(V: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``V . m`` (n, M) of vectors V (n, 3) and horizontal meridians m (M, 3): the bits of
    ``np.einsum("nj,nkj->nk", V, m broadcast to (n, M, 3))`` in half its time. einsum sums
    the three products in order onto +0; m's z is 0, so its product (+-0) changes a sum only
    where the sum is zero, and adding +0.0 gives einsum's +0 there. With the kernels loaded
    in one pass (``meridian_dots``: the same roundings, so the same bits; a nan's sign may
    differ where both products are nan, which finite V and m never make)."""
    if m[:, 2].any():
        return np.einsum("nj,nkj->nk", V, np.broadcast_to(m, (len(V),) + m.shape))
    k = compiled.kernels(work=float(V.shape[0]) * m.shape[0])
    if k is not None:
        r = np.empty((len(V), len(m)))
        k["meridian_dots"](np.ascontiguousarray(V, float), np.ascontiguousarray(m, float), r)
        return r
    r = V[:, 0, None] * m[:, 0]
    r += V[:, 1, None] * m[:, 1]
    r += 0.0
    return r


def theta_interval(rot: Rotary, phi, constraints, ref, m=None):
    """Interval [lo, hi] of signed tilt on the meridian at rotary ``phi`` ((n,) or (n, M))
    where every constraint ``(h (n,3), b (n,))``, ``h . a >= b``, holds; arcs are taken on
    the branch nearest ``ref`` (shaped like phi; a point known or expected inside, e.g. the
    normal's tilt on that meridian). Empty where lo > hi. ``m``: ``rot.meridian(phi)`` when
    the caller has it, or on a grid (n, M) whose rows share the rotary values, the (M, 3)
    meridians of one row."""
    phi = np.asarray(phi, float)
    m = rot.meridian(phi) if m is None else m
    grid = phi.ndim == 2
    lo = np.full(phi.shape, -np.inf)
    hi = np.full(phi.shape, np.inf)
    # on a grid, a cone's arcs (b = 0, every row's |hz| above 1e-15) in the kernel: the
    # nearest branch, lo and hi element by element in place, numpy's operations (the same bits)
    k = compiled.kernels(work=float(phi.size) * len(constraints)) if grid else None
    ref_c = np.ascontiguousarray(np.broadcast_to(ref, phi.shape), float) if k is not None else None
    for h, b in constraints:
        hz = component(h, 2)                # (contiguous: the same arctan2 code whatever the heap)
        hz = hz[:, None] if grid else hz
        if not grid:
            hm = np.einsum("ij,ij->i", h, m)
        elif m.ndim == 2:
            hm = _meridian_dots(h, m)
        else:
            hm = np.einsum("nj,nkj->nk", h, m)
        bb = np.asarray(b, float)[:, None] if grid else np.asarray(b, float)
        al = np.arctan2(hm, hz)
        if k is not None and not np.any(bb) and np.all(np.abs(hz) > 1e-15):
            k["cone_arcs"](np.ascontiguousarray(al), ref_c, _HALF_PI, lo, hi)
            continue
        al = ref + (np.pi - np.mod(np.pi - (al - ref), 2 * np.pi))          # nearest ref
        if not np.any(bb):
            # b = 0 (the lead/tilt cones): c is +0 where R > 1e-15, else -1; the same half
            # arcs as below without their passes over the grid, and R > 1e-15 without libm's
            # hypot (15 ms a grid) where |hz| or |hm| is above 1e-15 (hypot >= both)
            row = np.abs(hz) > 1e-15
            if np.all(row):                          # (as a rule: every half arc is pi/2)
                lo = np.maximum(lo, al - _HALF_PI)
                hi = np.minimum(hi, al + _HALF_PI)
                continue
            big = row | (np.abs(hm) > 1e-15)
            small = np.nonzero(~big)
            if len(small[0]):
                big[small] = np.hypot(np.broadcast_to(hz, big.shape)[small], hm[small]) > 1e-15
            half = np.where(big, _HALF_PI, np.pi)
        else:
            R = np.hypot(hz, hm)
            with np.errstate(divide="ignore", invalid="ignore"):
                c = np.where(R > 1e-15, bb / np.where(R > 1e-15, R, 1.0), np.where(bb <= 0, -1.0, 2.0))
            half = np.where(c <= -1.0, np.pi, np.where(c >= 1.0, -1.0, np.arccos(np.clip(c, -1.0, 1.0))))
        lo = np.maximum(lo, al - half)
        hi = np.minimum(hi, al + half)
    return lo, hi


def _latitude_terms(rot: Rotary, constraints) -> list:
    """What :func:`phi_interval` takes of each constraint ``(h, b)`` whatever the tilt:
    ``h . meridian(phi) = A cos phi + B sin phi`` as its length hypot(A, B) and angle
    arctan2(B, A), with ``h_z`` and ``b``."""
    out = []
    for h, b in constraints:
        hx, hy, hz = components(h)          # (contiguous: the same ufunc code whatever the heap)
        if rot.about == "X":
            A_, B_ = -hy, hx
        else:
            A_, B_ = hx, hy
        out.append((np.hypot(A_, B_), np.arctan2(B_, A_), hz, np.asarray(b, float)))
    return out


def phi_interval(rot: Rotary, theta, constraints, ref, terms=None):
    """Interval [lo, hi] of rotary values around ``ref`` (n,) where the tilt ``theta`` (n,)
    keeps every constraint ``(h, b)``: a circle of latitude meets each half-space in an arc.
    ``terms``: :func:`_latitude_terms` of the constraints when the caller has them."""
    theta = np.asarray(theta, float)
    n = len(theta)
    st, ct = np.sin(theta), np.cos(theta)
    lo = np.full(n, -np.inf)
    hi = np.full(n, np.inf)
    for hyp, ang, hz, b in (_latitude_terms(rot, constraints) if terms is None else terms):
        rho = hyp * np.abs(st)
        beta = ang + np.where(st < 0, np.pi, 0.0)
        beta = ref + (np.pi - np.mod(np.pi - (beta - ref), 2 * np.pi))
        need = b - hz * ct
        with np.errstate(divide="ignore", invalid="ignore"):
            c = np.where(rho > 1e-12, need / np.where(rho > 1e-12, rho, 1.0), np.where(need <= 1e-12, -1.0, 2.0))
        half = np.where(c <= -1.0, np.inf, np.where(c >= 1.0, -1.0, np.arccos(np.clip(c, -1.0, 1.0))))
        lo = np.maximum(lo, beta - half)
        hi = np.minimum(hi, beta + half)
    return lo, hi


# --- the continuous smoothing ------------------------------------------------------------------

def _add_to(x: np.ndarray, at: np.ndarray, v: np.ndarray) -> None:
    """``x += np.bincount(at, v, minlength=len(x))`` (x 1-D): in place at ``at`` where its
    indices rise strictly (no two values meet), else through the bincount."""
    if len(at) < 2 or bool(np.all(at[1:] > at[:-1])):
        x[at] += v
    else:
        x += np.bincount(at, v, minlength=len(x))


class _Banded:
    """A symmetric positive definite banded system (upper form, ``u`` off-diagonals) assembled
    from terms ``W (r + v . x)^2``; :meth:`solve_box` minimises ``x^T H x / 2 + g^T x`` within
    bounds by an active set (exact for the convex quadratic)."""

    def __init__(self, N: int, u: int = 2):
        self.N, self.u = N, u
        self.ab = np.zeros((u + 1, N))
        self.g = np.zeros(N)

    def add(self, W, idx, V, r):
        """Terms: weights W (T,), variable indices idx (T,k), coefficients V (T,k), residuals r (T,).
        Each (a, b) pair of a term's variables is summed per element (np.bincount) and added;
        where a pair's elements are distinct (as a rule: one term per point) the values are
        added in place, the same sums (g and ab hold no -0: x + (0 + v) == x + v)."""
        W = np.broadcast_to(np.asarray(W, float), (len(idx),))
        k = idx.shape[1]
        if not self.ab.flags.c_contiguous:
            self.ab = np.ascontiguousarray(self.ab)
        ab = self.ab.reshape(-1)                     # a view of ab
        for a in range(k):
            _add_to(self.g, idx[:, a], W * r * V[:, a])
            for b in range(k):
                i, j = idx[:, a], idx[:, b]
                keep = i <= j
                if keep.all():
                    _add_to(ab, (self.u + i - j) * self.N + j, W * V[:, a] * V[:, b])
                elif keep.any():
                    flat = (self.u + i[keep] - j[keep]) * self.N + j[keep]
                    _add_to(ab, flat, (W * V[:, a] * V[:, b])[keep])

    def matvec(self, x):
        u, N, ab = self.u, self.N, self.ab
        y = ab[u] * x
        for k in range(1, u + 1):
            band = ab[u - k, k:]                 # H[i, i + k]
            y[:-k] += band * x[k:]
            y[k:] += band * x[:-k]
        return y

    def solve_box(self, lo, hi, iterations: int = 40, at=None):
        """argmin over lo <= x <= hi (lo <= hi everywhere), by the active-set loop from the
        active set ``at`` ((N,) int8: -1 at lo, +1 at hi, 0 free; updated in place to the one
        the loop ends with) or, without it, from every row free. With the compiled kernels loaded
        already (then every solve below would run in ``banded_solve``) the whole loop runs in
        the ``solve_box`` kernel: the same operations in the same order, so the same x,
        without the numpy calls' overhead per iteration (57 iterations of 14.7k rows on the
        keycap), and each iteration takes again only the steps of the factor and the
        substitutions whose inputs changed (u = 2; the same bits)."""
        N, u = self.N, self.u
        if at is None:
            at = np.zeros(N, np.int8)
        elif at.dtype != np.int8 or at.shape != (N,) or not at.flags.c_contiguous:
            raise ValueError(f"solve_box: the active set must be a contiguous ({N},) int8 array")
        k = compiled.loaded()
        if k is not None and u == 2:
            x = np.empty(N)
            lo_c = np.require(np.broadcast_to(lo, (N,)), np.float64, "C")
            hi_c = np.require(np.broadcast_to(hi, (N,)), np.float64, "C")
            info = k["solve_box"](np.require(self.ab, np.float64, "C"), np.require(self.g, np.float64, "C"),
                                  lo_c, hi_c, int(iterations), x, at)
            if info > 0:
                raise np.linalg.LinAlgError(f"{info}th leading minor not positive definite")
            return np.clip(x, lo, hi)
        x = np.zeros(N)
        for _ in range(iterations):
            fixed = at != 0
            xf = np.where(at < 0, lo, np.where(at > 0, hi, 0.0))
            ab = self.ab.copy()
            rhs = -self.g - self.matvec(xf)
            if fixed.any():
                f = np.nonzero(fixed)[0]
                for k in range(1, u + 1):
                    c = f[f + k < N]
                    ab[u - k, c + k] = 0.0       # H[f, f + k]
                    c = f[f - k >= 0]
                    ab[u - k, c] = 0.0           # H[f - k, f]
                ab[u, f] = 1.0
                rhs[f] = 0.0
            x = _solve_banded(ab, rhs) + xf
            change = False
            low, high = ~fixed & (x < lo - 1e-12), ~fixed & (x > hi + 1e-12)
            if low.any() or high.any():
                at[low], at[high] = -1, 1
                change = True
            grad = self.matvec(x) + self.g
            rel = ((at < 0) & (grad < -1e-12)) | ((at > 0) & (grad > 1e-12))
            if rel.any() and not change:
                at[rel] = 0
                change = True
            if not change:
                break
        return np.clip(x, lo, hi)


def _solve_banded(ab: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """scipy's ``solveh_banded`` (upper form) for the system :meth:`_Banded.solve_box` builds,
    in the compiled kernel when numba is there (LAPACK's reference order of operations);
    ``ab`` and ``rhs`` are overwritten.

    The kernels are loaded for the first solve of a process, not once its work reaches
    ``compiled.LOAD_WORK`` as elsewhere: OpenBLAS's LAPACK rounds differently from the
    kernel, and the active set of the box-constrained problem carries that to the 7th digit
    of some axes, so a job's program would depend on what the process ran before it (a
    second job in a FreeCAD session or a test process differed from the first)."""
    k = compiled.kernels()
    if k is None or len(ab) < 3:        # (one off-diagonal: scipy takes LAPACK's LDL^T, ptsv)
        return solveh_banded(ab, rhs, lower=False, check_finite=False)
    ab = np.require(ab, np.float64, ("C", "W"))
    rhs = np.require(rhs, np.float64, ("C", "W"))
    info = k["banded_solve"](ab, rhs)
    if info > 0:
        raise np.linalg.LinAlgError(f"{info}th leading minor not positive definite")
    return rhs


def _quadratic(x0_len: int, ds, couple, L: float, w_vel: float, l_acc: float, block=None) -> _Banded:
    """Velocity and acceleration terms of one joint coordinate along the path (see the module);
    ``block`` (n-1,): extra factors of the blocks' velocity terms."""
    n = x0_len
    B = _Banded(n, 2)
    j = np.nonzero(couple)[0]
    one = np.ones(len(j))
    if len(j):
        f = 1.0 if block is None else block[j]
        B.add(w_vel * L / ds[j] * f, np.stack([j, j + 1], 1), np.stack([-one, one], 1), np.zeros(len(j)))
    k = np.nonzero(couple[:-1] & couple[1:])[0] + 1 if n > 2 else np.zeros(0, int)
    if len(k) and l_acc > 0:
        d0, d1 = ds[k - 1], ds[k]
        dm = 0.5 * (d0 + d1)
        ca, cc = 1.0 / (d0 * dm), 1.0 / (d1 * dm)
        B.add(w_vel * L * dm * l_acc ** 2, np.stack([k - 1, k, k + 1], 1),
              np.stack([ca, -(ca + cc), cc], 1), np.zeros(len(k)))
    return B


def smooth_joints(path, rot: Rotary, theta0, phi0, pref, normal, cost: SmoothingCost, constraints, *,
                  checker=None, move_free=None, pole_tilt: float = 0.0, rounds: int = 6, alternations: int = 3,
                  lean: float = 2.0 * DEG, bisect: int = 4, free_tilt=None, tick=None, max_step=None,
                  hard=None):
    """Polish the programme's collision-free poses ``(theta0, phi0)`` (rad, phi unwound) in
    joint space: the rotary values are smoothed (velocity and acceleration terms, held to the
    programme's tool-axis direction in proportion to sin^2 theta: nothing near the pole),
    then the tilts solve their convex problem on each point's admissible arc at the new
    rotary value (:meth:`_Banded.solve_box`); a few such alternations, then the moved poses
    are checked. A colliding pose goes as far toward its new value as the checks allow
    (bisection in joint space), its rotary value is held there and its tilt may not come
    nearer the preferred axis; then the polish is repeated (``rounds`` at most). Every
    returned pose was checked free (or is the programme's). ``max_step`` (rad) with ``hard``
    ((n-1,) bool, the moves the programme kept within it): where polished neighbours end up
    farther apart, the poses around go back to the programme's (:func:`_within_steps`).
    Returns ``(theta, phi, info)``."""
    n = len(theta0)
    info = {"joint_rounds": 0, "joint_checks": 0, "held_points": 0}
    theta0 = np.asarray(theta0, float)
    phi0 = np.asarray(phi0, float)
    if n < 3:
        return theta0.copy(), phi0.copy(), info
    ds = np.maximum(np.linalg.norm(np.diff(path.contact, axis=0), axis=1), 1e-3)
    L = cost.length
    couple = np.ones(n - 1, bool) if move_free is None else ~np.asarray(move_free, bool)
    if rot.phi_limited:
        couple &= np.abs(np.diff(phi0)) < 0.5 * np.pi            # rewinds of a limited C
    half = np.zeros(n)
    half[:-1] += 0.5 * ds
    half[1:] += 0.5 * ds
    K0 = rot.axis(theta0, phi0)
    alpha = max(cost.alpha, 1e-9)
    Qphi = _quadratic(n, ds, couple, L, alpha * cost.w + cost.beta * 0.0, cost.l_phi)
    Qth = _quadratic(n, ds, couple, L, alpha + cost.beta, cost.l_theta)
    held = np.zeros(n, bool)                       # pose held after a collision
    theta, phi = theta0.copy(), phi0.copy()        # the last poses checked free (and admissible)
    M = 0 if free_tilt is None else free_tilt.shape[1]
    bw_t = bw_p = None
    hold = (half / L) * np.sin(theta0) ** 2 + 1e-9 * half / L
    lat = _latitude_terms(rot, constraints)        # the constraints' terms for phi_interval, once

    def arcs(ph, th, idx=None):
        cons = constraints if idx is None else [(h[idx], np.asarray(b)[idx]) for h, b in constraints]
        lo, hi = theta_interval(rot, ph, cons, th)
        return np.maximum(lo, rot.theta_lo), np.minimum(hi, rot.theta_hi)

    def admissible(ph, th, idx):
        """Whether the poses (ph, th) of the points ``idx`` lie on their arcs (the cones, the
        tilt axis's range) and off the pole by ``pole_tilt`` on the programme's side."""
        lo, hi = arcs(ph, th, idx)
        ok = (th >= lo - 1e-12) & (th <= hi + 1e-12)
        if pole_tilt > 0:
            t0 = theta0[idx]
            ok &= np.where(t0 > 0, th >= pole_tilt - 1e-12, np.where(t0 < 0, th <= -pole_tilt + 1e-12, True))
        return ok

    built = {}
    # each solve starts from the active set the last one of its kind ended with (the
    # alternations' problems differ little: on the keycap the second and third alternations'
    # solves each end in their first iteration from it, against 40-46 from every row free)
    act_phi = np.zeros(n, np.int8)
    act_theta = np.zeros(n, np.int8)

    def quadratic(Q: _Banded, bw, w_vel: float, l_acc: float) -> np.ndarray:
        """The band of ``_quadratic(..., bw)``: Q's where every block weight is 1 (the same
        products: x * 1.0 is x), the last one built for the same weights, else built."""
        if bw is None or not (bw != 1.0).any():
            return Q.ab
        last = built.get(id(Q))
        if last is None or not np.array_equal(last[0], bw):
            last = built[id(Q)] = (bw.copy(), _quadratic(n, ds, couple, L, w_vel, l_acc, bw).ab)
        return last[1]

    for r in range(rounds):
        info["joint_rounds"] = r + 1
        th_c = np.where(held, theta, theta0)           # every round starts from the programme
        ph_c = np.where(held, phi, phi0)
        tp = None                                      # best_theta(pref, ph_c) once known
        for _ in range(alternations):
            start = (th_c, ph_c, bw_t, bw_p, act_phi.copy(), act_theta.copy())
            # 1. rotary values: smooth where the tilt stays admissible, held where the tool
            # axis would turn with them (nothing near the pole)
            plo, phi_hi = phi_interval(rot, th_c, constraints, ph_c, lat)
            # ... or at a little more tilt away from the preferred axis, which the tilt step
            # may then take (the rotary value held by a tilt on its bound can move)
            away = np.where(th_c >= (rot.best_theta(pref, ph_c) if tp is None else tp), 1.0, -1.0)
            th2 = np.clip(th_c + away * lean, rot.theta_lo, rot.theta_hi)
            l2, h2 = phi_interval(rot, th2, constraints, ph_c, lat)
            ok2 = (l2 <= ph_c) & (ph_c <= h2)
            plo, phi_hi = np.where(ok2, np.minimum(plo, l2), plo), np.where(ok2, np.maximum(phi_hi, h2), phi_hi)
            if rot.phi_limited:
                plo, phi_hi = np.maximum(plo, rot.phi_lo), np.minimum(phi_hi, rot.phi_hi)
            if free_tilt is not None:        # ... and through azimuths known free
                az = ph_c + np.where(th_c < 0, np.pi, 0.0)
                wl, wr = _azimuth_window(free_tilt, az, np.abs(th_c) + lean, M)
                plo, phi_hi = np.maximum(plo, ph_c - wl), np.minimum(phi_hi, ph_c + wr)
            plo = np.where(held, ph_c, np.minimum(plo, ph_c))   # the current value is admissible
            phi_hi = np.where(held, ph_c, np.maximum(phi_hi, ph_c))
            B = _Banded(n, 2)
            B.ab[:] = quadratic(Qphi, bw_p, alpha * cost.w, cost.l_phi)
            B.add(hold, np.arange(n)[:, None], np.ones((n, 1)), -phi0)
            try:
                ph_c = B.solve_box(plo, phi_hi, at=act_phi)
            except np.linalg.LinAlgError:
                # a run of points at the pole, where the rotary value hardly weighs, held to the
                # programme by almost nothing: the factor cancels to a pivot of 0 or less (a flat
                # square under a fork head: its C uncoupled across rewinds). Held by 1e-9 of the
                # largest diagonal more, it is definite again; elsewhere nothing changes
                B.add(np.full(n, 1e-9 * float(np.abs(B.ab[2]).max())), np.arange(n)[:, None],
                      np.ones((n, 1)), -phi0)
                ph_c = B.solve_box(plo, phi_hi, at=act_phi)
            # 2. tilts: the convex problem on the admissible arcs at the new rotary values
            tp = rot.best_theta(pref, ph_c)
            lo, hi = arcs(ph_c, th_c)
            if pole_tilt > 0:                          # stay on the programme's side of the pole
                lo = np.where(theta0 > 0, np.maximum(lo, pole_tilt), lo)
                hi = np.where(theta0 < 0, np.minimum(hi, -pole_tilt), hi)
            if free_tilt is not None:        # the free tilts the programme found
                up = th_c >= 0
                t_pos = _tilt_table(free_tilt, ph_c, M)
                t_neg = _tilt_table(free_tilt, ph_c + np.pi, M)
                # a raised side keeps the tilt at its bound; a raised other side keeps it off
                # the pole's other side
                b_up = np.where(t_pos > 0, t_pos, np.where(t_neg > 0, 0.0, -np.inf))
                b_dn = np.where(t_neg > 0, -t_neg, np.where(t_pos > 0, 0.0, np.inf))
                lo = np.where(up, np.maximum(lo, b_up), lo)
                hi = np.where(~up, np.minimum(hi, b_dn), hi)
            lo, hi = np.minimum(lo, th_c), np.maximum(hi, th_c)
            lo, hi = np.where(held, th_c, lo), np.where(held, th_c, hi)
            B = _Banded(n, 2)
            B.ab[:] = quadratic(Qth, bw_t, alpha + cost.beta, cost.l_theta)
            B.add(half / L, np.arange(n)[:, None], np.ones((n, 1)), -tp)
            th_c = B.solve_box(lo, hi, at=act_theta)
            if cost.feed > 0 and cost.over > 0:
                # blocks beyond an axis's speed at the feed would slow it: weigh them more
                # in the next alternation (iteratively reweighted)
                r_t = np.abs(np.diff(th_c)) / (ds * rot.v_theta / cost.feed)
                r_p = np.abs(np.diff(ph_c)) / (ds * rot.v_phi / cost.feed)
                bw_t = np.maximum(1.0 if bw_t is None else bw_t,
                                  np.minimum(1.0 + cost.over * np.maximum(r_t - 1.0, 0.0) ** 2, 100.0))
                bw_p = np.maximum(1.0 if bw_p is None else bw_p,
                                  np.minimum(1.0 + cost.over * np.maximum(r_p - 1.0, 0.0) ** 2, 100.0))
            if all(a is b or (a is not None and b is not None and np.array_equal(a, b))
                   for a, b in zip(start, (th_c, ph_c, bw_t, bw_p, act_phi, act_theta))):
                # a fixed point: the next alternation would start from the same values and
                # active sets and give them again (the keycap's second alternation gave the
                # first's bits, its solves ending where they started)
                break
        # 3. the tilts onto their arcs: step 1 may move a rotary value to where only a little
        # more tilt is admissible (``lean``) and step 2's box holds the current tilt, so a tilt
        # may end up to ``lean`` beyond its cone (the keycap's side tilt 61.8 deg against its 60
        # at 406 points); it goes to the arc's nearest end, once per round (inside the
        # alternations the moves added up: up to 3 ``lean`` more tilt on both sides of a pole
        # crossing, a 19 deg step against the programme's 7)
        a_lo, a_hi = arcs(ph_c, th_c)
        if pole_tilt > 0:
            a_lo = np.where(theta0 > 0, np.maximum(a_lo, pole_tilt), a_lo)
            a_hi = np.where(theta0 < 0, np.minimum(a_hi, -pole_tilt), a_hi)
        th_c = np.where(held | (a_lo > a_hi), th_c, np.minimum(np.maximum(th_c, a_lo), a_hi))
        # lazy collision checks of the moved poses; a colliding one goes as far as it can. A
        # moved pose still outside the cones (an empty arc) is not taken either, and goes as far
        # as they allow
        K = rot.axis(theta, phi)
        Kc = rot.axis(th_c, ph_c)
        todo = np.nonzero(angle_between(Kc, K) > 1e-9)[0]
        bad = np.zeros(0, int)
        if len(todo):
            inside = (th_c[todo] >= a_lo[todo] - 1e-12) & (th_c[todo] <= a_hi[todo] + 1e-12)
            bad, ask = todo[~inside], todo[inside]
            if checker is not None and len(ask):
                hit = checker.collides(path.center[ask], Kc[ask])
                info["joint_checks"] += len(ask)
                if tick is not None:
                    tick()
                bad = np.union1d(bad, ask[hit])
        good = np.setdiff1d(todo, bad)
        theta[good], phi[good] = th_c[good], ph_c[good]
        if len(bad) == 0:
            break
        # first keep the new rotary value with the tilt where it was, or a little further
        # from the preferred axis (a collision limits the tilt more often than the azimuth:
        # the rotary value then stays with its smoothed neighbours)
        tp_b = rot.best_theta(pref[bad], ph_c[bad])
        away = np.where(theta[bad] >= tp_b, 1.0, -1.0)
        placed = np.zeros(len(bad), bool)
        for extra in (0.0, lean, 2 * lean):
            q = np.nonzero(~placed)[0]
            if len(q) == 0:
                break
            tt = np.clip(np.where(away[q] > 0, np.maximum(theta[bad[q]], th_c[bad[q]]),
                                  np.minimum(theta[bad[q]], th_c[bad[q]])) + away[q] * extra,
                         rot.theta_lo, rot.theta_hi)
            ok = admissible(ph_c[bad[q]], tt, bad[q])
            q, tt = q[ok], tt[ok]
            if len(q):
                free = (np.ones(len(q), bool) if checker is None else
                        ~checker.collides(path.center[bad[q]], rot.axis(tt, ph_c[bad[q]])))
                info["joint_checks"] += 0 if checker is None else len(q)
                theta[bad[q[free]]], phi[bad[q[free]]] = tt[free], ph_c[bad[q[free]]]
                placed[q[free]] = True
        held[bad] = True
        bad = bad[~placed]
        t_lo, t_hi = np.zeros(len(bad)), np.ones(len(bad))
        for _ in range(bisect):
            t = 0.5 * (t_lo + t_hi)
            tt = theta[bad] + t * (th_c[bad] - theta[bad])
            pt = phi[bad] + t * (ph_c[bad] - phi[bad])
            q = np.nonzero(admissible(pt, tt, bad))[0]
            free = np.zeros(len(bad), bool)
            if len(q):
                free[q] = True if checker is None else ~checker.collides(path.center[bad[q]], rot.axis(tt[q], pt[q]))
                info["joint_checks"] += 0 if checker is None else len(q)
            t_lo = np.where(free, t, t_lo)
            t_hi = np.where(free, t_hi, t)
        theta[bad] = theta[bad] + t_lo * (th_c[bad] - theta[bad])
        phi[bad] = phi[bad] + t_lo * (ph_c[bad] - phi[bad])
    info["held_points"] = int(held.sum())
    if max_step is not None and hard is not None:
        back = _within_steps(rot.axis(theta, phi), rot.axis(theta0, phi0), hard, max_step)
        theta, phi = np.where(back, theta0, theta), np.where(back, phi0, phi)
    return theta, phi, info


def _within_steps(K, K0, hard, max_step: float) -> np.ndarray:
    """Mask of the points whose polished axes ``K`` go back to the programme's ``K0`` so that
    no ``hard`` move turns the axis by more than ``max_step`` (rad): both ends of a move
    beyond it, and on, until none is (the programme keeps it on every hard move, so this
    ends). The polish holds each tilt on its own arc: at a pole crossing under a tight cone
    both sides may lean away (the keycap under 25 deg limits: 11.2 deg against the
    programme's 7.2)."""
    n = len(K)
    back = np.zeros(n, bool)
    hard = np.asarray(hard, bool)
    moves = np.nonzero(hard)[0]                           # move i joins points i and i + 1
    while len(moves):
        a, b = (np.where(back[m, None], K0[m], K[m]) for m in (moves, moves + 1))
        over = moves[angle_between(b, a) > max_step + 1e-9]
        new = np.unique(np.concatenate([over, over + 1]))
        new = new[~back[new]]
        back[new] = True
        # only the moves next to a point that went back can change
        near = np.unique(np.concatenate([new - 1, new]))
        moves = near[(near >= 0) & (near < n - 1)]
        moves = moves[hard[moves]]
    return back


# --- the rotary travel the cones force -----------------------------------------------------------

def forced_rotary_travel(grid: MeridianGrid, status, ds, air=None):
    """The least rotary (C) travel (rad) of any pose sequence over the grid's rotary values:
    a Viterbi programme minimising sum |dphi| alone, over the meridians that meet the
    admissible cone (lead/tilt limits, the controls' cones, the tilt axis's range) and are
    not known to collide at every admissible tilt (``status`` 2 from the checks of
    :func:`joint_programme`; meridians never checked count as free, so the figure is a lower
    bound for that grid), with the same ban on rotary steps above ``IN_PLACE`` on short
    blocks (``ds`` (n-1,) contact spacing; ``air`` (n,) points reached by a retract or rapid
    are exempt). Tilts and the maximum axis step are left free: what remains is what the
    cones, the collisions and the tilt range force, e.g. a half-turn of C where the tool
    must lean further to the other side than the other branch allows. A finer grid
    (``resolution``) finds narrower collision-free windows and can do with less. Returns
    ``(travel, states)``, ``(nan, None)`` when no sequence exists."""
    n, M = grid.theta.shape
    phis = grid.phi
    D = np.abs(np.pi - np.mod(np.pi - (phis[None, :] - phis[:, None]), 2 * np.pi))
    swing = D > IN_PLACE[1] + 1e-9
    air = np.zeros(n, bool) if air is None else np.asarray(air, bool)
    node = np.where(grid.ok & (np.asarray(status) != 2), 0.0, np.inf)
    short = (np.asarray(ds) < IN_PLACE[0]) & ~air[1:]
    # the two transitions there are: D, and D with the swings forbidden (into a short block)
    both = np.stack([D, np.where(swing, np.inf, D)])
    kind = short.astype(np.intp)

    plain: dict = {}             # blocks without a short block: the same array each time

    def block(i0: int, i1: int) -> np.ndarray:
        s = kind[i0 - 1:i1 - 1]
        if not s.any():
            t = plain.get(i1 - i0)
            if t is None:
                t = plain[i1 - i0] = np.broadcast_to(D, (i1 - i0, M, M)).copy()
            return t
        return np.take(both, s, axis=0)         # (one gather; keycap: 4954 short blocks)

    # with the kernels: each move's transition read from its kind's matrix in the kernel
    # (kind_steps: no block made; the same transitions, so the same states; keycap: one call
    # where its 1,100 runs of one kind took a call each, the figure 0.020 -> 0.011 s profiled)
    both_c, kind_c = np.ascontiguousarray(both, float), np.ascontiguousarray(kind, np.int64)

    def steps(k, acc, node_, i0: int, i1: int, tie: float, back) -> int:
        return k["kind_steps"](acc, node_, both_c, kind_c, i0, i1, tie, back)
    states, _ = viterbi(node, from_blocks(block, steps if n > 1 else None))
    if states is None:
        return np.nan, None
    return float(D[states[:-1], states[1:]].sum()), states
