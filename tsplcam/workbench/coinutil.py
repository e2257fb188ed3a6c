"""Coin (pivy) building blocks for tsplcam's views: shaded grids, polylines, markers, labels.

Shared by every view provider (model, and later path preview and processing list), so that
all of them look alike: lines and markers are unlit (BASE_COLOR) and keep their colour at
any angle, labels are framed text that stays readable on any patch colour.
"""
from __future__ import annotations

import numpy as np
from pivy import coin

DASHED = 0x0F0F          # SoDrawStyle.linePattern of dashed lines (8 on, 8 off)
DOTTED = 0x3333


def _floats(a) -> list:
    return np.asarray(a, dtype=float).tolist()


def switch(visible: bool = True, name: str = "") -> coin.SoSwitch:
    s = coin.SoSwitch()
    if name:
        s.setName(name)
    s.whichChild = coin.SO_SWITCH_ALL if visible else coin.SO_SWITCH_NONE
    return s


def set_visible(sw: coin.SoSwitch, visible: bool) -> None:
    value = coin.SO_SWITCH_ALL if visible else coin.SO_SWITCH_NONE
    if sw.whichChild.getValue() != value:
        sw.whichChild = value


def is_visible(sw: coin.SoSwitch) -> bool:
    return sw.whichChild.getValue() == coin.SO_SWITCH_ALL


def material(colour, diffuse: float = 0.7, emissive: float = 0.35, ambient: float = 0.3,
             specular: float = 0.12, shininess: float = 0.2, transparency: float = 0.0) -> coin.SoMaterial:
    """A material whose colour stays recognisable at grazing angles under the headlight:
    part of it is emissive, so surfaces seen edge-on do not go black."""
    m = coin.SoMaterial()
    c = tuple(float(x) for x in colour)
    m.diffuseColor.setValue(*(diffuse * x for x in c))
    m.ambientColor.setValue(*(ambient * x for x in c))
    m.specularColor.setValue(specular, specular, specular)
    m.shininess.setValue(shininess)
    m.emissiveColor.setValue(*(emissive * x for x in c))
    if transparency:
        m.transparency.setValue(transparency)
    return m


def unlit(colour) -> list:
    """Nodes that make what follows flat-coloured (lines, points, markers)."""
    lm = coin.SoLightModel()
    lm.model = coin.SoLightModel.BASE_COLOR
    m = coin.SoBaseColor()
    m.rgb.setValue(*(float(x) for x in colour))
    return [lm, m]


def two_sided() -> coin.SoShapeHints:
    """Both sides of open surfaces lit (no backface culling, two-sided lighting)."""
    h = coin.SoShapeHints()
    h.vertexOrdering = coin.SoShapeHints.COUNTERCLOCKWISE
    h.shapeType = coin.SoShapeHints.UNKNOWN_SHAPE_TYPE
    return h


def grid_mesh(points, normals, quads, colour, name: str = "") -> coin.SoSeparator:
    """A shaded quad mesh with per-vertex normals and one colour; ``name`` names the
    separator (picking tells patches apart by it)."""
    sep = coin.SoSeparator()
    if name:
        sep.setName(name)
    sep.addChild(material(colour))
    coords = coin.SoCoordinate3()
    coords.point.setValues(0, len(points), _floats(points))
    nrm = coin.SoNormal()
    nrm.vector.setValues(0, len(normals), _floats(normals))
    binding = coin.SoNormalBinding()
    binding.value = coin.SoNormalBinding.PER_VERTEX_INDEXED
    faces = coin.SoIndexedFaceSet()
    idx = np.column_stack([np.asarray(quads, int), -np.ones(len(quads), int)]).ravel().tolist()
    faces.coordIndex.setValues(0, len(idx), idx)
    faces.normalIndex.setValues(0, len(idx), idx)
    for n in (coords, nrm, binding, faces):
        sep.addChild(n)
    return sep


