"""One finishing path over the whole model: isoparametric zigzags patch after patch, as the
processing list says (shang2020 section 3.5; docs/method.md section 3).

For each step (patch, start corner, finish corner, crossfeed) of the processing list:

* the line positions come from :class:`~tsplcam.toolpath.lines.Placer` (side steps under
  the scallop limit, parity tuned so the zigzag ends at the finish corner, first line on
  the start corner's edge, last line on the far edge);
* the lines alternate direction; consecutive lines are joined by LINK moves along the
  patch edge (on the surface, no retraction);
* points along lines and links are spaced by the chord tolerance
  (:func:`~tsplcam.toolpath.chord.place_curves`, every line and link of the step at once);
* the first point of a step is the previous step's last point (the shared corner node,
  the same point to rounding), reached by a zero-length LINK; a step marked
  ``retract_before`` is reached by RETRACT, RAPID and an approach LINK instead.

The tool axis is the surface normal until the orientation stage replaces it.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from ..errors import InputError
from ..layout.layout import CORNER_NAMES, Layout
from .chord import Curve, place_curves
from .lines import LineFrame, LinePlacement, Placer, Target, check_patch_reachable, parity_for
from .parallel import map_pieces, worker_count
from .path import Move, ToolPath

CLEARANCE_MODES = ("auto", "plane", "sphere")


@dataclass
class PathSettings:
    """Everything the generator needs besides the model and the processing list (mm, mm/min).

    ``undercut_fraction``: the chords may leave up to min(chord_tol, undercut_fraction * h)
    of material where the line is concave along the feed; the side-step target is lowered
    by the same amount (module doc of :mod:`tsplcam.toolpath.chord`).
    ``clearance``: height above the model's top (plane) or the bounding sphere (sphere) for
    retractions; ``clearance_mode`` 'auto' takes the plane when every surface normal points
    up (a part machined from above, like the molds) and the sphere otherwise.
    ``balance``: spread the partial last gap over all gaps (see :mod:`tsplcam.toolpath.lines`).
    """
    tool_radius: float
    scallop: float
    chord_tol: float = 0.001
    max_step: float = 1.0
    feed: float = 1000.0
    clearance: float = 5.0
    clearance_mode: str = "auto"
    samples: int | None = None
    balance: bool = True
    undercut_fraction: float = 0.1
    tune_parity: bool = True

    def check(self) -> "PathSettings":
        def positive(name, value):
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not np.isfinite(value) \
                    or value <= 0:
                raise InputError(f"{name} must be a positive number of mm, not {value!r}", item=name)
        positive("tool radius", self.tool_radius)
        positive("scallop", self.scallop)
        positive("chord tolerance", self.chord_tol)
        positive("max step", self.max_step)
        positive("feed", self.feed)
        positive("clearance", self.clearance)
        if self.scallop >= self.tool_radius:
            raise InputError(f"the scallop {self.scallop:g} mm must be smaller than the tool radius "
                             f"{self.tool_radius:g} mm", item="scallop")
        if self.chord_tol >= self.tool_radius:
            raise InputError(f"the chord tolerance {self.chord_tol:g} mm must be smaller than the tool "
                             f"radius {self.tool_radius:g} mm", item="chord tolerance")
        if self.clearance_mode not in CLEARANCE_MODES:
            raise InputError(f"clearance mode {self.clearance_mode!r} is not one of "
                             + ", ".join(CLEARANCE_MODES), item="clearance mode")
        if self.samples is not None and (not isinstance(self.samples, int) or self.samples < 9):
            raise InputError(f"samples per line must be an integer >= 9, not {self.samples!r}",
                             item="samples")
        if not 0 <= self.undercut_fraction < 1:
            raise InputError("undercut fraction must be in [0, 1)", item="undercut fraction")
        return self

    @property
    def undercut(self) -> float:
        return min(self.chord_tol, self.undercut_fraction * self.scallop)


@dataclass
class PathStep:
    """One zigzag: what :func:`build_path` needs of a processing step (a plan Step works too).
    ``finish`` None lets the parity of the line count decide where it ends."""
    patch: int
    start: int = 0
    finish: int | None = None
    crossfeed: str = "u"
    retract_before: bool = False


@dataclass
class StepPoints:
    """The points of one step, before they are joined into the path."""
    P: np.ndarray
    n: np.ndarray
    uv: np.ndarray
    move: np.ndarray
    line: np.ndarray           # local line index, -1 on link points between lines
    placement: LinePlacement
    frame: LineFrame


def step_points(model, patch: int, start: int, finish: int | None, crossfeed: str,
                settings: PathSettings) -> StepPoints:
    """Lines, links and points of one zigzag on ``patch`` from corner ``start``; ``finish``
    None lets the parity fall where it falls (the compound-NURBS baseline)."""
    p = model.patches[patch]
    frame = LineFrame(p, crossfeed, start)
    parity = parity_for(frame, finish)
    r = settings.tool_radius
    check_patch_reachable(frame, r)
    target = Target(r, settings.scallop, settings.undercut, settings.max_step)
    placer = Placer(frame, target, settings.samples)
    placement = placer.tuned(parity if settings.tune_parity else None, settings.balance)
    s = placement.s
    dense = 16 * frame.cells_along + 1
    cross_cells = p.shape[0] if crossfeed == "u" else p.shape[1]
    # the lines, and the links along the edge t = t_from from the previous line's end
    curves, line_of = [], []
    for k, sk in enumerate(s):
        t_from = frame.t0 if k % 2 == 0 else 1.0 - frame.t0
        if k > 0:
            curves.append(Curve("s", t_from, s[k - 1], sk,
                                max(5, int(np.ceil(16 * cross_cells * (sk - s[k - 1]))) + 1)))
            line_of.append(-1)
        curves.append(Curve("t", sk, t_from, 1.0 - t_from, dense))
        line_of.append(k)
    placed = place_curves(frame, curves, r, settings.chord_tol, settings.undercut, settings.max_step)
    P, N, U, V, MV, LN = [], [], [], [], [], []
    for k, (_, lp, ln_, lu, lv) in zip(line_of, placed):
        if k < 0:
            m = len(lp) - 2
            if m > 0:
                P.append(lp[1:-1]), N.append(ln_[1:-1]), U.append(lu[1:-1]), V.append(lv[1:-1])
                MV.append(np.full(m, Move.LINK)), LN.append(np.full(m, -1))
            continue
        mv = np.full(len(lp), Move.CUT)
        mv[0] = Move.LINK
        P.append(lp), N.append(ln_), U.append(lu), V.append(lv), MV.append(mv), LN.append(np.full(len(lp), k))
    return StepPoints(np.concatenate(P), np.concatenate(N), np.column_stack([np.concatenate(U), np.concatenate(V)]),
                      np.concatenate(MV).astype(np.int8), np.concatenate(LN), placement, frame)


class Clearance:
    """Air moves between two surface points (module doc): RETRACT, RAPID(s), approach LINK,
    as ball centres and axes."""

    def __init__(self, model, settings: PathSettings):
        lo, hi = model.bounding_box(17)
        self.r = settings.tool_radius
        mode = settings.clearance_mode
        if mode == "auto":
            g = np.linspace(0.0, 1.0, 17)
            U, V = np.meshgrid(g, g)
            nz = min(float(pt.evaluate(U.ravel(), V.ravel(), second=False).normal[:, 2].min())
                     for pt in model.patches)
            mode = "plane" if nz >= -1e-3 else "sphere"
        self.mode = mode
        self.z = hi[2] + settings.clearance + self.r           # ball centre height at clearance
        self.o = 0.5 * (lo + hi)
        self.R = 0.5 * float(np.linalg.norm(hi - lo)) + settings.clearance + self.r

    def moves(self, c0, a0, c1, a1):
        """(centres, axes, moves) of the air points from centre c0 (axis a0) to c1 (axis a1),
        c1 itself included as the approach's end."""
        if self.mode == "plane":
            up0 = np.array([c0[0], c0[1], max(self.z, c0[2])])
            up1 = np.array([c1[0], c1[1], max(self.z, c1[2])])
            C = [up0, up1, c1]
            A = [a0, a1, a1]
            M = [Move.RETRACT, Move.RAPID, Move.LINK]
        else:
            e0 = self._exit(c0, a0)
            e1 = self._exit(c1, a1)
            d0, d1 = (e0 - self.o) / self.R, (e1 - self.o) / self.R
            ang = float(np.arccos(np.clip(d0 @ d1, -1.0, 1.0)))
            k = max(1, int(np.ceil(ang / np.radians(10.0))))
            C, A, M = [e0], [a0], [Move.RETRACT]
            for j in range(1, k + 1):
                f = j / k
                d = _slerp(d0, d1, f)
                C.append(self.o + self.R * d)
                A.append(_slerp(a0, a1, f))
                M.append(Move.RAPID)
            C.append(c1), A.append(a1), M.append(Move.LINK)
        return np.array(C), np.array(A), np.array(M, np.int8)

    def _exit(self, c, a):
        """Where the ray c + l a leaves the clearance sphere."""
        w = c - self.o
        b = float(w @ a)
        disc = b * b - (float(w @ w) - self.R * self.R)
        lam = -b + np.sqrt(max(disc, 0.0))
        return c + max(lam, 0.0) * a


