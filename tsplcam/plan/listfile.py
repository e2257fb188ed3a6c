"""The processing-list file (JSON): what the planner writes, a person edits, the path generator reads.

Schema, version 1 (``tsplcam/plan/PROCESSING-LIST.md`` explains it for people)::

    {
      "format": "tsplcam-processing-list",      required, exactly this
      "version": 1,                             required, exactly 1
      "model": "keycap.tsm",                    optional: the model's file name
      "layout": "sha256:0123456789abcdef",      optional: topology fingerprint; when
                                                present it must match the model's layout
      "patches": 5,                             optional: patch count; checked if present
      "units": "mm",                            optional, "mm" (the only unit)
      "steps": [                                required: one entry per patch, in order
        {"patch": 2,                            required: patch index 0..n-1
         "start": "lower-left",                 corner name or index 0..3
         "finish": "upper-right",               corner name or index 0..3
         "crossfeed": "u",                      "u" or "v"
         "retract_before": false,               true: retract after the step before and
                                                approach this step's start from clearance
         "link": "boundary",                    optional, informational, checked if present:
                                                "first", "boundary", "corner", "retract"
         "pinned": ["position", "start"],       optional: fields the solver must keep
         "orientation": {"lead": 3}}            optional: tool-axis settings for this patch
      ],                                        (the orientation stage checks the keys)
      "summary": {...}, "solver": {...}         optional, informational, ignored on reading
    }

Corner names: lower-left (u,v)=(0,0), lower-right (1,0), upper-right (1,1), upper-left
(0,1). A step's zigzag must be able to run from start to finish with its crossfeed
(:func:`~tsplcam.plan.steps.crossfeeds_for`), and unless ``retract_before`` is true its
start must be the same node (point) as the previous step's finish.

:func:`load` checks a complete list against the model's layout and raises
:class:`~tsplcam.errors.InputError` with the file, the line of the step and
``item = "step 4 (patch 6)"``: unknown patch, patch missing or repeated, a start corner
that is not the previous finish's point, a corner link where the patches share no corner,
a finish the crossfeed cannot reach. With ``partial=True`` unpinned corners and crossfeed
may be null or absent and chaining is not checked: the form :func:`complete_file` reads.
"""
from __future__ import annotations

import json

from ..errors import InputError
from ..inputfile import loads_json, read_text
from ..layout.layout import CORNER_NAMES
from .graph import NONE, PatchGraph, layout_hash
from .steps import CROSSFEEDS, LINKS, PIN_FIELDS, ProcessingList, Step, corner_index, \
    crossfeeds_for

FORMAT = "tsplcam-processing-list"
VERSION = 1
_TOP_KEYS = {"format", "version", "model", "layout", "patches", "units", "steps", "summary",
             "solver"}
_STEP_KEYS = {"patch", "start", "finish", "crossfeed", "retract_before", "link", "pinned", "orientation"}


# -- writing -----------------------------------------------------------------------------
def to_dict(plist: ProcessingList) -> dict:
    steps = []
    for s in plist.steps:
        steps.append({
            "patch": int(s.patch),
            "start": CORNER_NAMES[s.start] if s.start is not None else None,
            "finish": CORNER_NAMES[s.finish] if s.finish is not None else None,
            "crossfeed": s.crossfeed,
            "retract_before": bool(s.retract_before),
            "link": s.link,
            "pinned": [f for f in PIN_FIELDS if f in s.pinned],
        })
        if s.orientation:
            steps[-1]["orientation"] = dict(s.orientation)
    out = {"format": FORMAT, "version": VERSION, "model": plist.model,
           "layout": plist.layout_hash, "patches": len(plist.steps), "units": plist.units,
           "steps": steps,
           "summary": {"retractions": plist.retractions, "corner_links": plist.corner_links,
                       "boundary_links": plist.boundary_links,
                       "retract_before_steps": plist.retraction_steps()}}
    if plist.info:
        out["solver"] = {k: v for k, v in plist.info.items()
                         if isinstance(v, (int, float, str, bool))}
    return out


def dumps(plist: ProcessingList) -> str:
    """JSON text with one step per line, so that a person can edit it line by line."""
    d = to_dict(plist)
    steps = d.pop("steps")
    head = json.dumps(d, indent=2)
    body = ",\n".join("    " + json.dumps(s) for s in steps)
    return head[:-2] + ',\n  "steps": [\n' + body + "\n  ]\n}\n"


def save(plist: ProcessingList, path) -> None:
    """Write the list as JSON, whole or not at all."""
    from ..outfile import write_text
    write_text(path, dumps(plist), what="processing list")


