"""The machine's two rotary axes as the part sees them, and the choice of poses along a path.

For every supported machine (table-table, head-table, head-head; tilt axis A about X or B
about Y, rotary axis C about Z) the tool axis in the part frame is

    K = Rz(phi) R_about(theta) z

with ``theta = e_t s_t (T - zero_t)`` and ``phi = e_c s_c (C - zero_c)`` (``s`` the axis's
sign, ``e = -1`` for a table axis, ``+1`` for a head axis; MACHINES.md). About X this is
``K = (sin phi sin theta, -cos phi sin theta, cos theta)``, ISO A/C (docs/post.md section 1); about Y
``(cos phi sin theta, sin phi sin theta, cos theta)``. Joint values are affine in (theta,
phi), so rotary motion is measured in these angles. Every axis off +Z has two poses,
``(theta, phi)`` and ``(-theta, phi + pi)``; on +Z (the pole, the singular pose) phi is free.

:class:`Rotary` holds the closed form, the limits and the axis dynamics (from a machine,
read by duck typing so this stage needs nothing from the post stage, or a virtual A/C table);
:func:`pose_sequence` picks one pose per point of a path (branch, C unwound or its
360-degree representative on a limited C, the free angle held and interpolated near the
pole) by dynamic programming (:func:`tsplcam.orientation.viterbi.viterbi`): the orientation
stage uses it to smooth in joint space, the post stage to write the program.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..numerics import component, components
from .viterbi import viterbi

DEG = np.pi / 180.0


def wrap_pi(a):
    """Angles (rad) into (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(a, float), 2.0 * np.pi)


def unit(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, float)
    n = np.linalg.norm(x, axis=-1, keepdims=True)
    return x / np.where(n > 0, n, 1.0)


