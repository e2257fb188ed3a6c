"""Controller dialects: one module per control, each with a writer and a reader.

A writer turns a :class:`Job` (the machine, the resolved settings and the motion rows) into
program text; the text depends only on its input (no dates, no machine-dependent
formatting), so the same input gives the same bytes. A reader parses the motion blocks of
that dialect back into :class:`ReadMove` rows, so tests can check a program from its text
alone: :func:`pose_of` turns a read move into tool tip and axis through the machine's
kinematics.
"""
from __future__ import annotations

import importlib
import re
from dataclasses import dataclass, field

import numpy as np

from ...errors import InputError
from ...numtext import fmt_col  # noqa: F401 (the writers' column formatter, shared with the CL data)

NAMES = ("heidenhain", "sinumerik", "fanuc", "linuxcnc")
# the file name extension each control expects for a program
EXTENSIONS = {"heidenhain": ".h", "sinumerik": ".mpf", "fanuc": ".nc", "linuxcnc": ".ngc"}


def extension(name: str) -> str:
    """File name extension of a program in dialect ``name`` (.nc when unknown)."""
    return EXTENSIONS.get(name, ".nc")


def get(name: str):
    """The dialect module called ``name``."""
    if name not in NAMES:
        raise InputError(f"unknown post dialect {name!r}; known: {', '.join(NAMES)}", item="--post")
    return importlib.import_module(f"{__name__}.{name}")


@dataclass
class Motion:
    """Program motion rows in program order (the block arriving at each row).

    ``tip``/``axis``: tool tip and axis the row commands (part frame); ``joints``: machine
    axes (mm, deg); ``rapid``: G0-type row; ``feed``: path feed (mm/min) of feed rows;
    ``inverse_time``: 1/min of feed rows (G93); ``source``: index into the tool path
    (fractional for inserted rows, -1 approach, -2 retract); ``move``: tsplcam Move of the
    source point or -1 (approach) / -2 (retract).
    """
    tip: np.ndarray
    axis: np.ndarray
    joints: np.ndarray
    rapid: np.ndarray
    feed: np.ndarray
    inverse_time: np.ndarray
    source: np.ndarray
    move: np.ndarray

    def __len__(self):
        return len(self.tip)


@dataclass
class Job:
    """Everything a writer needs."""
    machine: object
    settings: dict
    motion: Motion
    header: list
    preposition: tuple           # (tilt, rotary) values before TCP / tool length is switched on
    blank: tuple                 # ((xmin, ymin, zmin), (xmax, ymax, zmax)) of the path, for BLK FORM
    tool_radius: float = 0.0


@dataclass
class ReadMove:
    """A motion block read back from program text."""
    line: int                    # 1-based line of the program
    rapid: bool
    program: bool                # in part (TCP) or joint coordinates, not a machine-coordinate move
    words: dict = field(default_factory=dict)   # axis letter / vector word -> value (modal values filled)
    feed: float | None = None
    inverse_time: bool = False


# --- number formatting ---------------------------------------------------------------------

def fmt(value: float, decimals: int, plus: bool = False) -> str:
    """Fixed decimals, no negative zero, optional explicit '+' (Heidenhain)."""
    s = f"{value:.{decimals}f}"
    if s.startswith("-") and not s.strip("-0."):
        s = s[1:]
    if plus and not s.startswith("-"):
        s = "+" + s
    return s


def fmt_feed(value: float, decimals: int = 3) -> str:
    """A feed with trailing zeros dropped (F1000, F237.5)."""
    s = f"{value:.{decimals}f}"
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return s


def fmt_feeds(values, floor: float, decimals: int) -> list:
    """``fmt_feed(max(v, floor), decimals)`` over an array, each distinct value formatted
    once (a path's feeds are a few values)."""
    seen: dict = {}
    out = []
    for v in np.asarray(values, float).tolist():
        t = seen.get(v)
        if t is None:
            t = seen[v] = fmt_feed(max(v, floor), decimals)
        out.append(t)
    return out


def spindle_coolant(s: dict) -> tuple[list, str | None]:
    """The spindle start (S... M3) and coolant (M8 flood, M7 mist) lines of an ISO program,
    and the coolant word (for its M9 at the end), from the post settings."""
    out = []
    if s.get("spindle"):
        out.append(f"S{fmt_feed(s['spindle'], 1)} M3")
    cool = {"flood": "M8", "mist": "M7"}.get(s.get("coolant"))
    if cool:
        out.append(cool)
    return out, cool


