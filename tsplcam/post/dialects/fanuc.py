"""Fanuc Series 30i/31i-B5 with tool centre point control.

``G43.4 H..`` (type 1: rotary axis angles, ``orientation = "angles"``) or ``G43.5 H..``
(type 2: tool axis ``I J K`` as seen from the program coordinate system, tip to spindle,
always all three written, ``orientation = "vector"``), cancelled by ``G49``; retract with
``G53`` (machine coordinates); ``G93`` inverse-time feed (F = 1/min on every G1) when
``inverse_time`` is set, clamped to the control's range ``inverse_time_max`` (9999.999 on
the Fanuc 16/18 manual) (docs/post.md sections 3.3, 3.4). Comments are upper case in parentheses.
"""
from __future__ import annotations

from . import Job, ReadMove, clean_comment, fmt, iso_motion, spindle_coolant, tcp_columns, words

NAME = "fanuc"
# the control computes the tool tip's feed itself (G43.4 / G43.5: F is the tool tip's feed
# over the part): inverse time (G93) only on request
TIP_FEED = True
JOINT_SPACE = False
ORIENTATIONS = ("angles", "vector")
DEFAULTS = {"decimals": {"linear": 4, "angle": 4, "vector": 7, "feed": 3},
            "orientation": "angles", "inverse_time_max": 9999.999, "work_offset": "G54",
            "program_number": 1000}
VECTOR_WORDS = ("I", "J", "K")


def write(job: Job) -> str:
    m, s, mo = job.machine, job.settings, job.motion
    dl, da, fd = (s["decimals"][k] for k in ("linear", "angle", "feed"))
    t, r = m.axis_names[3], m.axis_names[4]
    name = clean_comment(str(s.get("program_name") or "TSPLCAM")).upper()
    out = ["%", f"O{int(s.get('program_number', 1000)):04d} ({name})"]
    out += [f"({clean_comment(h).upper()})" for h in job.header]
    safe = f"G90 G53 G0 Z{fmt(m.safe_z, dl)}"
    out += ["G21 G17 G40 G49 G80 G90 G94", safe, f"T{s['tool']} M6", s["work_offset"]]
    lines, cool = spindle_coolant(s)
    out += lines
    out.append(f"G0 {t}{fmt(job.preposition[0], da)} {r}{fmt(job.preposition[1], da)}")
    xyz, ori, vector = tcp_columns(job)
    words = [f"X{xyz[0][i]} Y{xyz[1][i]} Z{xyz[2][i]} " +
             (f"I{ori[0][i]} J{ori[1][i]} K{ori[2][i]}" if vector else f"{t}{ori[0][i]} {r}{ori[1][i]}")
             for i in range(len(mo))]
    out += iso_motion(mo, words, s["inverse_time"], fd, f"G43.5 H{s['tool']} " if vector else f"G43.4 H{s['tool']} ")
    out.append("G49")
    if cool:
        out.append("M9")
    out += ["M5", safe, "M30", "%"]
    return "\n".join(out) + "\n"


def read(text: str) -> list:
    """Motion blocks; ``program`` is True between G43.4/G43.5 and G49, except G53 moves."""
    moves, modal, tcp, motion, inv, feed = [], {}, False, None, False, None
    for ln, raw in enumerate(text.splitlines(), 1):
        line = raw.upper()
        while "(" in line:
            a, b = line.find("("), line.find(")")
            line = line[:a] + " " + (line[b + 1:] if b > a else "")
        w = words(line)
        gs = [v for a, v in w if a == "G"]
        for g in gs:
            if g in (0.0, 1.0):
                motion = g
            elif g in (43.4, 43.5):
                tcp = True
            elif g == 49.0:
                tcp = False
            elif g == 93.0:
                inv = True
            elif g in (94.0, 95.0):
                inv = False
        axes = {a: v for a, v in w if a in ("X", "Y", "Z", "A", "B", "C", "I", "J", "K")}
        if not axes or motion is None:
            continue
        modal.update(axes)
        f = next((v for a, v in w if a == "F"), None)
        if f is not None:
            feed = f
        moves.append(ReadMove(line=ln, rapid=motion == 0.0, program=tcp and 53.0 not in gs,
                              words=dict(modal), feed=None if motion == 0.0 else feed, inverse_time=inv))
    return moves
