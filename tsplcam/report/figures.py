"""The report's pictures, one function each. Every function draws from the objects the
pipeline made, writes one PNG and returns the figures it shows (for the tables beside it
and for tests).

Sizes are fixed (:data:`SIZES`, pixels at :data:`tsplcam.report.style.DPI`), patch k has the
same colour everywhere (:func:`tsplcam.report.style.patch_colours`), and every axis names its
unit.
"""
from __future__ import annotations

import numpy as np

from ..layout.layout import CORNER_UV, EDGE_CORNERS
from ..toolpath.path import Move
from . import scene, style

SIZES = {"layout": (1300, 620), "path": (1300, 660), "scallop": (1400, 600), "axis": (1300, 600),
         "machine": (1300, 1000), "clearance": (1300, 460), "time": (1300, 500), "baseline": (1300, 440)}


def pixel_size(name: str) -> tuple[int, int]:
    """(width, height) in pixels of picture ``name``."""
    return SIZES[name]


def _lighter(rgba: np.ndarray, amount: float) -> np.ndarray:
    out = np.array(rgba, float, copy=True)
    out[..., :3] = out[..., :3] + (1.0 - out[..., :3]) * amount
    return out


def _surface(sc: scene.Scene, quads: scene.SurfaceQuads, colours: np.ndarray, light: float = 0.0) -> None:
    face = scene.shade(_lighter(colours[quads.patch], light), quads.normal, sc.view)
    sc.polygons(quads.corners, face, width=0.3)


def _patch_borders(model, samples: int = 33) -> list:
    """Polylines (samples, 3) along every patch's four edges."""
    return [_on_patch(model, p.index, CORNER_UV[c0], CORNER_UV[c1], samples)
            for p in model.patches for c0, c1 in EDGE_CORNERS]


def _centres(model):
    """Surface point and normal at (u, v) = (0.5, 0.5) of every patch."""
    P, N = [], []
    for p in model.patches:
        sp = p.evaluate(np.array([0.5]), np.array([0.5]))
        P.append(sp.P[0])
        N.append(sp.normal[0])
    return np.array(P).reshape(-1, 3), np.array(N).reshape(-1, 3)


def _triad(ax, v: scene.View) -> None:
    """Small X, Y, Z arrows in the lower left corner showing a 3D view's orientation (the top
    view has X and Y on its axes)."""
    if v is scene.TOP:
        return
    o = np.array([0.07, 0.09])
    for k, (name, c) in enumerate((("X", "#c0392b"), ("Y", "#27ae60"), ("Z", "#2c6fbb"))):
        e = np.zeros(3)
        e[k] = 1.0
        d = np.array([e @ v.right, e @ v.up]) * 0.055
        if np.linalg.norm(d) < 1e-3:
            ax.text(*o, f"{name} toward you", transform=ax.transAxes, fontsize=8, color=c, ha="left", va="top")
            continue
        ax.annotate("", xy=o + d, xytext=o, xycoords="axes fraction",
                    arrowprops=dict(arrowstyle="-|>", color=c, lw=1.4))
        ax.text(*(o + 1.3 * d), name, transform=ax.transAxes, fontsize=8, color=c, ha="center", va="center",
                fontweight="bold")


def _on_patch(model, patch: int, uv0, uv1, samples: int = 17) -> np.ndarray:
    """Points of the straight (u, v) segment uv0 -> uv1 on a patch (mm)."""
    t = np.linspace(0.0, 1.0, samples)[:, None]
    uv = np.clip(np.asarray(uv0, float) * (1 - t) + np.asarray(uv1, float) * t, 1e-7, 1 - 1e-7)
    return model.patches[patch].evaluate(uv[:, 0], uv[:, 1]).P


def graph_lines(model, layout, pairs_boundary, pairs_corner):
    """The adjacency graph on the surface (shang2020 figure 4): each boundary link runs from
    a patch centre to the shared edge's midpoint and on to the other centre, each corner link
    through the shared corner; polylines (k, 3) per link."""
    mid = np.array([0.5, 0.5])
    edge_of = {}
    for link in layout.edge_links:
        edge_of.setdefault((min(link.a, link.b), max(link.a, link.b)), link)
    boundary = []
    for a, b in pairs_boundary:
        link = edge_of[(a, b)]
        ma = CORNER_UV[list(EDGE_CORNERS[link.ea])].mean(axis=0)
        mb = CORNER_UV[list(EDGE_CORNERS[link.eb])].mean(axis=0)
        boundary.append(np.vstack([_on_patch(model, link.a, mid, ma), _on_patch(model, link.b, mb, mid)]))
    corner = []
    for a, b in pairs_corner:
        node = sorted(set(layout.corner_nodes[a].tolist()) & set(layout.corner_nodes[b].tolist()))[0]
        ca = CORNER_UV[list(layout.corner_nodes[a]).index(node)]
        cb = CORNER_UV[list(layout.corner_nodes[b]).index(node)]
        corner.append(np.vstack([_on_patch(model, a, mid, ca), _on_patch(model, b, cb, mid)]))
    return boundary, corner


