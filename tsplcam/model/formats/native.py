"""tsplcam's own model file (``.tspl``): a T-mesh with knot intervals, or a Catmull-Clark cage.

JSON, one vertex or face per line, numbers written with Python's shortest round-trip
``repr`` so that write -> read -> write gives identical bytes and the surface evaluates
identically. The schema (version 1) is documented in ``NATIVE.md`` beside this file.
Errors name the file and the line of the offending vertex or face.
"""
from __future__ import annotations

import bisect
import json
import os

import numpy as np

from ...errors import InputError
from ...inputfile import first_coordinate_error, naming, read_json, weight_error

FORMAT = "tsplcam-model"
VERSION = 2                    # 2 adds "creases" and "corners" to catmull-clark cages
CREASE_VERSION = 2
KINDS = ("t-spline", "catmull-clark")
T_SPLINE_BOUNDARY = "repeat-last-knot"
#: a t-spline's open boundaries not clamped, read as the Fusion reader reads them: the
#: boundary clamped with the second grip row of OpenSubdiv's edge-and-corner rule, boundary
#: star points from local Catmull-Clark cages (docs/formats.md section 2.5)
T_SPLINE_OPEN = "edge-and-corner"
T_SPLINE_BOUNDARIES = (T_SPLINE_BOUNDARY, T_SPLINE_OPEN)
CAGE_BOUNDARIES = ("edge-only", "edge-and-corner")
UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}


# -- writing -----------------------------------------------------------------------------------
def _num(x) -> str:
    x = float(x)
    if not np.isfinite(x):
        raise InputError(f"cannot write the number {x!r}: the model is invalid")
    return repr(x)


def dumps(control, name: str | None = None) -> str:
    """The text of a native file for a ``TMesh`` (kind t-spline) or a ``Cage`` (kind
    catmull-clark); a ``Model`` is written through its control mesh."""
    from ..cage import Cage
    from ..tmesh import TMesh
    if hasattr(control, "patches"):                   # a Model
        if getattr(control, "no_native", None):
            raise InputError(f"cannot write a native model of {control.no_native}")
        own = getattr(control, "name", None)
        if own and own != os.path.basename(getattr(control, "source", None) or ""):
            name = name or own                        # not just the file name it was read from
        control = control.control
    if isinstance(control, TMesh):
        control.validate()
        kind, boundary = "t-spline", T_SPLINE_BOUNDARY
        points, weights = control.points, control.weights
        name = name or control.name
    elif isinstance(control, Cage):
        control.mesh.validate(control.homogeneous())
        kind, boundary = "catmull-clark", control.mesh.boundary_rule
        points = control.points
        weights = np.ones(len(points)) if control.weights is None else np.asarray(control.weights, float)
    else:
        raise InputError(f"cannot write a {type(control).__name__} as a native model (only T-meshes and "
                         f"cages have a native file)")
    creased = kind == "catmull-clark" and control.mesh.creased
    # a file without creases is written as version 1, which every tsplcam reads
    out = ["{", f'  "format": "{FORMAT}",', f'  "version": {CREASE_VERSION if creased else 1},',
           '  "units": "mm",', f'  "kind": "{kind}",']
    if name:
        out.append(f'  "name": {json.dumps(str(name))},')
    out.append(f'  "boundary": "{boundary}",')
    out.append('  "vertices": [')
    n = len(points)
    for k, (p, w) in enumerate(zip(points, weights)):
        out.append("    [" + ", ".join(_num(x) for x in (*p, w)) + "]" + ("," if k < n - 1 else ""))
    out.append("  ],")
    out.append('  "faces": [')
    if kind == "t-spline":
        nf = len(control.faces)
        for f in range(nf):
            loop = ", ".join(str(int(v)) for v in control.faces[f])
            cs = ", ".join(str(int(c)) for c in control.corners[f])
            d = ", ".join(_num(x) for x in control.intervals[f])
            out.append(f'    {{"vertices": [{loop}], "corners": [{cs}], "intervals": [{d}]}}'
                       + ("," if f < nf - 1 else ""))
    else:
        faces = control.mesh.faces
        for f, quad in enumerate(faces):
            out.append("    [" + ", ".join(str(int(v)) for v in quad) + "]" + ("," if f < len(faces) - 1 else ""))
    if creased:
        mesh = control.mesh
        out.append("  ],")
        rows = [f"    [{a}, {b}, {_num(x)}]" for (a, b), x in sorted((mesh.sharpness or {}).items())]
        out.append('  "creases": [' + ("\n" + ",\n".join(rows) + "\n  " if rows else "") + "],")
        rows = [f"    [{v}, {_num(x)}]" for v, x in sorted((mesh.corner_sharpness or {}).items())]
        out.append('  "corners": [' + ("\n" + ",\n".join(rows) + "\n  " if rows else "") + "]")
    else:
        out.append("  ]")
    out.append("}")
    return "\n".join(out) + "\n"


