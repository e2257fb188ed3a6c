"""From settings to a machine program: the one place where the stages are put together.

    model ──> processing list ──> path ──> tool axes ──> machine program
    load_model  processing_list   make_path    make_program (orientation, post)

The command line (``path`` and ``job``, :mod:`tsplcam.job`), batch runs and the workbench's
program object all call these functions with a :class:`tsplcam.settings.JobSettings`, so
the same settings give the same program bytes wherever they come from.
"""
from __future__ import annotations

import contextlib
import functools
import multiprocessing
import os
import time
from dataclasses import dataclass, field

from . import load_model
from .errors import InputError
from .numerics import one_blas_thread
from .settings import PATH_KEYS, JobSettings

__all__ = ["CheckerAhead", "Program", "checker_ahead", "load_model", "load_stock", "load_tool", "make_baseline",
           "make_path", "make_program", "processing_list", "program_file_name", "tool_radius"]


@contextlib.contextmanager
def _option(name: str):
    """An InputError raised while reading what option ``name`` gives names that option."""
    try:
        yield
    except InputError as exc:
        if exc.item is not None:
            raise
        raise InputError(exc.message, path=exc.path, line=exc.line, item=name) from None


def processing_list(model, settings: JobSettings):
    """The list of ``settings.processing_list`` checked against the model's layout, or the
    planner's list when there is none."""
    if settings.processing_list:
        from .plan import load as load_list
        from .layout.layout import Layout
        with _option("processing_list"):
            return load_list(settings.processing_list, Layout.from_model(model))
    from .toolpath.zigzag import default_plan
    return default_plan(model)


def load_tool(settings: JobSettings):
    """The cutter of ``settings.tool`` (None when no tool is given), its ball radius checked
    against ``settings.tool_radius`` when both are given."""
    if not settings.tool:
        return None
    from .orientation import load_tool as load
    with _option("tool"):
        tool = load(settings.tool)
    if settings.tool_radius is not None and abs(tool.ball_radius - settings.tool_radius) > 1e-9:
        raise InputError(f"{settings.tool_radius:g} mm differs from the ball radius {tool.ball_radius:g} mm "
                         f"of tool {tool.name!r}", item="tool_radius")
    return tool


def tool_radius(settings: JobSettings, tool=None) -> float:
    """The ball radius the path is made for: ``settings.tool_radius``, else the tool's."""
    if settings.tool_radius is not None:
        return float(settings.tool_radius)
    tool = tool or load_tool(settings)
    if tool is None:
        raise InputError("give the ball radius or a tool", item="tool_radius")
    return float(tool.ball_radius)


def load_machine(settings: JobSettings):
    """The Machine of ``settings.machine``, or None; the feed and the spindle speed of
    ``settings`` are checked against its limits (before any long work starts)."""
    if not settings.machine:
        return None
    from .post import load_machine as load
    with _option("machine"):
        machine = load(settings.machine)
    machine.check_feed(settings.feed, "feed")
    machine.check_spindle(settings.spindle, "spindle")
    if settings.axes_form is not None:
        from .post.post import dialect_of
        mod = dialect_of(machine, settings.dialect)
        if settings.axes_form not in mod.ORIENTATIONS:
            raise InputError(f"the {mod.NAME} dialect writes the tool axes as {' or '.join(mod.ORIENTATIONS)}, "
                             f"not as the tool {settings.axes_form}", item="axes_form")
    return machine


def load_stock(settings: JobSettings):
    """The stock triangles (vertices (n,3), triangles (m,3)): the OBJ file of
    ``settings.stock``, else the block a shipped sample brings, else None."""
    if settings.stock:
        from .errors import InputError
        from .model.formats import reader_for
        with _option("stock"):
            reader = reader_for(settings.stock, surface=False)
            if reader is None:
                raise InputError("a stock mesh is read from an OBJ file (.obj)", path=settings.stock)
            return reader.read(settings.stock)
    from .model.samples import sample_stock
    return sample_stock(settings.model)


