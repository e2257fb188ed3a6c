"""Progress of long work, and stopping it: one callback that every stage calls.

A progress callback is ``progress(stage, done, total)``: ``stage`` names the work in a
CAM programmer's words ("path", "tool axes", "program", "scallop"), ``done`` of ``total``
units are finished (the units are the stage's own: steps, poses checked, blocks; the last
call of a stage has ``done == total``). Stages call it often enough that a person waiting
sees it move (at least about once a second), never per point in a hot loop.

To stop the work, the callback raises :class:`Cancelled` (the workbench's cancel button
does); the stage lets it through, so nothing half-made is returned or written. The command
line shows the calls as a bar per stage on stderr (:class:`TerminalProgress`).

Stages whose older interface takes ``progress(done, total)`` get :func:`for_stage`.
"""
from __future__ import annotations

import sys
import time
from typing import Callable, Optional

from .errors import TsplcamError

Progress = Callable[[str, int, int], None]


class Cancelled(TsplcamError):
    """The work was stopped on request (a progress callback raised it)."""

    def __init__(self, message: str = "stopped on request"):
        super().__init__(message)


def for_stage(progress: Optional[Progress], stage: str) -> Optional[Callable[[int, int], None]]:
    """``progress`` bound to ``stage``, as a ``(done, total)`` callback (None stays None)."""
    if progress is None:
        return None
    return lambda done, total: progress(stage, done, total)


def report(progress: Optional[Progress], stage: str, done: int, total: int) -> None:
    """Call ``progress`` if there is one."""
    if progress is not None:
        progress(stage, done, total)


class TerminalProgress:
    """Progress as a bar per stage on ``stream`` (stderr: the report stays on stdout).

    On a terminal the bar is redrawn in place at most every ``interval`` seconds; in a log
    (not a terminal) each stage writes one line when it ends, so logs stay short."""

    def __init__(self, stream=None, width: int = 30, interval: float = 0.1):
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self.interval = interval
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._last = 0.0
        self._stage = None
        self._t0 = time.perf_counter()

    def __call__(self, stage: str, done: int, total: int) -> None:
        now = time.perf_counter()
        if stage != self._stage:
            self._stage, self._t0 = stage, now
        finished = total > 0 and done >= total
        if not finished and (not self.tty or now - self._last < self.interval):
            return
        self._last = now
        frac = min(1.0, done / total) if total > 0 else 0.0
        fill = int(round(frac * self.width))
        line = (f"{stage:<12} [{'#' * fill}{'.' * (self.width - fill)}] {100 * frac:3.0f} % "
                f"({done}/{total}, {now - self._t0:.1f} s)")
        if self.tty:
            self.stream.write("\r" + line + ("\n" if finished else ""))
        elif finished:
            self.stream.write(line + "\n")
        self.stream.flush()
