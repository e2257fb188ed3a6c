"""Orientation stage: tool axes that keep shank and holder off the part, smoothed along the path.

API::

    from tsplcam.orientation import orient, load_tool, CollisionChecker
    tool = load_tool("ball6_impeller")                     # shipped name, .json or .fctb path
    path2, report = orient(path, model, tool, strategy="smooth", stock=(V, T), machine=machine)
    print(report.summary())

Strategies: ``fixed`` (three-axis), ``closest-z`` (shang2020), ``smooth`` (global DP after
xu2013 plus continuous relaxation); see :mod:`tsplcam.orientation.orient`. Tool files:
``tsplcam/orientation/TOOLS.md``. Collision geometry: :mod:`tsplcam.orientation.collision`.
Metrics live in :mod:`tsplcam.verify.orientation`.
"""
from .candidates import Limits, Reach  # noqa: F401
from .collision import CollisionChecker, tessellate_model  # noqa: F401
from .orient import STRATEGIES, OrientationReport, orient  # noqa: F401
from .tool import HolderSegment, Tool, load_tool, read_fctb, read_tool  # noqa: F401

# what a user picks for the tool axes: the surface normal as the path has it (no tool
# geometry, no collision checks), or one of the strategies above
ORIENTATIONS = ("normal",) + tuple(STRATEGIES)
