"""View provider of the program: the path, the tool axes, the stock and the tool itself.

* The path along the ball centres, coloured by ``ColourBy``: "Tilt" (gray, the axes tell),
  "Patch" (each patch's colour of the model's palette), or "Feed" (the feed each block runs
  at after the machine's axis limits, blue slow to red fast); links orange and thicker,
  retracts and rapids red dashed.
* Tool-axis glyphs: at every k-th path point (about ``Shafts`` of them, evenly along the
  path) a line from the ball centre along the tool axis, ``ShaftLength`` long, coloured by
  the angle between the axis and +Z (near black vertical, to red at the largest tilt).
* The stock the program was checked against when it is not a document object of its own
  (the keycap_mold sample's block), transparent gray (``ShowStock``).
* The shaded tool, shank and holder at path point ``ToolAt`` (-1: hidden), the task panel's
  slider moves it along the path.
* Points where shank or holder touch the part or stock, red (only a program made without
  collision checks, surface-normal axes, can have them).
* A program that is not valid (it or an input failed to recompute) is drawn gray with a red
  label saying why.

Drawn from the stored results, never recomputed.
"""
from __future__ import annotations

import numpy as np

from . import coinutil, display
from .proxy import DrawnViewProxy, EditableMixin, add_property

PATH_COLOUR = (0.35, 0.35, 0.40)
INVALID_COLOUR = (0.6, 0.6, 0.6)
COLLISION_COLOUR = (0.95, 0.0, 0.0)
STOCK_COLOUR = (0.55, 0.55, 0.60)
LINK_COLOUR = (1.00, 0.50, 0.00)
AIR_COLOUR = (0.85, 0.05, 0.05)
TOOL_COLOURS = {"ball": (0.90, 0.68, 0.10), "flutes": (0.90, 0.68, 0.10), "shank": (0.62, 0.64, 0.68),
                "holder": (0.30, 0.32, 0.36)}
TILT_BANDS = 6          # colour bands from vertical to the largest tilt
FEED_BANDS = 6
COLOUR_MODES = ["Tilt", "Patch", "Feed"]


def ensure_view_properties(vobj) -> None:
    g = "Tool axes"
    add_property(vobj, "App::PropertyInteger", "Shafts", g, "How many tool axes to draw along the path", 400)
    add_property(vobj, "App::PropertyLength", "ShaftLength", g,
                 "Length of the drawn tool axes (0: a tenth of the path's size)", 0.0)
    if add_property(vobj, "App::PropertyEnumeration", "ColourBy", g,
                    "Colour of the path: Tilt (gray path, axes coloured by tilt), Patch, or Feed (blue slow "
                    "to red fast, after the machine's axis limits)"):
        vobj.ColourBy = COLOUR_MODES
        vobj.ColourBy = "Tilt"
    add_property(vobj, "App::PropertyBool", "ShowStock", g,
                 "Draw the stock the program was checked against (when it is not an object of its own)", True)
    add_property(vobj, "App::PropertyInteger", "ToolAt", g,
                 "Draw the tool, shank and holder at this path point (-1: not drawn)", -1)


def tilt_colour(t: float) -> tuple:
    """Near black (0, vertical) to pure red (1, the largest tilt): readable over every patch
    colour of the model's palette."""
    t = float(np.clip(t, 0.0, 1.0))
    return (0.08 + 0.87 * t, 0.08 * (1.0 - t), 0.08 * (1.0 - t))


def feed_colour(t: float) -> tuple:
    """Blue (0, the slowest block) through green to red (1, the fastest)."""
    t = float(np.clip(t, 0.0, 1.0))
    if t < 0.5:
        return (0.05, 0.3 + 1.2 * t, 0.95 - 1.6 * t)
    return (0.1 + 1.7 * (t - 0.5), 0.9 - 1.6 * (t - 0.5), 0.15)


def shaft_sample(n: int, shafts: int) -> np.ndarray:
    """Indices of about ``shafts`` points spread evenly over n path points."""
    if n == 0:
        return np.zeros(0, int)
    return np.unique(np.linspace(0, n - 1, max(2, min(int(shafts), n))).round().astype(int))


