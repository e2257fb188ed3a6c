"""Siemens Sinumerik 840D sl / ONE with ``TRAORI`` (five-axis transformation).

Retract with ``G0 SUPA Z.. D0`` (machine coordinates), tool change, rotaries prepositioned,
then ``TRAORI``, ``ORIWKS`` and ``ORIAXES`` with machine angles (``orientation = "angles"``)
or ``ORIVECT`` with the tool vector ``A3= B3= C3=`` pointing to the tool adapter
(``orientation = "vector"``, always all three components), ``G93`` inverse-time feed (F is
1/min, on every G1) when ``inverse_time`` is set, ``TRAFOOF`` at the end (docs/post.md section 3.2).
"""
from __future__ import annotations

from . import Job, ReadMove, clean_comment, fmt, iso_motion, spindle_coolant, tcp_columns, words

NAME = "sinumerik"
# the control computes the tool tip's feed itself (TRAORI: F is the tool tip's path feed):
# inverse time (G93) only on request
TIP_FEED = True
JOINT_SPACE = False
ORIENTATIONS = ("angles", "vector")
DEFAULTS = {"decimals": {"linear": 4, "angle": 5, "vector": 7, "feed": 4},
            "orientation": "angles", "work_offset": "G54"}
VECTOR_WORDS = ("A3", "B3", "C3")


def write(job: Job) -> str:
    m, s, mo = job.machine, job.settings, job.motion
    dl, da, fd = (s["decimals"][k] for k in ("linear", "angle", "feed"))
    t, r = m.axis_names[3], m.axis_names[4]
    out = [f"; {clean_comment(h, ';')}" for h in job.header]
    safe = f"G0 SUPA Z{fmt(m.safe_z, dl)} D0"
    out += ["G17 G90 G71 G40 G94", safe, f"T{s['tool']}", "M6", "D1", s["work_offset"]]
    lines, cool = spindle_coolant(s)
    out += lines
    out.append(f"G0 {t}{fmt(job.preposition[0], da)} {r}{fmt(job.preposition[1], da)}")
    xyz, ori, vector = tcp_columns(job)
    out += ["TRAORI", "ORIWKS", "ORIVECT" if vector else "ORIAXES"]
    words = [f"X{xyz[0][i]} Y{xyz[1][i]} Z{xyz[2][i]} " +
             (f"A3={ori[0][i]} B3={ori[1][i]} C3={ori[2][i]}" if vector else f"{t}{ori[0][i]} {r}{ori[1][i]}")
             for i in range(len(mo))]
    out += iso_motion(mo, words, s["inverse_time"], fd)
    out += ["TRAFOOF"]
    if cool:
        out.append("M9")
    out += ["M5", safe, "M30"]
    return "\n".join(out) + "\n"


def read(text: str) -> list:
    """Motion blocks; ``program`` is True between TRAORI and TRAFOOF, except SUPA moves."""
    moves, modal, tcp, motion, inv, feed = [], {}, False, None, False, None
    for ln, raw in enumerate(text.splitlines(), 1):
        line = raw.split(";")[0].strip().upper()
        if not line:
            continue
        if line.startswith("TRAORI"):
            tcp = True
            continue
        if line.startswith("TRAFOOF"):
            tcp = False
            continue
        w = words(line)
        for a, v in w:
            if a == "G" and v in (0.0, 1.0):
                motion = v
            elif a == "G" and v == 93.0:
                inv = True
            elif a == "G" and v in (94.0, 95.0):
                inv = False
        axes = {a: v for a, v in w if a in ("X", "Y", "Z", "A", "B", "C", "A3", "B3", "C3")}
        if not axes or motion is None:
            continue
        modal.update(axes)
        f = next((v for a, v in w if a == "F"), None)
        if f is not None:
            feed = f
        moves.append(ReadMove(line=ln, rapid=motion == 0.0, program=tcp and "SUPA" not in line,
                              words=dict(modal), feed=None if motion == 0.0 else feed, inverse_time=inv))
    return moves
