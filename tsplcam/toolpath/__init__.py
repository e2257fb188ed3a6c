"""Toolpath stage: isoparametric zigzag paths with scallop-height control (shang2020 3.5).

What the other stages call::

    from tsplcam.toolpath import zigzag_path, baseline_path, write_cl, read_cl
    path = zigzag_path(model, plist, tool_radius=0.5, scallop=0.005)   # plist: tsplcam.plan
    write_cl(path, "keycap.cl")

:class:`~tsplcam.toolpath.path.ToolPath` is the interface between the stages.
"""
from .path import Move, ToolPath  # noqa: F401


def __getattr__(name):
    # the generator is imported on first use so that ``tsplcam.toolpath.path`` stays light
    if name in ("zigzag_path", "build_path", "default_plan", "PathSettings", "PathStep"):
        from . import zigzag
        return getattr(zigzag, name)
    if name in ("baseline_path", "baseline_steps"):
        from . import baseline
        return getattr(baseline, name)
    if name in ("write_cl", "read_cl", "cl_text", "parse_cl", "CLData"):
        from . import cldata
        return getattr(cldata, name)
    raise AttributeError(name)