# -- patch layout ------------------------------------------------------------------------------
def layout_figure(out: str, model, plist=None, colours=None) -> dict:
    """Patches, extraordinary points and the adjacency graph (boundary links solid, corner
    links dashed) in the top view, and the patches in a 3D view; patch numbers on both."""
    from ..layout.layout import Layout
    from ..plan.graph import BOUNDARY, CORNER, PatchGraph
    layout = Layout.from_model(model)
    graph = PatchGraph(layout)
    n = len(model.patches)
    colours = style.patch_colours(n) if colours is None else colours
    quads = scene.surface_quads(model)
    borders = _patch_borders(model)
    centres, cnormals = _centres(model)
    eps = [e for e in model.extraordinary if not e.boundary]
    step_of = {s.patch: i + 1 for i, s in enumerate(plist.steps)} if plist is not None else {}
    boundary_pairs = sorted({(min(a, b), max(a, b)) for a, b in zip(*np.nonzero(graph.kind == BOUNDARY))})
    corner_pairs = sorted({(min(a, b), max(a, b)) for a, b in zip(*np.nonzero(graph.kind == CORNER))})
    lines_b, lines_c = graph_lines(model, layout, boundary_pairs, corner_pairs)
    with style.drawing():
        fig = style.figure(*SIZES["layout"])
        axes = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.0, 1.0]})
        for ax, v in zip(axes, (scene.TOP, scene.ISO)):
            sc = scene.Scene(v, lift=1.5 * quads.size)
            _surface(sc, quads, colours, light=0.35)
            for line in borders:
                sc.polyline(line, "#202020", width=1.1)
            sc.draw(ax)
            xy, _ = v.project(centres)
            seen = np.ones(n, bool) if v is scene.TOP else scene.facing(v, cnormals)
            if v is scene.TOP:
                for line in lines_b:
                    q = v.project(line)[0]
                    ax.plot(q[:, 0], q[:, 1], color="black", lw=2.2, zorder=5, solid_capstyle="round")
                for line in lines_c:
                    q = v.project(line)[0]
                    ax.plot(q[:, 0], q[:, 1], color="black", lw=1.5, ls=(0, (4, 3)), zorder=5)
            ep_xy = v.project(np.array([e.position for e in eps]).reshape(-1, 3))[0]
            ax.scatter(ep_xy[:, 0], ep_xy[:, 1], s=70, c=style.AIR, edgecolors="white", linewidths=1.2,
                       zorder=7)
            for k in np.nonzero(seen)[0]:
                ax.text(xy[k, 0], xy[k, 1], str(k), ha="center", va="center", fontsize=11, fontweight="bold",
                        zorder=8, bbox=dict(boxstyle="circle,pad=0.3", fc="white", ec=colours[k][:3], lw=2.0))
                if k in step_of and v is scene.TOP:
                    ax.annotate(f"step {step_of[k]}", xy[k], xytext=(0, -14), textcoords="offset points",
                                ha="center", va="top", fontsize=8, zorder=8, color="#222222",
                                bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.85))
            scene.plain_axes(ax, v, "Patches and adjacency graph, top view" if v is scene.TOP
                             else "Patches, 3D view")
            _triad(ax, v)
        from matplotlib.lines import Line2D
        handles = [Line2D([], [], color="black", lw=2.2, label="boundary link (shared edge)"),
                   Line2D([], [], color="black", lw=1.5, ls=(0, (4, 3)), label="corner link (shared corner)"),
                   Line2D([], [], marker="o", ls="none", mfc=style.AIR, mec="white", ms=9,
                          label=f"extraordinary point ({len(eps)})")]
        axes[1].legend(handles=handles, loc="lower right", frameon=False)
        style.patch_legend(axes[1], colours, range(n), loc="upper left", bbox_to_anchor=(1.0, 1.0))
        style.title(fig, f"{model.name}: {n} patches, {len(eps)} extraordinary points, "
                     f"{len(boundary_pairs)} boundary links, {len(corner_pairs)} corner links")
        style.arrange(fig, [axes])
        style.save(fig, out)
    return {"patches": n, "extraordinary": len(eps), "boundary_links": len(boundary_pairs),
            "corner_links": len(corner_pairs)}


