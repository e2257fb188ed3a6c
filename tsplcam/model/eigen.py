"""Subdivision matrices of irregular configurations, for exact evaluation next to irregular
vertices.

Stam (1998, "Exact evaluation of Catmull-Clark subdivision surfaces at arbitrary parameter
values") writes the surface over a face F with one extraordinary corner as
    P(s, t) = b(s', t')^T  S_k  A^(n-1)  C0,
where C0 are the K control points around F, A the K x K subdivision matrix (one
refinement maps the configuration to the same configuration one level down), n the level
at which (s, t) falls into one of the three regular sub-patches k of the ring
[0, 2^(1-n)]^2 minus [0, 2^-n]^2, S_k picks that sub-patch's 16 B-spline control points,
and b the bicubic B-spline basis. Stam evaluates A^(n-1) through A's eigenvectors; tsplcam
subdivides instead (``cells.LevelCells``: the configuration of every level, kept as its
difference from the limit point), which needs no eigenvectors and keeps full precision
where they are ill-conditioned or do not exist (Jordan blocks at some boundary vertices).
The eigenvalues still give the limit point (the left eigenvector of 1), the tangent plane
(left eigenvectors of the subdominant eigenvalues) and the checks against published spectra.

Unlike Stam's paper, A and S_k are not written out by hand for interior vertices only:
they are computed for the configuration at hand by refining its own neighbourhood with the
mesh's subdivision rules (``QuadMesh.refine``: boundaries and creases as OpenSubdiv) and
read off the sparse refinement matrix, so the same code covers any valence, boundary
vertices and crease configurations. No tables are shipped.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .quadmesh import INFINITE, QuadMesh, unit_weights

# sub-patches of Stam's ring, in the order cells.LevelCells uses:
# k = 0: s' >= 1/2, t' < 1/2; k = 1: both >= 1/2; k = 2: s' < 1/2, t' >= 1/2.
# (child corner offset d from the irregular corner, stencil frame corner k0 of that child)
_SUBPATCH_CHILDREN = ((1, 3), (2, 2), (3, 1))


class NotSelfSimilar(InputError):
    """The face's neighbourhood only becomes self-similar after more refinement."""


