"""The program document object (``TsplcamProgram``): tool axes and G-code for a tool path.

Inputs are a linked TsplcamToolPath and the options a CAM programmer picks when posting,
one property per option of :class:`tsplcam.settings.JobSettings` (``fields.PROGRAM_FIELDS``:
tool, orientation and the tool-axis controls (target, lead, side tilt, point, direction,
largest tilt and its axis, tilt range, pole tilt, the lead/side-tilt limits from the normal,
the largest axis step), holder clearance, smoothing length, rotary weight, machine,
controller, axes form, spindle speed) and a Stock object. A document saved before a property
existed gets it at its default on reload; the program's inputs key then changes, so its stored
program counts as older than its inputs until recomputed (the safe side).
:meth:`TsplcamProgram.settings` reads them back as JobSettings; on recompute (only when an
input changed: orientation with collision checks takes seconds to minutes) the object calls
the engine's one program builder, :func:`tsplcam.program.make_program`, which the command
line's ``path`` and ``job`` call too, so the program is byte for byte what they write. In the
GUI that runs in a child process with progress and cancel (``runner``).

The G-code (``ProgramFile``) and the oriented path (``AxesFile``, .npz) are kept inside
the .FCStd, so a reloaded document has both at once; ``export_program`` writes the G-code
where the user wants it, and refuses while the program is not valid: when it or any input
failed to recompute, was changed and not recomputed, or is older than its inputs
(``validity.problem``). A path that would collide, or a pose outside the machine's limits, or
a feed or spindle speed beyond them, is an error (named by point, patch and (u, v), or by
the property), never a program.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile

import numpy as np

import FreeCAD

from ..errors import InputError
from ..post.timing import hms
from ..program import program_file_name
from ..settings import PROGRAM_KEYS
from . import messages, validity
from .fields import PATH_FIELDS, PROGRAM_FIELDS, add_properties, checked, set_values, values_of
from .modelobject import model_of
from .pathobject import is_path_object, load_npz, path_of, save_npz
from .proxy import FeatureProxy, add_property, set_read_only
from .transaction import in_transaction

TITLE = "Program"
# results of the post kept for the CAM tool controller (the machine file's post section, or
# the program's options)
POST_RESULTS = {"tool": "ToolNumber", "coolant": "Coolant", "work_offset": "WorkOffset", "spindle": "SpindleUsed"}


def tool_names() -> list[str]:
    """Shipped tools (``tsplcam/data/tools``), by name."""
    from ..orientation.tool import shipped_tools_dir
    return sorted(os.path.splitext(f)[0] for f in os.listdir(shipped_tools_dir()) if f.endswith(".json"))


def machine_names() -> list[str]:
    from ..post.machine import machine_files
    return sorted(machine_files())


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
    VERSION = 2
    TITLE = TITLE

    _result = None
    _axes_file = None
    _posted = None            # the latest PostResult computed in this session (never saved)

    @staticmethod
    def ensure_properties(obj, values: dict | None = None) -> None:
        g = "Program"
        add_property(obj, "App::PropertyLink", "ToolPath", g, "The tool path this program runs")
        add_properties(obj, PROGRAM_FIELDS, g, values)
        add_property(obj, "App::PropertyFile", "ToolFile", g,
                     "A tool file of your own (.json or FreeCAD CAM .fctb); when set, used instead of Tool")
        add_property(obj, "App::PropertyLink", "Stock", g,
                     "Stock, mold block or fixture (a Part or Mesh object) the tool must clear too; "
                     "empty: the model alone (the keycap_mold sample brings its block)")
        add_property(obj, "App::PropertyFileIncluded", "ProgramFile", g,
                     "The posted program, kept inside the document", hidden=True)
        add_property(obj, "App::PropertyString", "ProgramName", g,
                     "File name for the program: the model's name and the controller's extension",
                     read_only=True)
        add_property(obj, "App::PropertyFileIncluded", "AxesFile", g,
                     "The path with its tool axes (numpy .npz), kept inside the document", hidden=True)
        add_property(obj, "App::PropertyFileIncluded", "MotionFile", g,
                     "The program's motion blocks (numpy .npz: tip, joints, feed mm/min, rapid), kept "
                     "inside the document for the CAM operation and the preview", hidden=True)
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
                     "Path points where shank or holder touch the part or stock: always 0 for checked "
                     "tool axes (a collision is an error there); counted, and drawn red, for surface-"
                     "normal axes, which are not checked while oriented", read_only=True)
        add_property(obj, "App::PropertyLength", "SmallestClearance", r,
                     "Smallest distance between shank/holder and the part", read_only=True)
        add_property(obj, "App::PropertyInteger", "ToolNumber", r, "Tool number the program calls",
                     read_only=True)
        add_property(obj, "App::PropertyFloat", "SpindleUsed", r, "Spindle speed the program runs (rpm)",
                     read_only=True)
        add_property(obj, "App::PropertyString", "Coolant", r, "Coolant the program switches on",
                     read_only=True)
        add_property(obj, "App::PropertyString", "WorkOffset", r, "Work offset (program zero) the program uses",
                     read_only=True)

    def onDocumentRestored(self, obj):
        self.ensure_properties(obj)
        # shipped tools and machines may have changed since the file was saved
        _enum(obj, "Tool", tool_names(), obj.Tool)
        _enum(obj, "Machine", machine_names(), obj.Machine)

    # -- inputs -----------------------------------------------------------------------------------
    def settings(self, obj):
        """The job settings of this program: its own properties, and the path options of its
        tool path (the linked Stock object goes to the builder as triangles, not as a file).
        Checked; errors name the property."""
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

    def stale(self, obj) -> str | None:
        if not all(f and os.path.isfile(f) for f in (obj.ProgramFile, obj.AxesFile)):
            return "the program has not been computed (recompute)"
        try:
            if self.inputs_key(obj) != obj.InputsKey:
                return "the stored program is older than its inputs (recompute)"
        except Exception as exc:
            return str(exc)
        return None

    def _check_inputs(self, obj):
        tp_obj = obj.ToolPath
        if tp_obj is None or not is_path_object(tp_obj):
            raise InputError("the program needs a tool path", item=obj.Label)
        stale = tp_obj.Proxy.stale(tp_obj)
        if stale:
            raise validity.StaleInput(f"input {tp_obj.Label}: {stale}", item=obj.Label)
        return tp_obj, tp_obj.ProcessingList.Model

    # -- computing ---------------------------------------------------------------------------------
    def compute(self, obj):
        tp_obj, model_obj = self._check_inputs(obj)
        stock = triangles_of(obj.Stock) if obj.Stock is not None else None
        return compute_program(path_of(tp_obj), model_of(model_obj), self.settings(obj), stock=stock,
                               plist=_plist_of(tp_obj), label=obj.Label)

    def recompute(self, obj):
        self._check_inputs(obj)
        key = self.inputs_key(obj)
        stored = all(f and os.path.isfile(f) for f in (obj.ProgramFile, obj.AxesFile))
        if key != obj.InputsKey or not stored:
            program = self.compute(obj)
            self.store(obj, program, key)
            self.update_info(obj, program)

    def store(self, obj, program, key: str) -> None:
        """Keep the program text, the oriented path and the motion blocks in the document."""
        posted = program.posted
        tmp = tempfile.mkdtemp(prefix="tsplcam-program-")
        try:
            # FreeCAD keeps the first name a PropertyFileIncluded was given: a fixed one here,
            # the real one in ProgramName
            prog = os.path.join(tmp, "program.nc")
            posted.write(prog)
            axes = os.path.join(tmp, "axes.npz")
            save_npz(program.path, axes)
            motion = os.path.join(tmp, "motion.npz")
            save_motion(posted, motion, getattr(program, "collides", None), len(program.path))
            obj.ProgramFile = prog                  # FreeCAD copies them into the document
            obj.AxesFile = axes
            obj.MotionFile = motion
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        obj.InputsKey = key
        set_read_only(obj, "ProgramName", program_file_name(_source_file(obj), posted.dialect))
        self._result, self._axes_file = program.path, obj.AxesFile
        self._posted = posted

    def oriented_path(self, obj):
        """The ToolPath with its tool axes, read from the document's copy once."""
        if self._result is None or self._axes_file != obj.AxesFile:
            if not obj.AxesFile or not os.path.isfile(obj.AxesFile):
                raise InputError("the program has not been computed yet (recompute)", item=obj.Label)
            self._result, self._axes_file = load_npz(obj.AxesFile), obj.AxesFile
        return self._result

    @staticmethod
    def update_info(obj, program) -> None:
        oriented, posted, metrics = program.path, program.posted, program.metrics
        set_read_only(obj, "Blocks", len(posted.motion))
        set_read_only(obj, "MachiningTime", hms(posted.time.total_s))
        info = posted.solution.info
        travel = float(info["tilt_travel_deg"] + info["rotary_travel_deg"])
        steps = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", oriented.axis[1:], oriented.axis[:-1]),
                                             -1.0, 1.0))) if len(oriented) > 1 else np.zeros(1)
        set_read_only(obj, "RotaryTravel", round(travel, 6))
        if abs(obj.LargestAxisStep.Value - float(steps.max())) > 1e-9:
            obj.LargestAxisStep = float(steps.max())
        collides = getattr(program, "collides", None)
        set_read_only(obj, "Collisions", int(metrics.collisions) if metrics is not None
                      else int(np.count_nonzero(collides)) if collides is not None else 0)
        clearance = float(metrics.min_clearance) if metrics is not None else 0.0
        if np.isfinite(clearance) and abs(obj.SmallestClearance.Value - clearance) > 1e-9:
            obj.SmallestClearance = clearance
        s = posted.settings
        set_read_only(obj, "ToolNumber", int(s.get("tool") or 0))
        set_read_only(obj, "SpindleUsed", float(s.get("spindle") or 0.0))
        set_read_only(obj, "Coolant", str(s.get("coolant") or "off"))
        set_read_only(obj, "WorkOffset", str(s.get("work_offset") or "G54"))