# -- tool path ---------------------------------------------------------------------------------
def path_figure(out: str, model, path, colours=None) -> dict:
    """The path coloured by patch, links on the surface black, air moves red dashed, in the
    top view and a 3D view."""
    n = len(model.patches)
    colours = style.patch_colours(n) if colours is None else colours
    quads = scene.surface_quads(model)
    mv = np.asarray(path.move)[1:]
    on = path.patch >= 0
    P = np.where(on[:, None], path.contact, path.center)
    surf = on[:-1] & on[1:]
    cut = surf & (mv == Move.CUT)
    link = surf & (mv != Move.CUT)
    air = ~surf
    seg_col = style.band_colours(path.patch[1:], colours)
    # lines about half their spacing wide in the picture, so the patch colours read
    lo, hi = model.bounding_box(5)
    step = np.sqrt(8.0 * path.tool_radius * float(path.info.get("settings", {}).get("scallop", 0.01)))
    px_per_mm = 560.0 / max(float(np.max((np.asarray(hi) - np.asarray(lo))[:2])), 1e-9)
    lw = float(np.clip(0.5 * step * px_per_mm * 72.0 / style.DPI, 0.35, 1.0))
    with style.drawing():
        fig = style.figure(*SIZES["path"])
        axes = fig.subplots(1, 2)
        for ax, v in zip(axes, (scene.TOP, scene.ISO)):
            sc = scene.Scene(v, lift=1.5 * quads.size)
            grey = np.tile([0.93, 0.93, 0.93, 1.0], (len(quads.patch), 1))
            sc.polygons(quads.corners, scene.shade(grey, quads.normal, v, ambient=0.75), width=0.3)
            sc.polyline(P, seg_col, keep=cut, width=lw)
            sc.polyline(P, style.LINK, keep=link, width=1.6)
            sc.polyline(P, style.AIR, keep=air, width=1.3, dashes=(4, 2))
            sc.draw(ax)
            s0, _ = v.project(P[0])
            s1, _ = v.project(P[-1])
            ax.plot(*s0, marker="^", ms=11, mfc="#2ecc71", mec="black", zorder=6, ls="none")
            ax.plot(*s1, marker="s", ms=9, mfc="white", mec="black", zorder=6, ls="none")
            scene.plain_axes(ax, v, "Top view" if v is scene.TOP else "3D view")
            _triad(ax, v)
        from matplotlib.lines import Line2D
        handles = [Line2D([], [], color=style.LINK, lw=1.6, label=f"link on the surface ({int(link.sum())})"),
                   Line2D([], [], color=style.AIR, lw=1.3, ls=(0, (4, 2)), label=f"air move ({int(air.sum())})"),
                   Line2D([], [], marker="^", ms=9, mfc="#2ecc71", mec="black", ls="none", label="start"),
                   Line2D([], [], marker="s", ms=8, mfc="white", mec="black", ls="none", label="end")]
        axes[1].legend(handles=handles, loc="lower right", frameon=False)
        order = list(dict.fromkeys(int(p) for p in path.patch[on]))
        style.patch_legend(axes[1], colours, order, title="patch\n(in order)", loc="upper left",
                           bbox_to_anchor=(1.0, 1.0))
        lines = len(np.unique(path.line[path.line >= 0]))
        style.title(fig, f"Tool path coloured by patch: {len(path):,} points, {lines} lines, "
                     f"{path.retractions} retractions")
        style.arrange(fig, [axes])
        style.save(fig, out)
    return {"cut_segments": int(cut.sum()), "link_segments": int(link.sum()), "air_segments": int(air.sum()),
            "patch_order": order}


