"""Helpers for GUI tests: read what the Report view shows, render the 3D view."""
import FreeCAD
import FreeCADGui


def _error_colour() -> str:
    grp = FreeCAD.ParamGet("User parameter:BaseApp/Preferences/OutputWindow")
    packed = grp.GetUnsigned("colorError", 0xff000000)
    return "#{:02x}{:02x}{:02x}".format((packed >> 24) & 0xff, (packed >> 16) & 0xff,
                                        (packed >> 8) & 0xff)


def report_view_lines():
    """(text, is_error) for every line of the Report view; errors are told by their colour."""
    from PySide import QtGui
    FreeCADGui.updateGui()
    red = _error_colour()
    out = []
    for widget in FreeCADGui.getMainWindow().findChildren(QtGui.QTextEdit):
        if widget.objectName() != "Report view":
            continue
        block = widget.document().begin()
        while block.isValid():
            colours = {r.format.foreground().color().name() for r in block.layout().formats()}
            out.append((block.text(), red in colours))
            block = block.next()
    return out


def report_view_mark() -> int:
    """A mark for :func:`errors_since`: the count of lines, less the empty one new text fills."""
    lines = report_view_lines()
    return len(lines) - 1 if lines and not lines[-1][0] else len(lines)


def errors_since(mark: int):
    """Error lines printed after line number ``mark`` of the Report view."""
    return [text for text, is_error in report_view_lines()[mark:] if is_error]


def save_view(path: str, width: int = 800, height: int = 600, view: str = "isometric") -> str:
    """Fit the active 3D view and save it as a PNG on white."""
    v = FreeCADGui.ActiveDocument.ActiveView
    getattr(v, "view" + view.capitalize())()
    v.fitAll()
    FreeCADGui.updateGui()
    v.saveImage(path, width, height, "White")
    return path


def image_rgb(path: str):
    """A PNG as a numpy (h, w, 3) float array in 0..1 (read with Qt: no extra packages)."""
    import numpy as np
    from PySide import QtGui
    img = QtGui.QImage(path)
    if img.isNull():
        raise ValueError(f"cannot read image {path}")
    img = img.convertToFormat(QtGui.QImage.Format_RGB32)
    w, h, stride = img.width(), img.height(), img.bytesPerLine()
    raw = np.frombuffer(bytes(img.constBits())[: stride * h], dtype=np.uint8)
    bgra = raw.reshape(h, stride // 4, 4)[:, :w]
    return bgra[:, :, [2, 1, 0]].astype(float) / 255.0


def hsv(rgb):
    """Hue (degrees), saturation and value of an (..., 3) RGB array, vectorised."""
    import numpy as np
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    mx = rgb.max(axis=-1)
    mn = rgb.min(axis=-1)
    d = mx - mn
    safe = np.where(d > 0, d, 1.0)
    h = np.where(mx == r, ((g - b) / safe) % 6.0,
                 np.where(mx == g, (b - r) / safe + 2.0, (r - g) / safe + 4.0)) * 60.0
    h = np.where(d > 0, h, 0.0)
    s = np.where(mx > 0, d / np.where(mx > 0, mx, 1.0), 0.0)
    return h, s, mx


def colour_pixel_counts(path: str, colours, hue_tolerance: float = 8.0, min_saturation: float = 0.3,
                        min_value: float = 0.1):
    """Pixels of the image whose hue is within ``hue_tolerance`` degrees of each colour's hue
    (saturated and bright enough to have a hue). Shading under white light scales a
    colour and specular light adds white: both keep its hue, so this counts a patch's
    pixels whatever the lighting."""
    import colorsys
    import numpy as np
    h, s, v = hsv(image_rgb(path))
    ok = (s >= min_saturation) & (v >= min_value)
    out = []
    for c in colours:
        hc = colorsys.rgb_to_hsv(*c)[0] * 360.0
        dh = np.abs(h - hc) % 360.0
        dh = np.minimum(dh, 360.0 - dh)
        out.append(int((ok & (dh <= hue_tolerance)).sum()))
    return out


def view_from(azimuth_deg: float, elevation_deg: float):
    """Point the active view's camera from azimuth/elevation (degrees; z up), then fit."""
    import math
    v = FreeCADGui.ActiveDocument.ActiveView
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    d = FreeCAD.Vector(-math.cos(e) * math.cos(a), -math.cos(e) * math.sin(a), -math.sin(e))  # look dir
    up = FreeCAD.Vector(0, 0, 1)
    right = d.cross(up)
    if right.Length < 1e-9:
        right = FreeCAD.Vector(1, 0, 0)
    right.normalize()
    up = right.cross(d)
    up.normalize()
    back = FreeCAD.Vector(-d.x, -d.y, -d.z)
    m = FreeCAD.Matrix(right.x, up.x, back.x, 0, right.y, up.y, back.y, 0, right.z, up.z, back.z, 0)
    v.setCameraOrientation(FreeCAD.Rotation(m).Q)
    v.fitAll()
    FreeCADGui.updateGui()
    return v
