"""The paper's baseline: the same job on the compound-NURBS version of the model.

shang2020 (introduction, section 4): on a compound NURBS model "isoparametric strategy has
to be applied patch by patch as the boundary between adjacent NURBS patches is usually
discontinuous ... a retraction is usually needed to connect the tool path of two
different patches". The baseline treats every patch of the model as an independent face
(each patch *is* the NURBS face the model would be exported as, so the geometry and the
scallop are the same; what changes is the linking):

* each face is cut on its own, from its own first corner (u, v) = (0, 0), with the planner's
  preferred crossfeed (the one stepping across the shorter extent), and ends wherever the
  parity of its line count puts it: no transit corners, no scallop tuning;
* faces in the same order as the T-spline processing list (so only the linking differs);
* between faces the tool retracts to clearance, moves rapidly and approaches the next
  face's first corner (:class:`~tsplcam.toolpath.zigzag.Clearance`).
"""
from __future__ import annotations

from ..layout.layout import Layout
from .path import ToolPath
from .zigzag import PathSettings, PathStep, build_path, default_plan


def baseline_steps(model, order=None) -> list[PathStep]:
    """One free-parity step per patch, in ``order`` (default: the planner's order)."""
    from ..plan.graph import model_edge_lengths, preferred_crossfeeds
    layout = Layout.from_model(model)
    preferred = preferred_crossfeeds(layout, model_edge_lengths(model))
    if order is None:
        order = default_plan(model).order
    return [PathStep(p, 0, None, preferred[p], i > 0) for i, p in enumerate(order)]


def baseline_path(model, tool_radius: float, scallop: float, chord_tol: float = 0.001,
                  order=None, **options) -> ToolPath:
    """The compound-NURBS baseline path (module doc); ``options`` as in PathSettings."""
    settings = PathSettings(tool_radius=tool_radius, scallop=scallop, chord_tol=chord_tol,
                            tune_parity=False, **options)
    tp = build_path(model, baseline_steps(model, order), settings, getattr(model, "name", ""))
    tp.info["generator"] = "compound-NURBS baseline (each face on its own, retractions between)"
    return tp
