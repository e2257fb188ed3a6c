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


def figure(width: int, height: int):
    """A Figure of width x height pixels (at :data:`DPI`), laid out by matplotlib's constrained
    layout. (A hundredth of a pixel more in inches: matplotlib truncates, and 4.6 * 100 is
    459.99999999999994 in floating point.)"""
    from matplotlib.figure import Figure
    return Figure(figsize=((width + 0.01) / DPI, (height + 0.01) / DPI), dpi=DPI, layout="constrained")


def save(fig, path: str) -> None:
    """Write ``fig`` as PNG without the varying metadata (matplotlib's version string)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    FigureCanvasAgg(fig)
    fig.savefig(path, format="png", dpi=DPI, metadata={"Software": None})


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
