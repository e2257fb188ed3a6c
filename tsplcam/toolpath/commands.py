"""The toolpath stage's part of ``python3 -m tsplcam path``: its options, building the path
from the arguments, writing CL data and the report (the command itself, with orientation and
posting, is registered by :mod:`tsplcam.pipeline`).

Examples::

    python3 -m tsplcam path keycap --tool-radius 0.5 --scallop 0.005 --cl keycap.cl
    python3 -m tsplcam path model.obj --tool-radius 1 --scallop 0.01 \\
        --processing-list list.json --cl model.cl --verify
    python3 -m tsplcam path keycap --tool-radius 0.5 --scallop 0.005 --baseline

MODEL is a model file (``tsplcam.load``) or the name of a shipped sample (keycap,
keycap_mold, head, figure4). Without ``--processing-list`` the planner's list is used.

Pieces: :func:`add_arguments` (options), :func:`build` (arguments -> model, processing list,
ToolPath), :func:`write_outputs` (files) and :func:`report` (text).
"""
from __future__ import annotations

import json
import os

from ..errors import InputError


def load_model(spec: str):
    """A model from a file, or from a shipped sample's name when no such file exists."""
    from .. import load
    from ..model.samples import SAMPLES, sample_path
    if not os.path.exists(spec) and spec in SAMPLES:
        return load(sample_path(spec))
    return load(spec)


def settings_from_args(args):
    from .zigzag import PathSettings
    return PathSettings(tool_radius=args.tool_radius, scallop=args.scallop, chord_tol=args.chord_tol,
                        max_step=args.max_step, feed=args.feed, clearance=args.clearance,
                        clearance_mode=args.clearance_mode, balance=not args.no_balance).check()


def build(args):
    """(model, processing list, ToolPath) from the parsed arguments."""
    from dataclasses import asdict
    from ..plan import load as load_list
    from .zigzag import default_plan, zigzag_path
    settings = settings_from_args(args)
    model = load_model(args.model)
    if args.processing_list:
        plist = load_list(args.processing_list, model.layout())
    else:
        plist = default_plan(model)
    options = {k: v for k, v in asdict(settings).items()
               if k not in ("tool_radius", "scallop", "chord_tol")}
    path = zigzag_path(model, plist, settings.tool_radius, settings.scallop, settings.chord_tol, **options)
    path.info["model"] = os.path.basename(args.model)
    return model, plist, path


def build_baseline(args, model, plist):
    from dataclasses import asdict
    from .baseline import baseline_path
    settings = settings_from_args(args)
    options = {k: v for k, v in asdict(settings).items()
               if k not in ("tool_radius", "scallop", "chord_tol", "tune_parity")}
    path = baseline_path(model, settings.tool_radius, settings.scallop, settings.chord_tol,
                         order=plist.order, **options)
    path.info["model"] = os.path.basename(args.model)
    return path


def write_outputs(args, path, baseline=None, extra: dict | None = None) -> list[str]:
    """Write the files the arguments ask for; returns what was written."""
    from .cldata import write_cl
    written = []
    if args.cl:
        write_cl(path, args.cl)
        written.append(args.cl)
    if baseline is not None and args.baseline_cl:
        write_cl(baseline, args.baseline_cl)
        written.append(args.baseline_cl)
    if args.json:
        doc = {"path": _summary(path), **(extra or {})}
        if baseline is not None:
            doc["baseline"] = _summary(baseline)
        try:
            with open(args.json, "w", encoding="utf-8") as fh:
                json.dump(doc, fh, indent=2, sort_keys=True, default=_json_default)
                fh.write("\n")
        except OSError as exc:
            raise InputError(f"cannot write the report: {exc.strerror}", path=args.json) from None
        written.append(args.json)
    return written


def _json_default(x):
    import numpy as np
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.floating,)):
        return float(x)
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def _summary(path) -> dict:
    from ..verify.metrics import path_metrics
    return {"metrics": path_metrics(path).as_dict(), "patches": path.info.get("patches", []),
            "settings": path.info.get("settings", {}), "seconds": path.info.get("seconds")}


