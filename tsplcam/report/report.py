"""``report.html`` of a job with its pictures, from the objects the pipeline made.

:func:`write_report` takes what the stages return (model, processing list, tool path,
oriented path with its metrics, posted program with its time estimate, scallop
verification, compound-NURBS baseline) and writes ``report.html`` plus PNG pictures in
``report_files/`` beside it. Whatever is not given leaves its section out.

Why files and not data URIs: the page stays small and readable as text, every picture
opens, links and attaches on its own (the README links one), and a browser's "save page"
uses the same ``<name>_files`` folder convention; the folder travels with the page.

The report reads every stage and ``verify``; nothing in the pipeline imports it.
"""
from __future__ import annotations

import contextlib
import dataclasses
import json
import multiprocessing
import os

import numpy as np

from .. import __version__
from ..errors import TsplcamError
from ..layout.layout import CORNER_NAMES
from ..post.timing import hms
from ..verify.metrics import path_metrics
from . import figures, page, style

FILES = "report_files"
CLEARANCE_POSES = 2000          # poses measured for the clearance plot (and around the closest)
CLEARANCE_TOP = 10.0            # mm: farther is drawn as "more than"
CLEARANCE_TESSELLATION = 0.02   # mm, chordal tolerance of the workpiece when the report builds it


def _f(x, digits: int = 3) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:,.{digits}f}"


def _n(x) -> str:
    return f"{int(x):,d}"


def _time(seconds: float) -> str:
    return f"{hms(seconds)} ({seconds:,.1f} s)"


def settings_rows(settings) -> list:
    """(name, value) pairs of a settings object: a dataclass, a dict or an argparse Namespace."""
    if settings is None:
        return []
    if dataclasses.is_dataclass(settings):
        items = [(f.name, getattr(settings, f.name)) for f in dataclasses.fields(settings)]
    elif isinstance(settings, dict):
        items = list(settings.items())
    else:
        items = sorted(vars(settings).items())
    rows = []
    for k, v in items:
        if callable(v):
            continue
        if isinstance(v, (dict, list, tuple)):
            v = json.dumps(v, sort_keys=True, default=str)
        rows.append((k, "default" if v is None else v))
    return rows


def clearance_groups(checker) -> dict:
    """The clearance plot's series and the tool parts of each: "shank", "holder" (those the
    tool has)."""
    names = [p.name for p in checker.tool.parts()]
    groups = {"shank": [n for n in names if n == "shank"],
              "holder": [n for n in names if n.startswith("holder")]}
    return {k: v for k, v in groups.items() if v}


def clearance_group(checker, path, parts, poses: int | None = None, top: float = CLEARANCE_TOP):
    """(point indices, mm) of the tool ``parts``' clearance along ``path``: measured
    (:class:`tsplcam.verify.orientation.ClearanceGauge`) at about ``poses`` poses (default
    :data:`CLEARANCE_POSES`, read when called) spread evenly over the path, and then at every
    pose next to the ten closest ones, so the smallest value is that of the closest pose, not
    of the nearest sample."""
    from ..verify.orientation import ClearanceGauge
    poses = CLEARANCE_POSES if poses is None else int(poses)
    n = len(path)
    step = max(1, int(np.ceil(n / poses)))
    base = np.unique(np.concatenate([np.arange(0, n, step), [n - 1]]))
    C, A = path.center, path.axis
    gauge = ClearanceGauge(checker, parts, top=top)
    v = gauge.measure(C[base], A[base])
    low = base[np.argsort(v, kind="stable")[:10]]
    near = np.unique(np.concatenate([np.arange(max(0, i - step), min(n, i + step + 1)) for i in low]))
    near = np.setdiff1d(near, base)
    idx, val = base, v
    if len(near):
        idx = np.concatenate([base, near])
        val = np.concatenate([v, gauge.measure(C[near], A[near])])
        order = np.argsort(idx, kind="stable")
        idx, val = idx[order], val[order]
    return idx, val


