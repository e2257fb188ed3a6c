"""Every option of a tsplcam job in one dataclass, :class:`JobSettings`, with its default,
its unit, its help text and its check.

The command line generates the options of ``path`` and ``job`` from these fields
(:mod:`tsplcam.job`), the workbench's program object maps its properties onto them, and
job files use the field names as keys (:meth:`JobSettings.from_dict` /
:meth:`JobSettings.to_dict`). A field ``tool_radius`` is the option ``--tool-radius``.

The defaults are the main job's: the keycap sample, the 1 mm ball ``ball1_keycap``, scallop
0.005 mm, chord tolerance 0.001 mm, smooth collision-free tool axes keeping shank and
holder 0.3 mm off the part, posted for ``mikron_ucp600_heidenhain`` in its controller's
dialect. Lengths in mm, feeds in mm/min.
"""
from __future__ import annotations

import math
from dataclasses import MISSING, asdict, dataclass, field, fields

from .errors import InputError

# option groups, in the order the help lists them
GROUPS = {
    "part": "the part",
    "path": "finishing path",
    "axes": "tool axes and collision checks",
    "machine": "machine and program",
    "outputs": "output files",
}

# the options each stage reads, besides the model
PATH_KEYS = ("scallop", "chord_tol", "max_step", "feed", "clearance", "clearance_mode", "balance")
# the tool-axis controls, handed to the orientation stage (tsplcam.orientation.settings)
AXIS_KEYS = ("target", "axis", "lead", "side_tilt", "point", "direction", "max_tilt", "limit_axis",
             "tilt_range", "pole_tilt")
# the tool-axis limits the job's options name apart from the orientation stage's settings
# (job option: OrientationSettings field)
AXIS_LIMITS = {"max_lead": "lead_max", "max_side_tilt": "tilt_max", "max_axis_step": "max_step"}
PROGRAM_KEYS = ("tool", "orientation", "holder_clearance", "smoothing_length", "rotary_weight",
                "machine", "dialect", "axes_form", "spindle") + AXIS_KEYS + tuple(AXIS_LIMITS)
# kinds of option whose value is one number, and the unit their messages name
NUMBER_KINDS = ("length", "length0", "feed", "factor", "angle", "rpm")
UNITS = {"length": "mm", "length0": "mm", "feed": "mm/min", "angle": "deg", "rpm": "rpm"}


def _orientations():
    from .orientation import ORIENTATIONS
    return ORIENTATIONS


def _targets():
    from .orientation.settings import TARGETS
    return TARGETS


def _dialects():
    from .post.dialects import NAMES
    return NAMES


def _clearance_modes():
    from .toolpath.zigzag import CLEARANCE_MODES
    return CLEARANCE_MODES


def _samples():
    from .model.samples import SAMPLES
    return ", ".join(SAMPLES)


# placeholders of the help texts, filled when the help is shown
HELP_LISTS = {"samples": _samples, "dialects": lambda: ", ".join(_dialects())}


def option(default, group: str, help: str, kind: str, metavar: str | None = None, choices=None,
           flags: tuple = (), command: str | None = None):
    """A field with what the command line and the checks need to know about it.

    ``kind``: ``length`` (a number > 0, mm), ``length0`` (>= 0, mm), ``feed`` (> 0, mm/min),
    ``rpm`` (> 0, revolutions per minute), ``factor`` (>= 0), ``angle`` (degrees; its range is the stage's to check), ``vector``
    (three numbers, x,y,z), ``pair`` (two numbers, min,max), ``choice`` (one of ``choices()``), ``flag`` (true/false), ``text`` (a
    name or file, required), ``name`` (a name or file, or nothing), ``file`` (a file name, or
    nothing when the default is nothing). ``flags``: command-line
    spellings other than ``--field-name``; ``command``: the one command an output belongs to.
    """
    return field(default=default, metadata=dict(group=group, help=help, kind=kind, metavar=metavar,
                                                choices=choices, flags=flags, command=command))


