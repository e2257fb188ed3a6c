"""Five-axis machine definitions: the kinematic chain, travel, limits and dynamics.

A machine is read from a JSON file with the header ``"format": "tsplcam-machine",
"version": 1``; the schema is documented in ``tsplcam/post/MACHINES.md``. Files use the
user-facing units (mm, degrees, mm/min and deg/min for velocities, mm/s^2 and deg/s^2 for
accelerations); :class:`Machine` keeps them as written and the kinematics converts to
radians where it computes.

Supported kinds (two rotary axes, the rotary "C" axis about Z, the tilt axis about X or Y,
spindle along machine +Z at home):

* ``table-table``: tilt axis on the machine bed carrying the rotary table (A/C or B/C
  trunnion, LinuxCNC ``xyzac-trt`` / ``xyzbc-trt``);
* ``head-table``: tilting head (B or A) and a rotary table C;
* ``head-head``: rotary head C carrying the tilting head (B or A), fixed table.

Machines are found by name in ``$TSPLCAM_MACHINE_PATH`` (``os.pathsep``-separated folders)
and then in the shipped ``tsplcam/data/machines``; a path to a ``.json`` file also works.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from .. import data_dir
from ..errors import InputError
from ..inputfile import COORDINATE_LIMIT, read_json

FORMAT = "tsplcam-machine"
VERSION = 1
# Smallest velocity (mm/min, deg/min) or acceleration (mm/s^2, deg/s^2) accepted: times are
# divided by these, and a denormal 1e-320 would turn them into infinities.
MIN_RATE = 1e-6
KINDS = ("table-table", "head-table", "head-head")
CONTROLLERS = ("heidenhain", "sinumerik", "fanuc", "linuxcnc")
LINEAR_NAMES = ("X", "Y", "Z")
AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}
# LinuxCNC trt kinematics modules (docs/post.md sections 2.1-2.2) and the pins each one reads.
LINUXCNC_KINS = {
    "xyzac-trt-kins": ("x-rot-point", "y-rot-point", "z-rot-point", "y-offset", "z-offset",
                       "tool-offset", "conventional-directions"),
    "xyzbc-trt-kins": ("x-rot-point", "y-rot-point", "z-rot-point", "x-offset", "z-offset",
                       "tool-offset", "conventional-directions"),
}


def shipped_dir() -> str:
    """Folder of the machine files shipped with tsplcam."""
    return os.path.join(data_dir(), "machines")


@dataclass
class LinearAxis:
    """A linear axis: travel of the spindle gauge point in machine coordinates (mm)."""
    name: str
    min: float
    max: float
    max_velocity: float        # mm/min
    max_acceleration: float    # mm/s^2


@dataclass
class RotaryAxis:
    """A rotary axis.

    The element it carries (table with the part, or spindle head) turns right-handed about
    ``about`` by ``sign * (value - zero)`` degrees. ISO/RS274 directions are ``sign = -1``
    for a table axis and ``+1`` for a head axis (docs/post.md section 1); LinuxCNC's trt
    modules without conventional directions turn the table by ``+value`` (``sign = +1``).
    ``pivot`` is a point of the axis line at home (all axes at zero), in machine coordinates
    for a table axis and relative to the spindle gauge point for a head axis (mm).
    ``min``/``max`` are None for an endless axis (``continuous``); its values are written
    unwound (running values, never a 360-degree swing).
    """
    name: str
    about: str
    sign: int
    zero: float
    pivot: tuple
    min: float | None
    max: float | None
    continuous: bool
    max_velocity: float        # deg/min
    max_acceleration: float    # deg/s^2

    @property
    def index(self) -> int:
        return AXIS_INDEX[self.about]

    def within(self, value) -> np.ndarray:
        """Mask of values inside the limits (all True for an endless axis)."""
        v = np.asarray(value, float)
        ok = np.ones(v.shape, bool)
        if self.min is not None:
            ok &= v >= self.min - 1e-9
        if self.max is not None:
            ok &= v <= self.max + 1e-9
        return ok


@dataclass
class Machine:
    """A five-axis machine (see the module docstring for kinds and units)."""
    name: str
    kind: str
    controller: str
    linear: dict                 # "X", "Y", "Z" -> LinearAxis
    tilt: RotaryAxis             # about X (A) or Y (B)
    rotary: RotaryAxis           # about Z (C)
    tool_length: float = 100.0   # mm, gauge point to tool tip, used for head pivots and Z travel
    safe_z: float = 0.0          # machine Z of the gauge point for retracts (G53 / M91 / SUPA)
    part_origin: tuple = (0.0, 0.0, 0.0)   # program zero in machine coordinates at home
    title: str = ""
    comment: str = ""
    post: dict = field(default_factory=dict)
    linuxcnc: dict | None = None
    path: str | None = None      # the file it was read from
    max_feed: float | None = None          # mm/min, the largest programmed feed; None: the slowest linear axis
    spindle_range: tuple | None = None     # (min, max) rpm the spindle runs at; None: not checked

    # --- derived -----------------------------------------------------------------------
    @property
    def axis_names(self) -> tuple:
        return ("X", "Y", "Z", self.tilt.name, self.rotary.name)

    @property
    def table_axes(self) -> list:
        """Rotary axes carried by the table side, outermost (on the bed) first."""
        if self.kind == "table-table":
            return [self.tilt, self.rotary]
        if self.kind == "head-table":
            return [self.rotary]
        return []

    @property
    def head_axes(self) -> list:
        """Rotary axes in the head, outermost (on the Z slide) first."""
        if self.kind == "head-head":
            return [self.rotary, self.tilt]
        if self.kind == "head-table":
            return [self.tilt]
        return []

    def on_table(self, axis: RotaryAxis) -> bool:
        return any(a is axis for a in self.table_axes)

    @property
    def max_velocity(self) -> np.ndarray:
        """Per-axis velocity limits (X, Y, Z mm/s; tilt, rotary deg/s)."""
        return np.array([self.linear[n].max_velocity for n in LINEAR_NAMES]
                        + [self.tilt.max_velocity, self.rotary.max_velocity]) / 60.0

    @property
    def max_acceleration(self) -> np.ndarray:
        """Per-axis acceleration limits (mm/s^2, deg/s^2)."""
        return np.array([self.linear[n].max_acceleration for n in LINEAR_NAMES]
                        + [self.tilt.max_acceleration, self.rotary.max_acceleration], float)

    @property
    def feed_limit(self) -> float:
        """The largest feed (mm/min) a program may ask for: ``max_feed`` from the file, else the
        slowest linear axis's velocity (no tool-tip feed along that axis could be faster)."""
        if self.max_feed is not None:
            return float(self.max_feed)
        return float(min(a.max_velocity for a in self.linear.values()))

    def check_feed(self, feed, item: str = "feed") -> None:
        """Refuse a feed (mm/min) above :attr:`feed_limit`, naming the limit and the machine."""
        limit = self.feed_limit
        if feed is not None and float(feed) > limit + 1e-9:
            where = "max_feed in its file" if self.max_feed is not None else "its slowest linear axis"
            raise InputError(f"{float(feed):g} mm/min is above the largest feed of machine {self.name}: "
                             f"{limit:g} mm/min ({where})", item=item)

    def check_spindle(self, rpm, item: str = "spindle") -> None:
        """Refuse a spindle speed (rpm) outside ``spindle_range``, naming the range."""
        if rpm is None or self.spindle_range is None:
            return
        lo, hi = self.spindle_range
        if not lo - 1e-9 <= float(rpm) <= hi + 1e-9:
            raise InputError(f"{float(rpm):g} rpm is outside the spindle range of machine {self.name}: "
                             f"{lo:g} to {hi:g} rpm (spindle_range in its file)", item=item)

    def to_dict(self) -> dict:
        """The machine as a version-1 JSON document (the LinuxCNC form is kept as written)."""
        def rot(ax: RotaryAxis) -> dict:
            d = {"about": ax.about}
            if self.linuxcnc is None:
                d.update(sign=ax.sign, zero=ax.zero, pivot=[float(v) for v in ax.pivot])
            if ax.continuous:
                d["continuous"] = True
            else:
                d.update(min=ax.min, max=ax.max)
            d.update(max_velocity=ax.max_velocity, max_acceleration=ax.max_acceleration)
            return d
        out = {"format": FORMAT, "version": VERSION, "name": self.name}
        if self.title:
            out["title"] = self.title
        if self.comment:
            out["comment"] = self.comment
        out.update(kind=self.kind, controller=self.controller)
        out["linear_axes"] = {n: {"min": a.min, "max": a.max, "max_velocity": a.max_velocity,
                                  "max_acceleration": a.max_acceleration}
                              for n, a in self.linear.items()}
        out["rotary_axes"] = {self.tilt.name: rot(self.tilt), self.rotary.name: rot(self.rotary)}
        if self.linuxcnc is not None:
            out["linuxcnc"] = dict(self.linuxcnc)
        out.update(tool_length=self.tool_length, safe_z=self.safe_z,
                   part_origin=[float(v) for v in self.part_origin])
        if self.max_feed is not None:
            out["max_feed"] = self.max_feed
        if self.spindle_range is not None:
            out["spindle_range"] = [float(v) for v in self.spindle_range]
        if self.post:
            out["post"] = dict(self.post)
        return out

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2) + "\n"

    def summary(self) -> str:
        """A few human-readable lines."""
        lines = [f"{self.name}: {self.title or self.kind}",
                 f"  kind {self.kind}, controller {self.controller}, axes {''.join(self.axis_names)}"]
        for n, a in self.linear.items():
            lines.append(f"  {n}: {a.min:g} .. {a.max:g} mm, {a.max_velocity:g} mm/min, "
                         f"{a.max_acceleration:g} mm/s^2")
        for ax in (self.tilt, self.rotary):
            rng = "endless" if ax.continuous else f"{ax.min:g} .. {ax.max:g} deg"
            where = "table" if self.on_table(ax) else "head"
            lines.append(f"  {ax.name}: {where}, about {ax.about}, sign {ax.sign:+d}, {rng}, "
                         f"{ax.max_velocity:g} deg/min, {ax.max_acceleration:g} deg/s^2")
        if self.linuxcnc:
            pins = ", ".join(f"{k}={v}" for k, v in self.linuxcnc.items())
            lines.append(f"  linuxcnc: {pins}")
        lines.append(f"  tool length {self.tool_length:g} mm, safe Z {self.safe_z:g}, "
                     f"part origin {tuple(float(v) for v in self.part_origin)}")
        spindle = ("not checked" if self.spindle_range is None
                   else f"{self.spindle_range[0]:g} to {self.spindle_range[1]:g} rpm")
        lines.append(f"  largest feed {self.feed_limit:g} mm/min, spindle {spindle}")
        if self.path:
            lines.append(f"  file {self.path}")
        return "\n".join(lines)


