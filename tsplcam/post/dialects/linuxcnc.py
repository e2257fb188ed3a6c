"""LinuxCNC (rs274ngc) in joint coordinates for a trt table machine.

The program commands machine axes X Y Z A C directly (identity kinematics, e.g. the
``sparm=identityfirst`` default of the xyzac-trt sim; docs/post.md section 2.1): tsplcam's inverse
kinematics is the same as ``xyzac-trt-kins`` with the pins of the machine file, the tool
length comes from the tool table through ``G43``, and points are inserted where joint
interpolation would leave the programmed line (linearisation). Inverse-time feed ``G93``
(an F word on every G1, docs/post.md section 2.5) gives each block its time; ``G94`` otherwise,
with F in the joint-space units LinuxCNC uses. G54 and G92 are cleared because a
joint-space program is only right with the part where the machine file puts it.
"""
from __future__ import annotations

import numpy as np

from . import Job, ReadMove, clean_comment, fmt, fmt_col, fmt_feed, spindle_coolant, words

NAME = "linuxcnc"
# joint coordinates: the interpreter does not know the tool tip (with G94, F is the joints'
# XYZ length per minute), so inverse time (G93) by default
TIP_FEED = False
JOINT_SPACE = True
ORIENTATIONS = ("angles",)
DEFAULTS = {"decimals": {"linear": 4, "angle": 6, "feed": 4},
            "orientation": "angles", "blend_tolerance": 0.01, "work_offset": "G54"}


def _c(text: str) -> str:
    return f"({clean_comment(text)})"


def write(job: Job) -> str:
    m, s, mo = job.machine, job.settings, job.motion
    dl, da = s["decimals"]["linear"], s["decimals"]["angle"]
    names = m.axis_names
    out = [_c(h) for h in job.header]
    out.append(_c("joint coordinates: run with identity kinematics, tool length by G43 from the tool table"))
    if m.linuxcnc:
        pins = " ".join(f"{k}={m.linuxcnc[k]}" for k in m.linuxcnc if k != "kinematics")
        out.append(_c(f"{m.linuxcnc['kinematics']} {pins}"))
    zeros = " ".join(f"{n}0" for n in names)
    out += ["G21 G90 G94 G17 G40 G49 G80",
            f"G10 L2 P1 {zeros}", s["work_offset"], "G92.1",
            f"G64 P{fmt(s['blend_tolerance'], 4)}",
            f"T{s['tool']} M6",
            f"G53 G0 Z{fmt(m.safe_z, dl)}",
            f"G0 {names[3]}{fmt(job.preposition[0], da)} {names[4]}{fmt(job.preposition[1], da)}",
            f"G43 H{s['tool']}"]
    out += spindle_coolant(s)[0]
    cols = [fmt_col(mo.joints[:, k], dl if k < 3 else da) for k in range(5)]
    inv = s["inverse_time"]
    mode = None
    fd = s["decimals"]["feed"]
    dq = np.diff(mo.joints, axis=0, prepend=mo.joints[:1])
    n0, n1, n2, n3, n4 = names[:5]
    coords = [f"{n0}{a} {n1}{b} {n2}{c} {n3}{d} {n4}{e}" for a, b, c, d, e in zip(*cols)]
    rapid = mo.rapid.tolist()
    inv_f = fmt_col(mo.inverse_time, fd) if inv else None
    for i in range(len(mo)):
        xyz = coords[i]
        if rapid[i]:
            out.append(f"G0 {xyz}")
            continue
        if inv:
            if mode != "G93":
                out.append("G93")
                mode = "G93"
            out.append(f"G1 {xyz} F{inv_f[i]}")
        else:
            # G94: F is XYZ length per minute, or rotary degrees per minute when XYZ stay.
            t = 1.0 / mo.inverse_time[i]
            lin = float(np.linalg.norm(dq[i, :3]))
            f = lin / t if lin > 1e-9 else float(np.linalg.norm(dq[i, 3:])) / t
            out.append(f"G1 {xyz} F{fmt_feed(max(f, 1e-3), fd)}")
    if mode == "G93":
        out.append("G94")
    out += ["M9", "M5", "G49", f"G53 G0 Z{fmt(m.safe_z, dl)}", "M2"]
    return "\n".join(out) + "\n"


def read(text: str) -> list:
    """Motion blocks; ``program`` is True between G43 and G49 except G53 moves."""
    moves, modal, tlo, motion, inv = [], {}, False, None, False
    for ln, raw in enumerate(text.splitlines(), 1):
        line = raw.split(";")[0]
        while "(" in line:
            a, b = line.find("("), line.find(")")
            line = line[:a] + " " + (line[b + 1:] if b > a else "")
        w = words(line)
        gs = [v for a, v in w if a == "G"]
        g53 = 53.0 in gs
        for g in gs:
            if g in (0.0, 1.0):
                motion = g
            elif g == 43.0:
                tlo = True
            elif g == 49.0:
                tlo = False
            elif g == 93.0:
                inv = True
            elif g in (94.0, 95.0):
                inv = False
        if any(g in (10.0,) for g in gs):
            continue
        axes = {a: v for a, v in w if a in "XYZABCUVW" and len(a) == 1}
        if not axes or motion is None:
            continue
        modal.update(axes)
        f = next((v for a, v in w if a == "F"), None)
        moves.append(ReadMove(line=ln, rapid=motion == 0.0, program=tlo and not g53,
                              words=dict(modal), feed=f, inverse_time=inv))
    return moves
