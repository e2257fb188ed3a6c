"""Wavefront OBJ quad cages with OpenSubdiv's tag lines (docs/formats.md section 3).

Reads ``v``, ``f v[/vt[/vn]]`` (1-based, negative indices relative), and the tags
``t interpolateboundary 1/0/0 <0|1|2>`` (1 = edge-and-corner, 2 = edge-only, the default
when absent, as in OpenSubdiv's regression harness). Crease, corner, hole and hierarchical
edit tags, and boundary rule 0 (none) are refused with the line that carries them rather
than evaluated wrongly. ``vt``, ``vn``, ``g``, ``o``, ``s``, ``usemtl`` are ignored.
``write_obj`` writes a cage so (the shipped samples).
"""
from __future__ import annotations

import numpy as np

from ...errors import InputError
from ...inputfile import coordinate_error, excerpt, split_lines
from ..cage import Cage
from ..quadmesh import QuadMesh

_RULES = {1: "edge-and-corner", 2: "edge-only"}


def read_obj(path: str, boundary_rule: str | None = None) -> Cage:
    points, faces, lines, vlines = [], [], [], []
    rule = None
    try:
        with open(path, "r", encoding="utf-8", errors="replace") as fh:
            text = split_lines(fh.read())
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=path)
    for ln, raw in enumerate(text, start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        tok = line.split()
        kind = tok[0]
        try:
            if kind == "v":
                if len(tok) < 4:
                    raise InputError("a vertex needs three coordinates", path=path, line=ln)
                xyz = [float(x) for x in tok[1:4]]
                why = coordinate_error(xyz)
                if why:
                    raise InputError(f"vertex {len(points) + 1}: {why}", path=path, line=ln)
                points.append(xyz)
                vlines.append(ln)
            elif kind == "f":
                idx = []
                for t in tok[1:]:
                    i = int(t.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(points) + i)
                if len(idx) != 4:
                    raise InputError(f"face has {len(idx)} vertices: tsplcam needs quad cages "
                                     f"(split n-gons into quads first)", path=path, line=ln)
                faces.append(idx)
                lines.append(ln)
            elif kind == "t":
                rule = _tag(tok, path, ln, rule)
            elif kind in ("vt", "vn", "vp", "g", "o", "s", "usemtl", "mtllib", "l"):
                continue
            else:
                raise InputError(f"unknown record {excerpt(kind, 40)}", path=path, line=ln)
        except ValueError:
            raise InputError(f"cannot read numbers in {excerpt(raw)}", path=path, line=ln)
    if not faces:
        raise InputError("no faces (f lines)", path=path, line=max(1, len(text)))
    mesh = QuadMesh(np.array(faces), len(points), boundary_rule or rule or "edge-only", path,
                    np.array(lines))
    # the cage's own checks in their order (indices, then edges), then unused vertices here,
    # where their lines are known
    for f, idx in enumerate(faces):
        if not all(0 <= i < len(points) for i in idx):
            raise InputError(f"{mesh.face_name(f)} refers to a vertex that does not exist (there "
                             f"are {len(points)})", path=path, line=lines[f])
    mesh.edges  # noqa: B018  (orientation and manifold edges)
    used = np.zeros(len(points), bool)
    used[np.array(faces).reshape(-1)] = True
    if not used.all():
        k = int(np.nonzero(~used)[0][0])
        raise InputError(f"vertex {k + 1} is not used by any face ({int((~used).sum())} unused "
                         f"vertices)", path=path, line=vlines[k])
    return Cage(mesh, np.array(points, dtype=float).reshape(-1, 3), None,
                {"interpolateboundary": mesh.boundary_rule})


def _tag(tok, path, ln, rule):
    name = tok[1] if len(tok) > 1 else ""
    if name == "interpolateboundary":
        try:
            value = int(tok[3])
        except (IndexError, ValueError):
            raise InputError("interpolateboundary tag needs an integer value", path=path, line=ln)
        if value not in _RULES:
            raise InputError(f"interpolateboundary {value} is not supported (1 edge-and-corner, "
                             f"2 edge-only)", path=path, line=ln)
        return _RULES[value]
    if name in ("crease", "corner"):
        raise InputError(f"'{name}' tags are not supported yet: tsplcam refuses sharp features "
                         f"rather than evaluating them wrongly", path=path, line=ln)
    raise InputError(f"tag '{name}' is not supported", path=path, line=ln)


def write_obj(cage: Cage, path: str, comment: str = "") -> None:
    """A cage as an OBJ file (mm), with OpenSubdiv's boundary tag."""
    tag = {rule: value for value, rule in _RULES.items()}[cage.mesh.boundary_rule]
    with open(path, "w") as fh:
        fh.write(f"# tsplcam sample: {comment}\n# units: mm\n")
        for p in cage.points:
            fh.write("v {:.10g} {:.10g} {:.10g}\n".format(*p))
        for f in cage.mesh.faces:
            fh.write("f {} {} {} {}\n".format(*(f + 1)))
        fh.write(f"t interpolateboundary 1/0/0 {tag}\n")