def _plist_of(tp_obj):
    from .planobject import plan_of
    return plan_of(tp_obj.ProcessingList)


def _machine_file(name: str) -> str | None:
    from ..post.machine import machine_files
    return machine_files().get(name)


def _source_file(obj) -> str:
    tp = obj.ToolPath
    model = tp.ProcessingList.Model if tp is not None else None
    return model.SourceFile if model is not None and model.SourceFile else "program"


def settings_of(program_obj, path_obj, model_obj, **changes):
    """JobSettings from a program object's properties (or, with ``program_obj`` None, from
    the preferences' defaults), the tool path object's path options, and ``changes`` (option
    names); checked, errors naming the property."""
    from .prefs import defaults
    s = {}
    if program_obj is not None:
        s = values_of(program_obj, PROGRAM_FIELDS)
        s["tool"] = program_obj.ToolFile or program_obj.Tool or None
    else:
        s = defaults(PROGRAM_FIELDS)
    if path_obj is not None:
        s.update(values_of(path_obj, PATH_FIELDS))
    if model_obj is not None and model_obj.SourceFile:
        s["model"] = model_obj.SourceFile
    s.update(changes)
    return checked(s)


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


def compute_program(toolpath, model, settings, stock=None, plist=None, label: str = "program"):
    """The tsplcam.program.Program (oriented path, posted program, metrics) from the engine's
    program builder, through the runner (GUI: child process with progress and cancel);
    ``stock`` (V, T) triangles of the linked Stock object, else the sample's mold block where
    the model is the keycap_mold sample. Raises InputError, CollisionError or KinematicsError
    naming the place, Cancelled on request."""
    from . import runner
    from .fields import named_properties
    with named_properties():
        return runner.run(f"Program of {label}", "program_task", toolpath, model, settings.to_dict(),
                          stock=stock, plist=plist)