# --- reading -------------------------------------------------------------------------------

class _Reader:
    """Typed access to a JSON object with errors naming the file and the key."""

    def __init__(self, path):
        self.path = path

    def fail(self, key, message):
        raise InputError(message, path=self.path, item=key)

    def obj(self, d, key):
        if not isinstance(d, dict):
            self.fail(key, "must be a JSON object")
        return d

    def check_keys(self, d, key, allowed, required=()):
        for k in d:
            if k not in allowed and k != "comment":
                k = k or '""'                       # an empty key still names itself
                self.fail(f"{key}.{k}" if key else k,
                          f"unknown key (allowed: {', '.join(sorted(allowed))})")
        for k in required:
            if k not in d:
                self.fail(f"{key}.{k}" if key else k, "missing")

    def num(self, d, key, name, default=None, positive=False, allow_none=False):
        full = f"{key}.{name}" if key else name
        if name not in d:
            if default is None and not allow_none:
                self.fail(full, "missing")
            return default
        v = d[name]
        if v is None and allow_none:
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.fail(full, f"must be a finite number, not {v!r}")
        if abs(v) > COORDINATE_LIMIT:
            self.fail(full, f"{v:g} is beyond +-{COORDINATE_LIMIT:g} (mm, degrees or per minute): "
                            f"no machine has that")
        if positive and not v >= MIN_RATE:
            self.fail(full, f"must be >= {MIN_RATE:g}, not {v!r}" + (" (> 0 but too small to divide by)"
                                                                    if v > 0 else ""))
        return float(v)

    def vec3(self, d, key, name, default=None):
        full = f"{key}.{name}" if key else name
        if name not in d:
            if default is None:
                self.fail(full, "missing")
            return tuple(default)
        v = d[name]
        if (not isinstance(v, list) or len(v) != 3
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                           and math.isfinite(x) and abs(x) <= COORDINATE_LIMIT for x in v)):
            self.fail(full, f"must be a list of three finite numbers (mm) within "
                            f"+-{COORDINATE_LIMIT:g}, not {v!r}")
        return tuple(float(x) for x in v)

    def choice(self, d, key, name, options, default=None):
        full = f"{key}.{name}" if key else name
        v = d.get(name, default)
        if v is None:
            self.fail(full, "missing")
        if v not in options:
            self.fail(full, f"must be one of {', '.join(map(str, options))}, not {v!r}")
        return v


