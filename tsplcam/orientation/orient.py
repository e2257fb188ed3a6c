"""Tool orientation strategies: fixed, closest to +Z (shang2020), smoothed (after xu2013).

``orient(path, model, tool, strategy=...)`` returns the path with new tool axes and an
:class:`OrientationReport`. Every strategy returns only poses the collision checker passed
(flutes, shank and holder off the workpiece, the ball not gouging any patch) and reachable
by the machine; where no such axis exists it raises :class:`CollisionError` naming the
point, patch, (u, v) and what the tool hits.

* ``fixed``: exactly the target axis at every point (one axis: 3+2, the three-axis baseline;
  or a fixed lead/tilt, toward a point or a line: orientation.controls); refused, naming the
  point, where it collides or leaves a limit.
* ``closest`` (``closest-z``): "tilt only where needed", shang2020 (end of 3.5): per point the
  collision-free axis closest to the target (+Z). Computed as the smooth strategy with a
  smoothing length of ``CLOSEST_LENGTH`` (0.05 mm): the deviation decides, the machine's
  joint motion only breaks ties, so where several poses are as close (at the pole, where
  any rotary value gives the axis) the rotary axis holds still, and no neighbouring axes
  differ by more than ``max_step``. :func:`orient_closest` is the literal per-point rule
  (candidates tried in order of their angle to the target, then pulled toward it by
  bisection), kept for comparisons: its axes jump where the nearest wall changes.
* ``smooth``: xu2013 replaces the per-point choice by a smooth sequence picked from a cone of
  candidates per point. Here that choice is made where the machine feels it, in the joint
  space of its rotary axes (orientation.smoothing): a Viterbi programme over poses of a grid
  of rotary values, each with its admissible tilt nearest the preferred axis, minimising
  rotary-axis velocity (in the machine's time units) plus the deviation from the preferred
  axis, with lazy collision checks; then a continuous polish of the chosen poses with
  velocity and acceleration terms against the machine's limits, on the admissible arcs and
  inside what the checks found free. Without a machine a virtual A/C table stands in.
"""
from __future__ import annotations

import contextlib
import functools
from dataclasses import dataclass, field

import numpy as np

from ..errors import CollisionError, InputError
from .candidates import (DEG, Z_AXIS, Limits, Reach, admissible, angle, candidate_axes,
                         feed_directions, unit)
from .aside import MIN_POINTS, Aside
from .collision import CollisionChecker, decided_there
from .controls import limit_halfspaces, point_settings, runs, target_axes
from .settings import STRATEGIES, OrientationSettings  # noqa: F401 (STRATEGIES: orient.STRATEGIES)
from .rotary import Rotary
from .smoothing import (NoPath, SmoothingCost, cone_halfspaces, forced_rotary_travel, free_tilts,
                        joint_programme, meridian_grid, resolve_meridians, smooth_joints)
from ..toolpath.path import Move

# The rotary axis's velocity counts twice its share of the tilt axis's time: with the squared
# velocities of J, 1 would be the time-consistent weight, but the machining time follows the
# peaks the squares smooth over; 2 measured best on the keycap, its mold half and deep_mold
# (estimated time / length-feed time 1.04, 1.09, 1.07 against 1.03, 1.15, 1.10 with 1, at a
# 0.01 mm scallop and the full acceleration weight).
ROTARY_WEIGHT = 2.0
# The acceleration terms at a sixteenth of their time-consistent weight (l = F v / (4 a)):
# the squared accelerations at full weight over-smooth, holding the axes off the bounds the
# walls set; the full jobs measured estimated time / length-feed time 1.092 on the mold half
# with 1/16 against 1.100 (1/4), 1.110 (1), 1.217 (4) and 1.134 without acceleration terms.
ACCELERATION_WEIGHT = 1.0 / 16.0
# The rotary travel sum |dC| (rad) in the programme, at this weight per radian: C moves only
# where the cones and the collisions make it, and the programme then meets the least travel
# its grid allows (forced_rotary_travel). Measured on the coarse test paths (scallop 0.2 mm):
# keycap_mold 2698 -> 2680, 2488, 2363 deg of C at weights 0.1, 1, 10 (100 and 1000 as 10),
# deep_mold 2056 -> 2056, 1978, 1598, the time ratio falling a little with it (1.091 ->
# 1.087, 1.062 -> 1.056). "closest" leaves it out: there the deviation decides.
TRAVEL_WEIGHT = 10.0


