"""APT-style CL data: the tool path as tool tips and tool axes (``GOTO/x,y,z,i,j,k``).

The format, for people and other CAM tools, is documented in ``CLDATA.md`` beside this
file. One writer (:func:`write_cl`, :func:`cl_text`) and one reader (:func:`read_cl`,
:func:`parse_cl`). Output is deterministic: the same path gives the same bytes.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from .. import __version__
from ..errors import InputError
from ..numtext import fmt_col
from .path import Move, ToolPath

FORMAT_VERSION = 1
COLUMNS = 72                     # APT records end before column 73; longer ones continue with $
XYZ_DECIMALS = 5
IJK_DECIMALS = 7
APPROACH, RETREAT = -1, -2       # kinds of the file's own first and last moves (not path points)
_KIND_NAMES = {Move.CUT: "CUT", Move.LINK: "LINK", Move.RETRACT: "RETRACT", Move.RAPID: "RAPID",
               APPROACH: "APPROACH", RETREAT: "RETREAT"}
_NAME_KINDS = {v: k for k, v in _KIND_NAMES.items()}


def _num(v: float, decimals: int) -> str:
    s = f"{v:.{decimals}f}"
    return s[1:] if s.startswith("-") and float(s) == 0.0 else s


def _gotos(tip: np.ndarray, axis: np.ndarray) -> list[str]:
    """The GOTO records of tips and axes, each as its lines (wrapped at COLUMNS) joined by
    newlines; numbers as :func:`_num` writes them, formatted a column at a time."""
    cols = [fmt_col(tip[:, c], XYZ_DECIMALS) for c in range(3)] + \
           [fmt_col(axis[:, c], IJK_DECIMALS) for c in range(3)]
    out = [f"GOTO/{x},{y},{z},{i},{j},{k}" for x, y, z, i, j, k in zip(*cols)]
    for n, text in enumerate(out):
        if len(text) > COLUMNS:
            out[n] = "\n".join(_wrap(text))
    return out


def _wrap(record: str) -> list[str]:
    """Split a record longer than COLUMNS after commas, ending continued lines with '$'."""
    out = []
    while len(record) > COLUMNS:
        cut = record.rfind(",", 0, COLUMNS - 1)
        if cut <= 0:
            break
        out.append(record[:cut + 1] + "$")
        record = record[cut + 1:]
    out.append(record)
    return out


def _comment(text: str) -> list[str]:
    """'$$ ' comment lines of at most COLUMNS characters (broken at spaces)."""
    out, cur = [], "$$"
    for word in text.split():
        if len(cur) + 1 + len(word) > COLUMNS and cur != "$$":
            out.append(cur)
            cur = "$$"
        cur = (cur + " " + word)[:COLUMNS]
    out.append(cur)
    return out


def _partno(name: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_.\- ]", "_", name or "TSPLCAM").strip().upper()
    return (s or "TSPLCAM")[:60]


def cl_text(path: ToolPath, partno: str | None = None, approach: float = 5.0,
            comments: list[str] | None = None) -> str:
    """The CL data of ``path`` as text. ``approach`` (mm, > 0) adds a RAPID to that distance
    above the first point along its tool axis before it and a retreat as far along the last
    axis after the last point (kinds APPROACH and RETREAT; 0 leaves them out)."""
    n = len(path)
    if n == 0:
        raise InputError("the tool path has no points")
    tip, axis = path.tip, path.axis / np.linalg.norm(path.axis, axis=1, keepdims=True)
    if not (np.all(np.isfinite(tip)) and np.all(np.isfinite(axis))):
        raise InputError("the tool path has a point or axis that is not a finite number")
    r = float(path.tool_radius)
    name = partno or str(path.info.get("model") or "tsplcam")
    s = path.info.get("settings", {})
    notes = [f"tsplcam {__version__} CL data, format version {FORMAT_VERSION} (tsplcam/toolpath/CLDATA.md)",
             f"model {name}: {n} path points, ball radius {r:g} mm"
             + (f", scallop {s['scallop']:g} mm, chord tolerance {s['chord_tol']:g} mm" if s else ""),
             "GOTO/x,y,z,i,j,k = tool tip (mm) and unit tool axis tip->spindle", *(comments or [])]
    lines = [ln for note in notes for ln in _comment(note)]
    lines += [f"PARTNO/{_partno(name)}", "UNITS/MM", "MULTAX/ON",
              f"CUTTER/{_num(2 * r, XYZ_DECIMALS)},{_num(r, XYZ_DECIMALS)}"]

    gotos = _gotos(tip, axis)
    fed = f"FEDRAT/MMPM,{_num(float(path.feed), 4)}"
    if approach and approach > 0:
        lines += ["$$ MOVE/APPROACH", "RAPID", _gotos(tip[:1] + approach * axis[:1], axis[:1])[0]]
    lines.append(fed)
    # the markers before each point: its move kind where it changes, its patch and line where
    # they change (or follow a point with none), RAPID before a rapid move
    move = np.array(path.move, dtype=np.int64)
    if approach and approach > 0:
        move[0] = int(Move.LINK)
    patch, line = np.asarray(path.patch, np.int64), np.asarray(path.line, np.int64)
    valid = (patch >= 0) & (line >= 0)
    new_kind = np.ones(n, bool)
    new_kind[1:] = move[1:] != move[:-1]
    new_mark = valid.copy()
    new_mark[1:] &= ~valid[:-1] | (patch[1:] != patch[:-1]) | (line[1:] != line[:-1])
    rapid = move == int(Move.RAPID)
    for i in np.flatnonzero(new_kind | new_mark | rapid).tolist():
        k = int(move[i])
        head = [f"$$ MOVE/{_KIND_NAMES.get(k, str(k))}"] if new_kind[i] else []
        if new_mark[i]:
            head.append(f"$$ PATCH/{int(patch[i])},LINE/{int(line[i])}")
        if rapid[i]:
            head.append("RAPID")
        gotos[i] = "\n".join(head + [gotos[i]])
    lines += gotos
    if approach and approach > 0:
        lines += ["$$ MOVE/RETREAT", _gotos(tip[-1:] + approach * axis[-1:], axis[-1:])[0]]
    lines.append("FINI")
    return "\n".join(lines) + "\n"


def write_cl(path: ToolPath, filename, partno: str | None = None, approach: float = 5.0,
             comments: list[str] | None = None) -> None:
    from ..outfile import write_text
    write_text(filename, cl_text(path, partno, approach, comments), encoding="ascii", what="CL file")


@dataclass
class CLData:
    """What a CL file says, one row per GOTO."""
    tip: np.ndarray              # (n, 3) mm
    axis: np.ndarray             # (n, 3) unit
    kind: np.ndarray             # (n,) int: Move value, or APPROACH / RETREAT
    rapid: np.ndarray            # (n,) bool: the GOTO followed a RAPID
    feed: np.ndarray             # (n,) mm/min in force (nan before any FEDRAT)
    patch: np.ndarray            # (n,) int, -1 where no PATCH marker applies
    line: np.ndarray             # (n,) int, -1 likewise
    cutter: tuple = ()           # the CUTTER parameters (diameter, corner radius, ...)
    units: str = "MM"
    partno: str = ""
    ignored: list = field(default_factory=list)   # (line number, major word) not interpreted

    def __len__(self) -> int:
        return len(self.tip)

    @property
    def tool_radius(self) -> float:
        return float(self.cutter[1]) if len(self.cutter) > 1 else float(self.cutter[0]) / 2

    def to_toolpath(self) -> ToolPath:
        """The path points (approach and retreat left out) as a ToolPath. CL data hold tips
        and axes only: the normal is set to the axis, so the ball centre and the tip are the
        file's while ``contact`` is the tip."""
        keep = self.kind >= 0
        n = int(keep.sum())
        r = self.tool_radius
        feed = self.feed[keep & (self.kind == Move.CUT)]
        return ToolPath(contact=self.tip[keep], normal=self.axis[keep], axis=self.axis[keep],
                        move=self.kind[keep], patch=self.patch[keep],
                        uv=np.full((n, 2), np.nan), line=self.line[keep], tool_radius=r,
                        feed=float(feed[0]) if len(feed) and np.isfinite(feed[0]) else 1000.0,
                        info={"source": "CL data", "partno": self.partno})