def write_native(control, path, name: str | None = None) -> str:
    """Write ``control`` (a TMesh, a Cage, or a Model) to ``path``; returns the path."""
    text = dumps(control, name)
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(text)
    return os.fspath(path)


# -- reading -----------------------------------------------------------------------------------
def _element_lines(text: str) -> dict:
    """1-based line of every element of the top-level arrays, by key (the text is valid JSON)."""
    dec = json.JSONDecoder()
    newlines = [i for i, c in enumerate(text) if c == "\n"]

    def line(pos):
        return bisect.bisect_left(newlines, pos) + 1

    def ws(i):
        while i < len(text) and text[i] in " \t\r\n":
            i += 1
        return i

    out = {}
    i = ws(0)
    if i >= len(text) or text[i] != "{":
        return out
    i = ws(i + 1)
    while i < len(text) and text[i] != "}":
        key, i = json.decoder.scanstring(text, i + 1)
        i = ws(ws(i) + 1)                       # past ':'
        if text[i] == "[":
            starts, j = [], ws(i + 1)
            while text[j] != "]":
                starts.append(line(j))
                _, j = dec.raw_decode(text, j)
                j = ws(j)
                if text[j] == ",":
                    j = ws(j + 1)
            out[key] = starts
            i = j + 1
        else:
            _, i = dec.raw_decode(text, i)
        i = ws(i)
        if i < len(text) and text[i] == ",":
            i = ws(i + 1)
    return out


def read_native(path):
    """The control mesh of a native file: (kind, TMesh or Cage, name)."""
    from ..cage import Cage
    from ..quadmesh import QuadMesh
    from ..tmesh import TMesh
    path = os.fspath(path)
    data, text = read_json(path, "model file")
    lines = _element_lines(text)

    def err(msg, key=None, k=None):
        ln = lines.get(key, [None] * (k + 1))[k] if key is not None and k is not None else None
        return InputError(msg, path=path, line=ln)

    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f'not a tsplcam model file (needs "format": "{FORMAT}")', path=path,
                         item="format")
    version = data.get("version")
    if not isinstance(version, int) or isinstance(version, bool):
        raise InputError('"version" must be an integer', path=path, item="version")
    if version > VERSION:
        raise InputError(f"written by a newer tsplcam (file version {version}); this one reads version "
                         f"{VERSION}", path=path, item="version")
    if version < 1:
        raise InputError(f"unknown file version {version}", path=path, item="version")
    units = data.get("units")
    if not isinstance(units, str) or units not in UNITS:
        raise InputError(f'"units" must be one of {", ".join(UNITS)} (got {units!r})', path=path,
                         item="units")
    kind = data.get("kind")
    if kind not in KINDS:
        raise InputError(f'"kind" must be one of {", ".join(KINDS)} (got {kind!r})', path=path,
                         item="kind")
    name = data.get("name")
    if name is not None and not isinstance(name, str):
        raise InputError('"name" must be a string', path=path, item="name")
    boundary = data.get("boundary", T_SPLINE_BOUNDARY if kind == "t-spline" else "edge-only")
    allowed = T_SPLINE_BOUNDARIES if kind == "t-spline" else CAGE_BOUNDARIES
    if boundary not in allowed:
        raise InputError(f'"boundary" of a {kind} model must be {" or ".join(allowed)} (got {boundary!r})',
                         path=path, item="boundary")
    known = {"format", "version", "units", "kind", "name", "boundary", "vertices", "faces"}
    if version >= CREASE_VERSION and kind == "catmull-clark":
        known |= {"creases", "corners"}
    unknown = set(data) - known
    if unknown:
        raise InputError(f"unknown keys {sorted(unknown)} (version {VERSION} files have none)", path=path,
                         item=repr(sorted(unknown)[0]))
    verts = data.get("vertices")
    faces = data.get("faces")
    if not isinstance(verts, list) or not verts:
        raise InputError('"vertices" must be a non-empty list', path=path, item="vertices")
    if not isinstance(faces, list) or not faces:
        raise InputError('"faces" must be a non-empty list', path=path, item="faces")
    P = np.empty((len(verts), 3))
    W = np.ones(len(verts))
    for k, v in enumerate(verts):
        if (not isinstance(v, list) or len(v) not in (3, 4)
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
            raise err(f"vertex {k + 1}: needs [x, y, z] or [x, y, z, w] numbers", "vertices", k)
        P[k] = v[:3]
        if len(v) == 4:
            W[k] = v[3]
    P *= UNITS[units]
    bad = first_coordinate_error(P)
    if bad is not None:
        raise err(f"vertex {bad[0] + 1}: {bad[1]}", "vertices", bad[0])
    for k, w in enumerate(W):
        why = weight_error(w)
        if why:
            raise err(f"vertex {k + 1}: {why}", "vertices", k)
    vlines = lines.get("vertices")
    flines = lines.get("faces")

    def ints(x, what, k):
        if not isinstance(x, list) or not all(isinstance(i, int) and not isinstance(i, bool) for i in x):
            raise err(f"face {k + 1}: {what} must be a list of integers", "faces", k)
        return x

    if kind == "catmull-clark":
        quads = []
        for k, f in enumerate(faces):
            f = ints(f, "a face", k)
            if len(f) != 4:
                raise err(f"face {k + 1} has {len(f)} vertices: a Catmull-Clark cage has quads only",
                          "faces", k)
            quads.append(f)
        mesh = QuadMesh(np.array(quads), len(P), boundary, path, np.array(flines) if flines else None)
        mesh.sharpness, mesh.corner_sharpness = _sharp_features(data, mesh, len(P), err)
        # exact by construction: weights as written in the file (absent = 1.0)
        cage = Cage(mesh, P, None if np.all(W == 1.0) else W, {"interpolateboundary": boundary})
        mesh.validate(cage.homogeneous())
        return kind, cage, name
    loops, corners, intervals = [], [], []
    for k, f in enumerate(faces):
        if not isinstance(f, dict) or set(f) - {"vertices", "corners", "intervals"} or "vertices" not in f:
            raise err(f'face {k + 1}: needs {{"vertices": [...], "corners": [...], "intervals": [...]}}',
                      "faces", k)
        loop = ints(f["vertices"], '"vertices"', k)
        cs = ints(f.get("corners", [0, 1, 2, 3] if len(loop) == 4 else None), '"corners"', k)
        d = f.get("intervals")
        if (not isinstance(d, list)
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in d)):
            raise err(f'face {k + 1}: "intervals" must be a list of numbers', "faces", k)
        loops.append(loop)
        corners.append(cs)
        intervals.append(d)
    mesh = TMesh(P, W, loops, corners, intervals, source=path, face_lines=flines, vertex_lines=vlines,
                 name=name)
    mesh.validate()
    # how its open boundaries are read (native_model): clamped as they are, or by the
    # edge-and-corner rule
    mesh.boundary_rule = boundary
    return kind, mesh, name


