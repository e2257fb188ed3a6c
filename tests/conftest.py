"""What the test files share: data locations, FreeCAD detection, test geometry and checks.

pytest loads this file first; ``TestTsplcam`` (freecadcmd) and ``tests/gui/run_gui_tests.py``
put ``tests/`` on ``sys.path`` so that test files, loaded by path, can ``from conftest import ...``.

External test data lives beside the checkout in ``../shared/data/external``
(or ``$TSPLCAM_SHARED/data/external``); tests that need it skip when it is absent.
"""
from __future__ import annotations

import os
import unittest

# realpath: under FreeCAD the checkout is reached through the Mod/tsplcam link
REPO_DIR = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
ARTIFACT_DIR = os.environ.get("TSPLCAM_ARTIFACTS", os.path.join(REPO_DIR, "build", "artifacts"))


def shared_dir() -> str:
    return os.environ.get("TSPLCAM_SHARED", os.path.join(os.path.dirname(REPO_DIR), "shared"))


def external(*parts: str) -> str:
    """Path of a file in ../shared/data/external; skips the calling test when absent."""
    path = os.path.join(shared_dir(), "data", "external", *parts)
    if not os.path.exists(path):
        raise unittest.SkipTest(f"external test data absent: {path}")
    return path


def artifact_path(name: str) -> str:
    """Where a test writes a picture or report for people to look at."""
    os.makedirs(ARTIFACT_DIR, exist_ok=True)
    return os.path.join(ARTIFACT_DIR, name)


def freecad_importable() -> bool:
    """True inside FreeCAD (freecadcmd or the GUI), where Part and OCCT are there too."""
    try:
        import FreeCAD  # noqa: F401
        import Part  # noqa: F401
    except ImportError:
        return False
    return True


def require_freecad():
    """The FreeCAD module, or skip the calling test (plain pytest has no FreeCAD)."""
    if not freecad_importable():
        raise unittest.SkipTest("FreeCAD is not importable here (run under freecadcmd)")
    import FreeCAD
    return FreeCAD


def needs_freecad(cls):
    """Class decorator: a TestCase that needs FreeCAD (document objects, OCCT comparisons).

    ``freecadcmd -t TestTsplcam`` runs exactly the classes marked so; plain pytest skips
    them. Every other test runs under pytest only, so each test runs once."""
    cls.needs_freecad = True
    return unittest.skipUnless(freecad_importable(), "needs FreeCAD: freecadcmd -t TestTsplcam runs it")(cls)


# -- test geometry several test files share (they cannot import one another) -------------
def ngon_prism(n: int, seed: int = 0, noise: float = 0.05):
    """A closed quad cage (Cage): two caps of n quads around a centre of valence n, joined by
    2n side quads (rim vertices alternate valence 4 and 3); perturbed by ``noise``."""
    import numpy as np
    from tsplcam.model.cage import Cage
    from tsplcam.model.quadmesh import QuadMesh
    rng = np.random.default_rng(seed)
    pts = [[0, 0, 1.2], [0, 0, -1.2]]
    for z in (1.0, -1.0):
        for j in range(2 * n):
            a = np.pi * j / n
            r = 1.0 if j % 2 == 0 else 1.25
            pts.append([r * np.cos(a), r * np.sin(a), z])

    def top(j):
        return 2 + (j % (2 * n))

    def bot(j):
        return 2 + 2 * n + (j % (2 * n))

    faces = []
    for j in range(n):
        faces.append([0, top(2 * j), top(2 * j + 1), top(2 * j + 2)])
        faces.append([1, bot(2 * j + 2), bot(2 * j + 1), bot(2 * j)])
    for j in range(2 * n):
        faces.append([top(j + 1), top(j), bot(j), bot(j + 1)])
    pts = np.array(pts, float) + noise * rng.standard_normal((len(pts), 3))
    return Cage(QuadMesh(np.array(faces), len(pts)), pts)


