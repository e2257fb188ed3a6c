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