def report(path, verification=None, baseline=None) -> str:
    """The text the command prints."""
    from ..verify.metrics import compare_table, path_metrics
    s = path.info["settings"]
    out = [f"{path.info.get('model', '')}: ball radius {s['tool_radius']:g} mm, scallop {s['scallop']:g} mm, "
           f"chord tolerance {s['chord_tol']:g} mm"]
    rows = [("step", "patch", "crossfeed", "start", "finish", "lines", "scallop used", "points", "cut mm")]
    for d in path.info["patches"]:
        rows.append((str(d["step"]), str(d["patch"]), d["crossfeed"], d["start"], d["finish"], str(d["lines"]),
                     f"{d['scallop_used']:.5g}", str(d["points"]), f"{d['cut_length']:.1f}"))
    w = [max(len(r[k]) for r in rows) for k in range(len(rows[0]))]
    out += ["  " + "  ".join(c.rjust(wk) for c, wk in zip(r, w)) for r in rows]
    m = path_metrics(path)
    out.append(f"{m.points} points, {m.lines} lines, length {m.length:.1f} mm (cut {m.cut_length:.1f}, "
               f"link {m.link_length:.1f}, air {m.air_length:.1f}), {m.retractions} retractions; "
               f"generated in {path.info['seconds']:.2f} s")
    if verification is not None:
        v = verification
        out.append(f"measured on {v.samples} surface samples + {v.ridges} ridges: largest scallop "
                   f"{v.max_scallop:.5f} mm at patch {v.max_at[0]} (u, v) = ({v.max_at[1]:.4f}, {v.max_at[2]:.4f}); "
                   f"cusp mean {v.cusp_mean:.5f} mm; mean material {v.mean_material:.5f} mm; gouge at points "
                   f"{v.gouge_points:.2e} mm, on chords {v.gouge_chords:.2e} mm, in the air {v.gouge_air:.2e} mm")
    if baseline is not None:
        out.append("T-spline path against the compound-NURBS baseline (each face on its own):")
        out.append(compare_table({"T-spline": m, "baseline": path_metrics(baseline)}))
    return "\n".join(out)


def _positive(text: str) -> float:
    import argparse
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not v > 0 or v != v or v == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive number")
    return v


def add_arguments(p) -> None:
    """The toolpath stage's options of the ``path`` command."""
    p.add_argument("model", help="model file (e.g. a .obj quad cage) or a shipped sample name")
    p.add_argument("--tool-radius", type=_positive, required=True, metavar="R", help="ball radius (mm)")
    p.add_argument("--scallop", type=_positive, required=True, metavar="H", help="scallop height limit (mm)")
    p.add_argument("--chord-tol", type=_positive, default=0.001, metavar="T",
                   help="chord tolerance along the lines (mm, default 0.001)")
    p.add_argument("--processing-list", metavar="FILE", help="processing list (JSON, see `tsplcam plan`); "
                                                             "default: planned here")
    p.add_argument("--cl", metavar="OUT", help="write the path as APT CL data (tsplcam/toolpath/CLDATA.md)")
    p.add_argument("--max-step", type=_positive, default=1.0, metavar="L",
                   help="longest step between points along a line (mm, default 1)")
    p.add_argument("--feed", type=_positive, default=1000.0, help="cutting feed (mm/min, default 1000)")
    p.add_argument("--clearance", type=_positive, default=5.0,
                   help="clearance for retractions (mm above the model or its bounding sphere, default 5)")
    p.add_argument("--clearance-mode", choices=("auto", "plane", "sphere"), default="auto",
                   help="retract to a plane above the model or to a sphere around it (default auto)")
    p.add_argument("--no-balance", action="store_true",
                   help="keep the paper's line positions (do not spread the last gap's slack)")
    p.add_argument("--verify", action="store_true",
                   help="measure scallop, cusps and gouges on the surface (tsplcam.verify) and report them")
    p.add_argument("--baseline", action="store_true",
                   help="also make the compound-NURBS baseline (each face on its own) and compare")
    p.add_argument("--baseline-cl", metavar="OUT", help="write the baseline path as CL data (implies --baseline)")
    p.add_argument("--json", metavar="FILE", help="write the figures (and verification) as JSON")

