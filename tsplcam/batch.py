"""Many jobs at once: ``python3 -m tsplcam batch JOBS... [--workers N] [--out DIR] [--force]
[--scheduler tcp://HOST:PORT]``.

Each job file (:mod:`tsplcam.jobfile`) runs as ``job`` would, in its own process, writing
into ``DIR/<job file's name without extension>/`` (its ``out`` key is not used). One job
failing does not stop the others. A line is printed per job as it finishes, a table at the
end, and ``DIR/summary.json`` holds one object per job in the order given: ``job`` (the job
file), ``name``, ``status`` (``ok`` or ``failed``), ``error``, ``reused``, the figures
(``points``, ``machining_time_s``, ``collisions``, ``gouges``, ``retractions``,
``scallop`` (the limit), ``max_scallop`` (measured), ``min_clearance``), ``program``, ``out``
and ``wall_s``.

Reruns: a job whose content hash is the one its last successful run recorded
(``DIR/<name>/batch.json``) is not run again and its row is reused (``reused: true``); the
hash covers the job's settings, the bytes of every file it reads (model, stock, processing
list, tool, machine) and tsplcam's version and source. ``--force`` runs every job.

Workers: ``--workers N`` jobs at a time (default: the cores this process may use), each in a
process of its own. The engine forks workers of its own for path steps and collision checks;
inside a batch each job gets ``cores // N`` of them (``TSPLCAM_WORKERS``, at least 1; an
explicit ``TSPLCAM_WORKERS`` in the environment wins), so N jobs on N cores do not
oversubscribe them.

``--scheduler tcp://HOST:PORT`` sends the jobs to a Dask distributed cluster instead
(``dask scheduler``, ``dask worker``; each job is one task, run by the same function as
here, with ``TSPLCAM_WORKERS=1`` in the worker). The workers need tsplcam at the same
version and source, and must see the job files, their inputs and DIR at the same paths (a
shared folder); each task checks both and refuses to run otherwise.

Exit codes: 0 every job ok (run or reused); 1 one or more jobs failed (named in the table
and in summary.json); 2 the batch itself refused (bad arguments, two job files of the same
name, an output folder that cannot be written, no scheduler at the address); 130 stopped
by Ctrl-C.
"""
from __future__ import annotations

import hashlib
import json
import multiprocessing
import os
import sys
import time
import traceback
from multiprocessing.connection import wait as wait_for

from .errors import InputError, TsplcamError
from .outfile import check_folder, write_text
from .numerics import BLAS_THREADS

RECORD = "batch.json"          # DIR/<name>/batch.json: the hash and row of the last good run
SUMMARY = "summary.json"
FIGURES = ("points", "machining_time_s", "collisions", "gouges", "retractions", "scallop", "max_scallop",
           "min_clearance")


# -- what a job is --------------------------------------------------------------------------
def job_name(path: str) -> str:
    """The job's folder under DIR: the job file's name without extension."""
    return os.path.splitext(os.path.basename(path))[0]


def _sha256_file(path: str) -> str | None:
    try:
        with open(path, "rb") as fh:
            return hashlib.sha256(fh.read()).hexdigest()
    except OSError:
        return None                       # the job's own run names the missing file


_SOURCE = None


def source_digest() -> str:
    """sha256 over tsplcam's Python source files (names and bytes), once per process."""
    global _SOURCE
    if _SOURCE is None:
        root = os.path.dirname(os.path.abspath(__file__))
        h = hashlib.sha256()
        for folder, dirs, files in sorted(os.walk(root)):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            for name in sorted(files):
                if name.endswith(".py"):
                    path = os.path.join(folder, name)
                    h.update(os.path.relpath(path, root).encode() + b"\0")
                    with open(path, "rb") as fh:
                        h.update(fh.read())
        _SOURCE = h.hexdigest()
    return _SOURCE


def job_hash(settings) -> str:
    """Content hash of a job: its settings (file names by their base name, ``out`` left out),
    the bytes of every file it reads, tsplcam's version and source."""
    from . import __version__
    from .jobfile import input_files
    files = input_files(settings)
    named = dict(settings.to_dict())
    named.pop("out", None)
    for key, _ in files:
        if isinstance(named.get(key), str):
            named[key] = os.path.basename(named[key])
    doc = {"tsplcam": __version__, "source": source_digest(), "settings": named,
           "inputs": [[key, os.path.basename(path), _sha256_file(path)] for key, path in files]}
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=list).encode()).hexdigest()


