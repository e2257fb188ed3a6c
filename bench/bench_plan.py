"""Speed of the plan stage: order + transit corners for 100-patch layouts.

shang2020 (section 3.3) reports LKH solving a 100-city problem in under a second. This
times :func:`tsplcam.plan.plan` (LKH order, forward pass with back tracking, exact
retraction marking when needed) on three 100-patch layouts and prints each time as a ratio
to a reference measured in the same run: elkai (LKH) on a random 100-city Euclidean TSP
with its default 10 runs. Ratios, not seconds, are what to compare between machines.

    /usr/bin/python3 bench/bench_plan.py
"""
from __future__ import annotations

import os
import sys

import numpy as np
from scipy.sparse.csgraph import connected_components

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from tsplcam.layout import examples as ex  # noqa: E402
from tsplcam.layout.layout import Layout  # noqa: E402
from tsplcam.plan import plan  # noqa: E402
from tsplcam.plan.corners import Rules, choose_corners  # noqa: E402
from tsplcam.plan.graph import PatchGraph, preferred_crossfeeds  # noqa: E402
from tsplcam.plan.order import lkh_order  # noqa: E402
from tsplcam.plan.steps import Pins  # noqa: E402
from common import best_of  # noqa: E402


def holey_grid(n=100, side=12, seed=4) -> Layout:
    """n cells of a side x side grid, the rest removed at random (holes, corner contacts)."""
    rng = np.random.default_rng(seed)
    keep = rng.choice(side * side, size=n, replace=False)
    cells = [(int(c) % side, int(c) // side) for c in keep]
    s = side + 1
    quads = [(j * s + i, j * s + i + 1, (j + 1) * s + i + 1, (j + 1) * s + i) for i, j in cells]
    return Layout.from_quads(quads)


def main() -> int:
    import elkai
    rng = np.random.default_rng(0)
    cities = {str(i): (float(x), float(y)) for i, (x, y) in enumerate(rng.random((100, 2)) * 1000)}
    ref, _ = best_of(lambda: elkai.Coordinates2D(cities).solve_tsp(runs=10))
    print(f"reference: elkai, random 100-city Euclidean TSP, 10 runs: {ref * 1e3:.1f} ms")
    layouts = {"grid 10x10": ex.grid(10, 10),
               "fans (extraordinary nodes)": ex.random_layout(8, 100, "fan"),
               "grid 12x12 with 44 holes": holey_grid()}
    print(f"{'layout':28s} {'order ms':>9s} {'corners ms':>11s} {'plan ms':>9s} {'ratio':>6s}  result")
    for name, lay in layouts.items():
        g = PatchGraph(lay)
        rules = Rules(g, preferred_crossfeeds(lay), Pins())
        t_order, order = best_of(lambda: lkh_order(g, Pins()))
        t_corner, _ = best_of(lambda: choose_corners(rules, order))
        t_plan, pl = best_of(lambda: plan(lay))
        pieces = connected_components(g.kind > 0)[0]
        print(f"{name:28s} {t_order * 1e3:9.1f} {t_corner * 1e3:11.1f} {t_plan * 1e3:9.1f} "
              f"{t_plan / ref:6.2f}  {pl.boundary_links} boundary, {pl.corner_links} corner, "
              f"{pl.retractions} retractions (>= {pieces - 1}: {pieces} separate pieces); "
              f"{pl.info['order_method']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
