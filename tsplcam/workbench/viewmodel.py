"""View provider of the model object: the patch layout drawn with Coin.

Layers (each under its own SoSwitch, toggled by a view property without rebuilding):
the surface, one palette colour per patch (``display.patch_colours``); patch boundaries;
patch numbers at the patch centres; extraordinary points (red spheres; irregular boundary
vertices smaller); the control mesh; the adjacency graph of shang2020 figure 4 (boundary
links solid, corner links dashed). Everything is drawn from the engine model, never from
OCCT shapes.
"""
from __future__ import annotations

import numpy as np

import FreeCAD
from pivy import coin

from ..layout.layout import Layout
from . import coinutil, display, messages
from .modelobject import PATCH_ELEMENT, model_of, patch_of_element
from .proxy import ViewProxy, add_property

LAYERS = ("surface", "edges", "numbers", "extraordinary", "control", "adjacency")
# view property -> layer it switches
TOGGLES = {"ShowPatchEdges": "edges", "ShowPatchNumbers": "numbers",
           "ShowExtraordinary": "extraordinary", "ShowControlMesh": "control",
           "ShowAdjacency": "adjacency"}
PROGRESS_PATCHES = 200      # show a progress bar when tessellating more patches than this
LABEL_LIFT = 0.01           # labels float this fraction of the model size above the surface
LABEL_PULL = 0.04           # ... and are drawn this fraction nearer the viewer


def ensure_view_properties(vobj) -> None:
    g = "Patch layout"
    add_property(vobj, "App::PropertyBool", "ShowPatchEdges", g, "Draw patch boundaries", True)
    add_property(vobj, "App::PropertyBool", "ShowPatchNumbers", g, "Label every patch with its number", True)
    add_property(vobj, "App::PropertyBool", "ShowExtraordinary", g,
                 "Mark extraordinary points (red; irregular boundary vertices smaller)", True)
    add_property(vobj, "App::PropertyBool", "ShowControlMesh", g,
                 "Draw the control mesh (cage or T-mesh)", False)
    add_property(vobj, "App::PropertyBool", "ShowAdjacency", g,
                 "Draw the patch adjacency graph: boundary links solid, corner links dashed", False)
    if add_property(vobj, "App::PropertyIntegerConstraint", "Density", g,
                    "Tessellation: quads per knot span along each direction"):
        vobj.Density = (8, 1, 64, 1)
    add_property(vobj, "App::PropertyInteger", "NeighboursOf", g,
                 "Colour patches by their link to this patch as in the paper's figure 4: "
                 "blue shares an edge, green only a corner, gray none (-1: one colour per patch)", -1)
    if add_property(vobj, "App::PropertyIntegerConstraint", "LabelSize", g,
                    "Font size of the patch numbers (pixels)"):
        vobj.LabelSize = (16, 6, 48, 1)


