"""The program document object (``TsplcamProgram``): tool axes and G-code for a tool path.

Inputs are a linked TsplcamToolPath and the settings a CAM programmer picks when posting:
tool, orientation strategy, machine, controller dialect, holder clearance, smoothing
length and rotary weight. Its properties map one to one onto the options of
:class:`tsplcam.settings.JobSettings` (:meth:`TsplcamProgram.settings`); on recompute (only
when an input changed: orientation with collision checks takes seconds to a minute) it calls
the engine's one program builder, :func:`tsplcam.program.make_program`, which the command
line's ``path`` and ``job`` call too, so the program is byte for byte what they write.

The G-code (``ProgramFile``) and the oriented path (``AxesFile``, .npz) are kept inside
the .FCStd, so a reloaded document has both at once; ``export_program`` writes the G-code
where the user wants it. A path that would collide, or a pose outside the machine's
limits, is an error (named by point, patch and (u, v)), never a program.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile

import numpy as np

import FreeCAD

from ..errors import InputError
from ..orientation import ORIENTATIONS
from ..orientation.orient import ROTARY_WEIGHT
from ..program import make_program as build_program, program_file_name
from ..settings import PROGRAM_KEYS, JobSettings
from . import messages
from .modelobject import model_of
from .pathobject import _busy, is_path_object, load_npz, path_of, save_npz
from ..post.timing import hms
from .proxy import FeatureProxy, add_property, set_read_only
from .transaction import in_transaction

TITLE = "Program"
CONTROLLER = "machine's controller"
DEFAULTS = JobSettings()
DEFAULT_MACHINE = DEFAULTS.machine
# option of JobSettings -> the property that sets it, on the program or on its tool path
# (errors name the property)
PROPERTY_OF = {"tool": "Tool", "orientation": "Orientation", "machine": "Machine", "dialect": "Dialect",
               "holder_clearance": "HolderClearance", "smoothing_length": "SmoothingLength",
               "rotary_weight": "RotaryWeight", "stock": "Stock", "tool_radius": "ToolRadius",
               "scallop": "Scallop", "chord_tol": "ChordTolerance", "feed": "Feed"}


def tool_names() -> list[str]:
    """Shipped tools (``tsplcam/data/tools``), by name."""
    from ..orientation.tool import shipped_tools_dir
    return sorted(os.path.splitext(f)[0] for f in os.listdir(shipped_tools_dir()) if f.endswith(".json"))


def machine_names() -> list[str]:
    from ..post.machine import machine_files
    return sorted(machine_files())


def dialect_names() -> list[str]:
    from ..post.dialects import NAMES
    return [CONTROLLER] + list(NAMES)


def tool_for_radius(radius: float) -> str | None:
    """The first shipped tool whose ball has ``radius`` (mm), else None."""
    from ..orientation import load_tool
    for name in tool_names():
        if abs(load_tool(name).ball_radius - radius) < 1e-9:
            return name
    return None


def _enum(obj, name: str, values: list[str], default: str) -> None:
    current = getattr(obj, name)
    setattr(obj, name, values)
    setattr(obj, name, current if current in values else default)


class TsplcamProgram(FeatureProxy):
    """Tool axes (collision-checked) and the machine program of a tool path."""
    TYPE = "TsplcamProgram"
    VERSION = 1

    _result = None
    _axes_file = None

    @staticmethod
    def ensure_properties(obj) -> None:
        g = "Program"
        add_property(obj, "App::PropertyLink", "ToolPath", g, "The tool path this program runs")
        if add_property(obj, "App::PropertyEnumeration", "Tool", g,
                        "Cutter with shank and holder for the collision checks (tsplcam/data/tools; "
                        "its ball radius must equal the path's)"):
            obj.Tool = tool_names()
        add_property(obj, "App::PropertyFile", "ToolFile", g,
                     "A tool file of your own (.json or FreeCAD CAM .fctb); when set, used instead of Tool")
        if add_property(obj, "App::PropertyEnumeration", "Orientation", g,
                        "Tool axes: smooth (xu2013, collision-free), closest-z (shang2020), fixed +Z, "
                        "or the surface normal (no collision checks)"):
            obj.Orientation = list(ORIENTATIONS)
            obj.Orientation = DEFAULTS.orientation
        if add_property(obj, "App::PropertyEnumeration", "Machine", g,
                        "Five-axis machine: kinematics, limits, axis speeds (python3 -m tsplcam machines)"):
            obj.Machine = machine_names()
            if DEFAULT_MACHINE in machine_names():
                obj.Machine = DEFAULT_MACHINE
        if add_property(obj, "App::PropertyEnumeration", "Dialect", g,
                        "Controller syntax of the program (default: the machine's controller)"):
            obj.Dialect = dialect_names()
            obj.Dialect = CONTROLLER
        add_property(obj, "App::PropertyLink", "Stock", g,
                     "Stock, mold block or fixture (a Part or Mesh object) the tool must clear too; "
                     "empty: the model alone (the keycap_mold sample brings its block)")
        add_property(obj, "App::PropertyLength", "HolderClearance", g,
                     "Distance kept between shank/holder and the part (the flutes only must not touch)",
                     DEFAULTS.holder_clearance)
        add_property(obj, "App::PropertyLength", "SmoothingLength", g,
                     "Smooth: a needed tilt is spread over about this length of path on each side",
                     DEFAULTS.smoothing_length)
        add_property(obj, "App::PropertyFloat", "RotaryWeight", g,
                     "Smooth: how much the rotary (C) axis motion counts, in the machine's time units "
                     "(default 2; 0: not at all, the tool-axis direction instead)", ROTARY_WEIGHT)
        add_property(obj, "App::PropertyFileIncluded", "ProgramFile", g,
                     "The posted program, kept inside the document", hidden=True)
        add_property(obj, "App::PropertyString", "ProgramName", g,
                     "File name for the program: the model's name and the controller's extension",
                     read_only=True)
        add_property(obj, "App::PropertyFileIncluded", "AxesFile", g,
                     "The path with its tool axes (numpy .npz), kept inside the document", hidden=True)
        add_property(obj, "App::PropertyString", "InputsKey", g,
                     "What the stored program was computed from", hidden=True)
        r = "Result"
        add_property(obj, "App::PropertyInteger", "Blocks", r, "Motion blocks of the program", read_only=True)
        add_property(obj, "App::PropertyString", "MachiningTime", r,
                     "Estimated machining time (h:mm:ss) from the machine's axis speeds", read_only=True)
        # a float: PropertyAngle stops at 360 degrees
        add_property(obj, "App::PropertyFloat", "RotaryTravel", r,
                     "Travel of both rotary axes (degrees)", read_only=True)
        add_property(obj, "App::PropertyAngle", "LargestAxisStep", r,
                     "Largest change of the tool axis between two path points", read_only=True)
        add_property(obj, "App::PropertyInteger", "Collisions", r,
                     "Collisions found when the result was checked again (always 0, or no program)",
                     read_only=True)
        add_property(obj, "App::PropertyLength", "SmallestClearance", r,
                     "Smallest distance between shank/holder and the part", read_only=True)

    def onDocumentRestored(self, obj):
        self.ensure_properties(obj)
        # shipped tools and machines may have changed since the file was saved
        _enum(obj, "Tool", tool_names(), obj.Tool)
        _enum(obj, "Machine", machine_names(), obj.Machine)

    # -- inputs -----------------------------------------------------------------------------------
    def settings(self, obj) -> JobSettings:
        """The job settings of this program: its own properties, and the ball radius, scallop,
        chord tolerance and feed of its tool path (the linked Stock object goes to the builder
        as triangles, not as a file). Checked; errors name the property."""
        tp = obj.ToolPath
        model = tp.ProcessingList.Model if tp is not None and tp.ProcessingList is not None else None
        return settings_of(obj, tp, model)

    def inputs_key(self, obj) -> str:
        h = hashlib.sha1()
        h.update(obj.ToolPath.InputsKey.encode())
        h.update(json.dumps(self.settings(obj).to_dict(PROGRAM_KEYS), sort_keys=True).encode())
        if obj.Stock is not None:
            V, T = triangles_of(obj.Stock)
            h.update(V.tobytes())
            h.update(T.tobytes())
        for f in (obj.ToolFile, _machine_file(obj.Machine)):
            if f and os.path.isfile(f):
                with open(f, "rb") as fh:
                    h.update(fh.read())
        return h.hexdigest()

    def _check_inputs(self, obj):
        tp_obj = obj.ToolPath
        if tp_obj is None or not is_path_object(tp_obj):
            raise InputError("the program needs a tool path", item=obj.Label)
        model_obj = tp_obj.ProcessingList.Model
        return tp_obj, model_obj

    # -- computing ---------------------------------------------------------------------------------
    def compute(self, obj):
        tp_obj, model_obj = self._check_inputs(obj)
        stock = triangles_of(obj.Stock) if obj.Stock is not None else None
        with progress_bar(f"tsplcam: tool axes of {obj.Label}") as progress:
            return compute_program(path_of(tp_obj), model_of(model_obj), self.settings(obj),
                                   stock=stock, progress=progress)

    def execute(self, obj):
        self._check_inputs(obj)
        key = self.inputs_key(obj)
        stored = all(f and os.path.isfile(f) for f in (obj.ProgramFile, obj.AxesFile))
        if key != obj.InputsKey or not stored:
            result = self.compute(obj)
            self.store(obj, result, key)
            self.update_info(obj, result)

    def store(self, obj, result, key: str) -> None:
        oriented, posted, _ = result
        tmp = tempfile.mkdtemp(prefix="tsplcam-program-")
        try:
            # FreeCAD keeps the first name a PropertyFileIncluded was given: a fixed one here,
            # the real one in ProgramName
            prog = os.path.join(tmp, "program.nc")
            posted.write(prog)
            axes = os.path.join(tmp, "axes.npz")
            save_npz(oriented, axes)
            obj.ProgramFile = prog                  # FreeCAD copies both into the document
            obj.AxesFile = axes
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        obj.InputsKey = key
        set_read_only(obj, "ProgramName", program_file_name(_source_file(obj), posted.dialect))
        self._result, self._axes_file = oriented, obj.AxesFile

    def oriented_path(self, obj):
        """The ToolPath with its tool axes, read from the document's copy once."""
        if self._result is None or self._axes_file != obj.AxesFile:
            if not obj.AxesFile or not os.path.isfile(obj.AxesFile):
                raise InputError("the program has not been computed yet (recompute)", item=obj.Label)
            self._result, self._axes_file = load_npz(obj.AxesFile), obj.AxesFile
        return self._result

    @staticmethod
    def update_info(obj, result) -> None:
        oriented, posted, metrics = result
        set_read_only(obj, "Blocks", len(posted.motion))
        set_read_only(obj, "MachiningTime", hms(posted.time.total_s))
        info = posted.solution.info
        travel = float(info["tilt_travel_deg"] + info["rotary_travel_deg"])
        steps = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", oriented.axis[1:], oriented.axis[:-1]),
                                             -1.0, 1.0))) if len(oriented) > 1 else np.zeros(1)
        set_read_only(obj, "RotaryTravel", round(travel, 6))
        if abs(obj.LargestAxisStep.Value - float(steps.max())) > 1e-9:
            obj.LargestAxisStep = float(steps.max())
        set_read_only(obj, "Collisions", int(metrics.collisions) if metrics is not None else 0)
        clearance = float(metrics.min_clearance) if metrics is not None else 0.0
        if np.isfinite(clearance) and abs(obj.SmallestClearance.Value - clearance) > 1e-9:
            obj.SmallestClearance = clearance


