"""Which document property holds which option of :class:`tsplcam.settings.JobSettings`.

One table (``PATH_FIELDS``, ``PROGRAM_FIELDS``) tells the tool-path and program objects which
properties to add, the task panel and the preferences page which control to show (with the
words a CAM programmer uses and the unit), and :func:`settings_of` how to read them back
into JobSettings. Feeds are plain numbers in mm/min (a FreeCAD speed property would show and
take mm/s); spindle speeds in rpm; lengths and angles are FreeCAD lengths (mm) and angles
(degrees). Optional options have an "unset" value: an empty text for points and ranges, 0
for the largest tilt and the spindle speed, the engine's default weight for the rotary weight,
an enumeration entry for controller and axes form.
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass, fields as dc_fields

from ..errors import InputError
from ..orientation.orient import ROTARY_WEIGHT
from ..settings import JobSettings, choices_of, default_of, help_text

CONTROLLER = "machine's controller"
MACHINE_CHOICE = "machine's choice"
DEFAULTS = JobSettings()


@dataclass(frozen=True)
class Field:
    name: str             # the JobSettings field
    prop: str             # the document property
    label: str            # what the panel calls it
    ptype: str            # FreeCAD property type
    unit: str = ""        # shown next to the value
    unset: object = None  # the property value that means "not given" (None: always given)

    @property
    def spec(self):
        return _SPECS[self.name]

    @property
    def kind(self) -> str:
        return self.spec.metadata["kind"]

    @property
    def tip(self) -> str:
        return help_text(self.spec)

    @property
    def default(self):
        return default_of(self.spec)


_SPECS = {f.name: f for f in dc_fields(JobSettings)}

PATH_FIELDS = (
    Field("tool_radius", "ToolRadius", "Ball radius", "App::PropertyLength", "mm"),
    Field("scallop", "Scallop", "Scallop height (sets the stepover)", "App::PropertyLength", "mm"),
    Field("chord_tol", "ChordTolerance", "Chord tolerance", "App::PropertyLength", "mm"),
    Field("max_step", "MaxStep", "Longest cutting move", "App::PropertyLength", "mm"),
    Field("feed", "Feed", "Cutting feed", "App::PropertyFloat", "mm/min"),
    Field("clearance", "Clearance", "Retract clearance", "App::PropertyLength", "mm"),
    Field("clearance_mode", "ClearanceMode", "Retract to", "App::PropertyEnumeration"),
    Field("balance", "Balance", "Even out the last stepover", "App::PropertyBool"),
)

PROGRAM_FIELDS = (
    Field("tool", "Tool", "Tool", "App::PropertyEnumeration"),
    Field("orientation", "Orientation", "Tool axes", "App::PropertyEnumeration"),
    Field("target", "Target", "Lean toward", "App::PropertyEnumeration"),
    Field("axis", "Axis", "Target axis (x, y, z)", "App::PropertyVector"),
    Field("lead", "Lead", "Lead (lag if negative)", "App::PropertyAngle", "°"),
    Field("side_tilt", "SideTilt", "Side tilt", "App::PropertyAngle", "°"),
    Field("point", "Point", "Point (x, y, z)", "App::PropertyString", "mm", ""),
    Field("direction", "Direction", "Line direction (x, y, z)", "App::PropertyString", "", ""),
    Field("max_tilt", "MaxTilt", "Largest tilt (0: machine's range)", "App::PropertyAngle", "°", 0.0),
    Field("limit_axis", "LimitAxis", "Tilt measured from (x, y, z)", "App::PropertyVector"),
    Field("tilt_range", "TiltRange", "Tilt axis range (min, max)", "App::PropertyString", "°", ""),
    Field("pole_tilt", "PoleTilt", "Pole tilt", "App::PropertyAngle", "°"),
    Field("max_lead", "MaxLead", "Largest lead or lag from the normal", "App::PropertyAngle", "°"),
    Field("max_side_tilt", "MaxSideTilt", "Largest side tilt from the normal", "App::PropertyAngle", "°"),
    Field("max_axis_step", "MaxAxisStep", "Largest axis step between points", "App::PropertyAngle", "°"),
    Field("holder_clearance", "HolderClearance", "Shank and holder clearance", "App::PropertyLength", "mm"),
    Field("smoothing_length", "SmoothingLength", "Smoothing length", "App::PropertyLength", "mm"),
    Field("rotary_weight", "RotaryWeight", "Rotary (C) axis weight", "App::PropertyFloat", "", ROTARY_WEIGHT),
    Field("machine", "Machine", "Machine", "App::PropertyEnumeration"),
    Field("dialect", "Dialect", "Controller", "App::PropertyEnumeration", "", CONTROLLER),
    Field("axes_form", "AxesForm", "Tool axes in the program", "App::PropertyEnumeration", "", MACHINE_CHOICE),
    Field("spindle", "SpindleSpeed", "Spindle speed (0: machine's)", "App::PropertyFloat", "rpm", 0.0),
)

ALL_FIELDS = PATH_FIELDS + PROGRAM_FIELDS
BY_NAME = {f.name: f for f in ALL_FIELDS}
# the preferences page: a new path's ball radius may be left to the tool (0)
PREFS_FIELDS = tuple(Field(f.name, f.prop, "Ball radius (0: the tool's)", f.ptype, f.unit, 0.0)
                     if f.name == "tool_radius" else f for f in ALL_FIELDS)
# option -> the property that sets it (errors name the property)
PROPERTY_OF = {f.name: f.prop for f in ALL_FIELDS} | {"stock": "Stock", "model": "Model"}


def choices(f: Field) -> list[str]:
    """The entries of an enumeration property."""
    if f.name == "tool":
        from .programobject import tool_names
        return tool_names()
    if f.name == "machine":
        from ..post.machine import machine_files
        return sorted(machine_files())
    out = list(choices_of(f.spec))
    if f.unset is not None and isinstance(f.unset, str) and f.unset:
        out = [f.unset] + out
    return out


def to_property(f: Field, value):
    """The property value for an option value (None -> the field's unset value)."""
    if value is None:
        if f.unset is None and f.kind not in ("name",):
            raise InputError("must be given", item=f.prop)
        return f.unset if f.unset is not None else ""
    if f.ptype == "App::PropertyString" and f.kind in ("vector", "pair"):
        return ", ".join(f"{float(x):g}" for x in value)
    if f.ptype == "App::PropertyVector":
        import FreeCAD
        return FreeCAD.Vector(*[float(x) for x in value])
    if f.ptype in ("App::PropertyFloat", "App::PropertyLength", "App::PropertyAngle"):
        return float(value)
    return value


def from_property(f: Field, value):
    """The option value of a property value (the unset value -> None); bad text is refused
    naming the property."""
    if hasattr(value, "Value") and not hasattr(value, "x"):          # a Quantity
        value = float(value.Value)
    if f.unset is not None and value == f.unset:
        return None
    if f.ptype == "App::PropertyString" and f.kind in ("vector", "pair"):
        n = 3 if f.kind == "vector" else 2
        text = str(value).strip().strip("()[]")
        if not text:
            return None
        try:
            numbers = tuple(float(x) for x in text.replace(";", ",").split(","))
        except ValueError:
            numbers = ()
        if len(numbers) != n:
            raise InputError(f"{text!r} is not {n} numbers separated by commas", item=f.prop)
        return numbers
    if f.ptype == "App::PropertyVector":
        return (float(value.x), float(value.y), float(value.z))
    if f.ptype == "App::PropertyBool":
        return bool(value)
    if f.ptype in ("App::PropertyFloat", "App::PropertyLength", "App::PropertyAngle"):
        return float(value)
    return str(value)


def add_properties(obj, table, group: str, values: dict | None = None) -> None:
    """The properties of ``table`` on ``obj`` (those it lacks), set to ``values`` or the
    JobSettings defaults; a feed kept as a FreeCAD speed by older documents becomes mm/min."""
    from .proxy import add_property
    values = values or {}
    for f in table:
        if f.prop in obj.PropertiesList and obj.getTypeIdOfProperty(f.prop) != f.ptype:
            old = getattr(obj, f.prop)
            kept = old.getValueAs("mm/min").Value if f.kind == "feed" and hasattr(old, "getValueAs") else None
            obj.removeProperty(f.prop)
            if kept is not None:
                values = dict(values, **{f.name: float(kept)})
        if f.prop in obj.PropertiesList:
            continue
        unit = f" ({f.unit})" if f.unit and f.ptype not in ("App::PropertyLength", "App::PropertyAngle") else ""
        add_property(obj, f.ptype, f.prop, group, f"{f.label}{unit}: {help_text(f.spec)}")
        if f.ptype == "App::PropertyEnumeration":
            setattr(obj, f.prop, choices(f))
        value = values.get(f.name, f.default)
        if value is None and f.unset is None:
            continue
        setattr(obj, f.prop, to_property(f, value))


def values_of(obj, table) -> dict:
    """Option values of ``obj``'s properties for the fields of ``table``."""
    return {f.name: from_property(f, getattr(obj, f.prop)) for f in table if f.prop in obj.PropertiesList}


def set_values(obj, table, values: dict) -> None:
    """Set the properties of ``table`` from option values (only those given)."""
    for f in table:
        if f.name in values and f.prop in obj.PropertiesList:
            new = to_property(f, values[f.name])
            if f.ptype == "App::PropertyEnumeration" and new not in obj.getEnumerationsOfProperty(f.prop):
                raise InputError(f"unknown {new!r}; one of {', '.join(obj.getEnumerationsOfProperty(f.prop))}",
                                 item=f.prop)
            if from_property(f, getattr(obj, f.prop)) != values[f.name]:
                setattr(obj, f.prop, new)


def checked(values: dict) -> JobSettings:
    """JobSettings from option values over the defaults, checked; errors name the property."""
    try:
        s = JobSettings(**values)
    except TypeError as exc:                     # an option JobSettings does not have
        raise InputError(str(exc)) from None
    return s.check(lambda name: PROPERTY_OF.get(name, name))


@contextlib.contextmanager
def named_properties():
    """Engine errors about an option (InputError.item a JobSettings field) name the document
    property that sets it instead (``feed`` -> ``Feed``)."""
    try:
        yield
    except InputError as exc:
        if exc.item in PROPERTY_OF and exc.item != PROPERTY_OF[exc.item]:
            raise InputError(exc.message, path=exc.path, line=exc.line, item=PROPERTY_OF[exc.item]) from None
        raise
