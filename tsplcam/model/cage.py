"""Catmull-Clark control cages (OBJ, OpenSubdiv conventions) as patch models.

The limit surface of a quad cage: faces whose four corners are regular are bicubic
B-spline patches (16 points, phantom points beyond an open boundary) converted to Bezier
cells; faces with one irregular corner are evaluated exactly by eigen-analysis
(``eigen.py``). Where a face has more than one irregular corner the cage is refined once
first, so that every face has at most one (Stam 1998's assumption). Patches come from
``decompose``; a cage face keeps its place in its patch for ``Model.evaluate_faces``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .basis import BSPLINE_TO_BEZIER
from .adaptive import AdaptiveCells, classify_many, resolve, rotation_index
from .cells import BezierCells, LevelCells
from .decompose import QuadDecomposition, decompose
from .eigen import NotSelfSimilar
from .model import ExtraordinaryPoint, FaceMap, Model, link_patches
from .patch import CORNER_UV, Patch
from .quadmesh import QuadMesh, refined_points


@dataclass
class Cage:
    """A quad control mesh with positions (n, 3) and weights (n,), as read from a file."""
    mesh: QuadMesh
    points: np.ndarray
    weights: np.ndarray | None = None
    tags: dict = field(default_factory=dict)

    def homogeneous(self) -> np.ndarray:
        w = np.ones(len(self.points)) if self.weights is None else np.asarray(self.weights, float)
        return np.column_stack([self.points * w[:, None], w])


def _children(items, level: int):
    """Cells of the faces ``items`` = [(face, i, j, rot)] after ``level`` refinements: child
    4 f + k of a face at cell (i, j) with rotation rot sits in the sub-cell at the parent's
    cell corner m = k - rot, with its own corner 0 (the parent's vertex) there too."""
    for _ in range(level):
        out = []
        for f, i, j, rot in items:
            for k in range(4):
                m = (k - rot) % 4
                di, dj = ((0, 0), (1, 0), (1, 1), (0, 1))[m]
                out.append((4 * f + k, 2 * i + di, 2 * j + dj, (-m) % 4))
        items = out
    return items


def cage_model(cage: Cage, name: str | None = None) -> Model:
    """The limit surface of ``cage`` split into patches."""
    mesh = cage.mesh
    H0 = cage.homogeneous()
    mesh.validate(H0)
    dec = decompose(mesh)
    # faces with two irregular corners are refined once first (Stam's assumption); corners
    # near semi-sharp creases are left to the local refinement of ``adaptive``
    irregular = np.array([bool(mesh.valence(v)) and not mesh.is_regular_vertex(v)
                          and not (mesh.creased and mesh.has_semi_sharp_at(v))
                          for v in range(mesh.n_vertices)])
    level = 1 if (irregular[mesh.faces].sum(axis=1) >= 2).any() else 0
    while True:
        try:
            patches = _build_patches(mesh, H0, dec, level)
            break
        except NotSelfSimilar:
            if level >= 2:
                raise
            level += 1
    return _finish(mesh, dec, patches, cage, name)


def _build_patches(mesh: QuadMesh, H0: np.ndarray, dec: QuadDecomposition, level: int) -> list[Patch]:
    emesh, He = mesh, H0
    for _ in range(level):
        emesh, R, _ = emesh.refine()
        He = refined_points(R, He)
    M = BSPLINE_TO_BEZIER
    patches = []
    for r, reg in enumerate(dec.regions):
        nc, nr = reg.size
        sub = 1 << level
        nu, nv = nc * sub, nr * sub
        group = np.zeros((nu, nv), dtype=int)
        local = np.zeros((nu, nv), dtype=int)
        bez, eig, deep = [], {}, []
        items = _children([(int(f), int(i), int(j), int(rot))
                           for f, (i, j), rot in zip(reg.faces, reg.cell, reg.rot)], level)
        found = classify_many(emesh, [t[0] for t in items], [t[3] for t in items], He)
        for (e, ci, cj, re), leaf in zip(items, found):
            if leaf is None:                 # near semi-sharp creases, several irregular corners
                local[ci, cj] = len(deep)
                group[ci, cj] = -3
                deep.append((e, re))
                continue
            if leaf[0] == "bezier":
                G = leaf[1].reshape(4, 4, 4)             # [j, i, c]
                local[ci, cj] = len(bez)
                group[ci, cj] = -1
                bez.append(np.einsum("aj,bi,jic->abc", M, M, G))
                continue
            _, scheme, cfg, k = leaf
            lst = eig.setdefault(id(scheme), (scheme, [], [], []))
            local[ci, cj] = len(lst[1])
            group[ci, cj] = -4 - list(eig).index(id(scheme))
            lst[1].append(He[cfg])
            lst[2].append(rotation_index((re - k) % 4))
            lst[3].append((int(emesh.faces[e][k]), e))
        groups, gid = [], {}
        if bez:
            gid[-1] = len(groups)
            groups.append(BezierCells(np.array(bez)))
        if deep:
            gid[-3] = len(groups)
            groups.append(AdaptiveCells(resolve(emesh, He, deep)))
        for n, (scheme, data, maps, where) in enumerate(eig.values()):
            gid[-4 - n] = len(groups)
            try:
                groups.append(LevelCells(scheme, np.array(data), np.array(maps)))
            except InputError:
                _name_irregular_vertex(emesh, scheme, data, where)
                raise
        group = np.vectorize(gid.get)(group)
        patches.append(Patch(r, np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), group, local,
                             groups, knot_size=(nc, nr)))
    return patches