class ClearanceSweep:
    """The shank's and holder's clearance along ``path`` (:func:`clearance_group` of each of
    :func:`clearance_groups`) measured by a forked process (an
    :class:`~tsplcam.orientation.aside.Aside`) and, once it asks for the result, by this one:
    the series are taken one by one from a shared counter, the holder's first (the longest:
    keycap_mold 1.78 s against the shank's 0.48, the keycap 1.14 against 0.37), so a report
    whose pictures are drawn before the forked process is done measures the shank itself
    (keycap_mold waited 0.78 s for the sweep after its pictures). Each series is measured by
    the same code on the same data wherever it is, so the values are the same; one the forked
    process took but did not deliver (it died) is measured here."""

    def __init__(self, checker, path):
        from ..orientation.aside import Aside
        self.checker, self.path = checker, path
        self.groups = clearance_groups(checker)
        self.order = list(reversed(list(self.groups)))          # the holder's first
        # (a shared counter where the sweep forks; one process takes every series at once)
        self._next = multiprocessing.get_context("fork").Value("i", 0) if Aside.can_fork() else _Count()
        self.aside = Aside(_take_series, self)

    @property
    def forked(self) -> bool:
        return self.aside.forked

    def result(self) -> dict:
        """name -> (point indices, mm), in :func:`clearance_groups`' order."""
        mine = _take_series(self)
        theirs = self.aside.result()
        return {name: mine[name] if name in mine else theirs[name] if name in theirs
                else clearance_group(self.checker, self.path, parts)
                for name, parts in self.groups.items()}

    def close(self) -> None:
        self.aside.close()


class _Count:
    """A multiprocessing Value's ``value`` and ``get_lock()`` for one process."""
    value = 0

    def get_lock(self):
        return contextlib.nullcontext()


def _take_series(sweep: ClearanceSweep) -> dict:
    """The series of ``sweep`` not yet taken, measured here one by one: name -> series."""
    out = {}
    while True:
        with sweep._next.get_lock():
            k = sweep._next.value
            if k >= len(sweep.order):
                return out
            sweep._next.value = k + 1
        name = sweep.order[k]
        out[name] = clearance_group(sweep.checker, sweep.path, sweep.groups[name])


def _timed(p, machine, dialect):
    """Machining time (s) of a path posted for ``machine``, or the simple A/C model's time."""
    from ..post import post_program
    from ..verify.orientation import orientation_metrics
    if machine is not None:
        try:
            return post_program(p, machine, dialect).time.total_s, f"posted for {machine.name}"
        except TsplcamError as exc:
            return float("nan"), f"not posted: {exc}"
    return orientation_metrics(p, None, None, clearance=False).time_s, "simple A/C model"


class _Report:
    """Collects the sections while the pictures are written; tells ``progress`` (stage
    "report") after each of the ``total`` pictures."""

    def __init__(self, out_dir: str, progress=None, total: int = 1):
        self.out_dir = out_dir
        self.sections: list[str] = []
        self.progress, self.total, self.done = progress, total, 0
        if progress is not None:
            progress("report", 0, total)

    def picture(self, name: str, draw, *args) -> tuple:
        """Draw picture ``name`` with ``draw(file, *args)``: (its address relative to the page,
        the figures ``draw`` returns)."""
        figs = draw(os.path.join(self.out_dir, FILES, f"{name}.png"), *args)
        self.done += 1
        if self.progress is not None:
            self.progress("report", min(self.done, self.total), self.total)
        return f"{FILES}/{name}.png", figs


def _covered_note(tool, series) -> str:
    """The clearance picture's word on parts whose lower end sits on flutes as wide (the
    checker keeps their clearance from that end up: below it the flutes, which cut, rule)."""
    names = [p.name for p, (bottom, _) in zip(tool.parts(), tool.exposed_ends())
             if not bottom and p.name != "flutes" and p.name in series]
    if not names:
        return ""
    return (f", by the {' and '.join(names)} from {'its' if len(names) == 1 else 'their'} lower end up "
            f"(below it the flutes, as wide, cut, and the {names[0]}'s rim may read closer)")


def clearance_wanted(tool) -> bool:
    """Whether a report of ``tool`` has a clearance section (some part above the flutes)."""
    return tool is not None and any(p.name != "flutes" for p in tool.parts())


