"""Task panel of the processing list: accept or edit the plan, re-solve around pins.

A table of the steps (patch, start, finish, crossfeed, how each step is reached, pins).
Changing a start, finish or crossfeed pins that field; Up/Down moves a step and pins its
position; "Pin order" pins or frees the position of the selected steps. "Solve" keeps the
pins and lets the planner do the rest (``tsplcam plan --complete``). Every edit is
checked at once against the model's layout (``tsplcam.plan.listfile.check``); the status
line says what is wrong (step and reason) or sums the list up. OK stores only a valid list.
"""
from __future__ import annotations

import copy
import os

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

from ..errors import InputError
from ..layout.layout import Layout
from . import messages
from .modelobject import model_of
from .planobject import plan_of, replan
from .resources import icon, ui_file

COLUMNS = ("Patch", "Start", "Finish", "Feed", "Link", "Pins")
TIPS = ("Patch machined in this step", "Start corner of the zigzag (u, v)",
        "Finish corner of the zigzag (u, v)",
        "Crossfeed: u = lines of constant u stepped across u; v = lines of constant v",
        "How the step is reached: first, boundary (corner of a shared edge), corner (a corner "
        "shared without an edge), RETRACT",
        "Pinned fields Solve keeps: P position, S start, F finish, C crossfeed")
CORNERS = ("LL (0,0)", "LR (1,0)", "UR (1,1)", "UL (0,1)")      # CORNER_NAMES, short
PIN_LETTERS = {"position": "P", "start": "S", "finish": "F", "crossfeed": "C"}


def _widen_task_dock(table, extra: int = 110) -> None:
    """Widen the dock holding the task panel so every column of ``table`` and every button
    shows (a fresh FreeCAD opens the Combo View about 250 px wide)."""
    mw = FreeCADGui.getMainWindow()
    docks = [d for d in mw.findChildren(QtGui.QDockWidget) if d.objectName() in ("Combo View", "Tasks")]
    if not docks:
        return
    table.resizeColumnsToContents()
    width = table.verticalHeader().width() + sum(table.columnWidth(k) for k in range(table.columnCount()))
    for dock in docks:
        if dock.width() < width + extra:
            mw.resizeDocks([dock], [width + extra], QtCore.Qt.Horizontal)


