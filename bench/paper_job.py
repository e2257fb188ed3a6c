"""The paper's own job, end to end: the keycap (shang2020 section 4) with a ball of radius
0.5 mm and a scallop limit of 0.005 mm, planned, cut as one path, written as CL data,
measured by the verification module on the whole surface, and compared with the
compound-NURBS baseline. Prints the figures the README quotes.

    /usr/bin/python3 bench/paper_job.py [--model keycap] [--radius 0.5] [--scallop 0.005]
                                        [--repeat 3] [--cl build/keycap.cl] [--json FILE]

Times are the best of ``--repeat`` runs (the machine is shared); the verification runs once.
The same path comes from ``python3 -m tsplcam path keycap --tool-radius 0.5 --scallop 0.005
--cl keycap.cl --verify --baseline``.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from tsplcam.layout.layout import Layout  # noqa: E402
from tsplcam.toolpath.baseline import baseline_path  # noqa: E402
from tsplcam.toolpath.cldata import read_cl, write_cl  # noqa: E402
from tsplcam import load_model  # noqa: E402
from tsplcam.toolpath.zigzag import default_plan, zigzag_path  # noqa: E402
from tsplcam.verify.metrics import compare_table, path_metrics  # noqa: E402
from tsplcam.verify.scallop import measure  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--model", default="keycap")
    ap.add_argument("--radius", type=float, default=0.5)
    ap.add_argument("--scallop", type=float, default=0.005)
    ap.add_argument("--chord-tol", type=float, default=0.001)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--spacing", type=float, default=None, help="verification grid spacing (mm)")
    ap.add_argument("--cl", default=None)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    model = load_model(args.model)
    t = time.perf_counter()
    plist = default_plan(model)
    t_plan = time.perf_counter() - t
    print(plist.table(Layout.from_model(model)))
    times, path = [], None
    for _ in range(max(1, args.repeat)):
        t = time.perf_counter()
        path = zigzag_path(model, plist, args.radius, args.scallop, args.chord_tol)
        times.append(time.perf_counter() - t)
    print(f"\n{args.model}: ball radius {args.radius} mm, scallop {args.scallop} mm, chord tolerance "
          f"{args.chord_tol} mm; plan {t_plan:.2f} s, path best of {len(times)}: {min(times):.2f} s")
    print(f"{'step':>4} {'patch':>5} {'crossfeed':>9} {'start':>12} {'finish':>12} {'lines':>5} "
          f"{'scallop used':>12} {'tuning trials':>13} {'points':>7} {'cut mm':>8}")
    for d in path.info["patches"]:
        print(f"{d['step']:>4} {d['patch']:>5} {d['crossfeed']:>9} {d['start']:>12} {d['finish']:>12} "
              f"{d['lines']:>5} {d['scallop_used']:>12.6f} {len(d['trials']):>13} {d['points']:>7} "
              f"{d['cut_length']:>8.1f}")
    m = path_metrics(path)
    cl = args.cl or os.path.join("build", f"{args.model}_paper_job.cl")
    os.makedirs(os.path.dirname(cl) or ".", exist_ok=True)
    t = time.perf_counter()
    write_cl(path, cl)
    t_cl = time.perf_counter() - t
    back = read_cl(cl)
    print(f"CL data: {cl}, {os.path.getsize(cl)} bytes, {len(back)} GOTO records, written in {t_cl:.2f} s")
    t = time.perf_counter()
    v = measure(path, model, spacing=args.spacing)
    t_v = time.perf_counter() - t
    h = args.scallop
    print(f"verification ({t_v:.1f} s, {v.samples} surface samples every {v.spacing:.4f} mm, "
          f"{v.ridges} ridges refined, {v.cusps} cusps between neighbouring lines):")
    print(f"  largest scallop {v.max_scallop:.6f} mm = {v.max_scallop / h:.3f} h "
          f"at patch {v.max_at[0]} (u, v) = ({v.max_at[1]:.4f}, {v.max_at[2]:.4f})")
    print(f"  cusp height mean {v.cusp_mean:.6f} mm = {v.cusp_mean / h:.3f} h, max {v.cusp_max / h:.3f} h")
    print(f"  mean material over the surface {v.mean_material:.6f} mm = {v.mean_material / h:.3f} h")
    print(f"  gouge: at path points {v.gouge_points:.2e} mm, on chords {v.gouge_chords:.2e} mm "
          f"(chord tolerance {args.chord_tol} mm), air {v.gouge_air:.2e} mm; uncovered samples {v.uncovered}")
    t = time.perf_counter()
    base = baseline_path(model, args.radius, args.scallop, args.chord_tol, order=plist.order)
    t_b = time.perf_counter() - t
    mb = path_metrics(base)
    print(f"\nagainst the compound-NURBS baseline (each face on its own, {t_b:.2f} s):")
    print(compare_table({"T-spline": m, "baseline": mb}))
    if args.json:
        doc = {"model": args.model, "radius": args.radius, "scallop": h, "chord_tol": args.chord_tol,
               "path_seconds": min(times), "patches": path.info["patches"], "metrics": m.as_dict(),
               "verification": {k: (list(x) if isinstance(x, tuple) else x) for k, x in v.as_dict().items()},
               "verification_seconds": t_v, "baseline": mb.as_dict()}
        with open(args.json, "w") as fh:
            json.dump(doc, fh, indent=2)
    return 0


main()
