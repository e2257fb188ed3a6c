"""Tensor-product rational B-spline patches (NURBS faces), as Bezier cells.

Used for B-spline faces from FreeCAD/STEP (the compound-NURBS baseline of shang2020) and as
the plain reference case of the T-spline kernel. The knot range [U0, U1] x [V0, V1] is
mapped linearly to the patch's unit square.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .basis import bspline_bezier_extraction
from .cells import BezierCells
from .patch import Patch


def flat_knots(knots, mults) -> np.ndarray:
    """Knot vector with repetitions from distinct knots and multiplicities (OCCT's form)."""
    return np.repeat(np.asarray(knots, float), np.asarray(mults, int))


def bspline_patch(poles, weights, uknots, vknots, p: int, q: int, index: int = 0,
                  name: str | None = None) -> Patch:
    """A patch from poles (nu, nv, 3) (first index along u), weights (nu, nv) or None, flat knot
    vectors (len nu+p+1 and nv+q+1) and degrees p, q."""
    poles = np.asarray(poles, float)
    nu, nv = poles.shape[:2]
    weights = np.ones((nu, nv)) if weights is None else np.asarray(weights, float)
    uknots = np.asarray(uknots, float)
    vknots = np.asarray(vknots, float)
    label = name or f"patch {index}"
    if len(uknots) != nu + p + 1 or len(vknots) != nv + q + 1:
        raise InputError(f"knot vectors of length {len(uknots)}, {len(vknots)} do not fit "
                         f"{nu} x {nv} poles of degree ({p}, {q})", item=label)
    if not (np.all(np.isfinite(poles)) and np.all(np.isfinite(weights))):
        raise InputError("a pole or weight is not a finite number", item=label)
    if np.any(weights <= 0):
        i, j = np.argwhere(weights <= 0)[0]
        raise InputError(f"weight of pole ({i}, {j}) is {weights[i, j]:g}: weights must be positive",
                         item=label)
    if np.any(np.diff(uknots) < 0) or np.any(np.diff(vknots) < 0):
        raise InputError("knot vector is not non-decreasing", item=label)
    Pw = np.concatenate([poles * weights[..., None], weights[..., None]], axis=2)   # (nu, nv, 4)
    su, Cu = bspline_bezier_extraction(uknots, p)
    sv, Cv = bspline_bezier_extraction(vknots, q)
    iu = su[:, None] - p + np.arange(p + 1)[None, :]          # (nsu, p+1) pole rows of each span
    iv = sv[:, None] - q + np.arange(q + 1)[None, :]
    # local poles of every cell: (nsu, nsv, p+1, q+1, 4)
    local = Pw[iu[:, None, :, None], iv[None, :, None, :]]
    ctrl = np.einsum("xai,ybj,xyabc->xyjic", Cu, Cv, local)   # (nsu, nsv, q+1, p+1, 4)
    U0, U1 = uknots[p], uknots[len(uknots) - p - 1]
    V0, V1 = vknots[q], vknots[len(vknots) - q - 1]
    ub = np.append((uknots[su] - U0) / (U1 - U0), 1.0)
    vb = np.append((vknots[sv] - V0) / (V1 - V0), 1.0)
    ub[0], vb[0] = 0.0, 0.0
    ns_u, ns_v = len(su), len(sv)
    group = np.zeros((ns_u, ns_v), dtype=int)
    local_idx = np.arange(ns_u * ns_v).reshape(ns_u, ns_v)
    cells = BezierCells(ctrl.reshape(ns_u * ns_v, q + 1, p + 1, 4))
    return Patch(index, ub, vb, group, local_idx, [cells], name=label, knot_size=(U1 - U0, V1 - V0))
