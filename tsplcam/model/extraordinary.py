"""Extraordinary points of a T-mesh and the exact evaluation of the faces around them.

An extraordinary point is an interior vertex whose faces do not make a full turn. Around it
the T-NURCC rule applies, which with uniform knot intervals is Catmull-Clark: its faces are
evaluated exactly by the cage machinery (``eigen.scheme_for``, Stam 1998). That is exact only
when every blending function reaching those faces is uniform (all its knot intervals equal
to the point's), which is checked here; anything else (non-uniform intervals or T-junctions
near the point, a face with two extraordinary corners, extraordinary points on the
boundary) is refused with an error that names the vertex or face.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .eigen import NotSelfSimilar, scheme_for
from .quadmesh import QuadMesh
from .tmesh import TMesh

if TYPE_CHECKING:
    from .knots import LocalKnots


@dataclass
class Extraordinary:
    """The extraordinary points of a T-mesh: ``interval[v]`` is the uniform knot interval
    around vertex v, ``face_vertex[f]`` the extraordinary corner of face f."""
    interval: dict = field(default_factory=dict)
    face_vertex: dict = field(default_factory=dict)


def find_extraordinary(mesh: TMesh) -> Extraordinary:
    """The extraordinary points of ``mesh``, refusing those the kernel cannot evaluate."""
    topo = mesh.topology
    out = Extraordinary()
    for v in range(mesh.n_vertices):
        if not topo.is_extraordinary(v):
            continue
        if topo.boundary[v]:
            raise mesh.error(f"{mesh.vertex_name(v)} is an extraordinary point on the boundary "
                             f"({topo.total[v]} quarter turns of faces): not supported in T-spline "
                             f"models (save it as a Catmull-Clark cage, or split the faces)")
        if any(topo.span(f, i) != 1 for f, i in topo.fan[v]):
            raise mesh.error(f"{mesh.vertex_name(v)} is a T-junction whose faces do not make a full "
                             f"turn: extraordinary points must be corners of all their faces")
        if topo.total[v] < 3:
            raise mesh.error(f"{mesh.vertex_name(v)} is an interior vertex with only "
                             f"{topo.total[v]} faces")
        d = [mesh.intervals[f][i] for f, i in topo.fan[v]]
        if max(d) - min(d) > topo.tol or min(d) <= 0:
            raise mesh.error(f"knot intervals at extraordinary {mesh.vertex_name(v)} are not uniform "
                             f"({', '.join(f'{x:g}' for x in d)}): T-NURCC refinement of non-uniform "
                             f"intervals is not supported; make the intervals of its two rings of "
                             f"faces equal")
        out.interval[v] = float(np.mean(d))
        for f, _ in topo.fan[v]:
            if not mesh.is_quad(f):
                raise mesh.error(f"{mesh.face_name(f)} touches extraordinary {mesh.vertex_name(v)} "
                                 f"and has T-junctions: not supported next to extraordinary points")
            if f in out.face_vertex:
                raise mesh.error(f"{mesh.face_name(f)} has two extraordinary corners "
                                 f"({mesh.vertex_name(out.face_vertex[f])} and {mesh.vertex_name(v)}): "
                                 f"refine the T-mesh so that they are further apart")
            out.face_vertex[f] = v
    return out


class _ZoneMesh(QuadMesh):
    """The quad faces around one extraordinary point as a cage for ``eigen.scheme_for``;
    boundary and vertex names are those of the whole T-mesh."""

    def setup(self, tmesh: TMesh, glob: list[int]):
        self._tmesh = tmesh
        self._glob = glob
        return self

    def is_boundary_edge(self, a: int, b: int) -> bool:
        return self._tmesh.topology.is_boundary_edge(self._glob[a], self._glob[b])

    def vertex_name(self, v: int) -> str:
        return self._tmesh.vertex_name(self._glob[v])


def extraordinary_cells(mesh: TMesh, ep: Extraordinary, knots: LocalKnots, supports: list,
                        Pw: np.ndarray) -> dict:
    """Catmull-Clark schemes for the faces around extraordinary points: face -> (scheme,
    homogeneous control points of its configuration, its extraordinary corner), with the
    check that every blending function reaching them (``supports``, ``blending.supports``)
    is uniform."""
    topo = mesh.topology
    out = {}
    for v, d in ep.interval.items():
        ring1 = [f for f, _ in topo.fan[v]]
        verts1 = {int(x) for f in ring1 for x in mesh.faces[f]}
        ring2 = sorted({g for w in verts1 for g, _ in topo.fan[w]})
        for g in ring2:
            if not mesh.is_quad(g):
                raise mesh.error(f"{mesh.face_name(g)} has T-junctions within two rings of faces of "
                                 f"extraordinary {mesh.vertex_name(v)}: not supported (T-NURCC "
                                 f"refinement); move the T-junctions further away")
        glob = sorted({int(x) for g in ring2 for x in mesh.faces[g]})
        loc = {x: k for k, x in enumerate(glob)}
        qm = _ZoneMesh(np.array([[loc[int(x)] for x in mesh.faces[g]] for g in ring2]), len(glob),
                       "edge-only", mesh.source).setup(mesh, glob)
        for f in ring1:
            k = [int(x) for x in mesh.faces[f]].index(v)
            try:
                scheme, cfg = scheme_for(qm, ring2.index(f), k)
            except NotSelfSimilar as exc:
                raise mesh.error(f"around extraordinary {mesh.vertex_name(v)}: {exc.message}")
            cfg_glob = [glob[c] for c in cfg]
            got = {A for A, _ in supports[f]}
            if got != set(cfg_glob):
                raise mesh.error(f"the blending functions on {mesh.face_name(f)} next to extraordinary "
                                 f"{mesh.vertex_name(v)} are not those of its Catmull-Clark "
                                 f"neighbourhood: the knot intervals around it are not uniform")
            want = np.array([-2 * d, -d, 0.0, d, 2 * d])
            for A, _ in supports[f]:
                if (np.abs(knots.s[A].real - want).max() > topo.tol
                        or np.abs(knots.t[A].real - want).max() > topo.tol):
                    raise mesh.error(
                        f"knot intervals near extraordinary {mesh.vertex_name(v)} are not uniform: "
                        f"{mesh.vertex_name(A)} has knots s {np.round(knots.s[A].real, 9).tolist()}, "
                        f"t {np.round(knots.t[A].real, 9).tolist()} (T-NURCC refinement of non-uniform "
                        f"intervals is not supported)")
            out[f] = (scheme, Pw[cfg_glob], k)
    return out
