"""Task panel of the processing list: accept or edit the plan, re-solve around pins.

A table of the steps (patch, start, finish, crossfeed, retract before, how each step is
reached, pins). Changing a start, finish or crossfeed pins that field; dragging a step's
number, or Up/Down, moves the step and pins its position; "Pin order" pins or frees the
position of the selected steps; the Retract box makes a step start with a retraction.
"Solve" keeps the pins and lets the planner do the rest (``tsplcam plan --complete``).
Every edit is checked at once against the model's layout (``tsplcam.plan.listfile.check``,
also "Validate"): the step at fault turns red with the reason beside it, and the status line
says it too, or sums the list up. The 3D view draws the working list and outlines the
selected step's patch with its start (green) and finish (red) corners. OK stores only a
valid list.
"""
from __future__ import annotations

import copy
import os
import re

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

from ..errors import InputError
from ..layout.layout import Layout
from . import messages
from .modelobject import model_of
from .planobject import plan_of, replan
from .resources import icon, ui_file
from .settingspanel import TaskPanel

COLUMNS = ("Patch", "Start", "Finish", "Crossfeed", "Retract", "Reached by", "Pins")
TIPS = ("Patch machined in this step", "Start corner of the zigzag (u, v)",
        "Finish corner of the zigzag (u, v)",
        "Crossfeed: the direction the passes step over; u = passes along v, stepped across u; "
        "v = passes along u, stepped across v",
        "Retract before this step (to the clearance height) instead of linking on the surface",
        "How the step is reached: first, boundary (corner of a shared edge), corner (a corner "
        "shared without an edge), RETRACT",
        "Pinned fields Solve keeps: P position, S start, F finish, C crossfeed")
BAD_ROW = QtGui.QColor(255, 200, 200) if hasattr(QtGui, "QColor") else None
CORNERS = ("LL (0,0)", "LR (1,0)", "UR (1,1)", "UL (0,1)")      # CORNER_NAMES, short
PIN_LETTERS = {"position": "P", "start": "S", "finish": "F", "crossfeed": "C"}


def _widen_task_dock(table, extra: int = 110) -> None:
    """Widen the dock holding the task panel so every column of ``table`` and every button
    shows."""
    from .settingspanel import widen_task_dock
    table.resizeColumnsToContents()
    width = table.verticalHeader().width() + sum(table.columnWidth(k) for k in range(table.columnCount()))
    widen_task_dock(width + extra)


