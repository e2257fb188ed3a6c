"""How the workbench tells people about bad input: the Report view, and a message box.

Every problem goes to the Report view (FreeCAD.Console) and, in the GUI, to one message
box with the message the engine wrote (file and line, or patch and (u, v)): never a
traceback dialog for bad input. Unexpected failures (bugs) print their traceback to the
Report view's log, and the box says so.

Tests set ``show_dialogs = False`` (or use ``quiet()``) and read ``recorded``: every
message reported, newest last, as (title, text, is_error).
"""
from __future__ import annotations

import contextlib
import traceback

import FreeCAD

from ..errors import TsplcamError

show_dialogs = True
recorded: list[tuple[str, str, bool]] = []
_MAX_RECORDED = 200
_panels: list = []          # task panels showing errors themselves, innermost last


def describe(exc: BaseException, action: str = "") -> str:
    """One message for an exception: tsplcam's own errors as they are (they name the place);
    anything else as an internal error, with the action that failed."""
    if isinstance(exc, TsplcamError):
        return str(exc)
    what = f"{action}: " if action else ""
    return f"{what}internal error {type(exc).__name__}: {exc} (details in the Report view)"


def printable(text: str) -> str:
    """``text`` with control characters escaped (a corrupt file's bytes can end up in a
    message; a NUL would cut it short in a message box)."""
    return "".join(c if c.isprintable() or c in "\n\t" else repr(c)[1:-1] for c in str(text))


def _record(title: str, text: str, is_error: bool) -> None:
    recorded.append((title, text, is_error))
    del recorded[:-_MAX_RECORDED]


def error(title: str, text: str) -> str:
    """Print ``text`` as an error and show it where the person works: in the open task
    panel that asked for the work (``in_panel``), else in a box (GUI, unless dialogs are off)."""
    text = printable(text)
    _record(title, text, True)
    FreeCAD.Console.PrintError(f"tsplcam: {text}\n")
    if _panels:
        _panels[-1](title, text)
    elif show_dialogs and FreeCAD.GuiUp:
        import FreeCADGui
        from PySide import QtGui
        QtGui.QMessageBox.critical(FreeCADGui.getMainWindow(), title, text)
    return text


def warning(title: str, text: str) -> str:
    text = printable(text)
    _record(title, text, False)
    FreeCAD.Console.PrintWarning(f"tsplcam: {text}\n")
    if show_dialogs and FreeCAD.GuiUp:
        import FreeCADGui
        from PySide import QtGui
        QtGui.QMessageBox.warning(FreeCADGui.getMainWindow(), title, text)
    return text


def info(text: str) -> None:
    FreeCAD.Console.PrintMessage(f"tsplcam: {text}\n")


def exception(title: str, exc: BaseException, action: str = "") -> str:
    """Report an exception: its message for tsplcam errors, plus the traceback in the log for
    anything else. Returns the message shown."""
    if not isinstance(exc, TsplcamError):
        FreeCAD.Console.PrintMessage("".join(traceback.format_exception(type(exc), exc, exc.__traceback__)))
    return error(title, describe(exc, action))


@contextlib.contextmanager
def in_panel(show):
    """Inside the block errors go to ``show(title, text)`` (a task panel's error line next to
    the control or step concerned) instead of a message box; the Report view gets them too."""
    _panels.append(show)
    try:
        yield
    finally:
        _panels.remove(show)


@contextlib.contextmanager
def quiet():
    """No dialogs inside the block (messages still go to the Report view and ``recorded``)."""
    global show_dialogs
    before = show_dialogs
    show_dialogs = False
    try:
        yield recorded
    finally:
        show_dialogs = before
