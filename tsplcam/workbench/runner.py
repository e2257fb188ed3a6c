"""Long work with a progress bar and a Cancel button, the GUI responsive meanwhile.

In the GUI a task of :mod:`tsplcam.workbench.worker` runs in a child process (the same
Python FreeCAD runs, ``python3 -m tsplcam.workbench.worker``): FreeCAD's event loop keeps
running (the window repaints, the view zooms), the engine's progress calls come back over a
pipe and show in the status bar as "stage, done of total", and Cancel (or Esc) ends the child
at once, whatever the engine is doing: no stage has to call back for a cancel to land.
Meanwhile input that could change the document (clicks on the tree, menus, the property
editor, keys) is held back; the view's wheel zoom and rotation pass.

Headless (freecadcmd, the tests' documents, ``job --fcstd``) the task runs in this process.

:func:`run` returns the task's result or raises what the task raised (a tsplcam error keeps
its message naming the place; the child's full traceback goes to the Report view), or
:class:`tsplcam.progress.Cancelled` after a cancel. ``last`` keeps the figures of the latest
run (seconds, the longest pause of the event loop, cancel latency) for tests and reports.
"""
from __future__ import annotations

import os
import pickle
import queue
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

import FreeCAD

from ..progress import Cancelled
from . import worker

#: "child": the GUI runs tasks in a child process (default); "inline": in FreeCAD's own
#: process (the headless default, and a fallback where no Python executable is found).
mode = "child"
active = None            # the run in progress (tests cancel it through here)
last: dict = {}          # figures of the latest run
POLL_MS = 25


def python_executable() -> str:
    """The Python FreeCAD itself runs (same version, same numpy, fcl, ...)."""
    v = sys.version_info
    for exe in (os.path.join(sys.prefix, "bin", f"python{v.major}.{v.minor}"),
                os.path.join(sys.prefix, "bin", f"python{v.major}"), "/usr/bin/python3"):
        if os.path.isfile(exe) and os.access(exe, os.X_OK):
            return exe
    exe = shutil.which("python3")
    if exe is None:
        raise RuntimeError("no python3 executable found for the worker process")
    return exe


def run(title: str, task: str, *args, **kwargs):
    """Run ``worker.<task>(*args, **kwargs)`` with progress and cancel (module doc)."""
    if not FreeCAD.GuiUp or mode != "child" or active is not None:
        return _inline(title, task, args, kwargs)
    return ChildRun(title, task, args, kwargs).run()


def _inline(title, task, args, kwargs):
    t = time.perf_counter()
    calls = []
    result = getattr(worker, task)(*args, progress=lambda *a: calls.append(a), **kwargs)
    last.clear()
    last.update(title=title, mode="inline", seconds=time.perf_counter() - t, progress=calls)
    return result


class ChildRun:
    """One task in a child process with its progress widget (see the module doc)."""

    def __init__(self, title, task, args, kwargs):
        self.title = title
        self.task = task
        self.args = args
        self.kwargs = kwargs
        self.lines: queue.Queue = queue.Queue()
        self.stderr: list[str] = []
        self.progress: list[tuple] = []
        self.cancelled_at = None
        self.done = False
        self.proc = None
        self.widget = None

    # -- the child --------------------------------------------------------------------------
    def _start(self, tmp: str) -> None:
        import tsplcam
        root = os.path.dirname(os.path.dirname(os.path.abspath(tsplcam.__file__)))
        env = dict(os.environ)
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        self.result_file = os.path.join(tmp, "result.pickle")
        self.proc = subprocess.Popen([python_executable(), "-m", "tsplcam.workbench.worker"], cwd=tmp, env=env,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     start_new_session=True)
        request = pickle.dumps((self.task, self.args, self.kwargs, self.result_file),
                               protocol=pickle.HIGHEST_PROTOCOL)

        def feed():
            try:
                self.proc.stdin.write(request)
                self.proc.stdin.close()
            except OSError:                    # the child ended (cancelled) before reading it all
                pass

        def read(stream, sink):
            for raw in iter(stream.readline, b""):
                sink(raw.decode("utf-8", "replace").rstrip("\n"))
            stream.close()
        for target, a in ((feed, ()), (read, (self.proc.stdout, self.lines.put)),
                          (read, (self.proc.stderr, self.stderr.append))):
            threading.Thread(target=target, args=a, daemon=True).start()

    def cancel(self) -> None:
        """End the child now (it and any processes it forked)."""
        if self.cancelled_at is not None or self.proc is None or self.done:
            return
        self.cancelled_at = time.perf_counter()
        if self.widget is not None:
            self.widget.set_text(f"{self.title}: stopping...")
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass

    # -- the loop -------------------------------------------------------------------------------
    def run(self):
        global active
        from PySide import QtCore
        tmp = tempfile.mkdtemp(prefix="tsplcam-run-")
        active = self
        t0 = time.perf_counter()
        gaps = [0.0]
        ticks = [t0]
        blocker = None
        try:
            self._start(tmp)
            self.widget = ProgressWidget(self.title, self.cancel)
            blocker = InputBlocker(self.widget, self.cancel)
            loop = QtCore.QEventLoop()

            def poll():
                now = time.perf_counter()
                gaps[0] = max(gaps[0], now - ticks[0])
                ticks[0] = now
                self._drain()
                if self.done or self.proc.poll() is not None:
                    self._drain()
                    loop.quit()
            timer = QtCore.QTimer()
            timer.setInterval(POLL_MS)
            timer.timeout.connect(poll)
            timer.start()
            loop.exec_()
            timer.stop()
            self.proc.wait()
            end = time.perf_counter()
            last.clear()
            last.update(title=self.title, mode="child", seconds=end - t0, max_gap=gaps[0], progress=self.progress,
                        cancel_latency=None if self.cancelled_at is None else end - self.cancelled_at)
            return self._result()
        finally:
            active = None
            if blocker is not None:
                blocker.remove()
            if self.widget is not None:
                self.widget.remove()
            if self.proc is not None and self.proc.poll() is None:
                self.cancel()
                self.proc.wait()
            shutil.rmtree(tmp, ignore_errors=True)

    def _drain(self) -> None:
        while True:
            try:
                line = self.lines.get_nowait()
            except queue.Empty:
                return
            if line == "D":
                self.done = True
            elif line.startswith("P\t"):
                _, stage, done, total = line.split("\t")
                self.progress.append((stage, int(done), int(total)))
                if self.widget is not None:
                    self.widget.show_progress(stage, int(done), int(total))

    def _result(self):
        if self.cancelled_at is not None:
            raise Cancelled(f"{self.title}: stopped on request")
        if not self.done or not os.path.isfile(self.result_file):
            tail = "\n".join(self.stderr[-20:])
            if tail:
                FreeCAD.Console.PrintMessage(tail + "\n")
            raise RuntimeError(f"{self.title}: the worker process ended with code {self.proc.returncode} "
                               f"before it finished")
        with open(self.result_file, "rb") as f:
            result = pickle.load(f)
        if result[0] == "ok":
            return result[1]
        _, exc, text, attrs = result
        for k, v in attrs.items():
            setattr(exc, k, v)
        FreeCAD.Console.PrintMessage(f"tsplcam worker ({self.title}):\n{text}")
        raise exc


