"""What the 3D view draws for a model, as plain numpy arrays (no FreeCAD, no Coin).

The view provider (``viewmodel.py``) turns these into Coin nodes; keeping the geometry
here makes it testable under plain pytest and reusable by later views (path preview,
processing list) that draw on the same surface:

* ``tessellate``: one quad grid per patch, points on the surface and their normals;
* ``patch_colours``: one palette colour per patch; neighbours (boundary or corner linked)
  always differ, every patch has its own colour while the palette lasts;
* ``adjacency``: the patch graph of shang2020 figure 4 drawn on the surface: a node at
  every patch centre, boundary links through the shared edge's midpoint, corner links
  through the shared corner, each a polyline that follows the surface;
* ``control_net``: the control mesh's points and edges when the model has one.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..layout.layout import CORNER_UV, EDGE_CORNERS, Layout

# A distinct palette (sRGB 0..1) with well separated hues; red is kept out of it on
# purpose: it marks extraordinary points. The first five (the keycap's) are 40 degrees
# or more apart in hue, so a screenshot test can tell them apart under any shading.
PALETTE = (
    (0.26, 0.52, 0.86),   # blue
    (0.96, 0.56, 0.16),   # orange
    (0.35, 0.72, 0.36),   # green
    (0.60, 0.42, 0.82),   # purple
    (0.90, 0.45, 0.72),   # pink
    (0.93, 0.80, 0.22),   # yellow
    (0.22, 0.72, 0.72),   # teal
    (0.62, 0.80, 0.22),   # lime
    (0.55, 0.36, 0.22),   # brown
    (0.50, 0.60, 0.95),   # periwinkle
)
EP_COLOUR = (0.85, 0.05, 0.05)          # extraordinary points: red
EDGE_COLOUR = (0.12, 0.12, 0.12)        # patch boundaries
CONTROL_COLOUR = (0.05, 0.05, 0.05)     # control mesh
BOUNDARY_LINK_COLOUR = (0.0, 0.0, 0.0)  # adjacency graph, solid
CORNER_LINK_COLOUR = (0.0, 0.0, 0.0)    # adjacency graph, dashed

MAX_POINTS = 2_000_000                  # tessellation budget for the whole model


@dataclass
class PatchMesh:
    """A patch sampled on a (nu+1) x (nv+1) grid: points row-major with u fastest."""
    patch: int
    nu: int
    nv: int
    points: np.ndarray     # ((nu+1)(nv+1), 3)
    normals: np.ndarray    # ((nu+1)(nv+1), 3), unit, finite

    def quads(self) -> np.ndarray:
        """(nu nv, 4) grid indices of the quads, counter-clockwise in (u, v)."""
        i, j = np.meshgrid(np.arange(self.nu), np.arange(self.nv))
        k = (j * (self.nu + 1) + i).ravel()
        return np.column_stack([k, k + 1, k + self.nu + 2, k + self.nu + 1])

    def boundary(self) -> list[np.ndarray]:
        """The four edges as polylines (edge k from corner k to k+1)."""
        g = self.points.reshape(self.nv + 1, self.nu + 1, 3)
        return [g[0, :], g[:, -1], g[-1, ::-1], g[::-1, 0]]


def samples_per_patch(model, density: int) -> list[tuple[int, int]]:
    """Grid size (nu, nv) per patch: ``density`` quads per knot span, within MAX_POINTS."""
    sizes = np.array([[max(1.0, round(p.knot_size[0])), max(1.0, round(p.knot_size[1]))]
                      for p in model.patches])
    d = max(1, int(density))
    total = float(((sizes * d + 1).prod(axis=1)).sum())
    if total > MAX_POINTS:
        d = max(1, int(d * np.sqrt(MAX_POINTS / total)))
    return [(int(a * d), int(b * d)) for a, b in sizes]


def tessellate(model, density: int = 8, progress=None) -> list[PatchMesh]:
    """Every patch on a grid; ``progress(k, n)`` is called after each patch when given."""
    out = []
    grids = samples_per_patch(model, density)
    for k, (patch, (nu, nv)) in enumerate(zip(model.patches, grids)):
        sp = patch.evaluate_grid(np.linspace(0.0, 1.0, nu + 1), np.linspace(0.0, 1.0, nv + 1), second=False)
        # the mesh runs u fastest (rows of constant v); the grid comes u slowest
        P = sp.P.reshape(nu + 1, nv + 1, 3).transpose(1, 0, 2).reshape(-1, 3)
        N = sp.normal.reshape(nu + 1, nv + 1, 3).transpose(1, 0, 2).reshape(-1, 3)
        out.append(PatchMesh(k, nu, nv, np.ascontiguousarray(P, float), _finite_unit(N)))
        if progress is not None:
            progress(k + 1, len(model.patches))
    return out


def _finite_unit(n: np.ndarray) -> np.ndarray:
    n = np.asarray(n, float).copy()
    bad = ~np.isfinite(n).all(axis=1)
    n[bad] = (0.0, 0.0, 1.0)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    tiny = length[:, 0] < 1e-12
    n[tiny] = (0.0, 0.0, 1.0)
    length[tiny] = 1.0
    return n / length


def model_size(model) -> float:
    """Diagonal of the model's bounding box (mm), never zero: scales markers and offsets."""
    lo, hi = model.bounding_box(5)
    return float(max(np.linalg.norm(np.asarray(hi) - np.asarray(lo)), 1e-6))