@dataclass
class JobSettings:
    """What to machine, with which tool and machine, and where the files go (module doc)."""
    # the part
    model: str = option("keycap", "part", "the part: a model file (.tspl, .tsm, .iga, or an .obj quad "
                        "cage, mm) or a shipped sample ({samples})", "text", "MODEL")
    processing_list: str | None = option(None, "part", "the patch order, start and finish corners and "
                                         "crossfeed to follow: a processing list (JSON) from `tsplcam plan`; "
                                         "default: planned here, with as few retractions as the part allows",
                                         "file", "FILE")
    stock: str | None = option(None, "part", "stock, mold block or fixture the shank and holder must clear "
                               "too: triangles in an OBJ file (mm); the keycap_mold sample brings its block",
                               "file", "OBJ")
    # the tool and the path
    tool: str | None = option("ball1_keycap", "path", "the cutter with its shank and holder: a shipped tool "
                              "(ball1_keycap, ball5_impeller, ball6_freecad_holder), a tool file (.json) or a "
                              "FreeCAD CAM bit (.fctb)", "name", "TOOL")
    tool_radius: float | None = option(None, "path", "ball radius of the cutter (mm); default: the tool's; "
                                       "with a tool the two must agree", "length", "MM")
    scallop: float = option(0.005, "path", "largest scallop height left between neighbouring passes (mm)",
                            "length", "MM")
    chord_tol: float = option(0.001, "path", "largest distance between a straight move and the surface "
                              "along a pass (mm)", "length", "MM")
    max_step: float = option(1.0, "path", "longest straight move along a pass (mm)", "length", "MM")
    feed: float = option(1000.0, "path", "cutting feed (mm/min)", "feed", "MM_PER_MIN")
    clearance: float = option(5.0, "path", "safe distance for retractions: above the part's top, or "
                              "outside the sphere around it (mm)", "length", "MM")
    clearance_mode: str = option("auto", "path", "retract to a plane above the part or to a sphere around "
                                 "it; auto: the plane when every surface normal points up, as in a mold",
                                 "choice", choices=_clearance_modes)
    balance: bool = option(True, "path", "keep the passes where the scallop limit puts them, the last gap of "
                           "a patch narrower, instead of spreading that slack over all gaps", "flag",
                           flags=("--no-balance",))
    # the tool axes
    orientation: str = option("smooth", "axes", "tool axes: normal (the surface normal, no collision "
                              "checks), fixed (exactly the target axis: 3+2, or a fixed lead/tilt), closest "
                              "(alias closest-z: per point the collision-free axis nearest the target, tilting "
                              "only where needed) or smooth (collision-free, changes spread along the path in "
                              "the machine's rotary axes)", "choice", choices=_orientations)
    target: str = option("axis", "axes", "what the tool axis leans toward: axis (a fixed direction, --axis), "
                         "lead-tilt (--lead and --side-tilt against the surface normal), toward-point / "
                         "away-from-point (--point), toward-line / away-from-line (through --point along "
                         "--direction)", "choice", choices=_targets)
    axis: tuple = option((0.0, 0.0, 1.0), "axes", "target tool axis x,y,z (part frame)", "vector", "X,Y,Z")
    lead: float = option(0.0, "axes", "lead-tilt target: lead toward the feed direction, negative for lag "
                         "(deg)", "angle", "DEG")
    side_tilt: float = option(0.0, "axes", "lead-tilt target: side tilt to the left of the feed direction "
                              "(deg)", "angle", "DEG")
    point: tuple | None = option(None, "axes", "point the axis leans toward or away from, or a point of the "
                                 "line (x,y,z mm)", "vector", "X,Y,Z")
    direction: tuple | None = option(None, "axes", "direction of that line (x,y,z)", "vector", "X,Y,Z")
    max_tilt: float | None = option(None, "axes", "largest angle between the tool axis and --limit-axis "
                                    "(deg); default: the machine's range alone", "angle", "DEG")
    limit_axis: tuple = option((0.0, 0.0, 1.0), "axes", "the axis --max-tilt is measured from (x,y,z)",
                               "vector", "X,Y,Z")
    tilt_range: tuple | None = option(None, "axes", "the machine's tilt axis narrowed to min,max (deg, "
                                      "machine values)", "pair", "MIN,MAX")
    pole_tilt: float = option(0.0, "axes", "smallest angle kept between the tool axis and the rotary axis "
                              "(deg); 0: at the pole the rotary axis holds still instead", "angle", "DEG")
    max_lead: float = option(60.0, "axes", "largest lead or lag of the tool axis from the surface normal, "
                             "along the feed (deg, 0 to 89.9)", "angle", "DEG")
    max_side_tilt: float = option(60.0, "axes", "largest side tilt of the tool axis from the surface normal, "
                                  "across the feed (deg, 0 to 89.9)", "angle", "DEG")
    max_axis_step: float = option(10.0, "axes", "closest and smooth: largest change of the tool axis from one "
                                  "point of a pass to the next that the axis search may take (deg; it searches "
                                  "a grid of rotary positions every 10 deg, so below about 10 it may refuse a "
                                  "turn the smoothing would spread finer); raise it where the job stops at a "
                                  "sharp turn", "angle", "DEG")
    holder_clearance: float = option(0.3, "axes", "distance kept between shank or holder and the part "
                                     "(mm); only the flutes may touch it", "length0", "MM")
    smoothing_length: float = option(5.0, "axes", "smooth: a tilt needed at one place is eased in and out "
                                     "over about this length of path on each side (mm)", "length", "MM")
    rotary_weight: float | None = option(None, "axes", "smooth, with a machine: how much the rotary (C) axis "
                                         "motion counts, in the machine's time units (default 2; 0: not at "
                                         "all, the change of the tool-axis direction instead)", "factor", "W")
    # the machine and the program
    machine: str | None = option("mikron_ucp600_heidenhain", "machine", "the five-axis machine: kinematics, "
                                 "travel and rotary limits, axis speeds (`python3 -m tsplcam machines`, or a "
                                 ".json file); its rotary range also bounds the tool axes", "name", "NAME")
    dialect: str | None = option(None, "machine", "controller syntax of the program: {dialects}; default: "
                                 "the machine's controller", "choice", "DIALECT", choices=_dialects,
                                 flags=("--dialect", "--post"))
    spindle: float | None = option(None, "machine", "spindle speed (rpm); default: the machine file's; "
                                   "refused outside the machine's spindle range", "rpm", "RPM")
    axes_form: str | None = option(None, "machine", "tool axes in the program as machine angles or as the "
                                   "tool vector (Heidenhain LN TX TY TZ, Sinumerik A3 B3 C3, Fanuc G43.5 I J K); "
                                   "default: the machine file's choice, else angles", "choice", "FORM",
                                   choices=("angles", "vector"))
    # where the files go
    out: str = option("tsplcam-job", "outputs", "folder for the program (named after the model, with the "
                      "controller's extension), the CL data, processing-list.json, report.json and report.html",
                      "text", "DIR", command="job")
    name: str | None = option(None, "outputs", "file name of the program and the CL data, without extension; "
                              "default: the model's", "name", "NAME", command="job")
    html_report: bool = option(True, "outputs", "write report.html with its pictures (report_files/) beside "
                               "report.json", "flag", flags=("--html-report", "--no-html-report"), command="job")
    gcode: str | None = option(None, "outputs", "write the machine program (G-code) to this file; needs a "
                               "machine", "file", "FILE", command="path")
    cl: str | None = option(None, "outputs", "write the path as APT CL data: tool tip (mm) and unit tool axis "
                            "per point", "file", "FILE", command="path")
    report: str | None = option(None, "outputs", "write the path's figures (and what --verify measured) as "
                                "JSON", "file", "FILE", flags=("--json",), command="path")
    verify: bool = option(True, "outputs", "measure scallop height, cusps and gouges on the surface and "
                          "report them, the report's scallop map (slow on fine paths: about 15 s on the main job)",
                          "flag", flags=("--verify", "--no-verify"))
    baseline: bool = option(False, "outputs", "also machine each face on its own (compound NURBS, "
                            "retracting between faces) and compare the two paths", "flag")
    baseline_cl: str | None = option(None, "outputs", "write that comparison path as CL data (implies "
                                     "--baseline)", "file", "FILE", command="path")
    fcstd: str | None = option(None, "outputs", "also write a FreeCAD document (.FCStd) with the model, "
                               "processing list, tool path, program and a FreeCAD CAM job holding the "
                               "program's moves (made by freecadcmd, which must be installed)", "file",
                               "FILE", command="job")

    # -- checks -------------------------------------------------------------------------------
    def check(self, label=None) -> "JobSettings":
        """Refuse a value that cannot be used, naming the option (``label(field name)``; by
        default the field name itself): numbers must be finite, lengths and feeds above 0,
        clearances and weights not below 0, choices known; and the options that need each
        other must come together. Returns self."""
        label = label or (lambda name: name)
        for f in fields(self):
            value = getattr(self, f.name)
            _check_value(f, value, label(f.name))
            if f.metadata["kind"] in ("vector", "pair") and value is not None:
                setattr(self, f.name, tuple(float(x) for x in value))     # a JSON list as a tuple
        if self.tool is None and self.tool_radius is None:
            raise InputError(f"needed when no tool ({label('tool')}) is given", item=label("tool_radius"))
        if self.orientation != "normal" and self.tool is None:
            raise InputError(f"orientation '{self.orientation}' needs a tool with its shank and holder "
                             f"({label('tool')})", item=label("orientation"))
        if self.tool_radius is not None:
            for name in ("scallop", "chord_tol"):
                if getattr(self, name) >= self.tool_radius:
                    raise InputError(f"{getattr(self, name):g} mm must be smaller than the tool radius "
                                     f"{self.tool_radius:g} mm", item=label(name))
        for name in ("max_lead", "max_side_tilt"):
            if not 0.0 <= getattr(self, name) <= 89.9:
                raise InputError(f"must be from 0 to 89.9 degrees, not {getattr(self, name):g}", item=label(name))
        if not 0.0 < self.max_axis_step <= 180.0:
            raise InputError(f"must be more than 0 and at most 180 degrees, not {self.max_axis_step:g}",
                             item=label("max_axis_step"))
        if self.orientation != "normal":
            try:
                self.orientation_settings()
            except InputError as exc:
                names = {"strategy": "orientation"} | {v: k for k, v in AXIS_LIMITS.items()}
                item = names.get(exc.item, exc.item)
                raise InputError(exc.message, item=label(item) if item else None) from None
        if self.name is not None and ("/" in self.name or "\\" in self.name or self.name.strip(".") == ""):
            raise InputError(f"a file name without folder, not {self.name!r}", item=label("name"))
        if self.machine is None:
            for name in ("gcode", "dialect", "axes_form", "spindle"):
                if getattr(self, name) is not None:
                    raise InputError(f"needs {label('machine')} (see `python3 -m tsplcam machines`)",
                                     item=label(name))
            if self.rotary_weight:
                raise InputError(f"needs {label('machine')}: it weighs that machine's rotary axis",
                                 item=label("rotary_weight"))
        return self

    # -- job files ----------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: dict, path: str | None = None, defaults: dict | None = None) -> "JobSettings":
        """Settings from a mapping of option names to values (a job file's JSON), over
        ``defaults``; unknown keys are refused by name. Checked."""
        if not isinstance(data, dict):
            raise InputError("the job settings are a JSON object of option names and values", path=path)
        known = {f.name for f in fields(cls)}
        unknown = sorted(str(k) for k in data if k not in known)
        if unknown:
            raise InputError(f"unknown option{'s' if len(unknown) > 1 else ''} "
                             f"{', '.join(repr(k) for k in unknown)} (known: {', '.join(sorted(known))})",
                             path=path)
        try:
            return cls(**{**(defaults or {}), **data}).check()
        except InputError as exc:
            if path is None or exc.path is not None:
                raise
            raise InputError(exc.message, path=path, item=exc.item) from None

    def to_dict(self, keys=None) -> dict:
        """The settings as plain JSON values (``keys``: only those options)."""
        d = asdict(self)
        return d if keys is None else {k: d[k] for k in keys}

    @classmethod
    def option_names(cls, command: str | None = None) -> list[str]:
        """The field names a command takes: every job and path option, and the outputs of
        ``command`` (all outputs when None)."""
        return [f.name for f in fields(cls) if command is None or f.metadata["command"] in (None, command)]

    def orientation_settings(self):
        """The orientation stage's settings (tsplcam.orientation.OrientationSettings), checked;
        errors name the option."""
        from .orientation.settings import OrientationSettings
        return OrientationSettings(strategy=self.orientation, smoothing_length=self.smoothing_length,
                                   rotary_weight=self.rotary_weight,
                                   **{k: getattr(self, k) for k in AXIS_KEYS},
                                   **{v: getattr(self, k) for k, v in AXIS_LIMITS.items()}).check()

    def path_settings(self, tool_radius: float):
        """The path generator's settings (tsplcam.toolpath.zigzag.PathSettings)."""
        from .toolpath.zigzag import PathSettings
        return PathSettings(tool_radius=tool_radius, **self.to_dict(PATH_KEYS))