def make_path(model, plist, settings: JobSettings, radius: float | None = None, progress=None,
              while_waiting=None):
    """The finishing path (ToolPath) of ``model`` in the order of ``plist``: one zigzag per
    patch, linked at shared corners, tool axes along the surface normals. ``progress``: a
    tsplcam.progress callback (stage "path"); ``while_waiting``: work for this process
    while worker processes make the path's points (e.g. a :class:`CheckerAhead`; called only
    when there are workers, see :func:`tsplcam.toolpath.parallel.map_pieces`)."""
    one_blas_thread()
    from .toolpath import zigzag_path
    radius = tool_radius(settings) if radius is None else radius
    options = _path_options(settings, radius)
    return zigzag_path(model, plist, radius, progress=progress, while_waiting=while_waiting, **options)


class CheckerAhead:
    """The orientation stage's collision checker, built ahead: called as ``while_waiting``
    of :func:`make_path`, it builds the checker (the part's tessellation, the stock, the
    broad phase's distance grids) and loads the compiled kernels (the ahead-of-time module,
    else numba's machinery) while the path's workers make the points, in the main process,
    which takes the pieces left once it is done (it counts as one of the cores:
    :func:`tsplcam.toolpath.parallel.map_pieces`).

    ``checker``: the CollisionChecker once built (None when not called: one process, or
    failed); its time then counts in the path stage's seconds, not the orientation's
    (``seconds``: how long the build took). An error of the build is kept, not raised: the
    orientation stage builds the checker again and raises it there, after the path's own
    errors, as without this."""

    def __init__(self, model, tool, stock, clearance: float):
        self.model, self.tool, self.stock, self.clearance = model, tool, stock, float(clearance)
        self.checker = None
        self.seconds = 0.0
        self.error = None

    def __call__(self) -> None:
        t = time.perf_counter()
        try:
            self.checker = collision_checker(self.model, self.tool, self.stock, self.clearance)
        except Exception as exc:                  # raised again where the checker is built
            self.error = exc
        else:
            with contextlib.suppress(Exception):  # the orientation meets its own error, if any
                _load_numba()
        self.seconds = time.perf_counter() - t


def checker_ahead(model, settings: JobSettings, tool, stock) -> CheckerAhead | None:
    """A :class:`CheckerAhead` for the job of ``settings`` (None when the job orients no
    tool axes or names no tool: nothing to build)."""
    if settings.orientation == "normal" or tool is None:
        return None
    return CheckerAhead(model, tool, stock, settings.holder_clearance)


def collision_checker(model, tool, stock, clearance: float):
    """The orientation's CollisionChecker: ``model``'s patches and ``stock`` ((V, T) or
    None) against ``tool``, with the holder ``clearance`` (mm)."""
    from .orientation import CollisionChecker
    meshes = [] if stock is None else [("stock", stock[0], stock[1])]
    return CollisionChecker(model, tool, meshes=meshes, clearance=clearance)


def _load_numba() -> None:
    """Load the orientation's compiled kernels: the ahead-of-time module where it is built
    and current (about 1 ms), else import numba and load its compiler's machinery through a
    throwaway set of the kernels (their first call of a process costs about 0.1 s more than
    the next kernel's; :func:`tsplcam.compiled.prepare`, with the orientation's warm-up
    :func:`tsplcam.orientation.warmup.exercise`). The kernels the orientation uses are not
    touched: whether it runs them or numpy stays its own choice
    (:func:`tsplcam.compiled.kernels`), so the program is the same bytes."""
    from . import compiled
    from .orientation.warmup import exercise
    compiled.prepare(exercise)


def make_baseline(model, plist, settings: JobSettings, radius: float):
    """The comparison path: each face of the model machined on its own (compound NURBS),
    retracting between faces, in the order of ``plist``."""
    from .toolpath.baseline import baseline_path
    return baseline_path(model, radius, order=plist.order, **_path_options(settings, radius))