# -- scallop -------------------------------------------------------------------------------
def scallop_cells(model, heights, cell: float):
    """Largest material height (mm) in cells of about ``cell`` mm on every patch (nan where no
    sample fell): (SurfaceQuads of the cells, value per cell)."""
    g = np.linspace(0.0, 1.0, 9)
    sizes = []
    for p in model.patches:
        P = p.evaluate_grid(np.clip(g, 1e-7, 1 - 1e-7), np.clip(g, 1e-7, 1 - 1e-7)).P.reshape(9, 9, 3)
        su = float(np.linalg.norm(np.diff(P, axis=0), axis=2).sum(axis=0).max())
        sv = float(np.linalg.norm(np.diff(P, axis=1), axis=2).sum(axis=1).max())
        sizes.append((max(2, int(np.ceil(su / cell))), max(2, int(np.ceil(sv / cell)))))
    quads = scene.surface_quads(model, cells=sizes)
    offset = np.concatenate([[0], np.cumsum([nu * nv for nu, nv in sizes])])
    value = np.full(len(quads.patch), -np.inf)
    nu = np.array([s[0] for s in sizes])[heights.patch]
    nv = np.array([s[1] for s in sizes])[heights.patch]
    iu = np.minimum((heights.uv[:, 0] * nu).astype(int), nu - 1)
    iv = np.minimum((heights.uv[:, 1] * nv).astype(int), nv - 1)
    np.maximum.at(value, offset[heights.patch] + iu * nv + iv, heights.height)
    value[~np.isfinite(value)] = np.nan
    return quads, value


def scallop_figure(out: str, model, verification, limit: float, tool_radius: float, known: bool = True) -> dict:
    """The scallop-height map measured on the surface (largest height per small cell, top and
    3D view) and the distribution of the measured heights, against the limit.

    A cell spans more than the flat side step ``sqrt(8 r h)``, so every cell holds a cusp and
    the map shows the largest scallop near each place, not the stripes of the lines. ``known``:
    False when the path does not say its limit (then ``limit`` only scales the colours)."""
    from matplotlib import colormaps
    from matplotlib.colors import Normalize
    hs = verification.heights
    lo, hi = model.bounding_box(5)
    diag = float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
    cell = max(diag / 140.0, 2.0 * verification.spacing, 1.6 * np.sqrt(8.0 * tool_radius * limit))
    quads, value = scallop_cells(model, hs, cell)
    um = 1000.0
    cmap = colormaps["viridis"].with_extremes(over=style.AIR, under="#2b3cff", bad="#d9d9d9")
    norm = Normalize(0.0, limit * um)
    face = cmap(norm(value * um))
    face[np.isnan(value)] = (0.85, 0.85, 0.85, 1.0)
    with style.drawing():
        fig = style.figure(*SIZES["scallop"])
        axes = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.0, 1.0, 0.62]})
        for ax, v in zip(axes[:2], (scene.TOP, scene.ISO)):
            sc = scene.Scene(v)
            sc.polygons(quads.corners, scene.shade(face, quads.normal, v, ambient=0.8), width=0.2)
            sc.draw(ax)
            scene.plain_axes(ax, v, "Top view" if v is scene.TOP else "3D view")
            _triad(ax, v)
        from matplotlib.cm import ScalarMappable
        cax = fig.add_axes([0.25, 0.1, 0.4, 0.025])
        cb = fig.colorbar(ScalarMappable(norm, cmap), cax=cax, orientation="horizontal", extend="both")
        cb.set_label(f"largest scallop height in a {cell:.2f} mm cell (µm); red above the {limit * um:g} µm "
                     "limit, blue a gouge" if known else
                     f"largest scallop height in a {cell:.2f} mm cell (µm); blue a gouge")
        ax = axes[2]
        grid_h = hs.height[~hs.ridge] * um
        cusp = np.asarray(verification.cusp_heights if verification.cusp_heights is not None else [], float) * um
        top = max(limit * um * 1.15, float(np.nanmax(hs.height)) * um * 1.02 if len(hs) else 0.0)
        bins = np.linspace(min(0.0, float(grid_h.min()) if len(grid_h) else 0.0), top, 60)
        ax.hist(np.clip(grid_h, bins[0], bins[-1]), bins=bins, color="#7f9cc0", label=f"surface samples ({len(grid_h):,})")
        if len(cusp):
            ax.hist(np.clip(cusp, bins[0], bins[-1]), bins=bins, color="#e08a2c", alpha=0.85,
                    label=f"cusp ridges between lines ({len(cusp):,})")
        if known:
            ax.axvline(limit * um, color=style.AIR, lw=2.0, label=f"limit {limit * um:g} µm")
        ax.axvline(verification.max_scallop * um, color="black", lw=1.4, ls=(0, (4, 2)),
                   label=f"largest {verification.max_scallop * um:.2f} µm")
        ax.set_yscale("log")
        ax.set_ylim(0.7, ax.get_ylim()[1] * 40.0)           # room for the legend above the bars
        ax.axvline(0.0, color="#888888", lw=0.8)
        ax.set_xlabel("material height left on the surface (µm)")
        ax.set_ylabel("count (log scale)")
        ax.set_title("Measured heights")
        ax.legend(loc="upper left", fontsize=8, framealpha=0.92)
        ratio = f" = {verification.max_scallop / limit:.2f} of the {limit * um:g} µm limit" if known else ""
        style.title(fig, f"Scallop height measured on the surface: largest {verification.max_scallop * um:.2f} µm"
                     f"{ratio}, mean cusp {verification.cusp_mean * um:.2f} µm")
        # the colour bar under the two views, centred, 55 % of their width; its ticks and label below it
        bar = 15.0
        below = style.overhang(cax)[2]
        style.arrange(fig, [axes], widths=[1.0, 1.0, 0.62], bottom=below + bar + style.GAP)
        x0, x1 = axes[0].bbox.x0, axes[1].bbox.x1
        style.place(cax, 0.5 * (x0 + x1) - 0.275 * (x1 - x0), style.PAD + below, 0.55 * (x1 - x0), bar)
        style.save(fig, out)
    finite = value[np.isfinite(value)]
    return {"cells": int(len(value)), "cells_measured": int(len(finite)), "cell_mm": cell,
            "cells_over_limit": int(np.count_nonzero(finite > limit)),
            "largest_cell": float(finite.max()) if len(finite) else float("nan")}


