"""Forward and inverse kinematics of the machine kinds, vectorised over points.

Joints are rows ``(X, Y, Z, tilt, rotary)`` in machine units (mm, degrees). X, Y, Z are the
position of the tool tip when every rotary axis is at zero, i.e. the machine position with
the tool length applied along Z as G43 / TOOL CALL does; the travel limits of the machine
file refer to the gauge point (``Z + tool_length``).

Chain (rigid rotations about the axis lines, ``R = rot(about, sign * (value - zero))``):

* part point ``p`` (program coordinates) sits at ``p + part_origin`` on the table at home;
  the table axes move it to ``M(p) = T_outer(T_inner(p + part_origin))``;
* the head axes move the tip from ``J`` to ``J + h(q)``, ``h = H_outer(H_inner(0))`` about
  lines through ``pivot + (0, 0, tool_length)`` relative to ``J``;
* the tip touches the part point: ``J = M(p) - h(q)``; the tool axis in the part frame is
  ``K = R_table^T R_head z``.

For every kind ``K = Rz(phi) R_tilt(theta) z`` with ``theta = e_t s_t (T - zero_t)``,
``phi = e_c s_c (C - zero_c)``, ``e = -1`` for a table axis, ``+1`` for a head axis. With ISO
signs this is docs/post.md section 1 (A/C: ``K = (sin C sin A, -cos C sin A, cos A)``); with LinuxCNC's
unconventional directions it is the table of docs/post.md section 2.3. Inverse: ``theta =
atan2(hypot(Kx, Ky), Kz)``, ``phi = atan2(Kx, -Ky)`` (tilt about X) or ``atan2(Ky, Kx)``
(about Y); the second solution is ``(-theta, phi + 180 deg)``.

:func:`solve_joints` picks one solution per point with
:func:`tsplcam.orientation.rotary.pose_sequence` (the same choice the orientation stage
smooths with): dynamic programming over the branches (and, for a C axis with a short range,
its 360-degree representatives) minimising the rotary motion time, flips and rewinds where
the tool axis is nearest the pole, unwinding an endless C (no 360-degree swings), holding and
interpolating the free angle inside a small cone around the singular pose (tool axis along
C) as docs/post.md section 4 describes; it refuses (never clips) a pose outside the limits. The
closed form lives in :class:`tsplcam.orientation.rotary.Rotary`.
:func:`linearise` inserts points where joint-space interpolation would take the tip off the
programmed line (docs/post.md section 4).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import KinematicsError
from ..orientation.rotary import Rotary, pose_sequence
from ..toolpath.path import Move
from .machine import Machine, RotaryAxis

DEG = np.pi / 180.0
Z_AXIS = np.array([0.0, 0.0, 1.0])


# --- rotations ----------------------------------------------------------------------------

def _rot(index: int, angle) -> np.ndarray:
    """Right-handed rotation matrices (n, 3, 3) about basis axis ``index`` by ``angle`` (rad)."""
    a = np.asarray(angle, float).reshape(-1)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros((len(a), 3, 3))
    i, j, k = index, (index + 1) % 3, (index + 2) % 3
    R[:, i, i] = 1.0
    R[:, j, j] = c
    R[:, k, k] = c
    R[:, j, k] = -s
    R[:, k, j] = s
    return R


def axis_rotation(ax: RotaryAxis, value) -> np.ndarray:
    """Rotation of the element ``ax`` carries when the axis reads ``value`` (degrees)."""
    return _rot(ax.index, ax.sign * (np.asarray(value, float) - ax.zero) * DEG)


def _apply(R, c, x):
    """Rotate points x (n,3) by R (n,3,3) about the line through c (3,) or (n,3)."""
    return c + np.einsum("nij,nj->ni", R, x - c)


def _apply_inv(R, c, x):
    return c + np.einsum("nji,nj->ni", R, x - c)


def _joint_values(machine: Machine, joints: np.ndarray):
    j = np.asarray(joints, float).reshape(-1, 5)
    return j, {id(machine.tilt): j[:, 3], id(machine.rotary): j[:, 4]}


def _defaults(machine, tool_length, part_origin):
    L = machine.tool_length if tool_length is None else float(tool_length)
    o = np.asarray(machine.part_origin if part_origin is None else part_origin, float).reshape(3)
    return L, o


def head_offset(machine: Machine, tilt, rotary, tool_length: float):
    """Tip minus J and the machine-frame tool axis, for rotary values (deg): (n,3), (n,3)."""
    values = {id(machine.tilt): np.asarray(tilt, float).reshape(-1),
              id(machine.rotary): np.asarray(rotary, float).reshape(-1)}
    n = len(values[id(machine.tilt)])
    x = np.zeros((n, 3))
    k = np.tile(Z_AXIS, (n, 1))
    for ax in reversed(machine.head_axes):        # inner axis first
        R = axis_rotation(ax, values[id(ax)])
        g = np.asarray(ax.pivot, float) + np.array([0.0, 0.0, tool_length])
        x = _apply(R, g, x)
        k = np.einsum("nij,nj->ni", R, k)
    return x, k


def forward(machine: Machine, joints, tool_length=None, part_origin=None):
    """Tool tip (n,3, program coordinates) and unit tool axis (n,3) for joint rows (n,5)."""
    L, origin = _defaults(machine, tool_length, part_origin)
    j, values = _joint_values(machine, joints)
    h, k = head_offset(machine, j[:, 3], j[:, 4], L)
    x = j[:, :3] + h
    for ax in machine.table_axes:                 # undo the outer axis first
        R = axis_rotation(ax, values[id(ax)])
        x = _apply_inv(R, np.asarray(ax.pivot, float), x)
        k = np.einsum("nji,nj->ni", R, k)
    return x - origin, k


def linear_joints(machine: Machine, tip, tilt, rotary, tool_length=None, part_origin=None):
    """X, Y, Z (n,3) that put the tip on ``tip`` (program coordinates) at the given rotaries."""
    L, origin = _defaults(machine, tool_length, part_origin)
    tilt = np.asarray(tilt, float).reshape(-1)
    rotary = np.asarray(rotary, float).reshape(-1)
    values = {id(machine.tilt): tilt, id(machine.rotary): rotary}
    x = np.asarray(tip, float).reshape(-1, 3) + origin
    for ax in reversed(machine.table_axes):       # inner axis first
        x = _apply(axis_rotation(ax, values[id(ax)]), np.asarray(ax.pivot, float), x)
    h, _ = head_offset(machine, tilt, rotary, L)
    return x - h


def rotary_of(machine: Machine) -> Rotary:
    """The machine's rotary axes in part-frame angles (orientation.rotary), cached on the machine."""
    r = getattr(machine, "_rotary", None)
    if r is None:
        r = Rotary.from_machine(machine)
        try:
            object.__setattr__(machine, "_rotary", r)
        except (AttributeError, TypeError):       # pragma: no cover
            pass
    return r