class ProcessingListPanel(TaskPanel):
    """FreeCAD task panel (``form``, ``accept``, ``reject``) over a working copy of the list."""

    active = None        # the open panel (tests and the view provider reach it here)

    def __init__(self, obj):
        self.obj = obj
        self.model = model_of(obj.Model)
        self.layout = Layout.from_model(self.model)
        self.plist = copy.deepcopy(plan_of(obj))
        self.valid = True
        self.bad_row = None
        self.bad_text = ""
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
        header = self.table.verticalHeader()
        header.setSectionsMovable(True)
        header.setToolTip("Drag a step's number to move the step (pins its position)")
        header.sectionMoved.connect(self._dragged)
        self.bad_row = None
        self.buttons = {}
        for key in ("up", "down", "pin", "clear", "solve", "load", "save", "validate"):
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
            box = QtGui.QCheckBox()
            box.setChecked(bool(s.retract_before))
            box.setEnabled(i > 0)
            box.setToolTip(TIPS[4])
            box.toggled.connect(lambda on, i=i: self._edit(i, "retract_before", bool(on)))
            t.setCellWidget(i, 4, box)
            reached = "RETRACT" if s.retract_before else (s.link or "")
            pins = "".join(PIN_LETTERS[f] for f in PIN_LETTERS if f in s.pinned)
            for col, text in ((5, reached), (6, pins)):
                it = QtGui.QTableWidgetItem(text)
                it.setFlags(it.flags() & ~QtCore.Qt.ItemIsEditable)
                t.setItem(i, col, it)
        self._mark_rows()
        t.blockSignals(False)
        t.resizeColumnsToContents()
        self._show_in_view()

    # -- editing ----------------------------------------------------------------------------------
    def _edit(self, i: int, field: str, index) -> None:
        if field != "retract_before" and index < 0:
            return
        s = self.plist.steps[i]
        value = ("u", "v")[index] if field == "crossfeed" else index
        if getattr(s, field) == value:
            return
        setattr(s, field, value)
        if field != "retract_before":
            s.pinned = frozenset(s.pinned | {field})
        self._fill()
        self.table.selectRow(i)

    def _dragged(self, logical: int, old: int, new: int) -> None:
        """A step's number dragged from row ``old`` to row ``new``: move the step there (its
        position pinned), and put the header back in order for the refilled table."""
        header = self.table.verticalHeader()
        header.blockSignals(True)
        header.moveSection(new, old)
        header.blockSignals(False)
        self.move_step(old, new)

    def move_step(self, i: int, j: int) -> None:
        """Move the step of row ``i`` to row ``j`` and pin its position."""
        steps = self.plist.steps
        if i == j or not (0 <= i < len(steps) and 0 <= j < len(steps)):
            return
        step = steps.pop(i)
        steps.insert(j, step)
        step.pinned = frozenset(step.pinned | {"position"})
        self._fill()
        self.table.selectRow(j)

    def _selected_rows(self) -> list[int]:
        return sorted({ix.row() for ix in self.table.selectionModel().selectedRows()})

    def _move(self, delta: int) -> None:
        rows = self._selected_rows()
        if len(rows) != 1:
            return
        i, j = rows[0], rows[0] + delta
        self.move_step(i, j)

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

    def _view(self):
        vobj = getattr(self.obj, "ViewObject", None)
        return getattr(vobj, "Proxy", None) if vobj is not None else None

    def _show_in_view(self) -> None:
        vp = self._view()
        if vp is not None and hasattr(vp, "show_list"):
            vp.show_list(self.plist)
            self._selection_changed()

    def _selection_changed(self):
        rows = self._selected_rows()
        vp = self._view()
        if vp is not None and hasattr(vp, "show_step"):
            vp.show_step(self.plist.steps[rows[0]] if len(rows) == 1 else None)

    def selected_step(self):
        rows = self._selected_rows()
        return self.plist.steps[rows[0]] if len(rows) == 1 else None

    def _on_validate(self):
        self._fill()
        if not self.valid and self.bad_row is not None:
            self.table.selectRow(self.bad_row)
            self.table.scrollToItem(self.table.item(self.bad_row, 0))

    # -- checking ---------------------------------------------------------------------------------
    def _set_status(self, text: str, ok: bool) -> None:
        self.valid = ok
        self.status.setText(text)
        self.status.setStyleSheet("" if ok else "color: #b00000; font-weight: bold")

    def _check(self) -> bool:
        from ..plan.listfile import check
        self.bad_row = None
        for s in self.plist.steps:           # how a step is reached follows from the order
            s.link = None
        try:
            check(self.plist, self.layout)
        except InputError as exc:
            self._set_status(str(exc), ok=False)
            m = re.match(r"step (\d+)", exc.item or "")
            if m:
                self.bad_row = int(m.group(1)) - 1
                self.bad_text = exc.message
            return False
        p = self.plist
        self._set_status(f"{len(p.steps)} steps: {p.boundary_links} boundary links, "
                         f"{p.corner_links} corner links, {p.retractions} retractions", ok=True)
        return True

    def _mark_rows(self) -> None:
        """The step at fault red, with the reason as its tooltip; the others plain."""
        t = self.table
        for i in range(t.rowCount()):
            bad = i == self.bad_row
            for col in (0, 5, 6):
                it = t.item(i, col)
                if it is None:
                    continue
                it.setBackground(QtGui.QBrush(BAD_ROW) if bad else QtGui.QBrush())
                it.setToolTip(self.bad_text if bad else "")
            head = t.verticalHeaderItem(i) or QtGui.QTableWidgetItem(str(i + 1))
            head.setText(f"{i + 1} !" if bad else str(i + 1))
            head.setToolTip(self.bad_text if bad else "")
            t.setVerticalHeaderItem(i, head)

    # -- FreeCAD task panel protocol ------------------------------------------------------------------
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

    def closing(self):
        vp = self._view()
        if vp is not None and hasattr(vp, "show_list"):
            vp.step = None
            vp.show_list(None)
        vobj = getattr(self.obj, "ViewObject", None)
        if vobj is not None and hasattr(vobj, "CurrentStep"):
            vobj.CurrentStep = 0