# -- along the path ----------------------------------------------------------------------------
def path_distance(points: np.ndarray) -> np.ndarray:
    """Distance along a polyline from its first point (mm)."""
    seg = np.linalg.norm(np.diff(np.asarray(points, float), axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)])


def _coloured_line(ax, x, y, patch, colours, lw: float = 1.0) -> None:
    """y over x, each piece in its patch's colour (grey off the surface); ``patch[i]`` colours
    the piece from point i - 1 to point i.

    Drawn as one polyline per run of pieces of one colour, not piece by piece: a
    LineCollection of tens of thousands of two-point lines cost a tenth of a second to build
    and as much to draw per plot, and its butt-ended pieces overlap at every joint."""
    from matplotlib.collections import LineCollection
    pts = np.column_stack([np.asarray(x, float), np.asarray(y, float)])
    key = np.asarray(patch, int)[1:]
    key = np.where((key >= 0) & (key < len(colours)), key, -1)
    good = np.isfinite(pts).all(axis=1)
    ok = good[:-1] & good[1:]
    m = len(key)
    if m:
        same = np.concatenate([[False], ok[:-1] & (key[1:] == key[:-1])])     # piece i continues i - 1
        start = np.nonzero(ok & ~same)[0]
        end = np.nonzero(ok & ~np.concatenate([same[1:], [False]]))[0]       # last piece of each run
        runs = [pts[a:b + 2] for a, b in zip(start, end)]
        if runs:
            ax.add_collection(LineCollection(runs, colors=style.band_colours(key[start], colours), linewidths=lw))
    ax.autoscale_view()


def axis_figure(out: str, path, colours) -> dict:
    """The tool axis along the path: its tilt from +Z and its angle to the surface normal, and
    its change from point to point."""
    s = path_distance(path.tip)
    K = path.axis
    tilt = np.degrees(np.arccos(np.clip(K[:, 2], -1.0, 1.0)))
    lead = np.degrees(np.arctan2(np.linalg.norm(np.cross(K, path.normal), axis=1),
                                 np.einsum("ij,ij->i", K, path.normal)))
    step = np.degrees(np.arctan2(np.linalg.norm(np.cross(K[1:], K[:-1]), axis=1),
                                 np.einsum("ij,ij->i", K[1:], K[:-1])))
    k = int(np.argmax(step)) if len(step) else 0
    with style.drawing():
        fig = style.figure(*SIZES["axis"])
        a1, a2 = fig.subplots(2, 1, sharex=True)
        a1.plot(s, lead, color="#555555", lw=0.7, ls=(0, (3, 2)), label="angle to the surface normal")
        _coloured_line(a1, s, tilt, path.patch, colours, lw=1.6)
        a1.plot([], [], color=colours[0], lw=1.6, label="tilt from +Z (coloured by patch)")
        a1.set_ylabel("angle (deg)")
        a1.set_title("Tool axis: tilt from vertical and angle to the surface normal")
        a1.legend(loc="upper right")
        _coloured_line(a2, s[1:], step, path.patch[1:], colours, lw=1.0)
        if len(step):
            a2.plot([s[k + 1]], [step[k]], marker="o", mfc="none", mec=style.AIR, ms=10, mew=1.5)
            a2.annotate(f"largest {step[k]:.2f} deg at point {k + 1}", (s[k + 1], step[k]), xytext=(10, 0),
                        textcoords="offset points", color=style.AIR, va="center",
                        bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="none", alpha=0.9))
        a2.set_ylabel("axis change to the next point (deg)")
        a2.set_xlabel("distance along the path, tool tip (mm)")
        a2.set_title("Tool-axis change from point to point")
        a2.set_ylim(bottom=0.0)
        a2.set_xlim(s[0], s[-1])
        style.patch_legend(a1, colours, list(dict.fromkeys(int(p) for p in path.patch[path.patch >= 0])),
                           loc="upper left", bbox_to_anchor=(1.0, 1.0))
        style.arrange(fig, [[a1], [a2]])
        style.save(fig, out)
    return {"max_step_deg": float(step.max()) if len(step) else 0.0, "max_tilt_deg": float(tilt.max()),
            "max_to_normal_deg": float(lead.max()), "length_mm": float(s[-1])}