@dataclass
class OrientationReport:
    """What the orientation stage did and what it measured while doing it."""
    strategy: str
    points: int
    checks: int = 0                    # collision queries (tool poses) asked of fcl
    seconds: float = 0.0
    dp_rounds: int = 0                 # lazy DP runs (smooth)
    resolved_points: int = 0           # points whose whole candidate cone was checked
    relaxation_moves: int = 0
    max_step_deg: float = 0.0
    mean_step_deg: float = 0.0
    max_deviation_deg: float = 0.0     # largest angle to the preferred axis
    c_travel_forced_deg: float | None = None   # least C travel the cones and collisions allow (grid)
    tolerance: float = 0.0
    triangles: int = 0
    settings: dict = field(default_factory=dict)
    _later: object = field(default=None, repr=False, compare=False)   # what finish() computes

    def finish(self) -> None:
        """Compute the figures :func:`orient` left for later (``later``: the forced C travel),
        into this report and the oriented path's ``info``; nothing when none is left."""
        later, self._later = self._later, None
        if later is not None:
            later()

    def summary(self) -> str:
        forced = "" if self.c_travel_forced_deg is None else \
            f", C travel the cones and collisions force {self.c_travel_forced_deg:.0f} deg"
        return (f"orientation {self.strategy}: {self.points} points, {self.checks} collision checks "
                f"in {self.seconds:.2f} s, largest step {self.max_step_deg:.2f} deg, mean "
                f"{self.mean_step_deg:.3f} deg, largest deviation from preferred "
                f"{self.max_deviation_deg:.1f} deg{forced} (mesh {self.triangles} triangles within "
                f"{self.tolerance:g} mm)")


def _where(path, i: int) -> str:
    text = f"point {i + path.info.get('index_offset', 0)}"
    if path.patch[i] >= 0:
        u, v = path.uv[i]
        text += f" (patch {int(path.patch[i])}, u={u:.4f}, v={v:.4f})"
    return text


def _cone_text(limits: Limits) -> str:
    """The lead/tilt cone around the normal as the job's options name it."""
    return f"max_lead {limits.lead_max / DEG:g} deg, max_side_tilt {limits.tilt_max / DEG:g} deg"


def _no_axis_error(path, checker: CollisionChecker, i: int, tried: np.ndarray, why: str) -> CollisionError:
    """CollisionError for point i naming what the most promising tried axis hits."""
    c = path.center[i]
    hit = None
    for a in tried:
        hit = checker.hit(c, a)
        if hit is not None:
            break
    what = f"; e.g. with axis ({tried[0][0]:.4f}, {tried[0][1]:.4f}, {tried[0][2]:.4f}) {hit}" \
        if hit is not None else ""
    if hit is not None and hit.clearance > 0.0:
        what += (" (room for the tool: a longer stick-out or a slimmer holder, a smaller holder "
                 "clearance, or wider tilt limits)")
    return CollisionError(f"{_where(path, i)}: {why}{what}")


def ball_check(path, checker: CollisionChecker, then=None) -> Aside:
    """The ball gouge check of ``path`` (its ball centres, which do not move with the axes:
    :func:`orient` raises its error) beside this process where the path is long enough to
    pay for a fork (:class:`~tsplcam.orientation.aside.Aside`); ``then``: a second piece the
    same process runs after it on arguments given later (:meth:`Aside.follow`), with the
    checker's BVH built there meanwhile (the broad phase answers the check itself without
    it); that process may start the checker's pool for it, and answers half of the
    checker's large batches until then (:attr:`CollisionChecker.beside`, set by the caller
    while it searches the axes)."""
    return Aside(_check_ball, path, checker, beside=len(path) >= MIN_POINTS, then=then,
                 meanwhile=None if then is None else checker.build_bvh, children=then is not None,
                 serve=None if then is None else functools.partial(decided_there, checker))


def _check_ball(path, checker: CollisionChecker) -> None:
    bad = checker.ball_gouges(path.center)
    if bad.any():
        i = int(np.argmax(bad))
        hit = checker.ball_hit(path.center[i])
        raise CollisionError(f"{_where(path, i)}: the ball cuts more than {checker.gouge_tolerance:g} mm "
                             f"into the part whatever the axis: {hit} ({int(bad.sum())} such points)")


# --- strategies ----------------------------------------------------------------------------

