"""FreeCAD CAM interop: a CAM Job holding the program's moves, so the CAM workbench lists it
and its post processors read it.

:func:`make_cam_job` adds, for a TsplcamProgram, a CAM Job (FreeCAD's own, ``Job.Create``)
with the model's surface as its base model, the program's stock as its stock where it has
one, the program's work offset as its fixture, a tool controller (a ball-end tool bit of the
program's ball radius and shank, the program's tool number, spindle speed, clockwise spindle
as the posts write M3) and one operation, a ``TsplcamCamOperation`` (Path::FeaturePython):
its Path holds every motion block of the program as G0/G1 with X Y Z (the tool tip in the
program's coordinates, as with tool centre point control) and the machine's two rotary axes
(A or B, and C, machine values), feeds on the feed blocks, and its CoolantMode the program's
coolant. The operation links the program: it is recomputed with it and fails with it.

Units: FreeCAD keeps feeds in Path commands in mm/s, as its own operations do, and its
posts write them in mm/min again; the program's feeds (mm/min) are divided by 60 here, at
this boundary only.

FreeCAD 0.20 names the modules ``PathScripts.PathJob`` etc., FreeCAD 1.x ``Path.Main.Job``,
``Path.Tool.Controller`` and ``Path.Tool.Bit``; the Path module itself may be called ``CAM``.
"""
from __future__ import annotations

import numpy as np

import FreeCAD

from ..errors import InputError
from . import messages, validity
from .proxy import FeatureProxy, Stateless, add_property, set_read_only

TITLE = "CAM job"
COOLANT = {"flood": "Flood", "mist": "Mist"}


def path_module():
    """FreeCAD's Path module (``CAM`` where it carries that name)."""
    try:
        import Path
    except ImportError:
        import CAM as Path
    return Path


def cam_api():
    """(Job, ToolController, ToolBit factory, Stock) modules of this FreeCAD."""
    try:
        from Path.Main import Job, Stock
        from Path.Tool import Controller
        from Path.Tool import Bit
        return Job, Controller, Bit.Factory, Stock
    except ImportError:
        from PathScripts import PathJob, PathStock, PathToolBit, PathToolController
        return PathJob, PathToolController, PathToolBit.Factory, PathStock


def cam_available() -> bool:
    try:
        path_module()
        cam_api()
    except Exception:
        return False
    return True


def feed_mm_per_s(feed_mm_per_min: float) -> float:
    """FreeCAD Path commands keep feeds in mm/s."""
    return float(feed_mm_per_min) / 60.0


def motion_commands(motion: dict) -> list[tuple[str, dict]]:
    """(G word, parameters) per motion block: G0 for rapids, G1 with F (mm/s) where the
    feed changes; X Y Z the tool tip, the rotary axes by the machine's names (machine values)."""
    names = motion["axis_names"]
    tip, joints = np.asarray(motion["tip"], float), np.asarray(motion["joints"], float)
    rapid, feed = np.asarray(motion["rapid"], bool), np.asarray(motion["feed"], float)
    out = []
    last_feed = None
    for k in range(len(tip)):
        p = {"X": float(tip[k, 0]), "Y": float(tip[k, 1]), "Z": float(tip[k, 2]),
             names[3]: float(joints[k, 3]), names[4]: float(joints[k, 4])}
        if rapid[k] or not np.isfinite(feed[k]):
            out.append(("G0", p))
            continue
        if last_feed is None or abs(feed[k] - last_feed) > 1e-9:
            p["F"] = feed_mm_per_s(feed[k])
            last_feed = float(feed[k])
        out.append(("G1", p))
    return out


