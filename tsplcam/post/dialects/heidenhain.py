"""Heidenhain TNC conversational (Klartext) with tool centre point management.

Program frame ``BEGIN PGM name MM`` / ``END PGM``, blank ``BLK FORM 0.1 / 0.2``,
``TOOL CALL n Z S..``, retract with ``M91`` (machine coordinates), rotaries prepositioned,
then ``FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS`` (``tcp = "FUNCTION TCPM"``, with
``REFPNT`` when set) or ``M128`` (``tcp = "M128"``) and the path as ``L X Y Z A C`` blocks
(or ``LN X Y Z TX TY TZ`` with ``orientation = "vector"``), F as tool-point feed (no
inverse time on the TNC), ``FMAX`` for rapids (docs/post.md section 3.1). Numbers follow the
TNC input format: 4 decimals for positions and angles, up to 8 for vector components; every value
carries its sign.
"""
from __future__ import annotations


from . import Job, ReadMove, clean_comment, fmt, fmt_col, fmt_feed, fmt_feeds, words

NAME = "heidenhain"
# the control computes the tool point's feed itself (FUNCTION TCPM F TCP, M128: F is that
# feed); the TNC has no inverse-time feed
TIP_FEED = True
INVERSE_TIME = False
JOINT_SPACE = False
ORIENTATIONS = ("angles", "vector")
DEFAULTS = {"decimals": {"linear": 4, "angle": 4, "vector": 7, "feed": 0},
            "orientation": "angles", "tcp": "FUNCTION TCPM", "refpnt": None,
            "program_name": "TSPLCAM"}
VECTOR_WORDS = ("TX", "TY", "TZ")


def write(job: Job) -> str:
    m, s, mo = job.machine, job.settings, job.motion
    dl, da, dv = s["decimals"]["linear"], s["decimals"]["angle"], s["decimals"]["vector"]
    name = "".join(ch for ch in str(s["program_name"]).upper() if ch.isalnum() or ch == "_") or "TSPLCAM"
    t, r = m.axis_names[3], m.axis_names[4]
    lines = [f"BEGIN PGM {name} MM"]
    lines += [f"; {clean_comment(h, ';')}" for h in job.header]
    lo, hi = job.blank
    lines.append("BLK FORM 0.1 Z " + " ".join(f"{a}{fmt(v, dl, True)}" for a, v in zip("XYZ", lo)))
    lines.append("BLK FORM 0.2 " + " ".join(f"{a}{fmt(v, dl, True)}" for a, v in zip("XYZ", hi)))
    safe = f"L Z{fmt(m.safe_z, dl, True)} R0 FMAX M91"
    lines.append(safe)
    spindle = f" S{fmt_feed(s['spindle'], 1)}" if s.get("spindle") else ""
    lines.append(f"TOOL CALL {s['tool']} Z{spindle}")
    lines.append(safe)
    lines.append(f"L {t}{fmt(job.preposition[0], da, True)} {r}{fmt(job.preposition[1], da, True)} R0 FMAX")
    if s.get("spindle"):
        lines.append("M3")
    cool = {"flood": "M8", "mist": "M7"}.get(s.get("coolant"))
    if cool:
        lines.append(cool)
    m128 = s["tcp"] == "M128"
    if not m128:
        tcpm = "FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS"
        if s.get("refpnt"):
            tcpm += f" REFPNT {s['refpnt']}"
        lines.append(tcpm)
    pts = mo.tip + (job.tool_radius * mo.axis if s.get("point") == "center" else 0.0)
    xyz = [fmt_col(pts[:, k], dl, True) for k in range(3)]
    if s["orientation"] == "vector":
        vec = [fmt_col(mo.axis[:, k], dv, True) for k in range(3)]
    else:
        rot = [fmt_col(mo.joints[:, k], da, True) for k in (3, 4)]
    fd = s["decimals"]["feed"]
    if s["orientation"] == "vector":
        blocks = [f"LN X{x} Y{y} Z{z} TX{a} TY{b} TZ{c}" for x, y, z, a, b, c in zip(*xyz, *vec)]
    else:
        blocks = [f"L X{x} Y{y} Z{z} {t}{a} {r}{c}" for x, y, z, a, c in zip(*xyz, *rot)]
    feeds = fmt_feeds(mo.feed, 1.0, fd)
    last_f = None
    for i, (block, rapid, f) in enumerate(zip(blocks, mo.rapid.tolist(), feeds)):
        if i == 0:
            block += " R0"
        if rapid:
            block += " FMAX"
            last_f = None
        elif f != last_f:
            block += f" F{f}"
            last_f = f
        if i == 0 and m128:
            block += " M128"
        lines.append(block)
    lines.append("M129" if m128 else "FUNCTION RESET TCPM")
    lines.append(safe)
    if cool:
        lines.append("M9")
    lines += ["M5", "M30", f"END PGM {name} MM"]
    return "\n".join(f"{k} {b}" for k, b in enumerate(lines)) + "\n"


def read(text: str) -> list:
    """Motion blocks; ``program`` is True while TCPM / M128 is on, except M91 blocks."""
    moves, modal, tcp, feed = [], {}, False, None
    for ln, raw in enumerate(text.splitlines(), 1):
        body = raw.split(";")[0].strip()
        parts = body.split(None, 1)
        if len(parts) < 2:
            continue
        body = parts[1]                       # drop the block number
        if body.startswith("FUNCTION RESET TCPM"):
            tcp = False
            continue
        if body.startswith("FUNCTION TCPM"):
            tcp = True
            continue
        w = words(body)
        ms = [v for a, v in w if a == "M"]
        if 128.0 in ms:
            tcp = True
        if 129.0 in ms:
            tcp = False
        if not (body.startswith("L ") or body.startswith("LN ")):
            continue
        axes = {a: v for a, v in w if a in ("X", "Y", "Z", "A", "B", "C", "TX", "TY", "TZ")}
        modal.update(axes)
        rapid = "FMAX" in body.split()
        f = next((v for a, v in w if a == "F"), None)
        if f is not None:
            feed = f
        moves.append(ReadMove(line=ln, rapid=rapid, program=tcp and 91.0 not in ms,
                              words=dict(modal), feed=None if rapid else feed))
    return moves