def _toward(a, b, t):
    """Great-circle points from a toward b at fractions t (all (n,3)/(n,))."""
    ang = angle(a, b)
    s = np.sin(ang)
    small = s < 1e-9
    w0 = np.where(small, 1 - t, np.sin((1 - t) * ang) / np.where(small, 1, s))
    w1 = np.where(small, t, np.sin(t * ang) / np.where(small, 1, s))
    return unit(w0[:, None] * a + w1[:, None] * b)


def orient_closest(path, checker, preferred, limits: Limits, reach, feed, bisect: int = 6, tick=None,
                   constraints=()):
    """shang2020: per point the admissible collision-free axis closest to ``preferred``;
    ``constraints``: half-spaces ``(h, b)``, ``h . a >= b``, the axes must keep too."""
    n = len(path)
    C = path.center
    A, ok = candidate_axes(path.normal, feed, preferred, limits, reach)
    ok &= _keeps(A, constraints)
    tick = tick or (lambda m: None)
    pref = unit(np.broadcast_to(preferred, (n, 3)).copy())
    dev = angle(A, pref[:, None, :])
    order = np.argsort(np.where(ok, dev, np.inf), axis=1, kind="stable")
    chosen = np.full(n, -1)
    open_ = ok.any(axis=1)
    if not open_.all():
        i = int(np.argmin(open_))
        raise CollisionError(f"{_where(path, i)}: no candidate axis within the lead/tilt limits "
                             f"({_cone_text(limits)}) and the machine's reach "
                             f"({reach.name if reach else 'no machine'})")
    for rank in range(A.shape[1]):
        idx = np.nonzero(open_ & (chosen < 0))[0]
        if len(idx) == 0:
            break
        col = order[idx, rank]
        valid = ok[idx, col]
        idx, col = idx[valid], col[valid]
        if len(idx) == 0:
            break
        free = ~checker.collides(C[idx], A[idx, col])
        chosen[idx[free]] = col[free]
        tick(A.shape[1])
    missing = np.nonzero(chosen < 0)[0]
    if len(missing):
        i = int(missing[0])
        raise _no_axis_error(path, checker, i, A[i, order[i, :3]],
                             f"no collision-free tool axis in the cone of {np.count_nonzero(ok[i])} "
                             f"candidates ({len(missing)} such points)")
    axes = A[np.arange(n), chosen]
    # pull toward the preferred axis by bisection along the great circle (free end: axes)
    lo = np.zeros(n)                                  # fraction known free
    hi = np.ones(n)                                   # fraction not known free
    top = angle(axes, pref) > 1e-9
    first = _toward(axes, pref, np.ones(n))
    okp = admissible(first[:, None], path.normal, feed, limits, reach)[:, 0]
    hi[~top] = 0.0
    for _ in range(bisect):
        idx = np.nonzero(top & (hi - lo > 1e-6))[0]
        if len(idx) == 0:
            break
        t = 0.5 * (lo[idx] + hi[idx])
        cand = _toward(axes[idx], pref[idx], t)
        good = admissible(cand[:, None], path.normal[idx], feed[idx], limits, reach)[:, 0]
        good &= _keeps(cand[:, None], [(h[idx], b[idx]) for h, b in constraints])[:, 0]
        free = np.zeros(len(idx), bool)
        if good.any():
            free[good] = ~checker.collides(C[idx[good]], cand[good])
        lo[idx[free]] = t[free]
        hi[idx[~free]] = t[~free]
    del okp, first
    return _toward(axes, pref, lo), {"bisection_steps": bisect}


def cutting_directions(path) -> np.ndarray:
    """Feed directions of the points for the lead/tilt cone: the central difference, except at
    a line's first and last point, where it is the line's own direction (the move to or
    from the neighbouring line is a link, not the cut: the cone must not turn with it)."""
    feed = feed_directions(path.contact, path.normal)
    n = len(path)
    if n < 3:
        return feed
    P, N = path.contact, path.normal
    link = np.asarray(path.move) != Move.CUT
    last = np.nonzero(link[1:])[0]                       # the point before a non-cut move
    first = np.nonzero(link[:-1])[0]                     # a point a non-cut move arrives at
    for idx, d in ((last[last >= 1], P[last[last >= 1]] - P[last[last >= 1] - 1]),
                   (first, P[first + 1] - P[first])):
        if len(idx) == 0:
            continue
        d = d - np.einsum("ij,ij->i", d, N[idx])[:, None] * N[idx]
        ok = np.linalg.norm(d, axis=1) > 1e-12
        feed[idx[ok]] = unit(d[ok])
    return feed


