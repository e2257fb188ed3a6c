"""The Fusion dialect of ``.tsm`` files (Fusion 360, T-Splines through ASM; docs/formats.md
section 2.5): the surface of a parsed file, and a writer of such files from quad cages.

What the dialect gives and how it is read (the records are parsed in ``tsm.py``):

* ``end-conditions MULTIPLE_KNOTS`` or ``SUBD_CREASES``, ``cap-type G1CAPS``,
  ``star-knot-rule NURCCS``; one grip per vertex, in vertex order without ``0m`` records,
  else by ``0m odd-grip-map`` and one ``0m gvp <vertex>`` per grip; weights honoured.
* Coordinates are centimetres whatever the ``units`` line says (``TsmInfo.scale_rule``).
* Boundary links carry the boundary vertex's kind (2 convex corner, 1 straight, 0 concave
  corner) and ``ec <edge> 0`` marks exactly the boundary edges: both are checked against
  the faces.
* ``100edges`` lists infinitely sharp crease edges, ``100verts`` infinitely sharp vertices
  (OpenSubdiv's crease and corner rules, sharpness infinite); ``106ek`` repeats every
  edge's knot interval and must agree with it.

The surface. A T-mesh without T-junctions whose knot intervals are all equal is a
Catmull-Clark cage: the surface is its limit (``cage.cage_model``), with open boundaries
under OpenSubdiv's edge-and-corner rule (boundary curves are the cubic B-splines of the
boundary grips, single-face corners interpolated) and the creases as infinitely sharp
OpenSubdiv creases, which bound patches. Star points (``cap-type G1CAPS``) are evaluated
exactly on that limit surface, a watertight reading that is G1 at the star itself.
Any other T-mesh (T-junctions, non-uniform intervals) goes to the T-spline kernel
(``tspline.tspline_model``, T-NURCC rule at stars). Its boundaries need zero outer knot
intervals, which Fusion files do not carry: ``clamped_boundary`` adds them, with the grips
that make the boundary the reflected B-spline of the boundary grips (the edge-and-corner
rule on uniform knots). A crease there is knot multiplicity three on its line: the
T-mesh is cut along the crease (``cut_along_creases``), each side clamped like a boundary,
and the patches on the two sides linked again (``join_across_creases``); on uniform knots
this is OpenSubdiv's infinitely sharp crease. Creases that end inside the surface and
sharp vertices are refused there with their line. A boundary vertex of three faces or more
(a star point on the boundary for Catmull-Clark) whose local cage (four to six rings of
faces) is uniform and free of T-junctions is clamped as a concave corner (faces at both
ends of its fan left out from four faces on), and the faces within two to four rings of it
are the Catmull-Clark limit of that cage (``boundary_stars.py``); other boundary stars are
refused with their line. ``kernel_model`` is that route for any T-mesh with open boundaries
that are not clamped: native ``.tspl`` t-splines with the ``edge-and-corner`` boundary
(``MeshReader``) and GrapeTec-style files with boundary stars (``grapetec_star_model``) take
it too.
"""
from __future__ import annotations

import os

import numpy as np

from ...inputfile import naming
from ..components import components
from ..quadmesh import INFINITE
from .tsm import PATTERNS, _Reader

#: relative spread of knot intervals still read as uniform
UNIFORM_TOL = 1e-9
def boundary_flag(turns: int) -> int:
    """How a boundary link marks its origin vertex, by the quarter turns of faces there: 2 a
    convex corner (one), 1 straight (two), 0 concave (three or more)."""
    return {1: 2, 2: 1}.get(int(turns), 0)


def _edge_ends(r, e):
    """The vertices (file ids) an edge's link joins."""
    link = r.l[r.e[e][1]]
    return link[4], r.l[link[2]][4]


def check_boundary(r, old) -> set:
    """The file's boundary edges (edge ids), with the flags of boundary links and the ``ec``
    records checked against the faces."""
    topo = old.topology
    boundary = set()
    for i, rec in enumerate(r.l):
        if rec is None or rec[5] != -1:
            continue
        ln, flag, v = rec[0], rec[7], rec[4]
        boundary.add(rec[6])
        k = r.compact.get(v)
        if k is None or not topo.boundary[k]:
            raise r.err(f"link {i} lies on the boundary (face -1) but vertex {v} is not on the boundary "
                        f"of the faces", ln)
        want = boundary_flag(topo.total[k])
        if flag != want:
            kinds = {2: "a convex corner", 1: "a straight boundary vertex", 0: "a concave corner"}
            raise r.err(f"boundary link {i}: flag {flag} says vertex {v} is {kinds.get(flag, 'nothing known')}, "
                        f"its faces make it {kinds[want]}", ln)
    seen = {}
    for ln, e in r.ec:
        if e in seen:
            raise r.err(f"a second ec record for edge {e} (the first is on line {seen[e]})", ln)
        seen[e] = ln
        if e not in boundary:
            raise r.err(f"ec {e}: edge {e} is not a boundary edge (ec marks the edges with a face -1 link)", ln)
    missing = sorted(boundary - set(seen))
    if missing:
        e = missing[0]
        raise r.err(f"boundary edge {e} has no ec record ({len(missing)} boundary edges without one)",
                    r.e[e][0] if 0 <= e < len(r.e) and r.e[e] is not None else None)
    return boundary


