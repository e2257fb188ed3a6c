"""Star points on an open boundary, for the T-spline kernel: the faces around them from
the Catmull-Clark limit of a local cage (OpenSubdiv's edge-and-corner rule), the rest from
the kernel.

A boundary vertex with three faces (a concave corner of the T-mesh) is an extraordinary
boundary vertex of Catmull-Clark under the edge-and-corner rule: the boundary curve runs
smoothly through it and the surface there is the limit of subdivision, which no tensor
B-spline gives. Where the star's neighbourhood (``RINGS`` rings of faces) has one knot
interval and no T-junctions, that limit is the reference (``cage.cage_model``). The
T-spline kernel builds the whole T-mesh with the star clamped as a concave corner
(``tsm.PATTERNS[3]``, every grip there the star's own): its functions reach only the two
rings of faces around the star, so on the third ring and beyond the kernel is the same
uniform B-spline as the cage's limit (the functions of the star's neighbours there use
only the knots on their own side). The cells of the first ``ZONE`` rings are then replaced
(``CageCells``) by the limit of a local cage of ``ZONE + 2`` rings, which is exact there
(a face's limit depends on its one-ring and their vertices' rules only). The two meet
along a line on which both are the same B-spline: C2 there, G1 at the star itself.

What is not yet taken is refused by name: boundary stars with four or more faces, and
boundary stars whose ``RINGS`` rings of faces have T-junctions, other knot intervals,
other irregular vertices or creases.
"""
from __future__ import annotations

import numpy as np

from .cells import _chain

#: rings of faces around a boundary star evaluated from its local cage
ZONE = 2
#: rings of faces that must be uniform and free of T-junctions and irregular vertices: the
#: zone, one ring more for the zone's own limit, and three for the kernel's knot vectors
#: that reach across the zone's edge
RINGS = 5
#: relative spread of knot intervals still read as uniform
UNIFORM_TOL = 1e-9


def rings(mesh, v: int, n: int) -> list[list[int]]:
    """The faces of T-mesh ``mesh`` within ``n`` rings of vertex v, ring by ring: ring 1 the
    faces at v, ring k + 1 the faces sharing a vertex with rings 1 .. k."""
    at = {}
    for f, loop in enumerate(mesh.faces):
        for w in loop:
            at.setdefault(int(w), set()).add(f)
    seen = set(at.get(v, ()))
    out = [sorted(seen)]
    for _ in range(n - 1):
        new = {g for f in out[-1] for w in mesh.faces[f] for g in at[int(w)]} - seen
        seen |= new
        out.append(sorted(new))
    return out


def check_neighbourhood(mesh, v: int, refuse) -> tuple[list[list[int]], float]:
    """The ``RINGS`` rings of faces around boundary star v and their common knot interval;
    ``refuse(message)`` raises the reader's error for anything the construction needs
    otherwise (T-junctions, other intervals, other irregular vertices)."""
    topo = mesh.topology
    rs = rings(mesh, v, RINGS)
    faces = [f for r in rs for f in r]
    d = np.concatenate([np.asarray(mesh.intervals[f], float) for f in faces])
    need = (f"a boundary star point needs its {RINGS} rings of faces free of T-junctions, other star "
            f"points and concave corners, with one knot interval")
    for f in faces:
        if len(mesh.faces[f]) != 4:
            refuse(f"{need}: {mesh.face_name(f)} has a T-junction")
    top = float(d.max())
    if not top > 0.0 or float(d.min()) < top * (1.0 - UNIFORM_TOL):
        refuse(f"{need}: its knot intervals run from {float(d.min()):g} to {top:g}")
    for w in sorted({int(x) for f in faces for x in mesh.faces[f]} - {v}):
        T, nf = int(topo.total[w]), len(topo.fan[w])
        if (T not in (1, 2) if topo.boundary[w] else T != 4) or nf != T:
            refuse(f"{need}: {mesh.vertex_name(w)} is not a regular vertex ({T} quarter turns)")
    return rs, top