_MARK = re.compile(r"^\$\$\s*(MOVE|PATCH)/(.*)$")


def parse_cl(text: str, path: str | None = None) -> CLData:
    """Read CL data (the subset CLDATA.md lists; other major words are skipped and listed in
    ``ignored``). Errors name the file and line."""
    records = []                 # (line number, record)
    pending, start = "", None
    for no, raw in enumerate(text.splitlines(), 1):
        s = raw.strip()
        if not s:
            continue
        if s.startswith("$$"):
            if not pending:
                records.append((no, s))
            continue
        if start is None:
            start = no
        if s.endswith("$"):
            pending += s[:-1]
            continue
        records.append((start, pending + s))
        pending, start = "", None
    if pending:
        raise InputError("the last record is continued ('$') but the file ends", path=path, line=start)
    tips, axes, kinds, rapids, feeds, patches, lines_ = [], [], [], [], [], [], []
    cutter, units, partno, ignored = (), "MM", "", []
    kind, rapid_next, feed = int(Move.CUT), False, np.nan
    patch, line = -1, -1
    last_axis = np.array([0.0, 0.0, 1.0])
    finished = False
    for no, rec in records:
        m = _MARK.match(rec)
        if m:
            if m.group(1) == "MOVE":
                name = m.group(2).strip().upper()
                if name not in _NAME_KINDS:
                    raise InputError(f"unknown move kind {name!r}", path=path, line=no)
                kind = _NAME_KINDS[name]
                if kind in (Move.RETRACT, Move.RAPID, APPROACH, RETREAT):
                    patch, line = -1, -1
            else:
                mm = re.match(r"^\s*(-?\d+)\s*,\s*LINE\s*/\s*(-?\d+)\s*$", m.group(2))
                if not mm:
                    raise InputError(f"bad PATCH marker {rec!r}", path=path, line=no)
                patch, line = int(mm.group(1)), int(mm.group(2))
            continue
        if rec.startswith("$$"):
            continue
        if finished:
            raise InputError("a record after FINI", path=path, line=no)
        word, _, rest = rec.partition("/")
        word = word.strip().upper()
        args = [a.strip() for a in rest.split(",")] if rest.strip() else []

        def numbers(count=None):
            try:
                vals = [float(a) for a in args]
            except ValueError:
                raise InputError(f"{word}: {rest.strip()!r} is not a list of numbers", path=path,
                                 line=no) from None
            if count is not None and len(vals) not in count:
                raise InputError(f"{word} needs {' or '.join(map(str, count))} numbers, not {len(vals)}",
                                 path=path, line=no)
            if not all(np.isfinite(vals)):
                raise InputError(f"{word}: a value is not a finite number", path=path, line=no)
            return vals

        if word == "GOTO":
            v = numbers((3, 6))
            a = np.array(v[3:]) if len(v) == 6 else last_axis
            na = float(np.linalg.norm(a))
            if na < 1e-9:
                raise InputError("GOTO: the tool axis (i, j, k) is zero", path=path, line=no)
            a = a / na
            last_axis = a
            tips.append(v[:3]), axes.append(a), kinds.append(kind), rapids.append(rapid_next)
            feeds.append(feed), patches.append(patch if kind >= 0 else -1)
            lines_.append(line if kind >= 0 else -1)
            rapid_next = False
        elif word == "RAPID":
            rapid_next = True
        elif word == "FEDRAT":
            vals = [a for a in args if a.upper() not in ("MMPM", "IPM", "MMPR", "IPR")]
            if any(a.upper() in ("IPM", "IPR", "MMPR") for a in args):
                raise InputError("FEDRAT: only MMPM (mm per minute) is read", path=path, line=no)
            try:
                feed = float(vals[0])
            except (ValueError, IndexError):
                raise InputError(f"FEDRAT: no feed value in {rest.strip()!r}", path=path, line=no) from None
        elif word == "UNITS":
            units = rest.strip().upper()
            if units != "MM":
                raise InputError(f"UNITS/{units}: only UNITS/MM is read", path=path, line=no)
        elif word == "CUTTER":
            cutter = tuple(numbers())
            if not cutter or cutter[0] <= 0:
                raise InputError("CUTTER needs a positive diameter", path=path, line=no)
        elif word == "PARTNO":
            partno = rest.strip()
        elif word == "MULTAX":
            pass
        elif word == "FINI":
            finished = True
        else:
            ignored.append((no, word))
    if not tips:
        raise InputError("no GOTO record", path=path)
    if not cutter:
        raise InputError("no CUTTER record (the ball radius is needed)", path=path)
    return CLData(np.array(tips, float), np.array(axes, float), np.array(kinds, int),
                  np.array(rapids, bool), np.array(feeds, float), np.array(patches, int),
                  np.array(lines_, int), cutter, units, partno, ignored)


def read_cl(filename) -> CLData:
    try:
        with open(filename, encoding="ascii", errors="replace") as fh:
            text = fh.read()
    except OSError as exc:
        raise InputError(f"cannot read the CL file: {exc.strerror}", path=str(filename)) from None
    return parse_cl(text, str(filename))