def default_of(f):
    return f.default if f.default is not MISSING else None


def help_text(f) -> str:
    """The field's help, with the lists it names filled in."""
    text = f.metadata["help"]
    return text.format(**{k: v() for k, v in HELP_LISTS.items() if "{" + k + "}" in text})


def choices_of(f) -> tuple:
    c = f.metadata["choices"]
    return tuple(c() if callable(c) else c) if c is not None else ()


def _check_value(f, value, name: str) -> None:
    kind = f.metadata["kind"]
    if kind == "flag":
        if not isinstance(value, bool):
            raise InputError(f"must be true or false, not {value!r}", item=name)
        return
    if value is None:
        if f.default is None or kind == "name":
            return
        raise InputError("must be given", item=name)
    if kind in ("vector", "pair"):
        n = 3 if kind == "vector" else 2
        if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != n or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value):
            raise InputError(f"must be {n} finite numbers, not {value!r}", item=name)
        return
    if kind in NUMBER_KINDS:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InputError(f"must be a finite number, not {value!r}", item=name)
        unit = f" ({UNITS[kind]})" if kind in UNITS and kind != "angle" else ""
        if kind in ("length", "feed", "rpm") and value <= 0:
            raise InputError(f"must be a positive number{unit}, not {value:g}", item=name)
        if kind in ("length0", "factor") and value < 0:
            raise InputError(f"must not be negative{unit}, not {value:g}", item=name)
        return
    if not isinstance(value, str) or not value.strip():
        raise InputError(f"must be a name or a file name, not {value!r}", item=name)
    if kind == "choice" and value not in choices_of(f):
        raise InputError(f"unknown {value!r}; one of {', '.join(choices_of(f))}", item=name)
