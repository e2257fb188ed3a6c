"""The workbench's long work (tool path, tool axes, program) as engine calls that run either
here or in a child process, never importing FreeCAD.

The tasks (:func:`path_task`, :func:`program_task`) call the engine's one program builder
(:mod:`tsplcam.program`), exactly as the command line does. The GUI runs them in a child
process (``python3 -m tsplcam.workbench.worker``, see :mod:`tsplcam.workbench.runner`): the
child has its own interpreter (FreeCAD's event loop never waits on it, and it may use both
cores), its progress calls come back over its stdout, and a cancel ends it at once, whatever
the stage is doing. Headless (freecadcmd, tests, ``job --fcstd``) the same functions run in
this process.

Protocol of the child: it reads one pickled request ``(function name, args, kwargs,
result file)`` from stdin, writes ``P<TAB>stage<TAB>done<TAB>total`` lines while it works
(at most ten a second, and every stage's last call), and at the end pickles
``("ok", result)`` or ``("error", exception, traceback text, attributes)`` (an
InputError's message, path, line and item, which pickling alone would fold into its text)
into the result file and writes ``D``.
"""
from __future__ import annotations

import pickle
import sys
import time
import traceback

TASKS = ("path_task", "program_task")


def path_task(model, plist, settings: dict, progress=None):
    """The finishing path (ToolPath) of ``model`` in the order of ``plist`` by the options of
    ``settings`` (a dict of JobSettings fields: tool_radius, scallop, chord_tol, max_step,
    feed, clearance, clearance_mode, balance)."""
    from ..program import make_path
    from ..settings import JobSettings
    s = JobSettings(**settings)
    return make_path(model, plist, s, s.tool_radius, progress=progress)


def program_task(path, model, settings: dict, stock=None, plist=None, progress=None):
    """Tool axes and machine program of ``path`` (a tsplcam.program.Program), by the
    options of ``settings`` (a dict of JobSettings fields). With surface-normal axes (no
    collision checks while orienting) and a tool, the poses are checked afterwards and the
    program's ``collides`` marks the path points where shank or holder touch, for the view."""
    from ..program import load_stock, load_tool, make_program
    from ..settings import JobSettings
    s = JobSettings(**settings)
    program = make_program(path, model, s, stock=stock, progress=progress, plist=plist)
    program.checker = None                   # fcl objects do not cross processes; nothing here needs it
    program.collides = None
    if s.orientation == "normal" and s.tool:
        import numpy as np
        from ..orientation import CollisionChecker
        stock = load_stock(s) if stock is None else stock
        meshes = [] if stock is None else [("stock", stock[0], stock[1])]
        checker = CollisionChecker(model, load_tool(s), meshes=meshes, clearance=s.holder_clearance)
        tp = program.path
        mask = np.zeros(len(tp), bool)
        step = 2000
        for a in range(0, len(tp), step):
            mask[a:a + step] = checker.collides(tp.center[a:a + step], tp.axis[a:a + step])
            if progress is not None:
                progress("collisions", min(a + step, len(tp)), len(tp))
        program.collides = mask
    return program


class PipeProgress:
    """A progress callback writing ``P`` lines to ``stream``, at most every ``interval``
    seconds per stage, the last call of a stage always."""

    def __init__(self, stream, interval: float = 0.1):
        self.stream = stream
        self.interval = interval
        self._last = {}

    def __call__(self, stage: str, done: int, total: int) -> None:
        now = time.monotonic()
        final = total > 0 and done >= total
        if not final and now - self._last.get(stage, -1.0) < self.interval:
            return
        self._last[stage] = now
        self.stream.write(f"P\t{stage}\t{int(done)}\t{int(total)}\n")
        self.stream.flush()


def _child() -> int:
    name, args, kwargs, result_file = pickle.load(sys.stdin.buffer)
    if name not in TASKS:
        raise SystemExit(f"unknown task {name!r}")
    out = sys.stdout
    try:
        result = ("ok", globals()[name](*args, progress=PipeProgress(out), **kwargs))
    except Exception as exc:                    # handed to the parent, which raises it again
        text = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
        attrs = {k: getattr(exc, k) for k in ("message", "path", "line", "item") if hasattr(exc, k)}
        try:
            pickle.loads(pickle.dumps(exc))
        except Exception:
            exc = RuntimeError(f"{type(exc).__name__}: {exc}")
        result = ("error", exc, text, attrs)
    with open(result_file, "wb") as f:
        pickle.dump(result, f, protocol=pickle.HIGHEST_PROTOCOL)
    out.write("D\n")
    out.flush()
    return 0


if __name__ == "__main__":
    from ..allocator import keep_freed_memory
    keep_freed_memory()
    sys.exit(_child())
