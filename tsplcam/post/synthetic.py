"""Synthetic tool paths with known geometry, for the post stage's tests and benchmarks.

They stand in for the surface kernel's paths: closed-form tips and axes that exercise the
kinematics (tool axis circling the C axis, passing through or near the singular pose,
tilted sweeps over a hemisphere).
"""
from __future__ import annotations

import numpy as np

from ..toolpath.path import Move, ToolPath


def _path(contact, normal, axis, tool_radius, feed, move=None):
    n = len(contact)
    t = np.linspace(0.0, 1.0, n)
    axis = np.asarray(axis, float)
    axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    return ToolPath(contact=contact, normal=normal, axis=axis,
                    move=np.full(n, Move.CUT, np.int8) if move is None else move,
                    patch=np.zeros(n, int), uv=np.column_stack([t, np.zeros(n)]),
                    line=np.zeros(n, int), tool_radius=tool_radius, feed=feed)


def hemisphere_sweep(n=400, radius=40.0, turns=2.0, lat=(20.0, 70.0), lean=0.3,
                     tool_radius=3.0, feed=1500.0) -> ToolPath:
    """A spiral on a sphere of ``radius`` about the origin, latitude rising through ``lat``
    (deg); the tool axis is the surface normal leaned upward by ``lean`` (a Z component
    added before normalising)."""
    t = np.linspace(0.0, 1.0, n)
    lon = 2.0 * np.pi * turns * t
    la = np.radians(lat[0] + (lat[1] - lat[0]) * t)
    nrm = np.column_stack([np.cos(la) * np.cos(lon), np.cos(la) * np.sin(lon), np.sin(la)])
    axis = nrm + np.array([0.0, 0.0, lean])
    return _path(radius * nrm, nrm, axis, tool_radius, feed)


def helix(n=600, turns=3.0, tilt=30.0, radius=25.0, pitch=2.0, tool_radius=3.0, feed=1200.0,
          phase=0.0) -> ToolPath:
    """Tips on a helix about Z; the tool axis at ``tilt`` (deg) from Z turning with it, so the
    C axis has to follow ``turns`` full turns."""
    t = np.linspace(0.0, 1.0, n)
    phi = 2.0 * np.pi * turns * t + np.radians(phase)
    th = np.radians(tilt)
    axis = np.column_stack([np.sin(th) * np.cos(phi), np.sin(th) * np.sin(phi), np.full(n, np.cos(th))])
    tip = np.column_stack([radius * np.cos(phi), radius * np.sin(phi), pitch * turns * t])
    contact = tip + tool_radius * axis - tool_radius * axis     # normal = axis: contact = tip
    return _path(contact, axis, axis, tool_radius, feed)


def pole_pass(n=201, tilt=20.0, miss=0.0, length=60.0, azimuth=30.0, tool_radius=3.0,
              feed=1000.0) -> ToolPath:
    """A straight line along which the tool axis swings from ``+tilt`` to ``-tilt`` (deg) in
    the vertical plane at ``azimuth`` (deg), passing the vertical (the C axis) at angular
    distance ``miss`` (deg): through the singular pose for ``miss = 0``, beside it otherwise."""
    t = np.linspace(-1.0, 1.0, n)
    a = np.radians(tilt) * t
    m = np.radians(miss)
    az = np.radians(azimuth)
    u = np.array([np.cos(az), np.sin(az), 0.0])          # swing direction
    w = np.array([-np.sin(az), np.cos(az), 0.0])         # miss direction
    axis = (np.sin(a)[:, None] * u + np.sin(m) * np.cos(a)[:, None] * w
            + (np.cos(m) * np.cos(a))[:, None] * np.array([0.0, 0.0, 1.0]))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    tip = np.column_stack([0.5 * length * t, 0.2 * length * t, 10.0 + 0.0 * t])
    normal = np.tile([0.0, 0.0, 1.0], (n, 1))
    contact = tip + tool_radius * axis - tool_radius * normal
    return _path(contact, normal, axis, tool_radius, feed)


def two_passes_with_retract(clearance=20.0) -> ToolPath:
    """Two hemisphere passes joined by a retract along the tool axis, a rapid at clearance and
    a link down to the second pass: every Move kind in one path."""
    a = hemisphere_sweep(n=120, turns=0.5, lat=(25.0, 35.0))
    b = hemisphere_sweep(n=120, turns=0.5, lat=(45.0, 55.0))
    up_a = a.tip[-1] + clearance * a.axis[-1]
    up_b = b.tip[0] + clearance * b.axis[0]
    tip = np.vstack([a.tip, up_a, up_b, b.tip])
    axis = np.vstack([a.axis, a.axis[-1], b.axis[0], b.axis])
    move = np.concatenate([a.move, [Move.RETRACT, Move.RAPID, Move.LINK], b.move[1:]]).astype(np.int8)
    normal = np.vstack([a.normal, a.axis[-1], b.axis[0], b.normal])
    contact = tip + a.tool_radius * axis - a.tool_radius * normal
    tp = _path(contact, normal, axis, a.tool_radius, a.feed, move=move)
    tp.patch[len(a.tip):len(a.tip) + 2] = -1
    tp.uv[len(a.tip):len(a.tip) + 2] = np.nan
    return tp