def polylines(lines, colour, width: float = 1.0, pattern: int | None = None) -> coin.SoSeparator:
    """Unlit polylines (a list of (k, 3) arrays), solid or with a line pattern."""
    sep = coin.SoSeparator()
    lines = [np.asarray(l, float).reshape(-1, 3) for l in lines if len(l) >= 2]
    if not lines:
        return sep
    for n in unlit(colour):
        sep.addChild(n)
    style = coin.SoDrawStyle()
    style.lineWidth = float(width)
    if pattern is not None:
        style.linePattern = pattern
    sep.addChild(style)
    pts = np.concatenate(lines)
    coords = coin.SoCoordinate3()
    coords.point.setValues(0, len(pts), _floats(pts))
    ls = coin.SoLineSet()
    counts = [len(l) for l in lines]
    ls.numVertices.setValues(0, len(counts), counts)
    sep.addChild(coords)
    sep.addChild(ls)
    return sep


def segments(points, edges, colour, width: float = 1.0) -> coin.SoSeparator:
    """Unlit straight segments between ``points`` (n, 3) given as index pairs (m, 2)."""
    sep = coin.SoSeparator()
    if len(edges) == 0:
        return sep
    for n in unlit(colour):
        sep.addChild(n)
    style = coin.SoDrawStyle()
    style.lineWidth = float(width)
    sep.addChild(style)
    coords = coin.SoCoordinate3()
    coords.point.setValues(0, len(points), _floats(points))
    ils = coin.SoIndexedLineSet()
    idx = np.column_stack([np.asarray(edges, int), -np.ones(len(edges), int)]).ravel().tolist()
    ils.coordIndex.setValues(0, len(idx), idx)
    sep.addChild(coords)
    sep.addChild(ils)
    return sep


def points(pts, colour, size: float = 4.0) -> coin.SoSeparator:
    sep = coin.SoSeparator()
    if len(pts) == 0:
        return sep
    for n in unlit(colour):
        sep.addChild(n)
    style = coin.SoDrawStyle()
    style.pointSize = float(size)
    sep.addChild(style)
    coords = coin.SoCoordinate3()
    coords.point.setValues(0, len(pts), _floats(pts))
    sep.addChild(coords)
    sep.addChild(coin.SoPointSet())
    return sep


def spheres(centres, radius: float, colour, lit: bool = True) -> coin.SoSeparator:
    """A sphere of ``radius`` at each centre (markers for points of interest)."""
    sep = coin.SoSeparator()
    if lit:
        sep.addChild(material(colour, diffuse=0.9, emissive=0.15, specular=0.5, shininess=0.6))
    else:
        for n in unlit(colour):
            sep.addChild(n)
    cx = coin.SoComplexity()
    cx.value = 0.6
    sep.addChild(cx)
    for c in np.asarray(centres, float).reshape(-1, 3):
        s = coin.SoSeparator()
        t = coin.SoTranslation()
        t.translation.setValue(*c.tolist())
        sph = coin.SoSphere()
        sph.radius = float(radius)
        s.addChild(t)
        s.addChild(sph)
        sep.addChild(s)
    return sep