def _keeps(A, constraints) -> np.ndarray:
    """Mask (n, m) of candidate axes A (n, m, 3) inside every half-space ``(h, b)``."""
    ok = np.ones(A.shape[:2], bool)
    for h, b in constraints:
        ok &= np.einsum("nmi,ni->nm", A, h) >= b[:, None] - 1e-12
    return ok


def _spacing(path) -> np.ndarray:
    ds = np.linalg.norm(np.diff(path.contact, axis=0), axis=1)
    return np.maximum(ds, 1e-3)


def orient_smooth(path, checker, preferred, limits: Limits, reach, feed, smoothing_length: float,
                  max_step: float, window: int = 2, cost: SmoothingCost | None = None,
                  constraints=(), pole_tilt: float = 0.0, tick=None, later: bool = False):
    """xu2013 after the module docstring, in the machine's joint space (orientation.smoothing):
    a Viterbi programme over the poses of a grid of rotary values (each with its admissible
    tilt nearest the preferred axis) with lazy collision checks, then the continuous
    joint-space smoothing. ``preferred`` (3,) or (n,3); ``constraints``: more half-spaces
    ``(h, b)``, ``h . a >= b``, the axes must keep (the controls' cones). ``later``: the
    figure of the forced C travel (info ``c_travel_forced_deg``) comes as a function that
    computes it, for a caller with time to spare later (it changes no axis)."""
    n = len(path)
    C = path.center
    pref = unit(np.broadcast_to(preferred, (n, 3)).copy())
    if cost is None:
        cost = SmoothingCost.build(None, smoothing_length)
    rot = cost.rotary
    tick = tick or (lambda m: None)
    M = max(12, int(round(2 * np.pi / limits.resolution)))
    cons = [(h, np.zeros(n)) for h in cone_halfspaces(path.normal, feed, limits.lead_max, limits.tilt_max)]
    cons += list(constraints)
    grid = meridian_grid(rot, pref, path.normal, cons, M, pole_tilt)
    none = ~grid.ok.any(axis=1)
    if none.any():
        i = int(np.argmax(none))
        raise CollisionError(f"{_where(path, i)}: no tool axis within the lead/tilt limits "
                             f"({_cone_text(limits)}), the controls' limits and the machine's reach "
                             f"({reach.name if reach else 'no machine'})")
    ds = _spacing(path)
    free_step = path.move != Move.CUT          # links and retracts: no hard step limit
    half = np.concatenate([[ds[0]], ds]) * 0.5 + np.concatenate([ds, [ds[-1]]]) * 0.5
    air = np.isin(path.move, (Move.RETRACT, Move.RAPID))
    try:
        states, rounds, checks, status = joint_programme(checker, C, grid, cost, pref, ds, half / smoothing_length,
                                                 max_step, free_step, limits.resolution, tick=lambda: tick(M),
                                                 air=air)
    except NoPath as e:
        i = e.point
        if e.kind == "point":
            k = np.nonzero(grid.ok[i])[0][:3]
            raise _no_axis_error(path, checker, i, rot.axis(grid.theta[i, k], grid.phi[k]),
                                 f"no collision-free tool axis on any of the {int(grid.ok[i].sum())} "
                                 "admissible rotary positions") from None
        raise CollisionError(f"{_where(path, i)} -> {_where(path, i + 1)}: no pair of collision-free "
                             f"axes within the largest axis step of {max_step / DEG:.1f} deg (allow a larger "
                             f"one, max_axis_step, or wider lead/tilt limits, {_cone_text(limits)}; or split "
                             "the path there)") from None
    # the least rotary travel any sequence of the grid's poses known or presumed free can have
    def forced_deg() -> float:
        return forced_rotary_travel(grid, status, ds, air=air)[0] / DEG
    forced = forced_deg if later else forced_deg()
    theta = grid.theta[np.arange(n), states].copy()
    phi = grid.phi[states]
    phi = phi[0] + np.concatenate([[0.0], np.cumsum(np.pi - np.mod(np.pi - np.diff(phi), 2 * np.pi))])
    moving = ~np.isin(path.move[1:], (Move.CUT, Move.LINK))
    theta, phi, info = smooth_joints(path, rot, theta, phi, pref, path.normal, cost, cons, checker=checker,
                                     free_tilt=free_tilts(grid, status), move_free=moving, pole_tilt=pole_tilt,
                                     tick=lambda: tick(M), max_step=max_step, hard=~free_step[1:])
    return rot.axis(theta, phi), {"dp_rounds": rounds, "resolved_points": 0,
                                  "relaxation_moves": info["joint_checks"], "candidates": M,
                                  "dp_checks": checks, "c_travel_forced_deg": forced} | info


