"""Evaluation next to extraordinary points, down to 2^-30 of a face from them, against an
independent reference: the neighbourhood of the point refined level by level with
Catmull-Clark's rules (``test_creases.RefMesh``, this test suite's own refinement), the
exact limits of the refined vertices there (closed-form masks) and the first and second
derivatives of the bicubic B-spline at regular refined vertices (3 x 3 masks)."""
import unittest

import numpy as np

from tsplcam.model.cage import cage_model
from tsplcam.model.formats.obj import read_obj
from conftest import RefMesh, external, ngon_prism

POS_TOL, DER_TOL = 1e-10, 1e-8           # of the model size, of the derivative's size


def limit_of(cage, v):
    """Closed-form Catmull-Clark limit of interior vertex v (Halstead et al. 1993)."""
    mesh, P = cage.mesh, cage.points
    fan, _ = mesh.fan(v)
    n = len(fan)
    e = sum(P[mesh.faces[f][(k + 1) % 4]] for f, k in fan)
    d = sum(P[mesh.faces[f][(k + 2) % 4]] for f, k in fan)
    return (n * n * P[v] + 4 * e + d) / (n * (n + 5))


def deep_errors(cage, ep: int, levels: int):
    """Largest errors on the faces around vertex ``ep`` at levels 1..levels: positions
    relative to the model size, first and second derivatives relative to their own size
    (the largest of the two first, of the three second derivatives at the point)
    (they vanish at valence 3 and grow without bound at valence 5 and more as the point
    nears), and the number of points compared.

    The reference refines the points' differences from the vertex's limit point (the rules
    are affine), so that a level-30 configuration keeps its digits."""
    model = cage_model(cage)
    scale = np.abs(model.node_points).max()
    mesh = cage.mesh
    c = limit_of(cage, ep)
    H = np.column_stack([cage.points - c, np.ones(len(cage.points))])
    ref = RefMesh(mesh.faces, H, {}, {}, mesh.boundary_rule).start()
    ref = ref.subset(ref.rings(ep, 4))
    v = int(np.nonzero(ref.ids == ep)[0][0])
    ring1 = {f for f, _ in mesh.fan(ep)[0]}
    worst = np.zeros(3)
    count = 0

    def rel(got, want):
        size = np.max([np.linalg.norm(w, axis=1) for w in want], axis=0) + 1e-300
        return max((np.linalg.norm(g - w, axis=1) / size).max() for g, w in zip(got, want))

    for level in range(1, levels + 1):
        ref = ref.refine()                         # the point keeps its index
        ref = ref.subset(ref.rings(v, 4))
        v = int(np.nonzero(ref.ids == v)[0][0])
        near = ref.rings(v, 2)
        L = ref.exact_limits()
        v0 = ref.F[:, 0]
        rows = np.nonzero(near & ~np.isnan(L[v0, 0]) & np.isin(ref.root, list(ring1)))[0]
        sp = model.evaluate_faces(ref.root[rows], ref.O[rows, 0], ref.O[rows, 1])
        worst[0] = max(worst[0], np.abs(sp.P - c - L[v0[rows]]).max() / scale)
        f, P, Ps, Pt, Pss, Pst, Ptt = ref.regular_jets(count=10 ** 6)
        inside = near[f] & np.isin(ref.root[f], list(ring1))
        f, P, Ps, Pt, Pss, Pst, Ptt = (x[inside] for x in (f, P, Ps, Pt, Pss, Pst, Ptt))
        count += len(rows) + len(f)
        if not len(f):
            continue
        sp = model.evaluate_faces(ref.root[f], ref.O[f, 0], ref.O[f, 1])
        A = np.linalg.inv(np.stack([ref.X[f], ref.Y[f]], axis=2))
        g1 = np.einsum("nia,inc->anc", A, np.array([Ps, Pt]))
        g2 = np.einsum("nia,ijnc,njb->abnc", A, np.array([[Pss, Pst], [Pst, Ptt]]), A)
        worst[1] = max(worst[1], rel((sp.Pu, sp.Pv), (g1[0], g1[1])))
        worst[2] = max(worst[2], rel((sp.Puu, sp.Puv, sp.Pvv), (g2[0, 0], g2[0, 1], g2[1, 1])))
    return worst, count


class NearExtraordinaryPoints(unittest.TestCase):
    def test_valences_3_to_8_down_to_2_pow_minus_30(self):
        for n in (3, 5, 6, 8):
            cage = ngon_prism(n, seed=n)
            worst, count = deep_errors(cage, 0, 30)
            self.assertGreater(count, 30 * 4 * n)
            self.assertLess(worst[0], POS_TOL, f"valence {n}: positions {worst}")
            self.assertLess(worst[1], DER_TOL, f"valence {n}: first derivatives {worst}")
            self.assertLess(worst[2], DER_TOL, f"valence {n}: second derivatives {worst}")

    def test_cube_corner(self):
        cage = read_obj(external("opensubdiv", "catmark_cube.obj"))
        worst, _ = deep_errors(cage, 0, 30)
        self.assertLess(worst[0], POS_TOL)
        self.assertLess(max(worst[1:]), DER_TOL)


if __name__ == "__main__":
    unittest.main()