class ProcessingListPanel:
    """FreeCAD task panel (``form``, ``accept``, ``reject``) over a working copy of the list."""

    active = None        # the open panel (tests and the view provider reach it here)

    def __init__(self, obj):
        self.obj = obj
        self.model = model_of(obj.Model)
        self.layout = Layout.from_model(self.model)
        self.plist = copy.deepcopy(plan_of(obj))
        self.valid = True
        self.form = self._build()
        self._fill()
        _widen_task_dock(self.table)
        ProcessingListPanel.active = self

    # -- widgets --------------------------------------------------------------------------------
    def _build(self):
        """The form from resources/ui/processing_list.ui; headers and signals here."""
        w = FreeCADGui.PySideUic.loadUi(ui_file("processing_list"))
        w.setWindowIcon(QtGui.QIcon(icon("plan")))
        self.table = w.findChild(QtGui.QTableWidget, "table")
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        for k, tip in enumerate(TIPS):
            self.table.horizontalHeaderItem(k).setToolTip(tip)
        self.table.verticalHeader().setVisible(True)
        self.table.horizontalHeader().setSectionResizeMode(QtGui.QHeaderView.ResizeToContents)
        self.table.itemSelectionChanged.connect(self._selection_changed)
        self.buttons = {}
        for key in ("up", "down", "pin", "clear", "solve", "load", "save"):
            b = w.findChild(QtGui.QPushButton, key)
            b.clicked.connect(getattr(self, "_on_" + key))
            self.buttons[key] = b
        self.status = w.findChild(QtGui.QLabel, "status")
        return w

    def _combo(self, values, current, on_change):
        c = QtGui.QComboBox()
        c.addItems(list(values))
        c.setCurrentIndex(current if current is not None else -1)
        c.currentIndexChanged.connect(on_change)
        return c

    def _fill(self) -> None:
        """Show the working list in the table and check it."""
        self._check()
        t = self.table
        t.blockSignals(True)
        t.setRowCount(len(self.plist.steps))
        for i, s in enumerate(self.plist.steps):
            item = QtGui.QTableWidgetItem(str(s.patch))
            item.setFlags(item.flags() & ~QtCore.Qt.ItemIsEditable)
            t.setItem(i, 0, item)
            t.setCellWidget(i, 1, self._combo(CORNERS, s.start,
                                              lambda k, i=i: self._edit(i, "start", k)))
            t.setCellWidget(i, 2, self._combo(CORNERS, s.finish,
                                              lambda k, i=i: self._edit(i, "finish", k)))
            t.setCellWidget(i, 3, self._combo(("u", "v"), ("u", "v").index(s.crossfeed)
                                              if s.crossfeed in ("u", "v") else None,
                                              lambda k, i=i: self._edit(i, "crossfeed", k)))
            reached = "RETRACT" if s.retract_before else (s.link or "")
            pins = "".join(PIN_LETTERS[f] for f in PIN_LETTERS if f in s.pinned)
            for col, text in ((4, reached), (5, pins)):
                it = QtGui.QTableWidgetItem(text)
                it.setFlags(it.flags() & ~QtCore.Qt.ItemIsEditable)
                t.setItem(i, col, it)
        t.blockSignals(False)
        t.resizeColumnsToContents()

    # -- editing ----------------------------------------------------------------------------------
    def _edit(self, i: int, field: str, index: int) -> None:
        if index < 0:
            return
        s = self.plist.steps[i]
        value = ("u", "v")[index] if field == "crossfeed" else index
        if getattr(s, field) == value:
            return
        setattr(s, field, value)
        s.pinned = frozenset(s.pinned | {field})
        self._fill()

    def _selected_rows(self) -> list[int]:
        return sorted({ix.row() for ix in self.table.selectionModel().selectedRows()})

    def _move(self, delta: int) -> None:
        rows = self._selected_rows()
        if len(rows) != 1:
            return
        i, j = rows[0], rows[0] + delta
        steps = self.plist.steps
        if not 0 <= j < len(steps):
            return
        steps[i], steps[j] = steps[j], steps[i]
        steps[j].pinned = frozenset(steps[j].pinned | {"position"})
        self._fill()
        self.table.selectRow(j)

    def _on_up(self):
        self._move(-1)

    def _on_down(self):
        self._move(+1)

    def _on_pin(self):
        rows = self._selected_rows()
        steps = self.plist.steps
        pin = not all("position" in steps[i].pinned for i in rows)
        for i in rows:
            p = set(steps[i].pinned)
            p.add("position") if pin else p.discard("position")
            steps[i].pinned = frozenset(p)
        self._fill()

    def _on_clear(self):
        for s in self.plist.steps:
            s.pinned = frozenset()
        self._fill()

    def _on_solve(self):
        try:
            self.plist = replan(self.model, self.plist)
        except Exception as exc:
            self._set_status(messages.describe(exc, "solving"), ok=False)
            return
        self._fill()

    def _on_load(self):
        path, _ = QtGui.QFileDialog.getOpenFileName(self.form, "Load processing list", "",
                                                    "Processing lists (*.json);;All files (*)")
        if path:
            self.load_file(path)

    def _on_save(self):
        path, _ = QtGui.QFileDialog.getSaveFileName(self.form, "Save processing list",
                                                    self.obj.Label + ".json", "Processing lists (*.json)")
        if path:
            self.save_file(path)

    def load_file(self, path: str) -> bool:
        """Replace the working list by a file's (pinned fields solved later with Solve)."""
        from ..plan import load
        try:
            self.plist = load(path, self.layout, partial=True)
        except Exception as exc:
            messages.exception("Processing list", exc, f"reading {path}")
            return False
        self._fill()
        return True

    def save_file(self, path: str) -> bool:
        from ..plan import save
        if not self._check():
            messages.error("Processing list", "the list is not valid: " + self.status.text())
            return False
        save(self.plist, path)
        messages.info(f"wrote {os.path.basename(path)}")
        return True

    def _selection_changed(self):
        rows = self._selected_rows()
        vobj = getattr(self.obj, "ViewObject", None)
        if vobj is not None and hasattr(vobj, "CurrentStep"):
            vobj.CurrentStep = rows[0] + 1 if len(rows) == 1 else 0

    # -- checking ---------------------------------------------------------------------------------
    def _set_status(self, text: str, ok: bool) -> None:
        self.valid = ok
        self.status.setText(text)
        self.status.setStyleSheet("" if ok else "color: #b00000; font-weight: bold")

    def _check(self) -> bool:
        from ..plan.listfile import check
        try:
            check(self.plist, self.layout)
        except InputError as exc:
            self._set_status(str(exc), ok=False)
            return False
        p = self.plist
        self._set_status(f"{len(p.steps)} steps: {p.boundary_links} boundary links, "
                         f"{p.corner_links} corner links, {p.retractions} retractions", ok=True)
        return True

    # -- FreeCAD task panel protocol ------------------------------------------------------------------
    def getStandardButtons(self):
        return int(QtGui.QDialogButtonBox.Ok | QtGui.QDialogButtonBox.Cancel)

    def accept(self):
        if not self._check():
            messages.error("Processing list", "not stored: " + self.status.text())
            return False
        doc = self.obj.Document
        doc.openTransaction("Edit processing list")
        self.obj.Proxy.set_list(self.obj, self.plist)
        doc.recompute()
        doc.commitTransaction()
        self._close()
        return True

    def reject(self):
        self._close()
        return True

    def _close(self):
        ProcessingListPanel.active = None
        vobj = getattr(self.obj, "ViewObject", None)
        if vobj is not None and hasattr(vobj, "CurrentStep"):
            vobj.CurrentStep = 0
        FreeCADGui.Control.closeDialog()
        gdoc = FreeCADGui.getDocument(self.obj.Document.Name)
        if gdoc is not None and gdoc.getInEdit() is not None:
            gdoc.resetEdit()