def orientation(machine: Machine, tilt, rotary) -> np.ndarray:
    """Unit tool axis (n,3) in the part frame for rotary values (deg), closed form."""
    r = rotary_of(machine)
    th, ph = r.from_machine_values(tilt, rotary)
    return r.axis(th, ph).reshape(-1, 3)


def _wrap180(a):
    """Angles (deg) into (-180, 180]."""
    return 180.0 - np.mod(180.0 - np.asarray(a, float), 360.0)


def inverse_orientation(machine: Machine, axis):
    """Both rotary solutions for unit tool axes (n,3).

    Returns ``tilt (n,2)``, ``rotary (n,2)`` in degrees (column 0: the branch with
    ``theta >= 0``, column 1 the other; rotary values in ``zero + (-180, 180]``) and
    ``theta`` (n,), the angle between the tool axis and the C axis (rad).
    """
    r = rotary_of(machine)
    K = np.asarray(axis, float).reshape(-1, 3)
    theta, phi = r.angles(K)
    tilt, rot = r.to_machine(np.stack([theta, -theta], axis=1), np.stack([phi, phi + np.pi], axis=1))
    rot = machine.rotary.zero + _wrap180(rot - machine.rotary.zero)
    return tilt, rot, theta


def best_tilt(machine: Machine, axis, rotary) -> np.ndarray:
    """Tilt (deg) that brings the tool closest to ``axis`` when the rotary axis is held."""
    r = rotary_of(machine)
    _, ph = r.from_machine_values(0.0, rotary)
    return r.to_machine(r.best_theta(np.asarray(axis, float).reshape(-1, 3), ph), 0.0)[0]


def angle_between(a, b) -> np.ndarray:
    """Angle (rad) between unit vectors, accurate for tiny angles."""
    a = np.asarray(a, float).reshape(-1, 3)
    b = np.asarray(b, float).reshape(-1, 3)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ni,ni->n", a, b))