def machine_from_dict(doc: dict, path: str | None = None) -> Machine:
    """Build and validate a :class:`Machine` from a parsed version-1 document."""
    r = _Reader(path)
    r.obj(doc, "(document)")
    if doc.get("format") != FORMAT:
        r.fail("format", f"must be {FORMAT!r}, not {doc.get('format')!r}")
    if doc.get("version") != VERSION:
        r.fail("version", f"version {doc.get('version')!r} is not supported (this tsplcam reads {VERSION})")
    r.check_keys(doc, "", {"format", "version", "name", "title", "kind", "controller", "linear_axes",
                           "rotary_axes", "linuxcnc", "tool_length", "safe_z", "part_origin", "post",
                           "max_feed", "spindle_range"},
                 required=("name", "kind", "controller", "linear_axes", "rotary_axes"))
    name = doc["name"]
    if not isinstance(name, str) or not name.strip():
        r.fail("name", "must be a non-empty string")
    kind = r.choice(doc, "", "kind", KINDS)
    controller = r.choice(doc, "", "controller", CONTROLLERS)

    lin_doc = r.obj(doc["linear_axes"], "linear_axes")
    r.check_keys(lin_doc, "linear_axes", set(LINEAR_NAMES), required=LINEAR_NAMES)
    linear = {}
    for n in LINEAR_NAMES:
        key = f"linear_axes.{n}"
        a = r.obj(lin_doc[n], key)
        r.check_keys(a, key, {"min", "max", "max_velocity", "max_acceleration"},
                     required=("min", "max", "max_velocity", "max_acceleration"))
        lo, hi = r.num(a, key, "min"), r.num(a, key, "max")
        if lo >= hi:
            r.fail(f"{key}.max", f"must be greater than min ({lo:g})")
        linear[n] = LinearAxis(n, lo, hi, r.num(a, key, "max_velocity", positive=True),
                               r.num(a, key, "max_acceleration", positive=True))

    lc = doc.get("linuxcnc")
    if lc is not None:
        r.obj(lc, "linuxcnc")
        kins = r.choice(lc, "linuxcnc", "kinematics", tuple(LINUXCNC_KINS))
        r.check_keys(lc, "linuxcnc", {"kinematics", *LINUXCNC_KINS[kins]},
                     required=("kinematics", *LINUXCNC_KINS[kins]))
        for pin in LINUXCNC_KINS[kins]:
            r.num(lc, "linuxcnc", pin)
        if lc["conventional-directions"] not in (0, 1):
            r.fail("linuxcnc.conventional-directions", "must be 0 or 1")
        if lc["tool-offset"] != 0:
            r.fail("linuxcnc.tool-offset",
                   "must be 0: LinuxCNC nets this pin to motion.tooloffset.z at run time and the "
                   "posted program applies the tool length with G43")
        if kind != "table-table":
            r.fail("linuxcnc.kinematics", f"{kins} is a table-table kinematics, kind is {kind!r}")

    rot_doc = r.obj(doc["rotary_axes"], "rotary_axes")
    if len(rot_doc) != 2:
        r.fail("rotary_axes", f"must name exactly two rotary axes, not {len(rot_doc)}")
    rotaries = []
    for n, a in rot_doc.items():
        key = f"rotary_axes.{n}"
        if n not in ("A", "B", "C"):
            r.fail(key, "rotary axes are named A, B or C")
        r.obj(a, key)
        allowed = {"about", "sign", "zero", "pivot", "min", "max", "continuous", "max_velocity",
                   "max_acceleration"}
        if lc is not None:
            allowed -= {"sign", "zero", "pivot"}
        r.check_keys(a, key, allowed, required=("about", "max_velocity", "max_acceleration"))
        about = r.choice(a, key, "about", LINEAR_NAMES)
        continuous = a.get("continuous", False)
        if not isinstance(continuous, bool):
            r.fail(f"{key}.continuous", "must be true or false")
        if continuous:
            if "min" in a or "max" in a:
                r.fail(f"{key}.continuous", "an endless axis has no min/max")
            lo = hi = None
        else:
            lo, hi = r.num(a, key, "min"), r.num(a, key, "max")
            if lo >= hi:
                r.fail(f"{key}.max", f"must be greater than min ({lo:g})")
        sign = a.get("sign", 1)
        if sign not in (1, -1) or isinstance(sign, bool):
            r.fail(f"{key}.sign", f"must be 1 or -1, not {sign!r}")
        rotaries.append(RotaryAxis(
            name=n, about=about, sign=int(sign), zero=r.num(a, key, "zero", default=0.0),
            pivot=r.vec3(a, key, "pivot", default=(0.0, 0.0, 0.0)), min=lo, max=hi,
            continuous=continuous,
            max_velocity=r.num(a, key, "max_velocity", positive=True),
            max_acceleration=r.num(a, key, "max_acceleration", positive=True)))
    rot = [ax for ax in rotaries if ax.about == "Z"]
    tilt = [ax for ax in rotaries if ax.about != "Z"]
    if len(rot) != 1 or len(tilt) != 1:
        r.fail("rotary_axes", "need one rotary axis about Z and one tilt axis about X or Y")
    rot, tilt = rot[0], tilt[0]
    if tilt.continuous:
        r.fail(f"rotary_axes.{tilt.name}.continuous", "a tilt axis needs min and max")

    if lc is not None:
        # Same numbers as the HAL pins (docs/post.md 2.1): C turns about the line through the
        # rot-point, the tilt axis about the line through rot-point + (x|y)-offset + z-offset;
        # unconventional directions (pin 0) turn the table by +value.
        xr, yr, zr = lc["x-rot-point"], lc["y-rot-point"], lc["z-rot-point"]
        want = "X" if lc["kinematics"] == "xyzac-trt-kins" else "Y"
        if tilt.about != want:
            r.fail(f"rotary_axes.{tilt.name}.about", f"{lc['kinematics']} tilts about {want}")
        dz = lc["z-offset"] + lc["tool-offset"]
        if want == "X":
            tilt.pivot = (float(xr), float(yr + lc["y-offset"]), float(zr + dz))
        else:
            tilt.pivot = (float(xr + lc["x-offset"]), float(yr), float(zr + dz))
        rot.pivot = (float(xr), float(yr), float(zr))
        s = -1 if lc["conventional-directions"] else 1
        tilt.sign = rot.sign = s
        tilt.zero = rot.zero = 0.0

    post = doc.get("post", {})
    r.obj(post, "post")
    for k in post:
        if k not in POST_KEYS and k != "comment":
            r.fail(f"post.{k}", f"unknown key (allowed: {', '.join(sorted(POST_KEYS))})")
    if "inverse_time" in post and not (isinstance(post["inverse_time"], bool) or post["inverse_time"] == "auto"):
        r.fail("post.inverse_time", f'must be true, false or "auto", not {post["inverse_time"]!r}')
    max_feed = r.num(doc, "", "max_feed", positive=True, allow_none=True)
    spindle_range = None
    if doc.get("spindle_range") is not None:
        v = doc["spindle_range"]
        if (not isinstance(v, list) or len(v) != 2 or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and 0 <= x <= 1e6
                for x in v) or v[0] >= v[1]):
            r.fail("spindle_range", f"must be [min, max] rpm with 0 <= min < max, not {v!r}")
        spindle_range = (float(v[0]), float(v[1]))
    title = doc.get("title", "")
    comment = doc.get("comment", "")
    machine = Machine(name=name.strip(), kind=kind, controller=controller, linear=linear, tilt=tilt,
                   rotary=rot, tool_length=r.num(doc, "", "tool_length", default=100.0),
                   safe_z=r.num(doc, "", "safe_z", default=linear["Z"].max),
                   part_origin=r.vec3(doc, "", "part_origin", default=(0.0, 0.0, 0.0)),
                   title=title if isinstance(title, str) else "",
                   comment=comment if isinstance(comment, str) else "",
                   post=dict(post), linuxcnc=dict(lc) if lc is not None else None, path=path,
                   max_feed=max_feed, spindle_range=spindle_range)
    for k in ("approach_feed", "link_feed", "retract_feed"):
        if isinstance(post.get(k), (int, float)) and not isinstance(post.get(k), bool):
            _refused(r, machine.check_feed, post[k], f"post.{k}")
    if isinstance(post.get("spindle"), (int, float)) and not isinstance(post.get("spindle"), bool):
        _refused(r, machine.check_spindle, post["spindle"], "post.spindle")
    return machine