def write_report(out_dir: str, *, model, path, processing_list=None, oriented=None, machine=None,
                 posted=None, verification=None, baseline=None, settings=None, tool=None, stock=None,
                 checker=None, progress=None, clearance=None) -> str:
    """Write ``out_dir/report.html`` and its pictures (``out_dir/report_files/*.png``);
    returns the page's path.

    ``model``: the Model; ``path``: the ToolPath as generated; ``processing_list``: the
    ProcessingList it followed; ``oriented``: the pipeline's Oriented (path with tool axes,
    report, metrics); ``machine``: a Machine (default: the posted program's); ``posted``:
    the PostResult (joints and time estimate); ``verification``: a ScallopReport, made with
    ``measure(..., heights=True)`` for the map; ``baseline``: the compound-NURBS ToolPath as
    generated (compared with ``path``, both with surface-normal axes) or oriented like the job
    (a Program, or a ToolPath with other axes: compared with the job's program);
    ``settings``: the job's settings (dataclass, dict or Namespace), shown as given;
    ``tool``: the Tool (header; with it the clearance is measured, against ``stock``
    (vertices, triangles) too); ``checker``: the orientation's CollisionChecker to reuse for
    that (default: ``oriented.checker`` if it has one, else one is built, which on a big
    model takes as long as the orientation's did); ``progress``: a tsplcam.progress callback
    told after each picture (stage "report"); ``clearance``: the :class:`ClearanceSweep` of
    the checker and the final path, started already (the job's, during its verification), else
    started here when the tool has a part above the flutes; closed on return.
    The same inputs give the same bytes."""
    if checker is None:
        checker = getattr(oriented, "checker", None)     # the orientation's, when it keeps it
    if tool is None and checker is not None:
        tool = checker.tool
    final = oriented.path if oriented is not None else path
    if clearance is None and clearance_wanted(tool):
        if checker is None:
            from ..orientation import CollisionChecker
            meshes = [] if stock is None else [("stock", stock[0], stock[1])]
            checker = CollisionChecker(model, tool, meshes=meshes, tolerance=CLEARANCE_TESSELLATION)
        # measured in a forked process while the other pictures are drawn (the keycap's: 180
        # grown tools' BVHs and their fcl queries, about 1.7 s), or here at once with one process
        clearance = ClearanceSweep(checker, final)
    try:
        return _write(out_dir, model=model, path=path, processing_list=processing_list, oriented=oriented,
                      machine=machine, posted=posted, verification=verification, baseline=baseline,
                      settings=settings, tool=tool, checker=checker, clearance=clearance, progress=progress)
    finally:
        if clearance is not None:
            clearance.close()