# -- colours ------------------------------------------------------------------------------
def patch_neighbours(layout) -> list[set[int]]:
    """Patches sharing at least one node with each patch (boundary and corner links)."""
    by_node: dict[int, list[int]] = {}
    for p, nodes in enumerate(layout.corner_nodes):
        for n in set(int(x) for x in nodes):
            by_node.setdefault(n, []).append(p)
    out = [set() for _ in range(layout.n_patches)]
    for patches in by_node.values():
        for p in patches:
            out[p].update(q for q in patches if q != p)
    for link in layout.edge_links:           # an edge link always shares nodes, but be sure
        if link.a != link.b:
            out[link.a].add(link.b)
            out[link.b].add(link.a)
    return out


def patch_colours(layout, palette=PALETTE) -> list[int]:
    """Palette index per patch: patch k gets colour k while the palette lasts; beyond that
    a greedy colouring where linked patches never share a colour if the palette allows."""
    n = layout.n_patches
    m = len(palette)
    if n <= m:
        return list(range(n))
    nbrs = patch_neighbours(layout)
    colour = [-1] * n
    used = np.zeros(m, dtype=int)
    # most constrained first (largest neighbourhood), ties by index: a DSatur-like order
    for p in sorted(range(n), key=lambda q: (-len(nbrs[q]), q)):
        taken = {colour[q] for q in nbrs[p] if colour[q] >= 0}
        free = [c for c in range(m) if c not in taken]
        pool = free if free else list(range(m))
        c = min(pool, key=lambda c: (used[c], (c - p) % m))
        colour[p] = c
        used[c] += 1
    return colour


# the colours of shang2020 figure 4 (a): each patch by its relation to one patch
RELATION_COLOURS = {
    "self": (0.98, 0.80, 0.10),        # the chosen patch: yellow
    "boundary": (0.20, 0.45, 0.90),    # shares an edge with it: blue
    "corner": (0.25, 0.70, 0.30),      # shares only a corner: green
    None: (0.72, 0.72, 0.72),          # not linked: gray
}


def relation_colours(layout, patch: int) -> list[tuple[float, float, float]]:
    """Per patch, the figure-4 colour of its relation to ``patch`` (shang2020 section 3.2)."""
    out = []
    for q in range(layout.n_patches):
        kind = "self" if q == patch else layout.link_kind(patch, q)
        out.append(RELATION_COLOURS[kind])
    return out


# -- adjacency graph ------------------------------------------------------------------------
@dataclass
class AdjacencyDrawing:
    """The patch graph on the surface: node points, and polylines per link kind."""
    centres: np.ndarray                              # (P, 3) patch centres, lifted
    boundary: list[np.ndarray] = field(default_factory=list)   # polylines (k, 3)
    corner: list[np.ndarray] = field(default_factory=list)
    boundary_pairs: list[tuple[int, int]] = field(default_factory=list)
    corner_pairs: list[tuple[int, int]] = field(default_factory=list)


def _surface_line(model, patch: int, uv0, uv1, samples: int, lift: float) -> np.ndarray:
    """Points of the straight (u, v) segment uv0 -> uv1 on the patch, lifted along the normal."""
    t = np.linspace(0.0, 1.0, samples)
    uv = np.asarray(uv0, float)[None, :] * (1 - t)[:, None] + np.asarray(uv1, float)[None, :] * t[:, None]
    sp = model.patches[patch].evaluate(uv[:, 0], uv[:, 1])
    return np.asarray(sp.P, float) + lift * _finite_unit(sp.normal)


def corner_links(layout) -> list[tuple[int, int, int, int]]:
    """(a, corner of a, b, corner of b) for every corner-only linked pair a < b (one shared
    corner each, the first in corner order)."""
    nbrs = patch_neighbours(layout)
    out = []
    for a in range(layout.n_patches):
        for b in sorted(nbrs[a]):
            if b <= a or layout.edge_links_between(a, b):
                continue
            pairs = layout.shared_corners(a, b)
            if pairs:
                out.append((a, pairs[0][0], b, pairs[0][1]))
    return out