class TsplcamCamOperation(FeatureProxy):
    """A CAM operation whose Path is the linked program's motion."""
    TYPE = "TsplcamCamOperation"
    VERSION = 1
    TITLE = TITLE

    @staticmethod
    def ensure_properties(obj) -> None:
        g = "Operation"
        add_property(obj, "App::PropertyLink", "Program", g, "The tsplcam program whose moves this operation holds")
        add_property(obj, "App::PropertyBool", "Active", g, "Post this operation (CAM)", True)
        add_property(obj, "App::PropertyLink", "ToolController", g, "The tool controller of the program's tool")
        if add_property(obj, "App::PropertyEnumeration", "CoolantMode", g, "Coolant the program switches on"):
            obj.CoolantMode = ["None", "Flood", "Mist"]
        add_property(obj, "App::PropertyString", "CycleTime", g, "Estimated machining time (h:mm:ss)",
                     read_only=True)
        add_property(obj, "App::PropertyString", "Comment", g, "Comment written by the posts", "")
        add_property(obj, "App::PropertyInteger", "Blocks", g, "Motion blocks", read_only=True)

    def onDocumentRestored(self, obj):
        self.ensure_properties(obj)

    def recompute(self, obj):
        from .programobject import is_program_object, motion_of
        prog = obj.Program
        if prog is None or not is_program_object(prog):
            raise InputError("the operation needs a tsplcam program", item=obj.Label)
        why = validity.problem(prog)
        if why:
            raise validity.StaleInput(f"input {why}", item=obj.Label)
        Path = path_module()
        cmds = [Path.Command(g, p) for g, p in motion_commands(motion_of(prog))]
        obj.Path = Path.Path(cmds)
        set_read_only(obj, "Blocks", len(cmds))
        set_read_only(obj, "CycleTime", prog.MachiningTime)
        mode = COOLANT.get(prog.Coolant, "None")
        if obj.CoolantMode != mode:
            obj.CoolantMode = mode
        tc = obj.ToolController
        if tc is not None:
            _set_tool_controller(tc, prog)


class CamOperationView(Stateless):
    """Tree icon of the operation; FreeCAD's Path view draws its moves."""

    def __init__(self, vobj):
        vobj.Proxy = self

    def attach(self, vobj):
        self.Object = vobj.Object

    def getIcon(self):
        from .resources import icon
        return icon("program")


def is_cam_operation(obj) -> bool:
    return getattr(getattr(obj, "Proxy", None), "Type", None) == TsplcamCamOperation.TYPE


def _set_tool_controller(tc, prog) -> None:
    from .fields import PATH_FIELDS, values_of
    feed = values_of(prog.ToolPath, PATH_FIELDS)["feed"]
    if int(tc.ToolNumber) != int(prog.ToolNumber):
        tc.ToolNumber = int(prog.ToolNumber)
    if abs(float(tc.SpindleSpeed) - float(prog.SpindleUsed)) > 1e-9:
        tc.SpindleSpeed = float(prog.SpindleUsed)
    for name in ("HorizFeed", "VertFeed"):
        q = FreeCAD.Units.Quantity(f"{feed_mm_per_s(feed)} mm/s")
        if abs(getattr(tc, name).Value - q.Value) > 1e-9:
            setattr(tc, name, q)


def model_shape(model, samples: int = 13):
    """The model's surface as a compound of B-spline faces, one per patch, interpolating a
    ``samples`` x ``samples`` grid of surface points (the CAM job's base model)."""
    import Part
    faces = []
    g = np.linspace(0.0, 1.0, samples)
    for patch in model.patches:
        U, V = np.meshgrid(g, g, indexing="ij")
        P = np.asarray(patch.evaluate(U.ravel(), V.ravel()).P, float).reshape(samples, samples, 3)
        s = Part.BSplineSurface()
        s.interpolate([[FreeCAD.Vector(*P[i, j]) for j in range(samples)] for i in range(samples)])
        faces.append(s.toShape())
    return Part.makeCompound(faces)