# -- motion blocks (for the CAM operation and the preview) ------------------------------------------
MOTION_ARRAYS = ("tip", "axis", "joints", "rapid", "feed", "move", "source")


def save_motion(posted, path: str, collides=None, points: int = 0) -> None:
    """The motion blocks, and per path point whether the tool collides there (only known for
    programs made without collision checks: surface-normal axes)."""
    m = posted.motion
    mask = np.zeros(points, bool) if collides is None else np.asarray(collides, bool)
    np.savez(path, **{k: np.asarray(getattr(m, k)) for k in MOTION_ARRAYS},
             axis_names=np.array(posted.machine.axis_names), machine=np.array(posted.machine.name),
             collides=mask)


def motion_of(obj) -> dict:
    """The program's motion blocks: tip (n,3) in part coordinates, axis (n,3), joints (n,5)
    (X Y Z and the two rotary axes in machine values), rapid (n,), feed (n,) mm/min (NaN on
    rapids), move (n,), source (n,) path point or -1/-2 for approach/retract, axis_names."""
    if not obj.MotionFile or not os.path.isfile(obj.MotionFile):
        raise InputError("the program has no stored motion (recompute)", item=obj.Label)
    with np.load(obj.MotionFile, allow_pickle=False) as z:
        out = {k: z[k] for k in MOTION_ARRAYS}
        out["axis_names"] = [str(x) for x in z["axis_names"]]
        out["machine"] = str(z["machine"])
        out["collides"] = z["collides"] if "collides" in z.files else np.zeros(0, bool)
    return out


