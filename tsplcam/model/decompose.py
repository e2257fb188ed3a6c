"""Split a quad mesh into four-sided patches (shang2020 section 2.2, figure 2).

Patch boundaries are the lines that run along mesh edges from every extraordinary point
and every boundary corner (separatrices), straight through regular vertices, until they
reach another such point or the boundary; and the open boundary itself. Between them
the faces form rectangles of r x c faces, each a patch with its own (u, v). A region with
no such point to start from (a torus, an open tube) is cut by seeding a line at one of its
vertices, so every closed or periodic part still becomes four-sided patches.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .quadmesh import QuadMesh

_STEP = ((0, -1), (1, 0), (0, 1), (-1, 0))     # neighbour cell across cell edge m


@dataclass
class Region:
    """A rectangle of faces: face f sits in cell (i, j) with its corner (rot + m) % 4 at cell
    corner m (0 = lower left, counter-clockwise)."""
    faces: np.ndarray
    cell: np.ndarray
    rot: np.ndarray
    size: tuple[int, int]
    corners: np.ndarray          # mesh vertices at the rectangle's corners 0..3

    def face_at(self) -> dict:
        return {(int(i), int(j)): (int(f), int(r)) for f, (i, j), r in zip(self.faces, self.cell, self.rot)}


@dataclass
class Decomposition:
    regions: list[Region]
    separatrices: set                        # undirected edges (a < b) on patch boundaries
    face_region: np.ndarray                  # (F,) region of each face
    links: list                              # ((region, edge), (region, edge), reversed)


def _key(a: int, b: int) -> tuple[int, int]:
    return (a, b) if a < b else (b, a)


def _ring(mesh: QuadMesh, v: int) -> list[int]:
    """Edge neighbours of v in rotational order (boundary vertices: first to last boundary edge)."""
    fan, boundary = mesh.fan(v)
    ring = [int(mesh.faces[f][(k + 1) % 4]) for f, k in fan]
    if boundary:
        f, k = fan[-1]
        ring.append(int(mesh.faces[f][(k + 3) % 4]))
    return ring


def _trace(mesh: QuadMesh, singular: set, start: int, first: int, traced: set) -> None:
    v, w = start, first
    for _ in range(4 * len(mesh.faces) + 4):
        key = _key(v, w)
        if key in traced:
            return
        traced.add(key)
        if w in singular or mesh.fan(w)[1]:
            return
        ring = _ring(mesh, w)
        v, w = w, ring[(ring.index(v) + 2) % 4]


def _components(mesh: QuadMesh, traced: set) -> list[list[int]]:
    parent = list(range(len(mesh.faces)))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for (a, b), (f, _) in mesh.edges.items():
        if a < b and (b, a) in mesh.edges and _key(a, b) not in traced:
            g = mesh.edges[(b, a)][0]
            parent[find(f)] = find(g)
    groups: dict[int, list[int]] = {}
    for f in range(len(mesh.faces)):
        groups.setdefault(find(f), []).append(f)
    return sorted(groups.values(), key=lambda g: g[0])


def _rectangle(mesh: QuadMesh, faces: list[int], traced: set):
    """Cell coordinates of a component, or None when it is not a proper rectangle."""
    members = set(faces)
    f0 = faces[0]
    cell = {f0: (0, 0)}
    rot = {f0: 0}
    queue = [f0]
    while queue:
        f = queue.pop()
        ci, cj = cell[f]
        for m in range(4):
            k = (rot[f] + m) % 4
            a, b = int(mesh.faces[f][k]), int(mesh.faces[f][(k + 1) % 4])
            hit = mesh.edges.get((b, a))
            if hit is None or _key(a, b) in traced:
                continue
            g, kk = hit
            if g not in members:
                continue
            want = (ci + _STEP[m][0], cj + _STEP[m][1])
            rg = (kk - (m + 2)) % 4
            if g in cell:
                if cell[g] != want or rot[g] != rg:
                    return None
                continue
            cell[g], rot[g] = want, rg
            queue.append(g)
    coords = np.array([cell[f] for f in faces])
    coords -= coords.min(axis=0)
    nc, nr = coords.max(axis=0) + 1
    if len({tuple(c) for c in coords}) != len(faces) or nc * nr != len(faces):
        return None
    lookup = {tuple(c): f for f, c in zip(faces, coords)}
    # a traced edge between grid neighbours inside the rectangle is a slit: not a patch
    for f, c in zip(faces, coords):
        for m in range(4):
            k = (rot[f] + m) % 4
            a, b = int(mesh.faces[f][k]), int(mesh.faces[f][(k + 1) % 4])
            nb = (c[0] + _STEP[m][0], c[1] + _STEP[m][1])
            if _key(a, b) in traced and nb in lookup:
                hit = mesh.edges.get((b, a))
                if hit is not None and hit[0] == lookup[nb]:
                    return None
    rots = np.array([rot[f] for f in faces])
    corners = []
    for m, c in enumerate(((0, 0), (nc - 1, 0), (nc - 1, nr - 1), (0, nr - 1))):
        f = lookup[c]
        corners.append(int(mesh.faces[f][(rots[faces.index(f)] + m) % 4]))
    return Region(np.array(faces), coords, rots, (int(nc), int(nr)), np.array(corners))


def decompose(mesh: QuadMesh) -> Decomposition:
    """Patches of a (validated) quad mesh."""
    singular = {v for v in range(mesh.n_vertices) if mesh.valence(v) and mesh.is_layout_vertex(v)}
    seeds: set[int] = set()
    for _ in range(len(mesh.faces) + 1):
        starts = singular | seeds
        traced: set = set()
        for v in sorted(starts):
            for w in _ring(mesh, v):
                if not mesh.is_boundary_edge(v, w):
                    _trace(mesh, starts, v, w, traced)
        for (a, b) in mesh.edges:            # the open boundary bounds patches too
            if mesh.is_boundary_edge(a, b):
                traced.add(_key(a, b))
        regions, bad = [], None
        for comp in _components(mesh, traced):
            reg = _rectangle(mesh, comp, traced)
            if reg is None:
                bad = comp
                break
            regions.append(reg)
        if bad is None:
            break
        # seed a line at a vertex of the offending component that is not yet a start
        candidates = [int(v) for f in bad for v in mesh.faces[f] if int(v) not in starts]
        if not candidates:
            raise InputError(f"cannot split the faces around {mesh.face_name(bad[0])} into "
                             f"four-sided patches", path=mesh.source)
        seeds.add(min(candidates))
    else:
        raise InputError("cannot split the surface into four-sided patches", path=mesh.source)
    face_region = np.full(len(mesh.faces), -1)
    for r, reg in enumerate(regions):
        face_region[reg.faces] = r
    links = _links(mesh, regions, face_region)
    return Decomposition(regions, traced, face_region, links)


def _links(mesh: QuadMesh, regions: list[Region], face_region: np.ndarray) -> list:
    """Whole-edge neighbours between regions: ((r, edge), (r', edge'), reversed)."""
    pos = {}
    for r, reg in enumerate(regions):
        for f, c, rot in zip(reg.faces, reg.cell, reg.rot):
            pos[int(f)] = (r, tuple(c), int(rot))
    out, seen = [], set()
    for r, reg in enumerate(regions):
        nc, nr = reg.size
        at = reg.face_at()
        sides = {0: [(i, 0) for i in range(nc)], 1: [(nc - 1, j) for j in range(nr)],
                 2: [(i, nr - 1) for i in reversed(range(nc))], 3: [(0, j) for j in reversed(range(nr))]}
        for m, cells in sides.items():
            if (r, m) in seen:
                continue
            across = []
            for c in cells:
                f, rot = at[c]
                k = (rot + m) % 4
                a, b = int(mesh.faces[f][k]), int(mesh.faces[f][(k + 1) % 4])
                hit = mesh.edges.get((b, a))
                if hit is None:
                    across.append(None)
                    continue
                g, kk = hit
                rg, cg, rotg = pos[g]
                across.append((rg, (kk - rotg) % 4, cg))
            if all(x is None for x in across):
                continue
            if any(x is None for x in across) or len({(x[0], x[1]) for x in across}) != 1:
                raise InputError(f"patch boundary of {mesh.face_name(int(at[cells[0]][0]))} is not one "
                                 f"whole edge of a neighbouring patch", path=mesh.source)
            rb, mb = across[0][0], across[0][1]
            nb_len = regions[rb].size[0] if mb in (0, 2) else regions[rb].size[1]
            if nb_len != len(cells):
                raise InputError(f"patches {r} and {rb} share only part of an edge", path=mesh.source)
            # cells run along edge m's direction; the neighbour's cells along its own edge
            first, last = across[0][2], across[-1][2]
            nb_side = _side_cells(regions[rb], mb)
            reversed_ = bool(nb_side.index(first) > nb_side.index(last)) if len(cells) > 1 else \
                _single_reversed(mesh, regions, r, m, rb, mb)
            out.append(((r, m), (rb, mb), reversed_))
            seen.add((r, m))
            seen.add((rb, mb))
    return out


def _side_cells(reg: Region, m: int) -> list:
    nc, nr = reg.size
    return {0: [(i, 0) for i in range(nc)], 1: [(nc - 1, j) for j in range(nr)],
            2: [(i, nr - 1) for i in reversed(range(nc))], 3: [(0, j) for j in reversed(range(nr))]}[m]


def _single_reversed(mesh, regions, r, m, rb, mb) -> bool:
    """Direction of a one-face-long shared edge, from the corner vertices."""
    a0, a1 = regions[r].corners[m], regions[r].corners[(m + 1) % 4]
    b0, b1 = regions[rb].corners[mb], regions[rb].corners[(mb + 1) % 4]
    if (a0, a1) == (b1, b0):
        return True
    if (a0, a1) == (b0, b1):
        return False
    return True