# --- choosing one solution per point --------------------------------------------------------

def describe_point(i: int, patch=None, uv=None) -> str:
    """'point i (patch p, u=.., v=..)' for messages."""
    text = f"point {i}"
    if patch is not None and 0 <= i < len(patch) and patch[i] >= 0:
        u, v = uv[i]
        text += f" (patch {int(patch[i])}, u={u:.4f}, v={v:.4f})"
    return text


def _limit_text(machine: Machine, tilt, joints_xyz, L) -> str | None:
    """First limit a pose violates, as text, or None."""
    t = machine.tilt
    if t.min is not None and tilt < t.min - 1e-9:
        return f"{t.name}={tilt:.4f} below min {t.min:g}"
    if t.max is not None and tilt > t.max + 1e-9:
        return f"{t.name}={tilt:.4f} above max {t.max:g}"
    for k, n in enumerate(("X", "Y", "Z")):
        a = machine.linear[n]
        v = joints_xyz[k] + (L if n == "Z" else 0.0)
        if v < a.min - 1e-9:
            return f"{n}={v:.4f} below min {a.min:g}" + (" (gauge point)" if n == "Z" else "")
        if v > a.max + 1e-9:
            return f"{n}={v:.4f} above max {a.max:g}" + (" (gauge point)" if n == "Z" else "")
    return None


def _travel_ok(machine: Machine, xyz: np.ndarray, L: float) -> np.ndarray:
    ok = np.ones(xyz.shape[:-1], bool)
    for k, n in enumerate(("X", "Y", "Z")):
        a = machine.linear[n]
        v = xyz[..., k] + (L if n == "Z" else 0.0)
        ok &= (v >= a.min - 1e-9) & (v <= a.max + 1e-9)
    return ok


@dataclass
class JointSolution:
    """One machine pose per point and what it took to get there."""
    joints: np.ndarray          # (n,5) X, Y, Z (mm), tilt, rotary (deg)
    axis: np.ndarray            # (n,3) tool axis the pose gives (part frame)
    branch: np.ndarray          # (n,) 0 = theta >= 0 side, 1 = the other side
    singular: np.ndarray        # (n,) inside the singular cone, free angle interpolated
    deviation: np.ndarray       # (n,) rad between requested and reached tool axis
    flips: int = 0              # branch changes between consecutive non-singular points
    info: dict = field(default_factory=dict)
    tip: np.ndarray | None = None   # (n,3) the tips the poses hold (solve_joints' second value)


SINGULAR_CONE = 0.5           # deg: solve_joints' default singular cone
SWING_LIMIT = 5.0             # deg: solve_joints' default swing limit