def feed_per_point(motion: dict, n: int) -> np.ndarray:
    """The feed (mm/min) of the block that reaches each path point (NaN where none does)."""
    src = np.asarray(motion["source"], float)
    feed = np.asarray(motion["feed"], float)
    out = np.full(n, np.nan)
    own = (src >= 0) & (np.abs(src - np.round(src)) < 1e-9)
    idx = np.round(src[own]).astype(int)
    ok = idx < n
    out[idx[ok]] = feed[own][ok]
    return out


def rotation_to(axis) -> tuple:
    """(axis, angle) of the rotation taking +Z to ``axis`` (unit)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    c = float(np.clip(a[2], -1.0, 1.0))
    k = np.cross([0.0, 0.0, 1.0], a)
    s = float(np.linalg.norm(k))
    if s < 1e-12:
        return (1.0, 0.0, 0.0), (0.0 if c > 0 else np.pi)
    return tuple(k / s), float(np.arctan2(s, c))


def tool_node(tool, segments: int = 24):
    """The tool in its own frame (ball centre at the origin, axis +Z): the ball, flutes, shank
    and holder as shaded surfaces of revolution."""
    from pivy import coin
    sep = coin.SoSeparator()
    r = tool.ball_radius
    sep.addChild(coinutil.material(TOOL_COLOURS["ball"], diffuse=0.8, emissive=0.15, specular=0.5, shininess=0.6))
    sph = coin.SoSphere()
    sph.radius = float(r)
    sep.addChild(sph)
    for part in tool.parts():
        kind = "holder" if part.name.startswith("holder") else part.name
        sep.addChild(coinutil.material(TOOL_COLOURS.get(kind, TOOL_COLOURS["holder"]), diffuse=0.8, emissive=0.15,
                                       specular=0.5, shininess=0.6, transparency=0.45 if kind == "holder" else 0.0))
        sep.addChild(revolved([(part.r0, part.z0), (part.r1, part.z1)], segments))
    return sep


def revolved(profile, segments: int = 24):
    """A closed frustum: the profile [(r0, z0), (r1, z1)] turned about Z, with both caps."""
    from pivy import coin
    (r0, z0), (r1, z1) = profile
    t = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring0 = np.column_stack([r0 * np.cos(t), r0 * np.sin(t), np.full(segments, z0)])
    ring1 = np.column_stack([r1 * np.cos(t), r1 * np.sin(t), np.full(segments, z1)])
    pts = np.vstack([ring0, ring1, [[0, 0, z0], [0, 0, z1]]])
    k = np.arange(segments)
    k1 = (k + 1) % segments
    side = np.column_stack([k, k1, segments + k1, segments + k])
    faces = [list(q) for q in side]
    c0, c1 = 2 * segments, 2 * segments + 1
    faces += [[c0, int(b), int(a)] for a, b in zip(k, k1)]
    faces += [[c1, segments + int(a), segments + int(b)] for a, b in zip(k, k1)]
    sep = coin.SoSeparator()
    hints = coin.SoShapeHints()
    hints.vertexOrdering = coin.SoShapeHints.COUNTERCLOCKWISE
    hints.shapeType = coin.SoShapeHints.SOLID
    hints.creaseAngle = 0.6
    coords = coin.SoCoordinate3()
    coords.point.setValues(0, len(pts), pts.tolist())
    fs = coin.SoIndexedFaceSet()
    idx = [i for f in faces for i in list(map(int, f)) + [-1]]
    fs.coordIndex.setValues(0, len(idx), idx)
    for n in (hints, coords, fs):
        sep.addChild(n)
    return sep


class ViewProviderProgram(EditableMixin, DrawnViewProxy):
    ensure_view_properties = staticmethod(ensure_view_properties)
    DISPLAY_MODE = "Axes"
    ICON = "program"

    @staticmethod
    def panel():
        from .settingspanel import SettingsPanel
        return SettingsPanel
    CHILD = "ToolPath"
    DATA_PROPS = ("AxesFile", "MotionFile")
    VIEW_PROPS = ("Shafts", "ShaftLength", "ColourBy", "ShowStock")
    TITLE = "Program"
    drawn_valid = True
    tool_switch = None
    _tool_key = None

    def onChanged(self, vobj, prop):
        if prop == "ToolAt" and self.group is not None:
            self.place_tool()
            return
        super().onChanged(vobj, prop)

    def draw(self, obj, group) -> bool:
        from . import validity
        from .programobject import TsplcamProgram, motion_of
        self.tool_switch = None
        self.drawn_valid = not validity.failed(obj)
        if not obj.AxesFile or not isinstance(obj.Proxy, TsplcamProgram):
            return False
        tp = obj.Proxy.oriented_path(obj)
        if len(tp) == 0:
            return False
        vobj = self.ViewObject
        valid = self.drawn_valid
        C, A = tp.center, tp.axis
        size = float(np.linalg.norm(C.max(axis=0) - C.min(axis=0))) or 1.0
        motion = None
        try:
            motion = motion_of(obj)
        except Exception:
            pass
        mode = getattr(vobj, "ColourBy", "Tilt") if valid else "Tilt"
        self._draw_path(group, tp, motion, mode, valid)
        length = float(getattr(vobj, "ShaftLength", 0.0) or 0.0) or 0.1 * size
        idx = shaft_sample(len(tp), getattr(vobj, "Shafts", 400))
        tilt = np.degrees(np.arccos(np.clip(A[idx, 2], -1.0, 1.0)))
        top = max(float(tilt.max()), 1e-9)
        band = np.minimum((tilt / top * TILT_BANDS).astype(int), TILT_BANDS - 1)
        for b in np.unique(band):
            sel = idx[band == b]
            pts = np.vstack([C[sel], C[sel] + length * A[sel]])
            edges = np.column_stack([np.arange(len(sel)), np.arange(len(sel)) + len(sel)])
            colour = tilt_colour((b + 0.5) / TILT_BANDS) if valid else INVALID_COLOUR
            group.addChild(coinutil.segments(pts, edges, colour, 2.0))
        if motion is not None and len(motion["collides"]) == len(tp) and motion["collides"].any():
            hit = motion["collides"]
            group.addChild(coinutil.spheres(C[hit][:: max(1, int(hit.sum()) // 2000)], 0.006 * size,
                                            COLLISION_COLOUR, lit=False))
        if getattr(vobj, "ShowStock", True):
            self._draw_stock(obj, group)
        if not valid:
            group.addChild(coinutil.labels([invalid_label(obj)], C[:1], 14, text_colour=(1.0, 1.0, 1.0),
                                           background=(0.75, 0.0, 0.0), pull=0.05 * size))
        from pivy import coin
        self.tool_switch = coinutil.switch(False, "tsplcam_tool")
        group.addChild(self.tool_switch)
        self._tool_key = None
        self.place_tool()
        return True

    def _draw_path(self, group, tp, motion, mode, valid) -> None:
        from ..toolpath.path import Move
        C = tp.center
        segs = display.segments_by_move(C, tp.move)
        cut = segs.get(int(Move.CUT), [])
        if not valid:
            group.addChild(coinutil.polylines([C], INVALID_COLOUR, 1.0))
            return
        if mode == "Patch":
            from ..layout.layout import Layout
            from .modelobject import model_of
            model = model_of(self.Object.ToolPath.ProcessingList.Model)
            colours = display.patch_colours(Layout.from_model(model))
            kind = np.asarray(tp.move[1:], int)
            for p in np.unique(tp.patch[tp.patch >= 0]):
                on = (kind == Move.CUT) & (tp.patch[1:] == p) & (tp.patch[:-1] == p)
                group.addChild(coinutil.segments(C, np.column_stack([np.nonzero(on)[0], np.nonzero(on)[0] + 1]),
                                                 display.PALETTE[colours[p]], 2.0))
        elif mode == "Feed" and motion is not None:
            f = feed_per_point(motion, len(tp))
            lo, hi = np.nanmin(f[1:]) if np.isfinite(f[1:]).any() else 0.0, np.nanmax(f) if np.isfinite(f).any() else 1.0
            t = np.where(np.isfinite(f), (f - lo) / max(hi - lo, 1e-9), 0.0)
            band = np.minimum((t * FEED_BANDS).astype(int), FEED_BANDS - 1)[1:]
            kind = np.asarray(tp.move[1:], int)
            for b in np.unique(band):
                on = np.nonzero((band == b) & (kind == Move.CUT))[0]
                group.addChild(coinutil.segments(C, np.column_stack([on, on + 1]),
                                                 feed_colour((b + 0.5) / FEED_BANDS), 2.0))
        else:
            group.addChild(coinutil.polylines(cut, PATH_COLOUR, 1.0))
        group.addChild(coinutil.polylines(segs.get(int(Move.LINK), []), LINK_COLOUR, 3.0))
        for m, pattern in ((int(Move.RETRACT), coinutil.DASHED), (int(Move.RAPID), coinutil.DOTTED)):
            group.addChild(coinutil.polylines(segs.get(m, []), AIR_COLOUR, 2.0, pattern))

    def _draw_stock(self, obj, group) -> None:
        """The stock the engine checked against when no Stock object is linked (a sample's)."""
        if obj.Stock is not None:
            return
        stock = implicit_stock(obj)
        if stock is None:
            return
        from pivy import coin
        V, T = stock
        sep = coin.SoSeparator()
        sep.setName("tsplcam_stock")
        sep.addChild(coinutil.two_sided())
        sep.addChild(coinutil.material(STOCK_COLOUR, transparency=0.7))
        coords = coin.SoCoordinate3()
        coords.point.setValues(0, len(V), np.asarray(V, float).tolist())
        fs = coin.SoIndexedFaceSet()
        idx = np.column_stack([np.asarray(T, int), -np.ones(len(T), int)]).ravel().tolist()
        fs.coordIndex.setValues(0, len(idx), idx)
        sep.addChild(coords)
        sep.addChild(fs)
        group.addChild(sep)
        group.addChild(coinutil.segments(V, feature_edges(V, T), (0.25, 0.25, 0.3), 1.0))

    def place_tool(self) -> None:
        """Move the drawn tool to path point ``ToolAt`` (built once per tool)."""
        sw = self.tool_switch
        if sw is None:
            return
        obj = self.Object
        k = int(getattr(self.ViewObject, "ToolAt", -1))
        try:
            tp = obj.Proxy.oriented_path(obj)
        except Exception:
            return
        if not 0 <= k < len(tp):
            coinutil.set_visible(sw, False)
            return
        from pivy import coin
        key = (obj.ToolFile or obj.Tool)
        if self._tool_key != key or sw.getNumChildren() == 0:
            sw.removeAllChildren()
            try:
                from ..program import load_tool
                tool = load_tool(obj.Proxy.settings(obj))
            except Exception:
                tool = None
            if tool is None:
                return
            sep = coin.SoSeparator()
            self.tool_transform = coin.SoTransform()
            sep.addChild(self.tool_transform)
            sep.addChild(tool_node(tool))
            sw.addChild(sep)
            self._tool_key = key
        axis, angle = rotation_to(tp.axis[k])
        self.tool_transform.translation.setValue(*[float(x) for x in tp.center[k]])
        self.tool_transform.rotation.setValue(coin.SbVec3f(*axis), angle)
        coinutil.set_visible(sw, True)


def feature_edges(V, T, angle_deg: float = 20.0) -> np.ndarray:
    """The edges of a triangle mesh where its faces meet at more than ``angle_deg`` (or only
    one face has it): the outline of a block, not its triangulation."""
    V = np.asarray(V, float)
    T = np.asarray(T, int)
    n = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    pairs = np.sort(np.vstack([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
    face = np.tile(np.arange(len(T)), 3)
    key = pairs[:, 0] * (len(V) + 1) + pairs[:, 1]
    order = np.argsort(key, kind="stable")
    key, face, pairs = key[order], face[order], pairs[order]
    first = np.nonzero(np.r_[True, key[1:] != key[:-1]])[0]
    count = np.diff(np.r_[first, len(key)])
    single = first[count == 1]
    double = first[count == 2]
    sharp = double[np.einsum("ij,ij->i", n[face[double]], n[face[double + 1]]) < np.cos(np.radians(angle_deg))]
    return pairs[np.sort(np.r_[single, sharp])].reshape(-1, 2)


def invalid_label(obj) -> str:
    """A short banner for a program that is not valid: which object failed (the reason is in
    the task panel, the tree's tooltip and the Report view)."""
    from .validity import failed
    chain = [o for o in [obj] + list(obj.OutListRecursive) if failed(o)]
    root = min(chain, key=lambda o: len(o.OutListRecursive)) if chain else obj
    what = "stopped" if "stopped on request" in (root.getStatusString() or "") else "failed"
    return f"NOT VALID: {root.Label} {what}"[:70]


def implicit_stock(obj):
    """(V, T) of the stock a program's engine run used without a Stock object: the block a
    shipped sample brings (tsplcam.program.load_stock), else None."""
    try:
        from ..program import load_stock
        return load_stock(obj.Proxy.settings(obj))
    except Exception:
        return None