def vertex_grips(r) -> dict:
    """File vertex id -> grip index: one grip per vertex in vertex order, or the grip map."""
    if r.grip_map_line is None:
        if len(r.g) != len(r.v):
            last = next((g[0] for g in reversed(r.g) if g is not None), None)
            raise r.err(f"{len(r.g)} control points (0g) for {len(r.v)} vertices: without a grip map "
                        f"(0m) every vertex has one, in vertex order", last)
        out = {}
        for k, (vrec, grec) in enumerate(zip(r.v, r.g)):
            if (vrec is None) != (grec is None):
                line = (grec or vrec)[0]
                raise r.err(f"vertex slot {k} and control point {k}: a null vertex goes with a null "
                            f"control point (a bare 0g) and only with one", line)
            if vrec is not None:
                out[k] = k
        return out
    out = {}
    for gi, ln, v, _ in r.mapped_grips():
        if not (0 <= v < len(r.v)) or r.v[v] is None:
            raise r.err(f"grip {gi} belongs to vertex {v}, which does not exist", ln)
        if v in out:
            raise r.err(f"vertex {v} has two grips (0m gvp), {out[v]} and {gi}", ln)
        out[v] = gi
    return out


def check_ek(r) -> None:
    """``106ek``: one per edge slot, each equal to its edge's interval."""
    if not r.ek:
        return
    if len(r.ek) != len(r.e):
        raise r.err(f"{len(r.ek)} 106ek records for {len(r.e)} edges (one per edge)", r.ek[-1][0])
    for k, ((ln, value), rec) in enumerate(zip(r.ek, r.e)):
        if rec is not None and abs(value - rec[2]) > UNIFORM_TOL * max(1.0, abs(rec[2])):
            raise r.err(f"106ek gives edge {k} the knot interval {value:g}, its e record (line {rec[0]}) "
                        f"{rec[2]:g}", ln)


def sharp_features(r, boundary: set) -> tuple[dict, dict]:
    """Crease edges (compact vertex pairs, a < b) and sharp vertices (compact ids) from
    ``100edges`` and ``100verts``, infinitely sharp; creases on boundary edges add nothing
    (the boundary is sharp already)."""
    edges, verts = {}, {}
    for ln, e in r.crease_edges:
        if not (0 <= e < len(r.e)) or r.e[e] is None:
            raise r.err(f"100edges: edge {e} does not exist", ln)
        if e in boundary:
            continue
        a, b = (r.compact[v] for v in _edge_ends(r, e))
        edges[(min(a, b), max(a, b))] = INFINITE
    for ln, v in r.crease_vertices:
        if v not in r.compact:
            raise r.err(f"100verts: vertex {v} does not exist or no face uses it", ln)
        verts[r.compact[v]] = INFINITE
    return edges, verts


def uniform_interval(old) -> float | None:
    """The common knot interval of a T-mesh without T-junctions, or None (T-junctions or
    intervals that differ by more than ``UNIFORM_TOL``)."""
    if any(len(f) != 4 for f in old.faces):
        return None
    d = np.concatenate(old.intervals)
    top = float(d.max())
    if not top > 0.0 or float(d.min()) < top * (1.0 - UNIFORM_TOL):
        return None
    return top


def _file_vertex(r, origin, k):
    """(file vertex id, its v line) of vertex k of a (possibly cut) T-mesh."""
    v = r.old_ids[origin[k]]
    return v, r.v[v][0]