def solve_joints(machine: Machine, tip, axis, *, tool_length=None, part_origin=None,
                 singular_cone: float = SINGULAR_CONE, radius: float = 0.0, patch=None, uv=None,
                 index_offset: int = 0, move=None, swing_limit: float = SWING_LIMIT) -> tuple:
    """Machine poses for tool tips and axes (program coordinates), see the module docstring.

    ``singular_cone`` (deg): inside it the rotary (C) angle is interpolated between the poses
    around it and the tilt re-fitted, so the tool axis moves by at most the cone angle; the
    ball centre ``tip + radius * axis`` is kept, so the returned tips move with the axis
    (exact for ``radius = 0`` and exactly at the pole). ``move`` (n,): the path's move kinds
    (branch flips and rewinds go to non-cutting blocks where they must happen);
    ``swing_limit`` (deg): the tool-axis sweep a flip or rewind may cause inside a block
    before it counts as sweeping (orientation.rotary.pose_sequence). Returns
    ``(JointSolution, tip)``. Raises :class:`KinematicsError` naming the first point no
    pose within limits reaches.
    """
    L, origin = _defaults(machine, tool_length, part_origin)
    tip = np.asarray(tip, float).reshape(-1, 3)
    K = np.asarray(axis, float).reshape(-1, 3)
    n = len(tip)
    where = lambda i: describe_point(i + index_offset, patch, uv)  # noqa: E731
    bad = ~(np.isfinite(tip).all(axis=1) & np.isfinite(K).all(axis=1))
    if bad.any():
        raise KinematicsError(f"{where(int(np.argmax(bad)))}: tool tip or axis is not finite")
    norm = np.linalg.norm(K, axis=1)
    if (norm < 1e-9).any():
        raise KinematicsError(f"{where(int(np.argmax(norm < 1e-9)))}: tool axis has zero length")
    K = K / norm[:, None]
    center = tip + radius * K
    rot = rotary_of(machine)
    rax = machine.rotary

    tilt2, rot2, theta = inverse_orientation(machine, K)
    cone = max(float(singular_cone), 0.0) * DEG
    singular = theta <= max(cone, 1e-12)
    xyz2 = np.stack([linear_joints(machine, tip, tilt2[:, b], rot2[:, b], L, origin)
                     for b in range(2)], axis=1)                     # (n,2,3)
    travel2 = _travel_ok(machine, xyz2, L)
    feas2 = machine.tilt.within(tilt2) & travel2
    if not rax.continuous and rax.min is not None:
        reach_c = np.zeros((n, 2), bool)
        for k in range(-2, 3):
            reach_c |= rax.within(rot2 + 360.0 * k)
        feas2 &= reach_c
    # A point no pose reaches is an error (singular points are re-fitted below: they need
    # only a tilt near zero, checked after the fit).
    none = ~singular & ~feas2.any(axis=1)
    if none.any():
        i = int(np.argmax(none))
        reasons = []
        for b in range(2):
            why = _limit_text(machine, tilt2[i, b], xyz2[i, b], L)
            if why is None and not rax.within(rot2[i, b] + 360.0 * np.arange(-2, 3)).any():
                why = f"{rax.name}={rot2[i, b]:.4f} outside {rax.min:g} .. {rax.max:g}"
            reasons.append(f"solution {b + 1}: {why or 'outside the rotary range'}")
        raise KinematicsError(f"{where(i)}: no pose of machine {machine.name} within its limits "
                              f"for tool axis ({K[i, 0]:.6f}, {K[i, 1]:.6f}, {K[i, 2]:.6f}) at tip "
                              f"({tip[i, 0]:.4f}, {tip[i, 1]:.4f}, {tip[i, 2]:.4f}); " + "; ".join(reasons))

    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(center, axis=0), axis=1))])
    cut = None if move is None else (np.asarray(move)[1:] == Move.CUT)
    ps = pose_sequence(rot, K, feasible=travel2, cone=cone, length=length, cut=cut,
                       swing_limit=float(swing_limit) * DEG)
    tilt, rotv = rot.to_machine(ps.theta, ps.phi)
    branch = ps.branch
    reached = rot.axis(ps.theta, ps.phi)
    deviation = angle_between(K, reached)
    deviation[~singular] = 0.0
    reached[~singular] = K[~singular]
    new_tip = center - radius * reached
    xyz = linear_joints(machine, new_tip, tilt, rotv, L, origin)

    # Final check of every pose (singular ones were re-fitted; a long C may run out of range).
    ok = machine.tilt.within(tilt) & rax.within(rotv) & _travel_ok(machine, xyz, L)
    if not ok.all():
        i = int(np.argmax(~ok))
        why = _limit_text(machine, tilt[i], xyz[i], L)
        if why is None:
            why = (f"{rax.name}={rotv[i]:.4f} outside {rax.min:g} .. {rax.max:g} after unwinding "
                   f"{abs(rotv[i] - rotv[0]) / 360.0:.1f} turns")
        raise KinematicsError(f"{where(i)}: pose outside the limits of machine {machine.name}: {why}")

    joints = np.column_stack([xyz, tilt, rotv])
    info = {"singular_points": int(singular.sum()),
            "max_axis_deviation_deg": float(deviation.max() / DEG) if n else 0.0,
            "branch_flips": ps.flips,
            "rotary_travel_deg": float(np.abs(np.diff(rotv)).sum()) if n > 1 else 0.0,
            "tilt_travel_deg": float(np.abs(np.diff(tilt)).sum()) if n > 1 else 0.0,
            "max_rotary_step_deg": float(np.abs(np.diff(rotv)).max()) if n > 1 else 0.0}
    return (JointSolution(joints=joints, axis=reached, branch=branch, singular=singular,
                          deviation=deviation, flips=ps.flips, info=info, tip=new_tip), new_tip)