def _row_patch(path, source: np.ndarray) -> np.ndarray:
    """Patch of every program row (-1 for approach, retract and off-surface rows)."""
    src = np.asarray(source, float)
    idx = np.clip(np.floor(np.where(src >= 0, src, 0)).astype(int), 0, len(path) - 1)
    return np.where(src >= 0, path.patch[idx], -1)


def program_time(posted) -> np.ndarray:
    """Time (s) at every program row from the machining-time estimate."""
    return np.concatenate([[0.0], np.cumsum(posted.time.block_time)])


def machine_figure(out: str, path, posted, colours) -> dict:
    """Each machine axis over the program time (X, Y, Z of the gauge point; the two rotaries),
    with the machine's travel limits, and a gauge of the travel each axis uses."""
    m = posted.machine
    L = float(posted.settings["tool_length"])
    J = np.array(posted.joints, float, copy=True)
    J[:, 2] += L
    t = program_time(posted)
    patch = _row_patch(path, posted.motion.source)
    names = m.axis_names
    axes_def = [m.linear["X"], m.linear["Y"], m.linear["Z"], m.tilt, m.rotary]
    used = {}
    with style.drawing():
        fig = style.figure(*SIZES["machine"])
        gs = fig.add_gridspec(5, 2, width_ratios=[1.0, 0.045])
        first = None
        grid = []
        for j, (name, ax_def) in enumerate(zip(names, axes_def)):
            ax = fig.add_subplot(gs[j, 0], sharex=first)
            first = first or ax
            unit = "mm" if j < 3 else "deg"
            y = J[:, j]
            _coloured_line(ax, t, y, patch, colours, lw=1.2)
            lo, hi = float(y.min()), float(y.max())
            on = patch >= 0
            wlo, whi = (float(y[on].min()), float(y[on].max())) if on.any() else (lo, hi)
            span = max(whi - wlo, 1.0 if j < 3 else 5.0)
            view = (wlo - 0.12 * span, whi + 0.12 * span)
            lim_lo, lim_hi = getattr(ax_def, "min", None), getattr(ax_def, "max", None)
            endless = bool(getattr(ax_def, "continuous", False)) or lim_lo is None
            for lim, side in ((lim_lo, "min"), (lim_hi, "max")):
                if endless or lim is None:
                    continue
                if view[0] - 2 * span <= lim <= view[1] + 2 * span:
                    view = (min(view[0], lim - 0.08 * span), max(view[1], lim + 0.08 * span))
                    ax.axhline(lim, color=style.AIR, lw=1.6, ls=(0, (6, 3)))
                    ax.annotate(f"{side} {lim:g} {unit}", (0.995, lim), xycoords=("axes fraction", "data"),
                                xytext=(0, -3 if side == "max" else 3), textcoords="offset points", ha="right",
                                va="top" if side == "max" else "bottom", color=style.AIR, fontsize=8)
    
            ax.set_ylim(*view)
            ax.set_ylabel(f"{name} (mm)" if j < 3 else f"{name} (deg)")
            what = f"{name} of the spindle gauge point (tool length {L:g} mm)" if j == 2 else name
            info = f"{what}: {wlo:.3f} to {whi:.3f} {unit} on the surface"
            if lo < wlo - 1e-6 or hi > whi + 1e-6:
                info += f", {lo:.3f} to {hi:.3f} with approach and retract"
            info += "; endless axis" if endless else f" (travel {lim_lo:g} to {lim_hi:g} {unit})"
            ax.set_title(info, loc="left", fontsize=9, fontweight="normal")
            if j < 4:
                ax.tick_params(labelbottom=False)
            else:
                ax.set_xlabel("program time (s)")
            # gauge: the travel of the axis and the part of it the program uses
            g = fig.add_subplot(gs[j, 1])
            g.grid(False)
            g.set_xticks([])
            if endless:
                g.set_ylim(lo - 0.1 * span, hi + 0.1 * span)
                g.bar(0, hi - lo, bottom=lo, width=0.8, color="#555555")
                g.set_title("endless", fontsize=7)
                frac = float("nan")
            else:
                g.bar(0, lim_hi - lim_lo, bottom=lim_lo, width=0.8, color="#e6e6e6", edgecolor="#999999")
                g.bar(0, max(hi - lo, 1e-3 * (lim_hi - lim_lo)), bottom=lo, width=0.8, color="#333333")
                g.set_ylim(lim_lo, lim_hi)
                frac = (hi - lo) / (lim_hi - lim_lo)
                g.set_title(f"{100 * frac:.0f} %", fontsize=7)
            g.yaxis.tick_right()
            g.tick_params(labelsize=7)
            grid.append([ax, g])
            used[name] = {"min": lo, "max": hi, "limit_min": None if endless else lim_lo,
                          "limit_max": None if endless else lim_hi, "fraction": frac}
        first.set_xlim(t[0], t[-1])
        style.title(fig, f"Machine axes along the program: {m.name} ({m.kind})")
        style.arrange(fig, grid, widths=[1.0, 0.045])
        style.save(fig, out)
    return used


