"""A turbine-impeller-like test part after xu2013 (section 7: a 108 mm cryogenic
turboexpander impeller): a hub with nine twisted blades, the passage between two
neighbouring blades as three B-spline patches (the rest of the part, as obstacles for the
collision check, is ``tsplcam.orientation.obstacles.impeller_mesh``).

Geometry (mm, cylindrical r, theta, z about the Z axis, which is the C axis of the machine):

* flow station u in [0, 1] runs from the inlet at r = 54 (diameter 108) inward to r = 22;
  the hub rises from z = 4 to z = 30 along it (z_h = 4 + 26 ((54 - r) / 32)^2);
* blades: camber theta_b(u) = 0.5 u^2 rad, height above the hub 10 -> 20 mm, thickness
  2.5 mm; a blade section leans over by ``lean(u)`` (tangential offset per unit height),
  which turns from -10 deg at the inlet to +25 deg at the exducer: the blade is twisted,
  and near the exducer its pressure side overhangs the passage floor;
* the passage of one pitch (40 deg) between blade 0's pressure side and blade 1's suction
  side is one cubic B-spline surface across (wall, root fillet, floor, root fillet, wall),
  split at knots into three patches (wall 0, floor, wall 1) that share their edges;
* ``tsplcam.orientation.obstacles.impeller_mesh`` adds the other eight passages (the same
  surface turned by the pitch), the blade tips and ends, and the hub nose, so the
  collision check sees neighbouring blades and hub.

At the blade roots a vertical tool's shank and holder run into the overhanging blade and
its neighbour, so only tilted axes reach (the tests show it with fcl).
"""
from __future__ import annotations

import numpy as np

from .bspline import bspline_patch
from .model import Model, link_patches
from .patch import CORNER_UV

BLADES = 9
R_IN, R_OUT = 22.0, 54.0
THICKNESS = 2.5
PITCH = 2 * np.pi / BLADES
DEG = np.pi / 180.0


def hub_z(r):
    return 4.0 + 12.0 * ((R_OUT - np.asarray(r, float)) / (R_OUT - R_IN)) ** 2


def _station(u):
    u = np.asarray(u, float)
    r = R_OUT - (R_OUT - R_IN) * u
    height = 10.0 + 10.0 * u
    camber = 0.3 * u ** 2
    lean = np.tan((-10.0 + 30.0 * u) * DEG)
    return r, height, camber, lean


FILLET = 6.0          # root fillet radius (mm) in the constant-r section (about 2.8 mm across the fillet at the exducer)
SECTION_POLES = 24


