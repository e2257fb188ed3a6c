"""Triangle meshes from OBJ files: stock, mold blocks and fixtures for the collision checks.

Only ``v`` and ``f`` records are read (``f`` indices 1-based, negative ones counted from the
last vertex, ``v/vt/vn`` forms allowed); faces with more than three corners are split
into a fan. Everything else (normals, texture coordinates, groups) is ignored. Units: mm.
"""
from __future__ import annotations

import numpy as np

from ...errors import InputError


def read_triangles(path: str) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3) float, triangles (m, 3) int) of an OBJ file. Errors name the file
    and line: unreadable numbers, a face with fewer than three corners, a coordinate that is
    not finite, a face that refers to a missing vertex, or no triangle at all."""
    V, T = [], []
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            lines = fh.read().splitlines()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=path) from None
    for ln, raw in enumerate(lines, start=1):
        tok = raw.split("#", 1)[0].split()
        if not tok:
            continue
        try:
            if tok[0] == "v":
                xyz = [float(x) for x in tok[1:4]]
                if len(xyz) < 3 or not all(np.isfinite(xyz)):
                    raise InputError("a vertex needs three finite coordinates", path=path, line=ln)
                V.append(xyz)
            elif tok[0] == "f":
                idx = [int(t.split("/")[0]) for t in tok[1:]]
                idx = [i - 1 if i > 0 else len(V) + i for i in idx]
                if len(idx) < 3:
                    raise InputError("a face needs three vertices", path=path, line=ln)
                if any(not 0 <= i < 2 ** 31 for i in idx):
                    raise InputError("a face refers to a vertex index out of range", path=path, line=ln)
                T += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
        except ValueError:
            raise InputError(f"cannot read numbers in {raw.strip()!r}", path=path, line=ln) from None
    V, T = np.array(V, float).reshape(-1, 3), np.array(T, int).reshape(-1, 3)
    if len(T) == 0 or T.min() < 0 or T.max() >= len(V):
        raise InputError("no triangles, or a face refers to a missing vertex", path=path)
    return V, T