def forced_c_travel(path, checker, machine=None, *, resolution: float = 10.0, lead_max: float = 60.0,
                    tilt_max: float = 60.0, preferred=(0.0, 0.0, 1.0)) -> float:
    """The C travel (deg) the cones force on ``path``, every pose of the grid checked: the
    smooth strategy's grid (rotary values every ``resolution`` degrees, on each the admissible
    tilts searched every ``resolution`` degrees from the one nearest ``preferred`` and the
    boundary bisected), each rotary value collision-checked along its whole arc, then
    :func:`~tsplcam.orientation.smoothing.forced_rotary_travel`. The reference for the figure
    the smooth strategy reports from its lazy checks (``c_travel_forced_deg``), and, at a finer
    resolution, how much of it the grid's coarseness makes. Costs about 100 checks a point."""
    n = len(path)
    rot = Rotary.from_machine(machine) if machine is not None else Rotary()
    M = max(12, int(round(360.0 / resolution)))
    feed = cutting_directions(path)
    pref = unit(np.broadcast_to(np.asarray(preferred, float), (n, 3)).copy())
    cons = [(h, np.zeros(n)) for h in cone_halfspaces(path.normal, feed, lead_max * DEG, tilt_max * DEG)]
    grid = meridian_grid(rot, pref, path.normal, cons, M)
    status = np.where(grid.ok, -1, 2).astype(np.int8)
    pj, pk = np.nonzero(status == -1)
    step = resolution * DEG
    resolve_meridians(checker, path.center, rot, grid, status, pj, pk, step,
                      count=int(np.ceil(np.pi / step)))
    travel, _ = forced_rotary_travel(grid, status, _spacing(path),
                                     air=np.isin(path.move, (Move.RETRACT, Move.RAPID)))
    return travel / DEG


def smoothing_cost(machine, reach, smoothing_length: float, rotary_weight: float | None,
                   feed: float, acceleration_weight: float = ACCELERATION_WEIGHT,
                   travel: float = 0.0) -> SmoothingCost:
    """The smooth strategy's weights (orientation.smoothing). With a machine: its rotary axes'
    joint space, rotary motion counted ``rotary_weight`` (default ``ROTARY_WEIGHT``) times in tilt-axis time
    (the machine's (tilt speed / rotary speed)^2), accelerations against its limits at the
    path's feed, the rotary travel at ``travel`` per radian (``TRAVEL_WEIGHT`` for smooth; none
    when the rotary weight is 0). Without one: the tool-axis direction (a rotary weight > 0 is
    refused: there is no rotary axis to weigh)."""
    for name, v in (("rotary weight", rotary_weight), ("acceleration weight", acceleration_weight)):
        if v is not None and (not np.isfinite(v) or v < 0):
            raise InputError(f"{name} must be a number >= 0, not {v}")
    if machine is None:
        if rotary_weight:
            raise InputError("a rotary weight needs a machine (--machine): it weighs that machine's rotary axis")
        cost = SmoothingCost.build(None, smoothing_length)
        if reach is not None:
            cost.rotary.theta_lo, cost.rotary.theta_hi = -reach.theta_max, reach.theta_max
        return cost
    rw = ROTARY_WEIGHT if rotary_weight is None else float(rotary_weight)
    cost = SmoothingCost.build(Rotary.from_machine(machine), smoothing_length, rw, acceleration_weight, feed)
    if rw == 0.0:
        cost.beta = 1.0                          # C not weighed: keep the axis direction smooth
    else:
        cost.travel = float(travel)
    return cost


