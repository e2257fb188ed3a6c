"""Star points on an open boundary, for the T-spline kernel: the faces around them from
the Catmull-Clark limit of a local cage (OpenSubdiv's edge-and-corner rule), the rest from
the kernel. Used by the Fusion ``.tsm`` reader, native ``.tspl`` t-splines with the
``edge-and-corner`` boundary and GrapeTec-style ``.tsm`` files (``tsm_fusion.kernel_model``).

A boundary vertex with three faces or more is an extraordinary boundary vertex of
Catmull-Clark under the edge-and-corner rule (valence 4 and more): the boundary curve runs
smoothly through it and the surface there is the limit of subdivision, which no tensor
B-spline gives. Where the star's local cage (``cage_rings`` rings of faces) has one knot
interval, no T-junctions and no other irregular vertex, that limit is the reference
(``cage.cage_model``):

* The kernel builds the T-mesh with the star clamped as a concave corner (``tsm.PATTERNS[3]``,
  every grip there the star's own). With four faces or more faces at both ends of its fan
  are left out of the kernel's T-mesh first (``notch``), so that the middle three remain;
  the left-out faces' corners become convex and concave corners of the kernel's boundary,
  clamped alike, so that its patches end on their sides. From six faces on, a spoke between
  two left-out faces is a straight boundary vertex of the kernel in the middle of a patch's
  side: that patch is split there, the line carried on across its neighbours to the
  boundary (``hole_sides``, ``split_at``), so that the patches stay conforming.
* The kernel's functions that see the star or the notches reach only ``zone_rings`` rings
  of faces (measured on uniform stars: 2 at three faces, 3 at four, 4 at five to ten, where
  the notches' sides overlap in knot space); beyond, the kernel is the same uniform
  B-spline as the limit (the functions there use only the knots on their own side).
* The cells of the zone's faces are replaced (``CageCells``) by the limit of a local cage
  of two rings more, which is exact there (a face's limit depends on its one-ring and their
  vertices' rules only); each left-out face is a patch of its own on the local cage, linked
  to the kernel's patches along its inner sides (``tsm_fusion.join_across_creases``). Zone
  and kernel meet along a line on which both are the same B-spline: C2 there, G1 at the
  star itself. T-junctions and other intervals beyond the local cage are taken where this
  still holds, which ``check_seams`` measures on every shared edge (a cubic's piece next
  to the seam does not see knots two intervals beyond it).

What is not taken is refused by name: boundary stars whose local cage has T-junctions,
other knot intervals or other irregular vertices, a kernel that does not meet the cage
(``check_seams``), a split line that runs into a patch without a cell break there, and
bodies so small that a left-out face has a corner on no other face. Creases are cut first
(``tsm_fusion.cut_along_creases``): within the rings they are boundaries of the local cage,
OpenSubdiv's infinitely sharp crease.
Model faces: the kernel's T-mesh faces, then the left-out ones (``model.notch_faces``: T-mesh
face of the file -> model face).
"""
from __future__ import annotations

import numpy as np

from .cells import _chain

#: rings of faces around a boundary star of three faces evaluated from its local cage; four
#: faces one more, five or more two more (the kernel is cut nearer, see ``notch``)
ZONE = 2
#: relative spread of knot intervals still read as uniform
UNIFORM_TOL = 1e-9


def zone_rings(faces: int) -> int:
    """Rings of faces around a boundary star of ``faces`` faces replaced by its local cage:
    as far as the kernel's surface differs from the limit without it (measured on uniform
    stars: two rings at three faces, three at four, four at five to twelve: with a local cage
    of three rings it is off by 1e-2 of the size in the third and fourth ring, with four
    exact to 1e-16). From five faces on, faces at both ends are left out: in the kernel's
    knot space the faces beyond them then lie in the same quadrant behind the star (its
    clamped corner has no size), and functions whose boxes reach across it are found on the
    other side too, one ring further out."""
    return {3: ZONE, 4: ZONE + 1}.get(faces, ZONE + 2)