def tcp_columns(job) -> tuple[list, list, bool]:
    """Formatted tip columns (X, Y, Z) and orientation columns: the tool axis vector
    (orientation "vector") or the two rotary angles, for the dialects that program the
    tool tip with TCP on (Fanuc, Sinumerik, Heidenhain)."""
    s, mo = job.settings, job.motion
    dl, da, dv = (s["decimals"][k] for k in ("linear", "angle", "vector"))
    vector = s["orientation"] == "vector"
    xyz = [fmt_col(mo.tip[:, k], dl) for k in range(3)]
    ori = ([fmt_col(mo.axis[:, k], dv) for k in range(3)] if vector
           else [fmt_col(mo.joints[:, k], da) for k in (3, 4)])
    return xyz, ori, vector


def iso_motion(mo, words, inverse_time: bool, feed_decimals: int, first: str = "") -> list:
    """G0/G1 blocks of an ISO program: ``words[i]`` is block i's coordinates; ``first`` goes
    before the first block's words (e.g. Fanuc's G43.4 H1). Inverse time (G93, F on every
    block, docs/post.md section 3.4) or modal F per minute; G94 restored at the end."""
    out, mode, last_f = [], None, None
    rapid = mo.rapid.tolist()
    feeds = fmt_col(mo.inverse_time, feed_decimals) if inverse_time else fmt_feeds(mo.feed, 1.0, 3)
    for i in range(len(mo)):
        lead = first if i == 0 else ""
        if rapid[i]:
            out.append(f"G0 {lead}{words[i]}")
            continue
        if inverse_time:
            pre = "G93 " if mode != "G93" else ""
            mode = "G93"
            out.append(f"{pre}G1 {lead}{words[i]} F{feeds[i]}")
        else:
            f = feeds[i]
            out.append(f"G1 {lead}{words[i]}" + (f" F{f}" if f != last_f else ""))
            last_f = f
    if mode == "G93":
        out.append("G94")
    return out


def clean_comment(text: str, forbid: str = "()") -> str:
    """Comment text safe for the dialect: printable ASCII, no characters it forbids."""
    out = "".join(ch if 32 <= ord(ch) < 127 and ch not in forbid else " " for ch in text)
    return re.sub(r"\s+", " ", out).strip()


# --- reading -------------------------------------------------------------------------------

NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)"


def words(line: str, pattern=re.compile(r"([A-Z]+\d(?==)|[A-Z]+)\s*=?\s*(" + NUMBER + r")")) -> list:
    """(address, value) pairs of a block, e.g. 'G1 X1.5 A3=0.25' -> [('G', 1.0), ...]."""
    return [(a, float(v)) for a, v in pattern.findall(line.upper())]


def pose_of(machine, move: ReadMove, settings: dict, joint_space: bool):
    """Tool tip and unit axis (part frame) a read move commands, via the kinematics."""
    tip, axis = _poses(machine, [move], settings, joint_space)
    return tip[0], axis[0]


def poses(machine, moves, settings: dict, joint_space: bool):
    """Tips (m,3) and axes (m,3) of the program moves among ``moves``: :func:`pose_of` of
    every move, the kinematics asked once for all rows (a call per move costs a hundred
    times more)."""
    sel = [mv for mv in moves if mv.program]
    if not sel:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return _poses(machine, sel, settings, joint_space)


def _poses(machine, sel: list, settings: dict, joint_space: bool):
    """Tips and unit axes of the read moves ``sel`` (at least one), one kinematics call."""
    from ..kinematics import forward, orientation
    names = machine.axis_names

    def table(keys):
        return np.array([[mv.words.get(n, 0.0) for n in keys] for mv in sel], float).reshape(len(sel), len(keys))

    if joint_space:
        return forward(machine, table(names), tool_length=settings.get("tool_length"),
                       part_origin=settings.get("part_origin"))
    tip = table("XYZ")
    vec = settings.get("vector_words")
    if settings.get("orientation") == "vector" and vec:
        axis = table(vec)
        axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    else:
        angles = table(names[3:5])
        axis = orientation(machine, angles[:, 0], angles[:, 1])
    if settings.get("point") == "center":
        tip = tip - settings.get("tool_radius", 0.0) * axis
    return tip, axis
