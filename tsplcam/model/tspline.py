"""T-spline surfaces: the surface of a T-mesh as patches of Bezier cells (and star cells).

The surface of a T-mesh (``tmesh.py``) is S = sum w_i B_i P_i / sum w_i B_i
(docs/method.md section 1.1; Sederberg et al. 2003, "T-splines and T-NURCCs").
``tspline_model`` builds it in steps, each in the module named for it:

1. ``knots.check_clamped``: boundaries need zero outer knot intervals;
2. ``extraordinary.find_extraordinary``: the star points (extraordinary points) and the
   faces around them (``stars.find_stars``). Stars closer than three edges: on a T-mesh that
   is a Catmull-Clark cage the whole surface goes to the subdivision path (``cage.py``);
   otherwise the faces within two rings of them come from a local cage's limit and the
   rest from these steps (``close_stars.py``, where their five rings are a uniform cage);
3. ``knots.local_knots``: every blending function's local knot vectors, by ray casting on
   the mesh (``twalk.py`` walks the rays);
4. ``stars.build_zone``: per star, the T-NURCC construction on its two rings of faces (the
   functions of the star and its neighbours by refinement to the regular level);
5. ``blending.supports``: the faces each other blending function is non-zero on;
6. ``decompose.decompose_tmesh``: four-sided patches between lines from extraordinary
   points and boundary corners (the same decomposition as for cages);
7. Bezier extraction (here): every patch's cells are cut by the knot lines inside it and
   each piece of each function becomes Bernstein coefficients (exact: a cubic per cell);
   cells on a star's first faces add its subdivided part (``stars.StarCells``).

API: ``tspline_model(mesh)`` -> ``TSplineModel`` (a ``Model``; ``evaluate_faces`` in T-mesh
face coordinates), ``knots.knot_vectors(mesh)`` (every vertex's local knot vectors),
``homogeneous_parts(patch)`` (sum w B P and sum w B without the division, for checks).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .blending import bezier_1d_many, supports
from .cells import BezierCells, _chain
from .decompose import Decomposition, decompose_tmesh, region_links
from .diffgeom import SurfacePoints
from .extraordinary import find_extraordinary
from .knots import LocalKnots, check_clamped, local_knots
from .model import ExtraordinaryPoint, Model, link_patches
from .patch import CORNER_UV, Patch
from .stars import StarCells, StarLevels, StarsTooClose, SumCells, build_zone, direct_functions, find_stars
from .tmesh import TMesh
from .twalk import Walker, apply, compose, inverse, map_knots, rot


class TSplineModel(Model):
    """A T-spline model: patches plus where every T-mesh face lies in them."""

    #: per T-mesh face, its pieces: (patch, (x0, x1, y0, y1) in the face's frame, map (q, tx,
    #: ty) from the face's frame to the patch's in knot units, patch size (PW, PH))
    face_pieces: list
    #: per T-mesh face, its size (W, H) in knot units
    face_size: list
    #: the node keys (``decompose.node_key``) of the model's nodes, in node order
    node_keys: list

    def evaluate_faces(self, face, s, t) -> SurfacePoints:
        """Evaluate in T-mesh faces' own coordinates: (0,0) at the face's corner 0, s toward
        corner 1, t toward corner 3, both scaled to [0, 1]. Returns P, Ps, Pt, ... in the
        fields P, Pu, Pv, ..."""
        face, s, t = np.broadcast_arrays(np.asarray(face, int).reshape(-1),
                                         np.asarray(s, float).reshape(-1), np.asarray(t, float).reshape(-1))
        n = len(face)
        H = np.empty((6, 3, n))
        normal = np.empty((n, 3))
        J = np.empty((n, 2, 2))
        patch = np.full(n, -1)
        u = np.empty(n)
        v = np.empty(n)
        # the points of every face (ascending, as np.nonzero(face == f)) from one stable sort
        order = np.argsort(face, kind="stable")
        faces, first = np.unique(face[order], return_index=True)
        for f, rows in zip(faces, np.split(order, first[1:])):
            if f < 0 or f >= len(self.face_pieces):
                raise InputError(f"face index {f} out of range", path=self.source)
            W, Hh = self.face_size[f]
            if W <= 0 or Hh <= 0:
                raise InputError(f"{self.control.face_name(int(f))} has zero size in knot space: "
                                 f"it is not part of the surface", path=self.source)
            x, y = s[rows] * W, t[rows] * Hh
            for p, (x0, x1, y0, y1), (q, tx, ty), (PW, PH) in self.face_pieces[f]:
                tolx, toly = 1e-12 * W, 1e-12 * Hh
                inside = (x >= x0 - tolx) & (x <= x1 + tolx) & (y >= y0 - toly) & (y <= y1 + toly) & (patch[rows] < 0)
                sel = rows[inside]
                if not len(sel):
                    continue
                px, py = rot(q, x[inside], y[inside])
                u[sel] = np.clip((px + tx) / PW, 0.0, 1.0)
                v[sel] = np.clip((py + ty) / PH, 0.0, 1.0)
                patch[sel] = p
                R = np.array([rot(q, 1.0, 0.0), rot(q, 0.0, 1.0)]).T         # columns: images of ex, ey
                J[sel] = (np.diag([1.0 / PW, 1.0 / PH]) @ R @ np.diag([W, Hh]))[None]
        if np.any(patch < 0):
            raise InputError("a face point lies outside every patch", path=self.source)
        for p in np.unique(patch):
            sel = np.nonzero(patch == p)[0]
            sp_ = self.patches[p].evaluate(u[sel], v[sel])
            for k, arr in enumerate((sp_.P, sp_.Pu, sp_.Pv, sp_.Puu, sp_.Puv, sp_.Pvv)):
                H[k][:, sel] = arr.T
            normal[sel] = sp_.normal
        H = _chain(H, J).transpose(0, 2, 1)
        return SurfacePoints(H[0], H[1], H[2], H[3], H[4], H[5], s, t, None, normal)


def homogeneous_parts(patch: Patch) -> tuple[Patch, Patch]:
    """Two polynomial patches over a T-spline patch's Bezier cells, without the rational
    division: the first evaluates to sum w_i B_i P_i, the second to (sum w_i B_i, 0, 0).
    With unit weights the second is the sum of the blending functions (partition of unity
    checks) and the first their combination of the points (linear precision checks)."""
    out = []
    for part in ("numerator", "weight"):
        groups = []
        for g in patch.groups:
            if not isinstance(g, BezierCells):
                raise InputError("homogeneous parts exist for Bezier cells only (this patch has "
                                 "extraordinary cells)", item=patch.name)
            c = g.ctrl.copy()
            if part == "weight":
                c[..., 0] = c[..., 3]
                c[..., 1:3] = 0.0
            c[..., 3] = 1.0
            groups.append(BezierCells(c))
        out.append(Patch(patch.index, patch.ubreaks, patch.vbreaks, patch.cell_group, patch.cell_local,
                         groups, name=f"{patch.name} ({part})", knot_size=patch.knot_size))
    return out[0], out[1]


def tspline_model(mesh: TMesh, name: str | None = None, subdivide_at=()) -> TSplineModel:
    """The surface of a T-mesh as patches over Bezier cells (and subdivided cells next to star
    points). ``subdivide_at``: regular interior vertices evaluated by the star construction
    too (valence 4; it must give the same surface: a check of the construction)."""
    if mesh.topology_built:
        mesh.validate()               # points and weights may have changed since the topology
    walker = Walker(mesh)             # (a mesh without one is validated as it is built)
    Pw = mesh.homogeneous()
    check_clamped(mesh)
    try:
        ep = find_extraordinary(mesh, walker)
    except StarsTooClose:
        cage = _as_cage(mesh)
        if cage is None:
            from .close_stars import close_star_model
            return close_star_model(mesh, walker, name)
        return _cage_tspline(mesh, cage, name)
    knots = local_knots(walker, ep.interval)
    stars = dict(ep.stars)
    if subdivide_at:
        stars = find_stars(walker, extra=set(subdivide_at))
    zones = [build_zone(walker, v, star, knots, Pw) for v, star in stars.items()]
    near = _zone_faces(zones)
    support = supports(walker, knots, set(stars), near)
    dec = decompose_tmesh(walker)
    patches, face_pieces = _extract(walker, dec, knots, support, zones, Pw)
    return _assemble(walker, dec, patches, face_pieces, ep.interval, name)


def _as_cage(mesh: TMesh):
    """The T-mesh as a Catmull-Clark cage when it is one (Sederberg et al. 2003): closed, no
    T-junctions, one knot interval everywhere; None otherwise."""
    from .cage import Cage
    from .quadmesh import QuadMesh
    topo = mesh.topology
    if any(len(f) != 4 for f in mesh.faces) or any((b, a) not in topo.edge_at for a, b in topo.edge_at):
        return None
    d = np.concatenate(mesh.intervals)
    if d.min() <= topo.tol or d.max() - d.min() > 1e-12 * d.max():
        return None
    return Cage(QuadMesh(np.array([[int(x) for x in f] for f in mesh.faces]), mesh.n_vertices), mesh.points,
                mesh.weights)


def _cage_tspline(mesh: TMesh, cage, name):
    """Star points closer than the T-NURCC construction takes (``stars.py``), on a T-mesh that is
    a Catmull-Clark cage: its limit surface by the subdivision path (``cage.py``, which takes
    extraordinary points two edges apart), the T-mesh kept as the model's control mesh."""
    from .cage import cage_model
    model = cage_model(cage, name or mesh.name)
    model.kind = "t-spline"
    model.source = mesh.source
    model.control = mesh
    return model