def _path_options(settings: JobSettings, radius: float) -> dict:
    """The path generator's keyword options, checked (scallop and chord tolerance below the
    ball radius)."""
    settings.path_settings(radius).check()
    return settings.to_dict(PATH_KEYS)


@dataclass
class Program:
    """A path with its tool axes, and the machine program when it was posted.

    ``report``: what the orientation did (None for surface-normal axes); ``metrics``: the
    axes measured again with the same collision checker (collisions, clearance, axis steps,
    rotary travel); ``posted``: the PostResult (program text, motion, time estimate);
    ``seconds``: run time of each step (orientation, post); ``checker``: the collision checker
    the axes were found and measured with (for more measurements, e.g. the report's);
    ``beside``: the value of :func:`make_program`'s ``beside`` work on the path."""
    path: object
    report: object = None
    metrics: object = None
    posted: object = None
    seconds: dict = field(default_factory=dict)
    checker: object = None
    beside: object = None


def make_program(path, model, settings: JobSettings, stock=None, progress=None, post: bool = True,
                 plist=None, checker=None, beside=None) -> Program:
    """Tool axes and machine program of ``path`` (a ToolPath of ``model``) by ``settings``
    (its ``tool``, ``orientation``, ``holder_clearance``, ``smoothing_length``,
    ``rotary_weight``, ``machine`` and ``dialect``). With more than one process the axes are
    measured (``metrics``) in a forked process while this one posts the program
    (:class:`~tsplcam.orientation.aside.Aside`): ``seconds["post_s"]`` is the post's wall time,
    ``seconds["orientation_s"]`` the tool axes' and what the wait for their metrics adds.

    ``stock``: (V, T) triangles the tool must clear besides the model (default:
    :func:`load_stock`); ``progress(stage, done, total)`` (tsplcam.progress) follows the
    tool axes ("tool axes": poses checked) and the program ("program"), and may raise
    Cancelled to stop; ``post``:
    False stops before the machine program; ``plist``: the processing list, whose steps may
    carry tool-axis settings for their patch; ``checker``: a CollisionChecker already built
    for this model, tool, stock and holder clearance (another path of the same job), reused
    rather than built again; ``beside(path)``: work of the caller's on the path with its axes
    (e.g. the job's CL text, a function of the path alone), its value in ``program.beside``:
    done in the forked process that measures the metrics, after their smallest clearance,
    while this one posts the program (the keycap's CL text, 8 ms, balances the two: this
    process's part of the post then took 0.065-0.068 s and the forked one's 0.048-0.052 s);
    with one process, or where the post stops early (``post`` False), here once the axes are
    made and measured. Raises InputError, CollisionError or KinematicsError naming the place; a path that
    collides is never returned."""
    one_blas_thread()
    machine = load_machine(settings)
    t = time.perf_counter()
    pending = None                     # the metrics, measured beside the post
    if settings.orientation != "normal":
        tool = load_tool(settings)
        if tool is None:
            raise InputError(f"orientation '{settings.orientation}' needs a tool with its shank and holder",
                             item="tool")
        if abs(tool.ball_radius - path.tool_radius) > 1e-9:
            raise InputError(f"tool {tool.name} has a ball of radius {tool.ball_radius:g} mm, the path was "
                             f"made for {path.tool_radius:g} mm: pick a matching tool or make the path for "
                             "that radius", item="tool")
        program, pending = _orient(path, model, settings, tool, machine,
                                   load_stock(settings) if stock is None else stock, progress, plist, checker,
                                   beside=post and machine is not None, work=beside)
        program.seconds["orientation_s"] = time.perf_counter() - t
    else:
        program = Program(path, beside=None if beside is None else beside(path))
    with contextlib.ExitStack() as stack:
        if pending is not None:
            stack.enter_context(pending)
        if post and machine is not None:
            from .post import post_program
            from .post.post import metrics_solution
            t = time.perf_counter()
            options = {} if settings.axes_form is None else {"orientation": settings.axes_form}
            if settings.spindle is not None:
                options["spindle"] = settings.spindle
            try:
                program.posted = post_program(program.path, machine, settings.dialect, progress=progress,
                                              **options)
                if pending is not None:      # (its metrics take the post's poses: the same values)
                    pending.joints = metrics_solution(program.posted)
            except Exception:
                if pending is not None:      # one process measures the axes first: its error first
                    pending.first()
                raise
            program.seconds["post_s"] = time.perf_counter() - t
        if program.report is not None:
            program.report.finish()      # (what orient left for this time: a figure of its report)
        if pending is not None:
            t = time.perf_counter()
            program.metrics = pending.result()
            program.beside = pending.beside()
            from .progress import report as tick
            tick(progress, "checking axes", 1, 1)
            program.seconds["orientation_s"] += time.perf_counter() - t
    return program