def is_program_object(obj) -> bool:
    return getattr(getattr(obj, "Proxy", None), "Type", None) == TsplcamProgram.TYPE


def program_text(obj) -> str:
    if not obj.ProgramFile or not os.path.isfile(obj.ProgramFile):
        raise InputError("the program has not been computed yet (recompute)", item=obj.Label)
    with open(obj.ProgramFile, encoding="ascii") as f:
        return f.read()


def export_program(obj, path: str) -> str:
    """Write the program's G-code to ``path`` (bytes as posted); returns ``path``. Refused,
    naming the reason, while the program is not valid (``validity.problem``): nothing stale
    is ever written."""
    from ..outfile import write_text
    why = validity.problem(obj)
    if why is not None:
        raise InputError(f"not exported: {why}", item=obj.Label)
    write_text(path, program_text(obj), encoding="ascii", what="program")
    return path


def program_defaults(path_obj, **settings) -> dict:
    """Program options for a new program of ``path_obj``: the preferences page's defaults, a
    shipped tool of the path's ball radius, then ``settings``."""
    from .prefs import defaults
    radius = float(path_obj.ToolRadius.Value)
    values = defaults(PROGRAM_FIELDS)
    tool = values.get("tool")
    if tool in tool_names():
        from ..orientation import load_tool
        if abs(load_tool(tool).ball_radius - radius) > 1e-9:
            tool = None
    values["tool"] = tool or tool_for_radius(radius)
    values.update(settings)
    if values["tool"] is None and values.get("orientation", "smooth") != "normal":
        raise InputError(f"no shipped tool has a ball of radius {radius:g} mm: add a tool file "
                         "(tsplcam/orientation/TOOLS.md) or post with orientation 'normal'",
                         item=path_obj.Label)
    return values


def make_program(path_obj, computed=None, **settings):
    """A TsplcamProgram for the tool path ``path_obj``: oriented and posted first (seconds to
    minutes; in the GUI with progress and cancel), added only on success; None after
    reporting why not (a collision or a pose outside the machine's limits, named by point,
    patch and (u, v); a feed or spindle speed beyond them). ``settings``: program options
    (JobSettings names: tool, orientation, target, lead, side_tilt, ..., machine, dialect,
    axes_form, spindle; defaults from the preferences), and stock (a document object);
    ``computed``: the tsplcam.program.Program the engine already made with them (headless
    documents)."""
    doc = path_obj.Document
    stock_obj = settings.pop("stock", None)
    try:
        values = program_defaults(path_obj, **settings)
        model_obj = path_obj.ProcessingList.Model
        s = settings_of(None, path_obj, model_obj, **values)
        stock = triangles_of(stock_obj) if stock_obj is not None else None
        program = computed if computed is not None else compute_program(
            path_of(path_obj), model_of(model_obj), s, stock=stock, plist=_plist_of(path_obj), label=path_obj.Label)
    except Exception as exc:
        messages.exception(TITLE, exc, f"posting {path_obj.Label}")
        return None

    def work():
        obj = doc.addObject("App::FeaturePython", "Program")
        TsplcamProgram(obj)
        obj.Label = f"{path_obj.Label} program"
        obj.ToolPath = path_obj
        obj.Stock = stock_obj
        program_values = {k: v for k, v in s.to_dict().items() if k != "tool"}
        set_values(obj, PROGRAM_FIELDS, program_values)
        if s.tool in tool_names():
            obj.Tool = s.tool
        elif s.tool:
            obj.ToolFile = s.tool
        obj.Proxy.store(obj, program, obj.Proxy.inputs_key(obj))
        TsplcamProgram.update_info(obj, program)
        if FreeCAD.GuiUp:
            from .viewprogram import ViewProviderProgram
            ViewProviderProgram(obj.ViewObject)
        return obj
    obj = in_transaction(doc, TITLE, f"adding the program of {path_obj.Label}", work)
    if obj is None:
        return None
    from .modelobject import plural
    messages.info(f"{obj.Label}: {obj.Blocks} blocks for {obj.Machine}, machining time {obj.MachiningTime}, "
                  f"rotary travel {obj.RotaryTravel:.0f} deg, largest axis step "
                  f"{obj.LargestAxisStep.Value:.2f} deg, {plural(obj.Collisions, 'collision')}")
    return obj