def _resolve(checker, C, A, status, resolved, idx, tick=None, chunk: int = 20000):
    """Check every still unknown candidate of the points ``idx`` (``chunk`` poses at a time,
    calling ``tick(m)`` after each for progress)."""
    idx = np.asarray(idx, int)
    if len(idx) == 0:
        return
    pi, ci = np.nonzero(status[idx] == -1)
    for s0 in range(0, len(pi), chunk):
        rows, cols = idx[pi[s0:s0 + chunk]], ci[s0:s0 + chunk]
        hit = checker.collides(C[rows], A[rows, cols])
        status[rows, cols] = np.where(hit, 1, 0)
        if tick is not None:
            tick(A.shape[1])
    resolved[idx] = True


# --- the stage's entry point -------------------------------------------------------------------

CLOSEST_LENGTH = 0.05      # mm: the smoothing length of "closest": the deviation decides, joints break ties


def _narrowed(machine, tilt_range):
    """The machine with its tilt axis limits narrowed to ``tilt_range`` (deg, machine values)."""
    if machine is None or tilt_range is None:
        return machine
    from dataclasses import replace
    t = machine.tilt
    lo = tilt_range[0] if t.min is None else max(t.min, tilt_range[0])
    hi = tilt_range[1] if t.max is None else min(t.max, tilt_range[1])
    if lo >= hi:
        raise InputError(f"tilt_range {tilt_range[0]:g} .. {tilt_range[1]:g} leaves nothing of "
                         f"{t.name}'s range on machine {machine.name}", item="tilt_range")
    return replace(machine, tilt=replace(t, min=lo, max=hi))


def _segment(path, a: int, b: int):
    """Points a..b-1 of a path as a path (messages keep the whole path's point numbers)."""
    from dataclasses import replace
    info = dict(path.info)
    info["index_offset"] = info.get("index_offset", 0) + a
    return replace(path, contact=path.contact[a:b], normal=path.normal[a:b], axis=path.axis[a:b],
                   move=path.move[a:b], patch=path.patch[a:b], uv=path.uv[a:b], line=path.line[a:b], info=info)


def orient_target(path, checker, targets, reach, constraints=()):
    """Exactly the target axis at every point (a fixed axis: 3+2; or a fixed lead/tilt, toward
    a point or a line); refused where it points into the surface, leaves the machine's reach or
    a limit cone, or collides, naming the point."""
    A = unit(np.asarray(targets, float))
    side = np.einsum("ij,ij->i", path.normal, A) <= 1e-6
    if side.any():
        i = int(np.argmax(side))
        a = A[i]
        raise CollisionError(f"{_where(path, i)}: the target axis ({a[0]:.4f}, {a[1]:.4f}, {a[2]:.4f}) "
                             f"points into the surface (the ball cannot touch there with it)")
    if reach is not None:
        out = ~reach.ok(A)
        if out.any():
            i = int(np.argmax(out))
            raise CollisionError(f"{_where(path, i)}: the target axis is outside the reach of {reach.name}")
    for h, b in constraints:
        out = np.einsum("ij,ij->i", h, A) < b - 1e-12
        if out.any():
            i = int(np.argmax(out))
            raise CollisionError(f"{_where(path, i)}: the target axis leaves the largest tilt allowed "
                                 f"({np.degrees(np.arccos(np.clip(b[i], -1, 1))):.1f} deg from the limit axis)")
    bad = checker.collides(path.center, A)
    if bad.any():
        i = int(np.argmax(bad))
        raise _no_axis_error(path, checker, i, A[i:i + 1],
                             f"the target axis collides ({int(bad.sum())} of {len(path)} points)")
    return A, {}


