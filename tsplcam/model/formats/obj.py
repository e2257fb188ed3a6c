"""Wavefront OBJ quad cages with OpenSubdiv's tag lines (docs/formats.md section 3).

Reads ``v``, ``f v[/vt[/vn]]`` (1-based, negative indices relative), and OpenSubdiv's tags
``t <name> <nints>/<nfloats>/<nstrings> <ints> <floats> <strings>`` as its regression
harness applies them (``far_utils.h``):

* ``interpolateboundary`` 1 edge-and-corner, 2 edge-only (the default when absent);
* ``crease``: pairs of 0-based vertex ids, one sharpness for all pairs or one per pair
  (s >= 10 infinitely sharp, negative values read as 0);
* ``corner``: 0-based vertex ids with one sharpness for all or one per vertex;
* ``creasemethod normal`` (OpenSubdiv's uniform creasing, the default).

Boundary rule 0 (none), holes, Chaikin creasing, hierarchical edits and other tags are
refused with the line that carries them rather than evaluated wrongly, and so is a crease
on a pair of vertices that is not an edge of the cage. ``vt``, ``vn``, ``g``, ``o``, ``s``,
``usemtl`` are ignored. ``write_obj`` writes a cage so (the shipped samples).
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
    tags = []
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
                tag = _tag(tok, path, ln)
                if tag[0] == "interpolateboundary":
                    rule = tag[1]
                elif tag[0] in ("crease", "corner"):
                    tags.append((ln,) + tag)
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
    sharpness, corners = _sharp_features(tags, mesh, len(points), path)
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
    mesh.sharpness = sharpness or None
    mesh.corner_sharpness = corners or None
    return Cage(mesh, np.array(points, dtype=float).reshape(-1, 3), None,
                {"interpolateboundary": mesh.boundary_rule})


def _tag(tok, path, ln):
    """One ``t`` line: ("interpolateboundary", rule), ("crease"/"corner", ints, floats) or
    ("creasemethod", None)."""
    name = tok[1] if len(tok) > 1 else ""
    try:
        counts = [int(x) for x in tok[2].split("/")]
        if len(counts) != 3 or min(counts) < 0:
            raise ValueError
        nint, nfloat, nstring = counts
        ints = [int(x) for x in tok[3:3 + nint]]
        floats = [float(x) for x in tok[3 + nint:3 + nint + nfloat]]
        strings = tok[3 + nint + nfloat:3 + nint + nfloat + nstring]
        if len(ints) != nint or len(floats) != nfloat or len(strings) != nstring:
            raise ValueError
    except (IndexError, ValueError):
        raise InputError(f"tag {excerpt(name, 40)!r}: expected '<ints>/<floats>/<strings>' counts and "
                         f"that many values", path=path, line=ln)
    if name == "interpolateboundary":
        if nint != 1:
            raise InputError("interpolateboundary tag needs one integer value", path=path, line=ln)
        if ints[0] not in _RULES:
            raise InputError(f"interpolateboundary {ints[0]} is not supported (1 edge-and-corner, "
                             f"2 edge-only)", path=path, line=ln)
        return ("interpolateboundary", _RULES[ints[0]])
    if name in ("crease", "corner"):
        per = 2 if name == "crease" else 1
        items = nint // per
        if nint == 0 or nint % per or not (nfloat == 1 or nfloat == items):
            raise InputError(f"'{name}' tag: {nint} vertex ids and {nfloat} sharpness values (expected "
                             f"{'pairs of vertex ids' if per == 2 else 'vertex ids'} and one sharpness "
                             f"for all or one each)", path=path, line=ln)
        if not all(np.isfinite(floats)):
            raise InputError(f"'{name}' tag: sharpness is not a number", path=path, line=ln)
        return (name, ints, floats)
    if name == "creasemethod":
        if strings != ["normal"]:
            raise InputError(f"creasemethod {' '.join(strings)!r} is not supported (only 'normal', "
                             f"OpenSubdiv's uniform creasing)", path=path, line=ln)
        return ("creasemethod", None)
    raise InputError(f"tag '{excerpt(name, 40)}' is not supported", path=path, line=ln)


def _sharp_features(tags, mesh: QuadMesh, n_points: int, path):
    """Edge and vertex sharpness from the crease and corner tags (the last tag naming an
    edge or vertex wins), single precision as OpenSubdiv stores it."""
    sharpness, corners = {}, {}
    for ln, name, ints, floats in tags:
        per = 2 if name == "crease" else 1
        for k in range(len(ints) // per):
            value = float(np.float32(max(0.0, floats[k] if len(floats) > 1 else floats[0])))
            ids = ints[per * k:per * k + per]
            bad = [i for i in ids if not 0 <= i < n_points]
            if bad:
                raise InputError(f"'{name}' tag: vertex id {bad[0]} does not exist (0-based ids, "
                                 f"{n_points} vertices)", path=path, line=ln)
            if name == "corner":
                corners[ids[0]] = value
                continue
            a, b = ids
            if (a, b) not in mesh.edges and (b, a) not in mesh.edges:
                raise InputError(f"'crease' tag: vertices {a} and {b} (0-based) are not joined by an "
                                 f"edge of the cage", path=path, line=ln)
            sharpness[(min(a, b), max(a, b))] = value
    return ({e: s for e, s in sharpness.items() if s > 0.0},
            {v: s for v, s in corners.items() if s > 0.0})


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
