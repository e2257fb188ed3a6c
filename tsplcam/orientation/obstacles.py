"""Obstacles around a machined surface for the collision check, as (name, vertices,
triangles) meshes: the impeller test part (``tsplcam.model.impeller``) beyond the one
passage that is machined.
"""
from __future__ import annotations

import numpy as np

from ..model.impeller import BLADES, PITCH, R_IN, hub_z, impeller
from ..model.model import Model
from .collision import tessellate_model


def _rot(P, ang):
    c, s = np.cos(ang), np.sin(ang)
    Q = P.copy()
    Q[..., 0] = c * P[..., 0] - s * P[..., 1]
    Q[..., 1] = s * P[..., 0] + c * P[..., 1]
    return Q


def impeller_mesh(model: Model | None = None, tolerance: float = 0.01, include_passage: bool = False):
    """Obstacles around the machined passage, as (name, vertices, triangles) meshes: the
    other eight passages (turned copies of the passage surface, tessellated within
    ``tolerance``), the blade tips and ends (leading and trailing edges), and the hub nose (the hub surface
    continued to the axis).
    ``include_passage`` adds the machined passage itself (for pictures)."""
    model = model or impeller()
    tm = tessellate_model(model, tolerance)
    out = []
    for k in range(BLADES):
        if k == 0 and not include_passage:
            continue
        out.append((f"passage {k}", _rot(tm.vertices, k * PITCH), tm.triangles.copy()))
    # passage borders: v = 0 (blade 0 tip side) and v = 1 (blade 1 tip side) curves
    nu = 161
    us = np.linspace(0, 1, nu)
    tip0 = model.patches[0].evaluate(us, np.zeros(nu)).P           # blade 0 pressure side tip
    tip1 = model.patches[2].evaluate(us, np.ones(nu)).P            # blade 1 suction side tip
    # blade 1's pressure side is passage 1's tip0; its tip face joins tip1 (passage 0) to it
    for k in range(BLADES):
        a = _rot(tip1, k * PITCH)
        b = _rot(tip0, (k + 1) * PITCH)
        V = np.vstack([a, b])
        i = np.arange(nu - 1)
        T = np.concatenate([np.column_stack([i, i + 1, nu + i + 1]), np.column_stack([i, nu + i + 1, nu + i])])
        out.append((f"blade {k + 1} tip", V, T))
        # blade ends: faces between the two sides at u = 0 and u = 1, from hub to tip
        for end, name in ((0, "leading edge"), (nu - 1, "trailing edge")):
            m = 24
            vv = np.linspace(0, 1, m)
            s1 = _rot(model.patches[2].evaluate(np.full(m, us[end]), vv).P, k * PITCH)
            s0 = _rot(model.patches[0].evaluate(np.full(m, us[end]), 1 - vv).P, (k + 1) * PITCH)
            V = np.vstack([s1, s0])
            j = np.arange(m - 1)
            T = np.concatenate([np.column_stack([j, j + 1, m + j + 1]), np.column_stack([j, m + j + 1, m + j])])
            out.append((f"blade {k + 1} {name}", V, T))
    # hub nose: the hub surface of revolution continued inside the exducer, r from R_IN to 0
    ang = np.linspace(0, 2 * np.pi, 181)[:-1]
    rr = np.linspace(R_IN, 0.0, 23)[:-1]
    V = np.vstack([np.column_stack([r * np.cos(ang), r * np.sin(ang), np.full(len(ang), hub_z(r))])
                   for r in rr] + [[[0.0, 0.0, float(hub_z(0.0))]]])
    na = len(ang)
    i = np.arange(na)
    T = []
    for k in range(len(rr) - 1):
        a, b = k * na + i, k * na + (i + 1) % na
        T += [np.column_stack([a, b, b + na]), np.column_stack([a, b + na, a + na])]
    last = (len(rr) - 1) * na
    T.append(np.column_stack([last + i, last + (i + 1) % na, np.full(na, len(V) - 1)]))
    out.append(("hub nose", V, np.concatenate(T)))
    return out
