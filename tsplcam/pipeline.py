"""The whole job, stage by stage: model -> plan -> path -> orientation -> post.

The only module that uses every stage; the command line (``path`` with its orientation and
posting options, and the main ``job``) and the workbench call it, so the headless job and
the GUI make the same program.

``python3 -m tsplcam path MODEL --tool-radius R --scallop H [...] [--tool T --orientation S]
[--machine M --post D --gcode OUT]``: the toolpath stage's options are documented in
:mod:`tsplcam.toolpath.commands`; orientation defaults to the surface normal (issue 6's path),
``fixed`` / ``closest-z`` / ``smooth`` need a tool with its shank and holder (``--tool``).
``python3 -m tsplcam job``: the paper's keycap job end to end (see :func:`run_job`).
"""
from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field

from .errors import InputError

ORIENTATIONS = ("normal", "fixed", "closest-z", "closest", "smooth")


# -- the pieces --------------------------------------------------------------------------------
def read_triangles(path: str):
    """A triangle mesh (vertices (n,3), triangles (m,3)) from an OBJ file, for stock and
    fixtures in collision checks. Quads are split; errors name the line."""
    import numpy as np
    V, T = [], []
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            lines = fh.read().splitlines()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=path) from None
    for ln, raw in enumerate(lines, start=1):
        tok = raw.split("#", 1)[0].split()
        if not tok:
            continue
        try:
            if tok[0] == "v":
                V.append([float(x) for x in tok[1:4]])
            elif tok[0] == "f":
                idx = [int(t.split("/")[0]) for t in tok[1:]]
                idx = [i - 1 if i > 0 else len(V) + i for i in idx]
                if len(idx) < 3:
                    raise InputError("a face needs three vertices", path=path, line=ln)
                T += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
        except ValueError:
            raise InputError(f"cannot read numbers in {raw.strip()!r}", path=path, line=ln) from None
    V, T = np.array(V, float).reshape(-1, 3), np.array(T, int).reshape(-1, 3)
    if len(T) == 0 or T.min() < 0 or T.max() >= len(V):
        raise InputError("no triangles, or a face refers to a missing vertex", path=path)
    return V, T


def sample_stock(model_spec: str):
    """The mold block around a shipped sample's cavity (keycap_mold, deep_mold), else None."""
    from .model import samples
    make = samples.STOCKS.get(os.path.basename(str(model_spec)).split(".")[0])
    return make() if make is not None else None


@dataclass
class Oriented:
    path: object
    report: object = None
    metrics: object = None


def orient_path(path, model, strategy: str, tool=None, machine=None, stock=None,
                clearance: float = 0.3, plist=None, plist_file=None, **limits) -> Oriented:
    """Tool axes by ``strategy``; 'normal' keeps the surface normals (no tool geometry needed).
    ``plist``: the processing list, whose steps may carry tool-axis settings per patch;
    ``limits``: orient's keywords (``settings`` an OrientationSettings among them).
    The result is re-checked for collisions with the same checker: zero or an error."""
    if strategy == "normal":
        return Oriented(path)
    if strategy not in ORIENTATIONS:
        raise InputError(f"unknown orientation {strategy!r} (one of {', '.join(ORIENTATIONS)})")
    if tool is None:
        raise InputError(f"orientation '{strategy}' needs a tool with its shank and holder (--tool)")
    from .orientation import CollisionChecker, orient
    from .verify.orientation import orientation_metrics
    meshes = [] if stock is None else [("stock", stock[0], stock[1])]
    checker = CollisionChecker(model, tool, meshes=meshes, clearance=clearance)
    from .orientation.controls import step_settings
    from .orientation.settings import OrientationSettings
    from .plan.listfile import orientation_blocks
    blocks = orientation_blocks(plist, plist_file) if plist is not None else {}
    if blocks:
        base = limits.get("settings") or OrientationSettings(strategy=strategy)
        limits["per_patch"] = step_settings(base, blocks)
    oriented, report = orient(path, model, tool, strategy, checker=checker, machine=machine, **limits)
    metrics = orientation_metrics(oriented, checker, machine)
    return Oriented(oriented, report, metrics)


