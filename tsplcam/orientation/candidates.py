"""Candidate tool axes per contact point and the machine's rotary reach.

Candidates (xu2013 section 3's cone of admissible orientations, discretised): around the
surface normal ``n`` at each point, rings at angles ``beta`` from the normal (every
``resolution`` up to the cone's limit) with spokes every ``resolution`` of arc, the spoke
origin turned toward the preferred axis so that every ring holds the direction closest to
it; plus the preferred axis itself and the normal. The lead angle is the axis's
inclination toward the feed direction ``f`` and the tilt its inclination sideways
(``s = n x f``): ``lead = atan2(a.f, a.n)``, ``tilt = atan2(a.s, a.n)`` (the Sinumerik
LEAD/TILT convention); a candidate is kept when both are within their limits.

Rotary reach (docs/post.md section 1): for a machine whose C axis is +Z in the part frame the
angle between the tool axis and +Z is the magnitude of the tilt axis value; with the two
inverse solutions (tilt, C) and (-tilt, C + 180 deg) an axis is reachable when either
solution is within the tilt limits (and the C limits when C is not endless). The machine
object is read by duck typing (``tilt``/``rotary`` with ``min``, ``max``, ``zero``,
``sign``, ``about``, ``continuous``; ``on_table(axis)``), so this stage needs nothing from
the post stage at import time.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..numerics import components

DEG = np.pi / 180.0
Z_AXIS = np.array([0.0, 0.0, 1.0])


def _length(x: np.ndarray) -> np.ndarray:
    """Euclidean length along the last axis of length 3, summed in numpy.linalg.norm's order
    (the same bits) without its general reduction, which is slow on short rows."""
    return np.sqrt(x[..., 0] * x[..., 0] + x[..., 1] * x[..., 1] + x[..., 2] * x[..., 2])


def unit(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, float)
    n = _length(x)[..., None]
    return x / np.where(n > 0, n, 1.0)


def angle(a, b) -> np.ndarray:
    """Angle (rad) between unit vectors along the last axis, accurate for small angles."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    c = np.sqrt((a1 * b2 - a2 * b1) ** 2 + (a2 * b0 - a0 * b2) ** 2 + (a0 * b1 - a1 * b0) ** 2)
    return np.arctan2(c, np.einsum("...i,...i->...", a, b))


