"""Metrics of an oriented tool path (docs/post.md section 5.2): collisions, clearance, smoothness,
rotary travel and machining time.

* collisions: poses whose flutes, shank or holder touch the workpiece, asked of fcl with
  the tool as primitives (``CollisionChecker.collides_exact``: Cylinder / Convex), and
  ball gouges (the shrunk-ball check); both must be 0.
* smallest clearance: fcl distance between the tool parts and the tessellated workpiece
  (plus the margin the checker grew the tool by). Computed exactly only on the poses that
  come closest: the tool is grown by 0.05, 0.1, 0.2 ... mm until some pose touches, the
  growth is bisected until a few dozen touch, and fcl.distance runs on those.
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

from dataclasses import dataclass, field

import numpy as np

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


def min_clearance(checker, centers, axes, levels=(0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0),
                  exact: int = 40):
    """(smallest clearance in mm, index of the pose) over the poses, see the module.

    The tool is grown level by level until some pose touches; between that level and the one
    before, the growth is bisected among the touching poses until at most ``exact`` are left
    (the closest pose touches at every growth above its clearance), and fcl.distance runs on
    those only: each distance query costs tens of ms against a fine workpiece mesh."""
    C = np.asarray(centers, float)
    A = np.asarray(axes, float)
    pick, lo, hi = None, 0.0, None
    for g in levels:
        hit = checker.collides(C, A, grow=g)
        if hit.any():
            pick, hi = np.nonzero(hit)[0], g
            break
        lo = g
    if pick is None:
        pick = np.arange(len(C))[:: max(1, len(C) // 200)]
    else:
        for _ in range(20):
            if len(pick) <= exact or hi - lo < 1e-4:
                break
            mid = 0.5 * (lo + hi)
            hit = checker.collides(C[pick], A[pick], grow=mid)
            if hit.any():
                pick, hi = pick[hit], mid
            else:
                lo = mid
    if len(pick) > 400:
        pick = pick[np.linspace(0, len(pick) - 1, 400).astype(int)]
    d = checker.clearance_of(C[pick], A[pick]) + checker.margin
    k = int(np.argmin(d))
    return float(d[k]), int(pick[k])


def _simple_ac(axis):
    """ISO A/C angles (deg) (docs/post.md section 1), C unwound, held through the pole."""
    K = np.asarray(axis, float)
    A = np.degrees(np.arctan2(np.hypot(K[:, 0], K[:, 1]), K[:, 2]))
    C = np.degrees(np.arctan2(K[:, 0], -K[:, 1]))
    pole = A < 1e-6
    if pole.all():
        C = np.zeros(len(K))
    else:
        good = np.nonzero(~pole)[0]
        C = C[good[np.clip(np.searchsorted(good, np.arange(len(K))), 0, len(good) - 1)]]
    dC = np.diff(C)
    dC = (dC + 180.0) % 360.0 - 180.0
    C = C[0] + np.concatenate([[0.0], np.cumsum(dC)])
    return A, C


def orientation_metrics(path: ToolPath, checker=None, machine=None, v_rotary=(5400.0, 9000.0),
                        clearance: bool = True) -> OrientationMetrics:
    """Metrics of ``path`` (its axes). ``checker``: the CollisionChecker the path was oriented
    with (None skips collisions and clearance); ``machine``: a tsplcam.post Machine (or name)
    for joints and time; ``v_rotary``: (A, C) deg/min of the simple model."""
    n = len(path)
    K = path.axis
    collisions = gouges = 0
    clr, clr_at = float("nan"), -1
    if checker is not None:
        collisions = int(checker.collides_exact(path.center, K).sum())
        gouges = int(checker.ball_gouges(path.center).sum())
        if clearance:
            clr, clr_at = min_clearance(checker, path.center, K)
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
        sol, tip = solve_joints(machine, path.tip, K, radius=path.tool_radius, patch=path.patch, uv=path.uv)
        J = sol.joints
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
    return OrientationMetrics(
        points=n, collisions=collisions, gouges=gouges, min_clearance=clr, min_clearance_point=clr_at,
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
    dC = np.abs(np.diff(J[:, 4]))
    feed_rows = ~mo.rapid[1:]
    out = {"machine": posted.machine.name, "dialect": posted.dialect,
           "time_s": float(posted.time.total_s), "length_feed_time_s": float(posted.time.feed_only_s),
           "time_ratio": float(posted.time.total_s / posted.time.feed_only_s) if posted.time.feed_only_s else 0.0,
           "tilt_travel_deg": float(info["tilt_travel_deg"]), "c_travel_deg": float(info["rotary_travel_deg"]),
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