def _axes(path, s: OrientationSettings, per_patch, checker, machine, reach, limits: Limits, tick,
          later: bool = False):
    """The tool axes of :func:`orient` run by run of one strategy: (axes, target axes, the
    strategies' figures summed, the smooth strategy's cost, the forced C travel: None, or with
    ``later`` a function that computes it)."""
    n = len(path)
    feed = cutting_directions(path)
    # per point: strategy, target axis and the largest-tilt cone
    groups = point_settings(path, s, per_patch)
    strat = np.empty(n, object)
    pref = np.zeros((n, 3))
    lim_h, lim_b = np.tile(Z_AXIS, (n, 1)), np.full(n, -2.0)
    pole = 0.0
    for gs, idx in groups:
        strat[idx] = gs.strategy
        pref[idx] = target_axes(gs, path.center[idx], path.normal[idx], feed[idx])
        for h, b in limit_halfspaces(gs, len(idx)):
            lim_h[idx], lim_b[idx] = h, b
        pole = max(pole, gs.pole_tilt)
    limited = bool((lim_b > -2.0).any())
    axes = np.zeros((n, 3))
    info: dict = {}
    cost = None
    forced = []                        # the C travel the cones force, per run (None: unknown)
    for a, b in runs(strat):
        seg = path if (a, b) == (0, n) else _segment(path, a, b)
        cons = [(lim_h[a:b], lim_b[a:b])] if limited else []
        kind = strat[a]
        if kind == "fixed":
            ax, inf = orient_target(seg, checker, pref[a:b], reach, cons)
        elif kind == "closest":
            c2 = smoothing_cost(machine, reach, CLOSEST_LENGTH, s.rotary_weight, path.feed)
            # (later: its forced C travel is dropped below, so it is never computed)
            ax, inf = orient_smooth(seg, checker, pref[a:b], limits, reach, feed[a:b], CLOSEST_LENGTH,
                                    s.max_step * DEG, cost=c2, constraints=cons, pole_tilt=pole * DEG,
                                    tick=tick, later=True)
        else:
            cost = smoothing_cost(machine, reach, s.smoothing_length, s.rotary_weight, path.feed,
                                  travel=TRAVEL_WEIGHT)
            ax, inf = orient_smooth(seg, checker, pref[a:b], limits, reach, feed[a:b], s.smoothing_length,
                                    s.max_step * DEG, cost=cost, constraints=cons, pole_tilt=pole * DEG,
                                    tick=tick, later=later)
        axes[a:b] = ax
        # the forced C travel from the smooth strategy's checks only: "closest" checks too few
        # poses for its lazy figure to be near the grid's
        f = inf.pop("c_travel_forced_deg", None) if kind == "smooth" else None
        forced = None if forced is None or f is None else forced + [f]
        for k, v in inf.items():
            info[k] = info.get(k, 0) + v if isinstance(v, (int, float)) else v
    if forced is None:
        return axes, pref, info, cost, None

    def total() -> float:
        out = 0.0                                     # (summed in the runs' order, from 0)
        for f in forced:
            out = out + (f() if callable(f) else f)
        return out
    return axes, pref, info, cost, total if later else total()