# -- reading -----------------------------------------------------------------------------
def _step_lines(text: str | None, count: int) -> list[int | None]:
    """Line (1-based) of each step's "patch" key, when the text makes it unambiguous."""
    if not text:
        return [None] * count
    at = text.find('"steps"')
    hits = []
    while at >= 0:
        at = text.find('"patch"', at + 1)
        if at >= 0:
            hits.append(text.count("\n", 0, at) + 1)
    if len(hits) != count:
        return [None] * count
    return hits


def from_dict(data, path=None, text=None, partial: bool = False) -> ProcessingList:
    """A processing list from parsed JSON; checks the form, not the model (see :func:`check`)."""
    if not isinstance(data, dict):
        raise InputError("a processing list is a JSON object", path=path, item="(document)")
    if data.get("format") != FORMAT:
        raise InputError(f"'format' is {data.get('format')!r}, expected {FORMAT!r}",
                         path=path, item="format")
    if data.get("version") != VERSION:
        raise InputError(f"'version' is {data.get('version')!r}; this tsplcam reads version "
                         f"{VERSION}", path=path, item="version")
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise InputError(f"unknown key(s) {', '.join(unknown)}", path=path, item="list")
    units = data.get("units", "mm")
    if units != "mm":
        raise InputError(f"units {units!r}: only 'mm' is supported", path=path, item="units")
    raw = data.get("steps")
    if not isinstance(raw, list):
        raise InputError("'steps' must be a list of steps", path=path, item="steps")
    lines = _step_lines(text, len(raw))
    steps = []
    for i, r in enumerate(raw):
        patch = r.get("patch") if isinstance(r, dict) else None
        item = f"step {i + 1}" + (f" (patch {patch})" if patch is not None else "")

        def bad(msg):
            return InputError(msg, path=path, line=lines[i], item=item)

        if not isinstance(r, dict):
            raise bad("a step is a JSON object")
        extra = sorted(set(r) - _STEP_KEYS)
        if extra:
            raise bad(f"unknown key(s) {', '.join(extra)} (a step has "
                      + ", ".join(sorted(_STEP_KEYS)) + ")")
        if isinstance(patch, bool) or not isinstance(patch, int):
            raise bad(f"'patch' must be a patch index, not {patch!r}")
        pinned = r.get("pinned", [])
        if not isinstance(pinned, list) or any(p not in PIN_FIELDS for p in pinned):
            raise bad(f"'pinned' must list fields among {', '.join(PIN_FIELDS)}, not {pinned!r}")
        vals = {}
        for key in ("start", "finish"):
            v = r.get(key)
            if v is None:
                if not partial or key in pinned:
                    raise bad(f"'{key}' corner is missing" + (" (it is pinned)" if partial else ""))
                vals[key] = None
                continue
            try:
                vals[key] = corner_index(v, f"'{key}'")
            except ValueError as exc:
                raise bad(str(exc)) from None
        d = r.get("crossfeed")
        if d is None:
            if not partial or "crossfeed" in pinned:
                raise bad("'crossfeed' is missing" + (" (it is pinned)" if partial else ""))
        elif d not in CROSSFEEDS:
            raise bad(f"'crossfeed' must be 'u' or 'v', not {d!r}")
        retract = r.get("retract_before", False)
        if not isinstance(retract, bool):
            raise bad(f"'retract_before' must be true or false, not {retract!r}")
        link = r.get("link")
        if link is not None and link not in LINKS:
            raise bad(f"'link' must be one of {', '.join(LINKS)}, not {link!r}")
        ori = r.get("orientation")
        if ori is not None and not isinstance(ori, dict):
            raise bad(f"'orientation' must be an object of tool-axis settings, not {ori!r}")
        steps.append(Step(patch, vals["start"], vals["finish"], d, retract, link,
                          frozenset(pinned), ori or None))
    patches = data.get("patches")
    if patches is not None and patches != len(steps) and not partial:
        raise InputError(f"'patches' says {patches} but the list has {len(steps)} steps",
                         path=path, item="patches")
    plist = ProcessingList(steps, str(data.get("model") or ""), units,
                           str(data.get("layout") or ""))
    plist.info["step_lines"] = lines
    return plist


