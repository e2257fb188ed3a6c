"""Run LinuxCNC's own G-code interpreter (``rs274``, Debian package linuxcnc-uspace) on a
program and read back the canonical moves it prints.

``rs274 -i INI -t TOOLTABLE -g PROGRAM OUT`` interprets the program without a machine and
writes one canonical call per line (``STRAIGHT_FEED(x, y, z, a, b, c)``,
``STRAIGHT_TRAVERSE(...)``); errors go to stderr with exit status 1. The canonical lines
carry 4 decimals; with ``precise=True`` a second run of the program with a
``(DEBUG, #5420 ...)`` line after each motion block reads the interpreter's position
parameters (current position, program coordinates) with 6 decimals, which the 1e-6 rad
round trip of the tool axis needs (1e-4 degree is 1.7e-6 rad).
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass

import numpy as np

AXES = "XYZABC"
_CANON = re.compile(r"(STRAIGHT_FEED|STRAIGHT_TRAVERSE)\(([^)]*)\)")
_MESSAGE = re.compile(r'MESSAGE\("\s*TSPLCAM ([^"]*)"\)')
_DEBUG = "(DEBUG, TSPLCAM #5420 #5421 #5422 #5423 #5424 #5425)"


def executable() -> str | None:
    """Path of rs274, or None when LinuxCNC is not installed."""
    return shutil.which("rs274") or ("/usr/bin/rs274" if os.path.exists("/usr/bin/rs274") else None)


@dataclass
class Rs274Result:
    returncode: int
    errors: str                  # stderr without the "executing" banner
    canon: str                   # the canonical output
    kinds: list                  # "feed" / "traverse" per motion, in program order
    moves: np.ndarray            # (m, 6) X Y Z A B C as printed (4 decimals)
    precise: np.ndarray | None   # (m, 6) the same from the position parameters (6 decimals)

    @property
    def ok(self) -> bool:
        return self.returncode == 0 and not self.errors


def _ini(coordinates: str) -> str:
    return ("[RS274NGC]\nPARAMETER_FILE = tsplcam.var\n"
            f"[TRAJ]\nCOORDINATES = {coordinates}\nLINEAR_UNITS = mm\nANGULAR_UNITS = deg\n"
            "[EMCIO]\nTOOL_TABLE = tsplcam.tbl\n")


def _motion_lines(text: str) -> list:
    from .dialects.linuxcnc import read
    return [mv.line for mv in read(text)]


def _run(exe, folder, program: str, timeout: float):
    with open(os.path.join(folder, "program.ngc"), "w", encoding="ascii") as f:
        f.write(program)
    out = os.path.join(folder, "canon.txt")
    if os.path.exists(out):
        os.remove(out)
    res = subprocess.run([exe, "-i", "tsplcam.ini", "-t", "tsplcam.tbl", "-g", "program.ngc", "canon.txt"],
                         cwd=folder, capture_output=True, text=True, stdin=subprocess.DEVNULL,
                         timeout=timeout)
    canon = open(out).read() if os.path.exists(out) else ""
    errors = "\n".join(ln for ln in (res.stderr + res.stdout).splitlines()
                       if ln.strip() and ln.strip() != "executing")
    return res.returncode, errors, canon


def run(text: str, coordinates: str = "XYZAC", tools=(1,), precise: bool = True,
        timeout: float = 300.0) -> Rs274Result:
    """Interpret ``text`` with rs274 and return its canonical moves (see the module doc).

    ``tools`` are entered in the tool table with length 0, so canonical coordinates are
    the program's own. Raises FileNotFoundError when rs274 is not installed.
    """
    exe = executable()
    if exe is None:
        raise FileNotFoundError("rs274 (Debian package linuxcnc-uspace) is not installed")
    with tempfile.TemporaryDirectory(prefix="tsplcam-rs274-") as folder:
        with open(os.path.join(folder, "tsplcam.ini"), "w") as f:
            f.write(_ini(coordinates))
        with open(os.path.join(folder, "tsplcam.tbl"), "w") as f:
            f.write("".join(f"T{t} P{t} Z0 D0 ;tsplcam\n" for t in tools))
        rc, errors, canon = _run(exe, folder, text, timeout)
        found = _CANON.findall(canon)
        kinds = ["feed" if k == "STRAIGHT_FEED" else "traverse" for k, _ in found]
        moves = np.array([[float(v) for v in args.split(",")[:6]] for _, args in found]).reshape(-1, 6)
        fine = None
        if precise and rc == 0:
            lines = text.splitlines()
            for ln in sorted(_motion_lines(text), reverse=True):
                lines.insert(ln, _DEBUG)
            rc2, errors2, canon2 = _run(exe, folder, "\n".join(lines) + "\n", timeout)
            if rc2 == 0:
                vals = [[float(v) for v in m.split()] for m in _MESSAGE.findall(canon2)]
                fine = np.array(vals).reshape(-1, 6)
            else:
                errors = (errors + "\n" + errors2).strip()
                rc = rc2
    return Rs274Result(returncode=rc, errors=errors, canon=canon, kinds=kinds, moves=moves, precise=fine)