class CageCells:
    """Cells of a kernel patch evaluated on a local Catmull-Clark cage: per cell, the cage
    face, and the linear map from the cell's (a, b) to that face's (s, t): (s, t) = A (a, b)
    + o. At ``star`` (the face's corner at the star, (s, t) in {0, 1}^2, or None) the
    limit normal is passed on."""

    kind = "cage"

    def __init__(self, model, face: list, A: list, o: list, star: list):
        self.model = model
        self.face = np.asarray(face, int)
        self.A = np.asarray(A, float).reshape(-1, 2, 2)
        self.o = np.asarray(o, float).reshape(-1, 2)
        self.star = [None if c is None else np.asarray(c, float) for c in star]

    def __len__(self) -> int:
        return len(self.face)

    def evaluate(self, idx: np.ndarray, a: np.ndarray, b: np.ndarray):
        A, o = self.A[idx], self.o[idx]
        s = np.clip(A[:, 0, 0] * a + A[:, 0, 1] * b + o[:, 0], 0.0, 1.0)
        t = np.clip(A[:, 1, 0] * a + A[:, 1, 1] * b + o[:, 1], 0.0, 1.0)
        sp = self.model.evaluate_faces(self.face[idx], s, t)
        Hst = np.zeros((6, 4, len(idx)))
        for k, arr in enumerate((sp.P, sp.Pu, sp.Pv, sp.Puu, sp.Puv, sp.Pvv)):
            Hst[k, :3] = arr.T
        Hst[0, 3] = 1.0
        H = _chain(Hst, A)
        at = np.zeros(len(idx), bool)
        for n, i in enumerate(idx):
            c = self.star[i]
            at[n] = c is not None and s[n] == c[0] and t[n] == c[1]
        return H, at, (np.asarray(sp.normal) if at.any() else None)


def override(model, zone: dict, local, star_corner: dict) -> None:
    """Replace the cells of the kernel ``model``'s faces in ``zone`` (T-mesh face -> local
    cage face) by the local cage model ``local`` (faces in the same (s, t) frame);
    ``star_corner[f]``: the (s, t) of the star in face f, if it is a corner of it. Corner
    nodes are evaluated again."""
    from .patch import CORNER_UV
    from .twalk import rot
    by_patch = {}
    for f, lf in zone.items():
        W, H = model.face_size[f]
        for p, (x0, x1, y0, y1), (q, tx, ty), (PW, PH) in model.face_pieces[f]:
            by_patch.setdefault(p, []).append((f, lf, W, H, (x0, x1, y0, y1), (q, tx, ty), (PW, PH)))
    for p, items in by_patch.items():
        patch = model.patches[p]
        ub, vb = patch.ubreaks, patch.vbreaks
        g = len(patch.groups)
        face, As, os_, star = [], [], [], []
        group = patch.cell_group.copy()
        local_ = patch.cell_local.copy()
        for f, lf, W, H, (x0, x1, y0, y1), (q, tx, ty), (PW, PH) in items:
            # the piece's rectangle in the patch's (u, v)
            cx, cy = rot(q, np.array([x0, x1, x1, x0]), np.array([y0, y0, y1, y1]))
            u = (np.asarray(cx) + tx) / PW
            v = (np.asarray(cy) + ty) / PH
            tol = 1e-9
            cols = np.nonzero((ub[:-1] >= u.min() - tol) & (ub[1:] <= u.max() + tol))[0]
            rws = np.nonzero((vb[:-1] >= v.min() - tol) & (vb[1:] <= v.max() + tol))[0]
            # patch (u, v) -> face (x, y): rotate back by -q
            for i in cols:
                for j in rws:
                    du, dv = ub[i + 1] - ub[i], vb[j + 1] - vb[j]
                    # (px, py) = (u PW - tx, v PH - ty); (x, y) = rot(-q, px, py); (s, t) = (x / W, y / H)
                    def st(uu, vv):
                        x, y = rot(-q % 4, uu * PW - tx, vv * PH - ty)
                        return np.array([x / W, y / H])
                    o = st(ub[i], vb[j])
                    Acol = np.column_stack([st(ub[i + 1], vb[j]) - o, st(ub[i], vb[j + 1]) - o])
                    local_[i, j] = len(face)
                    group[i, j] = g
                    face.append(lf)
                    As.append(Acol)
                    os_.append(o)
                    star.append(star_corner.get(f))
        patch.groups.append(CageCells(local, face, As, os_, star))
        patch.cell_group = group
        patch.cell_local = local_
    for patch in model.patches:
        model.node_points[patch.corner_nodes] = patch.evaluate(CORNER_UV[:, 0], CORNER_UV[:, 1]).P
