"""The orientation controls as geometry: target axes and limit cones per point.

:func:`target_axes` turns an :class:`~tsplcam.orientation.settings.OrientationSettings`
target into the preferred tool axis at every point (unit, part frame, tip toward spindle):

* ``axis``: the fixed direction;
* ``lead-tilt``: ``a ~ n + tan(lead) f + tan(side_tilt) s`` with the surface normal ``n``,
  the feed direction ``f`` and ``s = n x f`` (so that ``atan2(a.f, a.n)`` is the lead and
  ``atan2(a.s, a.n)`` the side tilt, the convention of the candidate cone);
* ``toward-point`` / ``away-from-point``: from the ball centre to the point, or away;
* ``toward-line`` / ``away-from-line``: from the ball centre to its foot on the line, or away.

:func:`limit_halfspaces` gives the largest-tilt cone ``a . c >= cos(max_tilt)`` as the
half-space form the smoothing and the candidate masks use. :func:`point_settings` maps a
processing list's per-step blocks onto the path's points (by patch).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .settings import OrientationSettings


def _unit(x):
    n = np.linalg.norm(x, axis=-1, keepdims=True)
    return x / np.where(n > 1e-15, n, 1.0)


def target_axes(s: OrientationSettings, center, normal, feed) -> np.ndarray:
    """Preferred axes (n,3) of the points (ball centres, normals, feed directions)."""
    n = len(center)
    if s.target == "axis":
        return np.tile(_unit(np.asarray(s.axis, float)), (n, 1))
    if s.target == "lead-tilt":
        side = np.cross(normal, feed)
        return _unit(normal + np.tan(np.radians(s.lead)) * feed + np.tan(np.radians(s.side_tilt)) * side)
    P = np.asarray(s.point, float)
    if s.target in ("toward-point", "away-from-point"):
        v = P - center
    else:
        d = _unit(np.asarray(s.direction, float))
        foot = P + np.einsum("ij,j->i", center - P, d)[:, None] * d
        v = foot - center
    if s.target.startswith("away"):
        v = -v
    degenerate = np.linalg.norm(v, axis=1) < 1e-9          # on the point or the line: the normal
    v = np.where(degenerate[:, None], normal, v)
    return _unit(v)


def limit_halfspaces(s: OrientationSettings, n: int) -> list:
    """``(h (n,3), b (n,))`` with ``h . a >= b`` for the largest tilt from ``limit_axis``."""
    if s.max_tilt is None:
        return []
    c = _unit(np.asarray(s.limit_axis, float))
    return [(np.tile(c, (n, 1)), np.full(n, np.cos(np.radians(s.max_tilt))))]


def point_settings(path, base: OrientationSettings, per_patch: dict | None) -> list:
    """The settings of each point as ``[(settings, point indices)]``: a point on a patch with
    a step block takes that block's settings, every other point (links between patches,
    patches without a block) the job's."""
    base.check()
    if not per_patch:
        return [(base, np.arange(len(path)))]
    patch = np.asarray(path.patch)
    out, rest = [], np.ones(len(path), bool)
    for p, s in sorted(per_patch.items()):
        if not isinstance(s, OrientationSettings):
            raise InputError(f"per-patch orientation settings must be OrientationSettings, not {type(s).__name__}")
        idx = np.nonzero(patch == p)[0]
        if len(idx):
            out.append((s.check(), idx))
            rest[idx] = False
    if rest.any():
        out.insert(0, (base, np.nonzero(rest)[0]))
    return out


def step_settings(base: OrientationSettings, blocks: dict) -> dict:
    """{patch: OrientationSettings} from a processing list's step blocks ``{patch: (block,
    where)}`` (plan.listfile.orientation_blocks): each block over ``base``, checked; errors
    name the file, line and step."""
    return {p: base.with_step(block, where) for p, (block, where) in blocks.items()}


def runs(strategy_of_point: np.ndarray) -> list:
    """Maximal runs ``(start, stop)`` of consecutive points with the same strategy."""
    s = np.asarray(strategy_of_point)
    if len(s) == 0:
        return []
    cut = np.nonzero(s[1:] != s[:-1])[0] + 1
    edges = np.concatenate([[0], cut, [len(s)]])
    return list(zip(edges[:-1], edges[1:]))