class _Metrics:
    """The orientation's metrics with their smallest clearance measured in a forked process
    (``aside``, an :class:`~tsplcam.orientation.aside.Aside`): :meth:`result` measures the rest
    here (``measure``: :func:`~tsplcam.verify.orientation.orientation_metrics` of the path)
    and takes the clearance from the fork; errors come as in one process (collisions,
    clearance, joints); :meth:`beside` gives the caller's work done there (the
    ``beside`` of :func:`make_program`). A context manager like the Aside it holds."""

    def __init__(self, measure, aside, work=None, path=None, claim=None):
        self.measure, self.aside = measure, aside
        self.work, self.path, self.claim = work, path, claim
        self.joints = None               # the post's poses of the path, where they are the metrics'
        self._value = None
        self._own = None                 # (value, error) of the work where this process took it

    def _clearance(self):
        """The forked process's clearance; first the caller's work, here, when that process
        has not taken it yet (:func:`_take`): it is still measuring, so this one, done with its
        own part, makes it meanwhile (the same function of the same path: the same value)."""
        if self.work is not None and self._own is None and _take(self.claim, HERE):
            try:
                self._own = (self.work(self.path), None)
            except Exception as exc:     # (raised after the metrics' errors, as in one process)
                self._own = (None, exc)
        return self.aside.result()[0]

    def result(self):
        if self._value is None:
            self._value = self.measure(measured=self._clearance, joints=self.joints)
        return self._value

    def beside(self):
        """The value of the caller's work on the path (None without one)."""
        if self._own is not None:
            value, error = self._own
            if error is not None:
                raise error
            return value
        return self.aside.result()[1]

    def first(self) -> None:
        """Raise the metrics' error, if they have one (the post failed: one process would
        have measured the axes first)."""
        self.result()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.aside.__exit__(*exc)


def _clearance_beside(checker, parent: int, workers: str | None, centers, axes):
    """:func:`~tsplcam.verify.orientation.min_clearance` of the poses as the job's forked
    process measures it: with the job's processes (``workers``: its ``TSPLCAM_WORKERS``) for
    its large collision batches (the checker's pool, its own: ``parent``'s serves ``parent``),
    since the main process only posts the program and then waits for it (figure4: levels of
    74,806 poses, its search 2.62 -> 1.62 s on two cores; the keycap's batches of 3,149
    start none)."""
    from .verify.orientation import min_clearance
    if os.getpid() != parent:
        checker.leave_pool()
        if workers is None:
            os.environ.pop("TSPLCAM_WORKERS", None)
        else:
            os.environ["TSPLCAM_WORKERS"] = workers
    return min_clearance(checker, centers, axes)


THERE, HERE = 1, 2                     # who took the caller's work: the forked process, this one


def _take(claim, who: int) -> bool:
    """Whether ``who`` takes the work ``claim`` (a shared byte, 0 while nobody has) stands for."""
    if claim is None:
        return True
    with claim.get_lock():
        if claim.value:
            return False
        claim.value = who
        return True