def _profile(u, samples: int = 1000):
    """The exact cross-section at station u in five pieces, each sampled evenly: blade 0's
    wall from its tip down, a root fillet of radius FILLET, the floor, the other fillet,
    blade 1's wall up. Points (x, h): x the arc length along the circle of radius r from
    theta = 0, h the height above the hub. Returns (pieces, r)."""
    r, H, camber, lean = _station(u)
    x0 = r * camber + 0.5 * THICKNESS                 # blade 0 pressure side at the root
    x1 = r * camber + r * PITCH - 0.5 * THICKNESS     # blade 1 suction side at the root
    dw = np.array([lean, 1.0]) / np.hypot(lean, 1.0)  # both walls rise along dw

    def corner(c, floor_dir):
        """Tangent points and arc of the fillet between the floor (from c along floor_dir)
        and the wall (from c along dw)."""
        phi = np.arccos(np.clip(np.dot(floor_dir, dw), -1, 1))
        t = FILLET / np.tan(phi / 2)
        bis = floor_dir + dw
        bis /= np.linalg.norm(bis)
        centre = c + bis * FILLET / np.sin(phi / 2)
        pa, pb = c + floor_dir * t, c + dw * t
        a0 = np.arctan2(*(pa - centre)[::-1])
        a1 = np.arctan2(*(pb - centre)[::-1])
        return pa, pb, centre, a0, a1

    c0, c1 = np.array([x0, 0.0]), np.array([x1, 0.0])
    f0a, f0b, m0, a00, a01 = corner(c0, np.array([1.0, 0.0]))
    f1a, f1b, m1, a10, a11 = corner(c1, np.array([-1.0, 0.0]))
    tip0 = c0 + dw * H / dw[1]
    tip1 = c1 + dw * H / dw[1]

    def arc(m, a, b, n=60):
        d = (b - a + np.pi) % (2 * np.pi) - np.pi
        t = a + d * np.linspace(0, 1, n)
        return m + FILLET * np.column_stack([np.cos(t), np.sin(t)])

    counts = np.full(5, samples // 5)
    pieces = [np.linspace(tip0, f0b, counts[0]), arc(m0, a01, a00, counts[1]),
              np.linspace(f0a, f1a, counts[2]), arc(m1, a10, a11, counts[3]),
              np.linspace(f1b, tip1, counts[4])]
    return pieces, r


def _section(u):
    """Control points (x, h) of the passage cross-section at station u: a least-squares
    cubic B-spline (SECTION_POLES poles, uniform clamped knots) through the exact profile,
    parametrised by arc length."""
    from .basis import bspline_basis
    pieces, r = _profile(u)
    P = np.vstack(pieces)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    t = np.linspace(0, 1, 600)
    pts = np.column_stack([np.interp(t * s[-1], s, P[:, 0]), np.interp(t * s[-1], s, P[:, 1])])
    span, vals = bspline_basis(_clamped(SECTION_POLES), 3, t)
    B = np.zeros((len(t), SECTION_POLES))
    for k in range(4):
        B[np.arange(len(t)), span - 3 + k] = vals[:, 0, k]
    ctrl, *_ = np.linalg.lstsq(B, pts, rcond=None)
    return ctrl, r


def _to_xyz(xh, r):
    th = xh[..., 0] / r
    z = hub_z(r) + xh[..., 1]
    return np.stack([r * np.cos(th), r * np.sin(th), np.broadcast_to(z, th.shape)], axis=-1)


def _poles(nu: int = 17):
    us = np.linspace(0.0, 1.0, nu)
    rows = []
    for u in us:
        xh, r = _section(u)
        rows.append(_to_xyz(xh, r))
    return np.array(rows)                               # (nu, nv, 3), first index along u


def _clamped(n: int, p: int = 3) -> np.ndarray:
    inner = np.linspace(0.0, 1.0, n - p + 1)
    return np.concatenate([[0.0] * p, inner, [1.0] * p])


def _insert(P, knots, t, p):
    """Boehm insertion of knot t once into the curves P (..., n, 3) along axis -2."""
    k = int(np.searchsorted(knots, t, side="right") - 1)
    n = P.shape[-2]
    Q = np.empty(P.shape[:-2] + (n + 1, 3))
    for i in range(n + 1):
        if i <= k - p:
            Q[..., i, :] = P[..., i, :]
        elif i >= k + 1:
            Q[..., i, :] = P[..., i - 1, :]
        else:
            a = (t - knots[i]) / (knots[i + p] - knots[i])
            Q[..., i, :] = a * P[..., i, :] + (1 - a) * P[..., i - 1, :]
    return Q, np.insert(knots, k + 1, t)


def _split(P, knots, t, p=3):
    """Split clamped curves at t into (left poles, left knots), (right poles, right knots)."""
    mult = int(np.count_nonzero(np.abs(knots - t) < 1e-12))
    for _ in range(p - mult):
        P, knots = _insert(P, knots, t, p)
    k = int(np.searchsorted(knots, t, side="left"))     # first t
    left_k = np.concatenate([knots[:k + p], [t]])
    right_k = np.concatenate([[t], knots[k:]])
    nl = len(left_k) - p - 1
    nr = len(right_k) - p - 1
    return (P[..., :nl, :], left_k), (P[..., P.shape[-2] - nr:, :], right_k)


def passage_surface(nu: int = 13):
    """Poles (nu, nv, 3) and knots of the whole passage surface (u against the flow, from the
    exducer at r = 22 to the inlet at r = 54; v from blade 0's tip across the floor to
    blade 1's tip)."""
    P = _poles(nu)[::-1]                  # patch u runs against the flow: normals into the passage
    return P, _clamped(P.shape[0]), _clamped(P.shape[1])


# v parameters of the splits: in the middle of the two root fillets
SPLITS = (0.3, 0.7)


def impeller() -> Model:
    """The passage between blades 0 and 1 as three linked patches: 0 = wall of blade 0
    (pressure side), 1 = floor with both root fillets, 2 = wall of blade 1 (suction side).
    Normals point into the passage (toward the tool)."""
    P, ku, kv = passage_surface()
    Pv = np.swapaxes(P, 0, 1)                            # curves along v: (nu, nv, 3) -> rows by u
    (A, ka), (rest, kr) = _split(np.swapaxes(Pv, 0, 1), kv, SPLITS[0])
    (B, kb), (C, kc) = _split(rest, kr, SPLITS[1])
    patches = []
    for idx, (poles, kvv, name) in enumerate(((A, ka, "wall 0"), (B, kb, "floor"), (C, kc, "wall 1"))):
        patches.append(bspline_patch(poles, None, ku, kvv, 3, 3, index=idx, name=name))
    # orientation: S_u x S_v must point into the passage; check on the floor
    sp = patches[1].evaluate(0.5, 0.5)
    if sp.normal[0, 2] < 0:                               # pragma: no cover - fixed by construction
        raise AssertionError("impeller passage normals point into the material")
    link_patches(patches, [((0, 2), (1, 0), True), ((1, 2), (2, 0), True)])
    corners = []
    nodes = []

    def node(p):
        for i, q in enumerate(nodes):
            if np.linalg.norm(q - p) < 1e-9:
                return i
        nodes.append(p)
        return len(nodes) - 1

    for p in patches:
        p.corner_nodes = np.array([node(p.evaluate(*CORNER_UV[k]).P[0]) for k in range(4)])
        corners.append(p.corner_nodes)
    return Model(patches, np.array(nodes), [], "bspline", name="impeller passage")