def prepare(path: str, out: str) -> dict:
    """A job's spec: its file, name, settings (``out`` = ``out/<name>``, absolute: a Dask
    worker runs in a folder of its own) and hash; a job file that cannot be read gives a
    spec with its ``error``."""
    name = job_name(path)
    spec = {"job": path, "name": name, "out": os.path.join(os.path.abspath(out), name), "settings": None,
            "hash": None, "error": None}
    from .jobfile import job_settings
    try:
        s = job_settings(path, overrides={"out": spec["out"]})
        spec["settings"] = s.to_dict()
        spec["hash"] = job_hash(s)
    except TsplcamError as exc:
        spec["error"] = " ".join(str(exc).split())
    return spec


def row_of(spec: dict, status: str, error: str | None = None, wall: float = 0.0, figures: dict | None = None,
           program: str | None = None) -> dict:
    """One object of summary.json."""
    row = {"job": spec["job"], "name": spec["name"], "status": status, "error": error, "reused": False,
           "out": spec["out"], "program": program, "wall_s": round(float(wall), 3)}
    row.update({k: None for k in FIGURES})
    if figures:
        row.update(figures)
    return row


def _figures(report: dict) -> dict:
    """The summary's figures from a job's report.json content."""
    o = report.get("orientation") or {}
    v = report.get("verification") or {}
    return {"points": report["path"]["points"], "machining_time_s": report["machining_time_s"],
            "collisions": o.get("collisions"), "gouges": o.get("gouges"),
            "retractions": report["path"]["retractions"], "scallop": report["settings"]["scallop"],
            "max_scallop": v.get("max_scallop"), "min_clearance": o.get("min_clearance")}


# -- running one job (in a batch process or on a Dask worker) ---------------------------------
def run_one(spec: dict, workers: int | None = None, check_inputs: bool = False) -> dict:
    """Run the job of ``spec`` (from :func:`prepare`) into ``spec["out"]``; its summary row.
    ``workers``: the engine's own worker processes for this job (TSPLCAM_WORKERS, unless the
    environment sets it already); ``check_inputs``: first make sure this process sees the
    same tsplcam and input files as the one that prepared the spec (a Dask worker)."""
    from .job import run_job
    from .settings import JobSettings
    t0 = time.perf_counter()
    if workers is not None and not os.environ.get("TSPLCAM_WORKERS", "").strip():
        os.environ["TSPLCAM_WORKERS"] = str(max(1, int(workers)))
    try:
        s = JobSettings(**spec["settings"]).check()
        if check_inputs and job_hash(s) != spec["hash"]:
            raise InputError("this worker sees other input files or another tsplcam than the machine that "
                             "started the batch (share the checkout, the job files and their inputs at the same "
                             "paths)", path=spec["job"])
        report = run_job(s, log=None, progress=lambda stage, done, total: None)
        return row_of(spec, "ok", wall=time.perf_counter() - t0, figures=_figures(report),
                      program=report["files"]["program"])
    except TsplcamError as exc:
        return row_of(spec, "failed", " ".join(str(exc).split()), time.perf_counter() - t0)
    except Exception as exc:                                    # a bug: keep its traceback
        row = row_of(spec, "failed", f"internal error: {type(exc).__name__}: {exc}", time.perf_counter() - t0)
        row["traceback"] = traceback.format_exc()
        return row


def _child(spec: dict, conn) -> None:
    """A batch process: one job, its row sent back through ``conn``."""
    try:
        row = run_one(spec)
    except BaseException as exc:                                # Ctrl-C, SystemExit
        row = row_of(spec, "failed", f"stopped: {type(exc).__name__}")
    conn.send(row)
    conn.close()


