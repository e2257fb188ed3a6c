"""How the report's pictures look: one set of matplotlib settings, the patch colours every
picture shares, and byte-stable PNG output.

Pictures are drawn on ``matplotlib.figure.Figure`` objects with the Agg canvas, never
through pyplot, so the report neither needs nor changes a GUI backend (the FreeCAD workbench
runs Qt). Fonts, sizes and the PNG metadata are fixed, so the same data give the same bytes.
"""
from __future__ import annotations

import colorsys
from contextlib import contextmanager

import numpy as np

DPI = 100
RC = {"font.family": "DejaVu Sans", "font.size": 10, "axes.titlesize": 12, "axes.titleweight": "bold",
      "axes.labelsize": 10, "legend.fontsize": 9, "figure.titlesize": 14, "figure.titleweight": "bold",
      "axes.grid": True, "grid.color": "#d8d8d8", "grid.linewidth": 0.6, "axes.axisbelow": True,
      "figure.facecolor": "white", "axes.facecolor": "white", "savefig.facecolor": "white",
      "path.simplify": True, "svg.hashsalt": "tsplcam", "figure.dpi": DPI, "savefig.dpi": DPI}

# Patch colours: matplotlib's tab10/tab20 without its red and greys (red marks extraordinary
# points, air moves and limits; grey marks moves off the surface), then evenly spread hues.
_BASE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf",
         "#aec7e8", "#ffbb78", "#98df8a", "#c5b0d5", "#c49c94", "#f7b6d2", "#dbdb8d", "#9edae5"]
AIR = "#d62728"          # retract, rapid and approach moves; out-of-limit marks
LINK = "#111111"         # links on the surface between lines and patches
OFF = "#9a9a9a"          # points off the surface in along-the-path bands


def patch_colours(n: int) -> np.ndarray:
    """(n, 4) RGBA colours, patch k always the same colour in every picture."""
    from matplotlib.colors import to_rgba
    out = [to_rgba(c) for c in _BASE[:n]]
    k = 0
    while len(out) < n:                      # golden-ratio hues beyond the table
        h = (0.07 + 0.618034 * k) % 1.0
        out.append((*colorsys.hsv_to_rgb(h, 0.55 if k % 2 else 0.75, 0.85 if k % 3 else 0.7), 1.0))
        k += 1
    return np.array(out, float).reshape(-1, 4)


def band_colours(patch: np.ndarray, colours: np.ndarray) -> np.ndarray:
    """RGBA per entry of ``patch`` (-1 and other off-surface values: grey)."""
    from matplotlib.colors import to_rgba
    p = np.asarray(patch, int)
    out = np.tile(np.array(to_rgba(OFF)), (len(p), 1))
    on = (p >= 0) & (p < len(colours))
    out[on] = colours[p[on]]
    return out


@contextmanager
def drawing():
    """The report's matplotlib settings for the pictures drawn inside."""
    import matplotlib
    with matplotlib.rc_context(RC):
        yield


#: pixels kept free at a picture's edges and between a title and what is under it
PAD = 4.0
#: pixels between neighbouring axes (beyond their tick labels, labels and titles)
GAP = 12.0


def figure(width: int, height: int):
    """A Figure of width x height pixels (at :data:`DPI`) on an Agg canvas, without a layout
    engine: every picture places its axes with :func:`arrange` (or :func:`place`). (A
    hundredth of a pixel more in inches: matplotlib truncates, and 4.6 * 100 is
    459.99999999999994 in floating point.)"""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=((width + 0.01) / DPI, (height + 0.01) / DPI), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def place(ax, left: float, bottom: float, width: float, height: float) -> None:
    """Put ``ax``'s box at pixels (left, bottom, width, height) from the figure's lower left."""
    W, H = ax.figure.bbox.width, ax.figure.bbox.height
    ax.set_position([left / W, bottom / H, width / W, height / H])


def overhang(ax) -> np.ndarray:
    """Pixels by which what ``ax`` draws around its box (tick labels, axis labels, title,
    legends outside it) reaches past the box: (left, right, bottom, top), none negative."""
    renderer = ax.figure.canvas.get_renderer()
    ax.apply_aspect()
    tb = ax.get_tightbbox(renderer, for_layout_only=True)
    b = ax.bbox
    return np.maximum([b.x0 - tb.x0, tb.x1 - b.x1, b.y0 - tb.y0, tb.y1 - b.y1], 0.0)


def title(fig, text: str):
    """The figure's title at its top edge; returns it."""
    return fig.suptitle(text, y=1.0 - PAD / fig.bbox.height, va="top")


