"""Plain iso-parametric zigzag paths for tests and benchmarks of the orientation stage.

Not the tool path generator (tsplcam.toolpath does scallop and chord control): evenly
spaced lines of constant v, points evenly spaced in u, alternate lines reversed, patches
one after the other. Enough to put the orientation strategies in front of real geometry.
"""
from __future__ import annotations

import numpy as np

from ..toolpath.path import Move, ToolPath


def zigzag(model, tool_radius: float, patches=None, lines: int = 12, points: int = 40,
           v_range=(0.0, 1.0), u_range=(0.0, 1.0), feed: float = 1000.0) -> ToolPath:
    """Zigzag over the listed patches (all by default): ``lines`` lines of constant v in
    ``v_range``, ``points`` points each over ``u_range``."""
    C, N, P, UV, L, M = [], [], [], [], [], []
    line = 0
    for k in (range(len(model.patches)) if patches is None else patches):
        patch = model.patches[k]
        for j, v in enumerate(np.linspace(*v_range, lines)):
            u = np.linspace(*u_range, points)
            if j % 2:
                u = u[::-1]
            sp = patch.evaluate(u, np.full(points, v))
            C.append(sp.P)
            N.append(sp.normal)
            P.append(np.full(points, k))
            UV.append(np.column_stack([u, np.full(points, v)]))
            L.append(np.full(points, line))
            mv = np.full(points, int(Move.CUT), np.int8)
            mv[0] = Move.LINK
            M.append(mv)
            line += 1
    contact = np.concatenate(C)
    normal = np.concatenate(N)
    return ToolPath(contact=contact, normal=normal, axis=normal.copy(), move=np.concatenate(M),
                    patch=np.concatenate(P), uv=np.concatenate(UV), line=np.concatenate(L),
                    tool_radius=float(tool_radius), feed=feed)