def _name_irregular_vertex(mesh: QuadMesh, scheme, data, where) -> None:
    """Raise the error of the first configuration whose limit normal fails, naming its
    vertex, the file and a line of one of its faces (the shared scheme knows none of them).
    Irregular vertices keep their cage index through refinement."""
    for C0, (v, e) in zip(data, where):
        try:
            scheme.limit_normal(C0)
        except InputError as exc:
            raise InputError(f"{mesh.vertex_name(v)}: {exc.message}", path=mesh.source,
                             line=mesh.face_line(e)) from None


def _finish(mesh: QuadMesh, dec: QuadDecomposition, patches: list[Patch], cage: Cage,
            name: str | None) -> Model:
    link_patches(patches, dec.links)
    node_vertex = sorted({int(v) for reg in dec.regions for v in reg.corners})
    node_of = {v: n for n, v in enumerate(node_vertex)}
    node_points = np.zeros((len(node_vertex), 3))
    for patch, reg in zip(patches, dec.regions):
        patch.corner_nodes = np.array([node_of[int(v)] for v in reg.corners])
        P = patch.evaluate(CORNER_UV[:, 0], CORNER_UV[:, 1]).P
        node_points[patch.corner_nodes] = P
    eps = []
    for v in range(mesh.n_vertices):
        fan, boundary = mesh.fan(v)
        if fan and mesh.is_layout_vertex(v) and (not boundary or not mesh.is_regular_vertex(v)):
            if v in node_of:
                eps.append(ExtraordinaryPoint(node_of[v], len(fan), node_points[node_of[v]], boundary))
    fmap_patch = dec.face_region.copy()
    fmap_cell = np.zeros((len(mesh.faces), 2), dtype=int)
    fmap_map = np.zeros(len(mesh.faces), dtype=int)
    fmap_size = np.zeros((len(mesh.faces), 2), dtype=int)
    for reg in dec.regions:
        for f, c, rot in zip(reg.faces, reg.cell, reg.rot):
            fmap_cell[f] = c
            fmap_map[f] = rotation_index((-int(rot)) % 4)     # face corner c -> cell corner c - rot
            fmap_size[f] = reg.size
    model = Model(patches, node_points, eps, "catmull-clark", mesh.source,
                  FaceMap(fmap_patch, fmap_cell, fmap_map, fmap_size), control=cage, name=name)
    model.node_vertex = np.array(node_vertex)
    return model
