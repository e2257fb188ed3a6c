"""Orientation stage: tool axes that keep shank and holder off the part, smoothed along the path.

API::

    from tsplcam.orientation import orient, load_tool, CollisionChecker
    tool = load_tool("ball6_impeller")                     # shipped name, .json or .fctb path
    path2, report = orient(path, model, tool, strategy="smooth", stock=(V, T), machine=machine)
    print(report.summary())

Strategies: ``fixed`` (exactly the target: 3+2 or a fixed lead/tilt), ``closest`` (tilt only
where needed, shang2020; alias ``closest-z``), ``smooth`` (xu2013, judged in the machine's
joint space); see :mod:`tsplcam.orientation.orient`. Settings and controls (target, lead/tilt,
toward a point or line, largest tilt, tilt range, pole tilt): :class:`OrientationSettings`
(:mod:`tsplcam.orientation.settings`, :mod:`tsplcam.orientation.controls`); the smoothing:
:mod:`tsplcam.orientation.smoothing`; the rotary axes' closed form and pose choice, shared
with the post: :mod:`tsplcam.orientation.rotary`. Tool files:
``tsplcam/orientation/TOOLS.md``. Collision geometry: :mod:`tsplcam.orientation.collision`.
Metrics live in :mod:`tsplcam.verify.orientation`.
"""
from .candidates import Limits, Reach  # noqa: F401
from .collision import CollisionChecker, tessellate_model  # noqa: F401
from .orient import OrientationReport, orient  # noqa: F401
from .settings import ALIASES, STRATEGIES, OrientationSettings  # noqa: F401
from .tool import HolderSegment, Tool, load_tool, read_fctb, read_tool  # noqa: F401

# what a user picks for the tool axes: the surface normal as the path has it (no tool
# geometry, no collision checks), or one of the strategies above
ORIENTATIONS = ("normal",) + tuple(STRATEGIES) + tuple(ALIASES)
