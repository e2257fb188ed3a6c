"""Speed of the toolpath stage and of the verification, as ratios to the kernel's evaluation
measured in the same run (the machine is shared: best of several runs).

Reference: evaluating every patch of the model at 20,000 (u, v) points with derivatives
(one ``Patch.evaluate`` call per patch), the unit of work the generator is built from.

    /usr/bin/python3 bench/bench_path.py [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from tsplcam.toolpath.cldata import cl_text  # noqa: E402
from tsplcam import load_model  # noqa: E402
from tsplcam.toolpath.zigzag import default_plan, zigzag_path  # noqa: E402
from tsplcam.verify.scallop import measure  # noqa: E402
from common import best_of  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    jobs = [("keycap", 0.5, 0.005), ("keycap", 0.5, 0.02), ("keycap_mold", 0.5, 0.01), ("head", 3.0, 0.05)]
    rng = np.random.default_rng(0)
    uv = rng.random((20000, 2))
    print(f"{'model':12s} {'r':>4s} {'h':>6s} {'ref s':>7s} {'path s':>7s} {'ratio':>6s} {'points':>7s} "
          f"{'CL s':>6s} {'verify s':>8s} {'ratio':>6s}")
    for name, r, h in jobs:
        model = load_model(name)
        plist = default_plan(model)
        ref, _ = best_of(lambda: [p.evaluate(uv[:, 0], uv[:, 1]).normal for p in model.patches], args.repeat)
        t_path, path = best_of(lambda: zigzag_path(model, plist, r, h), args.repeat)
        t_cl, _ = best_of(lambda: cl_text(path), args.repeat)
        t_v, _ = best_of(lambda: measure(path, model), 1)
        print(f"{name:12s} {r:4g} {h:6g} {ref:7.3f} {t_path:7.2f} {t_path / ref:6.0f} {len(path):7d} "
              f"{t_cl:6.2f} {t_v:8.1f} {t_v / ref:6.0f}")
    return 0


main()
