"""Ball-end tool model: ball, flutes, shank and a holder of cylinders and cones.

Read from a ``tsplcam-tool`` JSON file (schema in ``tsplcam/orientation/TOOLS.md``) or from
a FreeCAD CAM ball-end tool bit (``.fctb``, ``"shape": "ballend.fcstd"``, parameters
``Diameter``, ``CuttingEdgeHeight``, ``Length``, ``ShankDiameter`` as unit strings). Units
are mm inside. Lengths along the tool are measured from the tool tip upward.

The tool is rotationally symmetric; its solid above the ball centre is described by a
*profile*: a list of frustums (z0, z1, radius0, radius1) in the tool frame whose origin is
the ball centre and whose +z is the tool axis (tip -> spindle).
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

from .. import data_dir
from ..errors import InputError
from ..inputfile import excerpt, read_json

FORMAT = "tsplcam-tool"
VERSION = 1
# mm: every length of a tool and its holder lies in [MIN_LENGTH, MAX_LENGTH): a micron to
# 100 m (a length of 1e-320 passed "> 0" and left a holder segment of zero height)
MIN_LENGTH, MAX_LENGTH = 1e-3, 1e5


@dataclass(frozen=True)
class HolderSegment:
    """One piece of the holder, stacked upward from the holder face: a cylinder
    (``diameter_bottom == diameter_top``) or a cone frustum."""
    length: float
    diameter_bottom: float
    diameter_top: float

    @property
    def kind(self) -> str:
        return "cylinder" if self.diameter_bottom == self.diameter_top else "cone"


@dataclass(frozen=True)
class ToolPart:
    """A solid of revolution about the tool axis between heights z0 < z1 above the ball
    centre, radius r0 at z0 and r1 at z1; ``name`` says which part of the tool it is."""
    name: str
    z0: float
    z1: float
    r0: float
    r1: float


@dataclass
class Tool:
    """A ball-end mill in its holder (mm).

    ``flute_length``: cutting length from the tip; ``shank_length``: stick-out from the tip
    to the holder face (the shank runs from the end of the flutes to there);
    ``holder``: segments stacked from the holder face upward.
    """
    name: str
    ball_radius: float
    flute_length: float
    shank_diameter: float
    shank_length: float
    holder: list = field(default_factory=list)
    source: str | None = None
    comment: str = ""

    def __post_init__(self):
        self.holder = [h if isinstance(h, HolderSegment) else HolderSegment(*h) for h in self.holder]
        where = self.source
        r, lf, ds, ls = self.ball_radius, self.flute_length, self.shank_diameter, self.shank_length
        for key, val in (("ball_radius", r), ("flute_length", lf), ("shank_diameter", ds),
                         ("shank_length", ls)):
            if not (isinstance(val, (int, float)) and MIN_LENGTH <= val < MAX_LENGTH):  # NaN fails
                raise InputError(f"{key} must be a length in mm in [{MIN_LENGTH:g}, {MAX_LENGTH:g}), "
                                 f"not {val!r}", path=where, item=key)
        if lf < r:
            raise InputError(f"flute_length {lf:g} is shorter than the ball radius {r:g}", path=where,
                             item="flute_length")
        if ls < lf:
            raise InputError(f"shank_length (stick-out) {ls:g} is shorter than flute_length {lf:g}",
                             path=where, item="shank_length")
        for k, h in enumerate(self.holder):
            if not all(MIN_LENGTH <= x < MAX_LENGTH for x in (h.length, h.diameter_bottom, h.diameter_top)):
                raise InputError(f"holder segment {k + 1}: length and diameters must be lengths in "
                                 f"[{MIN_LENGTH:g}, {MAX_LENGTH:g}) mm", path=where, item=f"holder[{k}]")

    # --- geometry ---------------------------------------------------------------------
    @property
    def radius(self) -> float:
        return self.ball_radius

    @property
    def length(self) -> float:
        """Tip to the top of the holder (mm)."""
        return self.shank_length + sum(h.length for h in self.holder)

    def parts(self) -> list:
        """The solids above the ball centre (tool frame, origin at the ball centre):
        flutes (radius = ball radius) from the centre to the end of the flutes, the shank,
        then every holder segment."""
        r = self.ball_radius
        out = []
        z = 0.0
        if self.flute_length > r:
            out.append(ToolPart("flutes", 0.0, self.flute_length - r, r, r))
            z = self.flute_length - r
        rs = 0.5 * self.shank_diameter
        if self.shank_length - r > z:
            out.append(ToolPart("shank", z, self.shank_length - r, rs, rs))
            z = self.shank_length - r
        for k, h in enumerate(self.holder):
            name = "holder" if len(self.holder) == 1 else f"holder {k + 1}"
            out.append(ToolPart(name, z, z + h.length, 0.5 * h.diameter_bottom, 0.5 * h.diameter_top))
            z += h.length
        return out

    def exposed_ends(self) -> list:
        """Per part of :meth:`parts`: (bottom, top), whether that end face is the tool's
        surface: a bottom lies on the solid below (the ball for the first part) and a top
        under the part above; an end as narrow as its neighbour or narrower is covered by it
        (a shank's bottom on flutes as wide, the flutes' on the ball)."""
        parts = self.parts()
        out = []
        for k, p in enumerate(parts):
            below = parts[k - 1].r1 if k else self.ball_radius
            above = parts[k + 1].r0 if k + 1 < len(parts) else 0.0
            out.append((below < p.r0 - 1e-12, above < p.r1 - 1e-12))
        return out

    def max_radius(self) -> float:
        return max([self.ball_radius] + [max(p.r0, p.r1) for p in self.parts()])

    def to_dict(self) -> dict:
        return {"format": FORMAT, "version": VERSION, "name": self.name, "units": "mm",
                "ball_radius": self.ball_radius, "flute_length": self.flute_length,
                "shank_diameter": self.shank_diameter, "shank_length": self.shank_length,
                "holder": [{"type": h.kind, "length": h.length,
                            **({"diameter": h.diameter_bottom} if h.kind == "cylinder" else
                               {"diameter_bottom": h.diameter_bottom, "diameter_top": h.diameter_top})}
                           for h in self.holder],
                **({"comment": self.comment} if self.comment else {})}

    def summary(self) -> str:
        hold = ", ".join(f"{h.kind} {h.length:g} mm x "
                         + (f"d{h.diameter_bottom:g}" if h.kind == "cylinder"
                            else f"d{h.diameter_bottom:g}->d{h.diameter_top:g}") for h in self.holder)
        return (f"{self.name}: ball R{self.ball_radius:g}, flutes {self.flute_length:g}, shank "
                f"d{self.shank_diameter:g} stick-out {self.shank_length:g}, holder [{hold or 'none'}]")


# --- reading -------------------------------------------------------------------------------

_UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, '"': 25.4, "inch": 25.4, "um": 1e-3}


def parse_length(text, path: str | None = None, key: str | None = None) -> float:
    """A FreeCAD quantity string ("6.0000 mm", "0.25 in", "1/8 in") or a number, in mm."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return float(text)
    if not isinstance(text, str):
        raise InputError(f"expected a length such as '6 mm', found {text!r}", path=path, item=key)
    m = re.fullmatch(r"\s*([-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)(?:\s*/\s*(\d+(?:\.\d*)?))?\s*"
                     r"(mm|cm|m|in|inch|\"|um)?\s*", text)
    if not m:
        raise InputError(f"cannot read the length {excerpt(text)}", path=path, item=key)
    value = float(m.group(1))
    if m.group(2):
        if float(m.group(2)) == 0.0:              # exact: only a literal zero divides by zero
            raise InputError(f"the length {excerpt(text)} divides by zero", path=path, item=key)
        value /= float(m.group(2))
    return value * _UNITS[m.group(3) or "mm"]


