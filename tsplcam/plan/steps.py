"""Processing steps, pins and the processing list (shang2020 section 3.3).

A *step* machines one patch with an isoparametric zigzag: (patch, start corner, finish
corner, crossfeed direction). Corners follow :mod:`tsplcam.layout.layout`: 0 lower-left
(u,v) = (0,0), 1 lower-right (1,0), 2 upper-right (1,1), 3 upper-left (0,1).

Which (start, finish, crossfeed) triples a zigzag can realise (section 3.5): crossfeed
``u`` means lines of constant u (each running along v), stepped across u from the start's
u-side to the opposite u-side; the v-side where it ends follows the parity of the line
count, which the path generator tunes. Hence:

* crossfeed ``u`` needs finish.u != start.u (same v-side: even count; diagonal: odd);
* crossfeed ``v`` needs finish.v != start.v;
* finish == start is impossible; a diagonal pair allows both directions, a pair on one
  edge exactly one.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..layout.layout import CORNER_NAMES, CORNER_UV

CROSSFEEDS = ("u", "v")
PIN_FIELDS = ("position", "start", "finish", "crossfeed")
# How a step is reached from the step before: the first step, through a shared edge's
# corner, through a corner shared without an edge, or after a retraction.
LINKS = ("first", "boundary", "corner", "retract")

_U = [int(c[0]) for c in CORNER_UV]
_V = [int(c[1]) for c in CORNER_UV]


def crossfeeds_for(start: int, finish: int) -> tuple[str, ...]:
    """Crossfeed directions whose zigzag runs from corner ``start`` to ``finish``."""
    out = []
    if _U[start] != _U[finish]:
        out.append("u")
    if _V[start] != _V[finish]:
        out.append("v")
    return tuple(out)


def is_diagonal(a: int, b: int) -> bool:
    return _U[a] != _U[b] and _V[a] != _V[b]


def corner_index(value, what: str = "corner") -> int:
    """A corner given as index 0..3 or by name ('lower-left', ...); ValueError otherwise."""
    if isinstance(value, bool):
        raise ValueError(f"{what} {value!r} is not a corner")
    if isinstance(value, int) and 0 <= value < 4:
        return value
    if isinstance(value, str):
        key = value.strip().lower().replace("_", "-").replace(" ", "-")
        if key in CORNER_NAMES:
            return CORNER_NAMES.index(key)
        if key.isdigit() and int(key) < 4:
            return int(key)
    raise ValueError(f"{what} {value!r} is not a corner (use 0..3 or one of "
                     + ", ".join(CORNER_NAMES) + ")")


@dataclass
class Step:
    """One patch of the processing list; ``retract_before`` marks a retraction into it."""
    patch: int
    start: int | None = None
    finish: int | None = None
    crossfeed: str | None = None
    retract_before: bool = False
    link: str = "first"
    pinned: frozenset = frozenset()
    orientation: dict | None = None     # optional tool-axis settings for this patch (a JSON object)

    def describe(self) -> str:
        s = CORNER_NAMES[self.start] if self.start is not None else "?"
        f = CORNER_NAMES[self.finish] if self.finish is not None else "?"
        return f"patch {self.patch} {s} -> {f} crossfeed {self.crossfeed or '?'}"


@dataclass
class Pins:
    """What a person fixed; the solver completes the rest (0-based positions).

    ``positions`` maps patch -> position in the order; ``start_patch``/``finish_patch`` are
    shorthands for positions 0 and n-1. ``start_corner``, ``finish_corner`` and
    ``crossfeed`` map patch -> value.
    """
    start_patch: int | None = None
    finish_patch: int | None = None
    positions: dict = field(default_factory=dict)
    start_corner: dict = field(default_factory=dict)
    finish_corner: dict = field(default_factory=dict)
    crossfeed: dict = field(default_factory=dict)

    def is_empty(self) -> bool:
        return (self.start_patch is None and self.finish_patch is None and not self.positions
                and not self.start_corner and not self.finish_corner and not self.crossfeed)


@dataclass
class ProcessingList:
    """The plan the path generator follows: steps in machining order, chained at corners."""
    steps: list
    model: str = ""
    units: str = "mm"
    layout_hash: str = ""
    info: dict = field(default_factory=dict)

    @property
    def order(self) -> list[int]:
        return [s.patch for s in self.steps]

    @property
    def retractions(self) -> int:
        return sum(1 for s in self.steps if s.retract_before)

    @property
    def corner_links(self) -> int:
        return sum(1 for s in self.steps if s.link == "corner")

    @property
    def boundary_links(self) -> int:
        return sum(1 for s in self.steps if s.link == "boundary")

    def retraction_steps(self) -> list[int]:
        """1-based step numbers that start after a retraction."""
        return [i + 1 for i, s in enumerate(self.steps) if s.retract_before]

    def table(self, layout=None) -> str:
        """The list as a text table (what ``tsplcam plan`` prints)."""
        rows = [("step", "patch", "start", "finish", "crossfeed", "reached by", "pinned")]
        for i, s in enumerate(self.steps):
            name = str(s.patch) if layout is None or not layout.patch_names \
                else f"{s.patch} ({layout.name(s.patch)})"
            rows.append((str(i + 1), name,
                         CORNER_NAMES[s.start] if s.start is not None else "?",
                         CORNER_NAMES[s.finish] if s.finish is not None else "?",
                         s.crossfeed or "?",
                         "RETRACT" if s.retract_before else s.link,
                         ",".join(f for f in PIN_FIELDS if f in s.pinned)))
        widths = [max(len(r[k]) for r in rows) for k in range(len(rows[0]))]
        lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
        lines.append(f"{len(self.steps)} patches, {self.boundary_links} boundary links, "
                     f"{self.corner_links} corner links, {self.retractions} retractions"
                     + (" (before step " + ", ".join(map(str, self.retraction_steps())) + ")"
                        if self.retractions else ""))
        return "\n".join(lines)