def orient(path, model=None, tool=None, strategy: str | None = None, *, settings: OrientationSettings | None = None,
           per_patch: dict | None = None, checker: CollisionChecker | None = None, stock=None, meshes=(),
           machine=None, preferred=None, fixed_axis=None, lead_max: float | None = None,
           tilt_max: float | None = None, resolution: float | None = None, max_step: float | None = None,
           smoothing_length: float | None = None, tolerance: float = 0.005, clearance: float = 0.0,
           max_tilt: float | None = None, rotary_weight: float | None = None, pole_tilt: float | None = None,
           progress=None, ball: Aside | None = None, later: bool = False):
    """Tool axes for ``path`` (a ToolPath). Angles in degrees at this interface.

    ``settings``: an :class:`OrientationSettings` (strategy, target, limits, smoothing; see
    orientation.settings); the keyword arguments override it (``strategy`` 'smooth',
    'closest' (or 'closest-z') or 'fixed'; ``preferred`` / ``fixed_axis`` the target axis;
    ``max_tilt`` degrees from +Z; the rest as the settings of the same name).
    ``per_patch``: {patch: OrientationSettings} from a processing list's step blocks; the
    points of those patches follow them (runs of one strategy are oriented one after the
    other). ``model``, ``tool``: the surface model and :class:`Tool` (or give a prepared
    ``checker``); ``stock``: (vertices, triangles) of the stock or mold block; ``meshes``:
    more (name, V, T) obstacles; ``machine``: a tsplcam.post Machine whose rotary limits bound
    the axes and whose joint space the smoothing works in.
    ``progress(done, total)``, when given, is called as collision checks accumulate: poses
    checked so far against the most there can be; the last call has done == total.
    ``ball``: the caller's :func:`ball_check` of this path and checker, started already (the
    caller keeps it, e.g. for a second piece in its process); by default orient starts its own.
    ``later``: the report's forced C travel (a figure only: 0.016-0.019 s on the keycap) is
    computed at :meth:`OrientationReport.finish`, which the caller calls when it has time to
    spare (e.g. while a forked process measures the axes); till then it is None.
    Returns ``(path_with_axes, OrientationReport)``; raises CollisionError where no
    admissible collision-free axis exists (naming point, patch, (u, v) and the obstacle), or
    where a fixed target collides.
    """
    import time
    from dataclasses import replace
    t0 = time.perf_counter()
    s = replace(settings) if settings is not None else OrientationSettings()
    given = {"strategy": strategy, "lead_max": lead_max, "tilt_max": tilt_max, "resolution": resolution,
             "max_step": max_step, "smoothing_length": smoothing_length, "max_tilt": max_tilt,
             "rotary_weight": rotary_weight, "pole_tilt": pole_tilt}
    for k, v in given.items():
        if v is not None:
            setattr(s, k, v)
    if s.strategy in ("fixed",) and fixed_axis is not None:
        s.axis, s.target = tuple(np.asarray(fixed_axis, float).reshape(3)), "axis"
    elif preferred is not None:
        s.axis, s.target = tuple(np.asarray(preferred, float).reshape(3)), "axis"
    s.check()
    machine = _narrowed(machine, s.tilt_range)
    if checker is None:
        if tool is None:
            raise InputError("orient needs a tool (or a prepared collision checker)")
        extra = list(meshes)
        if stock is not None:
            extra.insert(0, ("stock", stock[0], stock[1]))
        checker = CollisionChecker(model, tool, meshes=extra, tolerance=tolerance, clearance=clearance)
    tool = checker.tool
    if abs(path.tool_radius - tool.ball_radius) > 1e-9:
        raise InputError(f"the path was made for a ball of radius {path.tool_radius:g} mm, the tool "
                         f"{tool.name} has {tool.ball_radius:g} mm")
    if len(path) == 0:
        return path, OrientationReport(s.strategy, 0)
    reach = Reach.from_machine(machine) if machine is not None else (
        Reach.max_tilt(s.max_tilt) if s.max_tilt is not None and np.allclose(unit(np.asarray(s.limit_axis)), Z_AXIS)
        else None)
    limits = Limits(s.lead_max * DEG, s.tilt_max * DEG, s.resolution * DEG)
    n = len(path)
    worst = [n]

    def tick(m: int) -> None:
        worst[0] = n * m
        if progress is not None:
            progress(min(checker.checks - checks0, worst[0] - 1), worst[0])
    checks0 = checker.checks
    # the ball's gouge check (the ball centres do not move with the axes) beside the axes'
    # search; its error, when it has one, is the one raised (one process meets it first)
    with contextlib.ExitStack() as own:
        if ball is None:
            ball = own.enter_context(ball_check(path, checker))
        try:
            axes, pref, info, cost, forced = _axes(path, s, per_patch, checker, machine, reach, limits, tick,
                                                   later=later)
        except Exception:
            ball.first()
            raise
        ball.result()
    if progress is not None:
        progress(worst[0], worst[0])
    out = path.with_axis(axes)
    steps = angle(axes[1:], axes[:-1]) / DEG if len(axes) > 1 else np.zeros(1)
    settings_used = s.as_dict() | dict(
        rotary_weight=float(cost.w) if cost is not None and machine is not None else 0.0,
        tolerance=checker.tolerance, clearance=checker.clearance,
        preferred=[float(x) for x in unit(np.asarray(s.axis, float))],
        reach=reach.name if reach else "none", tool=tool.name,
        steps_with_own_settings=sorted(int(p) for p in (per_patch or {})))
    rep = OrientationReport(s.strategy, n, checks=checker.checks - checks0,
                            seconds=time.perf_counter() - t0,
                            dp_rounds=info.get("dp_rounds", 0), resolved_points=info.get("resolved_points", 0),
                            relaxation_moves=info.get("relaxation_moves", 0),
                            max_step_deg=float(steps.max()), mean_step_deg=float(steps.mean()),
                            max_deviation_deg=float((angle(axes, pref) / DEG).max()),
                            c_travel_forced_deg=None if forced is None or callable(forced) else round(float(forced), 6),
                            tolerance=checker.tolerance, triangles=checker.triangles, settings=settings_used)
    told = out.info["orientation"] = settings_used | {"report": rep.summary(),
                                                      "c_travel_forced_deg": rep.c_travel_forced_deg}
    if callable(forced):
        def finish() -> None:
            rep.c_travel_forced_deg = round(float(forced()), 6)
            told.update(report=rep.summary(), c_travel_forced_deg=rep.c_travel_forced_deg)
        rep._later = finish
    return out, rep