def _alpha(r, old, k, w, origin):
    """The share of the way from boundary vertex k toward its inward neighbour w at which
    the second grip of the clamped boundary sits: a / (2a + b), a the interval k-w and b the
    next one straight on beyond w (b = a where the line leaves the mesh at w, reflected
    there too). It reproduces a boundary (or crease) of OpenSubdiv's rule
    on uniform knots, where the boundary point is kept and the curve is continued by
    reflection through it: knot insertion (blossoming) of that reflected B-spline."""
    topo = old.topology
    a = topo.length(k, w).real
    back = topo.edge_angle[(w, k)]
    T = int(topo.total[w])
    if topo.boundary[w]:                 # a boundary fan spans the angles 0 .. T
        on = [x for x in (back + 2, back - 2) if 0 <= x <= T]
        if not on:
            return 1.0 / 3.0              # the line leaves the mesh at w: reflected there, b = a
        beyond = topo.edge_by_angle[w].get(on[0])
    else:
        beyond = topo.edge_by_angle[w].get((back + 2) % 4) if T == 4 else None
    v, line = _file_vertex(r, origin, k)
    if beyond is None:
        raise r.err(f"open boundary or crease at vertex {v}: the line inward through vertex "
                    f"{_file_vertex(r, origin, w)[0]} does not go straight on (a star point or T-junction "
                    f"there): the boundary rule needs the knot interval beyond it", line)
    b = topo.length(w, beyond).real
    if not 2 * a + b > 0:
        raise r.err(f"open boundary or crease at vertex {v}: zero knot intervals inward", line)
    return a / (2 * a + b)


def clamped_boundary(r, old, G0, origin, stars=()):
    """Ring-view grips (``tsm._Reader.build``) of a Fusion T-mesh with open boundaries, for
    the T-spline kernel's clamped boundary: every boundary grip stays on the boundary ring
    (zero knot interval outside) and the file vertex takes the second grip of the clamped
    B-spline, per direction that meets the boundary (straight vertices one, convex corners
    two and their product). Boundary stars in ``stars`` (three faces) are clamped as a
    concave corner with every grip the star's own (``boundary_stars``: the kernel's surface
    there is replaced; with more faces, which only ``keep_file_grips`` asks, just their
    own); other concave corners and boundary stars are refused."""
    topo = old.topology
    H = np.column_stack([G0[:, :3] * G0[:, 3:], G0[:, 3]])
    rows, lines, names, pos = [], [], [], {}

    def add(h, k, what):
        rows.append(np.append(h[:3] / h[3], h[3]))
        lines.append(old.vertex_lines[k])
        names.append(f"{what} grip (line {old.vertex_lines[k]})")
        return len(rows) - 1

    for k in range(old.n_vertices):
        if not topo.boundary[k]:
            pos[k] = {(0, 0): add(H[k], k, "own")}
            continue
        T = int(topo.total[k])
        nb = topo.edge_by_angle[k]
        if T == 2 and 1 in nb:
            w = nb[1]
            al = _alpha(r, old, k, w, origin)
            pos[k] = {(0, -1): add(H[k], k, "boundary"), (0, 0): add(H[k] + al * (H[w] - H[k]), k, "clamped")}
        elif T == 1:
            f, i = topo.fan[k][0]
            loop = old.faces[f]
            if len(loop) != 4:
                raise r.err(f"open boundary: the corner face at vertex {_file_vertex(r, origin, k)[0]} has "
                            f"T-junctions", _file_vertex(r, origin, k)[1])
            px, py = nb[0], nb[1]
            pxy = int(loop[(list(loop).index(k) + 2) % 4])
            ax, ay = _alpha(r, old, k, px, origin), _alpha(r, old, k, py, origin)
            C, X, Y, XY = H[k], H[px], H[py], H[pxy]
            pos[k] = {(-1, -1): add(C, k, "corner"),
                      (0, -1): add(C + ax * (X - C), k, "clamped"),
                      (-1, 0): add(C + ay * (Y - C), k, "clamped"),
                      (0, 0): add(C + ax * (X - C) + ay * (Y - C) + ax * ay * (XY - X - Y + C), k, "clamped")}
        elif k in stars:
            pos[k] = {p: add(H[k], k, "star") for p in sorted(PATTERNS[3] if T == 3 else {(0, 0)})}
        else:
            what = "a concave corner" if T == 3 else "a T-junction" if T == 2 else "a star point"
            v, line = _file_vertex(r, origin, k)
            raise r.err(f"open boundary or crease at vertex {v}, {what}: not supported by the T-spline "
                        f"kernel's clamped boundary", line)
    return pos, np.array(rows), lines, names


def boundary_stars(r, old, origin) -> dict:
    """Boundary star points of the T-mesh (boundary vertices with three faces or more; on a
    T-mesh cut along its creases) -> their rings of faces
    (``boundary_stars.check_neighbourhood``, which refuses what they need otherwise with the
    vertex's line)."""
    from ..boundary_stars import check_neighbourhood
    topo = old.topology
    out = {}
    for k in range(old.n_vertices):
        if not topo.boundary[k] or int(topo.total[k]) < 3:
            continue
        v, line = _file_vertex(r, origin, k)

        def refuse(message, v=v, line=line):
            raise r.err(f"open boundary at vertex {v}, a star point on the boundary: {message}", line)
        out[k] = check_neighbourhood(old, k, refuse)[0]
    return out


