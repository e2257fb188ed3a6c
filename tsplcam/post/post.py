"""From a :class:`~tsplcam.toolpath.path.ToolPath` to a controller program.

:func:`post_program` solves the machine poses of the path (kinematics.solve_joints), adds
the approach along the tool axis from a safe height and the retract, linearises for joint-
space dialects, gives every feed block its time (path length over feed, or longer when an
axis velocity limit says so; docs/post.md section 3.4), estimates the machining time
(timing.estimate) and lets the dialect write the text.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import __version__
from ..errors import InputError, KinematicsError
from ..toolpath.path import Move, ToolPath
from . import dialects
from .dialects import Job, Motion
from .kinematics import SINGULAR_CONE, SWING_LIMIT, JointSolution, linear_joints, linearise, solve_joints, swing
from .machine import Machine, load_machine
from .timing import TimeReport, estimate

APPROACH, RETRACT_OUT = -1, -2

# Options of post_program with their defaults when neither the call, the machine's "post"
# section nor the dialect sets them.
GENERIC = {"tool": 1, "spindle": 10000.0, "coolant": "flood", "approach_distance": 5.0,
           "approach_height_max": 200.0, "swing_limit": SWING_LIMIT,
           "approach_feed": None, "link_feed": None, "retract_feed": None, "inverse_time": "auto",
           "orientation": "angles", "tcp": None, "refpnt": None, "linear_tolerance": 0.001,
           "singular_cone": SINGULAR_CONE, "blend_tolerance": 0.01, "program_name": "TSPLCAM",
           "inverse_time_max": None, "work_offset": "G54", "tool_length": None,
           "part_origin": None, "point": "tip", "program_number": 1000}


@dataclass
class PostResult:
    """A posted program and the figures behind it.

    The motion arrays (``tip``, ``axis``, ``joints``, ``rapid``, ``source``, ``move``) have one
    row per motion block of the program in part (or joint) coordinates, in program order;
    ``solution`` holds the machine poses of the tool path's own points.
    """
    text: str
    dialect: str
    machine: Machine
    settings: dict
    motion: Motion
    solution: JointSolution
    time: TimeReport
    inserted: int = 0
    linear_deviation: float = float("nan")
    feed_clamped: int = 0
    reorientations: int = 0     # retract-reorient-approach sequences the post inserted
    notes: list = field(default_factory=list)

    @property
    def tip(self):
        return self.motion.tip

    @property
    def axis(self):
        return self.motion.axis

    @property
    def joints(self):
        return self.motion.joints

    def write(self, path: str) -> None:
        """Write the program text (bytes exactly as ``text``, LF line ends), whole or not at all."""
        from ..outfile import write_text
        write_text(path, self.text, encoding="ascii", what="program")

    def summary(self) -> str:
        """Lines to print for a job: kinematics figures and the time estimate."""
        info = self.solution.info
        lines = [f"posted {len(self.motion)} blocks for {self.machine.name} ({self.dialect}, "
                 f"{self.settings['orientation']}), {len(self.solution.joints)} path points, "
                 f"{self.inserted} inserted for linearisation",
                 f"  rotary travel {info['tilt_travel_deg']:.1f} deg {self.machine.tilt.name}, "
                 f"{info['rotary_travel_deg']:.1f} deg {self.machine.rotary.name}, largest "
                 f"{self.machine.rotary.name} step {info['max_rotary_step_deg']:.3f} deg, "
                 f"branch flips {info['branch_flips']}, singular points {info['singular_points']} "
                 f"(axis moved up to {info['max_axis_deviation_deg']:.4f} deg)"]
        if np.isfinite(self.linear_deviation):
            lines.append(f"  joint-space tip deviation after linearisation {self.linear_deviation * 1000:.3f} um")
        if self.feed_clamped:
            lines.append(f"  {self.feed_clamped} blocks slowed to the control's inverse-time range")
        lines.append(self.time.summary())
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


def dialect_of(machine: Machine, dialect: str | None = None):
    """The dialect module a program for ``machine`` is written in: ``dialect``, else the
    machine file's post dialect, else its controller's."""
    return dialects.get(dialect or machine.post.get("dialect") or machine.controller)


def resolve_settings(machine: Machine, dialect_module, options: dict) -> dict:
    """Options of a call over the machine's "post" section over the dialect's defaults."""
    unknown = sorted(set(options) - set(GENERIC) - {"decimals"})
    if unknown:
        raise InputError(f"unknown post option(s): {', '.join(unknown)}")
    s = dict(GENERIC)
    dec = {"linear": 4, "angle": 4, "vector": 7, "feed": 3}
    for layer in (dialect_module.DEFAULTS, {k: v for k, v in machine.post.items() if k != "dialect"},
                  {k: v for k, v in options.items() if v is not None}):
        for k, v in layer.items():
            if k == "decimals":
                dec.update(v)
            elif k != "comment":
                s[k] = v
    s["decimals"] = dec
    if s["orientation"] not in dialect_module.ORIENTATIONS:
        raise InputError(f"dialect {dialect_module.NAME} writes orientation as "
                         f"{' or '.join(dialect_module.ORIENTATIONS)}, not {s['orientation']!r}",
                         item="orientation")
    if dialect_module.NAME == "heidenhain" and s["tcp"] not in ("FUNCTION TCPM", "M128"):
        raise InputError(f"tcp must be 'FUNCTION TCPM' or 'M128', not {s['tcp']!r}", item="tcp")
    s["inverse_time"] = inverse_time(dialect_module, s["inverse_time"])
    if s["coolant"] not in ("flood", "mist", "off", None):
        raise InputError(f"coolant must be flood, mist or off, not {s['coolant']!r}", item="coolant")
    for k in ("approach_distance", "linear_tolerance", "singular_cone", "swing_limit"):
        if not isinstance(s[k], (int, float)) or not np.isfinite(s[k]) or s[k] < 0:
            raise InputError(f"{k} must be a number >= 0, not {s[k]!r}", item=k)
    if s["linear_tolerance"] <= 0:
        raise InputError("linear_tolerance must be > 0", item="linear_tolerance")
    if s["refpnt"] == "CENTER-CENTER":
        s["point"] = "center"
    s["vector_words"] = getattr(dialect_module, "VECTOR_WORDS", None)
    return s


def inverse_time(dialect_module, value) -> bool:
    """Whether the program feeds in inverse time (G93: F = 1 / block time in minutes).

    ``"auto"`` (the default): only where the control cannot compute the tool tip's feed
    itself, i.e. a program in machine-joint coordinates without tool centre point control
    (LinuxCNC with identity kinematics). With TCP on (Heidenhain FUNCTION TCPM F TCP or
    M128, Sinumerik TRAORI, Fanuc G43.4 / G43.5) the F word is the tool tip's feed over the
    part in mm/min, and G94 says it directly (docs/post.md section 3.4). ``True`` or
    ``False`` choose; the TNC has no inverse time."""
    if value == "auto":
        return not dialect_module.TIP_FEED
    if not isinstance(value, bool):
        raise InputError(f"inverse_time must be true, false or \"auto\", not {value!r}", item="inverse_time")
    if value and not getattr(dialect_module, "INVERSE_TIME", True):
        raise InputError(f"dialect {dialect_module.NAME} has no inverse-time feed: its F is the tool "
                         "point's feed already (FUNCTION TCPM F TCP, M128)", item="inverse_time")
    return value


def _approach_height(machine, tip0, axis0, q0, L, origin, d):
    """Distance along the tool axis from the first point up to the machine's safe Z, kept
    inside the travel; at least the approach distance ``d``."""
    j0 = linear_joints(machine, tip0, [q0[0]], [q0[1]], L, origin)[0]
    g = linear_joints(machine, tip0 + axis0, [q0[0]], [q0[1]], L, origin)[0] - j0
    if g[2] <= 0.05:
        return d
    h = max((machine.safe_z - L - j0[2]) / g[2], d)
    for k, n in enumerate("XYZ"):               # travel is linear in h: shrink to fit
        ax = machine.linear[n]
        off = L if n == "Z" else 0.0
        for bound in (ax.min, ax.max):
            v_h = j0[k] + off + h * g[k]
            if not (ax.min - 1e-9 <= v_h <= ax.max + 1e-9) and abs(g[k]) > 1e-12:
                h_lim = (bound - j0[k] - off) / g[k]
                if d - 1e-9 <= h_lim < h:
                    h = h_lim
    return max(h, d)


def metrics_solution(result: PostResult) -> JointSolution | None:
    """The post's joint solution of the path's points where it is the one the orientation's
    metrics solve for themselves (:func:`~tsplcam.verify.orientation.orientation_metrics`:
    the machine's own tool length and part origin, :func:`solve_joints`' singular cone and
    swing limit, the path's moves), so they take it rather than solving the same poses again
    (the keycap: 10 ms); else None."""
    s, m = result.settings, result.machine
    same = (float(s["tool_length"]) == float(m.tool_length)
            and tuple(map(float, s["part_origin"])) == tuple(map(float, m.part_origin))
            and float(s["singular_cone"]) == SINGULAR_CONE and float(s["swing_limit"]) == SWING_LIMIT)
    return result.solution if same and result.solution.tip is not None else None


def post_program(toolpath: ToolPath, machine, dialect: str | None = None, progress=None,
                 **options) -> PostResult:
    """Post ``toolpath`` for ``machine`` (a Machine, a shipped name or a file) in ``dialect``
    (heidenhain, sinumerik, fanuc, linuxcnc; default: the machine's controller).

    Options (defaults from the machine file's "post" section, then the dialect): tool,
    spindle (rpm), coolant (flood/mist/off), approach_distance (mm along the tool axis),
    approach_feed / link_feed / retract_feed (mm/min, default the path feed),
    inverse_time (G93: true, false, or "auto": only for programs in machine-joint coordinates,
    see :func:`inverse_time`), orientation (angles/vector), tcp and refpnt (Heidenhain),
    linear_tolerance (mm, joint-space linearisation), singular_cone (deg), blend_tolerance,
    program_name, inverse_time_max, work_offset, tool_length, part_origin, decimals
    ({"linear", "angle", "vector", "feed"}).

    ``progress``: a tsplcam.progress callback, called for stage "program" as the poses are
    solved, linearised and written (it may raise Cancelled to stop).

    Raises KinematicsError for a pose outside the machine's limits (naming the point) and
    InputError for bad options, or for a feed or spindle speed beyond the machine's limits.
    """
    def report(progress, stage, done, total):
        if progress is not None:
            progress(stage, done, total)
    machine = load_machine(machine)
    mod = dialect_of(machine, dialect)
    s = resolve_settings(machine, mod, options)
    for key in ("approach_feed", "link_feed", "retract_feed"):
        machine.check_feed(s[key], key)
    machine.check_spindle(s["spindle"], "spindle")
    if not isinstance(toolpath, ToolPath):
        raise InputError("post_program needs a ToolPath")
    n = len(toolpath)
    if n == 0:
        raise InputError("the tool path has no points")
    L = machine.tool_length if s["tool_length"] is None else float(s["tool_length"])
    origin = np.asarray(machine.part_origin if s["part_origin"] is None else s["part_origin"], float)
    s["tool_length"], s["part_origin"] = L, tuple(float(v) for v in origin)
    R = float(toolpath.tool_radius)
    s["tool_radius"] = R
    feed = float(toolpath.feed)
    if not np.isfinite(feed) or feed <= 0:
        raise InputError(f"the tool path's feed must be > 0 mm/min, not {feed!r}")
    machine.check_feed(feed, "feed")
    steps = 4 if mod.JOINT_SPACE else 3
    report(progress, "program", 0, steps)
    f_app = float(s["approach_feed"] or feed)
    f_link = float(s["link_feed"] or feed)
    f_ret = float(s["retract_feed"] or feed)

    axis_in = np.asarray(toolpath.axis, float)
    tip_in = np.asarray(toolpath.tip, float)
    sol, tip = solve_joints(machine, tip_in, axis_in, tool_length=L, part_origin=origin,
                            singular_cone=s["singular_cone"], radius=R, patch=toolpath.patch,
                            uv=toolpath.uv, move=toolpath.move, swing_limit=s["swing_limit"])
    report(progress, "program", 1, steps)
    joints = sol.joints.copy()
    da = int(s["decimals"]["angle"])
    if mod.JOINT_SPACE:
        # Write what the machine will do: rotaries rounded as printed, XYZ from them.
        rot = np.round(joints[:, 3:], da)
        joints = np.column_stack([linear_joints(machine, tip, rot[:, 0], rot[:, 1], L, origin), rot])
    if s["orientation"] == "vector":
        # The control chooses the angles: command the tool path's own tip and axis.
        norm = np.linalg.norm(axis_in, axis=1, keepdims=True)
        cmd_axis, cmd_tip = axis_in / norm, tip_in
    else:
        cmd_axis, cmd_tip = sol.axis, tip

    # Where the rotaries would swing the tool through the part inside a cutting block (a
    # rewind at the end of a limited C, a branch flip forced by the limits), leave the part:
    # retract, reorient at the safe height, approach again.
    mv = np.asarray(toolpath.move, int)
    path_rapid = mv == Move.RAPID
    path_rapid[0] = False
    sw = swing(machine, joints, cmd_axis)
    rewind = np.abs(np.diff(joints[:, 4])) > 180.0 + 1e-6
    flip = (sol.branch[1:] != sol.branch[:-1]) & ~sol.singular[1:] & ~sol.singular[:-1]
    breaks = np.nonzero(~path_rapid[1:] & (rewind | flip)
                        & (sw > float(s["swing_limit"]) * np.pi / 180.0))[0]
    path_feed = np.where(mv == Move.CUT, feed, np.where(mv == Move.LINK, f_link, f_ret)).astype(float)
    path_move = mv.copy()
    d = float(s["approach_distance"])
    hmax = float(s["approach_height_max"]) if s["approach_height_max"] else np.inf
    if machine.kind == "table-table":
        hmax = np.inf                            # the tool axis is machine Z: up to safe Z

    def along(i, dist):
        """Rows on the tool axis of path point i at the given distances (tip, joints)."""
        dist = np.asarray(dist, float)
        p = cmd_tip[i] + dist[:, None] * cmd_axis[i]
        q = joints[i, 3:]
        jj = np.column_stack([linear_joints(machine, p, np.full(len(p), q[0]), np.full(len(p), q[1]),
                                            L, origin), np.tile(q, (len(p), 1))])
        lim = _travel_violation(machine, jj, L)
        if lim:
            raise KinematicsError(f"the approach or retract {dist.max():g} mm along the tool axis of "
                                  f"point {i} is outside the travel of machine {machine.name}: {lim}")
        return p, jj

    # the program's rows in runs of rows, each field an array: (tip, axis, joints, rapid,
    # feed, source, move), concatenated at the end (the same rows as one at a time)
    runs = []

    def add(p, jj, i, rap, f, src, code):
        k = len(p)
        runs.append((p, np.broadcast_to(cmd_axis[i], (k, 3)), jj, np.full(k, rap, bool), np.full(k, f, float),
                      np.full(k, src, float), np.full(k, code, int)))

    cuts = np.concatenate([[-1], breaks, [n - 1]])
    for seg, (a, b) in enumerate(zip(cuts[:-1] + 1, cuts[1:])):
        h = min(_approach_height(machine, cmd_tip[a], cmd_axis[a], joints[a, 3:], L, origin, d), max(hmax, d))
        dist = [h] + ([d] if h > d + 1e-6 and d > 0 else [])
        p, jj = along(a, dist)
        add(p, jj, a, True, np.nan, -1.0, APPROACH)
        r = slice(a, b + 1)
        rap = path_rapid[r].copy()
        rap[0] = False                           # the first row of a run is the approach's end
        fm = np.where(path_rapid[r], np.nan, path_feed[r])
        fm[0] = f_app
        code = path_move[r].astype(int)
        code[0] = APPROACH
        runs.append((cmd_tip[r], cmd_axis[r], joints[r], rap, fm, np.arange(a, b + 1, dtype=float), code))
        if d > 0:
            p, jj = along(b, [d])
            add(p, jj, b, False, f_ret, -2.0, RETRACT_OUT)
        if b != n - 1:                           # up to the safe height before reorienting
            h = min(_approach_height(machine, cmd_tip[b], cmd_axis[b], joints[b, 3:], L, origin, d),
                    max(hmax, d))
            if h > d + 1e-6:
                p, jj = along(b, [h])
                add(p, jj, b, True, np.nan, -2.0, RETRACT_OUT)
    tips, axes, J, rapid, fmm, source, move = (np.concatenate([np.asarray(run[k]) for run in runs])
                                               for k in range(7))
    # A row that repeats the previous pose is a block that does nothing: leave it out.
    same = np.zeros(len(tips), bool)
    same[1:] = ((np.abs(np.diff(tips, axis=0)).max(axis=1) < 1e-9)
                & (np.abs(np.diff(J, axis=0)).max(axis=1) < 1e-9))
    dropped = int(same.sum())
    if dropped:
        keep = ~same
        tips, axes, J, rapid, fmm, source, move = (a[keep] for a in (tips, axes, J, rapid, fmm, source, move))

    inserted, lin_dev = 0, float("nan")
    if mod.JOINT_SPACE:
        feedrow = ~rapid
        feedrow[0] = False
        src_key = np.arange(len(J), dtype=float)
        J, tips, src_key, feedrow, inserted, lin_dev = linearise(
            machine, J, tips, src_key, feedrow, float(s["linear_tolerance"]), tool_length=L,
            part_origin=origin, angle_decimals=da)
        # Carry the per-row data over to the inserted rows (an inserted row belongs to the
        # block it splits: same feed, move kind; source interpolated).
        owner = np.ceil(src_key - 1e-9).astype(int)
        frac = src_key - np.floor(src_key)
        lo = np.floor(src_key).astype(int)
        src0 = source[lo]
        src1 = source[np.minimum(lo + 1, len(source) - 1)]
        new_source = np.where(frac > 0, np.where((src0 >= 0) & (src1 >= 0), src0 + frac * (src1 - src0),
                                                  np.where(src1 >= 0, src1, src0)), source[lo])
        axes = _axes_of(machine, J, axes, owner, frac, L, origin)
        rapid, fmm, move, source = rapid[owner], fmm[owner], move[owner], new_source
        report(progress, "program", 2, steps)

    # Block times: tip length over feed, or longer where an axis velocity limit says so.
    vmax_min = machine.max_velocity * 60.0                      # per minute
    dJ = np.abs(np.diff(J, axis=0, prepend=J[:1]))
    length = np.linalg.norm(np.diff(tips, axis=0, prepend=tips[:1]), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_feed = np.where(rapid, 0.0, length / fmm)
    t_axis = (dJ / vmax_min).max(axis=1)
    t_block = np.maximum(t_feed, t_axis)
    # the control's G93 range (inverse_time_max) only binds programs in inverse time
    inv_max = s["inverse_time_max"] if s["inverse_time"] else None
    floor = 1.0 / float(inv_max) if inv_max else 1e-7
    clamped = int(np.count_nonzero(~rapid[1:] & (t_block[1:] < floor))) if inv_max else 0
    t_block = np.maximum(t_block, floor)
    inv_time = np.where(rapid, np.nan, 1.0 / t_block)
    cmd_feed = np.where(rapid, np.nan, np.where(t_feed > 0, np.minimum(fmm, length / t_block), fmm))
    motion = Motion(tip=tips, axis=axes, joints=J, rapid=rapid, feed=cmd_feed, inverse_time=inv_time,
                    source=source, move=move)

    # Time the joints as the program positions them (rounded as printed): the unrounded ones
    # carry last bits that vary from run to run, and an axis's acceleration-limited time grows
    # with the square root of its move, so a 1e-14 deg wobble would show as 1e-8 s.
    dl = int(s["decimals"]["linear"])
    J_printed = np.column_stack([np.round(J[:, :3], dl), np.round(J[:, 3:], da)])
    time = estimate(J_printed, np.where(rapid, 0.0, t_feed)[1:] * 60.0, machine.max_velocity,
                    machine.max_acceleration, axis_names=machine.axis_names,
                    cut=(move[1:] == Move.CUT), rapid=rapid[1:])
    report(progress, "program", steps - 1, steps)

    blank_pts = np.vstack([toolpath.contact, tip_in])
    lo, hi = blank_pts.min(axis=0) - R, blank_pts.max(axis=0) + R
    t_h = int(round(time.total_s))
    header = [f"tsplcam {__version__} five-axis finishing program",
              f"machine {machine.name}: {machine.title or machine.kind}",
              f"dialect {mod.NAME}, orientation {s['orientation']}, "
              f"{'inverse time feed' if s['inverse_time'] else 'feed per minute'}",
              f"tool T{s['tool']}: ball radius {R:.4f} mm, tool length {L:.4f} mm assumed",
              f"program zero at X{origin[0]:.4f} Y{origin[1]:.4f} Z{origin[2]:.4f} machine coordinates, rotaries at zero",
              f"{n} path points, {len(motion)} motion blocks, {inserted} inserted",
              f"estimated machining time {t_h // 3600}:{t_h // 60 % 60:02d}:{t_h % 60:02d}"]
    job = Job(machine=machine, settings=s, motion=motion, header=header,
              preposition=(float(J[0, 3]), float(J[0, 4])), blank=(lo, hi), tool_radius=R)
    text = mod.write(job)
    report(progress, "program", steps, steps)
    notes = []
    if dropped:
        notes.append(f"{dropped} repeated poses left out (zero-length blocks)")
    if len(breaks):
        notes.append(f"{len(breaks)} retract-reorient-approach sequences inserted where the rotaries "
                     f"would swing the tool axis more than {float(s['swing_limit']):g} deg inside a "
                     f"feed block (before path points {', '.join(str(int(b) + 1) for b in breaks[:10])}"
                     f"{', ...' if len(breaks) > 10 else ''})")
    return PostResult(text=text, dialect=mod.NAME, machine=machine, settings=s, motion=motion,
                      solution=sol, time=time, inserted=inserted, linear_deviation=lin_dev,
                      feed_clamped=clamped, reorientations=len(breaks), notes=notes)


def _axes_of(machine, J, axes, owner, frac, L, origin):
    """Tool axes of rows after linearisation: original rows keep theirs, inserted rows take
    the orientation their rotary values give."""
    from .kinematics import orientation
    out = axes[owner].copy()
    ins = frac > 0
    if ins.any():
        out[ins] = orientation(machine, J[ins, 3], J[ins, 4])
    return out


def _travel_violation(machine, joints, L):
    for k, n in enumerate("XYZ"):
        a = machine.linear[n]
        v = joints[:, k] + (L if n == "Z" else 0.0)
        if (v < a.min - 1e-9).any():
            return f"{n}={v.min():.4f} below min {a.min:g}"
        if (v > a.max + 1e-9).any():
            return f"{n}={v.max():.4f} above max {a.max:g}"
    return None