def adjacency(model, layout=None, lift: float | None = None, samples: int = 9) -> AdjacencyDrawing:
    """Patch graph of shang2020 section 3.2 / figure 4 drawn on the model: every boundary
    link runs centre -> shared edge midpoint -> centre, every corner link centre -> shared
    corner -> centre, each half along a straight line of its patch's (u, v)."""
    layout = layout or Layout.from_model(model)
    if lift is None:
        lift = 0.004 * model_size(model)
    centre = np.array([0.5, 0.5])
    cs = []
    for k in range(len(model.patches)):
        cs.append(_surface_line(model, k, centre, centre, 1, lift)[0])
    drawing = AdjacencyDrawing(np.array(cs).reshape(-1, 3))
    for link in layout.edge_links:
        ma = CORNER_UV[list(EDGE_CORNERS[link.ea])].mean(axis=0)
        mb = CORNER_UV[list(EDGE_CORNERS[link.eb])].mean(axis=0)
        half_a = _surface_line(model, link.a, centre, ma, samples, lift)
        half_b = _surface_line(model, link.b, mb, centre, samples, lift)
        drawing.boundary.append(np.vstack([half_a, half_b]))
        drawing.boundary_pairs.append((link.a, link.b))
    for a, ca, b, cb in corner_links(layout):
        half_a = _surface_line(model, a, centre, CORNER_UV[ca], samples, lift)
        half_b = _surface_line(model, b, CORNER_UV[cb], centre, samples, lift)
        drawing.corner.append(np.vstack([half_a, half_b]))
        drawing.corner_pairs.append((a, b))
    return drawing


# -- labels and markers ----------------------------------------------------------------------
def patch_centres(model, lift: float = 0.0) -> np.ndarray:
    """Surface point at (u, v) = (0.5, 0.5) of every patch, lifted along its normal."""
    return np.array([_surface_line(model, k, (0.5, 0.5), (0.5, 0.5), 1, lift)[0]
                     for k in range(len(model.patches))]).reshape(-1, 3)


