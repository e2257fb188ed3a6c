"""The tool path that crosses stages: one row per point, numpy arrays throughout.

Units: mm. ``move[i]`` is the kind of motion that *arrives* at point i, as a G-code block
does: CUT (feed, in contact), LINK (feed, short connection on the surface between lines
or patches), RETRACT (up to clearance, away from the surface) and RAPID (air move at
clearance height). A path without retraction has no RETRACT or RAPID after its first point.

The tool axis ``axis`` is a unit vector from the tool tip toward the spindle. For a ball
end of radius r the ball centre is ``contact + r * normal`` and the tip is
``centre - r * axis`` whatever the axis; the orientation stage replaces ``axis``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import IntEnum

import numpy as np


class Move(IntEnum):
    CUT = 0
    LINK = 1
    RETRACT = 2
    RAPID = 3


@dataclass
class ToolPath:
    contact: np.ndarray          # (n, 3) cutter contact points on the surface
    normal: np.ndarray           # (n, 3) unit surface normal, pointing to the tool side
    axis: np.ndarray             # (n, 3) unit tool axis, tip -> spindle
    move: np.ndarray             # (n,) int8, Move of the motion arriving at the point
    patch: np.ndarray            # (n,) int, patch index (-1 off the surface)
    uv: np.ndarray               # (n, 2) patch parameters (nan off the surface)
    line: np.ndarray             # (n,) int, running index of the isoparametric line (-1 off)
    tool_radius: float
    feed: float = 1000.0         # mm/min, cutting feed
    info: dict = field(default_factory=dict)   # per-patch figures, settings used

    def __post_init__(self):
        self.contact = np.asarray(self.contact, float).reshape(-1, 3)
        self.normal = np.asarray(self.normal, float).reshape(-1, 3)
        self.axis = np.asarray(self.axis, float).reshape(-1, 3)
        self.move = np.asarray(self.move, np.int8).reshape(-1)
        self.patch = np.asarray(self.patch, int).reshape(-1)
        self.uv = np.asarray(self.uv, float).reshape(-1, 2)
        self.line = np.asarray(self.line, int).reshape(-1)
        n = len(self.contact)
        for name in ("normal", "axis", "move", "patch", "uv", "line"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"ToolPath.{name} has {len(getattr(self, name))} rows, contact has {n}")

    def __len__(self) -> int:
        return len(self.contact)

    @property
    def center(self) -> np.ndarray:
        """Ball centres (mm)."""
        return self.contact + self.tool_radius * self.normal

    @property
    def tip(self) -> np.ndarray:
        """Tool tips (mm): the point the controllers program (Fanuc G43.4, TRAORI, trt kins)."""
        return self.center - self.tool_radius * self.axis

    def with_axis(self, axis: np.ndarray) -> "ToolPath":
        """A copy with other tool axes (normalised)."""
        axis = np.asarray(axis, float)
        axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
        return replace(self, axis=axis, info=dict(self.info))

    @property
    def retractions(self) -> int:
        return int(np.count_nonzero(self.move[1:] == Move.RETRACT))