def clearance_figure(out: str, path, series: dict, required: float, colours, top: float) -> dict:
    """Clearance along the path of each tool part group (``series``: name -> (point indices,
    mm; inf beyond ``top``)), with the clearance the orientation kept."""
    s = path_distance(path.tip)
    res = {}
    with style.drawing():
        fig = style.figure(*SIZES["clearance"])
        ax = fig.subplots()
        lows = []
        for k, (name, (idx, d)) in enumerate(series.items()):
            idx, d = np.asarray(idx, int), np.asarray(d, float)
            shown = np.where(np.isfinite(d), d, top)
            i = int(np.argmin(shown))
            label = f"{name}: smallest {shown[i]:.3f} mm at point {idx[i]}"
            if k == 0:
                _coloured_line(ax, s[idx], shown, path.patch[idx], colours, lw=1.3)
                ax.plot([], [], color="#555555", lw=1.3, label=label + " (line coloured by patch)")
            else:
                ax.plot(s[idx], shown, color="#222222", label=label, lw=1.0, ls=(0, (4, 2)))
            lows.append(shown[i])
            ax.plot([s[idx[i]]], [shown[i]], marker="v", ms=9, color="black", ls="none", zorder=5)
            res[name] = {"min": float(shown[i]), "at": int(idx[i]), "poses": int(len(idx)),
                         "beyond_top": int(np.count_nonzero(~np.isfinite(d)))}
        ax.axhline(required, color=style.AIR, lw=1.6, ls=(0, (6, 3)), label=f"clearance kept {required:g} mm")
        ax.axhspan(top, top * 1.6, color="#eeeeee", zorder=0)
        ax.text(s[-1], top * 1.05, f"more than {top:g} mm", ha="right", va="bottom", fontsize=8, color="#666666")
        ax.set_yscale("log")
        ax.set_ylim(max(min(lows + [required]) * 0.6, 1e-3), top * 1.6)
        ax.set_xlim(s[0], s[-1])
        ax.set_xlabel("distance along the path, tool tip (mm)")
        ax.set_ylabel("distance to the part (mm, log scale)")
        ax.set_title("Clearance along the path: shank and holder to the workpiece (part, stock, fixtures)")
        ax.legend(loc="lower right", ncol=1, framealpha=0.9)
        style.arrange(fig, [[ax]])
        style.save(fig, out)
    return res


