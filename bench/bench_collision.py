"""Collision checks per second on the keycap mold and the impeller (target: 20,000 poses/s).

Poses are the orientation stage's real workload: every candidate axis of the smoothed
strategy's cones at the points of a zigzag path (ball tangent to the surface, axes within
60 deg of the normal). Timed: ``CollisionChecker.collides`` (the tool as one circumscribed
mesh, one BVH-BVH fcl query per pose) and, as the reference measured in the same run,
the same poses asked one at a time of fcl primitives part by part (``collides_exact``,
Cylinder / Convex per tool part, the straightforward Python loop). Best of three runs.

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


def run(name, checker, path):
    C, A = poses(path)
    t_mesh, hit = best_of(lambda: checker.collides(C, A))
    n_ref = 4000
    t_ref, hit_ref = best_of(lambda: checker.collides_exact(C[:n_ref], A[:n_ref]))
    rate, rate_ref = len(C) / t_mesh, n_ref / t_ref
    agree = np.mean(hit[:n_ref] == hit_ref)
    print(f"{name}: {checker.triangles} triangles, {len(C)} poses, {hit.mean():.0%} colliding")
    print(f"  mesh tool, batched      {rate:10.0f} poses/s   ({'meets' if rate >= 20000 else 'below'} the 20,000 target)")
    print(f"  fcl primitives, per part {rate_ref:9.0f} poses/s   (reference)")
    print(f"  ratio {rate / rate_ref:.2f}; verdicts agree on {agree:.2%} of the reference poses "
          f"(the mesh is conservative by its polygon tolerance)")
    return rate


def main():
    mold = cage_model(samples.keycap_mold())
    V, T = samples.keycap_mold_stock()
    t0 = time.perf_counter()
    ch = CollisionChecker(mold, load_tool("ball1_keycap"), meshes=[("stock", V, T)], tolerance=0.005)
    print(f"keycap mold checker built in {time.perf_counter() - t0:.2f} s (tessellation + BVH)")
    run("keycap mold", ch, zigzag(mold, 0.5, lines=10, points=40))
    imp = impeller()
    t0 = time.perf_counter()
    ch = CollisionChecker(imp, load_tool("ball5_impeller"), meshes=impeller_mesh(imp), tolerance=0.01)
    print(f"impeller checker built in {time.perf_counter() - t0:.2f} s (tessellation + BVH)")
    run("impeller", ch, zigzag(imp, 2.5, lines=12, points=60))


main()
