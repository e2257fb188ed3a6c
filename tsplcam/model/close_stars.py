"""Star points closer than three edges apart, in T-meshes that are not plain Catmull-Clark
cages: the faces around them from the limit of a local Catmull-Clark cage, the rest from
the kernel.

The T-NURCC construction (``stars.py``) needs every star's two rings of faces to itself.
Where stars are closer (a cluster: stars whose one-ring vertex sets meet, chained), and the
cluster's neighbourhood has one knot interval, no T-junctions and no other irregular
vertex, the surface there is the Catmull-Clark limit of the control points (Sederberg et
al. 2003: uniform T-NURCCs are Catmull-Clark), whatever the T-mesh is further out (open
boundary, T-junctions, other intervals, other stars):

* The kernel is built with the cluster's stars left without their construction: their own
  functions are left out, every other function is the T-spline's own (ray-cast knots;
  ``blending.supports`` told that the zone's faces may be reached around a star). On a
  face whose vertices are all regular and whose one-ring's rays meet only uniform regular
  structure these are the 16 uniform B-splines of its one-ring, as in the limit: measured,
  the kernel differs from the limit on the faces within ``ZONE`` rings of the cluster's
  stars only (three clusters on tori: 0.13 to 0.27 of the model size on the first ring, 2e-2
  to 3e-2 on the second, within 7e-16 from the third on).
* The cells of the zone's faces (``ZONE`` rings) are replaced by the limit of a local cage
  of the zone and one ring more (``CAGE_MARGIN``) (``boundary_stars.CageCells`` through
  ``boundary_stars.override``), exact there: a face's limit depends on its one-ring and its
  corners' rules only. Zone and kernel meet along a line on which both are the same
  uniform B-spline: C2 there, G1 at the stars (the limit's own normal there).
* The neighbourhood that must be uniform (``NEED`` rings): the zone and three rings more.
  The local cage lies within it, and so do the knots of every
  kernel function whose value or first or second derivatives are non-zero on the zone's
  edge (vertices up to one edge from it, whose rays reach two faces further): the seam is
  C2 whatever lies beyond (measured with a T-junction just outside: gaps 6e-16 of the
  model size, normals 7e-13 degrees apart).

Refused by name (``stars.StarsTooClose``): close stars whose ``NEED`` rings have a
T-junction, more than one knot interval, a zero interval, an irregular vertex that is not
one of the cluster's stars, or a boundary vertex. A cluster on a uniform cage that is a
plain Catmull-Clark cage never comes here (``tspline._as_cage`` takes the whole mesh).
"""
from __future__ import annotations

import numpy as np

from .boundary_stars import CageCells, override, rings, vertex_faces
from .cells import _chain
from .stars import _too_close

#: rings of faces around a cluster's stars evaluated from the local cage (measured: the
#: kernel without the clustered stars' construction differs from the limit on rings 1 and 2)
ZONE = 2
#: rings of the local cage beyond the zone: a zone face's limit depends on its one-ring and
#: its corners' rules, so its corners must be interior vertices of the local cage (measured:
#: without the margin 1.2e-2 of the model size off, with one ring exact to 3e-16)
CAGE_MARGIN = 1
#: rings that must be uniform, regular and free of T-junctions around a cluster: the zone,
#: and the kernel functions non-zero to second order on its edge with their rays
NEED = ZONE + 3
#: relative spread of knot intervals still read as one interval
UNIFORM_TOL = 1e-9


def interior_stars(mesh) -> list[int]:
    """Interior vertices whose faces do not make a full turn (the kernel's star points)."""
    topo = mesh.topology
    return [v for v in range(mesh.n_vertices) if not topo.boundary[v] and topo.is_extraordinary(v)]


def clusters(mesh) -> list[list[int]]:
    """The stars closer than three edges apart, in clusters: two stars are close when the
    vertices of their faces meet (they share a face, or one is the other's neighbour, or
    they share a neighbour); clusters are the chains of close stars. Stars with no close
    star are left to the T-NURCC construction."""
    at = vertex_faces(mesh)
    stars = interior_stars(mesh)
    near = {v: {int(w) for f in at.get(v, ()) for w in mesh.faces[f]} for v in stars}
    parent = {v: v for v in stars}

    def root(v):
        while parent[v] != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v

    close = set()
    for i, v in enumerate(stars):
        for w in stars[i + 1:]:
            if near[v] & near[w]:
                parent[root(v)] = root(w)
                close |= {v, w}
    groups = {}
    for v in sorted(close):
        groups.setdefault(root(v), []).append(v)
    return sorted(groups.values())