def _machine_file(name: str) -> str | None:
    from ..post.machine import machine_files
    return machine_files().get(name)


def _source_file(obj) -> str:
    tp = obj.ToolPath
    model = tp.ProcessingList.Model if tp is not None else None
    return model.SourceFile if model is not None and model.SourceFile else "program"


def settings_of(program_obj, path_obj, model_obj, **changes) -> JobSettings:
    """JobSettings from a program object's properties (or, with ``program_obj`` None, from
    the defaults), the tool path object's ball radius, scallop, chord tolerance and feed,
    and ``changes`` (option names); checked, errors naming the property."""
    s = {}
    if program_obj is not None:
        p = program_obj
        s = dict(tool=p.ToolFile or p.Tool or None, orientation=p.Orientation, machine=p.Machine,
                 dialect=None if p.Dialect == CONTROLLER else p.Dialect,
                 holder_clearance=float(p.HolderClearance.Value), smoothing_length=float(p.SmoothingLength.Value),
                 rotary_weight=float(p.RotaryWeight))
    if path_obj is not None:
        s.update(tool_radius=float(path_obj.ToolRadius.Value), scallop=float(path_obj.Scallop.Value),
                 chord_tol=float(path_obj.ChordTolerance.Value), feed=float(path_obj.Feed.getValueAs("mm/min")))
    if model_obj is not None and model_obj.SourceFile:
        s["model"] = model_obj.SourceFile
    s.update(changes)
    try:
        settings = JobSettings(**s)
    except TypeError as exc:            # an option JobSettings does not have
        raise InputError(str(exc)) from None
    return settings.check(lambda name: PROPERTY_OF.get(name, name))


