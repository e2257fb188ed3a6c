"""Task panels of the tool path and the program, and the preferences page.

Every option of the object (``fields.PATH_FIELDS`` or ``PROGRAM_FIELDS``) with its unit,
in a CAM programmer's words; "Generate" stores them and recomputes the object (in the GUI
with a progress bar and Cancel in the status bar), and an error appears in the panel, next
to the option it names, instead of in a box. The program's panel also moves the shaded tool
and holder along the path (a slider over the path points, naming patch and (u, v), tilt and
machine angles) and picks how the path is coloured (tilt, patch, feed).

The preferences page (Edit > Preferences > T-spline CAM) shows the same controls for every
option: the defaults of new tool paths and programs (``prefs``).
"""
from __future__ import annotations

import numpy as np

import FreeCADGui
from PySide import QtCore, QtGui

from . import messages, prefs, validity
from .proxy import close_task_panel
from .controls import FieldControls
from .fields import PATH_FIELDS, PREFS_FIELDS, PROGRAM_FIELDS, PROPERTY_OF, checked, set_values, values_of
from .modelobject import plural
from .resources import icon

ERROR_STYLE = "color: #b00000; font-weight: bold"


def _is_program(obj) -> bool:
    from .programobject import is_program_object
    return is_program_object(obj)


def widen_task_dock(width: int) -> None:
    """Widen the dock holding the task panels to ``width`` pixels when it is narrower (a fresh
    FreeCAD opens the Combo View about 250 px wide: too narrow for labels, values and units)."""
    mw = FreeCADGui.getMainWindow()
    for dock in mw.findChildren(QtGui.QDockWidget):
        if dock.objectName() in ("Combo View", "Tasks") and dock.width() < width:
            mw.resizeDocks([dock], [width], QtCore.Qt.Horizontal)


class TaskPanel:
    """What every tsplcam task panel shares: OK and Cancel, and closing (``closing`` clears
    what the panel showed in the 3D view); ``active`` is the open panel of each kind (tests
    reach it there)."""
    active = None

    def getStandardButtons(self):
        return int(QtGui.QDialogButtonBox.Ok | QtGui.QDialogButtonBox.Cancel)

    def reject(self):
        self._close()
        return True

    def closing(self) -> None:
        """Subclasses: undo what the panel showed in the view."""

    def _close(self):
        type(self).active = None
        self.closing()
        close_task_panel(self.obj)