# -- the path command -------------------------------------------------------------------------
def _cmd_path(args) -> int:
    from .toolpath import commands as tp
    t0 = time.perf_counter()
    tool = _tool_for(args)
    model, plist, path = tp.build(args)
    baseline = tp.build_baseline(args, model, plist) if args.baseline or args.baseline_cl else None
    verification, extra = None, {}
    if args.verify:
        from .verify.scallop import measure
        verification = measure(path, model, progress=_progress("measuring scallop, patch"))
        extra["verification"] = verification.as_dict()
    machine = None
    if args.machine:
        from .post import load_machine
        machine = load_machine(args.machine)
    stock = read_triangles(args.stock) if args.stock else sample_stock(args.model)
    oriented = orient_path(path, model, args.orientation, tool, machine, stock, args.holder_clearance,
                           plist=plist, plist_file=getattr(args, "processing_list", None),
                           smoothing_length=args.smoothing_length, rotary_weight=args.rotary_weight,
                           progress=_progress("orienting: poses checked / at most"))
    path = oriented.path
    if oriented.metrics is not None:
        extra["orientation"] = oriented.metrics.as_dict()
    posted = None
    if args.gcode:
        if machine is None:
            raise InputError("--gcode needs --machine (see `python3 -m tsplcam machines`)")
        from .post import post_program
        posted = post_program(path, machine, args.post, orientation=args.axes_form)
        posted.write(args.gcode)
        extra["machining_time_s"] = posted.time.total_s
        from .verify.orientation import machine_motion
        extra["machine_motion"] = machine_motion(posted, path)
    written = tp.write_outputs(args, path, baseline, extra)
    print(tp.report(path, verification, baseline))
    if oriented.report is not None:
        print(oriented.report.summary())
        print(oriented.metrics.summary())
    if posted is not None:
        print(posted.summary())
        written.append(args.gcode)
    for f in written:
        print(f"wrote {f}")
    print(f"time taken {time.perf_counter() - t0:.2f} s")
    return 0


def _progress(what: str):
    """A progress callback printing 'what k/n' on stderr (the report stays on stdout)."""
    import sys

    def report(done: int, total: int) -> None:
        print(f"\r{what} {done}/{total}", end="\n" if done == total else "", file=sys.stderr, flush=True)
    return report


def _tool_for(args):
    """The tool of --tool, checked against --tool-radius."""
    if not args.tool:
        return None
    from .orientation import load_tool
    tool = load_tool(args.tool)
    if abs(tool.ball_radius - args.tool_radius) > 1e-9:
        raise InputError(f"--tool-radius {args.tool_radius:g} mm differs from the ball radius "
                         f"{tool.ball_radius:g} mm of tool {tool.name!r}")
    return tool


def add_path_command(subparsers) -> None:
    from .toolpath import commands as tp
    p = subparsers.add_parser("path", help="finishing path over the whole model (shang2020 3.5): CL data, "
                                           "tool axes and G-code")
    tp.add_arguments(p)
    g = p.add_argument_group("tool orientation (issue 7)")
    g.add_argument("--orientation", choices=ORIENTATIONS, default="normal",
                   help="tool axes: the surface normal (default), fixed +Z (three-axis), the collision-free "
                        "axis closest to +Z (closest, or closest-z: shang2020, tilt only where needed), or "
                        "smooth (xu2013, in the machine's joint space)")
    g.add_argument("--tool", metavar="TOOL", help="tool: a shipped name, a tsplcam tool .json or a FreeCAD "
                                                  ".fctb (its ball radius must equal --tool-radius)")
    g.add_argument("--stock", metavar="OBJ", help="stock or fixture triangles (OBJ) for collision checks "
                                                  "(the keycap_mold sample brings its block)")
    g.add_argument("--holder-clearance", type=float, default=0.3, metavar="MM",
                   help="distance kept between shank/holder and part (mm, default 0.3; the flutes only must not touch)")
    g.add_argument("--smoothing-length", type=float, default=5.0, metavar="MM",
                   help="smooth: a needed tilt is spread over about this length of path on each side "
                        "(mm, default 5)")
    g.add_argument("--rotary-weight", type=float, default=None, metavar="W",
                   help="smooth, with --machine: how much the rotary (C) axis motion counts, in the "
                        "machine's time units (default 2; 0: not at all, the tool-axis direction instead)")
    g = p.add_argument_group("posting (issue 8)")
    g.add_argument("--machine", metavar="NAME", help="machine (`python3 -m tsplcam machines`); also limits "
                                                     "the tool axes to its rotary range")
    g.add_argument("--post", metavar="DIALECT", help="heidenhain, sinumerik, fanuc or linuxcnc (default: the "
                                                     "machine's controller)")
    g.add_argument("--gcode", metavar="OUT", help="write the machine program")
    g.add_argument("--axes-form", choices=("angles", "vector"), default=None,
                   help="tool axes in the program as machine angles (default) or as the tool vector "
                        "(Heidenhain LN TX TY TZ, Sinumerik A3 B3 C3, Fanuc G43.5 I J K)")
    p.set_defaults(func=_cmd_path)


# -- the main job -----------------------------------------------------------------------------
@dataclass
class JobSettings:
    """The paper's job (shang2020 section 4): keycap, 1 mm ball, scallop 5 um, on a Mikron UCP 600
    (Heidenhain, A/C table); tool axes smoothed and collision-free."""
    model: str = "keycap"
    tool: str = "ball1_keycap"
    scallop: float = 0.005
    chord_tol: float = 0.001
    orientation: str = "smooth"
    machine: str = "mikron_ucp600_heidenhain"
    dialect: str | None = None
    axes_form: str | None = None       # "angles" or "vector" in the program (default: the dialect's)
    holder_clearance: float = 0.3
    out: str = "tsplcam-job"
    extra: dict = field(default_factory=dict)