def time_figure(out: str, path, posted, colours) -> dict:
    """What sets the machining time: the seconds set by the feed and by each axis, and the
    tool-tip speed along the program against the programmed feed."""
    tr = posted.time
    by = tr.time_by_limit()
    t = program_time(posted)
    tip = np.asarray(posted.tip, float)
    length = np.linalg.norm(np.diff(tip, axis=0), axis=1)
    bt = np.asarray(tr.block_time, float)
    feed_rows = ~np.asarray(posted.motion.rapid, bool)[1:]
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where((bt > 0) & feed_rows, length / bt * 60.0, np.nan)
    patch = _row_patch(path, posted.motion.source)[1:]
    with style.drawing():
        fig = style.figure(*SIZES["time"])
        a1, a2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [0.55, 1.0]})
        names = ["feed", *tr.axis_names]
        vals = np.array([by[n] for n in names])
        cols = ["#4c72b0"] + ["#8c8c8c"] * len(tr.axis_names)
        bars = a1.barh(np.arange(len(names))[::-1], vals, color=cols)
        for b, v in zip(bars, vals):
            a1.text(b.get_width(), b.get_y() + b.get_height() / 2, f" {v:.1f} s ({100 * v / max(tr.total_s, 1e-12):.0f} %)",
                    va="center", fontsize=9)
        a1.set_yticks(np.arange(len(names))[::-1], ["programmed feed", *[f"axis {n}" for n in tr.axis_names]])
        a1.set_xlim(0, max(vals.max() * 1.45, 1e-6))
        a1.set_xlabel("time of the blocks it sets (s)")
        a1.set_title("What sets each block's time")
        mid = 0.5 * (t[:-1] + t[1:])
        ok = np.isfinite(speed)
        _coloured_line(a2, mid[ok], speed[ok], patch[ok], colours, lw=0.8)
        a2.axhline(path.feed, color=style.AIR, lw=1.5, ls=(0, (6, 3)), label=f"programmed feed {path.feed:g} mm/min")
        a2.set_xlim(t[0], t[-1])
        a2.set_ylim(0, max(path.feed * 1.15, float(np.nanmax(speed)) * 1.05 if ok.any() else 1.0))
        a2.set_xlabel("program time (s)")
        a2.set_ylabel("tool-tip speed (mm/min)")
        a2.set_title("Tool-tip speed in feed blocks (coloured by patch)")
        a2.legend(loc="lower right")
        style.title(fig, f"Machining time {tr.total_s:.1f} s (cutting {tr.cut_s:.1f} s, air {tr.air_s:.1f} s) "
                     f"against {tr.feed_only_s:.1f} s of length over feed")
        style.arrange(fig, [[a1, a2]], widths=[0.55, 1.0])
        style.save(fig, out)
    return {"by_limit": by, "mean_feed_speed": float(np.nanmean(speed)) if ok.any() else float("nan")}


def baseline_figure(out: str, rows: dict) -> dict:
    """The T-spline path against the compound-NURBS baseline: retractions, air moves, length
    (cutting, links, air) and machining time. ``rows``: label -> dict of those figures."""
    labels = list(rows)
    cols = ["#2c6fbb", "#9a9a9a"]
    with style.drawing():
        fig = style.figure(*SIZES["baseline"])
        axes = fig.subplots(1, 4)
        x = np.arange(len(labels))
        for ax, key, title, unit in ((axes[0], "retractions", "Retractions", "count"),
                                     (axes[1], "air_moves", "Air moves", "count")):
            v = [rows[n][key] for n in labels]
            b = ax.bar(x, v, color=cols[:len(labels)])
            ax.bar_label(b, labels=[f"{int(q)}" for q in v], padding=2)
            ax.set_title(title)
            ax.set_ylabel(unit)
            ax.set_ylim(0, max(max(v) * 1.25, 1))
        ax = axes[2]
        bottom = np.zeros(len(labels))
        for key, name, c in (("cut_length", "cutting", "#4c72b0"), ("link_length", "links", "#111111"),
                             ("air_length", "air", style.AIR)):
            v = np.array([rows[n][key] for n in labels])
            ax.bar(x, v, bottom=bottom, color=c, label=name)
            bottom += v
        for i, tot in enumerate(bottom):
            ax.text(i, tot, f"{tot:.1f}", ha="center", va="bottom")
        ax.set_ylim(0, bottom.max() * 1.15)
        ax.set_title("Path length")
        ax.set_ylabel("length (mm)")
        ax.legend(loc="lower right", fontsize=8)
        ax = axes[3]
        v = [rows[n].get("time_s", float("nan")) for n in labels]
        b = ax.bar(x, np.nan_to_num(v), color=cols[:len(labels)])
        ax.bar_label(b, labels=[f"{q:.1f}" if np.isfinite(q) else "n/a" for q in v], padding=2)
        ax.set_title("Machining time")
        ax.set_ylabel("time (s)")
        ax.set_ylim(0, max(np.nan_to_num(v).max() * 1.2, 1.0))
        for ax in axes:
            ax.set_xticks(x, [lb.replace(" ", "\n", 1) for lb in labels])
            ax.grid(axis="x", visible=False)
        style.title(fig, "T-spline path against the compound-NURBS baseline (each face cut on its own)")
        style.arrange(fig, [list(axes)])
        style.save(fig, out)
    return {n: dict(rows[n]) for n in labels}