# -- widgets -----------------------------------------------------------------------------------------
def _status_bar():
    import FreeCADGui
    return FreeCADGui.getMainWindow().statusBar()


class ProgressWidget:
    """Stage text, a bar and a Cancel button at the right of FreeCAD's status bar."""

    def __init__(self, title: str, on_cancel):
        from PySide import QtGui
        self.title = title
        w = QtGui.QWidget()
        w.setObjectName("tsplcam_progress")
        lay = QtGui.QHBoxLayout(w)
        lay.setContentsMargins(0, 0, 0, 0)
        self.label = QtGui.QLabel(f"{title}: starting")
        self.bar = QtGui.QProgressBar()
        self.bar.setRange(0, 0)                          # busy until the first report
        self.bar.setFixedWidth(180)
        self.button = QtGui.QPushButton("Cancel")
        self.button.setObjectName("tsplcam_cancel")
        self.button.setToolTip("Stop this computation now (Esc); nothing half-made is kept")
        self.button.clicked.connect(on_cancel)
        for x in (self.label, self.bar, self.button):
            lay.addWidget(x)
        self.widget = w
        _status_bar().addPermanentWidget(w)
        w.show()

    def set_text(self, text: str) -> None:
        self.label.setText(text)

    def show_progress(self, stage: str, done: int, total: int) -> None:
        if total > 0:
            self.bar.setRange(0, total)
            self.bar.setValue(min(done, total))
        self.label.setText(f"{self.title}: {stage} {done} of {total}")

    def remove(self) -> None:
        try:
            _status_bar().removeWidget(self.widget)
            self.widget.deleteLater()
        except RuntimeError:                 # the main window is gone (closing)
            pass


class InputBlocker:
    """Holds back input that could change the document while a run is going; Esc cancels.
    Wheel and mouse moves, and clicks of the middle and right buttons (view navigation),
    reach the 3D view; the progress widget gets everything."""

    def __init__(self, progress: ProgressWidget, on_cancel):
        from PySide import QtCore, QtGui
        E = QtCore.QEvent
        blocked = {E.MouseButtonPress, E.MouseButtonRelease, E.MouseButtonDblClick, E.KeyPress, E.KeyRelease,
                   E.Wheel, E.ContextMenu, E.Shortcut, E.ShortcutOverride, E.Drop, E.Close}
        keep = progress.widget
        app = QtGui.QApplication.instance()
        Qt = QtCore.Qt

        class Filter(QtCore.QObject):
            def eventFilter(self, obj, event):
                t = event.type()
                if t not in blocked:
                    return False
                if isinstance(obj, QtGui.QWidget) and (obj is keep or keep.isAncestorOf(obj)):
                    return False
                if t == E.KeyPress and event.key() == Qt.Key_Escape:
                    on_cancel()
                    return True
                if isinstance(obj, QtGui.QWidget) and _in_3d_view(obj):
                    if t == E.Wheel:
                        return False
                    if t in (E.MouseButtonPress, E.MouseButtonRelease) and event.button() != Qt.LeftButton:
                        return False
                return True
        self.filter = Filter()
        self.app = app
        app.installEventFilter(self.filter)

    def remove(self) -> None:
        self.app.removeEventFilter(self.filter)


def _in_3d_view(widget) -> bool:
    w = widget
    while w is not None:
        name = w.metaObject().className()
        if "View3DInventor" in name or name in ("QGLWidget", "QOpenGLWidget", "QuarterWidget"):
            return True
        w = w.parentWidget()
    return False