def cones(tips, directions, radius: float, height: float, colour, segments: int = 10) -> coin.SoSeparator:
    """Arrow heads: a cone of ``height`` with its apex at each tip, pointing along each
    direction (unit vectors). One face set in model coordinates: no per-cone rotation
    nodes (they inflate Coin's bounding boxes, and with them the view's fit)."""
    sep = coin.SoSeparator()
    tips = np.asarray(tips, float).reshape(-1, 3)
    dirs = np.asarray(directions, float).reshape(-1, 3)
    if not len(tips):
        return sep
    sep.addChild(material(colour, diffuse=0.8, emissive=0.3, specular=0.3, shininess=0.5))
    # two unit vectors across each direction
    helper = np.where(np.abs(dirs[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(dirs, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(dirs, e1)
    ang = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    base = tips - height * dirs                                            # (n, 3)
    ring = (base[:, None, :] + radius * (np.cos(ang)[None, :, None] * e1[:, None, :]
                                         + np.sin(ang)[None, :, None] * e2[:, None, :]))
    pts = np.concatenate([tips[:, None, :], base[:, None, :], ring], axis=1)   # (n, 2 + s, 3)
    n, m = len(tips), segments + 2
    k = np.arange(segments)
    side = np.column_stack([np.zeros(segments, int), 2 + k, 2 + (k + 1) % segments])
    bottom = np.column_stack([np.ones(segments, int), 2 + (k + 1) % segments, 2 + k])
    tri = np.concatenate([side, bottom])                                   # (2 s, 3)
    idx = (tri[None, :, :] + (m * np.arange(n))[:, None, None]).reshape(-1, 3)
    coords = coin.SoCoordinate3()
    flat = pts.reshape(-1, 3)
    coords.point.setValues(0, len(flat), _floats(flat))
    faces = coin.SoIndexedFaceSet()
    ci = np.column_stack([idx, -np.ones(len(idx), int)]).ravel().tolist()
    faces.coordIndex.setValues(0, len(ci), ci)
    hints = coin.SoShapeHints()
    hints.vertexOrdering = coin.SoShapeHints.COUNTERCLOCKWISE
    hints.shapeType = coin.SoShapeHints.SOLID
    hints.creaseAngle = 0.0
    for node in (hints, coords, faces):
        sep.addChild(node)
    return sep


def haloed_polylines(lines, colour, width: float, halo=(1.0, 1.0, 1.0), halo_width: float | None = None,
                     pull: float = 0.0, pattern: int | None = None) -> coin.SoSeparator:
    """Polylines with a wider light line under them: readable on any patch colour. The
    coloured line is drawn ``pull`` nearer the viewer so it always wins over its halo."""
    sep = coin.SoSeparator()
    sep.addChild(polylines(lines, halo, halo_width or width + 3.5))
    top = coin.SoSeparator()
    if pull:
        top.addChild(toward_viewer(pull))
    top.addChild(polylines(lines, colour, width, pattern))
    sep.addChild(top)
    return sep


_LABEL_IMAGES: dict = {}


def label_image(text: str, size: int = 14, text_colour=(0.0, 0.0, 0.0),
                background=(1.0, 1.0, 1.0), border=(0.0, 0.0, 0.0)) -> tuple[int, int, bytes]:
    """(width, height, RGBA bytes bottom row first) of a round label: ``text`` in bold on a
    disc (a pill for long text) with a thin border, like the nodes of shang2020 figure 4."""
    key = (text, size, tuple(text_colour), tuple(background), tuple(border))
    if key in _LABEL_IMAGES:
        return _LABEL_IMAGES[key]
    from PySide import QtCore, QtGui
    font = QtGui.QFont()
    font.setPixelSize(int(size))
    font.setBold(True)
    fm = QtGui.QFontMetrics(font)
    tw = fm.horizontalAdvance(text) if hasattr(fm, "horizontalAdvance") else fm.width(text)
    h = int(fm.height() * 1.25) + 2
    w = max(h, tw + h // 2 + 4)
    img = QtGui.QImage(w, h, QtGui.QImage.Format_RGBA8888)
    img.fill(QtGui.QColor(0, 0, 0, 0))
    qc = lambda c: QtGui.QColor.fromRgbF(*(float(x) for x in c))   # noqa: E731
    p = QtGui.QPainter(img)
    p.setRenderHint(QtGui.QPainter.Antialiasing, True)
    p.setRenderHint(QtGui.QPainter.TextAntialiasing, True)
    pen = QtGui.QPen(qc(border))
    pen.setWidthF(1.5)
    p.setPen(pen)
    p.setBrush(QtGui.QBrush(qc(background)))
    r = QtCore.QRectF(1.0, 1.0, w - 2.0, h - 2.0)
    p.drawRoundedRect(r, (h - 2) / 2.0, (h - 2) / 2.0)
    p.setPen(qc(text_colour))
    p.setFont(font)
    p.drawText(r, QtCore.Qt.AlignCenter, text)
    p.end()
    img = img.mirrored(False, True)          # Coin's images start at the bottom row
    data = bytes(img.constBits())[: w * h * 4]
    _LABEL_IMAGES[key] = (w, h, data)
    return w, h, data


def toward_viewer(distance: float) -> coin.SoCallback:
    """A node that moves what follows it ``distance`` toward the viewer, along the view
    direction, while rendering: on screen nothing moves, but labels clear the surface they
    sit on (no half-hidden labels at grazing angles) and stay hidden behind anything
    thicker than ``distance``."""
    def pull(_data, action):
        if not action.isOfType(coin.SoGLRenderAction.getClassTypeId()):
            return
        state = action.getState()
        d = coin.SoViewVolumeElement.get(state).getProjectionDirection()
        coin.SoModelMatrixElement.translateBy(state, None, d * (-float(distance)))
    node = coin.SoCallback()
    node.setCallback(pull)
    return node


def labels(texts, positions, size: int = 14, text_colour=(0.0, 0.0, 0.0),
           background=(1.0, 1.0, 1.0), names=None, pull: float = 0.0, extents=None,
           room: float = 5.0) -> coin.SoSeparator:
    """Screen-aligned round labels (``label_image``) centred on 3D positions.

    They keep the depth test, so a label on the far side of the model stays hidden;
    ``pull`` moves them that far toward the viewer (``toward_viewer``). ``names`` name
    each label's separator (a pick on a label then names what it labels). With
    ``extents`` (one (k, 3) point array per label: what it labels), a label shows only
    while that thing covers ``room`` times the label's area on screen, so zooming out
    over hundreds of patches does not bury the model under numbers (SoLevelOfDetail)."""
    sep = coin.SoSeparator()
    positions = np.asarray(positions, float).reshape(-1, 3)
    if pull and len(positions):
        # the view's near and far planes follow the scene's bounds: make room for the pull
        sep.addChild(_bounds_only(np.vstack([positions.min(axis=0) - pull, positions.max(axis=0) + pull])))
        sep.addChild(toward_viewer(pull))
    names = list(names) if names is not None else [""] * len(positions)
    extents = list(extents) if extents is not None else [None] * len(positions)
    for text, p, name, ext in zip(texts, positions, names, extents):
        w, h, data = label_image(str(text), size, text_colour, background)
        s = coin.SoSeparator()
        if name:
            s.setName(name)
        t = coin.SoTranslation()
        t.translation.setValue(*p.tolist())
        image = coin.SoImage()
        image.image.setValue(coin.SbVec2s(w, h), 4, data)
        image.horAlignment = coin.SoImage.CENTER
        image.vertAlignment = coin.SoImage.HALF
        if ext is None:
            s.addChild(t)
            s.addChild(image)
        else:
            lod = coin.SoLevelOfDetail()
            lod.screenArea.setValue(float(room * w * h))
            shown = coin.SoSeparator()
            shown.addChild(_bounds_only(ext))
            shown.addChild(t)
            shown.addChild(image)
            lod.addChild(shown)
            lod.addChild(_bounds_only(ext))      # too small: nothing drawn, same bounds
            s.addChild(lod)
        sep.addChild(s)
    return sep


def _bounds_only(points) -> coin.SoSeparator:
    """Invisible points that give a node the bounding box of ``points``."""
    pts = np.asarray(points, float).reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    sep = coin.SoSeparator()
    style = coin.SoDrawStyle()
    style.style = coin.SoDrawStyle.INVISIBLE
    coords = coin.SoCoordinate3()
    coords.point.setValues(0, 2, [lo.tolist(), hi.tolist()])
    sep.addChild(style)
    sep.addChild(coords)
    sep.addChild(coin.SoPointSet())
    return sep