def run_job(s: JobSettings, log=print) -> dict:
    """Model -> processing list -> path -> tool axes -> program, with a report; files in ``s.out``."""
    from .orientation import load_tool
    from .plan import save as save_list
    from .post import load_machine, post_program
    from .toolpath import zigzag_path
    from .toolpath.cldata import write_cl
    from .toolpath.commands import load_model
    from .toolpath.zigzag import default_plan
    from .verify.metrics import path_metrics
    os.makedirs(s.out, exist_ok=True)
    figures: dict = {"settings": s.__dict__.copy()}
    t_all = time.perf_counter()
    t = time.perf_counter()
    model = load_model(s.model)
    log(f"model {s.model}: {len(model.patches)} patches, "
        f"{sum(not e.boundary for e in model.extraordinary)} extraordinary points ({time.perf_counter() - t:.2f} s)")
    t = time.perf_counter()
    plist = default_plan(model)
    save_list(plist, os.path.join(s.out, "processing-list.json"))
    log(f"processing list: {len(plist.steps)} steps, {plist.retractions} retractions, "
        f"{plist.corner_links} corner links ({time.perf_counter() - t:.2f} s)")
    tool = load_tool(s.tool)
    machine = load_machine(s.machine)
    t = time.perf_counter()
    path = zigzag_path(model, plist, tool.ball_radius, s.scallop, s.chord_tol)
    m = path_metrics(path)
    log(f"path: {m.lines} lines, {m.points} points, {m.length:.1f} mm, {m.retractions} retractions "
        f"({time.perf_counter() - t:.2f} s)")
    figures["path"] = m.as_dict()
    t = time.perf_counter()
    oriented = orient_path(path, model, s.orientation, tool, machine, sample_stock(s.model), s.holder_clearance,
                           progress=_progress("orienting: poses checked / at most"))
    if oriented.metrics is not None:
        log(f"tool axes ({s.orientation}): {oriented.metrics.summary()} ({time.perf_counter() - t:.2f} s)")
        figures["orientation"] = oriented.metrics.as_dict()
    t = time.perf_counter()
    posted = post_program(oriented.path, machine, s.dialect, orientation=s.axes_form)
    ext = {"heidenhain": ".h", "sinumerik": ".mpf", "fanuc": ".nc", "linuxcnc": ".ngc"}.get(posted.dialect, ".nc")
    program = os.path.join(s.out, f"{os.path.basename(s.model).split('.')[0]}{ext}")
    posted.write(program)
    cl = os.path.join(s.out, f"{os.path.basename(s.model).split('.')[0]}.cl")
    write_cl(oriented.path, cl)
    log(posted.summary())
    figures["machining_time_s"] = posted.time.total_s
    from .verify.orientation import machine_motion
    figures["machine_motion"] = machine_motion(posted, oriented.path)
    mm = figures["machine_motion"]
    log(f"machine motion: time {mm['time_s']:.1f} s = {mm['time_ratio']:.3f} x length/feed "
        f"({mm['length_feed_time_s']:.1f} s); C travel {mm['c_travel_deg']:.0f} deg "
        f"({mm['c_deg_per_mm']:.2f} deg/mm), branch flips {mm['branch_flips']}, pole points "
        f"{mm['pole_points']}, largest axis step {mm['max_axis_step_deg']:.2f} deg, retract-reorient "
        f"{mm['reorientations']}")
    figures["seconds"] = time.perf_counter() - t_all
    with open(os.path.join(s.out, "report.json"), "w", encoding="utf-8") as fh:
        from .toolpath.commands import _json_default
        json.dump(figures, fh, indent=2, sort_keys=True, default=_json_default)
        fh.write("\n")
    log(f"wrote {program}, {cl}, processing-list.json and report.json in {s.out} "
        f"({figures['seconds']:.1f} s in all)")
    return figures


def _cmd_job(args) -> int:
    from . import __version__
    print(f"tsplcam {__version__}: the paper's keycap job (shang2020 section 4)")
    s = JobSettings(out=args.out)
    for k in ("model", "tool", "scallop", "orientation", "machine", "dialect", "axes_form"):
        v = getattr(args, k)
        if v is not None:
            setattr(s, k, v)
    run_job(s)
    return 0


def add_job_command(subparsers) -> None:
    p = subparsers.add_parser("job", help="the main job on the bundled default model: keycap, 1 mm ball, "
                                          "5 um scallop, smooth collision-free axes, Heidenhain program")
    p.add_argument("--out", default="tsplcam-job", help="output folder (default ./tsplcam-job)")
    p.add_argument("--model", help="model file or sample name (default keycap)")
    p.add_argument("--tool", help="tool (default ball1_keycap)")
    p.add_argument("--scallop", type=float, help="scallop height (mm, default 0.005)")
    p.add_argument("--orientation", choices=ORIENTATIONS, help="tool axes (default smooth)")
    p.add_argument("--machine", help="machine (default mikron_ucp600_heidenhain)")
    p.add_argument("--dialect", help="controller dialect (default: the machine's)")
    p.add_argument("--axes-form", choices=("angles", "vector"),
                   help="tool axes in the program as machine angles (default) or as the tool vector")
    p.set_defaults(func=_cmd_job)
