"""How the tool axes are chosen: one dataclass of orientation settings, per job or per step.

The controls a CAM programmer expects, all in the part frame, degrees and mm:

* ``strategy``: ``smooth`` (tilt spread along the path, judged in the machine's joint space),
  ``closest`` (per point the collision-free axis closest to the target: "tilt only where
  needed"; ``closest-z`` is its old name) or ``fixed`` (exactly the target everywhere: 3+2
  with a fixed axis, or a fixed lead/tilt; refused where it collides);
* the target (the preferred axis) by ``target``: ``axis`` (a fixed direction, +Z by default),
  ``lead-tilt`` (``lead`` toward the feed direction, negative = lag, and ``side_tilt`` to
  its left, relative to the surface normal: the Sinumerik LEAD/TILT convention),
  ``toward-point`` / ``away-from-point`` (``point``), ``toward-line`` / ``away-from-line``
  (the line through ``point`` along ``direction``);
* limits: ``lead_max`` / ``tilt_max`` around the normal, ``max_tilt`` degrees from
  ``limit_axis`` (a cone every axis must stay in), ``tilt_range`` (the machine's tilt axis
  limits narrowed, degrees in machine values), ``pole_tilt`` (smallest angle to the rotary
  axis; 0: the rotary axis holds still at the pole instead);
* the smoothing: ``smoothing_length`` (mm), ``max_step`` (deg), ``rotary_weight``,
  ``resolution`` (deg, candidates and rotary grid).

:meth:`OrientationSettings.check` refuses bad values naming the setting; a processing-list
step may override the target and limit settings (:data:`STEP_KEYS`) with a block read by
:meth:`OrientationSettings.with_step`.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

from ..errors import InputError

STRATEGIES = ("smooth", "closest", "fixed")
ALIASES = {"closest-z": "closest"}
TARGETS = ("axis", "lead-tilt", "toward-point", "away-from-point", "toward-line", "away-from-line")
# settings a processing-list step may set for its patch
STEP_KEYS = ("strategy", "target", "axis", "lead", "side_tilt", "point", "direction", "max_tilt",
             "limit_axis", "pole_tilt")


def _vec(value, name: str, nonzero: bool = True):
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be three numbers, not {value!r}", item=name) from None
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise InputError(f"{name} must be three finite numbers, not {value!r}", item=name)
    if nonzero and math.hypot(*v) < 1e-12:
        raise InputError(f"{name} must not be the zero vector", item=name)
    return v


@dataclass
class OrientationSettings:
    """The orientation stage's settings (see the module); defaults are the paper's job."""
    strategy: str = "smooth"
    target: str = "axis"
    axis: tuple = (0.0, 0.0, 1.0)
    lead: float = 0.0
    side_tilt: float = 0.0
    point: tuple | None = None
    direction: tuple | None = None
    lead_max: float = 60.0
    tilt_max: float = 60.0
    max_tilt: float | None = None
    limit_axis: tuple = (0.0, 0.0, 1.0)
    tilt_range: tuple | None = None
    pole_tilt: float = 0.0
    resolution: float = 10.0
    max_step: float = 10.0
    smoothing_length: float = 5.0
    rotary_weight: float | None = None

    def check(self) -> "OrientationSettings":
        """Normalise and check every value; InputError naming the setting. Returns self."""
        self.strategy = ALIASES.get(self.strategy, self.strategy)
        if self.strategy not in STRATEGIES:
            raise InputError(f"unknown orientation strategy {self.strategy!r} (one of "
                             f"{', '.join(STRATEGIES)})", item="strategy")
        if self.target not in TARGETS:
            raise InputError(f"unknown orientation target {self.target!r} (one of {', '.join(TARGETS)})",
                             item="target")
        self.axis = _vec(self.axis, "axis")
        self.limit_axis = _vec(self.limit_axis, "limit_axis")
        if self.target in ("toward-point", "away-from-point", "toward-line", "away-from-line"):
            if self.point is None:
                raise InputError(f"target {self.target} needs a point", item="point")
        if self.point is not None:
            self.point = _vec(self.point, "point", nonzero=False)
        if self.target in ("toward-line", "away-from-line"):
            if self.direction is None:
                raise InputError(f"target {self.target} needs the line's direction", item="direction")
        if self.direction is not None:
            self.direction = _vec(self.direction, "direction")
        for name, lo, hi in (("lead", -89.0, 89.0), ("side_tilt", -89.0, 89.0), ("lead_max", 0.0, 89.9),
                             ("tilt_max", 0.0, 89.9), ("pole_tilt", 0.0, 30.0)):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
                raise InputError(f"{name} must be a number from {lo:g} to {hi:g} degrees, not {v!r}", item=name)
        for name in ("resolution", "max_step", "smoothing_length"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise InputError(f"{name} must be a number > 0, not {v!r}", item=name)
        if self.max_tilt is not None and not (isinstance(self.max_tilt, (int, float))
                                              and 0.0 < self.max_tilt <= 180.0):
            raise InputError(f"max_tilt must be a number from 0 to 180 degrees, not {self.max_tilt!r}",
                             item="max_tilt")
        if self.rotary_weight is not None and not (isinstance(self.rotary_weight, (int, float))
                                                   and math.isfinite(self.rotary_weight)
                                                   and self.rotary_weight >= 0):
            raise InputError(f"rotary_weight must be a number >= 0, not {self.rotary_weight!r}",
                             item="rotary_weight")
        if self.tilt_range is not None:
            try:
                lo, hi = (float(x) for x in self.tilt_range)
            except (TypeError, ValueError):
                raise InputError(f"tilt_range must be two numbers (deg), not {self.tilt_range!r}",
                                 item="tilt_range") from None
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise InputError(f"tilt_range must be min < max, not {self.tilt_range!r}", item="tilt_range")
            self.tilt_range = (lo, hi)
        return self

    def with_step(self, block: dict, where: str = "step") -> "OrientationSettings":
        """These settings with a processing-list step's ``orientation`` block applied (only
        :data:`STEP_KEYS`), checked."""
        if not isinstance(block, dict):
            raise InputError("'orientation' must be an object of settings", item=where)
        unknown = sorted(set(block) - set(STEP_KEYS))
        if unknown:
            raise InputError(f"unknown orientation setting(s) {', '.join(unknown)} (a step may set "
                             f"{', '.join(STEP_KEYS)})", item=where)
        try:
            return replace(self, **block).check()
        except InputError as exc:                    # (the item names the place once)
            raise InputError(str(exc), item=where) from None

    def as_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "OrientationSettings":
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise InputError(f"unknown orientation setting(s) {', '.join(unknown)}", item="orientation")
        return cls(**d).check()
