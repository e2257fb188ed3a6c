"""Errors tsplcam raises on purpose: each names where the problem is.

Bad input never surfaces as a traceback from deep inside numpy; it becomes one of
these, with the file and line, or the patch and (u, v), or the point of the path.
"""
from __future__ import annotations


class TsplcamError(Exception):
    """Base of every deliberate tsplcam error."""


#: An error message longer than this is cut in its middle (a value quoted from a corrupt
#: file can be megabytes long); the start says what is wrong, the end often what is expected.
MESSAGE_LIMIT = 600


class InputError(TsplcamError):
    """A file, record or argument that cannot be used as given.

    ``path`` and ``line`` (1-based) locate it when it comes from a file; ``item`` names
    the record, face, vertex or step.
    """

    def __init__(self, message: str, path: str | None = None, line: int | None = None,
                 item: str | None = None):
        if len(message) > MESSAGE_LIMIT:
            cut = len(message) - MESSAGE_LIMIT
            message = (message[:MESSAGE_LIMIT * 2 // 3] + f" [... {cut} characters ...] "
                       + message[-(MESSAGE_LIMIT // 3):])
        if item is not None and len(str(item)) > MESSAGE_LIMIT // 3:
            item = str(item)[:MESSAGE_LIMIT // 3] + "..."
        self.message = message
        self.path = path
        self.line = line
        self.item = item
        where = ""
        if path is not None:
            where = str(path) + (f", line {line}" if line is not None else "") + ": "
        elif line is not None:
            where = f"line {line}: "
        what = f"{item}: " if item else ""
        super().__init__(where + what + message)


class GeometryError(TsplcamError):
    """The geometry forbids what was asked (a gouge, an unreachable concave region, ...)."""


class CollisionError(GeometryError):
    """No collision-free tool pose exists at a point of the path."""


class KinematicsError(TsplcamError):
    """A pose the machine cannot reach (travel or rotary limits)."""