def triangles_of(obj, tolerance: float = 0.01):
    """Triangles (vertices (n,3), triangles (m,3)) of a Mesh object exactly, or of a Part
    shape tessellated within ``tolerance`` mm, with its placement."""
    mesh = getattr(obj, "Mesh", None)
    if mesh is not None and hasattr(mesh, "Topology"):
        pts, tris = mesh.Topology
    else:
        shape = getattr(obj, "Shape", None)
        if shape is None or shape.isNull() or not shape.Faces:
            raise InputError("the stock must be a Part or Mesh object with faces", item=obj.Label)
        pts, tris = shape.tessellate(tolerance)
    V = np.array([[p.x, p.y, p.z] for p in pts], float).reshape(-1, 3)
    T = np.array(tris, int).reshape(-1, 3)
    if len(T) == 0:
        raise InputError("the stock has no triangles", item=obj.Label)
    return V, T


def compute_program(toolpath, model, settings: JobSettings, stock=None, progress=None):
    """(oriented ToolPath, PostResult, orientation metrics or None) from the engine's program
    builder; ``stock`` (V, T) triangles of the linked Stock object, else the sample's mold
    block where the model is the keycap_mold sample; ``progress(done, total)`` follows the
    collision checks. Raises InputError, CollisionError or KinematicsError naming the place."""
    staged = None if progress is None else (lambda stage, done, total: progress(done, total)
                                            if stage == "tool axes" else None)
    program = build_program(toolpath, model, settings, stock=stock, progress=staged)
    return program.path, program.posted, program.metrics


