"""The keycap job's stages in-process, for the README's example report and the report tests.

    /usr/bin/python3 -m tsplcam.report.example [--scallop 0.005] [--out docs/report-example]

runs model -> processing list -> path -> smooth collision-free tool axes -> Heidenhain program
(the main job's defaults), measures the scallop on the surface and builds the compound-NURBS
baseline, then writes the report; it prints each stage's time, the report's time and its size.
"""
from __future__ import annotations

import argparse
import os
import time

DEFAULTS = {"model": "keycap", "tool": "ball1_keycap", "scallop": 0.005, "chord_tol": 0.001,
            "orientation": "smooth", "machine": "mikron_ucp600_heidenhain", "dialect": None,
            "holder_clearance": 0.3, "baseline_axes": "job"}


def job_objects(log=None, **settings) -> dict:
    """Everything :func:`tsplcam.report.write_report` takes, for the job ``settings`` (keys of
    :data:`DEFAULTS`), made by the program builder (tsplcam.program) the job uses;
    ``log(stage, seconds)`` is told each. ``baseline_axes``: "job" orients the baseline like
    the job (what a shop would run), "normal" keeps its surface normals (quicker; compares
    the linking only)."""
    from ..program import (load_machine, load_model, load_stock, load_tool, make_baseline, make_path,
                           make_program, processing_list)
    from ..settings import JobSettings
    from ..verify.scallop import measure
    s = dict(DEFAULTS, **settings)
    if s["baseline_axes"] not in ("job", "normal"):
        raise ValueError(f"baseline_axes must be 'job' or 'normal', not {s['baseline_axes']!r}")
    js = JobSettings(**{k: v for k, v in s.items() if k != "baseline_axes"}).check()
    log = log or (lambda stage, seconds: None)
    out = {"settings": s}

    def stage(name, make):
        t = time.perf_counter()
        value = make()
        log(name, time.perf_counter() - t)
        return value

    model = out["model"] = stage("model", lambda: load_model(js.model))
    plist = out["processing_list"] = stage("processing list", lambda: processing_list(model, js))
    tool = out["tool"] = load_tool(js)
    out["machine"] = load_machine(js)
    stock = out["stock"] = load_stock(js)
    path = out["path"] = stage("path", lambda: make_path(model, plist, js, tool.ball_radius))
    program = out["oriented"] = stage("tool axes and program", lambda: make_program(path, model, js, stock=stock,
                                                                                      plist=plist))
    out["posted"] = program.posted
    out["checker"] = program.checker
    out["verification"] = stage("scallop verification", lambda: measure(path, model, heights=True))
    base = stage("baseline", lambda: make_baseline(model, plist, js, tool.ball_radius))
    if s["baseline_axes"] == "job":
        base = stage("baseline tool axes", lambda: make_program(base, model, js, stock=stock, post=False)).path
    out["baseline"] = base
    return out


def folder_size(path: str) -> int:
    """Bytes of every file under ``path``."""
    return sum(os.path.getsize(os.path.join(d, f)) for d, _, files in os.walk(path) for f in files)


def main(argv=None) -> int:
    from .report import FILES, write_report
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/report-example")
    for k, v in DEFAULTS.items():
        ap.add_argument("--" + k.replace("_", "-"), type=type(v) if v is not None else str, default=v)
    args = ap.parse_args(argv)
    settings = {k: getattr(args, k) for k in DEFAULTS}
    objects = job_objects(log=lambda stage, sec: print(f"{stage}: {sec:.2f} s"), **settings)
    objects["settings"] = {k: v for k, v in objects["settings"].items() if k != "baseline_axes"}
    t = time.perf_counter()
    page = write_report(args.out, **objects)
    took = time.perf_counter() - t
    pictures = os.path.join(args.out, FILES)
    print(f"report: {took:.2f} s, {os.path.getsize(page) + folder_size(pictures):,d} bytes "
          f"({len(os.listdir(pictures))} pictures): {page}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