def _slerp(a, b, f):
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    ang = float(np.arccos(np.clip(a @ b, -1.0, 1.0)))
    if ang < 1e-9:
        return a
    if abs(ang - np.pi) < 1e-6:                          # opposite: go round any perpendicular
        perp = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        perp /= np.linalg.norm(perp)
        return np.cos(np.pi * f) * a + np.sin(np.pi * f) * perp
    return (np.sin((1 - f) * ang) * a + np.sin(f * ang) * b) / np.sin(ang)


def _step_piece(model, steps, settings, i):
    """The points of step i and the seconds they took (the frame is left out: it holds the
    patch, which is rebuilt where the result arrives rather than sent between processes)."""
    st = steps[i]
    t0 = time.perf_counter()
    try:
        sp = step_points(model, st.patch, st.start, st.finish, st.crossfeed, settings)
    except InputError as exc:
        raise InputError(exc.message, path=exc.path, line=exc.line,
                         item=f"step {i + 1} (patch {st.patch})") from None
    sp.frame = None
    return sp, time.perf_counter() - t0


def build_path(model, steps, settings: PathSettings, name: str = "", workers: int | None = None,
               progress=None, while_waiting=None) -> ToolPath:
    """The whole path for ``steps``: objects with patch, start, finish (None: free),
    crossfeed and retract_before (a ProcessingList's steps, or the baseline's). The steps'
    points are made in ``workers`` processes (default: one per core, see
    :mod:`tsplcam.toolpath.parallel`), the same points as in one. ``progress``: a
    tsplcam.progress callback, stage "path", one unit per step made. ``while_waiting``: other
    work for this process while the workers make the points, called only when there are
    workers (see :func:`~tsplcam.toolpath.parallel.map_pieces`); its time is part of the
    path's ``seconds``."""
    settings.check()
    t_start = time.perf_counter()
    r = settings.tool_radius
    steps = list(steps)
    size = [int(np.prod(model.patches[st.patch].shape)) for st in steps]
    tick = None if progress is None else (lambda done, total: progress("path", done, total))
    if tick is not None:
        tick(0, len(steps))
    pieces = map_pieces(_step_piece, (model, steps, settings), len(steps),
                        worker_count(workers, len(steps) + (while_waiting is not None)),
                        order=np.argsort(size)[::-1], tick=tick,
                        while_waiting=while_waiting)
    clearance = None
    rows = []                 # per chunk: (P, n, axis, move, patch, uv, line)
    per_patch = []
    line_base = 0
    prev = None               # (centre, axis) of the last point so far
    for i, st in enumerate(steps):
        sp, seconds = pieces[i]
        sp.frame = LineFrame(model.patches[st.patch], st.crossfeed, st.start)
        n = len(sp.P)
        move = sp.move.copy()
        if prev is not None and st.retract_before:
            if clearance is None:
                clearance = Clearance(model, settings)
            c1, a1 = sp.P[0] + r * sp.n[0], sp.n[0]
            C, A, M = clearance.moves(prev[0], prev[1], c1, a1)
            m = len(C) - 1
            rows.append((C[:m] - r * A[:m], A[:m], A[:m], M[:m], np.full(m, -1),
                         np.full((m, 2), np.nan), np.full(m, -1)))
            move[0] = Move.LINK
        elif prev is None:
            move[0] = Move.CUT
        line = np.where(sp.line >= 0, sp.line + line_base, -1)
        rows.append((sp.P, sp.n, sp.n, move, np.full(n, st.patch), sp.uv, line))
        prev = (sp.P[-1] + r * sp.n[-1], sp.n[-1])
        seg = np.linalg.norm(np.diff(sp.P, axis=0), axis=1)
        finish = sp.frame.corner_of(1, sp.frame.end_t(sp.placement.count - 1))
        per_patch.append({
            "step": i + 1, "patch": int(st.patch), "start": CORNER_NAMES[st.start],
            "finish": CORNER_NAMES[finish], "crossfeed": st.crossfeed,
            "retract_before": bool(getattr(st, "retract_before", False)) and i > 0,
            "lines": int(sp.placement.count), "scallop_used": float(sp.placement.scallop),
            "balanced": float(sp.placement.balanced),
            "trials": [(float(h), int(c)) for h, c in sp.placement.trials],
            "points": int(n), "cut_length": float(seg[sp.move[1:] == Move.CUT].sum()),
            "link_length": float(seg[sp.move[1:] == Move.LINK].sum()),
            "seconds": seconds})
        line_base += sp.placement.count
    P, Nn, A, M, PA, UV, LN = (np.concatenate([r_[k] for r_ in rows]) for k in range(7))
    info = {"model": name or getattr(model, "name", ""), "generator": "isoparametric zigzag",
            "settings": asdict(settings), "patches": per_patch,
            "clearance_mode": clearance.mode if clearance else None,
            "seconds": time.perf_counter() - t_start}
    return ToolPath(contact=P, normal=Nn, axis=A, move=M, patch=PA, uv=UV, line=LN,
                    tool_radius=r, feed=settings.feed, info=info)


