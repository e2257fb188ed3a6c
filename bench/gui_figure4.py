"""GUI responsiveness and cancel latency of the workbench on the figure-4 sample (a macro).

    QTWEBENGINE_DISABLE_SANDBOX=1 xvfb-run -a -s "-screen 0 1280x1024x24" freecad bench/gui_figure4.py

Opens figure4, plans it, makes its tool path (scallop 0.01 mm, the issue's case) and program
(the defaults: smooth collision-free axes, Heidenhain) the way the commands do, while an
independent 20 ms Qt timer records how long FreeCAD's event loop went without running
(the longest pause is what a person feels as a freeze). Then it starts both again and
presses Cancel after a few seconds, and records how long the run took to stop. For
comparison the path is also made in FreeCAD's own process (runner.mode = "inline"), as
before the child process. Prints one line per figure and leaves with os._exit.
"""
import os
import sys
import time
import traceback


def log(*a):
    print(*a, file=sys.__stdout__)
    sys.__stdout__.flush()


class Ticks:
    """The longest interval between two runs of a 20 ms timer of the event loop."""

    def __init__(self):
        from PySide import QtCore
        self.timer = QtCore.QTimer()
        self.timer.setInterval(20)
        self.timer.timeout.connect(self.tick)

    def tick(self):
        now = time.perf_counter()
        self.gap = max(self.gap, now - self.last)
        self.last = now

    def __enter__(self):
        self.gap, self.last = 0.0, time.perf_counter()
        self.timer.start()
        return self

    def __exit__(self, *a):
        self.tick()
        self.timer.stop()


def main():
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    sys.path.insert(0, here)
    import FreeCAD
    import FreeCADGui
    from PySide import QtCore
    from tsplcam.model.samples import sample_path
    from tsplcam.workbench import importer, messages, pathobject, planobject, programobject, runner
    messages.show_dialogs = False
    FreeCADGui.activateWorkbench("TsplcamWorkbench")
    model_obj = importer.open(sample_path("figure4"))
    doc = model_obj.Document
    plan = planobject.make_processing_list(model_obj)

    with Ticks() as t:
        t0 = time.perf_counter()
        path = pathobject.make_tool_path(plan, scallop=0.01)
        took = time.perf_counter() - t0
    log(f"path (child process): {took:.2f} s, {path.Points} points; longest event-loop pause {t.gap:.3f} s; "
        f"progress reports {len(runner.last['progress'])}")
    with Ticks() as t:
        t0 = time.perf_counter()
        prog = programobject.make_program(path)
        took = time.perf_counter() - t0
    if prog is None:
        log("program failed:", messages.recorded[-1:])
        return
    stages = []
    for stage, done, total in runner.last["progress"]:
        if not stages or stages[-1][0] != stage:
            stages.append([stage, 0])
        stages[-1][1] += 1
    log(f"program (child process): {took:.2f} s, {prog.Blocks} blocks; longest event-loop pause {t.gap:.3f} s; "
        f"progress reports per stage {stages}")

    for what, obj, prop, value, after in (("path", path, "Scallop", 0.009, 2.0),
                                          ("program", prog, "SmoothingLength", 6.0, 20.0)):
        setattr(obj, prop, value)
        QtCore.QTimer.singleShot(int(after * 1000), lambda: runner.active.cancel() if runner.active else None)
        with Ticks() as t:
            t0 = time.perf_counter()
            doc.recompute()
            took = time.perf_counter() - t0
        log(f"{what} cancelled {after:g} s in: recompute returned after {took:.2f} s; cancel latency "
            f"{runner.last.get('cancel_latency', float('nan')):.3f} s; longest event-loop pause {t.gap:.3f} s; "
            f"state {obj.State}")

    runner.mode = "inline"
    doc.removeObject(prog.Name)                       # the path alone
    path.Scallop = 0.011
    with Ticks() as t:
        t0 = time.perf_counter()
        doc.recompute()
        took = time.perf_counter() - t0
    log(f"path in FreeCAD's own process (inline): {took:.2f} s; longest event-loop pause {t.gap:.3f} s")


try:
    main()
except Exception:
    traceback.print_exc(file=sys.__stdout__)
sys.__stdout__.flush()
os._exit(0)