def check(plist: ProcessingList, layout, path=None, partial: bool = False) -> ProcessingList:
    """Check a list against the model's layout; raise InputError naming the step at fault.

    Fills in each step's ``link`` (how it is reached) once it is known to be right.
    """
    graph = PatchGraph(layout)
    n = graph.n
    lines = plist.info.get("step_lines") or [None] * len(plist.steps)
    if plist.layout_hash and plist.layout_hash != layout_hash(layout):
        raise InputError(f"the list was planned on layout {plist.layout_hash}, this model's "
                         f"layout is {layout_hash(layout)} (another model, or its patches "
                         "changed): plan it again", path=path, item="layout")
    seen: dict[int, int] = {}
    for i, s in enumerate(plist.steps):
        item = f"step {i + 1} (patch {s.patch})"

        def bad(msg):
            return InputError(msg, path=path, line=lines[i], item=item)

        if not 0 <= s.patch < n:
            raise bad(f"unknown patch {s.patch}: the model has patches 0..{n - 1}")
        if s.patch in seen:
            raise bad(f"patch {s.patch} is repeated (it is already step {seen[s.patch] + 1})")
        seen[s.patch] = i
        if s.start is not None and s.finish is not None:
            if s.start == s.finish:
                raise bad(f"start and finish are both {CORNER_NAMES[s.start]}: a zigzag "
                          "cannot end at the corner it started from")
            if s.crossfeed is not None and s.crossfeed not in crossfeeds_for(s.start, s.finish):
                other = crossfeeds_for(s.start, s.finish)[0]
                raise bad(f"a zigzag with crossfeed {s.crossfeed} cannot run from "
                          f"{CORNER_NAMES[s.start]} to {CORNER_NAMES[s.finish]} "
                          f"(crossfeed {other} can)")
        if i == 0:
            if s.retract_before:
                raise bad("the first step cannot retract before (it starts from clearance)")
            derived = "first"
        else:
            prev = plist.steps[i - 1]
            kind = graph.kind[prev.patch, s.patch]
            derived = "retract" if s.retract_before else (graph.link(prev.patch, s.patch)
                                                          or "none")
            what = f"step {i} (patch {prev.patch})"
            if s.link is not None and s.link != derived and not partial:
                if s.link == "corner" and kind == NONE:
                    raise bad(f"a corner link is used where patches {prev.patch} and "
                              f"{s.patch} share no corner")
                if s.link in ("corner", "boundary") and kind == NONE:
                    raise bad(f"a {s.link} link is used where patches {prev.patch} and "
                              f"{s.patch} share no corner")
                if s.link == "boundary":
                    raise bad(f"a boundary link is used where patches {prev.patch} and "
                              f"{s.patch} share only a corner, no edge")
                raise bad(f"'link' says {s.link!r} but this step is reached by {derived!r}")
            if not s.retract_before and not partial:
                if kind == NONE:
                    raise bad(f"patches {prev.patch} and {s.patch} share no corner: step "
                              f"{i + 1} cannot follow {what} without a retraction (set "
                              "retract_before, or reorder)")
                a = int(graph.corner_nodes[prev.patch, prev.finish])
                b = int(graph.corner_nodes[s.patch, s.start])
                if a != b:
                    meet = [CORNER_NAMES[c] for c in range(4)
                            if graph.entries(prev.patch, prev.finish, s.patch) == [c]]
                    hint = (f" (patch {s.patch}'s corner there is {meet[0]})" if meet else
                            f" (patch {s.patch} has no corner at that point)")
                    raise bad(f"starts at {CORNER_NAMES[s.start]} (node {b}), which is not the "
                              f"point where {what} finishes ({CORNER_NAMES[prev.finish]}, node "
                              f"{a}){hint}; set retract_before to retract there")
        if not partial:
            s.link = derived
    missing = sorted(set(range(n)) - set(seen))
    if missing:
        raise InputError(f"patch(es) {', '.join(map(str, missing))} of the model are missing "
                         f"from the list ({len(plist.steps)} steps for {n} patches)",
                         path=path, item="steps")
    return plist


def loads(text: str, layout, path=None, partial: bool = False) -> ProcessingList:
    data = loads_json(text, path)
    plist = from_dict(data, path=path, text=text, partial=partial)
    return check(plist, layout, path=path, partial=partial)


def load(path, layout, partial: bool = False) -> ProcessingList:
    """Read and check a processing list against the model's layout (what the path generator calls)."""
    text = read_text(path, "processing list")
    return loads(text, layout, path=str(path), partial=partial)


def complete_file(path, layout, **options) -> ProcessingList:
    """Read a (possibly partial) list, keep what it pins and solve the rest."""
    from .solve import complete
    plist = load(path, layout, partial=True)
    done = complete(plist, layout, **options)
    blocks = {s.patch: s.orientation for s in plist.steps if s.orientation}
    for s in done.steps:
        s.orientation = blocks.get(s.patch)
    return done


def orientation_blocks(plist: ProcessingList, path=None) -> dict:
    """{patch: (block, where)} of the steps that carry an ``orientation`` block; ``where``
    names the file, line and step for messages."""
    lines = plist.info.get("step_lines") or [None] * len(plist.steps)
    out = {}
    for i, s in enumerate(plist.steps):
        if s.orientation:
            where = (f"{path}: " if path else "") + (f"line {lines[i]}: " if lines[i] else "") + \
                f"step {i + 1} (patch {s.patch})"
            out[s.patch] = (dict(s.orientation), where)
    return out