def arc_poles(a0: float, a1: float):
    """Rational quadratic arc of the unit circle from angle a0 to a1 (< 180 deg): poles, weights."""
    import numpy as np
    h = 0.5 * (a1 - a0)
    m = 0.5 * (a0 + a1)
    P = np.array([[np.cos(a0), np.sin(a0)], [np.cos(m) / np.cos(h), np.sin(m) / np.cos(h)],
                  [np.cos(a1), np.sin(a1)]])
    return P, np.array([1.0, np.cos(h), 1.0])


def cylinder_patch(R: float, H: float, beta: float = 0.6981317007977318, outward: bool = True):
    """Exact NURBS piece of a cylinder about z (a Patch): angle -beta..beta along u (default
    40 deg), z = 0..H along v; ``outward=False`` reverses u, so the normal points inward."""
    import numpy as np
    from tsplcam.model.bspline import bspline_patch
    az, wa = arc_poles(-beta, beta)
    poles = np.zeros((3, 2, 3))
    w = np.zeros((3, 2))
    for i in range(3):
        for j in range(2):
            poles[i, j] = [R * az[i, 0], R * az[i, 1], H * j]
            w[i, j] = wa[i]
    if not outward:
        poles, w = poles[::-1], w[::-1]
    return bspline_patch(poles, w, [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], 2, 1)


def plane_patch(W: float, H: float):
    """The rectangle [0, W] x [0, H] in z = 0 as a bilinear Patch."""
    import numpy as np
    from tsplcam.model.bspline import bspline_patch
    poles = np.array([[[0, 0, 0], [0, H, 0]], [[W, 0, 0], [W, H, 0]]], float)
    return bspline_patch(poles, None, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)


def one_patch_model(patch, name: str = "test patch"):
    """A Model of a single patch (its corners are nodes 0..3)."""
    from tsplcam.model.model import Model
    patch.corner_nodes = [0, 1, 2, 3]
    corners = patch.evaluate([0, 1, 1, 0], [0, 0, 1, 1]).P
    return Model([patch], corners, [], "bspline", name=name)


def assert_finite_everywhere(test, named_models, samples: int = 17) -> None:
    """No evaluation returns NaN: position, derivatives, normal, principal curvatures and
    directions on a grid of every patch (corners included) of every (name, model)."""
    import numpy as np
    g = np.linspace(0, 1, samples)
    U, V = np.meshgrid(g, g)
    for name, model in named_models:
        for p in model.patches:
            s = p.evaluate(U.ravel(), V.ravel())
            for arr in (s.P, s.Pu, s.Pv, s.Puu, s.Puv, s.Pvv, s.normal,
                        *s.principal_curvatures, *s.principal_directions):
                test.assertTrue(np.all(np.isfinite(arr)), f"{name} {p.name}")


def edge_pair(model, link, tau):
    """Both sides of a shared patch edge (a layout EdgeLink) evaluated at the same points:
    (SurfacePoints of patch a, of patch b) at fractions ``tau`` along a's edge."""
    pa, pb = model.patches[link.a], model.patches[link.b]
    sa = pa.evaluate(*pa.edge_params(link.ea, tau))
    sb = pb.evaluate(*pb.edge_params(link.eb, 1 - tau if link.reversed else tau))
    return sa, sb


def curvature_gap(sa, sb):
    """(largest difference of the sorted principal curvatures of two evaluations of the same
    points, 1 + largest |curvature|), with b's signs turned to a's normal."""
    import numpy as np
    sign = np.sign(np.einsum("ij,ij->i", sa.normal, sb.normal))[:, None]
    ka = np.sort(np.column_stack(sa.principal_curvatures), axis=1)
    kb = np.sort(np.column_stack(sb.principal_curvatures) * sign, axis=1)
    return float(np.abs(ka - kb).max()), 1.0 + float(np.abs(ka).max())