def _zone_faces(zones: list) -> dict:
    """Per face of a star's two rings: (star, sector, which neighbours' functions may spread
    through it): a spoke vertex's through the two sectors beside its spoke, a diagonal
    vertex's through its own sector and the two beside it."""
    out = {}
    for z_i, z in enumerate(zones):
        n = z.n
        for g, (j, _) in z.chart.items():
            ok = out.setdefault(g, (z_i, j, {}))[2]
            for k in range(n):
                ok.setdefault(z.spokes[k], set()).update({j} if j in ((k - 1) % n, k) else set())
                ok.setdefault(z.diags[k], set()).update({j} if j in ((k - 1) % n, k, (k + 1) % n) else set())
    # supports() asks: is the face's sector among the vertex's sectors
    return {g: (z_i, j, {A: ({j} if sec else set()) for A, sec in ok.items()}) for g, (z_i, j, ok) in out.items()}


def _extract(walker: Walker, dec: Decomposition, knots: LocalKnots, support: list, zones: list,
             Pw: np.ndarray, replaced=frozenset()) -> tuple[list[Patch], list]:
    """Bezier extraction: every region of ``dec`` becomes a patch whose cells are cut by the
    knot lines of the blending functions on its faces (``support``; on the two rings of
    faces around a star, the plain B-splines of its construction in place of its W0
    functions), each cell's Bernstein coefficients exact; on a star's first faces every cell
    adds the star's subdivided part (``stars.StarCells``). ``replaced``: faces whose cells
    the caller replaces (``close_stars.py``: not checked here). Returns the patches (region r
    is patch r) and every face's pieces in them (``TSplineModel.face_pieces``)."""
    mesh, topo, tol = walker.mesh, walker.topo, walker.tol
    levels = [StarLevels(z) for z in zones]
    direct, excluded, first = {}, {}, {}
    for z_i, z in enumerate(zones):
        for g, rows in direct_functions(z, walker).items():
            direct.setdefault(g, []).extend(rows)
            excluded.setdefault(g, set()).update(z.w0)
        for j, f in enumerate(z.faces):
            first[f] = (z_i, j, z.chart[f][1])
    patches = []
    face_pieces = [[] for _ in range(topo.nf)]
    for r, comp in enumerate(dec.regions):
        fm = dec.face_map[r]
        X0, X1, Y0, Y1 = dec.region_rects[r]
        PW, PH = (X1 - X0).real, (Y1 - Y0).real
        if PW <= tol or PH <= tol:
            raise mesh.error(f"the patch around {mesh.face_name(dec.pieces[comp[0]][0])} has zero size "
                             f"in knot space (zero knot intervals along a whole patch side)")
        shift = (0, -X0, -Y0)
        items = []
        ub, vb = [0.0, PW], [0.0, PH]
        for p in comp:
            f, x0, x1, y0, y1 = dec.pieces[p]
            if (x1 - x0).real <= tol or (y1 - y0).real <= tol:
                continue                   # no area: no cells
            m = compose(shift, fm[f])     # face -> patch frame
            mr = (m[0], m[1].real, m[2].real)
            px0, px1, py0, py1 = (c.real for c in dec.rects[p])
            px0, px1, py0, py1 = px0 - X0.real, px1 - X0.real, py0 - Y0.real, py1 - Y0.real
            fns = _face_functions(knots, support[f], excluded.get(f, ()), direct.get(f, ()), Pw, mr)
            _, UK, VK = fns
            ub.extend(UK[(px0 < UK) & (UK < px1)].tolist())
            vb.extend(VK[(py0 < VK) & (VK < py1)].tolist())
            ub.extend((px0, px1))
            vb.extend((py0, py1))
            items.append((p, f, mr, (px0, px1, py0, py1), fns))
            face_pieces[f].append((r, (x0.real, x1.real, y0.real, y1.real), mr, (PW, PH)))
        ub = _cluster(ub, tol)
        vb = _cluster(vb, tol)
        nu, nv = len(ub) - 1, len(vb) - 1
        owner = np.full((nu, nv), -1)
        local = np.zeros((nu, nv), dtype=int)
        group = np.zeros((nu, nv), dtype=int)
        bez = []                                    # bicubic Bezier cells
        star_entries, star_cells = [], []           # (star, sector, q, shift, widths), (iu, iv, bezier)
        # every piece's cells, then the Bernstein coefficients of all pieces' functions at once
        # (bezier_1d_many), then the cells in order; a piece covering cells twice raises
        # where the loop reaches it, as before
        spans, jobs, clash = [], [], None
        for n_item, (p, f, m, (px0, px1, py0, py1), (pts, UK, VK)) in enumerate(items):
            iu0, iu1 = _locate(ub, px0, tol), _locate(ub, px1, tol)
            iv0, iv1 = _locate(vb, py0, tol), _locate(vb, py1, tol)
            if np.any(owner[iu0:iu1, iv0:iv1] >= 0):
                clash = n_item
                break
            owner[iu0:iu1, iv0:iv1] = n_item
            spans.append((iu0, iu1, iv0, iv1))
            jobs.append((UK, np.array(ub[iu0:iu1]), np.array(ub[iu0 + 1:iu1 + 1])))
            jobs.append((VK, np.array(vb[iv0:iv1]), np.array(vb[iv0 + 1:iv1 + 1])))
        coeffs = bezier_1d_many(jobs)
        for n_item, (p, f, m, _, (pts, _, _)) in enumerate(items):
            if n_item == clash:
                raise AssertionError("patch cells covered twice")
            iu0, iu1, iv0, iv1 = spans[n_item]
            Cu, Cv = coeffs[2 * n_item], coeffs[2 * n_item + 1]      # (k, cu, 4), (k, cv, 4)
            ctrl = np.einsum("kbj,kai,kc->abjic", Cv, Cu, pts)   # (cu, cv, 4, 4, 4)
            star = first.get(f)
            if star is not None:
                z_i, j, mc = star
                to_chart = compose(mc, inverse(m))         # patch frame -> sector chart
                q = to_chart[0]
            for a in range(iu1 - iu0):
                for b in range(iv1 - iv0):
                    cell = ctrl[a, b]
                    local[iu0 + a, iv0 + b] = len(bez)
                    bez.append(cell)
                    if star is None:
                        if f in replaced:
                            continue
                        if min(cell[0, 0, 3], cell[0, -1, 3], cell[-1, 0, 3], cell[-1, -1, 3]) <= 0.0:
                            raise mesh.error(f"the surface has no point at a corner of a cell of "
                                             f"{mesh.face_name(f)} (no blending function reaches it)")
                        continue
                    u0, v0 = ub[iu0 + a], vb[iv0 + b]
                    sx, sy = apply(to_chart, u0, v0)
                    star_entries.append((z_i, j, q, (complex(sx).real, complex(sy).real),
                                         (ub[iu0 + a + 1] - u0, vb[iv0 + b + 1] - v0)))
                    star_cells.append((iu0 + a, iv0 + b, len(bez) - 1))
        if np.any(owner < 0):
            raise mesh.error(f"the patch around {mesh.face_name(dec.pieces[comp[0]][0])} is not covered "
                             f"by its faces")
        groups = [BezierCells(np.array(bez))] if bez else []
        if star_cells:
            sc = StarCells(levels, star_entries)
            g = len(groups)
            groups.append(SumCells(groups[0], [c[2] for c in star_cells], sc, np.arange(len(star_cells))))
            for n_cell, (iu, iv, _) in enumerate(star_cells):
                group[iu, iv] = g
                local[iu, iv] = n_cell
        patch = Patch(len(patches), np.array(ub) / PW, np.array(vb) / PH, group, local, groups,
                      knot_size=(PW, PH))
        patches.append(patch)
    return patches, face_pieces


