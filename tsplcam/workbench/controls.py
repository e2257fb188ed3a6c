"""Controls for options of :class:`tsplcam.settings.JobSettings`, one per field of ``fields``:
a spin box with its unit (mm, mm/min, degrees, rpm), a check box, a list, or a text of
numbers; grouped as the command line groups them. The task panels of the tool path and the
program and the preferences page are built from these, so they show the same words, units
and limits.
"""
from __future__ import annotations

from PySide import QtGui

from ..errors import InputError
from ..settings import GROUPS
from .fields import Field, choices, from_property, to_property

ERROR_STYLE = "background-color: #ffd8d8"
# which tool-axis controls matter for which target
TARGET_NEEDS = {"axis": ("axis",), "lead-tilt": ("lead", "side_tilt"), "toward-point": ("point",),
                "away-from-point": ("point",), "toward-line": ("point", "direction"),
                "away-from-line": ("point", "direction")}
TARGET_FIELDS = ("axis", "lead", "side_tilt", "point", "direction")
AXIS_FIELDS = ("target", "axis", "lead", "side_tilt", "point", "direction", "max_tilt", "limit_axis",
               "tilt_range", "pole_tilt", "max_lead", "max_side_tilt", "max_axis_step", "holder_clearance",
               "smoothing_length", "rotary_weight", "tool")
SPECIAL = {"max_tilt": "machine's range", "spindle": "machine's", "tool_radius": "the tool's"}


def _spin(f: Field) -> QtGui.QDoubleSpinBox:
    w = QtGui.QDoubleSpinBox()
    w.setKeyboardTracking(False)
    kind = f.kind
    if kind in ("length", "length0"):
        w.setDecimals(4)
        w.setRange(0.0 if kind == "length0" or f.unset == 0.0 else 0.0001, 10000.0)
        w.setSingleStep(0.001 if f.name in ("scallop", "chord_tol") else 0.1)
    elif kind == "feed":
        w.setDecimals(0)
        w.setRange(1.0, 1e6)
        w.setSingleStep(100.0)
    elif kind == "rpm":
        w.setDecimals(0)
        w.setRange(0.0, 1e6)
        w.setSingleStep(500.0)
    elif kind == "angle":
        w.setDecimals(3)
        w.setRange(0.0 if f.name == "max_tilt" else -180.0, 180.0)
    else:
        w.setDecimals(3)
        w.setRange(0.0, 1e6)
    if f.unit:
        w.setSuffix(" " + f.unit)
    if f.name in SPECIAL:
        w.setSpecialValueText(SPECIAL[f.name])
    return w