def cut_along_creases(r, old, creases: dict):
    """The T-mesh ``old`` cut open along its crease edges, and the vertex of ``old`` each
    vertex comes from. A vertex on creases is split into one copy per sector of faces
    between its crease edges (same grip); a crease that ends inside the surface (one
    crease edge at an inner vertex) cannot be cut and is refused, and so is a crease vertex
    whose sectors would be clamped differently (a crease turning at a vertex)."""
    from ..tmesh import TMesh
    faces = [list(map(int, f)) for f in old.faces]
    at = {}                                          # vertex -> [(face, loop index)]
    for f, loop in enumerate(faces):
        for i, v in enumerate(loop):
            at.setdefault(v, []).append((f, i))
    origin = list(range(old.n_vertices))
    lines, labels = list(old.vertex_lines), list(old.vertex_labels)
    on_crease = sorted({v for e in creases for v in e})
    first_line = r.crease_edges[0][0] if r.crease_edges else None
    for v in on_crease:
        around = sorted({f for f, _ in at[v]})              # the faces at v, joined across
        index = {f: k for k, f in enumerate(around)}       # its edges that are not creases
        by_edge = {}
        for f, i in at[v]:
            m = len(faces[f])
            for w in (faces[f][(i + 1) % m], faces[f][(i - 1) % m]):
                by_edge.setdefault((min(v, w), max(v, w)), []).append(f)
        sector = components(len(around), [(index[fs[0]], index[g]) for e, fs in by_edge.items()
                                          if e not in creases for g in fs[1:]])
        if sector.max() == 0:
            raise r.err(f"the crease ends inside the surface at vertex {r.old_ids[v]}: the T-spline kernel "
                        f"cuts the surface along creases, so they must run from boundary to boundary or "
                        f"close", first_line)
        for k in range(1, int(sector.max()) + 1):
            copy = len(origin)
            origin.append(v)
            lines.append(lines[v])
            labels.append(labels[v] + " (across the crease)")
            for f, i in at[v]:
                if sector[index[f]] == k:
                    faces[f][i] = copy
    mesh = TMesh(np.zeros((len(origin), 3)), None, faces, old.corners, old.intervals, source=old.source,
                 face_lines=old.face_lines, vertex_lines=lines, vertex_labels=labels, face_labels=old.face_labels)
    mesh.validate()
    # both sides must treat every crease vertex alike: all straight (the crease runs
    # straight through an inner vertex: OpenSubdiv's crease rule) or all corners (every edge
    # sharp: its corner rule); a crease that turns, or runs past a star, is refused
    turns = {}
    for k, v in enumerate(origin):
        if v in on_crease:
            turns.setdefault(v, []).append(int(mesh.topology.total[k]))
    for v, ts in turns.items():
        if not (all(t == 1 for t in ts) or (all(t == 2 for t in ts) and not old.topology.boundary[v])):
            raise r.err(f"the crease at vertex {r.old_ids[v]} turns or meets a star point (the faces between "
                        f"its crease edges make {' and '.join(f'{t} quarter turns' for t in ts)}): the T-spline "
                        f"kernel's crease needs it straight through the vertex, or every edge there creased",
                        first_line)
    return mesh, origin


def join_across_creases(model, samples: int = 5) -> int:
    """Make the patches on the two sides of a cut crease neighbours again: every pair of
    patch edges without a neighbour that coincide along their whole length (to 1e-9 of the
    model size, at ``samples`` points) is linked, and their corner nodes become one.
    Returns the number of links made."""
    from ..model import EdgeNeighbour
    from ..patch import CORNER_UV
    free = [(p.index, e) for p in model.patches for e in range(4) if p.neighbours[e] is None]
    if not free:
        return 0
    tau = np.linspace(0.0, 1.0, samples)
    pts = {pe: model.patches[pe[0]].evaluate(*model.patches[pe[0]].edge_params(pe[1], tau)).P for pe in free}
    every = np.concatenate([model.patches[p].evaluate(CORNER_UV[:, 0], CORNER_UV[:, 1]).P
                            for p in range(len(model.patches))])
    tol = 1e-9 * max(float(np.linalg.norm(every.max(0) - every.min(0))), 1e-300)
    same = {}                                       # node -> node it becomes

    def root(n):
        while n in same:
            n = same[n]
        return n
    made = 0
    for i, a in enumerate(free):
        for b in free[i + 1:]:
            if model.patches[a[0]].neighbours[a[1]] is not None or model.patches[b[0]].neighbours[b[1]] is not None:
                continue
            for rev in (True, False):
                other = pts[b][::-1] if rev else pts[b]
                if np.abs(pts[a] - other).max() <= tol:
                    model.patches[a[0]].neighbours[a[1]] = EdgeNeighbour(b[0], b[1], rev)
                    model.patches[b[0]].neighbours[b[1]] = EdgeNeighbour(a[0], a[1], rev)
                    ca = [model.patches[a[0]].corner_nodes[(a[1] + k) % 4] for k in (0, 1)]
                    cb = [model.patches[b[0]].corner_nodes[(b[1] + k) % 4] for k in ((1, 0) if rev else (0, 1))]
                    for x, y in zip(ca, cb):
                        rx, ry = root(int(x)), root(int(y))
                        if rx != ry:                # union of the two nodes' sets
                            same[ry] = rx
                    made += 1
                    break
    if same:
        used = sorted({root(int(n)) for p in model.patches for n in p.corner_nodes})
        new = {n: k for k, n in enumerate(used)}
        for p in model.patches:
            p.corner_nodes = np.array([new[root(int(n))] for n in p.corner_nodes])
        model.node_points = model.node_points[used]
        keys = getattr(model, "node_keys", None)
        if keys is not None:
            model.node_keys = [keys[n] for n in used]
        kept = {}
        for ep in model.extraordinary:
            ep.node = new[root(ep.node)]
            kept.setdefault(ep.node, ep)
        model.extraordinary = list(kept.values())
    return made