class SubdivisionScheme:
    """The subdivision matrix of one local configuration (one irregular vertex type), its
    sub-patch pickers, limit-point and tangent masks and spectrum."""

    def __init__(self, template: QuadMesh, face: int, corner: int, cut_edges: set, label: str):
        self.label = label
        config = template.config(face, corner)
        K = len(config)
        if sorted(config) != list(range(template.n_vertices)):
            raise AssertionError("configuration and template vertices differ")
        self.K = K
        child, R, tainted = template.refine(cut_edges)
        child_cut = set()
        eid = {e: i for i, e in enumerate(template.undirected_edges())}
        nv = template.n_vertices
        for (a, b) in cut_edges:
            e = nv + eid[(a, b)]
            child_cut.add((min(a, e), max(a, e)))
            child_cut.add((min(b, e), max(b, e)))
        cfg1 = child.config(4 * face + corner, 0)
        if (len(cfg1) != K or tainted[cfg1].any()
                or not _same_features(template, config, cut_edges, child, cfg1, child_cut)):
            raise NotSelfSimilar(f"{label}: the neighbourhood of this irregular vertex does not "
                             f"subdivide into the same configuration")
        Rd = R.toarray()
        perm = np.asarray(config)
        A = Rd[np.asarray(cfg1)][:, perm]
        S = []
        for d, k0 in _SUBPATCH_CHILDREN:
            cf = 4 * face + (corner + d) % 4
            St = child.regular_stencil(cf, k0, cut_edges=child_cut).toarray()
            used = np.nonzero(np.abs(St).sum(axis=0) > 0)[0]
            if tainted[used].any():
                raise InputError(f"{label}: a regular sub-patch needs points outside the "
                                 f"configuration")
            S.append((St @ Rd)[:, perm])
        self.A = A
        self.S = np.stack(S)                                 # (3, 16, K)
        self.config_order = perm
        # left eigenvector of eigenvalue 1: the limit-point mask (A 1 = 1, affine invariance)
        _, sv, vt = np.linalg.svd((A - np.eye(K)).T)
        if sv[-1] > 1e-9 or (K > 1 and sv[-2] < 1e-9):
            raise InputError(f"{label}: eigenvalue 1 is not simple (no unique limit point)")
        l0 = vt[-1]
        self.limit_mask = l0 / l0.sum()
        self.tangent_masks = _tangent_masks(A, label)
        lam = np.linalg.eigvals(A)
        if np.abs(lam.imag).max() <= 1e-9:
            lam = lam.real
        self.lam = lam[np.argsort(-np.abs(lam), kind="stable")]

    def levels(self, C0: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
        """Limit point L (4,) and d_m = A^m (C0 - L) for m < count, (count, K, 4).

        Iterating on the difference keeps full relative precision at every level: no O(1)
        quantities ever cancel, unlike powers of A applied to C0. Where every weight of C0 is
        exactly 1 (a polynomial cage), L's weight is 1 and the differences' weights 0, exactly:
        the limit mask sums to 1 and A keeps constants (affine invariance). Computed, they
        are 1 and 0 only up to the rounding of the BLAS's sums, which depends on the kernel
        it picks for the processor (OpenBLAS's Haswell kernels left 2^-53 on the keycap's
        limit weight, grown to 0.022 by the deep levels' scaling, SkylakeX's none), and
        that decides whether the patch is evaluated as polynomial (``Patch._polynomial``)."""
        L = self.limit_mask @ C0
        if unit_weights(C0):
            L[3] = 1.0
        d = np.empty((count, self.K, C0.shape[1]))
        d[0] = C0 - L[None, :]
        for m in range(1, count):
            d[m] = self.A @ d[m - 1]
        return L, d

    @property
    def subdominant(self) -> float:
        """Largest |eigenvalue| below the dominant 1."""
        lam = np.sort(np.abs(self.lam))[::-1]
        return float(lam[1])

    def limit_normal(self, C0: np.ndarray) -> np.ndarray:
        """Unit normal of the tangent plane at the irregular vertex (orientation unfixed),
        from the tangent masks (left eigenvectors of the largest eigenvalues below 1)
        applied to the configuration's homogeneous control points C0 (K, 4)."""
        L = self.limit_mask @ C0
        X = L[:3] / L[3]
        t1, t2 = ((m @ C0)[:3] - X * (m @ C0)[3] for m in self.tangent_masks)
        n = np.cross(t1, t2)
        length = np.linalg.norm(n)
        if not length > 1e-12 * (np.linalg.norm(t1) * np.linalg.norm(t2) + 1e-300):
            # the scheme is shared by every vertex of its kind, in any file: name the kind only
            # (the caller knows which vertex and file)
            raise InputError(f"{self.label.split(' (')[0]}: degenerate tangent plane at the "
                             f"irregular vertex")
        return n / length


def _same_features(parent: QuadMesh, cfg0: list, cut0: set, child: QuadMesh, cfg1: list, cut1: set) -> bool:
    """Whether the infinitely sharp edges and corners sit at the same places of the two
    configurations (creases and corners that do not pass through the irregular vertex move
    outward under refinement: such a neighbourhood is not yet self-similar). Edges where the
    configuration was cut out of its mesh are not features."""
    if not parent.creased and not child.creased:
        return True

    def sharp_edge(mesh, cut, a, b):
        if mesh.is_boundary_edge(a, b):
            return (min(a, b), max(a, b)) not in cut
        return (mesh.sharpness or {}).get((min(a, b), max(a, b)), 0.0) >= INFINITE

    def sharp_vertex(mesh, cut, v):
        if (mesh.corner_sharpness or {}).get(v, 0.0) >= INFINITE:
            return True
        fan, boundary = mesh.fan(v)
        if not (boundary and len(fan) == 1 and mesh.boundary_rule == "edge-and-corner"):
            return False
        nb = mesh.neighbours(v)
        return not any((min(v, w), max(v, w)) in cut for w in (nb[0], nb[-1]))

    for f in range(len(parent.faces)):
        quad = parent.faces[f]
        for k in range(4):
            a, b = int(quad[k]), int(quad[(k + 1) % 4])
            i, j = cfg0.index(a), cfg0.index(b)
            if sharp_edge(parent, cut0, a, b) != sharp_edge(child, cut1, cfg1[i], cfg1[j]):
                return False
    return all(sharp_vertex(parent, cut0, a) == sharp_vertex(child, cut1, b) for a, b in zip(cfg0, cfg1))


def _tangent_masks(A: np.ndarray, label: str) -> tuple[np.ndarray, np.ndarray]:
    """Two left eigenvectors of the largest eigenvalues below 1: masks whose application to
    the control points gives two tangent vectors at the limit point (Halstead et al. 1993
    write them in closed form for interior Catmull-Clark vertices). Found as null spaces of
    A^T - lambda I by SVD, which works even where A as a whole is defective.

    Eigenvalues within 1e-6 are one, taken at their mean: a defective one (a Jordan block of
    two) comes out of ``eigvals`` as a pair split by about the square root of the rounding,
    along the real axis or across it (the boundary vertex of four faces: 0.5 +- 1e-8 with
    OpenBLAS's Haswell kernels, 0.5 +- 4e-9 i with its Prescott kernels), whose mean is exact
    to the rounding while each of the pair is not. When only eigenvalues with an imaginary
    part below 1e-9 were kept and clustered within 1e-8, the pair was split or not by the
    kernel's rounding (the normal there moved by up to 1.1e-9 between kernels) or dropped as
    complex, and the second mask came from the next eigenvalue, 0.366: a normal 90 deg off."""
    K = len(A)
    lam = np.linalg.eigvals(A)
    lam = np.sort(lam.real[np.abs(lam.imag) < 1e-6])[::-1]
    clusters: list[list[float]] = []            # equal eigenvalues, kept unrounded
    for x in lam:
        if clusters and abs(clusters[-1][-1] - x) < 1e-6:
            clusters[-1].append(x)
        else:
            clusters.append([x])
    masks = []
    for value in (float(np.mean(c)) for c in clusters):
        if abs(value - 1.0) < 1e-9 or value < 1e-12:
            continue
        _, sv, vt = np.linalg.svd((A - value * np.eye(K)).T)
        null = vt[sv < 1e-8 * max(1.0, sv[0])]
        for row in null:
            masks.append(row)
            if len(masks) == 2:
                return masks[0], masks[1]
    raise InputError(f"{label}: no tangent plane at the irregular vertex")


_SCHEMES: dict = {}


def _canonical_faces(tfaces: np.ndarray) -> tuple:
    """The quads (local vertex indices) as a key independent of their order and first
    corners: each rotated to start at its smallest index (orientation kept), then sorted."""
    out = []
    for quad in tfaces.tolist():
        k = quad.index(min(quad))
        out.append(tuple(quad[k:] + quad[:k]))
    return tuple(sorted(out))


def scheme_for(mesh: QuadMesh, face: int, corner: int) -> tuple[SubdivisionScheme, list[int]]:
    """The scheme of face ``face`` with its irregular vertex at ``corner``, and the face's
    configuration vertices (mesh indices) in the scheme's order. Schemes are cached by the
    configuration's topology, so all faces at vertices of one kind share one decomposition."""
    config = mesh.config(face, corner)
    local = {v: i for i, v in enumerate(config)}
    faces = mesh.neighbourhood_faces(face)
    tfaces = np.array([[local[int(v)] for v in mesh.faces[g]] for g in faces])
    real_boundary, cut = [], set()
    directed = {(int(mesh.faces[h][m]), int(mesh.faces[h][(m + 1) % 4])) for h in faces for m in range(4)}
    for g in faces:
        quad = mesh.faces[g]
        for k in range(4):
            a, b = int(quad[k]), int(quad[(k + 1) % 4])
            if (b, a) in directed:           # the edge's other side is in the neighbourhood
                continue
            la, lb = local[a], local[b]
            key = (min(la, lb), max(la, lb))
            if mesh.is_boundary_edge(a, b):
                real_boundary.append(key)
            else:
                cut.add(key)
    sharp, corners = {}, {}
    if mesh.sharpness:
        for g in faces:
            quad = mesh.faces[g]
            for k in range(4):
                a, b = int(quad[k]), int(quad[(k + 1) % 4])
                s = mesh.sharpness.get((min(a, b), max(a, b)), 0.0)
                if s > 0.0:
                    la, lb = local[a], local[b]
                    sharp[(min(la, lb), max(la, lb))] = s
    if mesh.corner_sharpness:
        corners = {local[v]: s for v, s in mesh.corner_sharpness.items() if v in local}
    # the configuration's order is canonical (QuadMesh.config: the face's own corners first,
    # from the irregular one, then each corner's fan in turn), so a neighbourhood of the same
    # kind has the same faces in local indices whatever its faces' order and first corners in
    # the mesh: each face from its smallest index, the faces sorted. The scheme is built from
    # those canonical faces (the face itself first, (0, 1, 2, 3)), so every neighbourhood of a
    # kind gives the same bits whichever the process met first (the keycap's twelve faces at
    # its four valence-3 vertices had twelve schemes in mesh order, 3 ms each; one this way)
    canon = _canonical_faces(tfaces)
    signature = (mesh.boundary_rule, canon, tuple(sorted(real_boundary)),
                 tuple(sorted(sharp.items())), tuple(sorted(corners.items())))
    sch = _SCHEMES.get(signature)
    if sch is None:
        if canon[0] != (0, 1, 2, 3):                 # (config puts the face's corners first)
            raise AssertionError("the face is not the configuration's first")
        v = int(mesh.faces[face][corner])
        fan, boundary = mesh.fan(v)
        label = (f"{'boundary' if boundary else 'interior'} vertex of {len(fan)} faces "
                 f"({mesh.vertex_name(v)}{', ' + mesh.source if mesh.source else ''})")
        template = QuadMesh(np.array(canon), len(config), mesh.boundary_rule, mesh.source,
                            sharpness=sharp or None, corner_sharpness=corners or None)
        sch = SubdivisionScheme(template, 0, 0, cut, label)
        _SCHEMES[signature] = sch
    return sch, config
