"""3D pictures on flat matplotlib axes: a view projects the model, and a painter's algorithm
(far to near, every quad and every path segment sorted together) hides what is behind.

matplotlib's own 3D axes sort whole collections, not their polygons, so a path on a surface
shows through the patches in front of it; drawing the projected items as one depth-sorted
PolyCollection does not. Path segments lie on the surface they are drawn on, so they are
sorted as if a little nearer (``lift``) than the quads under them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class View:
    """Orthographic view: ``eye`` points from the model toward the viewer; screen x is
    ``right``, screen y is ``up``."""
    name: str
    eye: np.ndarray
    right: np.ndarray
    up: np.ndarray

    def project(self, P: np.ndarray):
        """(screen xy (..., 2), depth (...)) of points (..., 3); larger depth is nearer."""
        P = np.asarray(P, float)
        return np.stack([P @ self.right, P @ self.up], axis=-1), P @ self.eye


def view(name: str, elevation: float, azimuth: float) -> View:
    """The view from elevation (deg above the XY plane) and azimuth (deg from +X toward +Y)."""
    el, az = np.radians(elevation), np.radians(azimuth)
    eye = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    if abs(eye[2]) > 1 - 1e-9:                       # from straight above: X right, Y up
        return View(name, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    right = np.cross([0.0, 0.0, 1.0], eye)
    right /= np.linalg.norm(right)
    return View(name, eye, right, np.cross(eye, right))


TOP = view("top view", 90.0, -90.0)
ISO = view("3D view", 32.0, -55.0)


@dataclass
class SurfaceQuads:
    """The model as quads for drawing: ``corners`` (m, 4, 3), ``patch`` (m,), ``uv`` (m, 2)
    of each quad's centre, ``normal`` (m, 3) of each quad (the model's side)."""
    corners: np.ndarray
    patch: np.ndarray
    uv: np.ndarray
    normal: np.ndarray
    size: float                  # largest quad diagonal, mm


def surface_quads(model, cells=None, per_patch: int | None = None) -> SurfaceQuads:
    """Quads over every patch: ``cells[p] = (nu, nv)`` per patch, or ``per_patch`` each way
    (default: about 20,000 quads in all, 4..24 per patch side)."""
    n_p = len(model.patches)
    if per_patch is None:
        per_patch = int(np.clip(np.sqrt(20000 / max(n_p, 1)), 4, 24))
    C, pp, uv, N = [], [], [], []
    for p in model.patches:
        nu, nv = cells[p.index] if cells is not None else (per_patch, per_patch)
        gu, gv = np.linspace(0.0, 1.0, nu + 1), np.linspace(0.0, 1.0, nv + 1)
        sp = p.evaluate_grid(np.clip(gu, 1e-7, 1 - 1e-7), np.clip(gv, 1e-7, 1 - 1e-7), second=False)
        G = sp.P.reshape(nu + 1, nv + 1, 3)
        Gn = sp.normal.reshape(nu + 1, nv + 1, 3)
        q = np.stack([G[:-1, :-1], G[1:, :-1], G[1:, 1:], G[:-1, 1:]], axis=2).reshape(-1, 4, 3)
        n = np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 1])
        ref = (Gn[:-1, :-1] + Gn[1:, :-1] + Gn[1:, 1:] + Gn[:-1, 1:]).reshape(-1, 3)
        n *= np.where(np.einsum("ij,ij->i", n, ref) < 0, -1.0, 1.0)[:, None]
        ln = np.linalg.norm(n, axis=1, keepdims=True)
        n = np.where(ln > 0, n / np.where(ln > 0, ln, 1.0), ref / np.maximum(np.linalg.norm(ref, axis=1, keepdims=True), 1e-300))
        cu, cv = np.meshgrid(0.5 * (gu[:-1] + gu[1:]), 0.5 * (gv[:-1] + gv[1:]), indexing="ij")
        C.append(q)
        pp.append(np.full(len(q), p.index))
        uv.append(np.column_stack([cu.ravel(), cv.ravel()]))
        N.append(n)
    corners = np.concatenate(C)
    size = float(np.linalg.norm(corners[:, 2] - corners[:, 0], axis=1).max()) if len(corners) else 0.0
    return SurfaceQuads(corners, np.concatenate(pp), np.concatenate(uv), np.concatenate(N), size)


def shade(colours: np.ndarray, normals: np.ndarray, v: View, ambient: float = 0.45) -> np.ndarray:
    """Lambert shading of RGBA colours, light from over the viewer's left shoulder."""
    light = v.eye + 0.45 * v.up - 0.35 * v.right
    light /= np.linalg.norm(light)
    k = ambient + (1.0 - ambient) * np.abs(normals @ light)
    out = np.array(colours, float, copy=True)
    out[:, :3] = np.clip(out[:, :3] * k[:, None], 0.0, 1.0)
    return out


