"""FreeCAD shapes (STEP, IGES, BRep files, bodies in a document) as compound-NURBS models.

Every face becomes a patch of its own (shang2020's compound-NURBS baseline), joined to its
neighbours by ``tsplcam.model.compound``. A face is taken when it is

* a B-spline surface, or a surface OCCT converts to one exactly (``face.toNurbs()``:
  planes, cylinders, cones, spheres, tori, surfaces of revolution and extrusion, Bezier
  surfaces; checked point by point against the original surface);
* untrimmed: one boundary loop, and every point of its edges (their curves in the face's
  parameter plane) on the boundary of the face's parameter rectangle. A face that is an
  iso-parametric rectangle inside a larger surface is cut out of it exactly
  (``BSplineSurface.segment``);
* four-sided without a collapsed side (no poles).

Anything else is refused with an InputError naming every such face (Face3, ...), until
trimmed faces are supported. A face whose orientation is Reversed gets its u reversed, so
that the patch normal S_u x S_v is the face's outward normal, as on the sample molds.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..model.bspline import bspline_patch, flat_knots
from ..model.compound import compound_model

# surfaces BRepBuilderAPI_NurbsConvert turns into B-splines without approximation
EXACT_TYPES = {"Part::GeomBSplineSurface", "Part::GeomBezierSurface", "Part::GeomPlane",
               "Part::GeomCylinder", "Part::GeomCone", "Part::GeomSphere", "Part::GeomToroid",
               "Part::GeomSurfaceOfRevolution", "Part::GeomSurfaceOfExtrusion"}
_EDGE_SAMPLES = 9


@dataclass
class FaceSource:
    """Where a patch came from: face ``name`` of the shape; the patch's unit square maps to
    the B-spline's parameters ``bounds`` = (U0, U1, V0, V1), u reversed when ``reversed``;
    ``surface_type`` of the original face (converted by OCCT unless a B-spline)."""
    name: str
    bounds: tuple
    reversed: bool
    surface_type: str

    def surface_params(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        """The face surface's (u, v) of the patch's (u, v)."""
        U0, U1, V0, V1 = self.bounds
        u = np.asarray(u, float)
        su = U1 - u * (U1 - U0) if self.reversed else U0 + u * (U1 - U0)
        return su, V0 + np.asarray(v, float) * (V1 - V0)


class _Refused(Exception):
    pass


def model_from_shape(shape, name: str | None = None, tol: float | None = None, path: str | None = None):
    """A compound-NURBS Model of every face of ``shape`` (a Part.Shape: solid, shell,
    compound or face). ``tol`` (mm) joins edges and corners; by default the larger of
    1e-6 times the model's size and twice the largest edge tolerance of the shape."""
    if shape is None or shape.isNull():
        raise InputError("the shape is empty", path=path, item=name)
    faces = shape.Faces
    if not faces:
        raise InputError("the shape has no faces", path=path, item=name)
    patches, sources, refused = [], [], []
    for i, face in enumerate(faces):
        label = f"Face{i + 1}"
        try:
            patch, src = face_patch(face, label, len(patches))
        except _Refused as why:
            refused.append(f"{label} {why}")
            continue
        except InputError as exc:          # bspline_patch's own checks
            refused.append(f"{label}: {exc.message}")
            continue
        patches.append(patch)
        sources.append(src)
    if refused:
        more = f" (and {len(refused) - 8} more)" if len(refused) > 8 else ""
        raise InputError(f"{len(refused)} of {len(faces)} faces cannot be patches: "
                         + "; ".join(refused[:8]) + more, path=path, item=name)
    if tol is None:
        bb = shape.BoundBox
        size = float(np.linalg.norm([bb.XLength, bb.YLength, bb.ZLength]))
        edge_tol = max([e.Tolerance for e in shape.Edges] or [0.0])
        tol = max(1e-6 * size, 2.0 * edge_tol)
    model = compound_model(patches, source=path, name=name, tol=tol)
    model.faces = sources
    return model


def model_from_step(path: str, name: str | None = None, tol: float | None = None):
    """A compound-NURBS Model of a STEP (or IGES, BRep) file, read by FreeCAD's Part.read."""
    import Part
    path = os.fspath(path)
    check_file_complete(path)
    try:
        shape = Part.read(path)
    except Exception as exc:               # OCCT's readers say little more than "failed"
        raise InputError(f"FreeCAD cannot read this file ({exc})", path=path)
    if shape.isNull() or not shape.Faces:
        raise InputError("the file holds no faces", path=path)
    return model_from_shape(shape, name or os.path.splitext(os.path.basename(path))[0], tol, path)