def _measured_beside(checker, parent: int, workers: str | None, path, work, claim, centers, axes):
    """The forked process's second piece: (:func:`_clearance_beside` of the poses, ``work``
    (the caller's, :func:`make_program`'s ``beside``) of ``path`` with the axes, or None:
    also where the caller took it meanwhile, done with its own part first: ``claim``)."""
    from dataclasses import replace
    found = _clearance_beside(checker, parent, workers, centers, axes)
    if work is None or not _take(claim, THERE):
        return found, None
    # (the axes as the path with axes holds them: the same path, bit for bit)
    return found, work(replace(path, axis=axes))


def _orient(path, model, settings: JobSettings, tool, machine, stock, progress, plist=None,
            checker=None, beside: bool = False, work=None):
    """Tool axes by the orientation settings (and a processing list's per-step blocks),
    checked again with the same collision checker: (Program, None), or with ``beside`` and
    more than one process (Program without its metrics, a :class:`_Metrics` whose smallest
    clearance is measured in a forked process while the caller posts the program: the one
    that checked the ball gouges while the axes were searched). ``work``: the caller's work on
    the path with its axes, done after the smallest clearance, there or here (its value in
    ``Program.beside``, or from the :class:`_Metrics`)."""
    from .orientation import orient
    from .orientation.aside import MIN_POINTS, Aside
    from .orientation.orient import ball_check
    from .orientation.controls import step_settings
    from .progress import for_stage
    from .verify.orientation import orientation_metrics
    base = settings.orientation_settings()
    per_patch = None
    if plist is not None:
        from .plan.listfile import orientation_blocks
        blocks = orientation_blocks(plist, settings.processing_list)
        per_patch = step_settings(base, blocks) if blocks else None
    if checker is None:
        checker = collision_checker(model, tool, stock, settings.holder_clearance)
    from .progress import report as tick
    # with the program posted here after the axes: the ball gouge check in a forked process
    # that then measures the axes' smallest clearance (most of the metrics' time) while this
    # one posts; it builds the checker's BVH between the two (the broad phase answers this
    # process's questions without it on most parts)
    companion = claim = None
    if beside and len(path) >= MIN_POINTS and Aside.can_fork():
        # the caller's work goes to whichever process is free first (the keycap's CL text, 11
        # ms: this one where the smallest clearance takes longer than the post)
        claim = multiprocessing.get_context("fork").Value("b", 0) if work is not None else None
        companion = ball_check(path, checker, then=(_measured_beside, checker, os.getpid(),
                                                    os.environ.get("TSPLCAM_WORKERS"), path, work, claim))
    checker.beside = companion                  # (half of the search's large batches there)
    try:
        # with the companion, the report's forced C travel is left for the wait for its metrics
        oriented, report = orient(path, model, tool, settings=base, per_patch=per_patch, checker=checker,
                                  machine=machine, progress=for_stage(progress, "tool axes"), ball=companion,
                                  later=companion is not None)
        tick(progress, "checking axes", 0, 1)
    except BaseException:                        # (a process waiting for its second piece)
        if companion is not None:
            companion.close()
        raise
    finally:
        checker.beside = None
    # orient refused the path if the ball gouged anywhere (its centres do not move with the
    # axes): no gouge to count again
    measure = functools.partial(orientation_metrics, oriented, checker, machine, gouges=0)
    if companion is not None:
        clear = companion.follow(oriented.center, oriented.axis)
        if clear.forked:
            return Program(oriented, report, None, checker=checker), _Metrics(measure, clear, work, oriented,
                                                                              claim)
        report.finish()
        metrics = measure(measured=lambda: clear.result()[0])
        made = clear.result()[1]
    else:
        metrics = measure()
        made = None if work is None else work(oriented)
    tick(progress, "checking axes", 1, 1)
    return Program(oriented, report, metrics, checker=checker, beside=made), None


def program_file_name(model: str, dialect: str) -> str:
    """The program's file name: the model's name with the controller's extension (keycap.h)."""
    from .post.dialects import extension
    stem = os.path.splitext(os.path.basename(str(model)))[0] or "program"
    return stem + extension(dialect)