class MeshReader(_Reader):
    """What ``kernel_model`` asks of a reader, for a T-mesh read from another file (a native
    ``.tspl`` with the edge-and-corner boundary): errors on its file, its vertices numbered
    from 1 with their lines, coordinates in mm already, the ring construction
    (``tsm._Reader.build``) labelling each boundary strip by the line of its face."""

    def __init__(self, mesh):
        super().__init__(mesh.source or "")
        self.mesh = mesh
        # the ring construction names its vertices and faces after these
        if mesh.vertex_labels is None:
            mesh.vertex_labels = [mesh.vertex_name(k) for k in range(mesh.n_vertices)]
        if mesh.face_labels is None:
            mesh.face_labels = [mesh.face_name(f) for f in range(len(mesh.faces))]
        self.scale = 1.0
        self.header, self.crease_edges, self.crease_vertices = {}, [], []
        self.old_ids = list(range(1, mesh.n_vertices + 1))
        lines = mesh.vertex_lines or [None] * mesh.n_vertices
        self.v = {k + 1: (lines[k],) for k in range(mesh.n_vertices)}
        self.l, self.e, self.g = [], [], []

    def _link_of(self, a, b):
        """A stand-in link record for the edge a -> b: its edge slot holds the face's line."""
        f, _ = self.mesh.topology.edge_at[(a, b)]
        self.e.append((self.mesh.face_lines[f] if self.mesh.face_lines is not None else None,))
        self.l.append((None,) * 6 + (len(self.e) - 1,))
        return len(self.l) - 1


def keep_file_grips(r, old, bstars: dict, pos: dict, rows, file_grips: dict, G) -> None:
    """The ring grips of a GrapeTec file (``file_grips``: old vertex -> {ring-view position:
    (x, y, z, w)}) in place of the edge-and-corner rule's (``pos``/``rows`` of the kernel's
    T-mesh, changed in place), except within the stars' rings, where the file's must be the
    rule's (to 1e-9 of the model size; ``G`` the Catmull-Clark control points): the faces
    there come from the local Catmull-Clark cage, which meets the kernel only if the
    kernel's grips around it are the rule's."""
    from ..boundary_stars import need_rings, rings
    near = {}
    for v in bstars:
        for f in [f for r_ in rings(old, v, need_rings(len(old.topology.fan[v]))) for f in r_]:
            for w in old.faces[f]:
                near.setdefault(int(w), v)
    origin = list(range(old.n_vertices))
    rule_pos, rule_rows, _, _ = clamped_boundary(r, old, G, origin, set(bstars))
    size = max(float(np.ptp(np.asarray(rule_rows)[:, :3], axis=0).max()), 1e-300)
    for k, grips in file_grips.items():
        for p, g in grips.items():
            row = np.asarray(g, float)
            if k in near:
                want = rule_rows[rule_pos[k][p]]
                d = float(np.linalg.norm(row[:3] - want[:3]))
                if d > 1e-9 * size or abs(row[3] - want[3]) > 1e-9:
                    v, line = _file_vertex(r, origin, k)
                    raise r.err(f"boundary vertex {v}, near the boundary star point at vertex "
                                f"{_file_vertex(r, origin, near[k])[0]}: its grip at {p} is {d:.3g} file units "
                                f"from the edge-and-corner rule's (the second row a / (2a + b) of the way "
                                f"inward, from the boundary grip): the faces near a boundary star come from "
                                f"a local Catmull-Clark cage, which meets the T-spline only if its grips "
                                f"there are the rule's", line)
            else:
                rows[pos[k][p]] = row