def check_cluster(mesh, cluster: list[int], at: dict) -> tuple[list[list[int]], float]:
    """The ``NEED`` rings of faces around a cluster of close stars and their one knot
    interval; refused by name (``StarsTooClose``) where the neighbourhood is not a uniform
    Catmull-Clark cage: a T-junction, other knot intervals, a boundary or irregular vertex
    that is not one of the cluster's stars."""
    topo = mesh.topology
    names = ", ".join(mesh.vertex_name(v) for v in cluster)
    need = (f"extraordinary points {names} are closer than three edges apart: the T-NURCC construction does not "
            f"take them, and their {NEED} rings of faces must then be a uniform Catmull-Clark cage (no "
            f"T-junctions, no boundary, no other star points, one knot interval), evaluated as its limit")
    for v in cluster:
        if int(topo.total[v]) < 3:
            raise mesh.error(f"{mesh.vertex_name(v)} is an interior vertex with only {int(topo.total[v])} "
                             f"faces", vertex=v)
    rs = rings(mesh, cluster, NEED, at)
    faces = [f for r in rs for f in r]
    for f in faces:
        if len(mesh.faces[f]) != 4:
            raise _too_close(mesh, f"{need}: {mesh.face_name(f)} has a T-junction (refine the T-mesh there "
                             f"or move the T-junction further out)", face=f)
    for w in sorted({int(x) for f in faces for x in mesh.faces[f]} - set(cluster)):
        if topo.boundary[w]:
            raise _too_close(mesh, f"{need}: {mesh.vertex_name(w)} is on the boundary", vertex=w)
        if int(topo.total[w]) != 4 or len(topo.fan[w]) != 4:
            raise _too_close(mesh, f"{need}: {mesh.vertex_name(w)} is not a regular vertex "
                             f"({int(topo.total[w])} quarter turns of faces)", vertex=w)
    own = float(np.asarray(mesh.intervals[rs[0][0]], float)[0])     # an interval at the stars
    for f in faces:
        d = np.asarray(mesh.intervals[f], float)
        odd = np.abs(d - own) > UNIFORM_TOL * max(own, topo.tol)
        if own <= topo.tol or odd.any():
            raise _too_close(mesh, f"{need}: {mesh.face_name(f)} has knot interval {float(d[odd.argmax()]):g} "
                             f"where the star points have {own:g}", face=f)
    return rs, own


def local_cage(mesh, faces: list[int]):
    """The local Catmull-Clark cage of T-mesh faces ``faces`` (all quads; each cage face in
    its T-mesh face's own (s, t) frame: the loop from the face's corner 0)."""
    from .cage import Cage, cage_model
    from .quadmesh import QuadMesh
    loops = [[int(mesh.faces[f][c]) for c in mesh.corners[f]] for f in faces]
    verts = sorted({w for lp in loops for w in lp})
    new = {w: i for i, w in enumerate(verts)}
    cage = Cage(QuadMesh(np.array([[new[w] for w in lp] for lp in loops]), len(verts), "edge-and-corner",
                         mesh.source),
                np.asarray(mesh.points, float)[verts], np.asarray(mesh.weights, float)[verts],
                {"interpolateboundary": "edge-and-corner"})
    return cage_model(cage, "close stars")


class StarsCageCells(CageCells):
    """``CageCells`` whose cells may have several star corners (close stars share faces):
    ``corners[i]`` the (s, t) of every star corner of cell i's face; at any of them the limit
    normal is passed on."""

    def __init__(self, cells: CageCells, corners: list):
        super().__init__(cells.model, cells.face, cells.A, cells.o, [None] * len(cells.face))
        k = max([len(c) for c in corners] + [1])
        self._corners = np.full((len(corners), k, 2), np.nan)
        for i, c in enumerate(corners):
            if len(c):
                self._corners[i, :len(c)] = c

    def evaluate(self, idx: np.ndarray, a: np.ndarray, b: np.ndarray):
        A, o = self.A[idx], self.o[idx]
        s = np.clip(A[:, 0, 0] * a + A[:, 0, 1] * b + o[:, 0], 0.0, 1.0)
        t = np.clip(A[:, 1, 0] * a + A[:, 1, 1] * b + o[:, 1], 0.0, 1.0)
        at = np.zeros(len(idx), bool)
        for c in np.moveaxis(self._corners[idx], 1, 0):          # each corner slot
            hit = (np.abs(s - c[:, 0]) <= 1e-13) & (np.abs(t - c[:, 1]) <= 1e-13)
            s = np.where(hit, c[:, 0], s)
            t = np.where(hit, c[:, 1], t)
            at |= hit
        sp = self.model.evaluate_faces(self.face[idx], s, t)
        Hst = np.zeros((6, 4, len(idx)))
        for k, arr in enumerate((sp.P, sp.Pu, sp.Pv, sp.Puu, sp.Puv, sp.Pvv)):
            Hst[k, :3] = arr.T
        Hst[0, 3] = 1.0
        return _chain(Hst, A), at, (np.asarray(sp.normal) if at.any() else None)