def check_file_complete(path: str) -> None:
    """Refuse STEP and IGES files cut short: OCCT reads a truncated IGES file without
    complaint (and a STEP file's error does not say why). STEP ends with
    ``END-ISO-10303-21;``, IGES with its Terminate line ('T' in column 73)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError("no such file", path=path)
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".step", ".stp", ".iges", ".igs"):
        return
    with open(path, "rb") as fh:
        fh.seek(0, os.SEEK_END)
        fh.seek(max(0, fh.tell() - 4096))
        tail = fh.read().decode("latin-1")
    lines = [ln for ln in tail.splitlines() if ln.strip()]
    if ext in (".step", ".stp"):
        if "END-ISO-10303-21" not in tail:
            raise InputError("the file is cut short: no END-ISO-10303-21 line at its end", path=path)
    elif not lines or len(lines[-1]) < 73 or lines[-1][72] != "T":
        raise InputError("the file is cut short: its last line is not the IGES Terminate "
                         "section", path=path)


def face_patch(face, label: str, index: int = 0):
    """(Patch, FaceSource) of one face; raises _Refused with the reason."""
    if len(face.Wires) != 1:
        raise _Refused(f"is trimmed: it has {len(face.Wires)} boundary loops (holes are not "
                       f"supported yet)")
    kind = face.Surface.TypeId
    if kind not in EXACT_TYPES:
        raise _Refused(f"has a {kind.split('Geom')[-1]} surface, which does not convert "
                       f"exactly to a B-spline")
    work = face
    if kind != "Part::GeomBSplineSurface":
        work = face.toNurbs().Faces[0]
        if work.Surface.TypeId != "Part::GeomBSplineSurface":
            raise _Refused(f"did not convert to a B-spline surface ({work.Surface.TypeId})")
    surf = work.Surface.copy()
    rng = tuple(work.ParameterRange)
    _check_on_rectangle(work, surf, rng)
    if work is not face:
        _check_conversion(face, work, rng)
    U0, U1, V0, V1 = surf.bounds()
    spans = (U1 - U0, V1 - V0)
    if any(abs(a - b) > 1e-9 * spans[k // 2] for k, (a, b) in enumerate(zip(rng, (U0, U1, V0, V1)))):
        try:
            surf.segment(*rng)               # an iso-parametric rectangle of a larger surface
        except Exception as exc:
            raise _Refused(f"is a part {rng} of its surface {surf.bounds()} that OCCT cannot cut "
                           f"out ({exc})")
    if surf.isUPeriodic():
        surf.setUNotPeriodic()
    if surf.isVPeriodic():
        surf.setVNotPeriodic()
    p, q = surf.UDegree, surf.VDegree
    poles = np.array([[[c.x, c.y, c.z] for c in row] for row in surf.getPoles()], float)
    weights = np.array(surf.getWeights(), float)
    uk = flat_knots(surf.getUKnots(), surf.getUMultiplicities())
    vk = flat_knots(surf.getVKnots(), surf.getVMultiplicities())
    bounds = tuple(float(x) for x in surf.bounds())
    rev = face.Orientation == "Reversed"
    if rev:                                  # keep the face's outward normal: S_u x S_v
        poles, weights = poles[::-1], weights[::-1]
        uk = (uk[0] + uk[-1]) - uk[::-1]
    patch = bspline_patch(poles, weights, uk, vk, p, q, index=index, name=label)
    return patch, FaceSource(label, bounds, rev, kind)


def _on_boundary(uv: np.ndarray, rng, tol: tuple) -> np.ndarray:
    u0, u1, v0, v1 = rng
    du = np.minimum(np.abs(uv[:, 0] - u0), np.abs(uv[:, 0] - u1)) <= tol[0]
    dv = np.minimum(np.abs(uv[:, 1] - v0), np.abs(uv[:, 1] - v1)) <= tol[1]
    inside = (uv[:, 0] >= u0 - tol[0]) & (uv[:, 0] <= u1 + tol[0]) & \
             (uv[:, 1] >= v0 - tol[1]) & (uv[:, 1] <= v1 + tol[1])
    return (du | dv) & inside


def _check_on_rectangle(face, surf, rng) -> None:
    """Every edge of the face runs along the boundary of its parameter rectangle."""
    u0, u1, v0, v1 = rng
    ptol = (1e-7 * (u1 - u0), 1e-7 * (v1 - v0))
    for e, edge in enumerate(face.Edges):
        if edge.Degenerated:
            raise _Refused("has a collapsed side (a pole): not supported")
        try:
            c2d, a, b = face.curveOnSurface(edge)
            uv = np.array([[w.x, w.y] for w in (c2d.value(t) for t in np.linspace(a, b, _EDGE_SAMPLES))])
        except Exception:                    # no curve on the surface stored: project
            uv = np.array([surf.parameter(edge.valueAt(t))
                           for t in np.linspace(edge.FirstParameter, edge.LastParameter, _EDGE_SAMPLES)])
        ok = _on_boundary(uv, rng, ptol)
        if not ok.all():
            x = uv[int(np.argmin(ok))]
            raise _Refused(f"is trimmed: its edge {e + 1} runs through ({x[0]:.6g}, {x[1]:.6g}) inside "
                           f"its parameter rectangle {tuple(round(r, 6) for r in rng)}")


def _check_conversion(face, work, rng) -> None:
    """OCCT's conversion must reproduce the original surface (sampled, projected back)."""
    orig = face.Surface
    bb = face.BoundBox
    tol = 1e-9 * max(1.0, float(np.linalg.norm([bb.XLength, bb.YLength, bb.ZLength])))
    u0, u1, v0, v1 = rng
    worst = 0.0
    for s in (0.1, 0.5, 0.9):
        for t in (0.1, 0.5, 0.9):
            P = work.valueAt(u0 + s * (u1 - u0), v0 + t * (v1 - v0))
            uo, vo = orig.parameter(P)
            worst = max(worst, (orig.value(uo, vo) - P).Length)
    if worst > tol:
        raise _Refused(f"does not convert exactly to a B-spline (off by {worst:.3g} mm)")