def slerp(a, b, t) -> np.ndarray:
    """Great-circle interpolation between unit vectors a, b (n,3) at fraction t."""
    ang = angle_between(a, b)
    sa = np.sin(ang)
    small = sa < 1e-12
    safe = np.where(small, 1.0, sa)
    w0 = np.where(small, 1.0 - t, np.sin((1.0 - t) * ang) / safe)
    w1 = np.where(small, t, np.sin(t * ang) / safe)
    v = w0[:, None] * a + w1[:, None] * b
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def swing(machine: Machine, joints, axis, samples=(0.25, 0.5, 0.75)) -> np.ndarray:
    """Largest angle (rad) between the tool axis while the rotaries move linearly from row k
    to row k+1 and the great circle between the two programmed axes, per block (n-1,).

    Small for ordinary blocks; large where the rotaries rewind a turn or flip branch while the
    tool axis itself hardly changes, i.e. where the tool would sweep through the part (the
    post retracts around such blocks).
    """
    j = np.asarray(joints, float)
    if len(j) < 2:
        return np.zeros(0)
    k0, k1 = axis[:-1], axis[1:]
    worst = np.zeros(len(j) - 1)
    for t in samples:
        q = (1 - t) * j[:-1, 3:] + t * j[1:, 3:]
        worst = np.maximum(worst, angle_between(orientation(machine, q[:, 0], q[:, 1]), slerp(k0, k1, t)))
    return worst


# --- joint-space linearisation ------------------------------------------------------------

def _segment_distance(p, a, b):
    """Distance of points p (n,3) from segments a-b (n,3)."""
    ab = b - a
    ll = np.einsum("ni,ni->n", ab, ab)
    t = np.where(ll > 0, np.einsum("ni,ni->n", p - a, ab) / np.where(ll > 0, ll, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def joint_deviation(machine: Machine, joints, tip, blocks, tool_length=None, part_origin=None,
                    samples=(0.25, 0.5, 0.75)) -> np.ndarray:
    """Largest distance of the tip from the programmed segment while the machine
    interpolates the joints linearly, for each block ``k -> k+1`` in ``blocks`` (mm)."""
    blocks = np.asarray(blocks, np.int64)
    if len(blocks) == 0:
        return np.zeros(0)
    q0, q1 = joints[blocks], joints[blocks + 1]
    a, b = tip[blocks], tip[blocks + 1]
    worst = np.zeros(len(blocks))
    for t in samples:
        p, _ = forward(machine, (1 - t) * q0 + t * q1, tool_length, part_origin)
        worst = np.maximum(worst, _segment_distance(p, a, b))
    return worst


def linearise(machine: Machine, joints, tip, source, feed, tolerance: float, *, tool_length=None,
              part_origin=None, angle_decimals: int | None = None, max_rounds: int = 40):
    """Insert points until the joint-interpolated tip stays within ``tolerance`` (mm) of
    every programmed feed segment (docs/post.md section 4).

    ``feed[k]`` marks the block arriving at point k as a feed move (rapids are left alone).
    An inserted point lies on the segment; its rotary values are the joint midpoint (rounded
    to ``angle_decimals`` when given, as the program will write them) and X, Y, Z put the tip
    exactly there. Returns ``joints, tip, source, feed, inserted_count, worst_deviation``.
    """
    joints = np.asarray(joints, float).copy()
    tip = np.asarray(tip, float).copy()
    source = np.asarray(source, float).copy()
    feed = np.asarray(feed, bool).copy()
    inserted = 0
    for _ in range(max_rounds):
        blocks = np.nonzero(feed[1:])[0]
        dev = joint_deviation(machine, joints, tip, blocks, tool_length, part_origin)
        split = blocks[dev > tolerance]
        if len(split) == 0:
            worst = float(dev.max()) if len(dev) else 0.0
            return joints, tip, source, feed, inserted, worst
        rot = 0.5 * (joints[split, 3:] + joints[split + 1, 3:])
        if angle_decimals is not None:
            rot = np.round(rot, angle_decimals)
        mid = 0.5 * (tip[split] + tip[split + 1])
        xyz = linear_joints(machine, mid, rot[:, 0], rot[:, 1], tool_length, part_origin)
        at = split + 1
        joints = np.insert(joints, at, np.column_stack([xyz, rot]), axis=0)
        tip = np.insert(tip, at, mid, axis=0)
        source = np.insert(source, at, 0.5 * (source[split] + source[split + 1]))
        feed = np.insert(feed, at, True)
        inserted += len(split)
    blocks = np.nonzero(feed[1:])[0]
    dev = joint_deviation(machine, joints, tip, blocks, tool_length, part_origin)
    k = int(blocks[np.argmax(dev)])
    raise KinematicsError(f"linearisation did not reach {tolerance:g} mm after {max_rounds} rounds "
                          f"near source point {source[k]:.3f} (deviation {dev.max():.4g} mm)")