def _number(d: dict, key: str, path, required=True, default=None):
    if key not in d:
        if required:
            raise InputError(f"missing key '{key}'", path=path, item=key)
        return default
    val = d[key]
    if isinstance(val, bool) or not isinstance(val, (int, float, str)):
        raise InputError(f"'{key}' must be a number (mm), found {val!r}", path=path, item=key)
    return parse_length(val, path, key)


def _holder(items, path) -> list:
    if not isinstance(items, list):
        raise InputError("'holder' must be a list of segments", path=path, item="holder")
    out = []
    for k, h in enumerate(items):
        item = f"holder[{k}]"
        if not isinstance(h, dict):
            raise InputError("a holder segment must be an object", path=path, item=item)
        kind = h.get("type", "cylinder")
        length = _number(h, "length", path)
        if kind == "cylinder":
            if "diameter" not in h:
                raise InputError("missing key 'diameter'", path=path, item=item)
            d = _number(h, "diameter", path)
            out.append(HolderSegment(length, d, d))
        elif kind == "cone":
            for key in ("diameter_bottom", "diameter_top"):
                if key not in h:
                    raise InputError(f"missing key '{key}'", path=path, item=item)
            out.append(HolderSegment(length, _number(h, "diameter_bottom", path),
                                     _number(h, "diameter_top", path)))
        else:
            raise InputError(f"unknown holder segment type {kind!r} (cylinder or cone)", path=path,
                             item=item)
    return out


