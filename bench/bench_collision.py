"""Collision checks per second on the keycap mold and the impeller (target: 20,000 poses/s).

Poses are the orientation stage's real workload: every candidate axis of the smoothed
strategy's cones at the points of a zigzag path (ball tangent to the surface, axes within
60 deg of the normal). Timed: ``CollisionChecker.collides`` (the numpy broad phase, fcl for
what it leaves open; a new checker per run, so no answer is remembered from the run
before), the same poses asked of fcl alone with the tool as one circumscribed mesh
(``collides_fcl``), and, as the reference measured in the same run, one at a time of fcl
primitives part by part (``collides_primitives``, Cylinder / Convex per tool part, the
straightforward Python loop). Best of three runs.

    /usr/bin/python3 bench/bench_collision.py
"""
from __future__ import annotations

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from tsplcam.model import samples  # noqa: E402
from tsplcam.model.cage import cage_model  # noqa: E402
from tsplcam.model.impeller import impeller  # noqa: E402
from tsplcam.orientation.obstacles import impeller_mesh  # noqa: E402
from tsplcam.orientation import CollisionChecker, load_tool  # noqa: E402
from tsplcam.orientation.candidates import Limits, candidate_axes, feed_directions  # noqa: E402
from tsplcam.orientation.testpaths import zigzag  # noqa: E402
from common import best_of  # noqa: E402


def poses(path, limit=20000, seed=0):
    feed = feed_directions(path.contact, path.normal)
    A, ok = candidate_axes(path.normal, feed, [0, 0, 1.0], Limits(np.radians(60), np.radians(60), np.radians(10)))
    i, j = np.nonzero(ok)
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(i), size=min(limit, len(i)), replace=False)
    return path.center[i[pick]], A[i[pick], j[pick]]


def run(name, make, path):
    C, A = poses(path)
    checker = make()

    def fresh():
        ch = make()
        ch.build_bvh()               # (else built at fcl's first question, inside the timing)
        t0 = time.perf_counter()
        out = ch.collides(C, A)
        return time.perf_counter() - t0, out, ch
    runs = [fresh() for _ in range(3)]
    t_bp, hit, ch = min(runs, key=lambda r: r[0])
    t_mesh, hit_mesh = best_of(lambda: checker.collides_fcl(C, A))
    n_ref = 4000
    t_ref, hit_ref = best_of(lambda: checker.collides_primitives(C[:n_ref], A[:n_ref]))
    rate_bp, rate, rate_ref = len(C) / t_bp, len(C) / t_mesh, n_ref / t_ref
    agree = np.mean(hit_mesh[:n_ref] == hit_ref)
    st = ch.broad.stats
    print(f"{name}: {checker.triangles} triangles, {len(C)} poses, {hit.mean():.0%} colliding")
    print(f"  broad phase + fcl       {rate_bp:10.0f} poses/s   ({(st['free'] + st['hit']) / len(C):.0%} decided in "
          f"numpy; the same answers as fcl: {np.array_equal(hit, hit_mesh)})")
    print(f"  fcl, mesh tool          {rate:10.0f} poses/s   ({'meets' if rate >= 20000 else 'below'} the 20,000 target)")
    print(f"  fcl primitives, per part {rate_ref:9.0f} poses/s   (reference)")
    print(f"  ratios {rate_bp / rate_ref:.2f} and {rate / rate_ref:.2f}; mesh and primitives agree on {agree:.2%} "
          f"of the reference poses (the mesh is conservative by its polygon tolerance)")
    return rate


def main():
    mold = cage_model(samples.keycap_mold())
    V, T = samples.keycap_mold_stock()
    t0 = time.perf_counter()
    make = lambda: CollisionChecker(mold, load_tool("ball1_keycap"), meshes=[("stock", V, T)], tolerance=0.005)  # noqa: E731
    make().build_bvh()
    print(f"keycap mold checker built in {time.perf_counter() - t0:.2f} s (tessellation + BVH + broad phase)")
    run("keycap mold", make, zigzag(mold, 0.5, lines=10, points=40))
    imp = impeller()
    t0 = time.perf_counter()
    make = lambda: CollisionChecker(imp, load_tool("ball5_impeller"), meshes=impeller_mesh(imp), tolerance=0.01)  # noqa: E731
    make().build_bvh()
    print(f"impeller checker built in {time.perf_counter() - t0:.2f} s (tessellation + BVH + broad phase)")
    run("impeller", make, zigzag(imp, 2.5, lines=12, points=60))


main()