def _sharp_features(data: dict, mesh, n: int, err):
    """Crease sharpness [[a, b, s], ...] (a, b 0-based vertices joined by an edge) and corner
    sharpness [[v, s], ...], as OpenSubdiv's crease and corner tags."""
    sharp, corners = {}, {}
    for key, width in (("creases", 3), ("corners", 2)):
        rows = data.get(key, [])
        if not isinstance(rows, list):
            raise err(f'"{key}" must be a list', key, 0)
        for k, row in enumerate(rows):
            if (not isinstance(row, list) or len(row) != width
                    or not all(isinstance(i, int) and not isinstance(i, bool) for i in row[:-1])
                    or not isinstance(row[-1], (int, float)) or isinstance(row[-1], bool)
                    or not np.isfinite(row[-1]) or row[-1] < 0):
                raise err(f"{key[:-1]} {k + 1}: needs [{'a, b' if width == 3 else 'v'}, sharpness >= 0]", key, k)
            ids = row[:-1]
            if not all(0 <= i < n for i in ids):
                raise err(f"{key[:-1]} {k + 1}: vertex {ids} does not exist", key, k)
            value = float(np.float32(row[-1]))
            if width == 2:
                if value > 0:
                    corners[ids[0]] = value
                continue
            a, b = ids
            if (a, b) not in mesh.edges and (b, a) not in mesh.edges:
                raise err(f"crease {k + 1}: vertices {a} and {b} are not joined by an edge", key, k)
            if value > 0:
                sharp[(min(a, b), max(a, b))] = value
    return sharp or None, corners or None


def native_model(path, **options):
    """The surface model of a native file."""
    kind, control, name = read_native(path)
    with naming(path):
        if kind == "catmull-clark":
            from ..cage import cage_model
            return cage_model(control, name=name)
        if getattr(control, "boundary_rule", T_SPLINE_BOUNDARY) == T_SPLINE_OPEN:
            from .tsm_fusion import MeshReader, kernel_model
            G = np.column_stack([control.points, control.weights])
            model, _ = kernel_model(MeshReader(control), control, G,
                                    name or os.path.splitext(os.path.basename(os.fspath(path)))[0])
            return model
        from ..tspline import tspline_model
        return tspline_model(control, name=name)