def kernel_model(r, old, G, name, creases=None, file_grips=None):
    """The T-spline kernel's surface of a T-mesh ``old`` with open boundaries that are not
    clamped (a Fusion file's, or a native file's with the edge-and-corner boundary): one
    grip per vertex (``G``, (x, y, z, w) rows in file units), creases (compact vertex pairs)
    cut first, boundaries clamped by ``clamped_boundary`` and boundary star points from
    local Catmull-Clark cages (``boundary_stars.py``). ``r`` gives the errors, the ring
    construction (``tsm._Reader.build``), the scale and the file's vertex ids and lines.
    ``file_grips`` (k -> {ring-view position: (x, y, z, w)}, a GrapeTec file's boundary
    blocks): kept where they are, except within the stars' rings, where they must be the
    edge-and-corner rule's own (the local cage's limit meets the kernel there).
    Returns the model and its boundary stars."""
    from ..tspline import tspline_model
    origin = list(range(old.n_vertices))
    if creases:
        old, origin = cut_along_creases(r, old, creases)
    bstars = boundary_stars(r, old, origin)
    kernel, kernel_face = old, np.arange(len(old.faces))
    if bstars:
        from ..boundary_stars import (attach, check_seams, hole_sides, notch, split_at, star_points,
                                      without_faces)
        drop = [f for k in bstars for f in notch(old, k)]
        kept = {int(w) for f in range(len(old.faces)) if f not in drop for w in old.faces[f]}
        for k in bstars:
            lone = [int(w) for f in notch(old, k) for w in old.faces[f] if int(w) not in kept]
            if lone:
                v, line = _file_vertex(r, origin, k)
                raise r.err(f"open boundary at vertex {v}, a star point on the boundary of "
                            f"{len(old.topology.fan[k])} faces: the T-spline kernel leaves its end faces "
                            f"out (evaluated from a local cage), which needs their corners on other "
                            f"faces too; vertex {_file_vertex(r, origin, lone[0])[0]} has no other face",
                            line)
        if drop:
            kernel, kernel_face = without_faces(old, drop)
    # the stars and the notches' concave corners: clamped with every grip their own (the
    # kernel's surface within their reach is replaced)
    concave = {k for k in range(kernel.n_vertices) if kernel.topology.boundary[k]
               and int(kernel.topology.total[k]) == 3} if bstars else set()
    pos, rows, lines, names = clamped_boundary(r, kernel, G[origin], origin, concave)
    if file_grips:
        keep_file_grips(r, old, bstars, pos, rows, file_grips, G[origin])
    mesh = r.build(kernel, pos, rows, lines, names, origin if creases else None)
    with naming(r.path):
        model = tspline_model(mesh, name=name)
        if bstars:
            added, limits = attach(model, old, kernel_face, bstars, G[origin], r.scale)
            if added:
                model.notch_faces = added
                # six faces or more: spokes between two left-out faces lie in the middle of a
                # kernel patch's side; the kernel's patches are split there
                big = [k for k in bstars if len(old.topology.fan[k]) >= 6]

                def refuse(why, k=big[0] if big else None):
                    v, line = _file_vertex(r, origin, k)
                    raise r.err(f"open boundary at vertex {v}, a star point on the boundary of "
                                f"{len(old.topology.fan[k])} faces: its left-out faces meet the kernel's "
                                f"patches in the middle of a side, and splitting them fails: {why}", line)
                if big:
                    split_at(model, hole_sides(model, kernel, {int(w) for f in drop for w in old.faces[f]}),
                             refuse)
    if bstars:
        def refuse_seam(k, why):
            v, line = _file_vertex(r, origin, k)
            raise r.err(f"open boundary at vertex {v}, a star point on the boundary: {why}", line)
        check_seams(model, old, kernel_face, bstars, refuse_seam)
    if creases or (bstars and added):
        join_across_creases(model)
    if bstars:
        star_points(model, limits)
        # the kernel's T-mesh is not this surface near the stars (their faces come from
        # local cages): it has no native file
        model.no_native = (f"{name}: its boundary star points are evaluated from local "
                           f"Catmull-Clark cages, which the T-mesh it keeps does not describe")
    return model, bstars