def run_local(specs: list, workers: int, done) -> None:
    """Run ``specs`` in up to ``workers`` processes at a time, one new process per job
    (started fresh, so that its environment sets its BLAS threads and engine workers);
    ``done(row)`` as each ends. A process that dies without a row (killed, out of memory)
    fails its job only."""
    ctx = multiprocessing.get_context("spawn")
    env = dict(BLAS_THREADS, TSPLCAM_WORKERS=os.environ.get("TSPLCAM_WORKERS", "").strip()
               or str(max(1, cores() // max(1, workers))))
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)                      # what the job processes start with
    pending, running = list(specs), {}
    try:
        while pending or running:
            while pending and len(running) < workers:
                spec = pending.pop(0)
                recv, send = ctx.Pipe(duplex=False)
                p = ctx.Process(target=_child, args=(spec, send), name=f"tsplcam-{spec['name']}")
                p.start()
                send.close()                     # the child holds the only writing end
                running[recv] = (p, spec, time.perf_counter())
            for conn in wait_for(list(running)):
                p, spec, t0 = running.pop(conn)
                try:
                    row = conn.recv()
                except (EOFError, OSError):
                    row = None
                conn.close()
                p.join()
                if row is None:
                    row = row_of(spec, "failed", f"the job's process ended without a result (exit code "
                                                 f"{p.exitcode}: killed, or out of memory?)", time.perf_counter() - t0)
                done(row)
    except BaseException:
        for p, _, _ in running.values():
            p.terminate()
        for p, _, _ in running.values():
            p.join()
        raise
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _dask_task(spec: dict) -> dict:
    """A job on a Dask worker: one engine process per task (the worker's threads and
    processes are the parallelism), inputs checked against the client's hash."""
    return run_one(spec, workers=1, check_inputs=True)


def run_dask(specs: list, address: str, done, timeout: str = "10s") -> None:
    """Run ``specs`` as tasks on the Dask cluster at ``address``; ``done(row)`` as each ends.
    ``timeout``: how long to wait for the scheduler to answer."""
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise InputError("needs the Dask 'distributed' package (bash scripts/install.sh installs it)",
                         item="--scheduler") from None
    try:
        client = Client(address, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise InputError(f"no Dask scheduler answers at {address}: {exc}", item="--scheduler") from None
    with client:
        futures = {}
        for spec in specs:
            f = client.submit(_dask_task, spec, key=f"tsplcam-{spec['name']}-{spec['hash'][:16]}", pure=False)
            futures[f.key] = (f, spec, time.perf_counter())
        for f in as_completed([f for f, _, _ in futures.values()], loop=client.loop):
            _, spec, t0 = futures[f.key]
            try:
                row = f.result()
            except Exception as exc:                  # the worker died, or could not import tsplcam
                text = " ".join(str(exc).split())
                if "deserializ" in text or "No module named 'tsplcam" in text:
                    text = "the scheduler or a worker cannot import tsplcam (start them with it importable: README)"
                row = row_of(spec, "failed", f"on the cluster: {type(exc).__name__}: {text}", time.perf_counter() - t0)
            if row["status"] == "ok" and not os.path.exists(os.path.join(spec["out"], "report.json")):
                row = row_of(spec, "failed", f"the worker wrote its files where this machine does not see them "
                                             f"({spec['out']}): DIR must be a shared folder", row["wall_s"])
            done(row)


def cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


# -- the batch ------------------------------------------------------------------------------
def _record(spec: dict) -> dict | None:
    """The row of the last successful run of ``spec``, when its hash is this one."""
    try:
        with open(os.path.join(spec["out"], RECORD), encoding="utf-8") as fh:
            rec = json.load(fh)
    except (OSError, ValueError):
        return None
    if not isinstance(rec, dict) or rec.get("hash") != spec["hash"] or not isinstance(rec.get("row"), dict):
        return None
    if not os.path.exists(os.path.join(spec["out"], "report.json")):
        return None
    return rec["row"]


def run_batch(jobs: list, out: str, workers: int | None = None, force: bool = False, scheduler: str | None = None,
              log=print) -> list:
    """Run the job files ``jobs`` into ``out/<name>/``: their rows (in the order given), also
    written to ``out/summary.json``. ``log(line)`` is told of each job as it finishes."""
    log = log or (lambda text: None)
    if not jobs:
        raise InputError("give at least one job file", item="JOBS")
    seen = {}
    for path in jobs:
        name = job_name(path)
        if name in seen:
            raise InputError(f"two job files named {name!r} ({seen[name]}, {path}) would write into the same "
                             f"folder {os.path.join(out, name)}: rename one", item="JOBS")
        seen[name] = path
    workers = cores() if workers is None else workers
    if workers < 1:
        raise InputError(f"must be 1 or more, not {workers}", item="--workers")
    check_folder(out, item="--out")
    t0 = time.perf_counter()
    specs = [prepare(path, out) for path in jobs]
    rows, todo = {}, []
    count = len(specs)

    def finished(row):
        rows[row["name"]] = row
        log(f"[{len(rows)}/{count}] {progress_line(row)}")
        if row["status"] == "ok" and not row["reused"]:
            spec = next(s for s in specs if s["name"] == row["name"])
            write_text(os.path.join(spec["out"], RECORD),
                       json.dumps({"hash": spec["hash"], "row": row}, indent=2, sort_keys=True) + "\n",
                       what="batch record")

    for spec in specs:
        if spec["error"] is not None:
            finished(row_of(spec, "failed", spec["error"]))
            continue
        old = None if force else _record(spec)
        if old is not None:
            finished(dict(old, reused=True, job=spec["job"], out=spec["out"]))
            continue
        todo.append(spec)
    if todo:
        if scheduler:
            run_dask(todo, scheduler, finished)
        else:
            run_local(todo, min(workers, len(todo)), finished)
    ordered = [rows[s["name"]] for s in specs]
    os.makedirs(out, exist_ok=True)
    write_text(os.path.join(out, SUMMARY), json.dumps(ordered, indent=2, sort_keys=True) + "\n", what="summary")
    wall = time.perf_counter() - t0
    log("")
    log(summary_table(ordered))
    ok = sum(r["status"] == "ok" for r in ordered)
    reused = sum(bool(r["reused"]) for r in ordered)
    where = ("none run" if not todo else f"on {scheduler}" if scheduler else f"{min(workers, len(todo))} at a time")
    log(f"{len(ordered)} jobs: {ok} ok ({reused} unchanged, not run again), {len(ordered) - ok} failed; "
        f"{wall:.1f} s ({where}); summary: {os.path.join(out, SUMMARY)}")
    return ordered


def _hms(seconds) -> str:
    from .post.timing import hms
    return "-" if seconds is None else hms(seconds)


def _mm(x, digits=4) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def progress_line(row: dict) -> str:
    """The line printed when a job finishes."""
    if row["status"] != "ok":
        return f"FAILED {row['name']}: {row['error']}"
    if row["reused"]:
        return f"ok     {row['name']}: unchanged since its last run, not run again (--force runs it)"
    return (f"ok     {row['name']}: {row['points']:,d} points, machining time {_hms(row['machining_time_s'])}, "
            f"{row['collisions'] if row['collisions'] is not None else '-'} collisions, scallop "
            f"{_mm(row['max_scallop'])} of {row['scallop']:g} mm ({row['wall_s']:.1f} s)")


def summary_table(rows: list) -> str:
    """The table printed at the end of a batch."""
    head = ("job", "status", "points", "machining time", "collisions", "scallop limit", "scallop measured",
            "wall (s)")
    body = [(r["name"], r["status"] + (" (unchanged)" if r["reused"] else ""),
             "-" if r["points"] is None else f"{r['points']:,d}", _hms(r["machining_time_s"]),
             "-" if r["collisions"] is None else str(r["collisions"] + (r["gouges"] or 0)),
             _mm(r["scallop"]), _mm(r["max_scallop"]), f"{r['wall_s']:.1f}") for r in rows]
    w = [max(len(x[k]) for x in [head] + body) for k in range(len(head))]
    lines = ["  ".join(c.ljust(wk) if k < 2 else c.rjust(wk) for k, (c, wk) in enumerate(zip(x, w)))
             for x in [head] + body]
    for r in rows:
        if r["status"] != "ok":
            lines.append(f"{r['name']}: {r['error']}")
    return "\n".join(lines)


# -- command line ---------------------------------------------------------------------------
def _cmd_batch(args) -> int:
    try:
        rows = run_batch(args.jobs, args.out, workers=args.workers, force=args.force, scheduler=args.scheduler)
    except KeyboardInterrupt:
        print("stopped", file=sys.stderr)
        return 130
    return 0 if all(r["status"] == "ok" for r in rows) else 1


def register(subparsers) -> None:
    """Add ``batch`` to the tsplcam command line."""
    p = subparsers.add_parser(
        "batch", help="run many job files at once, in parallel processes or on a Dask cluster",
        description="Runs each job file (tsplcam/JOBFILE.md) as `job` would, into DIR/<job file name>/, in "
                    "parallel processes (or on a Dask cluster with --scheduler); prints a line per finished job "
                    "and a table, writes DIR/summary.json. Jobs whose settings and input files did not change "
                    "since their last good run are not run again. Exit code 0 all ok, 1 some job failed, 2 the "
                    "batch itself refused (one line naming the option or file).")
    p.add_argument("jobs", nargs="+", metavar="JOB.json", help="job files")
    p.add_argument("--out", default="tsplcam-batch", metavar="DIR",
                   help="folder for the jobs' folders and summary.json (default tsplcam-batch)")
    p.add_argument("--workers", type=int, metavar="N", default=None,
                   help="jobs at a time, one process each (default: the number of cores)")
    p.add_argument("--force", action="store_true", help="run every job, also the unchanged ones")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", default=None,
                   help="run the jobs on this Dask distributed scheduler's workers (shared folders: README)")
    p.set_defaults(func=_cmd_batch)
