"""Tool orientation strategies: fixed, closest to +Z (shang2020), smoothed (after xu2013).

``orient(path, model, tool, strategy=...)`` returns the path with new tool axes and an
:class:`OrientationReport`. Every strategy returns only poses the collision checker passed
(flutes, shank and holder off the workpiece, the ball not gouging any patch) and reachable
by the machine; where no such axis exists it raises :class:`CollisionError` naming the
point, patch, (u, v) and what the tool hits.

* ``fixed``: one axis for the whole path (three-axis machining, the comparison baseline).
* ``closest-z``: shang2020 (end of 3.5): per point the collision-free axis closest to the
  preferred axis (+Z). Candidates are tried in order of their angle to +Z, in batches
  over all points still open, then the winner is pulled toward +Z by bisection along the
  great circle between them (as close as the collision check allows, not just the nearest
  discrete candidate).
* ``smooth``: xu2013 replaces the per-point choice by a smooth sequence picked from a cone of
  candidates per point. Here that choice is global and exact over the discrete candidates:
  a Viterbi dynamic programme minimising, along the path (docs/method.md section 4.4),

      J = sum_i  L * dtheta_i^2 / ds_i  +  sum_i  dev_i^2 * ds_i / L

  (dtheta_i the angle between consecutive axes, ds_i the contact spacing, dev_i the angle
  to the preferred axis, L the ``smoothing_length``: a required tilt is spread over about L
  mm on each side, like a membrane under tension, cf. xu2013 eq. (22)), with a hard
  ``max_step`` per point and only admissible (cone, rotary reach) candidates. A squared
  change is used rather than xu2013's plain sum of angles because the plain sum (total
  variation) is indifferent between one jump and a ramp. Collision checks are lazy: the
  programme runs on candidates not yet known to collide, the chosen poses are checked, and
  every point whose chosen pose collides gets all its candidates checked before the next
  run; the loop ends when the chosen sequence is collision-free, which is then optimal for
  the true collision-free sets. Finally the discrete sequence is relaxed continuously
  (red-black Gauss-Seidel on J, each move kept only when it is admissible and
  collision-free), which removes the candidate grid's quantisation. With a machine and a
  ``rotary_weight`` w > 0 each step also costs ``L * w (v_tilt / v_C)^2 dC^2 / ds``, dC the
  turn of the rotary axis C (the azimuth about +Z, modulo 180 deg where the tilt may change
  sign instead, free inside the post's 0.5 deg singular cone): where the tilt follows walls
  around a cavity this trades a little axis angle for much less C travel.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import CollisionError, InputError
from .candidates import (DEG, Z_AXIS, Limits, Reach, admissible, angle, candidate_axes,
                         feed_directions, unit)
from .collision import CollisionChecker
from ..toolpath.path import Move

STRATEGIES = ("fixed", "closest-z", "smooth")


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
    tolerance: float = 0.0
    triangles: int = 0
    settings: dict = field(default_factory=dict)

    def summary(self) -> str:
        return (f"orientation {self.strategy}: {self.points} points, {self.checks} collision checks "
                f"in {self.seconds:.2f} s, largest step {self.max_step_deg:.2f} deg, mean "
                f"{self.mean_step_deg:.3f} deg, largest deviation from preferred "
                f"{self.max_deviation_deg:.1f} deg (mesh {self.triangles} triangles within "
                f"{self.tolerance:g} mm)")


def _where(path, i: int) -> str:
    text = f"point {i}"
    if path.patch[i] >= 0:
        u, v = path.uv[i]
        text += f" (patch {int(path.patch[i])}, u={u:.4f}, v={v:.4f})"
    return text


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
    return CollisionError(f"{_where(path, i)}: {why}{what}")


def _check_ball(path, checker: CollisionChecker) -> None:
    bad = checker.ball_gouges(path.center)
    if bad.any():
        i = int(np.argmax(bad))
        hit = checker.ball_hit(path.center[i])
        raise CollisionError(f"{_where(path, i)}: the ball cuts more than {checker.gouge_tolerance:g} mm "
                             f"into the part whatever the axis: {hit} ({int(bad.sum())} such points)")


# --- strategies ----------------------------------------------------------------------------

def orient_fixed(path, checker, axis=Z_AXIS, reach=None):
    a = unit(np.asarray(axis, float).reshape(3))
    A = np.tile(a, (len(path), 1))
    side = np.einsum("ij,j->i", path.normal, a) <= 1e-6
    if side.any():
        i = int(np.argmax(side))
        raise CollisionError(f"{_where(path, i)}: the fixed axis ({a[0]:.4f}, {a[1]:.4f}, {a[2]:.4f}) "
                             f"points into the surface (the ball cannot touch there with it)")
    if reach is not None and not reach.ok(a[None])[0]:
        raise CollisionError(f"the fixed axis is outside the reach of {reach.name}")
    bad = checker.collides(path.center, A)
    if bad.any():
        i = int(np.argmax(bad))
        raise _no_axis_error(path, checker, i, A[i:i + 1],
                             f"the fixed axis collides ({int(bad.sum())} of {len(path)} points)")
    return A, {}


def _toward(a, b, t):
    """Great-circle points from a toward b at fractions t (all (n,3)/(n,))."""
    ang = angle(a, b)
    s = np.sin(ang)
    small = s < 1e-9
    w0 = np.where(small, 1 - t, np.sin((1 - t) * ang) / np.where(small, 1, s))
    w1 = np.where(small, t, np.sin(t * ang) / np.where(small, 1, s))
    return unit(w0[:, None] * a + w1[:, None] * b)


def orient_closest(path, checker, preferred, limits: Limits, reach, feed, bisect: int = 6, tick=None):
    """shang2020: per point the admissible collision-free axis closest to ``preferred``."""
    n = len(path)
    C = path.center
    A, ok = candidate_axes(path.normal, feed, preferred, limits, reach)
    tick = tick or (lambda m: None)
    pref = unit(np.broadcast_to(preferred, (n, 3)).copy())
    dev = angle(A, pref[:, None, :])
    order = np.argsort(np.where(ok, dev, np.inf), axis=1, kind="stable")
    chosen = np.full(n, -1)
    open_ = ok.any(axis=1)
    if not open_.all():
        i = int(np.argmin(open_))
        raise CollisionError(f"{_where(path, i)}: no candidate axis within the lead/tilt limits and the "
                             f"machine's reach ({reach.name if reach else 'no machine'})")
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
        free = np.zeros(len(idx), bool)
        if good.any():
            free[good] = ~checker.collides(C[idx[good]], cand[good])
        lo[idx[free]] = t[free]
        hi[idx[~free]] = t[~free]
    del okp, first
    return _toward(axes, pref, lo), {"bisection_steps": bisect}


def _spacing(path) -> np.ndarray:
    ds = np.linalg.norm(np.diff(path.contact, axis=0), axis=1)
    return np.maximum(ds, 1e-3)


SINGULAR_CONE = 0.5 * DEG      # the post holds the rotary axis within this of +Z (docs/post.md 4)


def _azimuth(A: np.ndarray, reach) -> np.ndarray:
    """Azimuth of axes about +Z (the rotary axis C of every supported machine) as a complex
    number: angle = azimuth, modulus 2 where both inverse solutions (tilt, C) and (-tilt,
    C + 180 deg) are within the machine's tilt range, else 1; NaN within the singular cone,
    where the post does not follow the azimuth."""
    th = np.arctan2(np.hypot(A[..., 0], A[..., 1]), A[..., 2])
    both = len(reach.intervals) == 2
    for a, b in reach.intervals:
        both = both & (th >= a - 1e-9) & (th <= b + 1e-9)
    z = np.exp(1j * np.arctan2(A[..., 1], A[..., 0])) * np.where(both, 2.0, 1.0)
    return np.where(th < SINGULAR_CONE, np.nan, z)


def _azimuth_step(za: np.ndarray, zb: np.ndarray) -> np.ndarray:
    """Rotary-axis motion (rad) between two axes given by :func:`_azimuth`: the azimuth change,
    modulo 180 deg where both axes can take either inverse solution (the post may flip the
    tilt's sign instead of turning C half a turn), 0 next to the pole."""
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.angle(zb / za)
    flip = (np.abs(za) > 1.5) & (np.abs(zb) > 1.5)
    d = np.where(flip, np.mod(d + 0.5 * np.pi, np.pi) - 0.5 * np.pi, d)
    return np.where(np.isnan(d), 0.0, d)


def _viterbi(A, allowed, node_cost, ds, L, max_step, free_step, phi=None, wrot=0.0):
    """Best state per point: min sum node_cost + L * (angle^2 + wrot * dC^2) / ds with steps
    <= max_step (except into points where ``free_step``); dC the rotary-axis motion
    (:func:`_azimuth_step` of the azimuths ``phi``). Returns (states, None) or (None, i)
    where the chain breaks at step i -> i+1."""
    n, m = allowed.shape
    big = np.inf
    acc = np.where(allowed[0], node_cost[0], big)
    back = np.zeros((n, m), np.int32)
    cmax = np.cos(max_step)
    for i in range(1, n):
        dots = np.clip(A[i - 1] @ A[i].T, -1.0, 1.0)                 # (m_prev, m)
        ang = np.arccos(dots)
        trans = ang * ang
        if wrot > 0.0:
            dc = _azimuth_step(phi[i - 1][:, None], phi[i][None, :])
            trans += wrot * dc * dc
        trans *= L / ds[i - 1]
        if not free_step[i]:
            trans[dots < cmax - 1e-12] = big
        tot = acc[:, None] + trans
        b = np.argmin(tot, axis=0)
        best = tot[b, np.arange(m)]
        acc = np.where(allowed[i], best + node_cost[i], big)
        back[i] = b
        if not np.isfinite(acc).any():
            return None, i - 1
    states = np.zeros(n, np.int64)
    states[-1] = int(np.argmin(acc))
    for i in range(n - 1, 0, -1):
        states[i - 1] = back[i, states[i]]
    return states, None


def _relax(path, checker, axes, pref, feed, limits, reach, L, max_step, rounds=40, wrot=0.0):
    """Red-black Gauss-Seidel on J: move each axis toward the weighted mean of its
    neighbours and the preferred axis, keeping only admissible, collision-free moves that
    lower its share of J and respect max_step. Returns (axes, moves)."""
    free_step = path.move != Move.CUT
    n = len(axes)
    if n < 3:
        return axes, 0
    ds = _spacing(path)
    wl = np.concatenate([[0.0], L / ds])                      # weight of the previous axis
    wr = np.concatenate([L / ds, [0.0]])                      # of the next
    half = np.concatenate([[0.0], ds]) * 0.5 + np.concatenate([ds, [0.0]]) * 0.5
    wp = half / L                                             # of the preferred axis
    C = path.center
    moves = 0

    def local_cost(x, idx):
        c = wp[idx] * angle(x, pref[idx]) ** 2
        prev = np.clip(idx - 1, 0, n - 1)
        nxt = np.clip(idx + 1, 0, n - 1)
        c = c + wl[idx] * angle(x, axes[prev]) ** 2 + wr[idx] * angle(x, axes[nxt]) ** 2
        if wrot > 0.0:
            px = _azimuth(x, reach)
            c = c + wrot * (wl[idx] * _azimuth_step(_azimuth(axes[prev], reach), px) ** 2
                            + wr[idx] * _azimuth_step(px, _azimuth(axes[nxt], reach)) ** 2)
        return c

    for r in range(rounds):
        changed = 0
        for parity in (0, 1):
            idx = np.arange(parity, n, 2)
            prev = np.clip(idx - 1, 0, n - 1)
            nxt = np.clip(idx + 1, 0, n - 1)
            target = unit(wl[idx, None] * axes[prev] + wr[idx, None] * axes[nxt] + wp[idx, None] * pref[idx])
            step = angle(axes[idx], target)
            live = step > 1e-5
            idx, target = idx[live], target[live]
            if len(idx) == 0:
                continue
            old = local_cost(axes[idx], idx)
            for frac in (1.0, 0.5):
                cand = _toward(axes[idx], target, np.full(len(idx), frac))
                better = local_cost(cand, idx) < old - 1e-15
                pv, nx = np.clip(idx - 1, 0, n - 1), np.clip(idx + 1, 0, n - 1)
                better &= (angle(cand, axes[pv]) <= max_step) | free_step[idx]
                better &= (angle(cand, axes[nx]) <= max_step) | free_step[nx]
                better &= admissible(cand[:, None], path.normal[idx], feed[idx], limits, reach)[:, 0]
                if better.any():
                    k = np.nonzero(better)[0]
                    free = ~checker.collides(C[idx[k]], cand[k])
                    k = k[free]
                    axes[idx[k]] = cand[k]
                    changed += len(k)
                    keep = np.ones(len(idx), bool)
                    keep[k] = False
                    idx, target, old = idx[keep], target[keep], old[keep]
                if len(idx) == 0:
                    break
        moves += changed
        if changed == 0:
            break
    return axes, moves


def orient_smooth(path, checker, preferred, limits: Limits, reach, feed, smoothing_length: float,
                  max_step: float, window: int = 2, relax_rounds: int = 40, max_rounds: int = 200,
                  wrot: float = 0.0, tick=None):
    n = len(path)
    C = path.center
    A, ok = candidate_axes(path.normal, feed, preferred, limits, reach)
    m = A.shape[1]
    tick = tick or (lambda m: None)
    pref = unit(np.broadcast_to(preferred, (n, 3)).copy())
    none = ~ok.any(axis=1)
    if none.any():
        i = int(np.argmax(none))
        raise CollisionError(f"{_where(path, i)}: no candidate axis within the lead/tilt limits and the "
                             f"machine's reach ({reach.name if reach else 'no machine'})")
    ds = _spacing(path)
    free_step = path.move != Move.CUT          # links and retracts: no hard step limit
    half = np.concatenate([[ds[0]], ds]) * 0.5 + np.concatenate([ds, [ds[-1]]]) * 0.5
    dev = angle(A, pref[:, None, :])
    node_cost = dev ** 2 * (half / smoothing_length)[:, None]
    if reach is None:
        wrot = 0.0                      # no machine: no rotary axis to weigh
    phi = _azimuth(A, reach) if wrot > 0.0 else None
    status = np.where(ok, -1, 2).astype(np.int8)         # -1 unknown, 0 free, 1 collides, 2 excluded
    resolved = np.zeros(n, bool)
    rounds = 0
    while True:
        rounds += 1
        tick(m)
        states, broke = _viterbi(A, status <= 0, node_cost, ds, smoothing_length, max_step, free_step,
                                 phi, wrot)
        if states is None:
            i = broke
            # a break is final only when both points' cones are fully known
            todo = [j for j in (i, i + 1) if not resolved[j]]
            if todo:
                for j in todo:
                    _resolve(checker, C, A, status, resolved, [j], tick)
                continue
            if not (status[i] == 0).any() or not (status[i + 1] == 0).any():
                j = i if not (status[i] == 0).any() else i + 1
                raise _no_axis_error(path, checker, j, A[j, np.argsort(np.where(ok[j], dev[j], np.inf))[:3]],
                                     f"no collision-free tool axis in the cone of {int(ok[j].sum())} "
                                     "candidates")
            raise CollisionError(f"{_where(path, i)} -> {_where(path, i + 1)}: no pair of collision-free "
                                 f"axes within the maximum step of {max_step / DEG:.1f} deg (raise max_step "
                                 "or the cone limits, or split the path there)")
        pick = states
        unknown = np.nonzero(status[np.arange(n), pick] == -1)[0]
        if len(unknown):
            hit = checker.collides(C[unknown], A[unknown, pick[unknown]])
            status[unknown, pick[unknown]] = np.where(hit, 1, 0)
            bad = unknown[hit]
        else:
            bad = np.zeros(0, int)
        if len(bad) == 0:
            break
        near = np.unique(np.clip(bad[:, None] + np.arange(-window, window + 1)[None, :], 0, n - 1))
        _resolve(checker, C, A, status, resolved, near[~resolved[near]], tick)
        if rounds >= max_rounds:                                     # pragma: no cover
            raise CollisionError(f"orientation DP did not settle in {max_rounds} rounds")
    axes = A[np.arange(n), pick].copy()
    axes, moves = _relax(path, checker, axes, pref, feed, limits, reach, smoothing_length, max_step,
                         relax_rounds, wrot)
    return axes, {"dp_rounds": rounds, "resolved_points": int(resolved.sum()), "relaxation_moves": moves,
                  "candidates": m}


def _rotary_weight(machine, rotary_weight: float | None) -> float:
    """Weight of the squared rotary-axis motion in J: the user's factor (default 0, the axis
    angle alone) times the machine's (tilt speed / rotary speed)^2, so that a factor 1 adds
    rotary joint motion in units of the tilt axis's time. Without a machine there is no
    rotary axis to weigh: a weight > 0 is refused."""
    if rotary_weight is None:
        rotary_weight = 0.0
    if rotary_weight < 0 or not np.isfinite(rotary_weight):
        raise InputError(f"rotary weight must be a number >= 0, not {rotary_weight}")
    if rotary_weight == 0.0:
        return 0.0
    if machine is None:
        raise InputError("a rotary weight needs a machine (--machine): it weighs that machine's rotary axis")
    vt, vr = machine.tilt.max_velocity, machine.rotary.max_velocity
    return float(rotary_weight * (vt / vr) ** 2) if vt and vr else float(rotary_weight)


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

def orient(path, model=None, tool=None, strategy: str = "smooth", *, checker: CollisionChecker | None = None,
           stock=None, meshes=(), machine=None, preferred=Z_AXIS, fixed_axis=Z_AXIS,
           lead_max: float = 60.0, tilt_max: float = 60.0, resolution: float = 10.0,
           max_step: float = 10.0, smoothing_length: float = 5.0, tolerance: float = 0.005,
           clearance: float = 0.0, max_tilt: float | None = None, rotary_weight: float | None = None,
           progress=None):
    """Tool axes for ``path`` (a ToolPath). Angles in degrees at this interface.

    ``model``, ``tool``: the surface model and :class:`Tool` (or give a prepared
    ``checker``); ``stock``: (vertices, triangles) of the stock or mold block; ``meshes``:
    more (name, V, T) obstacles; ``machine``: a tsplcam.post Machine whose rotary limits
    bound the axes (or ``max_tilt`` degrees from +Z); ``strategy``: 'fixed', 'closest-z' or
    'smooth'; cone limits ``lead_max``/``tilt_max`` around the normal, candidate
    ``resolution``; smooth only: ``max_step`` per point, ``smoothing_length`` (mm) and
    ``rotary_weight``: how much the rotary (C) axis motion counts next to the change of the
    axis direction, scaled by the machine's tilt/rotary speed ratio squared (default 0: the
    tool axis angle alone; needs a machine). It pays where the tilt follows walls around a
    cavity (the mold: C travel and machining time about a third lower on the test path);
    on the impeller it does not (C travel up to 20 % higher, time equal).
    ``progress(done, total)``, when given, is called as collision checks accumulate: poses
    checked so far against the most there can be (every candidate of every point); the last
    call has done == total.
    Returns ``(path_with_axes, OrientationReport)``; raises CollisionError where no
    admissible collision-free axis exists (naming point, patch, (u, v) and the obstacle).
    """
    import time
    t0 = time.perf_counter()
    if strategy not in STRATEGIES:
        raise InputError(f"unknown orientation strategy {strategy!r} (one of {', '.join(STRATEGIES)})")
    for name, value in (("smoothing length", smoothing_length), ("maximum step", max_step),
                        ("candidate resolution", resolution)):
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a number > 0, not {value:g}")
    wrot = _rotary_weight(machine, rotary_weight) if strategy == "smooth" else 0.0
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
        return path, OrientationReport(strategy, 0)
    reach = Reach.from_machine(machine) if machine is not None else (
        Reach.max_tilt(max_tilt) if max_tilt is not None else None)
    limits = Limits(lead_max * DEG, tilt_max * DEG, resolution * DEG)
    checks0 = checker.checks
    _check_ball(path, checker)
    feed = feed_directions(path.contact, path.normal)
    pref = unit(np.asarray(preferred, float).reshape(3))
    worst = [len(path)]

    def tick(m: int) -> None:
        worst[0] = len(path) * m
        if progress is not None:
            progress(min(checker.checks - checks0, worst[0] - 1), worst[0])
    if strategy == "fixed":
        axes, info = orient_fixed(path, checker, fixed_axis, reach)
    elif strategy == "closest-z":
        axes, info = orient_closest(path, checker, pref, limits, reach, feed, tick=tick)
    else:
        axes, info = orient_smooth(path, checker, pref, limits, reach, feed, smoothing_length,
                                   max_step * DEG, wrot=wrot, tick=tick)
    if progress is not None:
        progress(worst[0], worst[0])
    out = path.with_axis(axes)
    steps = angle(axes[1:], axes[:-1]) / DEG if len(axes) > 1 else np.zeros(1)
    settings = dict(strategy=strategy, lead_max=lead_max, tilt_max=tilt_max, resolution=resolution,
                    max_step=max_step, smoothing_length=smoothing_length,
                    rotary_weight=wrot,
                    tolerance=checker.tolerance,
                    clearance=checker.clearance, preferred=[float(x) for x in pref],
                    reach=reach.name if reach else "none", tool=tool.name)
    rep = OrientationReport(strategy, len(path), checks=checker.checks - checks0,
                            seconds=time.perf_counter() - t0,
                            dp_rounds=info.get("dp_rounds", 0), resolved_points=info.get("resolved_points", 0),
                            relaxation_moves=info.get("relaxation_moves", 0),
                            max_step_deg=float(steps.max()), mean_step_deg=float(steps.mean()),
                            max_deviation_deg=float((angle(axes, pref[None]) / DEG).max()),
                            tolerance=checker.tolerance, triangles=checker.triangles, settings=settings)
    out.info["orientation"] = settings | {"report": rep.summary()}
    return out, rep
