"""Wavefront OBJ quad cages with OpenSubdiv's tag lines (docs/formats.md section 3).

Reads ``v``, ``f v[/vt[/vn]]`` (1-based, negative indices relative), and the tags
``t interpolateboundary 1/0/0 <0|1|2>`` (1 = edge-and-corner, 2 = edge-only, the default
when absent, as in OpenSubdiv's regression harness). Crease, corner, hole and hierarchical
edit tags, and boundary rule 0 (none) are refused with the line that carries them rather
than evaluated wrongly. ``vt``, ``vn``, ``g``, ``o``, ``s``, ``usemtl`` are ignored.
"""
from __future__ import annotations

import numpy as np

from ...errors import InputError
from ..cage import Cage
from ..quadmesh import QuadMesh

_RULES = {1: "edge-and-corner", 2: "edge-only"}


def read_obj(path: str, boundary_rule: str | None = None) -> Cage:
    points, faces, lines = [], [], []
    rule = None
    try:
        with open(path, "r", encoding="utf-8", errors="replace") as fh:
            text = fh.read().splitlines()
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
                points.append([float(x) for x in tok[1:4]])
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
                raise InputError(f"unknown record {kind!r}", path=path, line=ln)
        except ValueError:
            raise InputError(f"cannot read numbers in {raw.strip()!r}", path=path, line=ln)
    if not faces:
        raise InputError("no faces", path=path)
    mesh = QuadMesh(np.array(faces), len(points), boundary_rule or rule or "edge-only", path,
                    np.array(lines))
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