def _guess(ax) -> np.ndarray:
    """The usual :func:`overhang` of ``ax`` from what it shows, without measuring: tick
    labels and a label left and below, a title above."""
    left = (40.0 if ax.yaxis.get_label_text() else 0.0) + (25.0 if ax.get_yticks().size else 0.0)
    bottom = (20.0 if ax.xaxis.get_label_text() else 0.0) + (20.0 if ax.get_xticks().size else 0.0)
    top = 20.0 if ax.get_title() or ax.get_title(loc="left") else 0.0
    return np.array([left, 0.0, bottom, top])


def arrange(fig, grid, widths=None, heights=None, *, top: float = 0.0, bottom: float = 0.0,
            left: float = 0.0, right: float = 0.0) -> None:
    """Lay out the axes of ``grid`` (rows of axes, None for an empty cell) in the figure:
    columns as wide as ``widths`` say relative to each other (default equal), rows as high
    as ``heights`` say, each column and row keeping room for the largest :func:`overhang`
    of its axes, :data:`GAP` between them and :data:`PAD` at the edges, the figure's title
    (:func:`title`) above them and ``top``/``bottom``/``left``/``right`` more pixels free.

    A one-pass stand-in for matplotlib's constrained layout, which measures every axes
    twice (a quarter of the pictures' time): here each axes is measured once, in a first
    placement with room for the usual overhangs (:func:`_guess`), then placed for good, so
    that the box it is measured in and the one it is drawn in have about the same size and
    hold the same ticks."""
    W, H = fig.bbox.width, fig.bbox.height
    rows = [list(r) for r in grid]
    nr, nc = len(rows), len(rows[0])
    widths = np.ones(nc) if widths is None else np.asarray(widths, float)
    heights = np.ones(nr) if heights is None else np.asarray(heights, float)
    head = 0.0
    sup = getattr(fig, "_suptitle", None)
    if sup is not None:
        head = sup.get_window_extent(fig.canvas.get_renderer()).height + 2.0 * PAD
    top = top + head

    def put(lo, ro, bo, to) -> None:
        aw = W - left - right - 2 * PAD - lo.sum() - ro.sum() - GAP * (nc - 1)
        ah = H - top - bottom - 2 * PAD - bo.sum() - to.sum() - GAP * (nr - 1)
        cw, rh = aw * widths / widths.sum(), ah * heights / heights.sum()
        x = left + PAD + np.concatenate([[0.0], np.cumsum(lo + cw + ro + GAP)[:-1]]) + lo
        y = H - top - PAD - np.concatenate([[0.0], np.cumsum(to + rh + bo + GAP)[:-1]]) - to - rh
        for i, r in enumerate(rows):
            for j, ax in enumerate(r):
                if ax is not None:
                    place(ax, x[j], y[i], cw[j], rh[i])

    def fit(measure) -> None:
        m = np.zeros((nr, nc, 4))
        for i, r in enumerate(rows):
            for j, ax in enumerate(r):
                if ax is not None:
                    m[i, j] = measure(ax)
        put(m[:, :, 0].max(axis=0), m[:, :, 1].max(axis=0), m[:, :, 2].max(axis=1), m[:, :, 3].max(axis=1))

    fit(_guess)          # room for the usual overhangs
    fit(overhang)        # each axes measured where that put it, then placed for good


#: zlib level of the PNG pictures: 3 writes them in about half the time of the usual 6 (the
#: keycap's eight: 0.28 s against 0.50 s) at about the same size (RGB: 2.0 MB against 2.2 MB)
PNG_LEVEL = 3


def save(fig, path: str) -> None:
    """Write ``fig`` as an RGB PNG without metadata but its resolution.

    Drawn once on an Agg canvas and encoded by Pillow (which matplotlib's own PNG output
    uses too): ``savefig`` draws a figure with a layout engine twice (once, not shown, to
    lay it out) and writes RGBA; the pictures are opaque (white background), so RGB keeps
    every pixel and a quarter fewer bytes to compress. Pillow writes no text chunks, so the
    bytes do not name the versions."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    canvas.draw()
    rgba = Image.frombuffer("RGBA", canvas.get_width_height(), canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
    rgba.convert("RGB").save(path, format="png", compress_level=PNG_LEVEL, dpi=(DPI, DPI))


def patch_legend(ax, colours: np.ndarray, patches, title: str = "patch", loc: str = "upper right", **kw):
    """A legend of filled squares naming the patches (at most 20; more are summarised)."""
    from matplotlib.patches import Patch as Swatch
    if ax.get_legend() is not None:           # keep a legend the axes already has
        ax.add_artist(ax.get_legend())
    patches = list(patches)
    shown = patches[:20]
    handles = [Swatch(facecolor=colours[p], edgecolor="none", label=str(p)) for p in shown]
    if len(patches) > len(shown):
        handles.append(Swatch(facecolor="white", edgecolor="none", label=f"... {len(patches)} in all"))
    return ax.legend(handles=handles, title=title, loc=loc, ncol=1 if len(handles) <= 10 else 2,
                     handlelength=1.0, columnspacing=0.8, **kw)