def make_cam_job(program_obj):
    """A CAM Job with the program's moves as its one operation (module doc); None after
    reporting why not (the program is not valid, or FreeCAD's CAM workbench is missing)."""
    from .modelobject import model_of
    from .programobject import is_program_object, triangles_of
    from .viewprogram import implicit_stock
    doc = program_obj.Document
    try:
        if not is_program_object(program_obj):
            raise InputError("select a tsplcam program", item=program_obj.Label)
        why = validity.problem(program_obj)
        if why:
            raise InputError(f"no CAM job from a program that is not valid: {why}", item=program_obj.Label)
        Job, Controller, BitFactory, Stock = cam_api()
        path_module()
        model_obj = program_obj.ToolPath.ProcessingList.Model
        shape = model_shape(model_of(model_obj))
        tool = _tool_of(program_obj)
        stock = (triangles_of(program_obj.Stock) if program_obj.Stock is not None else implicit_stock(program_obj))
    except Exception as exc:
        messages.exception(TITLE, exc, f"making a CAM job of {program_obj.Label}")
        return None

    def work():
        FreeCAD.setActiveDocument(doc.Name)
        base = doc.addObject("Part::Feature", "Surface")
        base.Label = f"{model_obj.Label} surface"
        base.Shape = shape
        if FreeCAD.GuiUp:
            base.ViewObject.Visibility = False
        job = Job.Create("Job", [base])
        job.Label = f"{program_obj.Label} CAM job"
        job.Fixtures = [program_obj.WorkOffset or "G54"]
        if hasattr(job, "JobType") and "Multiaxis" in job.getEnumerationsOfProperty("JobType"):
            job.JobType = "Multiaxis"
        if stock is not None:
            _stock_box(job, Stock, np.asarray(stock[0], float))
        for old in list(job.Tools.Group):           # the default tool controller a new job brings
            bit = getattr(old, "Tool", None)
            job.Tools.removeObject(old)
            doc.removeObject(old.Name)
            if bit is not None and hasattr(bit, "Name") and not bit.InList:
                _remove_bit(doc, bit)
        bit = BitFactory.Create(f"Ball {2 * tool.ball_radius:g} mm", "ballend.fcstd")
        bit.Diameter = FreeCAD.Units.Quantity(f"{2 * tool.ball_radius} mm")
        for prop, value in (("ShankDiameter", tool.shank_diameter), ("Length", tool.shank_length),
                            ("CuttingEdgeHeight", tool.flute_length)):
            if prop in bit.PropertiesList:
                setattr(bit, prop, FreeCAD.Units.Quantity(f"{value} mm"))
        if FreeCAD.GuiUp and getattr(bit, "ViewObject", None) is not None:
            bit.ViewObject.Visibility = False
        tc = Controller.Create(f"TC: {tool.name}", tool=bit, toolNumber=int(program_obj.ToolNumber))
        tc.SpindleDir = "Forward"
        job.Proxy.addToolController(tc)
        op = doc.addObject("Path::FeaturePython", "TsplcamOperation")
        TsplcamCamOperation(op)
        op.Label = f"{program_obj.Label} moves"
        op.Program = program_obj
        op.ToolController = tc
        if FreeCAD.GuiUp:
            CamOperationView(op.ViewObject)
        job.Proxy.addOperation(op)
        op.Proxy.recompute(op)
        return job
    job = _in_transaction(doc, work, program_obj)
    if job is not None:
        messages.info(f"{job.Label}: one operation of {len(job.Operations.Group[0].Path.Commands)} moves, "
                      f"tool T{program_obj.ToolNumber}, S{program_obj.SpindleUsed:g}, {program_obj.WorkOffset}")
    return job


def _in_transaction(doc, work, program_obj):
    from .transaction import in_transaction
    return in_transaction(doc, TITLE, f"making a CAM job of {program_obj.Label}", work)


def _tool_of(program_obj):
    from ..program import load_tool
    tool = load_tool(program_obj.Proxy.settings(program_obj))
    if tool is None:
        raise InputError("the CAM job needs the program's tool (its ball radius and shank)", item="Tool")
    return tool


def _remove_bit(doc, bit) -> None:
    """A tool bit and the shape body it loaded."""
    body = getattr(bit, "BitBody", None)
    names = [bit.Name] + ([o.Name for o in body.OutListRecursive] + [body.Name] if body is not None else [])
    for name in names:
        if doc.getObject(name) is not None:
            try:
                doc.removeObject(name)
            except Exception:
                pass


def _stock_box(job, Stock, V) -> None:
    """The job's stock: a box around the program's stock triangles."""
    lo, hi = V.min(axis=0), V.max(axis=0)
    old = job.Stock
    box = Stock.CreateBox(job, extent=FreeCAD.Vector(*(hi - lo)),
                          placement=FreeCAD.Placement(FreeCAD.Vector(*lo), FreeCAD.Rotation()))
    job.Stock = box
    if old is not None and old.Name != box.Name:
        job.Document.removeObject(old.Name)