class FieldControls:
    """A form of controls for ``table`` (fields.Field), grouped; ``changed()`` is called on
    every edit. ``values()`` reads them as option values (bad text is refused naming the
    control), ``set_values`` shows option values, ``mark`` shows an error next to one."""

    def __init__(self, table, values: dict, changed=None):
        self.table = list(table)
        self.changed = changed or (lambda: None)
        self.widget = QtGui.QWidget()
        outer = QtGui.QVBoxLayout(self.widget)
        outer.setContentsMargins(0, 0, 0, 0)
        self.controls: dict = {}
        self.labels: dict = {}
        self.boxes: dict = {}
        for group in GROUPS:
            members = [f for f in self.table if f.spec.metadata["group"] == group]
            if not members:
                continue
            box = QtGui.QGroupBox(GROUPS[group][:1].upper() + GROUPS[group][1:])
            form = QtGui.QFormLayout(box)
            form.setFieldGrowthPolicy(QtGui.QFormLayout.AllNonFixedFieldsGrow)
            for f in members:
                w = self._make(f)
                label = QtGui.QLabel(f.label)
                label.setToolTip(f.tip)
                w.setToolTip(f.tip)
                w.setObjectName(f.prop)
                form.addRow(label, w)
                self.controls[f.name] = (f, w)
                self.labels[f.name] = label
            self.boxes[group] = box
            outer.addWidget(box)
        self.set_values(values)
        self._update_enabled()

    # -- building -------------------------------------------------------------------------------
    def _make(self, f: Field):
        if f.ptype == "App::PropertyBool":
            w = QtGui.QCheckBox()
            w.toggled.connect(self._edited)
        elif f.ptype == "App::PropertyEnumeration":
            w = QtGui.QComboBox()
            w.addItems(choices(f))
            w.currentIndexChanged.connect(self._edited)
        elif f.ptype in ("App::PropertyVector", "App::PropertyString"):
            w = QtGui.QLineEdit()
            w.setPlaceholderText("not given" if f.unset == "" else "x, y, z")
            if f.unit:
                w.setToolTip(f"{f.tip} ({f.unit})")
            w.editingFinished.connect(self._edited)
        else:
            w = _spin(f)
            w.valueChanged.connect(self._edited)
        return w

    def _edited(self, *args):
        self._update_enabled()
        self.changed()

    def _update_enabled(self) -> None:
        """Tool-axis controls only where they act: none for surface-normal axes, the target's
        own controls for the chosen target."""
        orientation = self._raw("orientation")
        target = self._raw("target")
        for name, (f, w) in self.controls.items():
            on = True
            if orientation == "normal" and name in AXIS_FIELDS:
                on = False
            elif name in TARGET_FIELDS and target is not None:
                on = name in TARGET_NEEDS.get(target, ())
            w.setEnabled(on)
            self.labels[name].setEnabled(on)

    # -- values ----------------------------------------------------------------------------------
    def _raw(self, name):
        if name not in self.controls:
            return None
        f, w = self.controls[name]
        if isinstance(w, QtGui.QComboBox):
            return w.currentText()
        return None

    def value(self, name: str):
        f, w = self.controls[name]
        if isinstance(w, QtGui.QCheckBox):
            return bool(w.isChecked())
        if isinstance(w, QtGui.QComboBox):
            return from_property(f, w.currentText())
        if isinstance(w, QtGui.QLineEdit):
            text = w.text().strip()
            as_text = f if f.ptype == "App::PropertyString" else Field(f.name, f.prop, f.label,
                                                                          "App::PropertyString", f.unit, "")
            try:
                value = from_property(as_text, text)
                if value is None and f.unset is None:
                    raise InputError("numbers separated by commas are needed", item=f.prop)
                return value
            except InputError as exc:
                raise InputError(exc.message, item=f.label) from None
        return from_property(f, float(w.value()))

    def values(self) -> dict:
        """Option values of every control (only the enabled ones count for the target's)."""
        return {name: self.value(name) for name in self.controls}

    def set_values(self, values: dict) -> None:
        for name, (f, w) in self.controls.items():
            if name not in values:
                continue
            v = values[name]
            w.blockSignals(True)
            try:
                if isinstance(w, QtGui.QCheckBox):
                    w.setChecked(bool(v))
                elif isinstance(w, QtGui.QComboBox):
                    text = to_property(f, v) if v is not None or f.unset is not None else ""
                    k = w.findText(str(text))
                    if k >= 0:
                        w.setCurrentIndex(k)
                elif isinstance(w, QtGui.QLineEdit):
                    w.setText("" if v is None else ", ".join(f"{float(x):g}" for x in v))
                else:
                    w.setValue(float(to_property(f, v)) if v is not None or f.unset is not None else 0.0)
            finally:
                w.blockSignals(False)
        self._update_enabled()

    # -- errors ----------------------------------------------------------------------------------
    def clear_marks(self) -> None:
        for name, (f, w) in self.controls.items():
            w.setStyleSheet("")
            w.setToolTip(f.tip)

    def mark(self, item: str | None, text: str) -> bool:
        """Show ``text`` at the control an error's item names (property, label or option);
        True when one was found."""
        for name, (f, w) in self.controls.items():
            if item in (name, f.prop, f.label) or (item and item.startswith(f.prop + " ")):
                w.setStyleSheet(ERROR_STYLE)
                w.setToolTip(text)
                return True
        return False
