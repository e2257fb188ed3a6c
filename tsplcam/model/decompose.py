"""Split a T-mesh (or a quad cage, a T-mesh without T-junctions) into four-sided patches
(shang2020 section 2.2, figure 2).

Patch boundaries are the lines that run from every extraordinary point and every boundary
corner (convex or concave) straight through the mesh to the next such point or the open
boundary: along edges, straight through regular vertices, and through a face where they
meet a T-junction by its stem (``twalk.py``); the open boundary bounds patches too. The
lines cut faces into pieces; pieces joined across edges that are not patch boundaries form
regions. Each region must be a rectangle in knot units: its pieces' frames agree (every
face gets one map into the region's frame), they tile the region's bounding box exactly,
and no line ends inside it (a slit). A region that is not (a torus, an open tube: no point
to start a line from) is cut by seeding a line at one of its vertices, and all is traced
again, so every closed or periodic part still becomes four-sided patches.

``decompose_tmesh`` is the algorithm; ``decompose`` gives a quad cage's patches as
rectangles of faces (``cage.py``). Bezier extractions (``bezier_mesh.py``) carry no knot
intervals until their patches are known (they are solved per patch afterwards), so they
share the two steps that need none: ``trace_lines`` (the lines, over steps each mesh gives:
``Walker.walk`` here, element segments there) and ``region_frames`` (every piece's frame in
its region, failing where a region is twisted); the rectangle checks are each mesh's own
(here in knot units, there on the lines' order alone).
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from .components import components, groups
from .quadmesh import QuadMesh
from .tmesh import Lex, TMesh, Topology
from .twalk import Walker, apply, compose, inverse


@dataclass
class Decomposition:
    """Regions of face pieces between the patch boundaries, each a rectangle in knot units.

    ``pieces[p]`` = (face, x0, x1, y0, y1): a piece of a face in the face's frame, between
    the face's ``breaks[face]`` (x values, y values) at positions ``piece_at[(face, ia, ib)]``.
    ``regions[r]`` lists region r's pieces (ascending; regions in the order of their first
    piece), ``region_of[p]`` the region of each piece, ``face_map[r][face]`` the map from
    the face's frame into the region's, ``region_rects[r]`` = (X0, X1, Y0, Y1) its rectangle
    in that frame, ``rects[p]`` piece p's rectangle (x0, x1, y0, y1) there. ``cuts`` are
    the pairs of pieces on either side of a patch boundary, (P, Q, side of P, side of Q)
    with the sides in their faces' frames.
    """
    pieces: list
    piece_at: dict
    breaks: list
    regions: list
    region_of: np.ndarray
    face_map: list
    region_rects: list
    rects: list
    cuts: list
    lex: Lex


def decompose_tmesh(walker: Walker, creases: set | None = None, crease_starts: set | None = None
                    ) -> Decomposition:
    """The patch regions of the T-mesh ``walker`` walks on. ``creases``: edges (a, b), a < b,
    that bound patches whatever else (infinitely sharp creases), and ``crease_starts`` the
    vertices where they end, meet or turn, from which lines start as from corners."""
    mesh, topo = walker.mesh, walker.topo
    starts = {v for v in range(mesh.n_vertices) if topo.is_layout_vertex(v)} | set(crease_starts or ())
    for _attempt in range(mesh.n_vertices + 1):
        traced, chords = _trace_all(walker, starts, creases)
        dec, bad = _regions(walker, traced, chords)
        if bad is None:
            return dec
        # seed a line at a vertex of the offending region that is not yet a start
        candidates = [int(x) for f in bad for x in mesh.faces[f] if int(x) not in starts]
        if not candidates:
            raise mesh.error(f"cannot split the faces around {mesh.face_name(bad[0])} into four-sided "
                             f"patches")
        starts.add(min(candidates))
    raise mesh.error("cannot split the surface into four-sided patches")


# -- patch boundaries -------------------------------------------------------------------------
def trace_lines(starts, walks, traced: set, on_chord, boundary_edge=None) -> None:
    """The patch boundaries' tracing, for every mesh that is split into patches (T-meshes
    and cages here, Bezier extractions in ``bezier_mesh.py``): from every start vertex
    (ascending), every line of ``walks(v)`` runs until it reaches another start or the open
    boundary, or runs onto a line traced before. A line is a sequence of steps, as
    ``Walker.walk`` gives them: ("edge", a, w, ...) along the edge from a to w, ("vertex",
    w, d) at vertex w (d None where the line cannot go on), and any other step crosses a
    face, handed to ``on_chord(step)``, which records it and says whether the line goes on.
    ``traced`` collects the edges (a, b), a < b; ``boundary_edge(a, w)`` stops a line at an
    edge of the open boundary (unless those edges are in ``traced`` from the start)."""
    for v in sorted(starts):
        for steps in walks(v):
            for step in steps:
                if step[0] == "vertex":
                    if step[1] in starts or step[2] is None:
                        break
                elif step[0] == "edge":
                    a, w = step[1], step[2]
                    key = (min(a, w), max(a, w))
                    if key in traced or (boundary_edge is not None and boundary_edge(a, w)):
                        break
                    traced.add(key)
                elif not on_chord(step):
                    break


def _trace_all(walker: Walker, starts: set, creases: set | None = None):
    """Lines from the start vertices: traced edges and chords through faces (a line that
    meets a T-junction by its stem goes on through the face, straight across)."""
    topo, lex = walker.topo, walker.lex
    traced = set(creases or ())
    chords = defaultdict(lambda: ([], []))         # face -> (x values of vertical, y of horizontal)

    def walks(v):
        T = int(topo.total[v])
        for th in (range(1, T) if topo.boundary[v] else range(T)):
            yield walker.walk(v, th, walker.straight)

    def on_chord(step):
        _, f, x0, y0, dirf = step
        xs, ys = chords[f]
        values, c = (ys, y0) if dirf % 2 == 0 else (xs, x0)
        if any(lex.eq(c, x) for x in values):
            return False
        values.append(c)
        return True

    trace_lines(starts, walks, traced, on_chord, topo.is_boundary_edge)
    return traced, chords


# -- regions ----------------------------------------------------------------------------------
def _regions(walker: Walker, traced, chords):
    """Pieces, their connections and regions: (Decomposition, None) when every region is a
    rectangle, else (None, the faces of the first region that is not)."""
    mesh, topo, lex = walker.mesh, walker.topo, walker.lex
    pieces = []                 # (face, xa, xb, ya, yb) in face frame
    piece_at = {}               # (face, ia, ib) -> piece id
    breaks = []
    for f in range(topo.nf):
        W, H = topo.size[f]
        xs, ys = chords.get(f, ([], [])) if f in chords else ([], [])
        xb = lex.unique([0j, W] + list(xs))
        yb = lex.unique([0j, H] + list(ys))
        breaks.append((xb, yb))
        for ia in range(len(xb) - 1):
            for ib in range(len(yb) - 1):
                piece_at[(f, ia, ib)] = len(pieces)
                pieces.append((f, xb[ia], xb[ia + 1], yb[ib], yb[ib + 1]))
    links = []            # (piece P, piece Q, f, j) connected across f's loop edge j
    cuts = []             # (piece P, piece Q, side of P, side of Q) on either side of a boundary
    for f in range(topo.nf):
        xb, yb = breaks[f]
        for ia in range(len(xb) - 1):          # chords inside the face
            for ib in range(len(yb) - 1):
                if ia + 1 < len(xb) - 1:
                    cuts.append((piece_at[(f, ia, ib)], piece_at[(f, ia + 1, ib)], 1, 3))
                if ib + 1 < len(yb) - 1:
                    cuts.append((piece_at[(f, ia, ib)], piece_at[(f, ia, ib + 1)], 2, 0))
        loop = mesh.faces[f]
        m = len(loop)
        for j in range(m):
            a, b = int(loop[j]), int(loop[(j + 1) % m])
            hit = topo.edge_at.get((b, a))
            if hit is None or (a > b):
                continue
            g, k = hit
            for P, Q in _across(walker, f, j, g, k, breaks, piece_at):
                if (min(a, b), max(a, b)) in traced:
                    cuts.append((P, Q, int(topo.side[f][j]), int(topo.side[g][k])))
                else:
                    links.append((P, Q, f, j))
    region_of = components(len(pieces), [(P, Q) for P, Q, _, _ in links])
    regions = groups(region_of)
    adj = defaultdict(list)
    for P, Q, f, j in links:
        adj[P].append((Q, f, j))
        adj[Q].append((P, f, j))
    inner_cuts = defaultdict(list)            # region -> cuts with both sides in it
    for cut in cuts:
        if region_of[cut[0]] == region_of[cut[1]]:
            inner_cuts[int(region_of[cut[0]])].append(cut)
    dec = Decomposition(pieces, piece_at, breaks, regions, region_of, [], [], [None] * len(pieces),
                        cuts, lex)
    for r, comp in enumerate(regions):
        fm = _place(walker, pieces, comp, adj)
        if fm is not None:
            for p in comp:
                dec.rects[p] = _piece_rect(lex, pieces[p], fm)
        rect = None if fm is None else _tiling(dec, comp)
        if rect is None or _slit(dec, inner_cuts[r], fm):
            return None, sorted({pieces[p][0] for p in comp})
        dec.face_map.append(fm)
        dec.region_rects.append(rect)
    return dec, None


def _piece_rect(lex: Lex, piece, fm: dict):
    """A piece's rectangle (x0, x1, y0, y1) in the frame of the face map ``fm``: the images
    of its corners (x0, y0) and (x1, y1), ordered per axis (equal ones kept in that order)."""
    f, x0, x1, y0, y1 = piece
    m = fm[f]
    ax, ay = apply(m, x0, y0)
    bx, by = apply(m, x1, y1)
    xs = (bx, ax) if lex.lt(bx, ax) else (ax, bx)
    ys = (by, ay) if lex.lt(by, ay) else (ay, by)
    return xs[0], xs[1], ys[0], ys[1]


def region_frames(first, frame, steps, same=None, key=None) -> dict | None:
    """Every piece's frame in its region, for every mesh split into patches (T-meshes and
    cages here, Bezier extractions in ``bezier_mesh.py``): the frame of the piece ``first``
    is ``frame``; ``steps(piece, its frame)`` yields (a piece joined to it inside the region,
    that piece's frame seen from this one). None when two ways across the region give a
    piece two frames (the region is twisted or wraps around: not a rectangle). ``key(piece)``
    names what a frame belongs to (a face holds one frame for all its pieces), ``same``
    compares frames (``==`` by default)."""
    key = key or (lambda piece: piece)
    frames = {key(first): frame}
    queue = [first]
    seen = {first}
    while queue:
        P = queue.pop()
        for Q, fq in steps(P, frames[key(P)]):
            old = frames.get(key(Q))
            if old is None:
                frames[key(Q)] = fq
            elif not (same(old, fq) if same else old == fq):
                return None
            if Q not in seen:
                seen.add(Q)
                queue.append(Q)
    return frames


def _place(walker: Walker, pieces, comp, adj) -> dict | None:
    """Maps of the region's faces into the frame of its first face, or None when two ways
    across the region give a face two different maps."""
    def steps(P, mP):
        fP = pieces[P][0]
        for Q, f, j in adj[P]:
            # crossing from fP to fQ over f's loop edge j (f is one of the two)
            if f == fP:
                _, mg = walker.cross_map(fP, j)              # map fQ -> fP
                yield Q, compose(mP, mg)
            else:
                _, mg = walker.cross_map(pieces[Q][0], j)    # map fP -> fQ
                yield Q, compose(mP, inverse(mg))

    return region_frames(comp[0], (0, 0j, 0j), steps, walker.same_map, key=lambda p: pieces[p][0])


def _tiling(dec: Decomposition, comp):
    """The region's rectangle (X0, X1, Y0, Y1) when its pieces tile it exactly, else None."""
    lex = dec.lex
    rects = [dec.rects[p] for p in comp]
    # neighbouring pieces share their sides' values: sort each value once
    xs = lex.unique(dict.fromkeys(c for x0, x1, _, _ in rects for c in (x0, x1)))
    ys = lex.unique(dict.fromkeys(c for _, _, y0, y1 in rects for c in (y0, y1)))
    xi = {x: i for i, x in enumerate(xs)}
    yi = {y: i for i, y in enumerate(ys)}

    def at(index, values, c):
        i = index.get(c)
        return lex.index(values, c) if i is None else i

    cover = np.zeros((len(xs) - 1, len(ys) - 1), dtype=int)
    for x0, x1, y0, y1 in rects:
        cover[at(xi, xs, x0):at(xi, xs, x1), at(yi, ys, y0):at(yi, ys, y1)] += 1
    if not np.all(cover == 1):
        return None
    return xs[0], xs[-1], ys[0], ys[-1]


def _slit(dec: Decomposition, cuts, fm) -> bool:
    """Whether a patch boundary runs between two pieces that are neighbours inside the
    region (a line ending inside it). A region may meet itself across its own boundary
    (a band closed around a tube or torus, cut open along one line): those pieces are at
    opposite sides of the rectangle, not neighbours."""
    lex = dec.lex
    for P, Q, kP, _ in cuts:
        a, b = dec.rects[P], dec.rects[Q]
        e = (kP + fm[dec.pieces[P][0]][0]) % 4            # P's side in the region's frame
        if e % 2 == 0:                                     # bottom or top: compare y, overlap in x
            touch = lex.eq(a[2], b[3]) if e == 0 else lex.eq(a[3], b[2])
            lo, hi = (a[0], b[0]), (a[1], b[1])
        else:
            touch = lex.eq(a[1], b[0]) if e == 1 else lex.eq(a[0], b[1])
            lo, hi = (a[2], b[2]), (a[3], b[3])
        if touch and lex.lt(max(lo, key=lex.key()), min(hi, key=lex.key())):
            return True
    return False


def _across(walker: Walker, f, j, g, k, breaks, piece_at):
    """Pairs of pieces (of f, of g) that share a stretch of the edge f:j = g:k."""
    faces = walker.mesh.faces
    if (len(faces[f]) == 4 and len(faces[g]) == 4 and len(breaks[f][0]) == 2 == len(breaks[f][1])
            and len(breaks[g][0]) == 2 == len(breaks[g][1])):
        return [(piece_at[(f, 0, 0)], piece_at[(g, 0, 0)])]     # two whole quads: one shared edge
    lex = walker.lex
    out = []
    sf, cf, sgnf, L = walker.side_range(f, j)
    sg, cg, sgng, _ = walker.side_range(g, k)

    def side_pieces(face, side):
        xb, yb = breaks[face]
        na, nb = len(xb) - 1, len(yb) - 1
        if side == 0:
            return [(piece_at[(face, a, 0)], xb[a], xb[a + 1]) for a in range(na)]
        if side == 1:
            return [(piece_at[(face, na - 1, b)], yb[b], yb[b + 1]) for b in range(nb)]
        if side == 2:
            return [(piece_at[(face, a, nb - 1)], xb[a], xb[a + 1]) for a in range(na)]
        return [(piece_at[(face, 0, b)], yb[b], yb[b + 1]) for b in range(nb)]

    # parameter along the edge from f's loop vertex j (distance)
    def clip(lo, hi):
        lo = lo if lex.lt(0j, lo) else 0j
        hi = hi if lex.lt(hi, L) else L
        return lo, hi

    fr = []
    for P, c0, c1 in side_pieces(f, sf):
        t0, t1 = (c0 - cf) * sgnf, (c1 - cf) * sgnf
        lo, hi = (t0, t1) if lex.lt(t0, t1) else (t1, t0)
        lo, hi = clip(lo, hi)
        if lex.lt(lo, hi):
            fr.append((P, lo, hi))
    # on g the edge runs from f's j+1 vertex (g's k) to f's j vertex: distance from f's j
    # vertex is L - (distance from g's k vertex)
    key = lex.key()
    for Q, c0, c1 in side_pieces(g, sg):
        u0, u1 = L - (c0 - cg) * sgng, L - (c1 - cg) * sgng
        lo, hi = (u0, u1) if lex.lt(u0, u1) else (u1, u0)
        lo, hi = clip(lo, hi)
        if not lex.lt(lo, hi):
            continue
        for P, a0, a1 in fr:
            if lex.lt(max(lo, a0, key=key), min(hi, a1, key=key)):
                out.append((P, Q))
    return out


# -- patch corners and neighbours -----------------------------------------------------------
def node_key(walker: Walker, f: int, x: complex, y: complex):
    """A name for the point (x, y) of face f that is the same from every face: a vertex,
    a point on an edge (by its distance from the edge's lower-numbered end) or a face point."""
    topo, lex = walker.topo, walker.lex
    loop = walker.mesh.faces[f]
    m = len(loop)
    for j in range(m):
        px, py = topo.pos[f][j]
        if lex.eq(px, x) and lex.eq(py, y):
            return ("v", int(loop[j]))
    for j in range(m):
        side, c0, sgn, L = walker.side_range(f, j)
        px, py = topo.pos[f][j]
        on = lex.eq(py, y) if side % 2 == 0 else lex.eq(px, x)
        if not on:
            continue
        t = ((x if side % 2 == 0 else y) - c0) * sgn
        if lex.lt(0j, t) and lex.lt(t, L):
            a, b = int(loop[j]), int(loop[(j + 1) % m])
            if a > b:
                a, b, t = b, a, L - t
            return ("e", a, b, round(t.real / walker.tol), round(t.imag * 1e6))
    return ("f", f, round(x.real / walker.tol), round(x.imag * 1e6), round(y.real / walker.tol),
            round(y.imag * 1e6))


def corner_keys(walker: Walker, dec: Decomposition, r: int) -> list:
    """Node keys of region r's four corners (lower left counter-clockwise)."""
    fm = dec.face_map[r]
    X0, X1, Y0, Y1 = dec.region_rects[r]
    lex = dec.lex
    out = []
    for cx, cy in ((X0, Y0), (X1, Y0), (X1, Y1), (X0, Y1)):
        key = None
        for p in dec.regions[r]:
            f = dec.pieces[p][0]
            x0, x1, y0, y1 = dec.rects[p]
            if lex.eq(x0, cx) or lex.eq(x1, cx):
                if lex.eq(y0, cy) or lex.eq(y1, cy):
                    fx, fy = apply(inverse(fm[f]), cx, cy)
                    key = node_key(walker, f, fx, fy)
                    break
        out.append(key)
    return out


def region_links(walker: Walker, dec: Decomposition) -> tuple[list, list]:
    """Whole-edge neighbours between regions, ((region, edge), (region', edge'), reversed),
    and every region's corner keys."""
    mesh = walker.mesh
    keys = [corner_keys(walker, dec, r) for r in range(len(dec.regions))]
    across = defaultdict(set)          # (region, side) -> {(region', side')}
    for P, Q, kP, kQ in dec.cuts:             # (a cut inside one region is where it meets itself)
        rp, rq = int(dec.region_of[P]), int(dec.region_of[Q])
        eP = (kP + dec.face_map[rp][dec.pieces[P][0]][0]) % 4
        eQ = (kQ + dec.face_map[rq][dec.pieces[Q][0]][0]) % 4
        across[(rp, eP)].add((rq, eQ))
        across[(rq, eQ)].add((rp, eP))
    out = []
    done = set()
    for (r, e), others in sorted(across.items()):
        if (r, e) in done:
            continue
        name = f"patch {r} (around {mesh.face_name(dec.pieces[dec.regions[r][0]][0])})"
        if len(others) != 1:
            raise mesh.error(f"{name}: its side {e} is not one whole edge of a neighbouring patch")
        rb, eb = next(iter(others))
        ka = (keys[r][e], keys[r][(e + 1) % 4])
        kb = (keys[rb][eb], keys[rb][(eb + 1) % 4])
        if ka == kb[::-1]:
            rev = True
        elif ka == kb:
            rev = False
        else:
            raise mesh.error(f"{name} and patch {rb} share only part of an edge")
        out.append(((r, e), (rb, eb), rev))
        done.add((r, e))
        done.add((rb, eb))
    return out, keys


# -- quad cages -------------------------------------------------------------------------------
@dataclass
class FaceRegion:
    """A patch of a quad cage: a rectangle of ``size`` (columns, rows) faces; face
    ``faces[k]`` sits in cell ``cell[k]`` with its corner (rot + m) % 4 at cell corner m
    (0 = lower left, counter-clockwise); ``corners`` are the cage vertices at the
    rectangle's corners 0..3."""
    faces: np.ndarray
    cell: np.ndarray
    rot: np.ndarray
    size: tuple[int, int]
    corners: np.ndarray


@dataclass
class QuadDecomposition:
    """A quad cage's patches (region r is patch r) and their whole-edge neighbours."""
    regions: list[FaceRegion]
    face_region: np.ndarray                  # (F,) region of each face
    links: list                              # ((region, edge), (region, edge), reversed)


def decompose(mesh: QuadMesh) -> QuadDecomposition:
    """Patches of a (validated) quad cage: the T-mesh decomposition with every knot
    interval 1, read back as rectangles of whole faces. Infinitely sharp creases are patch
    boundaries (a tool path line never crosses one)."""
    faces = np.asarray(mesh.faces, dtype=int)
    tmesh = TMesh(np.zeros((mesh.n_vertices, 3)), None, list(faces), [(0, 1, 2, 3)] * len(faces),
                  [np.ones(4)] * len(faces), source=mesh.source,
                  face_labels=[mesh.face_name(f) for f in range(len(faces))],
                  vertex_labels=[mesh.vertex_name(v) for v in range(mesh.n_vertices)])
    walker = Walker(tmesh, Topology(tmesh))
    creases = mesh.crease_edges() if mesh.creased else None
    starts = {v for v in range(mesh.n_vertices) if mesh.is_layout_vertex(v)} if creases else None
    dec = decompose_tmesh(walker, creases, starts)
    links, keys = region_links(walker, dec)
    regions = []
    for r, comp in enumerate(dec.regions):
        fm = dec.face_map[r]
        X0, X1, Y0, Y1 = (int(round(c.real)) for c in dec.region_rects[r])
        region_faces = np.array([dec.pieces[p][0] for p in comp])
        cell = np.array([[int(round(c.real)) for c in dec.rects[p][::2]] for p in comp])
        rot = np.array([(-fm[f][0]) % 4 for f in region_faces])
        if any(key[0] != "v" for key in keys[r]):
            raise AssertionError("a cage patch corner that is not a cage vertex")
        corners = np.array([key[1] for key in keys[r]])
        regions.append(FaceRegion(region_faces, cell - [X0, Y0], rot, (X1 - X0, Y1 - Y0), corners))
    return QuadDecomposition(regions, np.asarray(dec.region_of, dtype=int), links)