class ViewProviderTsplcamModel(ViewProxy):
    """Draws a TsplcamModel: see the module docstring for the layers."""
    ensure_view_properties = staticmethod(ensure_view_properties)
    DISPLAY_MODE = "Patches"
    ICON = "model"

    # transient (class defaults: __init__ does not run on restore)
    root = None
    layers = None
    _built_for = None

    def attach(self, vobj):
        super().attach(vobj)
        self.root = coin.SoSeparator()
        self.root.setName("TsplcamModel")
        self.root.addChild(coinutil.two_sided())
        self.layers = {}
        for name in LAYERS:
            prop = next((p for p, l in TOGGLES.items() if l == name), None)
            visible = True if prop is None else bool(getattr(vobj, prop, False))
            sw = coinutil.switch(visible, "tsplcam_" + name)
            self.layers[name] = sw
            self.root.addChild(sw)
        vobj.addDisplayMode(self.root, "Patches")
        self._built_for = None
        self.rebuild()

    # -- FreeCAD hooks ---------------------------------------------------------------------

    def updateData(self, obj, prop):
        if prop in ("SourceFile", "Format", "Patches"):
            self.rebuild()

    def onChanged(self, vobj, prop):
        if self.layers is None:
            return
        if prop in TOGGLES:
            layer = TOGGLES[prop]
            visible = bool(getattr(vobj, prop))
            if visible and self.layers[layer].getNumChildren() == 0:
                self._build_layer(layer)
            coinutil.set_visible(self.layers[layer], visible)
        elif prop == "Density":
            self.rebuild(force=True)
        elif prop == "LabelSize":
            self._build_layer("numbers")
            if coinutil.is_visible(self.layers["adjacency"]):
                self._build_layer("adjacency")
        elif prop == "NeighboursOf":
            self._build_layer("surface")

    def finishRestoring(self):
        self.rebuild(after_restore=True)

    def getElementPicked(self, pick):
        """'Patch<k>' for a pick on patch k (selection and pins name patches so)."""
        path = pick.getPath()
        for i in range(path.getLength() - 1, -1, -1):
            name = path.getNode(i).getName().getString()
            if patch_of_element(name) is not None:
                return name
        raise NotImplementedError    # anything else: the whole object

    def setupContextMenu(self, vobj, menu):
        from PySide import QtGui
        for prop, text in (("ShowPatchNumbers", "Patch numbers"), ("ShowExtraordinary", "Extraordinary points"),
                           ("ShowControlMesh", "Control mesh"), ("ShowAdjacency", "Adjacency graph")):
            action = QtGui.QAction(text, menu)
            action.setCheckable(True)
            action.setChecked(bool(getattr(vobj, prop)))
            action.toggled.connect(lambda on, p=prop: setattr(vobj, p, bool(on)))
            menu.addAction(action)

    # -- building -----------------------------------------------------------------------------
    def model(self):
        return model_of(self.Object)

    def rebuild(self, force: bool = False, after_restore: bool = False) -> bool:
        """(Re)build every visible layer from the model; False when there is no model yet.
        While the document loads, waits for finishRestoring (properties arrive one by one)."""
        if self.layers is None:
            return False
        if not after_restore and self.restoring():
            self.later(lambda: self.rebuild(after_restore=True))
            return False
        obj = self.Object
        if not getattr(obj, "SourceFile", ""):
            return False
        try:
            model = self.model()
        except Exception as exc:
            messages.exception("tsplcam model", exc, f"reading the model of {obj.Label}")
            for sw in self.layers.values():
                sw.removeAllChildren()
            self._built_for = None
            return False
        if not force and self._built_for is model:
            return True
        self._built_for = model
        self._cache = {}
        for name, sw in self.layers.items():
            sw.removeAllChildren()
        for name in LAYERS:
            if coinutil.is_visible(self.layers[name]) or name == "surface":
                self._build_layer(name)
        return True

    def _density(self) -> int:
        return int(getattr(self.ViewObject, "Density", 8))

    def _meshes(self):
        cache = self._cache
        key = ("meshes", self._density())
        if key not in cache:
            model = self._built_for
            n = len(model.patches)
            bar = None
            if n > PROGRESS_PATCHES:
                bar = FreeCAD.Base.ProgressIndicator()
                bar.start(f"tsplcam: tessellating {n} patches", n)
            try:
                cache[key] = display.tessellate(model, self._density(),
                                                (lambda k, total: bar.next()) if bar else None)
            finally:
                if bar is not None:
                    bar.stop()
        return cache[key]

    def _extents(self):
        """Per patch, its tessellation points: labels show only where a patch has room."""
        return [m.points for m in self._meshes()]

    def _marker_radius(self) -> float:
        """Extraordinary point markers: small against the model and against its patches."""
        if "marker" not in self._cache:
            diags = [np.linalg.norm(m.points.max(axis=0) - m.points.min(axis=0)) for m in self._meshes()]
            self._cache["marker"] = max(1e-9, min(0.014 * self._size(), 0.06 * float(np.median(diags))))
        return self._cache["marker"]

    def _size(self) -> float:
        if "size" not in self._cache:
            self._cache["size"] = display.model_size(self._built_for)
        return self._cache["size"]

    def _build_layer(self, name: str) -> None:
        model = self._built_for
        sw = self.layers[name]
        sw.removeAllChildren()
        if model is None:
            return
        try:
            node = getattr(self, "_layer_" + name)(model)
        except Exception as exc:
            messages.exception("tsplcam model", exc, f"drawing the {name} of {self.Object.Label}")
            return
        if node is not None:
            sw.addChild(node)

    def _layer_surface(self, model):
        sep = coin.SoSeparator()
        offset = coin.SoPolygonOffset()      # faces slightly back: lines on them stay visible
        offset.factor = 1.0
        offset.units = 1.0
        sep.addChild(offset)
        layout = Layout.from_model(model)
        focus = int(getattr(self.ViewObject, "NeighboursOf", -1))
        if 0 <= focus < layout.n_patches:
            colours = display.relation_colours(layout, focus)
        else:
            colours = [display.PALETTE[c] for c in display.patch_colours(layout)]
        for mesh, c in zip(self._meshes(), colours):
            sep.addChild(coinutil.grid_mesh(mesh.points, mesh.normals, mesh.quads(), c,
                                            PATCH_ELEMENT + str(mesh.patch)))
        return sep

    def _layer_edges(self, model):
        lines = [edge for mesh in self._meshes() for edge in mesh.boundary()]
        return coinutil.polylines(lines, display.EDGE_COLOUR, 1.5)

    def _layer_numbers(self, model):
        size = self._size()
        centres = display.patch_centres(model, lift=LABEL_LIFT * size)
        size_px = int(getattr(self.ViewObject, "LabelSize", 16))
        n = len(model.patches)
        return coinutil.labels([str(k) for k in range(n)], centres, size_px,
                               names=[PATCH_ELEMENT + str(k) for k in range(n)], pull=LABEL_PULL * size,
                               extents=self._extents())

    def _layer_extraordinary(self, model):
        pos, valence, boundary = display.extraordinary_points(model)
        sep = coin.SoSeparator()
        r = self._marker_radius()
        if (~boundary).any():
            sep.addChild(coinutil.spheres(pos[~boundary], r, display.EP_COLOUR))
        if boundary.any():
            sep.addChild(coinutil.spheres(pos[boundary], 0.55 * r, display.EP_COLOUR))
        return sep

    def _layer_control(self, model):
        net = display.control_net(model)
        if net is None:
            messages.info(f"{self.Object.Label}: this model has no control mesh to show")
            return None
        pts, edges = net
        sep = coin.SoSeparator()
        sep.addChild(coinutil.segments(pts, edges, display.CONTROL_COLOUR, 1.2))
        sep.addChild(coinutil.points(pts, display.CONTROL_COLOUR, 5.0))
        return sep

    def _layer_adjacency(self, model):
        d = display.adjacency(model, lift=0.006 * self._size())
        sep = coin.SoSeparator()
        sep.addChild(coinutil.polylines(d.boundary, display.BOUNDARY_LINK_COLOUR, 3.5))
        sep.addChild(coinutil.polylines(d.corner, display.CORNER_LINK_COLOUR, 2.5, coinutil.DASHED))
        # the graph's nodes are the patch numbers (figure 4 (b)), also when numbers are off
        size = self._size()
        n = len(model.patches)
        sep.addChild(coinutil.labels([str(k) for k in range(n)],
                                     display.patch_centres(model, lift=LABEL_LIFT * size),
                                     int(getattr(self.ViewObject, "LabelSize", 16)),
                                     names=[PATCH_ELEMENT + str(k) for k in range(n)],
                                     pull=LABEL_PULL * size, extents=self._extents()))
        return sep

