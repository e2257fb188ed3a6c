"""The surface model every later stage works on: patches, nodes, extraordinary points.

A model is a set of four-sided patches, each with (u, v) on the unit square. Patch corners
are *nodes*; a node shared by several patches is one point of the surface. For subdivision
cages the model also keeps where each cage face lies in its patch, so that
``evaluate_faces`` answers in OpenSubdiv's per-face coordinates.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .cells import SQUARE_MAPS, _chain
from .diffgeom import SurfacePoints
from .patch import CORNER_UV, EDGE_CORNERS, EdgeNeighbour, Patch


@dataclass
class FaceMap:
    """Where cage faces sit in their patches: (u, v) = ((i, j) + A (s, t) + o) / (nu, nv)."""
    patch: np.ndarray     # (F,) patch of each face
    cell: np.ndarray      # (F, 2) cell column and row of the face in its patch
    map_index: np.ndarray  # (F,) index into SQUARE_MAPS: face (s, t) -> cell (a, b)
    cells: np.ndarray     # (F, 2) patch size in faces (nu, nv)


@dataclass
class ExtraordinaryPoint:
    node: int
    valence: int
    position: np.ndarray
    boundary: bool = False


class Model:
    """Patches of one surface; ``units`` is always mm inside tsplcam.

    The last six attributes belong to some kinds of model only (None on the others); the
    reader or builder of that kind sets them.
    """

    patches: list[Patch]
    #: (n, 3) position of every node (a patch corner shared by the patches meeting there)
    node_points: np.ndarray
    #: extraordinary points among the nodes (valence other than 4 inside, above 2 on the boundary)
    extraordinary: list[ExtraordinaryPoint]
    #: how the surface is defined: "catmull-clark", "t-spline", "bezier", "bspline", ...
    kind: str
    #: the file the model was read from, for messages
    source: str | None
    #: cages: where each cage face lies in its patch (``evaluate_faces``)
    face_map: FaceMap | None
    #: the control mesh (cage or T-mesh) when there is one
    control: object
    name: str
    units: str
    #: cages and Bezier meshes: the control-mesh vertex (cage vertex, merged element corner) of
    #: every node
    node_vertex: np.ndarray | None
    #: Bezier meshes (``bezier_mesh``): per element or piece of one, where it sits in which
    #: patch (``ElementPlace``)
    elements: list | None
    #: Bezier meshes: what the recovery of the mesh found (``bezier_mesh.MeshInfo``)
    mesh_info: object | None
    #: ``.iga`` files: the file's content (``formats.iga.IgaFile``)
    iga: object | None
    #: CAD imports (the workbench's STEP/IGES reader): the face each patch was made from
    faces: list | None
    #: ``.tsm`` files: what the file said and how it was read (``formats.tsm.TsmInfo``: dialect,
    #: scale applied to its coordinates, surface construction, footer)
    tsm: object | None

    def __init__(self, patches: list[Patch], node_points: np.ndarray,
                 extraordinary: list[ExtraordinaryPoint], kind: str, source: str | None = None,
                 face_map: FaceMap | None = None, control=None, name: str | None = None):
        self.patches = patches
        self.node_points = np.asarray(node_points, float).reshape(-1, 3)
        self.extraordinary = extraordinary
        self.kind = kind
        self.source = source
        self.face_map = face_map
        self.control = control
        self.name = name or (source.rsplit("/", 1)[-1] if source else kind)
        self.units = "mm"
        self.node_vertex = None
        self.elements = None
        self.mesh_info = None
        self.iga = None
        self.faces = None
        self.tsm = None

    def __repr__(self) -> str:
        return (f"<Model {self.name!r}: {len(self.patches)} patches, "
                f"{len(self.extraordinary)} extraordinary points, {self.kind}>")

    # -- evaluation -----------------------------------------------------------------------
    def evaluate(self, patch: int, u, v) -> SurfacePoints:
        return self.patches[patch].evaluate(u, v)

    def evaluate_faces(self, face, s, t) -> SurfacePoints:
        """Evaluate in cage faces' own coordinates (OpenSubdiv's convention for quads: (0,0) at
        the face's first vertex, s toward its second, t toward its last). Returns P, Ps, Pt,
        Pss, Pst, Ptt in the fields P, Pu, Pv, Puu, Puv, Pvv, one row per (face, s, t)."""
        if self.face_map is None:
            raise InputError("evaluate_faces needs a model made from a control cage", path=self.source)
        face, s, t = np.broadcast_arrays(np.asarray(face, int).reshape(-1),
                                         np.asarray(s, float).reshape(-1), np.asarray(t, float).reshape(-1))
        fm = self.face_map
        if np.any((face < 0) | (face >= len(fm.patch))):
            raise InputError(f"face index out of range 0..{len(fm.patch) - 1}", path=self.source)
        A = np.stack([SQUARE_MAPS[m][0] for m in range(8)])[fm.map_index[face]]
        o = np.stack([SQUARE_MAPS[m][1] for m in range(8)])[fm.map_index[face]]
        a = A[:, 0, 0] * s + A[:, 0, 1] * t + o[:, 0]
        b = A[:, 1, 0] * s + A[:, 1, 1] * t + o[:, 1]
        size = fm.cells[face].astype(float)
        u = (fm.cell[face, 0] + a) / size[:, 0]
        v = (fm.cell[face, 1] + b) / size[:, 1]
        n = len(face)
        H = np.empty((6, 3, n))
        normal = np.empty((n, 3))
        for p in np.unique(fm.patch[face]):
            sel = np.nonzero(fm.patch[face] == p)[0]
            sp_ = self.patches[p].evaluate(u[sel], v[sel])
            for k, arr in enumerate((sp_.P, sp_.Pu, sp_.Pv, sp_.Puu, sp_.Puv, sp_.Pvv)):
                H[k][:, sel] = arr.T
            normal[sel] = sp_.normal
        # (u, v) = (cell + A (s, t) + o) / size: d(u,v)/d(s,t) = diag(1/size) A
        J = A / size[:, :, None]
        H = _chain(H, J).transpose(0, 2, 1)
        # the face frame may be mirrored against the patch frame: keep S_s x S_t orientation
        flip = np.linalg.det(A) < 0
        normal[flip] *= -1.0
        return SurfacePoints(H[0], H[1], H[2], H[3], H[4], H[5], s, t, None, normal)

    # -- topology -------------------------------------------------------------------------
    def edge_transform(self, patch: int, edge: int) -> np.ndarray:
        """Affine map (2 x 3) from this patch's (u, v) to the neighbour's across ``edge``,
        continuing the parametrisation in knot units (shang2020 section 2.2: adjacent
        patches' parameters differ by a translation and a rotation)."""
        a = self.patches[patch]
        nb = a.neighbours[edge]
        if nb is None:
            raise InputError(f"{a.name} has no neighbour across edge {edge}")
        b = self.patches[nb.patch]
        # knot-unit coordinates (alpha along the shared edge from a's first corner, beta across
        # it, positive into a and negative into b); y is the inward normal of a counter-clockwise
        # edge, taken before b's edge is turned to start where a's starts.
        def frame(p: Patch, e: int, swap: bool):
            c0, c1 = EDGE_CORNERS[e]
            d = CORNER_UV[c1] - CORNER_UV[c0]
            y = np.array([-d[1], d[0]])
            if swap:
                c0, c1 = c1, c0
            ks = np.array(p.knot_size)
            return CORNER_UV[c0], (CORNER_UV[c1] - CORNER_UV[c0]) / ks, y / ks

        oa, xa, ya = frame(a, edge, False)
        ob, xb, yb = frame(b, nb.edge, nb.reversed)
        L = np.column_stack([xb, -yb]) @ np.linalg.inv(np.column_stack([xa, ya]))
        t = ob - L @ oa
        return np.column_stack([L, t])

    def corner_neighbours(self, patch: int, corner: int) -> list[tuple[int, int]]:
        """(patch, corner) of every other patch corner at the same node."""
        node = self.patches[patch].corner_nodes[corner]
        return [(p.index, k) for p in self.patches for k in range(4)
                if p.corner_nodes[k] == node and (p.index, k) != (patch, corner)]

    def bounding_box(self, n: int = 9) -> tuple[np.ndarray, np.ndarray]:
        g = np.linspace(0, 1, n)
        U, V = np.meshgrid(g, g)
        pts = np.concatenate([p.evaluate(U.ravel(), V.ravel()).P for p in self.patches])
        return pts.min(axis=0), pts.max(axis=0)


def link_patches(patches: list[Patch], edge_pairs) -> None:
    """Set ``neighbours`` from ((patch, edge), (patch, edge), reversed) triples."""
    for (pa, ea), (pb, eb), rev in edge_pairs:
        patches[pa].neighbours[ea] = EdgeNeighbour(pb, eb, rev)
        patches[pb].neighbours[eb] = EdgeNeighbour(pa, ea, rev)
