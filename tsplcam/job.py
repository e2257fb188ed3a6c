"""The ``path`` and ``job`` commands: settings from the command line, the program from
:mod:`tsplcam.program`, the files and the report.

``python3 -m tsplcam path MODEL --tool-radius R --scallop H [...]``: one path with the
files asked for (``--cl``, ``--gcode``, ``--json``), tool axes by ``--orientation``
(default: the surface normal), a program when ``--machine`` and ``--gcode`` are given.

``python3 -m tsplcam job [MODEL] [--config JOB.json] [--out DIR] [...]``: model ->
processing list -> path -> tool axes -> program with every default of
:class:`tsplcam.settings.JobSettings` (the main job), the surface verification
(``--no-verify`` skips it) and the compound-NURBS baseline on request (``--baseline``);
writes the program, the CL data, ``processing-list.json``, ``report.json`` and
``report.html`` with its pictures (:mod:`tsplcam.report`) into DIR. ``--config`` reads a
job file (:mod:`tsplcam.jobfile`); options given beside it override its values.

Both commands take the options of :class:`JobSettings`, generated from its fields. Every
option is checked and every input read before the long work starts; the files are written
at the end, all at once (:mod:`tsplcam.outfile`): a refused or failed run leaves no file.
The report's figures depend only on the inputs; the run times are kept apart in its
``timing`` block. Its ``path_s`` and ``orientation_s`` are the wall times of the two stages;
while worker processes make the path's points the main process builds the orientation's
collision checker (and loads the compiled kernels), so with workers that build counts in
``path_s`` (the log's path line says how long it took), with one process in
``orientation_s`` as before. With workers the tool axes' metrics are checked in a forked
process while the program is posted: ``post_s`` is the post's own time and
``orientation_s`` holds the tool axes and whatever wait for their metrics follows the post
(:func:`tsplcam.program.make_program`).
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import tempfile
import time
from dataclasses import dataclass, field, fields

from . import load_model
from .errors import InputError
from .outfile import check_folder, check_writable, make_folders, replace_folder, write_texts
from .progress import TerminalProgress, for_stage, report
from .program import (checker_ahead, load_machine, load_stock, load_tool, make_baseline, make_path,
                      make_program, processing_list, program_file_name, tool_radius)
from .settings import GROUPS, NUMBER_KINDS, JobSettings, choices_of, default_of, help_text

# what differs between the two commands: the model is an argument of `path`, which also
# needs the ball radius (or a tool) and the scallop and makes no tool axes or program unless
# asked for
COMMANDS = {
    "path": dict(positional="model", required=("scallop",),
                 defaults=dict(tool=None, machine=None, orientation="normal", verify=False),
                 help="finishing path over the whole part without retractions; CL data, tool axes and G-code "
                      "on request",
                 description="A ball-end finishing path over every patch of the part, patch after patch in "
                             "the processing list's order. Lengths in mm, feeds in mm/min. Exit code 0, or 2 "
                             "with one line naming the option, file or place on bad input or a refused "
                             "geometry."),
    "job": dict(positional=None, required=(), defaults={},
                help="the whole job, model to machine program and report (default: keycap, 1 mm ball, 0.005 mm "
                     "scallop, smooth collision-free axes, Heidenhain)",
                description="Model, processing list, path, tool axes and machine program in one run, the "
                            "scallop measured on the surface; writes the program, CL data, processing-list.json, "
                            "report.json and report.html with its pictures into --out. MODEL may also be given "
                            "as --model or in the job file. Lengths in mm, feeds in mm/min. Exit code 0, or 2 "
                            "with one line naming the option, file or place."),
}
VECTOR_KINDS = {"vector": 3, "pair": 2}


# -- options from the settings' fields ----------------------------------------------------------
def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def _numbers(n: int):
    """An argument type for ``n`` comma-separated numbers ('0,0,1')."""
    def parse(text: str) -> tuple:
        parts = text.replace(" ", "").split(",")
        try:
            values = tuple(float(x) for x in parts)
        except ValueError:
            values = ()
        if len(values) != n:
            raise argparse.ArgumentTypeError(f"{text!r} is not {n} numbers separated by commas")
        return values
    return parse


def flags_of(f) -> tuple:
    return f.metadata["flags"] or ("--" + f.name.replace("_", "-"),)


def label_for(command: str):
    """How the command line spells an option: ``tool_radius`` -> ``--tool-radius``."""
    spec = COMMANDS[command]
    by_name = {f.name: (f.metadata["metavar"] if f.name == spec["positional"] else flags_of(f)[0])
               for f in fields(JobSettings)}
    return lambda name: by_name.get(name, name)


def add_options(parser, command: str) -> None:
    """The options of ``command``, one per field of JobSettings that it takes."""
    spec = COMMANDS[command]
    names = set(JobSettings.option_names(command))
    groups = {}
    for f in fields(JobSettings):
        if f.name not in names:
            continue
        md = f.metadata
        default = spec["defaults"].get(f.name, default_of(f))
        text = help_text(f)
        if f.name == spec["positional"]:
            parser.add_argument(f.name, metavar=md["metavar"], help=text)
            continue
        kw = dict(dest=f.name, default=argparse.SUPPRESS)
        flags = flags_of(f)
        if md["kind"] == "flag":
            if len(flags) == 2 and flags[1] == "--no-" + flags[0][2:]:       # --verify / --no-verify
                kw["action"] = argparse.BooleanOptionalAction
                flags = flags[:1]
                text += f" (default: {'on' if default else 'off'})"
            else:
                kw["action"] = "store_false" if default else "store_true"
        else:
            kind = md["kind"]
            kw.update(metavar=md["metavar"], type=_number if kind in NUMBER_KINDS
                      else _numbers(VECTOR_KINDS[kind]) if kind in VECTOR_KINDS else str)
            if md["kind"] == "choice":
                kw["choices"] = choices_of(f)
                kw.pop("metavar") if md["metavar"] is None else None
            if f.name in spec["required"]:
                kw["required"] = True
            elif default is not None and "default:" not in text:
                shown = (f"{default:g}" if isinstance(default, float) else
                         ",".join(f"{x:g}" for x in default) if isinstance(default, tuple) else str(default))
                unit = text.endswith(("(mm)", "(mm/min)", "(deg)", "(rpm)"))
                text = text[:-1] + f", default {shown})" if unit else text + f" (default {shown})"
        if md["group"] not in groups:
            groups[md["group"]] = parser.add_argument_group(GROUPS[md["group"]])
        groups[md["group"]].add_argument(*flags, help=text, **kw)


def settings_from_args(args, command: str) -> JobSettings:
    """JobSettings of the parsed arguments over the command's defaults (and, for ``job``, over
    the job file of ``--config``), checked; errors name the option as the command line spells
    it, or the job file and its key."""
    names = set(JobSettings.option_names(command))
    given = {k: v for k, v in vars(args).items() if k in names}
    model = getattr(args, "model_arg", None)
    if model is not None:
        if "model" in given and given["model"] != model:
            raise InputError(f"the model is given twice, as MODEL {model!r} and as --model {given['model']!r}",
                             item="--model")
        given["model"] = model
    defaults = COMMANDS[command]["defaults"]
    config = getattr(args, "config", None)
    if config:             # errors name the file and its key, or the option as typed
        from .jobfile import job_settings
        return job_settings(config, overrides=given, defaults=defaults, label=label_for(command))
    with named_options(command):
        return JobSettings(**{**defaults, **given}).check(label_for(command))


@contextlib.contextmanager
def named_options(command: str):
    """Errors about an option (InputError.item a field name) name it as the command line does."""
    label = label_for(command)
    try:
        yield label
    except InputError as exc:
        if exc.item is None or label(exc.item) == exc.item:
            raise
        raise InputError(exc.message, path=exc.path, line=exc.line, item=label(exc.item)) from None


#: significant digits of a report's numbers (:func:`json_text`)
REPORT_DIGITS = 12


def json_text(doc: dict) -> str:
    """A report as JSON text: sorted keys, numpy numbers as plain ones, every real number
    to :data:`REPORT_DIGITS` significant digits, LF line ends.

    Twelve digits are nanometres on a metre-sized part, far below any figure's meaning; the
    digits beyond them carry only the rounding of the sums a statistic is reduced by (a mean
    axis step summed over a thousand steps moves in its 15th digit when one step's last bit
    does), which the program's own numbers, written to a micrometre, never show."""
    import numpy as np

    def plain(x):
        if isinstance(x, (float, np.floating)):
            x = float(x)
            return float(f"{x:.{REPORT_DIGITS}g}") if np.isfinite(x) else x
        if isinstance(x, bool):
            return x
        if isinstance(x, (int, np.integer)):
            return int(x)
        if isinstance(x, dict):
            return {k: plain(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [plain(v) for v in x]
        if isinstance(x, np.ndarray):
            return plain(x.tolist())
        if isinstance(x, str) or x is None:
            return x
        return str(x)
    return json.dumps(plain(doc), indent=2, sort_keys=True) + "\n"


def _check_outputs(outputs: list, label) -> None:
    """Refuse an output whose folder is missing or not writable, and one file given twice."""
    seen = {}
    for name, filename, what in outputs:
        if not filename:
            continue
        check_writable(filename, what, item=label(name))
        key = os.path.realpath(filename)
        if key in seen:
            raise InputError(f"the same file as {label(seen[key])}", path=filename, item=label(name))
        seen[key] = name


# -- the path command -------------------------------------------------------------------------
def _cmd_path(args) -> int:
    s = settings_from_args(args, "path")
    t0 = time.perf_counter()
    with named_options("path") as label:
        _check_outputs([("gcode", s.gcode, "program"), ("cl", s.cl, "CL file"), ("report", s.report, "report"),
                        ("baseline_cl", s.baseline_cl, "CL file")], label)
        model = load_model(s.model)
        plist = processing_list(model, s)
        tool = load_tool(s)
        radius = tool_radius(s, tool)
        load_machine(s)
        stock = load_stock(s) if s.orientation != "normal" else None
        timing = {}
        bar = TerminalProgress()
        ahead = checker_ahead(model, s, tool, stock)
        path = make_path(model, plist, s, radius, progress=bar, while_waiting=ahead)
        path.info["model"] = os.path.basename(s.model)
        timing["path_s"] = path.info["seconds"]
        baseline = None
        if s.baseline or s.baseline_cl:
            baseline = make_baseline(model, plist, s, radius)
            baseline.info["model"] = os.path.basename(s.model)
            timing["baseline_s"] = baseline.info["seconds"]
        verification = None
        if s.verify:
            from .verify.scallop import measure
            t = time.perf_counter()
            verification = measure(path, model, progress=for_stage(bar, "scallop"))
            timing["verify_s"] = time.perf_counter() - t
        program = make_program(path, model, s, stock=stock, progress=bar, post=bool(s.gcode), plist=plist,
                               checker=None if ahead is None else ahead.checker,
                               beside=cl_text if s.cl else None)
        timing.update(program.seconds)
        files = []
        if s.cl:
            files.append((s.cl, program.beside, "CL file", "ascii"))
        if baseline is not None and s.baseline_cl:
            files.append((s.baseline_cl, cl_text(baseline), "CL file", "ascii"))
        if s.report:
            timing["total_s"] = time.perf_counter() - t0
            doc = path_figures(program, verification, baseline)
            doc["timing"] = timing
            files.append((s.report, json_text(doc), "report"))
        if program.posted is not None:
            files.append((s.gcode, program.posted.text, "program", "ascii"))
        written = write_texts(files)
    print(path_report(program.path, verification, baseline))
    if program.report is not None:
        print(program.report.summary())
        print(program.metrics.summary())
    if program.posted is not None:
        print(program.posted.summary())
        print(motion_summary(motion_figures(program)))
    for f in written:
        print(f"wrote {f}")
    print(f"time taken {time.perf_counter() - t0:.2f} s")
    return 0


def cl_text(path) -> str:
    from .toolpath.cldata import cl_text as text
    return text(path)


def _summary(path) -> dict:
    """Figures of a path; its run times go to the report's timing block."""
    from .verify.metrics import path_metrics
    patches = [{k: v for k, v in d.items() if k != "seconds"} for d in path.info.get("patches", [])]
    return {"metrics": path_metrics(path).as_dict(), "patches": patches, "settings": path.info.get("settings", {})}


def path_figures(program, verification=None, baseline=None) -> dict:
    """The ``path --json`` report (without its timing block)."""
    doc = {"path": _summary(program.path)}
    if verification is not None:
        doc["verification"] = verification.as_dict()
    if program.metrics is not None:
        doc["orientation"] = program.metrics.as_dict()
    if program.posted is not None:
        doc["machining_time_s"] = program.posted.time.total_s
        doc["machine_motion"] = motion_figures(program)
    if baseline is not None:
        doc["baseline"] = _summary(baseline)
    return doc


def path_report(path, verification=None, baseline=None) -> str:
    """The text the path command prints."""
    from .verify.metrics import compare_table, path_metrics
    s = path.info["settings"]
    out = [f"{path.info.get('model', '')}: ball radius {s['tool_radius']:g} mm, scallop {s['scallop']:g} mm, "
           f"chord tolerance {s['chord_tol']:g} mm"]
    rows = [("step", "patch", "crossfeed", "start", "finish", "lines", "scallop used", "points", "cut mm")]
    for d in path.info["patches"]:
        rows.append((str(d["step"]), str(d["patch"]), d["crossfeed"], d["start"], d["finish"], str(d["lines"]),
                     f"{d['scallop_used']:.5g}", str(d["points"]), f"{d['cut_length']:.1f}"))
    w = [max(len(r[k]) for r in rows) for k in range(len(rows[0]))]
    out += ["  " + "  ".join(c.rjust(wk) for c, wk in zip(r, w)) for r in rows]
    m = path_metrics(path)
    out.append(f"{m.points} points, {m.lines} lines, length {m.length:.1f} mm (cut {m.cut_length:.1f}, "
               f"link {m.link_length:.1f}, air {m.air_length:.1f}), {m.retractions} retractions; "
               f"generated in {path.info['seconds']:.2f} s")
    if verification is not None:
        v = verification
        out.append(f"measured on {v.samples} surface samples + {v.ridges} ridges: largest scallop "
                   f"{v.max_scallop:.5f} mm at patch {v.max_at[0]} (u, v) = ({v.max_at[1]:.4f}, {v.max_at[2]:.4f}); "
                   f"cusp mean {v.cusp_mean:.5f} mm; mean material {v.mean_material:.5f} mm; gouge at points "
                   f"{v.gouge_points:.2e} mm, on chords {v.gouge_chords:.2e} mm, in the air {v.gouge_air:.2e} mm")
    if baseline is not None:
        out.append("T-spline path against the compound-NURBS baseline (each face on its own):")
        out.append(compare_table({"T-spline": m, "baseline": path_metrics(baseline)}))
    return "\n".join(out)


# -- the job ----------------------------------------------------------------------------------
@dataclass
class JobResult:
    """What the job's stages made, before any file is written: the inputs read, the path as
    generated, the Program (tool axes, metrics, posted program, collision checker), and the
    verification and baseline when asked for. ``timing``: seconds per stage."""
    settings: JobSettings
    model: object
    plist: object
    tool: object
    machine: object
    stock: object
    path: object
    program: object
    verification: object = None
    baseline: object = None
    timing: dict = field(default_factory=dict)
    cl: str | None = None              # the CL data's text, made beside the post (Program.beside)
    clearance: object = None           # the report's clearance measurement, started meanwhile (a ClearanceSweep)

    def report_inputs(self) -> dict:
        """The keyword arguments of :func:`tsplcam.report.write_report` (the orientation's
        collision checker is handed on, so the report builds none of its own)."""
        return dict(model=self.model, path=self.path, processing_list=self.plist, oriented=self.program,
                    machine=self.machine, posted=self.program.posted, verification=self.verification,
                    baseline=self.baseline, settings=report_settings(self.settings),
                    tool=self.tool, stock=self.stock, checker=self.program.checker, clearance=self.clearance)


def report_settings(s: JobSettings) -> dict:
    """The job's settings as its reports show them: every option of the job but the folder
    the reports are in, so that a report does not depend on where it was written."""
    return s.to_dict([k for k in JobSettings.option_names("job") if k != "out"])


def make_job(s: JobSettings, log=None, progress=None, baseline_axes: str = "job",
             report_ahead: bool = False) -> JobResult:
    """Model -> processing list -> path -> tool axes -> program, then the surface
    verification (``s.verify``, heights kept for the report's map) and the compound-NURBS
    baseline (``s.baseline``; ``baseline_axes`` "job" gives it tool axes by the job's
    strategy, "normal" keeps its surface normals). ``log(text)`` is told each stage's result;
    ``progress``: a tsplcam.progress callback. ``report_ahead``: the HTML report follows, so
    its clearance measurement starts in a forked process on the core the verification's last
    patch leaves idle, when no baseline is to be made (``JobResult.clearance``, for
    :func:`tsplcam.report.write_report`).
    Writes nothing."""
    from .verify.metrics import path_metrics
    log = log or (lambda text: None)
    if baseline_axes not in ("job", "normal"):
        raise ValueError(f"baseline_axes must be 'job' or 'normal', not {baseline_axes!r}")
    s.check()
    if not s.machine:
        raise InputError("the job makes a machine program: give a machine", item="machine")
    timing = {}
    t = time.perf_counter()
    model = load_model(s.model)
    timing["model_s"] = time.perf_counter() - t
    log(f"model {s.model}: {len(model.patches)} patches, "
        f"{sum(not e.boundary for e in model.extraordinary)} extraordinary points ({timing['model_s']:.2f} s)")
    t = time.perf_counter()
    plist = processing_list(model, s)
    timing["plan_s"] = time.perf_counter() - t
    log(f"processing list: {len(plist.steps)} steps, {plist.retractions} retractions, "
        f"{plist.corner_links} corner links ({timing['plan_s']:.2f} s)")
    tool = load_tool(s)
    radius = tool_radius(s, tool)
    machine = load_machine(s)
    stock = load_stock(s)
    ahead = checker_ahead(model, s, tool, stock)
    t = time.perf_counter()
    path = make_path(model, plist, s, radius, progress=progress, while_waiting=ahead)
    timing["path_s"] = time.perf_counter() - t
    m = path_metrics(path)
    meanwhile = "" if ahead is None or ahead.checker is None else \
        f"; collision checker built meanwhile in {ahead.seconds:.2f} s"
    log(f"path: {m.lines} lines, {m.points} points, {m.length:.1f} mm, {m.retractions} retractions "
        f"({timing['path_s']:.2f} s{meanwhile})")
    program = make_program(path, model, s, stock=stock, progress=progress, plist=plist,
                           checker=None if ahead is None else ahead.checker, beside=cl_text)
    timing.update(program.seconds)
    if program.metrics is not None:
        log(f"tool axes ({s.orientation}): {program.metrics.summary()} ({timing['orientation_s']:.2f} s)")
    log(program.posted.summary())
    job = JobResult(s, model, plist, tool, machine, stock, path, program, timing=timing, cl=program.beside)
    try:
        if s.verify:
            from .verify.scallop import measure
            t = time.perf_counter()
            # (not with the baseline to make next: a sweep started now shares the cores with it,
            # the keycap's job with --baseline 3.904 -> 3.988 s)
            ahead = _clearance_ahead(job) if report_ahead and not s.baseline else None
            job.verification = measure(path, model, heights=True, progress=for_stage(progress, "scallop"),
                                       when_idle=ahead)
            timing["verify_s"] = time.perf_counter() - t
            v = job.verification
            log(f"scallop measured on {v.samples:,d} surface samples + {v.ridges:,d} ridges: largest "
                f"{v.max_scallop:.5f} mm of {s.scallop:g} mm, gouge at points {v.gouge_points:.1e} mm "
                f"({timing['verify_s']:.2f} s)")
        if s.baseline:
            t = time.perf_counter()
            report(progress, "baseline", 0, 1)
            base = make_baseline(model, plist, s, radius)
            report(progress, "baseline", 1, 1)
            if baseline_axes == "job" and s.orientation != "normal":
                renamed = None if progress is None else (
                    lambda stage, done, total: progress("baseline axes" if stage == "tool axes" else stage, done, total))
                base = make_program(base, model, s, stock=stock, progress=renamed, post=False,
                                    checker=job.program.checker)
            job.baseline = base
            timing["baseline_s"] = time.perf_counter() - t
            b = path_metrics(getattr(base, "path", base))
            log(f"compound-NURBS baseline: {b.retractions} retractions, {b.air_moves} air moves, "
                f"{b.length:.1f} mm ({timing['baseline_s']:.2f} s)")
    except BaseException:
        if job.clearance is not None:                # (the report it was for is not written)
            job.clearance.close()
        raise
    return job


def _clearance_ahead(job: JobResult):
    """The verification's ``when_idle``: the report's clearance measurement
    (:class:`tsplcam.report.report.ClearanceSweep` with the job's checker) started in a forked
    process, where the report measures one and a fork is to be had. On the keycap the
    verification's last patch left one core idle for 0.37 s, and the report then waited
    0.2-0.3 s for this measurement after drawing its other pictures."""
    def start() -> None:
        from .orientation.aside import Aside
        from .report.report import ClearanceSweep, clearance_wanted
        checker = job.program.checker
        if job.clearance is None and checker is not None and clearance_wanted(job.tool) and Aside.can_fork():
            job.clearance = ClearanceSweep(checker, job.program.path)
    return start


def job_figures(job: JobResult) -> dict:
    """report.json of a job (its timing block apart)."""
    from .verify.metrics import path_metrics
    s, program = job.settings, job.program
    figures = {"settings": report_settings(s), "path": path_metrics(program.path).as_dict(),
               "machining_time_s": program.posted.time.total_s,
               "machine_motion": motion_figures(program)}
    if program.metrics is not None:
        figures["orientation"] = program.metrics.as_dict()
    if job.verification is not None:
        figures["verification"] = job.verification.as_dict()
    if job.baseline is not None:
        figures["baseline"] = {"path": path_metrics(getattr(job.baseline, "path", job.baseline)).as_dict()}
    return figures


def import_ahead() -> None:
    """Import the modules the job loads where it first needs them (kept lazy so that
    ``import tsplcam`` stays light): the TSP solver, the forked processes' queues, the
    clearance and path metrics, the CL writer and the post's dialects. Called before the
    job's clock starts: loading the program's code is start-up, as the command's own imports
    are (without byte-code caches about 20 ms of compiling, 6.5 ms of it in the forked
    process's clearance search on the keycap job)."""
    import elkai  # noqa: F401
    import multiprocessing.popen_fork  # noqa: F401
    import multiprocessing.queues  # noqa: F401
    import multiprocessing.sharedctypes  # noqa: F401
    import multiprocessing.synchronize  # noqa: F401
    from .orientation import warmup  # noqa: F401
    from .post import dialects
    from .toolpath import cldata  # noqa: F401
    from .verify import metrics, orientation  # noqa: F401
    for name in dialects.NAMES:
        dialects.get(name)


def run_job(s: JobSettings, log=print, progress=None) -> dict:
    """The job (:func:`make_job`) and its files in ``s.out`` (made when missing), all written
    at the end: program, CL data, processing list, report.json and, with ``s.html_report``,
    report.html with its pictures. Returns report.json's content. ``progress``: a
    tsplcam.progress callback (default: a bar on stderr)."""
    log = log or (lambda text: None)
    progress = progress or TerminalProgress()
    s.check()
    check_folder(s.out, item="out")
    if s.fcstd:
        from .workbench.headless import check_fcstd
        check_fcstd(s.fcstd)
    import_ahead()
    t_all = time.perf_counter()
    job = make_job(s, log, progress, report_ahead=s.html_report)
    try:
        return _write_job(s, job, t_all, log, progress)
    finally:
        if job.clearance is not None:                # (closed by the report, unless it failed first)
            job.clearance.close()


def _write_job(s: JobSettings, job: JobResult, t_all: float, log, progress) -> dict:
    """:func:`run_job`'s files of ``job`` (its clock started at ``t_all``)."""
    from .plan.listfile import dumps as list_text
    from .post.dialects import extension
    timing = job.timing
    figures = job_figures(job)
    log(motion_summary(figures["machine_motion"]))
    post = job.program.posted
    name = s.name + extension(post.dialect) if s.name else program_file_name(s.model, post.dialect)
    cl_name = os.path.splitext(name)[0] + ".cl"
    figures["files"] = {"program": name, "cl": cl_name}
    files = [(os.path.join(s.out, name), post.text, "program", "ascii"),
             (os.path.join(s.out, cl_name), job.cl if job.cl is not None else cl_text(job.program.path),
              "CL file", "ascii"),
             (os.path.join(s.out, "processing-list.json"), list_text(job.plist), "processing list")]
    made = make_folders(s.out)
    draft = None
    try:
        if s.html_report:
            from .report import write_report
            t = time.perf_counter()
            draft = tempfile.mkdtemp(prefix=".report-", dir=s.out)
            page = write_report(draft, progress=progress, **job.report_inputs())
            with open(page, encoding="utf-8") as fh:
                files.append((os.path.join(s.out, "report.html"), fh.read(), "report"))
            timing["report_s"] = time.perf_counter() - t
        timing["total_s"] = time.perf_counter() - t_all
        figures["timing"] = timing
        files.append((os.path.join(s.out, "report.json"), json_text(figures), "report"))
        written = write_texts(files)
        if draft is not None:
            replace_folder(os.path.join(draft, "report_files"), os.path.join(s.out, "report_files"),
                           "report's pictures")
    except BaseException:
        for folder in reversed(made):          # a failed run leaves no folder it made
            shutil.rmtree(folder, ignore_errors=True)
        raise
    finally:
        if draft is not None:
            shutil.rmtree(draft, ignore_errors=True)
    names = [os.path.basename(f) for f in written]
    log(f"wrote {', '.join(names[:-1])} and {names[-1]} in {s.out} ({timing['total_s']:.1f} s in all"
        + (f"; report {timing['report_s']:.1f} s" if "report_s" in timing else "") + ")")
    if s.html_report:
        log(f"report: {os.path.abspath(os.path.join(s.out, 'report.html'))}")
    if s.fcstd:
        from .workbench.headless import write_fcstd
        log(f"wrote {write_fcstd(s, job.plist, job.path, job.program)} (FreeCAD document with a CAM job)")
    return figures


def motion_figures(program) -> dict:
    """report.json's ``machine_motion``: what the machine does with the posted program
    (tsplcam.verify.orientation.machine_motion) and, beside its C travel, the least C travel
    the tool-axis cones, the collisions and the tilt range force on the orientation stage's
    pose grid (``c_travel_forced_deg``; tsplcam.orientation.smoothing.forced_rotary_travel)
    and the ratio of the two."""
    from .verify.orientation import machine_motion
    mm = machine_motion(program.posted, program.path)
    forced = program.path.info.get("orientation", {}).get("c_travel_forced_deg")
    if forced is not None:
        mm["c_travel_forced_deg"] = forced
        mm["c_travel_over_forced"] = round(mm["c_travel_deg"] / forced, 6) if forced > 0 else None
    return mm


def motion_summary(mm: dict) -> str:
    """One line of what the machine does: time against length/feed, C travel (and what the
    cones force), flips, poles."""
    forced = f", forced {mm['c_travel_forced_deg']:.0f} deg" if mm.get("c_travel_forced_deg") is not None else ""
    return (f"machine motion: time {mm['time_s']:.1f} s = {mm['time_ratio']:.3f} x length/feed "
            f"({mm['length_feed_time_s']:.1f} s); C travel {mm['c_travel_deg']:.0f} deg{forced} "
            f"({mm['c_deg_per_mm']:.2f} deg/mm), branch flips {mm['branch_flips']}, pole points "
            f"{mm['pole_points']}, largest axis step {mm['max_axis_step_deg']:.2f} deg, retract-reorient "
            f"{mm['reorientations']}")


def _cmd_job(args) -> int:
    from . import __version__
    s = settings_from_args(args, "job")
    print(f"tsplcam {__version__}: {s.model}, tool {s.tool}, scallop {s.scallop:g} mm, "
          f"{s.orientation} tool axes, {s.machine}")
    with named_options("job"):
        run_job(s)
    return 0


# -- registering ------------------------------------------------------------------------------
def register(subparsers, command: str) -> None:
    """Add ``command`` (``path`` or ``job``) to the tsplcam command line."""
    spec = COMMANDS[command]
    p = subparsers.add_parser(command, help=spec["help"], description=spec["description"])
    if command == "job":
        p.add_argument("model_arg", nargs="?", metavar="MODEL", default=None,
                       help="the part, as --model (give it once)")
        p.add_argument("--config", metavar="JOB.json", help="read the job's settings from a job file (keys: the "
                       "options' names, file names relative to the file; tsplcam/JOBFILE.md); options given "
                       "beside it override its values")
    add_options(p, command)
    p.set_defaults(func={"path": _cmd_path, "job": _cmd_job}[command])