def close_star_model(mesh, walker, name=None):
    """The surface of T-mesh ``mesh`` with stars closer than three edges apart (``clusters``):
    the kernel (``tspline.py``'s steps) without the clustered stars' construction, the
    faces within ``ZONE`` rings of them from their local cage's limit. Refused by name
    where a cluster's neighbourhood is not uniform (``check_cluster``)."""
    from .blending import supports
    from .decompose import decompose_tmesh
    from .knots import local_knots
    from .patch import CORNER_UV
    from .stars import build_zone, find_stars
    from .tspline import _assemble, _extract, _zone_faces
    at = vertex_faces(mesh)
    groups = clusters(mesh)
    checked = [(c, *check_cluster(mesh, c, at)) for c in groups]
    close = {v for c in groups for v in c}
    stars = find_stars(_Masked(walker, close))              # the other stars, checked as ever
    interval = {v: float(np.mean(d)) for v, (_, _, _, d) in stars.items()}
    for c, _, d in checked:
        interval.update({v: d for v in c})
    Pw = mesh.homogeneous()
    knots = local_knots(walker, interval)
    zones = [build_zone(walker, v, star, knots, Pw) for v, star in stars.items()]
    near = _zone_faces(zones)
    cage_faces = {f for _, rs, _ in checked for r in rs[:ZONE] for f in r}
    for f in cage_faces:
        near[f] = (-1, -1, {})                  # reached around a star: ignored, replaced below
    support = supports(walker, knots, set(stars) | close, near)
    dec = decompose_tmesh(walker)
    patches, face_pieces = _extract(walker, dec, knots, support, zones, Pw, cage_faces)
    # the zones' cells are replaced below: until then their corners may have no weight (the
    # clustered stars' own functions are left out), and ``override`` evaluates every
    # corner node again once the last zone is replaced
    with np.errstate(invalid="ignore", divide="ignore"):
        model = _assemble(walker, dec, patches, face_pieces, interval, name)
        for c, rs, _ in checked:
            zone_faces = [f for r in rs[:ZONE] for f in r]
            local = local_cage(mesh, [f for r in rs[:ZONE + CAGE_MARGIN] for f in r])
            corners = {}
            for i, f in enumerate(zone_faces):
                loop = [int(mesh.faces[f][k]) for k in mesh.corners[f]]
                corners[i] = [CORNER_UV[k] for k, w in enumerate(loop) if w in c]
            override(model, {f: i for i, f in enumerate(zone_faces)}, local, {})
            for patch in model.patches:
                for g, cells in enumerate(patch.groups):
                    if type(cells) is CageCells and cells.model is local:
                        patch.groups[g] = StarsCageCells(cells, [corners[int(i)] for i in cells.face])
    if not np.isfinite(model.node_points).all():
        raise AssertionError("a corner node of the close stars' model has no point")
    for e in model.extraordinary:
        e.position = model.node_points[e.node]
    return model


class _Masked:
    """A walker whose topology does not report the clustered stars as extraordinary, so that
    ``stars.find_stars`` finds and checks the other stars only."""

    def __init__(self, walker, close: set):
        self.mesh, self.tol = walker.mesh, walker.tol
        self.topo = _MaskedTopology(walker.topo, close)
        self._walker = walker

    def __getattr__(self, name):
        return getattr(self._walker, name)


class _MaskedTopology:
    def __init__(self, topo, close: set):
        self._topo, self._close = topo, close

    def is_extraordinary(self, v: int) -> bool:
        return v not in self._close and self._topo.is_extraordinary(v)

    def __getattr__(self, name):
        return getattr(self._topo, name)