@dataclass
class Scene:
    """Items to draw in one view: filled polygons and polylines, sorted together by depth."""
    view: View
    lift: float = 0.0                        # depth bonus of lines (mm)
    _items: list = field(default_factory=list)

    def polygons(self, corners: np.ndarray, face: np.ndarray, edge=None, width: float = 0.25) -> None:
        """Filled polygons (m, k, 3) with RGBA faces (m, 4) and edges (default: the face)."""
        corners = np.asarray(corners, float)
        xy, d = self.view.project(corners)
        closed = np.concatenate([xy, xy[:, :1]], axis=1)
        face = np.asarray(face, float)
        edge = face if edge is None else np.broadcast_to(np.asarray(edge, float), face.shape)
        self._items.append((closed, d.mean(axis=1), face, edge, np.full(len(corners), width), None))

    def polyline(self, points: np.ndarray, colour, keep=None, width: float = 0.8, dashes=None) -> None:
        """The polyline through ``points`` (n, 3): segment i (points i -> i+1) drawn where
        ``keep[i]`` (default all), in ``colour`` (one, or RGBA per segment (n-1, 4)).

        Drawn as long pieces, not segment by segment: separately drawn segments leave
        anti-aliasing seams at every joint, which on dense parallel lines line up into false
        steps. A piece ends where the segments stop, change colour, or span more depth than
        ``lift`` (so the depth sort stays right)."""
        from matplotlib.colors import to_rgba
        P = np.asarray(points, float).reshape(-1, 3)
        m = len(P) - 1
        if m < 1:
            return
        keep = np.ones(m, bool) if keep is None else np.asarray(keep, bool)
        col = np.array(to_rgba(colour)) if isinstance(colour, str) else np.asarray(colour, float)
        col = np.broadcast_to(col, (m, 4))
        xy, d = self.view.project(P)
        span = self.lift if self.lift > 0 else np.inf
        starts = np.nonzero(keep & np.concatenate([[True], ~keep[:-1] | (col[1:] != col[:-1]).any(axis=1)]))[0]
        # a run s0 .. e-1 ends where the next one starts or a dropped segment comes
        stops = np.union1d(np.union1d(starts, np.nonzero(~keep)[0]), [m])
        ends = stops[np.searchsorted(stops, starts, side="right")]
        pieces, depth, colours = [], [], []
        for s0, e in zip(starts.tolist(), ends.tolist()):
            a = s0
            while a < e:                                 # cut the run where the depth spreads
                dd = d[a:e + 1]
                spread = np.maximum.accumulate(dd) - np.minimum.accumulate(dd)
                b = a + max(1, int(np.searchsorted(spread, span, side="right")) - 1)
                b = min(b, e)
                pieces.append(xy[a:b + 1])
                depth.append(d[a:b + 1].max() + self.lift)
                colours.append(col[a])
                a = b
        if pieces:
            n = len(pieces)
            self._items.append((pieces, np.array(depth), np.zeros((n, 4)), np.array(colours), np.full(n, width),
                                dashes))

    def draw(self, ax) -> None:
        """Add everything to ``ax`` far to near, and fit the axes to it (equal scales)."""
        from matplotlib.collections import PolyCollection
        if not self._items:
            return
        paths, depth, face, edge, width, dash = [], [], [], [], [], []
        for xy, d, f, e, w, ds in self._items:
            paths += list(xy)                       # polygons (m, k, 2) or a list of pieces
            depth.append(d)
            face.append(f)
            edge.append(e)
            width.append(w)
            dash += [ds] * len(xy)
        depth = np.concatenate(depth)
        order = np.argsort(depth, kind="stable")
        styles = [(0, None) if ds is None else (0, ds) for ds in dash]
        width = np.concatenate(width)[order]
        # one width for all where they agree: matplotlib scales a dash pattern per width given
        # (a tenth of a second for the scallop map's 20,000 cells)
        same = len(width) and bool((width == width[0]).all())
        col = PolyCollection([paths[i] for i in order], closed=False,
                             facecolors=np.concatenate(face)[order], edgecolors=np.concatenate(edge)[order],
                             linewidths=float(width[0]) if same else width,
                             linestyles=[styles[i] for i in order] if any(ds is not None for ds in dash) else "solid",
                             joinstyle="round", capstyle="round")
        ax.add_collection(col)
        pts = np.concatenate([np.asarray(p) for p in paths])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = 0.04 * max(hi - lo)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal", adjustable="datalim")


def facing(v: View, normals: np.ndarray) -> np.ndarray:
    """True where a surface with these normals (toward the tool side) faces the viewer."""
    return np.asarray(normals, float) @ v.eye > 0.05


def plain_axes(ax, v: View, title: str) -> None:
    """A view's axes: no ticks; the top view keeps X and Y in mm as its labels."""
    ax.set_title(title)
    ax.grid(False)
    if v.name == TOP.name:
        ax.set_xlabel("X (mm)")
        ax.set_ylabel("Y (mm)")
    else:
        ax.set_xticks([])
        ax.set_yticks([])
        for s in ax.spines.values():
            s.set_visible(False)