def _write(out_dir: str, *, model, path, processing_list, oriented, machine, posted, verification, baseline,
           settings, tool, checker, clearance, progress) -> str:
    """:func:`write_report` once the tool and checker are known; ``clearance``: the
    :class:`ClearanceSweep` (None: no clearance section)."""
    os.makedirs(os.path.join(out_dir, FILES), exist_ok=True)
    final = oriented.path if oriented is not None else path
    metrics = oriented.metrics if oriented is not None else None
    if machine is None and posted is not None:
        machine = posted.machine
    colours = style.patch_colours(len(model.patches))
    pm = path_metrics(final)
    limit = float(path.info.get("settings", {}).get("scallop", float("nan")))   # unknown for a path read from CL data
    pictures = 3 + (verification is not None and verification.heights is not None) + 2 * (posted is not None) \
        + (tool is not None) + (baseline is not None)
    rep = _Report(out_dir, progress, pictures)
    cards = []

    # -- layout -----------------------------------------------------------------------------
    src, figs = rep.picture("layout", figures.layout_figure, model, processing_list, colours)
    parts = [page.picture(src, "patch layout", f"The {figs['patches']} patches in the colours every picture "
                          "uses, the extraordinary points (red) and the adjacency graph: a solid line joins "
                          "patches sharing an edge, a dashed line patches sharing only a corner. The "
                          "processing list hands the tool from patch to patch through these links.",
                          figures.pixel_size("layout"))]
    if processing_list is not None:
        rows = [(i + 1, s.patch, CORNER_NAMES[s.start] if s.start is not None else "?",
                 CORNER_NAMES[s.finish] if s.finish is not None else "?", s.crossfeed or "?",
                 "RETRACT" if s.retract_before else s.link) for i, s in enumerate(processing_list.steps)]
        parts.append("<h3>Processing list</h3>" + page.row_table(
            ("step", "patch", "start corner", "finish corner", "crossfeed", "reached by"), rows,
            ident="processing-list", numeric=(0, 1)))
        parts.append(page.note(f"{len(processing_list.steps)} steps, {processing_list.boundary_links} through "
                               f"shared edges, {processing_list.corner_links} through shared corners, "
                               f"{processing_list.retractions} retractions."))
    rep.sections.append(page.section("layout", "Patch layout and processing list", *parts))

    # -- path -------------------------------------------------------------------------------
    src, figs = rep.picture("path", figures.path_figure, model, final, colours)
    rows = [("points", _n(pm.points)), ("lines", _n(pm.lines)), ("patches", _n(pm.patches)),
            ("cutting length (mm)", _f(pm.cut_length, 1)), ("links on the surface (mm)", _f(pm.link_length, 1)),
            ("air moves (mm)", _f(pm.air_length, 1)), ("total length (mm)", _f(pm.length, 1)),
            ("air moves", _n(pm.air_moves)), ("retractions", _n(pm.retractions)),
            ("feed (mm/min)", _f(final.feed, 0))]
    per_patch = path.info.get("patches") or []
    pp = [(d["step"], d["patch"], d["crossfeed"], d["lines"], _f(d["scallop_used"] * 1000.0, 2), _n(d["points"]),
           _f(d["cut_length"], 1)) for d in per_patch]
    rep.sections.append(page.section(
        "path", "Tool path",
        page.picture(src, "tool path", "The finishing path coloured by patch, in machining order from the green "
                     "triangle to the white square. Black: links on the surface between lines and from patch to "
                     "patch; red dashed: moves through the air (retract, rapid, approach).",
                     figures.pixel_size("path")),
        '<div class="tables">' + page.key_values("Path", rows, ident="path-figures")
        + ("<div><h3>Per patch</h3>" + page.row_table(
            ("step", "patch", "crossfeed", "lines", "scallop used (µm)", "points", "cutting (mm)"), pp,
            ident="per-patch", numeric=(0, 1, 3, 4, 5, 6)) + "</div>" if pp else "") + "</div>"))
    cards.append(page.card("points", _n(pm.points), f"{pm.lines:,d} lines on {pm.patches} patches", ident="h-points"))
    cards.append(page.card("path length", f"{pm.length:,.1f} mm", f"cutting {pm.cut_length:,.1f}, links "
                           f"{pm.link_length:,.1f}, air {pm.air_length:,.1f} mm", ident="h-length"))
    cards.append(page.card("retractions", _n(pm.retractions), f"{pm.air_moves} air moves", bad=pm.retractions > 0,
                           ident="h-retractions"))

    # -- scallop ------------------------------------------------------------------------------
    if verification is not None:
        v = verification
        parts = []
        if v.heights is not None and len(v.heights):
            shown = limit if np.isfinite(limit) else max(v.max_scallop, 1e-6)
            src, figs = rep.picture("scallop", figures.scallop_figure, model, v, shown, path.tool_radius,
                                    bool(np.isfinite(limit)))
            parts.append(page.picture(src, "scallop height map", "Material left on the surface, measured by the "
                                      "verification module (the swept ball against the surface, cusp ridges "
                                      "refined), as the largest height in each small cell: yellow is near the "
                                      "limit, red above it; the histogram shows every measured height.",
                                      figures.pixel_size("scallop")))
        else:
            parts.append(page.note("No height map: the verification was made without heights "
                                   "(measure(..., heights=True) keeps them)."))
        rows = [("limit (µm)", _f(limit * 1000.0, 2)), ("largest scallop (µm)", _f(v.max_scallop * 1000.0, 3)),
                ("largest / limit", _f(v.max_scallop / limit, 3)),
                ("at patch (u, v)", f"{v.max_at[0]} ({v.max_at[1]:.4f}, {v.max_at[2]:.4f})"),
                ("mean cusp height (µm)", _f(v.cusp_mean * 1000.0, 3)), ("largest cusp (µm)", _f(v.cusp_max * 1000.0, 3)),
                ("mean material (µm)", _f(v.mean_material * 1000.0, 3)), ("surface samples", _n(v.samples)),
                ("sample spacing (mm)", _f(v.spacing, 4)), ("refined ridges", _n(v.ridges)),
                ("uncovered samples", _n(v.uncovered)), ("gouge at path points (mm)", f"{v.gouge_points:.2e}"),
                ("gouge on chords (mm)", f"{v.gouge_chords:.2e}"), ("gouge in the air (mm)", f"{v.gouge_air:.2e}")]
        parts.append(page.key_values("Measured on the surface", rows, ident="scallop-figures"))
        rep.sections.append(page.section("scallop", "Scallop height", *parts))
        over = bool(v.max_scallop > limit * (1 + 1e-9))
        cards.append(page.card("largest scallop", f"{v.max_scallop * 1000.0:.2f} µm",
                               f"{v.max_scallop / limit:.2f} of the {limit * 1000.0:g} µm limit"
                               if np.isfinite(limit) else "limit unknown", bad=over, ident="h-scallop"))

    # -- tool axis ----------------------------------------------------------------------------
    src, figs = rep.picture("axis", figures.axis_figure, final, colours)
    parts = [page.picture(src, "tool axis along the path", "Top: the tool axis's tilt from vertical (coloured by "
                          "patch) and its angle to the surface normal. Bottom: how much the axis turns from one "
                          "point to the next; smooth axes keep this small and free of spikes.",
                          figures.pixel_size("axis"))]
    if metrics is not None:
        m = metrics
        rows = [("strategy", oriented.report.strategy if oriented.report is not None else "n/a"),
                ("collisions (flutes, shank, holder)", _n(m.collisions)), ("ball gouges", _n(m.gouges)),
                ("largest axis step (deg)", _f(m.max_step_deg, 3)), ("mean axis step (deg)", _f(m.mean_step_deg, 3)),
                ("total axis variation (deg)", _f(m.total_variation_deg, 1)),
                ("largest step per mm (deg/mm)", _f(m.max_step_per_mm, 3)),
                ("rotary travel (deg)", _f(m.rotary_travel_deg, 1)), ("tilt axis travel (deg)", _f(m.tilt_travel_deg, 1)),
                ("rotary axis travel (deg)", _f(m.c_travel_deg, 1)),
                ("smallest clearance, orientation metrics (mm)", _f(m.min_clearance, 3))]
        parts.append(page.key_values("Orientation", rows, ident="orientation-figures"))
    rep.sections.append(page.section("axis", "Tool axis", *parts))
    if metrics is not None:
        cards.append(page.card("collisions", _n(metrics.collisions + metrics.gouges),
                               f"{metrics.collisions} tool, {metrics.gouges} ball gouges",
                               bad=(metrics.collisions + metrics.gouges) > 0, ident="h-collisions"))

    # -- machine axes ---------------------------------------------------------------------------
    if posted is not None:
        src, used = rep.picture("machine", figures.machine_figure, final, posted, colours)
        info = posted.solution.info
        rows = []
        for j, name in enumerate(posted.machine.axis_names):
            u = used[name]
            unit = "mm" if j < 3 else "deg"
            travel = "endless" if u["limit_min"] is None else f"{u['limit_min']:g} to {u['limit_max']:g}"
            rows.append((name, unit, _f(u["min"], 3), _f(u["max"], 3), travel,
                         "" if u["limit_min"] is None else f"{100 * u['fraction']:.1f} %",
                         _f(float(posted.time.travel[j]), 1)))
        rep.sections.append(page.section(
            "machine", "Machine axes",
            page.picture(src, "machine axes", "Every machine axis over the program time, from the post's joint "
                         "solution (coloured by patch as in the path picture; grey: approach and retract). Red "
                         "dashed lines are travel limits within view; the bars at right show the whole travel and "
                         "the part of it the program uses.", figures.pixel_size("machine")),
            page.row_table(("axis", "unit", "lowest", "highest", "travel", "travel used", "distance moved"), rows,
                           ident="machine-axes", numeric=(2, 3, 5, 6)),
            page.note(f"{len(posted.motion):,d} blocks ({posted.inserted:,d} inserted for linearisation), "
                      f"dialect {posted.dialect}, branch flips {info['branch_flips']}, singular points "
                      f"{info['singular_points']}, {posted.reorientations} retract-reorient-approach sequences.")))

    # -- clearance ------------------------------------------------------------------------------
    # its section stands here, but its picture is drawn last: the series is measured in a
    # forked process while the time and baseline pictures are drawn
    clearance_at, collisions_card = len(rep.sections), len(cards) - 1

    def clearance_section() -> None:
        kept = None
        if oriented is not None and oriented.report is not None:
            kept = oriented.report.settings.get("clearance")
        if kept is None:
            kept = checker.clearance
        series = clearance.result()
        src, figs = rep.picture("clearance", figures.clearance_figure, final, series, float(kept), colours,
                                CLEARANCE_TOP)
        rows = [(name, _f(d["min"], 3), d["at"]) for name, d in figs.items()]
        measured = sum(len(i) for i, _ in series.values())
        rep.sections.insert(clearance_at, page.section(
            "clearance", "Clearance",
            page.picture(src, "clearance along the path", f"Distance from the shank and from the holder to the "
                         f"workpiece along the path (log scale), measured by growing the tool part until it "
                         f"touches: {measured:,d} poses in all, spread over the path and around the closest ones; "
                         f"the surface as triangles within {checker.mesh.chordal_error:.3f} mm. Red dashed: the "
                         f"clearance the tool axes were chosen to keep{_covered_note(checker.tool, figs)}.",
                         figures.pixel_size("clearance")),
            page.row_table(("tool part", "smallest clearance (mm)", "at point"), rows, ident="clearance",
                           numeric=(1, 2))))
        if metrics is not None:
            close = ", ".join(f"{k} {d['min']:.2f} mm" for k, d in figs.items())
            cards[collisions_card] = page.card("collisions", _n(metrics.collisions + metrics.gouges),
                                               f"closest: {close}", bad=(metrics.collisions + metrics.gouges) > 0,
                                               ident="h-collisions")

    # -- time ---------------------------------------------------------------------------------
    if posted is not None:
        tr = posted.time
        src, figs = rep.picture("time", figures.time_figure, final, posted, colours)
        by = figs["by_limit"]
        rows = [(n, "mm" if j < 3 else "deg", _f(float(tr.travel[j]), 1), _f(float(tr.average_speed[j]), 1),
                 _f(float(tr.peak_speed[j]), 1), _f(float(posted.machine.max_velocity[j]) * 60.0, 0),
                 _n(tr.limiting_blocks[j]), _f(by[n], 1))
                for j, n in enumerate(tr.axis_names)]
        rep.sections.append(page.section(
            "time", "Machining time",
            page.picture(src, "time per axis", "Left: the estimated time split by what sets each block's "
                         "duration, the programmed feed or an axis's velocity and acceleration limits. Right: the "
                         "tool-tip speed this gives in every feed block against the programmed feed.",
                         figures.pixel_size("time")),
            page.key_values("Estimate", [("total", _time(tr.total_s)), ("cutting", _time(tr.cut_s)),
                                         ("air (approach, retract, rapids)", _time(tr.air_s)),
                                         ("length over feed alone", _time(tr.feed_only_s)),
                                         ("blocks", _n(tr.blocks)), ("set by the feed (s)", _f(by["feed"], 1))],
                            ident="time-figures"),
            page.row_table(("axis", "unit", "travel", "average speed (/min)", "peak speed (/min)",
                            "axis limit (/min)", "blocks it limits", "time it sets (s)"), rows, ident="time-axes",
                           numeric=(2, 3, 4, 5, 6, 7))))
        cards.append(page.card("machining time", hms(tr.total_s),
                               f"{tr.total_s:,.1f} s; length/feed alone {tr.feed_only_s:,.1f} s", ident="h-time"))
    else:
        t_feed = pm.length / final.feed * 60.0
        cards.append(page.card("length / feed", hms(t_feed), f"{t_feed:,.1f} s (no program posted)", ident="h-time"))

    # -- baseline -----------------------------------------------------------------------------
    if baseline is not None:
        dialect = posted.dialect if posted is not None else None
        base = getattr(baseline, "path", baseline)
        # a baseline with tool axes of its own is compared with the job's program; one with
        # the surface normals (as generated) with the T-spline path as generated
        own_axes = hasattr(baseline, "path") or not np.allclose(base.axis, base.normal)
        ours = final if own_axes else path
        table, notes = {}, []
        for label, p in (("T-spline path", ours), ("compound-NURBS baseline", base)):
            d = path_metrics(p).as_dict()
            if p is final and own_axes and posted is not None:
                d["time_s"], how = posted.time.total_s, "the job's program"
            else:
                d["time_s"], how = _timed(p, machine, dialect)
            notes.append(f"{label}: {how}")
            table[label] = d
        src, figs = rep.picture("baseline", figures.baseline_figure, table)
        keys = [("retractions", "retractions", _n), ("air moves", "air_moves", _n), ("points", "points", _n),
                ("lines", "lines", _n), ("cutting length (mm)", "cut_length", lambda x: _f(x, 1)),
                ("links on the surface (mm)", "link_length", lambda x: _f(x, 1)),
                ("air moves (mm)", "air_length", lambda x: _f(x, 1)), ("total length (mm)", "length", lambda x: _f(x, 1)),
                ("machining time (s)", "time_s", lambda x: _f(x, 1))]
        labels = list(table)
        rows = [(name, *(fmt(table[lb][k]) for lb in labels)) for name, k, fmt in keys]
        axes_note = ("Both with tool axes of their own (the job's strategy), so the times are what the machine "
                     "would run." if own_axes else "Both keep their surface-normal tool axes here, so the "
                     "comparison is about the linking.")
        tail = ""
        if posted is not None and not own_axes:
            tail = f" The job's program with its own tool axes takes {posted.time.total_s:,.1f} s."
        rep.sections.append(page.section(
            "baseline", "Against the compound-NURBS baseline",
            page.picture(src, "comparison with the baseline", "The same model cut as independent NURBS faces (each "
                         "from its own corner, retracting between faces) against the T-spline path. " + axes_note,
                         figures.pixel_size("baseline")),
            page.row_table(("", *labels), rows, ident="baseline", numeric=(1, 2)),
            page.note("Times: " + "; ".join(notes) + "." + tail)))

    if clearance is not None:
        clearance_section()

    # -- header -------------------------------------------------------------------------------
    eps = [e for e in model.extraordinary if not e.boundary]
    lo, hi = model.bounding_box(9)
    size = np.asarray(hi) - np.asarray(lo)
    job = [("name", model.name), ("kind", model.kind), ("patches", _n(len(model.patches))),
           ("extraordinary points", f"{len(eps)} (valence {', '.join(str(e.valence) for e in eps) or '-'})"),
           ("size X x Y x Z (mm)", " x ".join(f"{x:.2f}" for x in size))]
    blocks = [page.key_values("Model", job, ident="model")]
    if tool is not None:
        blocks.append(page.key_values("Tool", [("name", tool.name), ("ball radius (mm)", f"{tool.ball_radius:g}"),
                                               ("flute length (mm)", f"{tool.flute_length:g}"),
                                               ("shank diameter (mm)", f"{tool.shank_diameter:g}"),
                                               ("stick-out (mm)", f"{tool.shank_length:g}"),
                                               ("holder", "; ".join(f"{h.kind} {h.length:g} mm, d{h.diameter_bottom:g}"
                                                                    + ("" if h.kind == "cylinder" else f"->d{h.diameter_top:g}")
                                                                    for h in tool.holder) or "none")], ident="tool"))
    else:
        blocks.append(page.key_values("Tool", [("ball radius (mm)", f"{path.tool_radius:g}")], ident="tool"))
    if machine is not None:
        rows = [("name", machine.name), ("title", machine.title or "-"), ("kind", machine.kind),
                ("controller", machine.controller)]
        if posted is not None:
            rows.append(("program dialect", posted.dialect))
        for n in ("X", "Y", "Z"):
            a = machine.linear[n]
            rows.append((f"{n} travel (mm)", f"{a.min:g} to {a.max:g}"))
        for a in (machine.tilt, machine.rotary):
            rows.append((f"{a.name} travel (deg)", "endless" if a.continuous or a.min is None else f"{a.min:g} to {a.max:g}"))
        blocks.append(page.key_values("Machine", rows, ident="machine-info"))
    ps = path.info.get("settings", {})
    blocks.append(page.key_values("Path settings", settings_rows(ps), ident="path-settings"))
    if settings is not None:
        blocks.append(page.key_values("Job settings", settings_rows(settings), ident="job-settings"))
    rep.sections.insert(0, page.section("job", "Job", '<div class="tables">' + "".join(blocks) + "</div>"))

    title = f"{model.name}: five-axis finishing report"
    sub = (f"{len(model.patches)} patches, tool {tool.name if tool is not None else f'ball R{path.tool_radius:g}'}"
           + (f", {machine.name}" if machine is not None else "")
           + (f"; scallop limit {limit * 1000.0:g} µm" if np.isfinite(limit) else ""))
    html = page.page(title, sub, cards, rep.sections,
                     f"Written by tsplcam {__version__}. The pictures are the PNG files in {FILES}/ beside this page.")
    out = os.path.join(out_dir, "report.html")
    with open(out, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(html)
    if progress is not None and rep.done < rep.total:
        progress("report", rep.total, rep.total)
    return out