def grapetec_star_model(r, old):
    """The surface of a GrapeTec-style ``.tsm`` (Bezier end conditions: grip blocks on the
    boundary) with boundary star points (boundary vertices of four faces or more, without a
    grip block): read as the Fusion dialect's T-mesh through ``kernel_model``, each vertex's
    Catmull-Clark control point its boundary grip (the block's grip on the boundary ring; at
    a convex corner the corner grip, at a star or a concave corner its own), the file's
    other grips kept (``keep_file_grips``). A concave corner (three faces) is then a star
    point too, so its block must repeat its own grip (the kernel's clamping of one)."""
    from .tsm import TsmInfo
    topo = old.topology
    blocks = r.grips(old)
    cage_at = {1: (-1, -1), 2: (0, -1)}
    G = np.empty((old.n_vertices, 4))
    file_grips = {}
    for k in range(old.n_vertices):
        T = int(topo.total[k])
        block = {p: np.asarray(r.g[g][1:5], float) for p, g in blocks[k].items()}
        if topo.boundary[k] and T == 3:
            own = block[(0, 0)]
            if any(np.abs(x - own).max() > 1e-12 * max(1.0, float(np.abs(own).max())) for x in block.values()):
                v = r.old_ids[k]
                raise r.err(f"concave corner at vertex {v} in a T-mesh with boundary star points: read as a "
                            f"star point of three faces (Catmull-Clark), its grip block must repeat its own "
                            f"grip", r.cg[v][0] if v in r.cg else r.v[v][0])
        G[k] = block[cage_at.get(T, (0, 0))] if topo.boundary[k] else block[(0, 0)]
        if topo.boundary[k] and T in cage_at:
            file_grips[k] = block
    name = os.path.splitext(os.path.basename(r.path))[0]
    model, _ = kernel_model(r, old, G, name, None, file_grips)
    model.tsm = TsmInfo.of(r, "T-spline with Bezier end conditions (boundary grip blocks); star points on "
                              "the boundary from local Catmull-Clark cages")
    return model


def fusion_model(r, t_spline: bool = False):
    """The surface of a parsed Fusion-dialect file ``r`` (a ``tsm._Reader``); ``t_spline``
    builds it with the T-spline kernel even where it is a uniform cage (for checks)."""
    from ..cage import Cage, cage_model
    from ..quadmesh import QuadMesh
    from .tsm import TsmInfo
    old = r.topology()
    topo = old.topology
    boundary = check_boundary(r, old)
    grip = vertex_grips(r)
    check_ek(r)
    creases, sharp = sharp_features(r, boundary)
    for v, k in r.compact.items():
        if v not in grip:
            raise r.err(f"vertex {v} has no control point", r.v[v][0])
    for v, g in grip.items():
        if v not in r.compact:
            raise r.err(f"control point {g} belongs to vertex {v}, which no face uses", r.g[g][0])
    G = np.array([r.g[grip[v]][1:5] for v in r.old_ids], float)
    stars = [k for k in range(old.n_vertices) if topo.is_extraordinary(k)]
    smooth, s_line = r.header.get("star-smoothness", (0, None))
    if stars and smooth != 0:
        raise r.err(f"star-smoothness {smooth} with star points: only 0 is supported", s_line)
    name = os.path.splitext(os.path.basename(r.path))[0]
    d = uniform_interval(old)
    if d is not None and not t_spline:
        mesh = QuadMesh(np.array([list(f) for f in old.faces]), old.n_vertices, "edge-and-corner", r.path,
                        np.array(old.face_lines))
        mesh.sharpness = creases or None
        mesh.corner_sharpness = sharp or None
        with naming(r.path):
            model = cage_model(Cage(mesh, G[:, :3] * r.scale, G[:, 3], {"interpolateboundary": "edge-and-corner"}),
                               name)
        surface = (f"Catmull-Clark limit of the cage (uniform knot interval {d:g}, no T-junctions; "
                   f"boundaries edge-and-corner, creases infinitely sharp)")
    else:
        if sharp:
            raise r.err("sharp vertices (100verts) on a T-mesh with T-junctions or non-uniform knot "
                        "intervals are not supported", r.crease_vertices[0][0])
        model, bstars = kernel_model(r, old, G, name, creases)
        surface = ("T-spline (T-junctions or non-uniform knot intervals; T-NURCC rule at star points; "
                   "open boundaries clamped with the second grip row of the edge-and-corner rule"
                   + ("; star points on the boundary from local Catmull-Clark cages)" if bstars else ")"))
    model.tsm = TsmInfo.of(r, surface, len(creases), len(sharp))
    return model


