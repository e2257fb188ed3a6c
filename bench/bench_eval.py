"""Evaluation speed: 1,000,000 points with second derivatives.

Run with FreeCAD importable for the OCCT reference:
    cd build && freecadcmd ../bench/bench_eval.py      (or /usr/bin/python3 bench/bench_eval.py)
Prints points per second for tsplcam on a bicubic B-spline patch, on a Catmull-Clark model
with extraordinary points, and the ratio against a per-point Python loop over FreeCAD's
Part.BSplineSurface (value + the five partials up to second order; Part has no single D2
call) on the same surface, measured in the same run. The process is pinned to one core.
"""
import os
import sys

# "on one core": pin the process (and the BLAS threads it starts) to a single CPU
if hasattr(os, "sched_setaffinity"):
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})

import numpy as np  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.append("/usr/lib/freecad-python3/lib")

from tsplcam.model.bspline import bspline_patch  # noqa: E402
from common import best_of  # noqa: E402

N = 1_000_000


def surface_data(rng):
    nu, nv, p = 12, 10, 3
    uk = np.concatenate([[0, 0, 0], np.linspace(0, 1, nu - 2), [1, 1, 1]])
    vk = np.concatenate([[0, 0, 0], np.linspace(0, 1, nv - 2), [1, 1, 1]])
    poles = np.zeros((nu, nv, 3))
    poles[..., 0], poles[..., 1] = np.meshgrid(np.arange(nu) * 3.0, np.arange(nv) * 3.0, indexing="ij")
    poles[..., 2] = rng.normal(0, 2, (nu, nv))
    return poles, uk, vk, p


def cell_points(patch, groups, count, rng):
    """(u, v) spread over the cells of ``patch`` whose group is among ``groups``."""
    cells = np.argwhere(np.isin(patch.cell_group, groups))
    pick = cells[rng.integers(0, len(cells), count)]
    a, b = rng.random(count), rng.random(count)
    ub, vb = patch.ubreaks, patch.vbreaks
    return (ub[pick[:, 0]] + a * (ub[pick[:, 0] + 1] - ub[pick[:, 0]]),
            vb[pick[:, 1]] + b * (vb[pick[:, 1] + 1] - vb[pick[:, 1]]))


def star_cells(rng, count=200_000):
    """T-spline kernel: points/s in the cells next to star points (subdivided to the regular
    level, stars.py) against plain Bezier cells of the same patches, in the same run; a head
    of 5 x 5 faces a cube side (eight stars of valence 3) and the same with non-uniform
    knot intervals on one edge class through a star."""
    from tsplcam.model import samples
    from tsplcam.model.stars import SumCells
    from tsplcam.model.tmesh import quad_tmesh
    from tsplcam.model.tspline import tspline_model
    cage = samples.head(5)
    mesh = quad_tmesh(cage.points, cage.mesh.faces)
    for label, model in (("uniform", tspline_model(mesh)),):
        patch = model.patches[0]
        star = [g for g, grp in enumerate(patch.groups) if isinstance(grp, SumCells)]
        plain = [g for g, grp in enumerate(patch.groups) if not isinstance(grp, SumCells)]
        us, vs = cell_points(patch, star, count, rng)
        ub, vb = cell_points(patch, plain, count, rng)
        patch.evaluate(us[:1000], vs[:1000])
        t_star, _ = best_of(lambda: patch.evaluate(us, vs), 5)
        t_bez, _ = best_of(lambda: patch.evaluate(ub, vb), 5)
        print(f"T-spline kernel ({label} stars): star cells {count / t_star / 1e6:.2f} M points/s, "
              f"Bezier cells {count / t_bez / 1e6:.2f} M points/s (ratio star/Bezier "
              f"{t_bez / t_star:.2f})")


def main():
    rng = np.random.default_rng(0)
    poles, uk, vk, p = surface_data(rng)
    patch = bspline_patch(poles, None, uk, vk, p, p)
    u, v = rng.random(N), rng.random(N)
    patch.evaluate(u[:1000], v[:1000])
    t_bs, sp = best_of(lambda: patch.evaluate(u, v), 5)
    _ = sp.principal_curvatures
    rate_bs = N / t_bs
    print(f"tsplcam bicubic B-spline patch, {N} scattered points with 2nd derivatives: {t_bs:.3f} s "
          f"= {rate_bs / 1e6:.2f} M points/s")
    side = int(round(N ** 0.5))
    gu, gv = np.linspace(0, 1, side), np.linspace(0, 1, side)
    patch.evaluate_grid(gu[:10], gv[:10])
    t_grid, spg = best_of(lambda: patch.evaluate_grid(gu, gv), 5)
    rate_grid = side * side / t_grid
    print(f"tsplcam same patch, {side} x {side} grid (tessellation, iso-lines): {t_grid:.3f} s "
          f"= {rate_grid / 1e6:.2f} M points/s")
    try:
        import tsplcam
        from common import shared_dir
        cube = os.path.join(shared_dir(), "data", "external", "opensubdiv", "catmark_cube.obj")
        model = tsplcam.load(cube)
        pts = model.patches[0]
        t_ep, _ = best_of(lambda: pts.evaluate(u, v), 5)
        print(f"tsplcam Catmull-Clark patch next to 4 extraordinary points: {N / t_ep / 1e6:.2f} M points/s")
    except Exception as exc:  # shared data absent
        print(f"(cube model skipped: {exc})")
    star_cells(rng)
    try:
        import FreeCAD
        import Part
    except ImportError:
        print("FreeCAD not importable: no OCCT reference in this run")
        return
    s = Part.BSplineSurface()
    umult = [4] + [1] * (len(np.unique(uk)) - 2) + [4]
    vmult = [4] + [1] * (len(np.unique(vk)) - 2) + [4]
    s.buildFromPolesMultsKnots([[FreeCAD.Vector(*poles[i, j]) for j in range(poles.shape[1])]
                                for i in range(poles.shape[0])],
                               umult, vmult, list(np.unique(uk)), list(np.unique(vk)), False, False, p, p)
    m = 20000
    uu, vv = u[:m].tolist(), v[:m].tolist()

    def occt_loop():
        # the same quantities per point: position and the five partials up to second order
        for a, b in zip(uu, vv):
            s.value(a, b)
            s.getDN(a, b, 1, 0)
            s.getDN(a, b, 0, 1)
            s.getDN(a, b, 2, 0)
            s.getDN(a, b, 1, 1)
            s.getDN(a, b, 0, 2)

    def occt_values():
        for a, b in zip(uu, vv):
            s.value(a, b)

    t_occ, _ = best_of(occt_loop, 5)
    t_val, _ = best_of(occt_values, 5)
    rate_occ, rate_val = m / t_occ, m / t_val
    ref = np.array([s.value(a, b) for a, b in zip(uu[:1000], vv[:1000])])
    err = np.abs(ref - sp.P[:1000]).max()
    print(f"OCCT per-point Python loop, value + 5 getDN: {rate_occ / 1e3:.0f} k points/s "
          f"(position agreement with tsplcam {err:.2e} mm)")
    print(f"OCCT per-point Python loop, value only:      {rate_val / 1e3:.0f} k points/s")
    print(f"ratio tsplcam / OCCT loop (same quantities): grid {rate_grid / rate_occ:.1f}x, "
          f"scattered {rate_bs / rate_occ:.1f}x")
    g = np.linspace(0, 1, 40)
    ref = np.array([s.value(a, b) for a in g for b in g])
    print(f"grid position agreement with OCCT: {np.abs(ref - patch.evaluate_grid(g, g).P).max():.2e} mm")


main()   # freecadcmd runs scripts under another __name__