def cage_rings(faces: int) -> int:
    """Rings that must be uniform and free of T-junctions and irregular vertices: the local
    cage's, the zone and two more (a face's limit depends on its one-ring and their
    vertices' rules). Beyond them T-junctions and other intervals are taken where the
    kernel still meets the zone's limit (``check_seams``: a cubic's piece next to the seam
    does not see the knots two intervals beyond it)."""
    return zone_rings(faces) + 2


def need_rings(faces: int) -> int:
    """Rings within which the kernel's grips must be those of the edge-and-corner rule
    (``tsm_fusion.keep_file_grips``): the local cage's and one more, whose functions reach
    across the zone's edge."""
    return zone_rings(faces) + 3


def notch(mesh, v: int) -> list[int]:
    """The faces at boundary star v left out of the kernel's T-mesh so that v keeps three
    faces (a concave corner the kernel clamps): none for three faces, the first for four,
    the first and the last for five, and from six on the first (T - 2) // 2 and the last
    (T - 3) // 2 (the middle three kept). Their outer corners become convex and concave
    corners of the kernel's boundary, so that its patches end on their sides; a spoke
    between two left-out faces becomes a straight boundary vertex in the middle of a kernel
    patch's side, where that patch is split (``hole_sides``, ``split_at``)."""
    fan = [f for f, _ in mesh.topology.fan[v]]
    m = len(fan) - 3
    return fan[:(m + 1) // 2] + fan[len(fan) - m // 2:]


def without_faces(mesh, drop):
    """The T-mesh ``mesh`` without the faces ``drop`` (same vertices; every vertex must keep
    a face), and the new index of every face (-1 for the dropped ones)."""
    from .tmesh import TMesh
    keep = [f for f in range(len(mesh.faces)) if f not in set(drop)]
    index = np.full(len(mesh.faces), -1)
    index[keep] = np.arange(len(keep))
    pick = lambda xs: None if xs is None else [xs[f] for f in keep]      # noqa: E731
    out = TMesh(np.zeros((mesh.n_vertices, 3)), None, [list(mesh.faces[f]) for f in keep],
                [list(mesh.corners[f]) for f in keep], [list(mesh.intervals[f]) for f in keep],
                source=mesh.source, face_lines=pick(mesh.face_lines), vertex_lines=mesh.vertex_lines,
                vertex_labels=mesh.vertex_labels, face_labels=pick(mesh.face_labels))
    out.validate()
    return out, index


def vertex_faces(mesh) -> dict:
    """Vertex -> the set of faces of T-mesh ``mesh`` at it."""
    at = {}
    for f, loop in enumerate(mesh.faces):
        for w in loop:
            at.setdefault(int(w), set()).add(f)
    return at


def rings(mesh, vertices, n: int, at: dict | None = None) -> list[list[int]]:
    """The faces of T-mesh ``mesh`` within ``n`` rings of a vertex or a set of vertices, ring
    by ring: ring 1 the faces at them, ring k + 1 the faces sharing a vertex with rings
    1 .. k. ``at``: :func:`vertex_faces` of the mesh, when the caller has it."""
    at = vertex_faces(mesh) if at is None else at
    vertices = [vertices] if np.ndim(vertices) == 0 else vertices
    seen = {f for v in vertices for f in at.get(int(v), ())}
    out = [sorted(seen)]
    for _ in range(n - 1):
        new = {g for f in out[-1] for w in mesh.faces[f] for g in at[int(w)]} - seen
        seen |= new
        out.append(sorted(new))
    return out


def check_neighbourhood(mesh, v: int, refuse) -> tuple[list[list[int]], float]:
    """The ``cage_rings`` rings of faces around boundary star v and their common knot interval;
    ``refuse(message)`` raises the reader's error for anything the construction needs
    otherwise (T-junctions, other intervals, other irregular vertices)."""
    topo = mesh.topology
    n = cage_rings(len(topo.fan[v]))
    rs = rings(mesh, v, n)
    faces = [f for r in rs for f in r]
    d = np.concatenate([np.asarray(mesh.intervals[f], float) for f in faces])
    need = (f"a boundary star point of {len(topo.fan[v])} faces needs its {n} rings of faces (its local "
            f"Catmull-Clark cage) free of T-junctions, other star points and concave corners, with one "
            f"knot interval")
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
        # the star's (s, t) per cell, NaN where the star is not a corner of the cell's face
        self._star = np.array([(np.nan, np.nan) if c is None else c for c in self.star], float).reshape(-1, 2)

    def __len__(self) -> int:
        return len(self.face)

    def evaluate(self, idx: np.ndarray, a: np.ndarray, b: np.ndarray):
        A, o = self.A[idx], self.o[idx]
        s = np.clip(A[:, 0, 0] * a + A[:, 0, 1] * b + o[:, 0], 0.0, 1.0)
        t = np.clip(A[:, 1, 0] * a + A[:, 1, 1] * b + o[:, 1], 0.0, 1.0)
        # at the star itself (to the rounding of the cell-to-face map): exactly there, where
        # the limit normal is known
        c = self._star[idx]
        at = (np.abs(s - c[:, 0]) <= 1e-13) & (np.abs(t - c[:, 1]) <= 1e-13)
        s = np.where(at, c[:, 0], s)
        t = np.where(at, c[:, 1], t)
        sp = self.model.evaluate_faces(self.face[idx], s, t)
        Hst = np.zeros((6, 4, len(idx)))
        for k, arr in enumerate((sp.P, sp.Pu, sp.Pv, sp.Puu, sp.Puv, sp.Pvv)):
            Hst[k, :3] = arr.T
        Hst[0, 3] = 1.0
        H = _chain(Hst, A)
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


def attach(model, old, kernel_face, stars: dict, G: np.ndarray, scale: float) -> dict:
    """Boundary stars into the kernel ``model`` of T-mesh ``old`` (built without the notch
    faces: ``kernel_face[f]`` is old face f's index in the model, -1 if left out): per star
    (``stars[v]`` = its rings of faces), a local cage of ``zone_rings + 2`` rings (points
    ``G`` (x, y, z, w) in file units, times ``scale``), whose limit replaces the kernel on the
    zone's faces and makes one patch of each notch face (corner nodes of their own: the
    caller links them, ``tsm_fusion.join_across_creases``). Returns old face -> model face
    for the notch faces (numbered after the model's T-mesh faces), and per star (faces,
    limit point) for ``star_points``."""
    from .cage import Cage, cage_model
    from .patch import CORNER_UV, Patch
    from .quadmesh import QuadMesh
    added, limits = {}, {}
    for v, rs in stars.items():
        T = len(old.topology.fan[v])
        z = zone_rings(T)
        faces = [f for r_ in rs[:z + 2] for f in r_]
        verts = sorted({int(w) for f in faces for w in old.faces[f]})
        new = {w: i for i, w in enumerate(verts)}
        loops = np.array([[new[int(w)] for w in old.faces[f]] for f in faces])
        cage = Cage(QuadMesh(loops, len(verts), "edge-and-corner", old.source),
                    G[verts, :3] * scale, G[verts, 3], {"interpolateboundary": "edge-and-corner"})
        local = cage_model(cage, "boundary star")
        inner = sum(len(r_) for r_ in rs[:z])
        zone, corner = {}, {}
        for i, f in enumerate(faces[:inner]):
            loop = [int(w) for w in old.faces[f]]
            if loop[int(old.corners[f][0])] != loop[0]:
                raise AssertionError("face frames")
            at = CORNER_UV[loop.index(v)] if v in loop else None
            k = int(kernel_face[f])
            if k >= 0:
                zone[k] = i
                if at is not None:
                    corner[k] = at
                continue
            # a notch face: one patch, one cell, the face's own (s, t)
            d = float(np.asarray(old.intervals[f], float).max())
            p = len(model.patches)
            patch = Patch(p, [0.0, 1.0], [0.0, 1.0], np.zeros((1, 1), int), np.zeros((1, 1), int),
                          [CageCells(local, [i], [np.eye(2)], [np.zeros(2)], [at])], knot_size=(d, d))
            n0 = len(model.node_points)
            patch.corner_nodes = np.arange(n0, n0 + 4)
            model.node_points = np.vstack([model.node_points, patch.evaluate(CORNER_UV[:, 0], CORNER_UV[:, 1]).P])
            model.node_keys.extend(("notch", f, c) for c in range(4))
            model.patches.append(patch)
            added[f] = len(model.face_pieces)
            model.face_pieces.append([(p, (0.0, d, 0.0, d), (0, 0.0, 0.0), (d, d))])
            model.face_size.append((d, d))
        override(model, zone, local, corner)
        f = next(f for f in faces if v in [int(w) for w in old.faces[f]])
        at = CORNER_UV[[int(w) for w in old.faces[f]].index(v)]
        limits[v] = (T, local.evaluate_faces([faces.index(f)], [at[0]], [at[1]]).P[0])
    return added, limits


def check_seams(model, old, kernel_face, stars: dict, refuse, samples: int = 5) -> None:
    """Where each star's zone (its faces from the local cage) meets the kernel's faces of the
    next ring: the same points (to 1e-9 of the model size) and normals (sine of the angle
    below 1e-9) at ``samples`` points of every shared edge, else ``refuse(v, message)``. On
    uniform knots they are the same B-spline there; T-junctions or other intervals beyond
    the local cage reach the seam when they are nearer than the kernel's functions there
    see."""
    from .patch import CORNER_UV
    P = model.node_points
    size = max(float(np.ptp(P, axis=0).max()), 1e-300)
    tau = np.linspace(0.0, 1.0, samples)
    for v, rs in stars.items():
        z = zone_rings(len(old.topology.fan[v]))
        inner = {f for r_ in rs[:z] for f in r_}
        fa, sa, ta, fb, sb, tb = [], [], [], [], [], []
        for g in rs[z]:
            loop = [int(w) for w in old.faces[g]]
            for i in range(4):
                a, b = loop[i], loop[(i + 1) % 4]
                f, _ = old.topology.edge_at.get((b, a), (None, None))
                if f is None or f not in inner or kernel_face[f] < 0:
                    continue
                other = [int(w) for w in old.faces[f]]
                for face, lp, out_f, out_s, out_t in ((g, loop, fb, sb, tb), (f, other, fa, sa, ta)):
                    c0, c1 = CORNER_UV[lp.index(a)], CORNER_UV[lp.index(b)]
                    st = c0[None, :] * (1 - tau)[:, None] + c1[None, :] * tau[:, None]
                    out_f.extend([int(kernel_face[face])] * samples)
                    out_s.extend(st[:, 0])
                    out_t.extend(st[:, 1])
        if not fa:
            continue
        A, B = model.evaluate_faces(fa, sa, ta), model.evaluate_faces(fb, sb, tb)
        gap = float(np.linalg.norm(A.P - B.P, axis=1).max()) / size
        sine = float(np.linalg.norm(np.cross(A.normal, B.normal), axis=1).max())
        if gap > 1e-9 or sine > 1e-9:
            refuse(v, f"the T-spline does not meet its local Catmull-Clark cage ({cage_rings(len(old.topology.fan[v]))} "
                      f"rings) where the cage's faces end after {z} rings (gap {gap:.2g} of the model size, "
                      f"normals {np.degrees(np.arcsin(min(sine, 1.0))):.2g} degrees apart): T-junctions or other "
                      f"knot intervals just beyond the cage reach it; refine the T-mesh there")


def star_points(model, limits: dict) -> None:
    """Each boundary star as the model's extraordinary point (boundary, valence its number of
    faces), at the node at its limit point (``limits[v]`` = (faces, point); the kernel's
    patch lines start on the star's clamped ring, not at the vertex)."""
    from .model import ExtraordinaryPoint
    pts = model.node_points
    size = max(float(np.ptp(pts, axis=0).max()), 1e-300)
    for v, (faces, at) in limits.items():
        gap = np.linalg.norm(pts - at, axis=1)
        n = int(np.argmin(gap))
        if gap[n] <= 1e-9 * size:
            model.extraordinary.append(ExtraordinaryPoint(n, faces, pts[n], True))


def hole_sides(model, kernel, verts) -> list:
    """The kernel's straight boundary vertices among ``verts`` (the corners of the faces it
    left out) that leaving them out made
    (the spokes between two left-out faces of a star of six or more faces): each lies in the
    middle of a side of a kernel patch, where two left-out faces' patches meet it. Returns
    per vertex (patch, axis, knot position along that axis in the patch's frame)."""
    from .patch import CORNER_UV
    from .twalk import rot
    topo = kernel.topology
    out = []
    for w in sorted(verts):
        if not topo.boundary[w] or int(topo.total[w]) != 2:
            continue
        f, _ = topo.fan[w][0]
        loop, cs = [int(x) for x in kernel.faces[f]], list(kernel.corners[f])
        k = next(k for k in range(4) if loop[cs[k]] == w)
        W, H = model.face_size[f]
        x, y = CORNER_UV[k] * (W, H)
        for p, (x0, x1, y0, y1), (q, tx, ty), (PW, PH) in model.face_pieces[f]:
            if x0 - 1e-9 * W <= x <= x1 + 1e-9 * W and y0 - 1e-9 * H <= y <= y1 + 1e-9 * H:
                px, py = rot(q, x, y)
                X, Y = float(px + tx), float(py + ty)
                on_v = min(abs(Y), abs(Y - PH)) <= 1e-9 * PH       # on the bottom or top side
                on_u = min(abs(X), abs(X - PW)) <= 1e-9 * PW
                if on_v and not on_u:
                    out.append((p, 0, X))
                elif on_u and not on_v:
                    out.append((p, 1, Y))
                break
    return out


def split_patch(model, p: int, axis: int, at: float) -> int:
    """Split patch p of a T-spline model along its cell break at knot position ``at`` along
    ``axis`` (0: u, 1: v; the patch's frame): p keeps the part below, a new patch (returned)
    takes the rest. Cells, face pieces and corner nodes follow; the neighbours of the split
    sides are unlinked (``tsm_fusion.join_across_creases`` links them again, splitting
    neighbours is the caller's)."""
    from .patch import CORNER_UV, Patch
    from .twalk import rot
    patch = model.patches[p]
    K = patch.knot_size[axis]
    br = patch.ubreaks if axis == 0 else patch.vbreaks
    k = int(np.argmin(np.abs(br * K - at)))
    if not 0 < k < len(br) - 1 or abs(br[k] * K - at) > 1e-9 * K:
        raise ValueError(f"{patch.name} has no cell break there (a T-junction ends the knot line)")
    c = br[k]
    lo, hi = (slice(None, k), slice(k, None))
    sl = (lambda s: (s, slice(None))) if axis == 0 else (lambda s: (slice(None), s))
    size_a = list(patch.knot_size)
    size_b = list(patch.knot_size)
    size_a[axis], size_b[axis] = c * K, (1.0 - c) * K
    br_a, br_b = br[:k + 1] / c, (br[k:] - c) / (1.0 - c)
    new = len(model.patches)
    b = Patch(new, br_b if axis == 0 else patch.ubreaks, patch.vbreaks if axis == 0 else br_b,
              patch.cell_group[sl(hi)], patch.cell_local[sl(hi)], patch.groups, knot_size=size_b)
    patch.cell_group, patch.cell_local = patch.cell_group[sl(lo)].copy(), patch.cell_local[sl(lo)].copy()
    if axis == 0:
        patch.ubreaks = br_a
    else:
        patch.vbreaks = br_a
    patch.knot_size = tuple(size_a)
    b.cell_group, b.cell_local = b.cell_group.copy(), b.cell_local.copy()
    # sides: the split line is p's side 1 (axis u) or 2 (axis v) and b's side 3 or 0; p's
    # sides along the split axis and the far side go to b or are cut in two
    far, near = (1, 3) if axis == 0 else (2, 0)
    along = (0, 2) if axis == 0 else (1, 3)
    for e in (far, *along):
        nb = patch.neighbours[e]
        if nb is not None:
            model.patches[nb.patch].neighbours[nb.edge] = None
        patch.neighbours[e] = None
    model.patches.append(b)
    # corner nodes: p's corners beyond the split are b's; the two new ones are new nodes
    cn = patch.corner_nodes.copy()
    n0 = len(model.node_points)
    b.corner_nodes = cn.copy()
    if axis == 0:                      # corners 1, 2 move to b; new nodes at p's 1, 2 = b's 0, 3
        patch.corner_nodes = np.array([cn[0], n0, n0 + 1, cn[3]])
        b.corner_nodes = np.array([n0, cn[1], cn[2], n0 + 1])
    else:                              # corners 2, 3 move to b; new nodes at p's 3, 2 = b's 0, 1
        patch.corner_nodes = np.array([cn[0], cn[1], n0 + 1, n0])
        b.corner_nodes = np.array([n0, n0 + 1, cn[2], cn[3]])
    ends = patch.evaluate(*CORNER_UV[[1, 2]].T).P if axis == 0 else patch.evaluate(*CORNER_UV[[3, 2]].T).P
    model.node_points = np.vstack([model.node_points, ends])
    if getattr(model, "node_keys", None) is not None:
        model.node_keys.extend(("split", p, axis, at, m) for m in range(2))
    # face pieces: in p's frame below the line, in b's (shifted) beyond it, cut where they cross
    for f, pieces in enumerate(model.face_pieces):
        out = []
        for piece in pieces:
            if piece[0] != p:
                out.append(piece)
                continue
            _, (x0, x1, y0, y1), (q, tx, ty), _ = piece
            cx, cy = rot(q, np.array([x0, x1]), np.array([y0, y1]))
            box = np.array([np.sort(np.asarray(cx, float) + tx), np.sort(np.asarray(cy, float) + ty)])
            for part, (a0, a1) in ((0, (box[axis, 0], min(box[axis, 1], c * K))),
                                   (1, (max(box[axis, 0], c * K), box[axis, 1]))):
                if a1 - a0 <= 1e-9 * K:
                    continue
                sub = box.copy()
                sub[axis] = (a0, a1)
                # the part back in the face's frame (the inverse quarter turns)
                fx, fy = rot((4 - q) % 4, sub[0] - tx, sub[1] - ty)
                rect = (float(np.min(fx)), float(np.max(fx)), float(np.min(fy)), float(np.max(fy)))
                if part == 0:
                    out.append((p, rect, (q, tx, ty), tuple(size_a)))
                else:
                    shift = (c * K, 0.0) if axis == 0 else (0.0, c * K)
                    out.append((new, rect, (q, tx - shift[0], ty - shift[1]), tuple(size_b)))
        model.face_pieces[f] = out
    return new


def split_at(model, sides: list, refuse) -> None:
    """Split the kernel's patches at ``hole_sides``, each line carried on across every patch
    side its far end lands inside of (at a cell break there) until it ends on a corner or
    the boundary, so that the patches stay conforming; ``refuse(why)`` raises the reader's
    error where a patch the line reaches has no cell break on it. The split sides are
    linked again by ``tsm_fusion.join_across_creases``."""
    P = model.node_points
    tol = 1e-9 * max(float(np.ptp(P, axis=0).max()), 1e-300)
    todo = list(sides)
    budget = 4 * len(model.patches) + 4
    while todo:
        budget -= 1
        if budget < 0:
            refuse("the patch lines from its spokes do not reach the boundary")
        p, axis, at = todo.pop()
        patch = model.patches[p]
        x = at / patch.knot_size[axis]
        uv = np.array([[x, 0.0], [x, 1.0]]) if axis == 0 else np.array([[0.0, x], [1.0, x]])
        ends = patch.evaluate(uv[:, 0], uv[:, 1]).P
        try:
            split_patch(model, p, axis, at)
        except ValueError as exc:
            refuse(f"the patch line from a spoke between two left-out faces runs into {exc}")
        for X in ends:
            hit = _side_through(model, X, tol)
            if hit is not None:
                todo.append(hit)


def _side_through(model, X, tol):
    """(patch, axis, knot position) of a patch side that has the point X inside it, at one
    of its cell breaks (where a split line ended: that patch is split there too), or None."""
    for q in model.patches:
        for axis, br in ((0, q.ubreaks), (1, q.vbreaks)):
            inner = br[1:-1]
            if not len(inner):
                continue
            for c in (0.0, 1.0):
                uu, vv = (inner, np.full(len(inner), c)) if axis == 0 else (np.full(len(inner), c), inner)
                gap = np.linalg.norm(q.evaluate(uu, vv).P - X, axis=1)
                k = int(np.argmin(gap))
                if gap[k] <= tol:
                    return q.index, axis, float(inner[k] * q.knot_size[axis])
    return None