def read_fctb(path: str, holder=None, name: str | None = None) -> Tool:
    """A FreeCAD CAM ball-end tool bit (.fctb). The file has no holder: pass ``holder``
    (HolderSegments) or the tool is checked without one (only flutes and shank)."""
    doc = read_json(path, "tool bit")[0]
    if not isinstance(doc, dict):
        raise InputError("a tool bit file holds one JSON object", path=path, item="(document)")
    shape = str(doc.get("shape", ""))
    if os.path.basename(shape).lower() not in ("ballend.fcstd", "ballend"):
        raise InputError(f"shape {shape!r} is not a ball end (ballend.fcstd): tsplcam finishes with "
                         "ball-end mills", path=path, item="shape")
    par = doc.get("parameter")
    if not isinstance(par, dict):
        raise InputError("missing key 'parameter'", path=path, item="parameter")

    def get(key, required=True):
        if key not in par:
            if required:
                raise InputError(f"missing key 'parameter.{key}'", path=path, item=f"parameter.{key}")
            return None
        return parse_length(par[key], path, f"parameter.{key}")

    d = get("Diameter")
    lf = get("CuttingEdgeHeight")
    length = get("Length")
    ds = get("ShankDiameter", required=False) or d
    return Tool(name=name or str(doc.get("name", os.path.basename(path))), ball_radius=0.5 * d,
                flute_length=lf, shank_diameter=ds, shank_length=length,
                holder=list(holder or []), source=path)


def read_tool(path: str) -> Tool:
    """A ``tsplcam-tool`` JSON file (see TOOLS.md) or a FreeCAD ``.fctb`` tool bit."""
    if path.lower().endswith(".fctb"):
        return read_fctb(path)
    return tool_from_dict(read_json(path, "tool file")[0], path)


def tool_from_dict(doc, path: str | None = None) -> Tool:
    if not isinstance(doc, dict):
        raise InputError("a tool file holds one JSON object", path=path, item="(document)")
    if doc.get("format") != FORMAT:
        raise InputError(f"'format' must be {FORMAT!r}, found {doc.get('format')!r}", path=path,
                         item="format")
    if doc.get("version") != VERSION:
        raise InputError(f"unsupported version {doc.get('version')!r} (this reader knows {VERSION})",
                         path=path, item="version")
    if doc.get("units", "mm") != "mm":
        raise InputError(f"'units' must be 'mm', found {doc.get('units')!r}", path=path,
                         item="units")
    holder = _holder(doc.get("holder", []), path)
    name = str(doc.get("name", os.path.splitext(os.path.basename(path or "tool"))[0]))
    if "fctb" in doc:
        fctb = doc["fctb"]
        if not isinstance(fctb, str) or not fctb.strip():
            raise InputError(f"'fctb' must name a FreeCAD tool bit file, not {fctb!r}", path=path,
                             item="fctb")
        if path is not None and not os.path.isabs(fctb):
            fctb = os.path.join(os.path.dirname(path), fctb)
        if not os.path.isfile(fctb):
            raise InputError(f"'fctb' names {fctb!r}, which is not a file (a relative name is "
                             f"read beside the tool file)", path=path, item="fctb")
        tool = read_fctb(fctb, holder, name)
        tool.source = path
        return tool
    return Tool(name=name, ball_radius=_number(doc, "ball_radius", path),
                flute_length=_number(doc, "flute_length", path),
                shank_diameter=_number(doc, "shank_diameter", path),
                shank_length=_number(doc, "shank_length", path), holder=holder, source=path,
                comment=str(doc.get("comment", "")))


def shipped_tools_dir() -> str:
    return os.path.join(data_dir(), "tools")


def load_tool(name_or_path: str) -> Tool:
    """A tool by shipped name (``tsplcam/data/tools/NAME.json``) or by path."""
    if os.path.exists(name_or_path):
        return read_tool(name_or_path)
    path = os.path.join(shipped_tools_dir(), name_or_path + ".json")
    if os.path.exists(path):
        return read_tool(path)
    names = sorted(os.path.splitext(f)[0] for f in os.listdir(shipped_tools_dir()) if f.endswith(".json"))
    raise InputError(f"no tool file {name_or_path!r} (shipped tools: {', '.join(names)})")