def _face_functions(knots: LocalKnots, support: list, skip, direct: list, Pw: np.ndarray, mr) -> tuple:
    """The blending functions on one face piece, in the patch frame (map ``mr`` face ->
    patch): homogeneous points (k, 4), u knots (k, 5), v knots (k, 5); first the functions
    of ``support`` (vertex, map face -> vertex frame) not in ``skip``, then the ``direct``
    ones (point, x knots, y knots in the face frame). Row by row what ``knots.in_frame`` and
    ``map_knots`` give (the same sums and negations, on arrays)."""
    rows = [(A, ma) for A, ma in support if A not in skip]
    pts, xs, ys = [], [], []
    if rows:
        idx = np.array([A for A, _ in rows])
        back = [inverse(ma) for _, ma in rows]
        x, y = _map_rows(knots.s[idx], knots.t[idx], np.array([b[0] for b in back]),
                         np.array([b[1] for b in back], dtype=complex)[:, None],
                         np.array([b[2] for b in back], dtype=complex)[:, None])
        pts.append(Pw[idx])
        xs.append(x.real)
        ys.append(y.real)
    if direct:
        pts.append(np.array([pt for pt, _, _ in direct]).reshape(-1, 4))
        xs.append(np.array([xk for _, xk, _ in direct]).reshape(-1, 5))
        ys.append(np.array([yk for _, _, yk in direct]).reshape(-1, 5))
    if not pts:
        return np.zeros((0, 4)), np.zeros((0, 5)), np.zeros((0, 5))
    X, Y = np.concatenate(xs), np.concatenate(ys)
    U, V = map_knots(X.T, Y.T, mr)            # knots along axis 0: map_knots reverses that one
    return np.concatenate(pts), np.ascontiguousarray(U.T), np.ascontiguousarray(V.T)


