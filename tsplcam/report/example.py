"""The README's example report: the main job's own report.

    /usr/bin/python3 -m tsplcam.report.example [--out docs/report-example] [--scallop 0.005]

runs the job of ``tsplcam/data/jobs/keycap.json`` (the main job with the scallop measured on
the surface and the compound-NURBS baseline oriented like the job) through
:func:`tsplcam.job.run_job`, exactly as ``python3 -m tsplcam job --config`` does, and copies
its ``report.html`` and ``report_files/`` into ``--out``; it prints each stage's time, the
report's time and its size. :func:`job_objects` hands the report's inputs to tests.
"""
from __future__ import annotations

import argparse
import os
import shutil
import tempfile

JOB_FILE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data", "jobs", "keycap.json")


def settings(**overrides):
    """The example job's JobSettings: the shipped keycap job file, with ``overrides``."""
    from ..jobfile import job_settings
    return job_settings(JOB_FILE, overrides=overrides)


def job_objects(log=None, baseline_axes: str = "job", **overrides) -> dict:
    """Everything :func:`tsplcam.report.write_report` takes, for the example job with
    ``overrides`` (JobSettings fields), made by the job's own stages
    (:func:`tsplcam.job.make_job`); ``log(text)`` is told each stage. ``baseline_axes``:
    "job" orients the baseline like the job (what a shop would run), "normal" keeps its
    surface normals (quicker; compares the linking only)."""
    from ..job import make_job
    return make_job(settings(**overrides), log=log, baseline_axes=baseline_axes).report_inputs()


def folder_size(path: str) -> int:
    """Bytes of every file under ``path``."""
    return sum(os.path.getsize(os.path.join(d, f)) for d, _, files in os.walk(path) for f in files)


def main(argv=None) -> int:
    from ..job import run_job
    from .report import FILES
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/report-example")
    ap.add_argument("--scallop", type=float, default=None, help="mm (default: the job file's)")
    args = ap.parse_args(argv)
    over = {} if args.scallop is None else {"scallop": args.scallop}
    with tempfile.TemporaryDirectory() as tmp:
        figures = run_job(settings(out=tmp, **over),       # its files are in a folder about to go
                          log=lambda text: None if text.startswith(("wrote ", "report: ")) else print(text))
        os.makedirs(args.out, exist_ok=True)
        shutil.copyfile(os.path.join(tmp, "report.html"), os.path.join(args.out, "report.html"))
        shutil.rmtree(os.path.join(args.out, FILES), ignore_errors=True)
        shutil.copytree(os.path.join(tmp, FILES), os.path.join(args.out, FILES))
    t = figures["timing"]
    print("times: " + ", ".join(f"{k[:-2]} {v:.2f} s" for k, v in t.items()))
    pictures = os.path.join(args.out, FILES)
    page = os.path.join(args.out, "report.html")
    print(f"report: {t['report_s']:.2f} s, {os.path.getsize(page) + folder_size(pictures):,d} bytes "
          f"({len(os.listdir(pictures))} pictures): {page}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