def _refused(r: "_Reader", check, value, key: str) -> None:
    """A post default the machine's own limits refuse: an error naming the file and key."""
    try:
        check(value)
    except InputError as exc:
        r.fail(key, exc.message)


# Keys a machine's "post" section may set (defaults for post_program's options).
POST_KEYS = {"dialect", "tool", "spindle", "coolant", "approach_distance", "approach_height_max",
             "approach_feed", "link_feed", "retract_feed", "inverse_time", "orientation", "tcp",
             "refpnt", "decimals", "linear_tolerance", "singular_cone", "swing_limit",
             "blend_tolerance", "program_name", "program_number", "inverse_time_max", "work_offset"}


def read_machine(path: str) -> Machine:
    """Read a machine file; errors name the file and the key (or the JSON line)."""
    doc, _ = read_json(path, "machine file")
    return machine_from_dict(doc, path)


def machine_dirs() -> list:
    """Folders searched for machines by name, user folders first."""
    dirs = [d for d in os.environ.get("TSPLCAM_MACHINE_PATH", "").split(os.pathsep) if d]
    return dirs + [shipped_dir()]


def machine_files() -> dict:
    """name (file stem) -> path of every machine found, the first folder winning."""
    found = {}
    for d in machine_dirs():
        if not os.path.isdir(d):
            continue
        for fn in sorted(os.listdir(d)):
            if fn.endswith(".json"):
                found.setdefault(fn[:-5], os.path.join(d, fn))
    return found


def load_machine(name_or_path) -> Machine:
    """A :class:`Machine` given as itself, a known name, or a path to a machine file."""
    if isinstance(name_or_path, Machine):
        return name_or_path
    s = str(name_or_path)
    if s.endswith(".json") or os.sep in s:
        return read_machine(s)
    files = machine_files()
    if s not in files:
        raise InputError(f"unknown machine {s!r}; known: {', '.join(sorted(files)) or 'none'}"
                         f" (or give a path to a .json machine file)", item="--machine")
    return read_machine(files[s])