def extraordinary_points(model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (n, 3), valences (n,) and boundary flags (n,) of the extraordinary points."""
    eps = list(model.extraordinary)
    pos = np.array([np.asarray(e.position, float) for e in eps]).reshape(-1, 3)
    return (pos, np.array([e.valence for e in eps], dtype=int).reshape(-1),
            np.array([bool(e.boundary) for e in eps], dtype=bool).reshape(-1))


# -- control mesh -------------------------------------------------------------------------------
def control_net(model) -> tuple[np.ndarray, np.ndarray] | None:
    """(points (n, 3), edges (m, 2)) of the model's control mesh, or None without one.

    Knows quad cages (``control.mesh.faces``) and anything with ``points`` plus ``edges``
    or ``faces`` (lists of index loops), so T-mesh readers can plug in by duck typing."""
    c = getattr(model, "control", None)
    if c is None:
        return None
    pts = getattr(c, "points", None)
    if pts is None:
        return None
    pts = np.asarray(pts, float).reshape(-1, 3)
    edges = getattr(c, "edges", None)
    if edges is not None and not callable(edges):
        e = np.asarray(edges, int).reshape(-1, 2)
        return pts, _unique_edges(e)
    faces = getattr(getattr(c, "mesh", None), "faces", None)
    if faces is None:
        faces = getattr(c, "faces", None)
    if faces is None:
        return None
    loops = [np.asarray(f, int).ravel() for f in faces]
    if not loops:
        return None
    e = np.concatenate([np.column_stack([f, np.roll(f, -1)]) for f in loops])
    return pts, _unique_edges(e)


def _unique_edges(e: np.ndarray) -> np.ndarray:
    e = np.sort(e, axis=1)
    return np.unique(e[e[:, 0] != e[:, 1]], axis=0)


# -- processing list --------------------------------------------------------------------------
@dataclass
class PlanDrawing:
    """A processing list on the model (shang2020 figure 8): per step a curve across its patch
    from the start corner to the finish corner, arrow positions and directions, where step
    numbers go, the transit points, and lifted arcs for retractions."""
    curves: list = field(default_factory=list)          # (k, 3) per step, in list order
    arrows: np.ndarray = None                           # (n, 3) arrow tips
    arrow_dirs: np.ndarray = None                       # (n, 3) unit directions
    label_points: np.ndarray = None                     # (n, 3)
    transits: np.ndarray = None                         # (m, 3) finish = next start points
    retractions: list = field(default_factory=list)     # (k, 3) per retraction
    start: np.ndarray = None                            # (3,) first step's start point
    finish: np.ndarray = None                           # (3,) last step's finish point


def _quadratic_uv(a, c, b, t):
    t = np.asarray(t, float)[:, None]
    return (1 - t) ** 2 * np.asarray(a, float) + 2 * t * (1 - t) * np.asarray(c, float) + t ** 2 * np.asarray(b, float)


def plan_drawing(model, plist, lift: float | None = None, samples: int = 25) -> PlanDrawing:
    """Geometry of a processing list on ``model``: each step's curve is the image of the
    quadratic (u, v) Bezier start corner -> patch centre -> finish corner, lifted along the
    normal; retractions rise by 8 % of the model size above both ends."""
    size = model_size(model)
    if lift is None:
        lift = 0.006 * size
    d = PlanDrawing()
    t = np.linspace(0.0, 1.0, samples)
    tips, dirs, labels, transits = [], [], [], []
    centre = (0.5, 0.5)
    ends = []
    for s in plist.steps:
        patch = model.patches[s.patch]
        uv = _quadratic_uv(CORNER_UV[s.start], centre, CORNER_UV[s.finish], t)
        sp = patch.evaluate(uv[:, 0], uv[:, 1])
        n = _finite_unit(sp.normal)
        curve = np.asarray(sp.P, float) + lift * n
        d.curves.append(curve)
        k = int(0.7 * (samples - 1))
        tip = curve[k]
        direction = curve[k + 1] - curve[k - 1]
        dirs.append(direction / max(np.linalg.norm(direction), 1e-12))
        tips.append(tip)
        labels.append(curve[int(0.3 * (samples - 1))])
        ends.append((curve[0], n[0], curve[-1], n[-1]))
    for i, s in enumerate(plist.steps[1:], start=1):
        p0, n0 = ends[i - 1][2], ends[i - 1][3]
        p1, n1 = ends[i][0], ends[i][1]
        if s.retract_before:
            h = 0.08 * size
            tt = np.linspace(0.0, 1.0, samples)[:, None]
            # a cubic Bezier up from the finish, across, down to the next start
            b = ((1 - tt) ** 3 * p0 + 3 * tt * (1 - tt) ** 2 * (p0 + h * n0)
                 + 3 * tt ** 2 * (1 - tt) * (p1 + h * n1) + tt ** 3 * p1)
            d.retractions.append(b)
        else:
            transits.append(p0)
    d.arrows = np.array(tips).reshape(-1, 3)
    d.arrow_dirs = np.array(dirs).reshape(-1, 3)
    d.label_points = np.array(labels).reshape(-1, 3)
    d.transits = np.array(transits).reshape(-1, 3)
    if ends:
        d.start, d.finish = ends[0][0], ends[-1][2]
    return d


# -- tool path ------------------------------------------------------------------------------------
def segments_by_move(points: np.ndarray, move: np.ndarray) -> dict:
    """{move: [polylines]}: the path cut into runs of one move type (the move of point i is
    the motion from i-1 to i, as in a G-code block)."""
    out: dict = {}
    if len(points) < 2:
        return out
    kind = np.asarray(move[1:], int)
    change = np.nonzero(np.diff(kind))[0] + 1
    starts = np.concatenate([[0], change])
    stops = np.concatenate([change, [len(kind)]])
    for a, b in zip(starts, stops):              # segments a..b-1 join points a..b
        out.setdefault(int(kind[a]), []).append(points[a:b + 1])
    return out


def step_highlight(model, step, samples: int = 33, lift: float | None = None):
    """What shows one step of a processing list: the outline of its patch (four lifted
    edge polylines), its start and finish corner points (or None where not chosen yet), and
    its start -> finish curve (or None)."""
    size = model_size(model)
    lift = 0.006 * size if lift is None else lift
    patch = model.patches[step.patch]
    t = np.linspace(0.0, 1.0, samples)
    outline = []
    for k in range(4):
        a, b = CORNER_UV[k], CORNER_UV[(k + 1) % 4]
        uv = a[None, :] * (1 - t)[:, None] + b[None, :] * t[:, None]
        sp = patch.evaluate(uv[:, 0], uv[:, 1])
        outline.append(np.asarray(sp.P, float) + lift * _finite_unit(sp.normal))

    def corner(c):
        if c is None:
            return None
        sp = patch.evaluate(np.array([CORNER_UV[c][0]]), np.array([CORNER_UV[c][1]]))
        return np.asarray(sp.P, float) + lift * _finite_unit(sp.normal)
    curve = None
    if step.start is not None and step.finish is not None:
        uv = _quadratic_uv(CORNER_UV[step.start], (0.5, 0.5), CORNER_UV[step.finish], t)
        sp = patch.evaluate(uv[:, 0], uv[:, 1])
        curve = np.asarray(sp.P, float) + 1.5 * lift * _finite_unit(sp.normal)
    return outline, corner(step.start), corner(step.finish), curve