class SettingsPanel(TaskPanel):
    """FreeCAD task panel (``form``, ``accept``, ``reject``) over a tool path or program."""

    active = None

    def __init__(self, obj):
        self.obj = obj
        self.program = _is_program(obj)
        self.table = PROGRAM_FIELDS if self.program else PATH_FIELDS
        values = values_of(obj, self.table)
        self.dirty = False
        self.form = QtGui.QWidget()
        self.form.setWindowTitle(obj.Label)
        self.form.setWindowIcon(QtGui.QIcon(icon("program" if self.program else "toolpath")))
        lay = QtGui.QVBoxLayout(self.form)
        self.controls = FieldControls(self.table, values, self._changed)
        lay.addWidget(self.controls.widget)
        row = QtGui.QHBoxLayout()
        self.generate = QtGui.QPushButton("Generate")
        self.generate.setObjectName("generate")
        self.generate.setToolTip("Store these values and compute again (progress and Cancel in the status bar)")
        self.generate.clicked.connect(self.apply)
        self.save_defaults = QtGui.QPushButton("Use as defaults")
        self.save_defaults.setToolTip("Make these values the defaults of new objects (Preferences > T-spline CAM)")
        self.save_defaults.clicked.connect(self._save_defaults)
        row.addWidget(self.generate)
        row.addWidget(self.save_defaults)
        lay.addLayout(row)
        self.status = QtGui.QLabel()
        self.status.setObjectName("status")
        self.status.setWordWrap(True)
        self.status.setTextInteractionFlags(QtCore.Qt.TextSelectableByMouse)
        lay.addWidget(self.status)
        if self.program:
            lay.addWidget(self._preview_box())
        self._show_state()
        widen_task_dock(self.form.sizeHint().width() + 60)
        SettingsPanel.active = self

    # -- the program's preview ---------------------------------------------------------------------
    def _preview_box(self):
        box = QtGui.QGroupBox("Preview")
        form = QtGui.QFormLayout(box)
        self.colour = QtGui.QComboBox()
        vobj = getattr(self.obj, "ViewObject", None)
        modes = list(vobj.getEnumerationsOfProperty("ColourBy")) if vobj is not None else ["Tilt"]
        self.colour.addItems(modes)
        if vobj is not None:
            self.colour.setCurrentIndex(max(0, modes.index(vobj.ColourBy)))
        self.colour.currentIndexChanged.connect(self._colour_changed)
        form.addRow("Colour the path by", self.colour)
        self.slider = QtGui.QSlider(QtCore.Qt.Horizontal)
        self.slider.setObjectName("tool_at")
        self.slider.setToolTip("Move the tool, shank and holder along the path")
        self.slider.valueChanged.connect(self._move_tool)
        self.show_tool = QtGui.QCheckBox("Show tool and holder")
        self.show_tool.toggled.connect(lambda on: self._move_tool(self.slider.value()))
        self.where = QtGui.QLabel()
        self.where.setWordWrap(True)
        form.addRow(self.show_tool)
        form.addRow("Along the path", self.slider)
        form.addRow(self.where)
        self._reset_slider()
        return box

    def _reset_slider(self) -> None:
        try:
            n = len(self.obj.Proxy.oriented_path(self.obj))
        except Exception:
            n = 0
        self.slider.setRange(0, max(0, n - 1))
        self.slider.setEnabled(n > 0)

    def _colour_changed(self, k: int) -> None:
        vobj = getattr(self.obj, "ViewObject", None)
        if vobj is not None:
            vobj.ColourBy = self.colour.itemText(k)

    def _move_tool(self, k: int) -> None:
        vobj = getattr(self.obj, "ViewObject", None)
        on = self.show_tool.isChecked()
        if vobj is not None:
            vobj.ToolAt = int(k) if on else -1
        try:
            tp = self.obj.Proxy.oriented_path(self.obj)
        except Exception:
            self.where.setText("")
            return
        if not 0 <= k < len(tp):
            return
        tilt = float(np.degrees(np.arccos(np.clip(tp.axis[k, 2], -1.0, 1.0))))
        patch = int(tp.patch[k])
        where = (f"patch {patch}, (u, v) = ({tp.uv[k, 0]:.4f}, {tp.uv[k, 1]:.4f})" if patch >= 0
                 else "in the air (retract)")
        self.where.setText(f"point {k} of {len(tp)}: {where}; tool axis tilted {tilt:.1f} deg")

    # -- values ------------------------------------------------------------------------------------
    def _changed(self) -> None:
        self.dirty = True
        self.controls.clear_marks()

    def _values(self) -> dict | None:
        try:
            values = self.controls.values()
            probe = dict(values)
            if self.program:
                probe.update(values_of(self.obj.ToolPath, PATH_FIELDS))
                probe["tool"] = self.obj.ToolFile or values["tool"]
            checked(probe)
        except Exception as exc:
            self.show_error("", messages.describe(exc))
            return None
        return values

    def show_error(self, title: str, text: str) -> None:
        self.status.setText(text)
        self.status.setStyleSheet(ERROR_STYLE)
        item = text.split(":", 1)[0].strip() if ":" in text else None
        if item:
            name = next((n for n, p in PROPERTY_OF.items() if p == item), item)
            self.controls.mark(name, text)

    def _show_state(self) -> None:
        why = validity.problem(self.obj)
        if why:
            self.status.setText(f"not valid: {why}")
            self.status.setStyleSheet(ERROR_STYLE)
            return
        self.status.setStyleSheet("")
        o = self.obj
        if self.program:
            self.status.setText(f"{o.Blocks} blocks for {o.Machine}, machining time {o.MachiningTime}, "
                                f"largest axis step {o.LargestAxisStep.Value:.2f} deg, "
                                f"smallest clearance {o.SmallestClearance.Value:.3f} mm, "
                                f"{plural(o.Collisions, 'collision')}")
        else:
            self.status.setText(f"{o.Points} points, {plural(o.Lines, 'pass', 'passes')}, largest stepover "
                                f"{o.LargestStepover.Value:.4f} mm, {plural(o.Retractions, 'retraction')}, "
                                f"cut {o.CutLength.Value:.1f} mm")

    def apply(self) -> bool:
        """Store the values and recompute; True when the object came out valid."""
        values = self._values()
        if values is None:
            return False
        doc = self.obj.Document
        try:
            set_values(self.obj, self.table, values)
        except Exception as exc:
            self.show_error("", messages.describe(exc))
            return False
        self.status.setText("computing...")
        self.status.setStyleSheet("")
        errors = []
        with messages.in_panel(lambda title, text: errors.append(text)):
            doc.recompute()
        self.dirty = False
        if errors or validity.failed(self.obj):
            self.show_error("", errors[0] if errors else validity.problem(self.obj) or "recompute failed")
            return False
        self._show_state()
        if self.program:
            self._reset_slider()
        return True

    def _save_defaults(self) -> None:
        values = self._values()
        if values is None:
            return
        try:
            prefs.store(values)
        except Exception as exc:
            self.show_error("", messages.describe(exc))
            return
        messages.info(f"defaults of new {'programs' if self.program else 'tool paths'} stored")

    # -- FreeCAD task panel protocol ------------------------------------------------------------------
    def accept(self):
        if self.dirty and not self.apply():
            return False
        self._close()
        return True

    def closing(self):
        vobj = getattr(self.obj, "ViewObject", None)
        if vobj is not None and "ToolAt" in vobj.PropertiesList:
            vobj.ToolAt = -1


class PreferencesPage:
    """Edit > Preferences > T-spline CAM: the defaults of new tool paths and programs."""

    def __init__(self, parent=None):
        self.form = QtGui.QWidget(parent)
        self.form.setWindowTitle("T-spline CAM")
        lay = QtGui.QVBoxLayout(self.form)
        note = QtGui.QLabel("Defaults of new tool paths and programs (the command line's defaults until "
                            "changed here). Lengths in mm, feeds in mm/min, angles in degrees.")
        note.setWordWrap(True)
        lay.addWidget(note)
        self.controls = FieldControls(PREFS_FIELDS, prefs.defaults())
        scroll = QtGui.QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(self.controls.widget)
        lay.addWidget(scroll, 1)
        reset = QtGui.QPushButton("Engine defaults")
        reset.clicked.connect(lambda: self.controls.set_values({f.name: f.default for f in PREFS_FIELDS}))
        lay.addWidget(reset)

    def loadSettings(self):
        self.controls.set_values(prefs.defaults())

    def saveSettings(self):
        try:
            prefs.store(self.controls.values())
        except Exception as exc:
            messages.error("T-spline CAM preferences", messages.describe(exc))