def angle_between(a, b) -> np.ndarray:
    """Angle (rad) between unit vectors along the last axis, accurate for small angles. The
    cross product and its length component by component (np.cross's products and
    differences, np.linalg.norm's sum in its order: the same bits, without the passes over
    (..., 3) arrays: half the time on the smoothing's 14.7k x 36 poses)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    c0 = a1 * b2 - a2 * b1
    c1 = a2 * b0 - a0 * b2
    c2 = a0 * b1 - a1 * b0
    return np.arctan2(np.sqrt(c0 * c0 + c1 * c1 + c2 * c2), np.einsum("...i,...i->...", a, b))


@dataclass
class Rotary:
    """The rotary axes in part-frame angles (rad): tilt ``theta`` (signed, both branches) in
    ``[theta_lo, theta_hi]``, rotary ``phi`` in ``[phi_lo, phi_hi]`` or endless (None).
    Velocities rad/s, accelerations rad/s^2; ``et``, ``zero_t``, ``ec``, ``zero_c`` map to
    machine values in degrees: ``T = zero_t + et * theta / DEG``, ``C = zero_c + ec * phi / DEG``."""
    about: str = "X"
    theta_lo: float = -np.pi
    theta_hi: float = np.pi
    phi_lo: float | None = None
    phi_hi: float | None = None
    v_theta: float = np.pi
    v_phi: float = np.pi
    a_theta: float = 10.0 * np.pi
    a_phi: float = 10.0 * np.pi
    et: float = 1.0
    zero_t: float = 0.0
    ec: float = 1.0
    zero_c: float = 0.0
    name: str = "virtual A/C table"
    machine: object = None

    @staticmethod
    def from_machine(machine) -> "Rotary":
        """From a tsplcam.post Machine (``tilt``/``rotary`` axes with ``about``, ``sign``,
        ``zero``, ``min``, ``max``, ``continuous``, velocities in deg/min, accelerations in
        deg/s^2; ``on_table(axis)``)."""
        t, r = machine.tilt, machine.rotary
        et = (-1.0 if machine.on_table(t) else 1.0) * t.sign
        ec = (-1.0 if machine.on_table(r) else 1.0) * r.sign
        lo = -np.inf if t.min is None else (t.min - t.zero) * et * DEG
        hi = np.inf if t.max is None else (t.max - t.zero) * et * DEG
        lo, hi = min(lo, hi), max(lo, hi)
        if r.continuous or r.min is None:
            plo = phi = None
        else:
            a, b = sorted(((r.min - r.zero) * ec * DEG, (r.max - r.zero) * ec * DEG))
            plo, phi = a, b
        return Rotary(t.about, max(lo, -np.pi), min(hi, np.pi), plo, phi,
                      t.max_velocity / 60.0 * DEG, r.max_velocity / 60.0 * DEG,
                      t.max_acceleration * DEG, r.max_acceleration * DEG,
                      et, t.zero, ec, r.zero, f"machine {machine.name}", machine)

    # --- closed form ------------------------------------------------------------------------
    def meridian(self, phi) -> np.ndarray:
        """Horizontal unit direction (…,3) toward which a positive tilt leans at rotary ``phi``:
        ``K(theta, phi) = cos(theta) z + sin(theta) meridian(phi)``."""
        phi = np.asarray(phi, float)
        if self.about == "X":
            return np.stack([np.sin(phi), -np.cos(phi), np.zeros_like(phi)], axis=-1)
        return np.stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)], axis=-1)

    def axis(self, theta, phi) -> np.ndarray:
        """Unit tool axes (…,3) of the poses: ``cos(theta) z + sin(theta) meridian(phi)``,
        component by component (the same operations, without passes over (…,3) arrays)."""
        theta = np.asarray(theta, float)
        c, s = np.cos(theta), np.sin(theta)
        m = self.meridian(phi)
        out = np.empty(np.broadcast_shapes(c.shape, m.shape[:-1]) + (3,))
        out[..., 0] = c * 0.0 + s * m[..., 0]
        out[..., 1] = c * 0.0 + s * m[..., 1]
        out[..., 2] = c * 1.0 + s * m[..., 2]
        return out

    def jacobian(self, theta, phi):
        """dK/dtheta and dK/dphi (…,3) at the poses."""
        theta = np.asarray(theta, float)
        m = self.meridian(phi)
        dm = self.meridian(np.asarray(phi, float) + 0.5 * np.pi)
        dth = -np.sin(theta)[..., None] * np.array([0.0, 0.0, 1.0]) + np.cos(theta)[..., None] * m
        return dth, np.sin(theta)[..., None] * dm

    def angles(self, K):
        """The pose with ``theta >= 0`` of unit axes K (…,3): ``theta, phi`` (rad; phi in
        (-pi, pi], 0 at the pole)."""
        kx, ky, kz = components(K)        # (contiguous: the same ufunc code whatever the heap)
        theta = np.arctan2(np.hypot(kx, ky), kz)
        if self.about == "X":
            phi = np.arctan2(kx, -ky + 0.0)
        else:
            phi = np.arctan2(ky, kx)
        return theta, phi

    def best_theta(self, K, phi, m=None) -> np.ndarray:
        """Signed tilt that brings the tool closest to ``K`` with the rotary held at ``phi``
        (``m``: ``meridian(phi)`` when the caller has it)."""
        K = np.asarray(K, float)
        m = self.meridian(phi) if m is None else m
        return np.arctan2(np.einsum("...i,...i->...", K, m), component(K, 2))

    def theta_ok(self, theta) -> np.ndarray:
        t = np.asarray(theta, float)
        return (t >= self.theta_lo - 1e-12) & (t <= self.theta_hi + 1e-12)

    def both(self, theta) -> np.ndarray:
        """Mask: both poses (theta and -theta) of axes at tilt ``theta >= 0`` are in range."""
        t = np.asarray(theta, float)
        return self.theta_ok(t) & self.theta_ok(-t)

    def to_machine(self, theta, phi):
        """Machine values (deg) of the poses: tilt T and rotary C."""
        return (self.zero_t + self.et * np.asarray(theta, float) / DEG,
                self.zero_c + self.ec * np.asarray(phi, float) / DEG)

    def from_machine_values(self, tilt, rot):
        """(theta, phi) in rad of machine values (deg)."""
        return (self.et * (np.asarray(tilt, float) - self.zero_t) * DEG,
                self.ec * (np.asarray(rot, float) - self.zero_c) * DEG)

    @property
    def phi_limited(self) -> bool:
        return self.phi_lo is not None

    def phi_ok(self, phi) -> np.ndarray:
        p = np.asarray(phi, float)
        if not self.phi_limited:
            return np.ones(p.shape, bool)
        return (p >= self.phi_lo - 1e-12) & (p <= self.phi_hi + 1e-12)

    @property
    def weight(self) -> float:
        """(v_theta / v_phi)^2: rotary motion in tilt-axis time units."""
        return (self.v_theta / self.v_phi) ** 2


def swing_mid(rot: Rotary, K0, K1, th0, ph0, th1, ph1) -> np.ndarray:
    """Angle (rad) at mid-block between the axis the joints give while they move linearly
    and the great circle between the programmed axes: large where the rotaries flip branch
    or rewind while the tool axis itself hardly changes (the tool would sweep)."""
    mid = unit(np.asarray(K0) + np.asarray(K1))
    return angle_between(rot.axis(0.5 * (th0 + th1), 0.5 * (ph0 + ph1)), mid)


@dataclass
class PoseSequence:
    """One pose per point: signed tilt and rotary (rad), branch, and the pole points."""
    theta: np.ndarray
    phi: np.ndarray
    branch: np.ndarray          # 0: theta >= 0 side, 1: the other
    singular: np.ndarray        # inside the pole cone: phi interpolated, theta re-fitted
    flips: int = 0


def pose_sequence(rot: Rotary, K, *, feasible=None, cone: float = 0.0, length=None, cut=None,
                  swing_limit: float = 5.0 * DEG) -> PoseSequence:
    """One pose per axis of ``K`` (n,3) along a path.

    ``feasible`` (n,2): which of the two poses (theta >= 0, theta <= 0) the caller allows
    (e.g. linear travel), on top of the tilt range; ``cone`` (rad): axes this close to the
    pole take no part in the choice, their rotary value is interpolated over the run (by
    ``length``, the cumulative path length, else by index) and the tilt re-fitted, so the
    tool axis moves by at most the cone; ``cut`` (n-1,) marks cutting blocks.

    Dynamic programming over the poses (and, for a limited rotary, its 360-degree
    representatives) minimises the rotary time sum |dtheta| / v_theta + |dphi| / v_phi; a
    block whose joints would swing the tool axis more than ``swing_limit`` off the great
    circle costs as much as a half turn more on a cutting block (a tenth of it elsewhere), so
    branch flips and rewinds go where the axis is nearest the pole, and to line ends. An
    endless rotary is unwound (neighbours differ by less than pi). Points no pose reaches
    keep both infeasible; the caller reports them.
    """
    K = unit(np.asarray(K, float).reshape(-1, 3))
    n = len(K)
    th, ph = rot.angles(K)
    T2 = np.stack([th, -th], axis=1)
    P2 = np.stack([ph, ph + np.pi], axis=1)
    feas2 = rot.theta_ok(T2)
    if feasible is not None:
        feas2 &= np.asarray(feasible, bool)
    singular = th <= max(cone, 1e-12)
    if cut is None:
        cut = np.ones(max(n - 1, 0), bool)
    if rot.phi_limited and rot.phi_hi - rot.phi_lo < 4.0 * np.pi:
        reps = np.arange(int(np.floor((rot.phi_lo - np.pi) / (2 * np.pi))),
                         int(np.ceil((rot.phi_hi + np.pi) / (2 * np.pi))) + 1)
        cand = wrap_pi(P2)[:, :, None] + 2 * np.pi * reps[None, None, :]
        ok = feas2[:, :, None] & rot.phi_ok(cand)
        keep = np.nonzero(ok.reshape(n, -1).any(axis=0))[0]
        R = len(reps)
        if len(keep) == 0:
            keep = np.arange(2 * R)
        Pst = cand.reshape(n, 2 * R)[:, keep]
        Tst = np.repeat(T2, R, axis=1)[:, keep]
        Fst = ok.reshape(n, 2 * R)[:, keep]
        Bst = np.repeat(np.arange(2), R)[keep]
        reps_mode = True
    else:
        Pst, Tst, Fst, Bst = P2, T2, feas2, np.arange(2)
        reps_mode = False

    idx = np.nonzero(~singular)[0]
    state = np.zeros(n, np.int64)
    if len(idx):
        Ts, Ps, Fs, Ks = Tst[idx], Pst[idx], Fst[idx], K[idx]
        dT = Ts[1:, None, :] - Ts[:-1, :, None]
        dP = Ps[1:, None, :] - Ps[:-1, :, None]
        if not reps_mode:
            dP = wrap_pi(dP)
        trans = np.abs(dT) / rot.v_theta + np.abs(dP) / rot.v_phi
        # a sweeping block (flip or rewind off the pole) costs a half turn more; only moves
        # that turn a rotary axis by more than 20 deg can sweep
        big = (np.abs(dP) > 20.0 * DEG) | (np.abs(dT) > 20.0 * DEG)
        sw = np.zeros(dP.shape)
        if big.any():
            k, a, b = np.nonzero(big)
            sw[k, a, b] = swing_mid(rot, Ks[k], Ks[k + 1], Ts[k, a], Ps[k, a], Ts[k + 1, b], Ps[k, a] + dP[k, a, b])
        blk_cut = np.ones(len(idx) - 1, bool)
        if len(idx) > 1:
            c = np.concatenate([[True], np.asarray(cut, bool)])
            # a block between kept points cuts if any block it spans cuts
            cs = np.cumsum(~c)
            blk_cut = (cs[idx[1:]] - cs[idx[:-1]]) < (idx[1:] - idx[:-1])
        pen = np.pi / rot.v_phi * np.where(blk_cut, 1.0, 0.1)
        trans = trans + np.where(sw > swing_limit, pen[:, None, None], 0.0)
        trans = np.where(Fs[1:, None, :] & Fs[:-1, :, None], trans, np.inf)
        node = np.where(Fs, 0.0, np.inf)
        node[0] += 1e-9 * Bst + 1e-12 * np.abs(Ps[0])   # ties: first branch, then rotary near zero
        s, broke = viterbi(node, trans)
        if s is None:
            # report the point; the caller explains the limits
            s = np.zeros(len(idx), np.int64)
            for k in range(len(idx)):
                if Fs[k].any():
                    s[k] = int(np.argmax(Fs[k]))
        state[idx] = s
    cols = np.arange(n)
    theta = Tst[cols, state].copy()
    phi = Pst[cols, state].copy()
    branch = np.broadcast_to(Bst, Tst.shape)[cols, state].astype(np.int8)
    if len(idx) and not reps_mode:
        r = phi[idx]
        r = r[0] + np.concatenate([[0.0], np.cumsum(wrap_pi(np.diff(r)))])
        if rot.phi_limited:                     # a long but limited rotary: shift whole turns in
            k_lo = np.ceil((rot.phi_lo - r.min()) / (2 * np.pi) - 1e-12)
            k_hi = np.floor((rot.phi_hi - r.max()) / (2 * np.pi) + 1e-12)
            if k_lo <= k_hi:
                r = r + 2 * np.pi * min(max(0.0, k_lo), k_hi)
        phi[idx] = r
    if singular.any():
        s8 = singular.astype(np.int8)
        starts = np.nonzero(np.diff(np.concatenate([[0], s8])) == 1)[0]
        ends = np.nonzero(np.diff(np.concatenate([s8, [0]])) == -1)[0]
        hold = 0.0 if rot.phi_ok(0.0) else 0.5 * (rot.phi_lo + rot.phi_hi)
        d_all = np.arange(n, dtype=float) if length is None else np.asarray(length, float)
        for a, b in zip(starts, ends):
            before, after = a - 1, b + 1
            if before >= 0 and after < n:
                c0, c1 = phi[before], phi[after]
                d = d_all[before:after + 1] - d_all[before]
                w = d / d[-1] if d[-1] > 0 else np.linspace(0.0, 1.0, len(d))
                phi[a:b + 1] = c0 + (c1 - c0) * w[1:-1]
            elif before >= 0:
                phi[a:b + 1] = phi[before]
            elif after < n:
                phi[a:b + 1] = phi[after]
            else:
                phi[a:b + 1] = hold
        sing = np.nonzero(singular)[0]
        theta[sing] = rot.best_theta(K[sing], phi[sing])
        branch[sing] = (theta[sing] < 0).astype(np.int8)
    nb = branch[~singular]
    flips = int(np.count_nonzero(nb[1:] != nb[:-1])) if len(nb) > 1 else 0
    return PoseSequence(theta, phi, branch, singular, flips)