# -- writing -----------------------------------------------------------------------------------------
def write_fusion_tsm(cage, path: str, creases=(), corners=(), grip_map: bool = False,
                     interval: float = 1.0, units: str = "1 centimeters",
                     end_conditions: str | None = None) -> None:
    """A quad cage or a T-mesh (``tmesh.TMesh``: its faces, corners, T-junctions and knot
    intervals), in mm, as a Fusion-dialect ``.tsm`` (centimetres): ``creases`` are vertex
    pairs (0-based) written to ``100edges``, ``corners`` vertices to ``100verts``.
    ``grip_map`` writes the grips in reverse vertex order with ``0m odd-grip-map`` and one
    ``0m gvp`` per grip. ``interval`` (cages): every edge's knot interval, or a function of
    an edge's two vertices (a < b). End conditions SUBD_CREASES with creases, else
    MULTIPLE_KNOTS (as Fusion writes them), unless given."""
    if hasattr(cage, "corners"):                     # a T-mesh
        loops = [[int(v) for v in f] for f in cage.faces]
        is_corner = [set(cs) for cs in cage.corners]
        given = {(int(f[i]), int(f[(i + 1) % len(f)])): float(d[i])
                 for f, d in zip(cage.faces, cage.intervals) for i in range(len(f))}
        knot = lambda a, b: given.get((a, b), given.get((b, a)))      # noqa: E731
        points, weights = cage.points, cage.weights
    else:
        loops = [[int(v) for v in f] for f in cage.mesh.faces]
        is_corner = [{0, 1, 2, 3}] * len(loops)
        knot = interval if callable(interval) else (lambda a, b: interval)
        points, weights = cage.points, cage.weights
    nv = len(points)
    links = []                                      # [prev, next, opp, vertex, face, edge, flag]
    at = {}                                         # (a, b) -> link
    turns = np.zeros(nv, int)
    starts = []
    for f, loop in enumerate(loops):
        base, m = len(links), len(loop)
        starts.append(base + min(is_corner[f]))
        for k in range(m):
            flag = 0 if k in is_corner[f] else 1
            links.append([base + (k - 1) % m, base + (k + 1) % m, -1, loop[k], f, -1, flag])
            at[(loop[k], loop[(k + 1) % m])] = base + k
            turns[loop[k]] += 1 if flag == 0 else 2
    out_boundary = {}
    for (a, b), i in list(at.items()):
        if (b, a) not in at:                        # a boundary link b -> a on face -1
            j = len(links)
            links.append([-1, -1, i, b, -1, -1, 1])
            at[(b, a)] = j
            out_boundary[b] = j
    for (a, b), i in at.items():
        links[i][2] = at[(b, a)]
    for v, j in out_boundary.items():
        a = links[links[j][2]][3]                   # the boundary link runs v -> a
        links[j][1] = out_boundary[a]
        links[out_boundary[a]][0] = j
        links[j][6] = boundary_flag(turns[v])
    edges = []
    for (a, b), i in sorted(at.items(), key=lambda kv: kv[1]):
        if links[i][5] < 0:
            links[i][5] = links[links[i][2]][5] = len(edges)
            edges.append(i)
    edge_id = {(links[i][3], links[links[i][2]][3]): e for e, i in enumerate(edges)}
    first = {}
    for i, ln in enumerate(links):
        first.setdefault(ln[3], i)
    pts = np.asarray(points, float) / 10.0
    w = np.ones(nv) if weights is None else np.asarray(weights, float)
    boundary_edges = sorted(links[i][5] for i in range(len(links)) if links[i][4] < 0)
    ends = end_conditions or ("SUBD_CREASES" if len(creases) or len(corners) else "MULTIPLE_KNOTS")
    rows = ["#TS0200", "", "degree 3", "cap-type G1CAPS", "star-smoothness 0", f"units {units}",
            f"end-conditions {ends}", "star-knot-rule NURCCS"]
    rows += [f"f {i} 0" for i in starts]
    rows += [f"e {i} {float(knot(*sorted((links[i][3], links[links[i][2]][3]))))!r}" for i in edges]
    rows += [f"v {first[v]} EAST" for v in range(nv)]
    rows += ["l " + " ".join(str(x) for x in ln) for ln in links]
    rows += [f"ec {e} 0" for e in boundary_edges]
    order = list(range(nv))[::-1] if grip_map else list(range(nv))
    if grip_map:
        rows += ["0m odd-grip-map"] + [f"0m gvp {v}" for v in order]
    rows += ["0g {!r} {!r} {!r} {!r}".format(*pts[v], float(w[v])) for v in order]
    if len(creases) or len(corners):
        ids = [edge_id.get((int(a), int(b)), edge_id.get((int(b), int(a)))) for a, b in creases]
        rows.append("100edges" + "".join(f" {e}" for e in ids))
        rows.append("100verts" + "".join(f" {int(v)}" for v in corners))
    rows += ["", "tol 1.00000000000000008e-05", "geom-tol 1.00000000000000008e-05", "ver 2",
             "behavior-version 4.0.1", "compat-version 4.0.1"]
    with open(path, "w") as fh:
        fh.write("\n".join(rows) + "\n")