def feed_directions(contact: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Unit feed direction per point (central differences, projected into the tangent plane);
    where it is undefined (repeated points) the previous one, else any tangent."""
    P = np.asarray(contact, float)
    n = len(P)
    d = np.zeros_like(P)
    if n > 1:
        d[1:-1] = P[2:] - P[:-2]
        d[0] = P[1] - P[0]
        d[-1] = P[-1] - P[-2]
    d = d - np.einsum("ij,ij->i", d, normal)[:, None] * normal
    ln = np.linalg.norm(d, axis=1)
    bad = ln < 1e-12
    if bad.any():
        alt = np.cross(normal, np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
        good = np.nonzero(~bad)[0]
        if len(good):
            idx = good[np.clip(np.searchsorted(good, np.arange(n)) - 1, 0, len(good) - 1)]
            fill = d[idx] - np.einsum("ij,ij->i", d[idx], normal)[:, None] * normal
            use = bad & (np.linalg.norm(fill, axis=1) > 1e-12)
            d[use] = fill[use]
            bad = bad & ~use
        d[bad] = alt[bad]
    return unit(d)


@dataclass
class Reach:
    """Tool axes a machine can reach: angle from +Z within [theta_min, theta_max] for some
    branch; ``c_ok`` optionally restricts the azimuth (limited C)."""
    intervals: tuple = ((0.0, np.pi),)          # allowed angle from +Z (rad), union
    machine: object = None
    name: str = "unlimited"

    @staticmethod
    def from_machine(machine) -> "Reach":
        t = machine.tilt
        et = (-1.0 if machine.on_table(t) else 1.0) * t.sign
        lo = -np.inf if t.min is None else t.min
        hi = np.inf if t.max is None else t.max
        iv = []
        for s in (1.0, -1.0):                    # branch 1: tilt = zero + theta*et; branch 2: minus
            a, b = sorted(((lo - t.zero) / (s * et), (hi - t.zero) / (s * et)))
            a, b = max(a, 0.0), min(b, 180.0)
            if a <= b:
                iv.append((a * DEG, b * DEG))
        return Reach(tuple(iv), machine, f"machine {machine.name}")

    @staticmethod
    def max_tilt(deg: float) -> "Reach":
        return Reach(((0.0, deg * DEG),), None, f"tilt <= {deg:g} deg")

    @property
    def theta_max(self) -> float:
        return max(b for _, b in self.intervals)

    def ok(self, axes: np.ndarray) -> np.ndarray:
        """Mask of reachable unit axes (..., 3)."""
        A = np.asarray(axes, float)
        ax, ay, az = components(A)           # (contiguous: the same ufunc code whatever the heap)
        th = np.arctan2(np.hypot(ax, ay), az)
        branch_ok = [(th >= a - 1e-9) & (th <= b + 1e-9) for a, b in self.intervals]
        m = self.machine
        if m is None or m.rotary.continuous or m.rotary.min is None or \
                (m.rotary.max - m.rotary.min) >= 360.0:
            out = np.zeros(th.shape, bool)
            for x in branch_ok:
                out |= x
            return out
        # limited C: check each branch with its own C value (and whole turns)
        r = m.rotary
        ec = (-1.0 if m.on_table(r) else 1.0) * r.sign
        t = m.tilt
        et = (-1.0 if m.on_table(t) else 1.0) * t.sign
        phi = np.arctan2(ax, -ay) if t.about == "X" else np.arctan2(ay, ax)
        out = np.zeros(th.shape, bool)
        for s, ph in ((1.0, phi), (-1.0, phi + np.pi)):
            tilt = t.zero + s * th / DEG * et
            okt = np.ones(th.shape, bool)
            if t.min is not None:
                okt &= tilt >= t.min - 1e-9
            if t.max is not None:
                okt &= tilt <= t.max + 1e-9
            c = r.zero + np.mod(ph / DEG * ec + 180.0, 360.0) - 180.0
            okc = np.zeros(th.shape, bool)
            for k in range(-2, 3):
                okc |= (c + 360.0 * k >= r.min - 1e-9) & (c + 360.0 * k <= r.max + 1e-9)
            out |= okt & okc
        return out


@dataclass
class Limits:
    """Cone of admissible axes around the normal (degrees at the interface, stored in rad)."""
    lead_max: float = 60.0 * DEG        # |lead| <= lead_max
    tilt_max: float = 60.0 * DEG        # |tilt| <= tilt_max
    resolution: float = 7.5 * DEG       # ring spacing and spoke arc

    @property
    def cone(self) -> float:
        return max(self.lead_max, self.tilt_max)


def lead_tilt(axes: np.ndarray, normal: np.ndarray, feed: np.ndarray):
    """(lead, tilt) in rad of axes (n, m, 3) at points with normals and feeds (n, 3)."""
    side = np.cross(normal, feed)
    an = np.einsum("nmi,ni->nm", axes, normal)
    af = np.einsum("nmi,ni->nm", axes, feed)
    asd = np.einsum("nmi,ni->nm", axes, side)
    return np.arctan2(af, an), np.arctan2(asd, an)


def admissible(axes, normal, feed, limits: Limits, reach: Reach | None) -> np.ndarray:
    """Mask (n, m): axis on the tool side of the surface, lead and tilt within the limits,
    and reachable by the machine."""
    lead, tilt = lead_tilt(axes, normal, feed)
    an = np.einsum("nmi,ni->nm", axes, normal)
    ok = (an > 1e-6) & (np.abs(lead) <= limits.lead_max + 1e-9) & (np.abs(tilt) <= limits.tilt_max + 1e-9)
    if reach is not None:
        ok &= reach.ok(axes)
    return ok


def ring_layout(limits: Limits) -> list:
    """(beta, spokes) of the rings: beta every ``resolution`` up to the cone, spokes so that
    neighbouring spokes are about ``resolution`` apart (at least 6)."""
    res = limits.resolution
    rings = []
    nb = int(np.ceil(limits.cone / res - 1e-9))
    for j in range(1, nb + 1):
        beta = min(j * res, limits.cone)
        rings.append((beta, max(6, int(np.ceil(2 * np.pi * np.sin(beta) / res)))))
    return rings


def candidate_axes(normal: np.ndarray, feed: np.ndarray, preferred: np.ndarray, limits: Limits,
                   reach: Reach | None = None):
    """Candidate axes (n, m, 3) and their admissibility mask (n, m).

    Column 0 is the preferred axis, column 1 the normal, then the rings (spoke 0 of each
    ring toward the preferred axis). Inadmissible candidates stay in the array (masked) so
    that every point has the same columns.
    """
    N = unit(np.asarray(normal, float))
    n = len(N)
    pref = unit(np.broadcast_to(np.asarray(preferred, float), (n, 3)).copy())
    # spoke origin: toward the preferred axis in the tangent plane, else the feed direction
    e1 = pref - np.einsum("ij,ij->i", pref, N)[:, None] * N
    ln = np.linalg.norm(e1, axis=1)
    e1 = np.where((ln > 1e-6)[:, None], e1 / np.where(ln > 1e-6, ln, 1.0)[:, None], feed)
    e2 = np.cross(N, e1)
    cols = [pref[:, None, :], N[:, None, :]]
    for beta, k in ring_layout(limits):
        psi = 2 * np.pi * np.arange(k) / k
        d = np.cos(psi)[None, :, None] * e1[:, None, :] + np.sin(psi)[None, :, None] * e2[:, None, :]
        cols.append(np.cos(beta) * N[:, None, :] + np.sin(beta) * d)
    A = unit(np.concatenate(cols, axis=1))
    return A, admissible(A, N, feed, limits, reach)