def _map_rows(xk: np.ndarray, yk: np.ndarray, q: np.ndarray, tx: np.ndarray, ty: np.ndarray):
    """``map_knots`` of knot rows (k, 5) with one map (q, tx, ty) per row (k,), (k, 1), (k, 1)."""
    X, Y = np.empty_like(xk), np.empty_like(yk)
    for r in np.unique(q % 4):
        sel = q % 4 == r
        x, y = map_knots(xk[sel].T, yk[sel].T, (int(r), tx[sel].T, ty[sel].T))
        X[sel], Y[sel] = x.T, y.T
    return X, Y


def _assemble(walker: Walker, dec: Decomposition, patches: list[Patch], face_pieces: list,
              ep_interval: dict, name) -> TSplineModel:
    """The model: patches linked across whole edges, corner nodes, extraordinary points."""
    mesh = walker.mesh
    links, corner_keys = region_links(walker, dec)
    link_patches(patches, links)
    node_of = {}
    for r in range(len(dec.regions)):
        for key in corner_keys[r]:
            node_of.setdefault(key, len(node_of))
    node_points = np.zeros((len(node_of), 3))
    for r, keys in enumerate(corner_keys):
        patch = patches[r]
        patch.corner_nodes = np.array([node_of[k] for k in keys])
        node_points[patch.corner_nodes] = patch.evaluate(CORNER_UV[:, 0], CORNER_UV[:, 1]).P
    eps = []
    for v in sorted(ep_interval):
        key = ("v", v)
        if key in node_of:
            eps.append(ExtraordinaryPoint(node_of[key], int(walker.topo.total[v]), node_points[node_of[key]],
                                          False))
    model = TSplineModel(patches, node_points, eps, "t-spline", mesh.source, None, control=mesh,
                         name=name or mesh.name)
    model.face_pieces = face_pieces
    model.face_size = [(W.real, H.real) for W, H in walker.topo.size]
    model.node_keys = list(node_of)
    return model


def _cluster(values, tol) -> list:
    """Sorted values with neighbours closer than tol merged."""
    out = []
    for v in sorted(values):
        if not out or v - out[-1] > tol:
            out.append(float(v))
    return out


def _locate(breaks, x, tol) -> int:
    i = int(np.searchsorted(breaks, x - tol))
    if i >= len(breaks) or abs(breaks[i] - x) > tol:
        raise AssertionError(f"{x} is not a break")
    return i