@contextlib.contextmanager
def progress_bar(text: str, steps: int = 100):
    """FreeCAD's progress bar (GUI only; headless None) as a ``progress(done, total)``
    callback, stopped however the work ends."""
    if not FreeCAD.GuiUp:
        yield None
        return
    bar = FreeCAD.Base.ProgressIndicator()
    bar.start(text, steps)
    shown = [0]

    def report(done: int, total: int) -> None:
        target = min(steps, int(steps * done / max(total, 1)))
        while shown[0] < target:
            bar.next()
            shown[0] += 1
    try:
        yield report
    finally:
        bar.stop()


def is_program_object(obj) -> bool:
    return getattr(getattr(obj, "Proxy", None), "Type", None) == TsplcamProgram.TYPE


def program_text(obj) -> str:
    if not obj.ProgramFile or not os.path.isfile(obj.ProgramFile):
        raise InputError("the program has not been computed yet (recompute)", item=obj.Label)
    with open(obj.ProgramFile, encoding="ascii") as f:
        return f.read()


def export_program(obj, path: str) -> str:
    """Write the program's G-code to ``path`` (bytes as posted); returns ``path``."""
    from ..outfile import write_text
    write_text(path, program_text(obj), encoding="ascii", what="program")
    return path


def make_program(path_obj, **settings):
    """A TsplcamProgram for the tool path ``path_obj``: oriented and posted first (seconds to a
    minute), added only on success; None after reporting why not (a collision or a pose
    outside the machine's limits, named by point, patch and (u, v)). ``settings``: tool,
    orientation, machine, dialect, holder_clearance, smoothing_length, rotary_weight (options
    of JobSettings, defaults from it), and stock (a document object)."""
    doc = path_obj.Document
    radius = float(path_obj.ToolRadius.Value)
    stock_obj = settings.pop("stock", None)
    busy = _busy()
    try:
        settings.setdefault("tool", tool_for_radius(radius))
        settings.setdefault("rotary_weight", ROTARY_WEIGHT)      # what the property shows
        if settings["tool"] is None and settings.get("orientation", DEFAULTS.orientation) != "normal":
            raise InputError(f"no shipped tool has a ball of radius {radius:g} mm: add a tool file "
                             "(tsplcam/orientation/TOOLS.md) or post with orientation 'normal'",
                             item=path_obj.Label)
        model_obj = path_obj.ProcessingList.Model
        s = settings_of(None, path_obj, model_obj, **settings)
        stock = triangles_of(stock_obj) if stock_obj is not None else None
        with progress_bar(f"tsplcam: tool axes of {path_obj.Label}") as progress:
            result = compute_program(path_of(path_obj), model_of(model_obj), s, stock=stock, progress=progress)
    except Exception as exc:
        messages.exception(TITLE, exc, f"posting {path_obj.Label}")
        return None
    finally:
        busy()

    def work():
        obj = doc.addObject("App::FeaturePython", "Program")
        TsplcamProgram(obj)
        obj.Label = f"{path_obj.Label} program"
        obj.ToolPath = path_obj
        obj.Stock = stock_obj
        if s.tool in tool_names():
            obj.Tool = s.tool
        elif s.tool:
            obj.ToolFile = s.tool
        obj.Orientation = s.orientation
        obj.Machine = s.machine
        obj.Dialect = s.dialect or CONTROLLER
        obj.HolderClearance = s.holder_clearance
        obj.SmoothingLength = s.smoothing_length
        obj.RotaryWeight = s.rotary_weight
        obj.Proxy.store(obj, result, obj.Proxy.inputs_key(obj))
        TsplcamProgram.update_info(obj, result)
        if FreeCAD.GuiUp:
            from .viewprogram import ViewProviderProgram
            ViewProviderProgram(obj.ViewObject)
        return obj
    obj = in_transaction(doc, TITLE, f"adding the program of {path_obj.Label}", work)
    if obj is None:
        return None
    messages.info(f"{obj.Label}: {obj.Blocks} blocks for {obj.Machine}, machining time {obj.MachiningTime}, "
                  f"rotary travel {obj.RotaryTravel:.0f} deg, largest axis step "
                  f"{obj.LargestAxisStep.Value:.2f} deg, {obj.Collisions} collisions")
    return obj
