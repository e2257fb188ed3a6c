"""The array forms of QuadMesh's refinement, regularity tests and regular stencils give the
same numbers to the bit as the face-by-face code they replace (tsplcam relies on that for
byte-identical outputs), on a creased OpenSubdiv shape refined twice."""
import numpy as np
from conftest import external

from tsplcam.model.formats.obj import read_obj


def _face_by_face(mesh, *args):
    """``refine`` through the face-by-face code (the arrays hidden for one call)."""
    saved, mesh._arr = mesh._arr, {}
    try:
        return mesh.refine(*args)
    finally:
        mesh._arr = saved


def test_array_forms_match_face_by_face_code():
    cage = read_obj(external("opensubdiv", "catmark_single_crease.obj"))
    mesh, H = cage.mesh, cage.homogeneous()
    rng = np.random.default_rng(3)
    for _ in range(2):
        assert mesh.arrays() is not None
        child, R, tainted = mesh._refine_arrays(None, None)
        child_ref, R_ref, tainted_ref = _face_by_face(mesh)
        # same structure, same values bit for bit, in the same order
        assert np.array_equal(child.faces, child_ref.faces)
        assert child.sharpness == child_ref.sharpness
        assert np.array_equal(R.indptr, R_ref.indptr) and np.array_equal(R.indices, R_ref.indices)
        assert R.data.tobytes() == R_ref.data.tobytes()
        assert np.array_equal(tainted, tainted_ref)
        mesh, H = child, R @ H
    regular, semi = mesh.regularity_arrays()
    fans = [mesh.fan(v) for v in range(mesh.n_vertices)]
    assert regular.tolist() == [mesh.is_regular_in(int(mesh.faces[c // 4][c % 4]), c // 4)
                                for c in range(4 * len(mesh.faces))]
    assert semi.tolist() == [mesh.has_semi_sharp_at(v) for v in range(mesh.n_vertices)]
    mesh._fans = None
    mesh._build_fans_walked()
    assert fans == mesh._fans
    faces = np.nonzero(regular.reshape(-1, 4).all(axis=1))[0][::7]
    rots = rng.integers(0, 4, len(faces))
    cols, wts, ok = mesh.regular_stencils(faces, rots)
    G = mesh.stencil_points(cols, wts, H)
    assert ok.all() and len(faces) > 50
    for n, (f, k) in enumerate(zip(faces.tolist(), rots.tolist())):
        assert (mesh.regular_stencil(f, k) @ H).tobytes() == G[n].tobytes()