def default_plan(model):
    """The planner's processing list for ``model`` (what ``tsplcam path`` uses without a list)."""
    from ..plan import plan
    from ..plan.graph import model_edge_lengths
    return plan(Layout.from_model(model), edge_lengths=model_edge_lengths(model), model=getattr(model, "name", ""))


def zigzag_path(model, plist=None, tool_radius: float = 0.5, scallop: float = 0.005,
                chord_tol: float = 0.001, **options) -> ToolPath:
    """The paper's finishing path: ``model`` (tsplcam Model), ``plist`` (ProcessingList;
    default: planned here), ball radius and scallop limit in mm. ``options``: the other
    fields of :class:`PathSettings`, ``progress`` (a tsplcam.progress callback) and
    ``while_waiting`` (see :func:`build_path`)."""
    progress = options.pop("progress", None)
    while_waiting = options.pop("while_waiting", None)
    settings = PathSettings(tool_radius=tool_radius, scallop=scallop, chord_tol=chord_tol, **options)
    settings.check()
    if plist is None:
        plist = default_plan(model)
    n = len(model.patches)
    seen = sorted(s.patch for s in plist.steps)
    if seen != list(range(n)):
        raise InputError(f"the processing list must list every patch 0..{n - 1} once, not {seen}")
    for i, s in enumerate(plist.steps):
        if s.start is None or s.finish is None or s.crossfeed is None:
            raise InputError("the step is incomplete (start, finish and crossfeed are needed; "
                             "complete the list with `tsplcam plan --complete`)",
                             item=f"step {i + 1} (patch {s.patch})")
    tp = build_path(model, plist.steps, settings, getattr(model, "name", ""), progress=progress,
                    while_waiting=while_waiting)
    tp.info["plan"] = {"order": plist.order, "retractions": plist.retractions}
    return tp
