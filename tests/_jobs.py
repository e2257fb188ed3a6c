"""Job runs and checks that several test files share; the runs made once per test process.

The main job through the command line (:data:`MAIN_JOB`: the keycap with the default machine
and strategy, coarse, with the surface verification, the baseline and the HTML report) takes
6-8 s of CPU, most of it the report's pictures and clearance. tests/test_pipeline.py (MainJob:
the files and the page) and tests/test_batch.py (the same job as a job file through `batch`,
in a process with another PYTHONHASHSEED and worker count: the same bytes) both need it, so
:func:`main_job` runs it once, on first use, in a folder kept until the process ends. Its
files are the tests' to read, not to change. Tests that need other options keep their own
runs.

Not a test file (no ``test_`` prefix): pytest and ``freecadcmd -t TestTsplcam`` do not load
it as one; test files import it as ``from _jobs import ...`` (``tests/`` is on ``sys.path``).
"""
from __future__ import annotations

import atexit
import os
import shutil
import subprocess
import tempfile
import threading
from dataclasses import dataclass

from conftest import REPO_DIR

SYSTEM_PYTHON = "/usr/bin/python3"

#: the main job's command line; ``--out`` relative to the run's own folder, two folders to make
MAIN_JOB = ("job", "keycap", "--out", os.path.join("new", "job"), "--scallop", "0.2", "--chord-tol", "0.01",
            "--baseline")
#: the same job as a job file (tsplcam/JOBFILE.md; tests/test_batch.py runs it through `batch`)
MAIN_JOB_FILE = {"model": "keycap", "scallop": 0.2, "chord_tol": 0.01, "baseline": True}
#: the shared run's PYTHONHASHSEED and TSPLCAM_WORKERS (two path workers: the main process
#: builds the collision checker meanwhile); tests/test_batch.py runs the job with other values
MAIN_JOB_SEED, MAIN_JOB_WORKERS = 0, 2


def tsplcam_env(seed: int | None = None, workers: int | None = None) -> dict:
    """The environment of ``python3 -m tsplcam`` as a user runs it from the checkout:
    PYTHONPATH the checkout only; ``seed``: PYTHONHASHSEED, ``workers``: TSPLCAM_WORKERS,
    when given."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = REPO_DIR
    if seed is not None:
        env["PYTHONHASHSEED"] = str(seed)
    if workers is not None:
        env["TSPLCAM_WORKERS"] = str(workers)
    return env


def run_tsplcam(argv, cwd: str, seed: int | None = None, workers: int | None = None,
                timeout: float = 900) -> subprocess.CompletedProcess:
    """``/usr/bin/python3 -m tsplcam ARGV`` in ``cwd`` (text output captured)."""
    return subprocess.run([SYSTEM_PYTHON, "-m", "tsplcam", *argv], cwd=cwd, env=tsplcam_env(seed, workers),
                          capture_output=True, text=True, timeout=timeout)


@dataclass(frozen=True)
class JobRun:
    """A finished run: its command line, the folder it ran in, its output folder (absolute)
    and the finished process (exit code, stdout, stderr)."""
    argv: tuple
    cwd: str
    out: str
    res: subprocess.CompletedProcess


_LOCK = threading.Lock()
_RUNS: dict = {}


def main_job() -> JobRun:
    """:data:`MAIN_JOB` with PYTHONHASHSEED :data:`MAIN_JOB_SEED` and :data:`MAIN_JOB_WORKERS`
    worker, run on the first call (in a folder removed when the process ends) and handed out
    as it finished on every later one; thread-safe (a caller waits for a run under way)."""
    with _LOCK:
        if "main" not in _RUNS:
            if not os.path.exists(SYSTEM_PYTHON):
                import unittest
                raise unittest.SkipTest(f"no {SYSTEM_PYTHON}")
            # the real path: the job prints its report's absolute path, made from its own cwd
            folder = os.path.realpath(tempfile.mkdtemp(prefix="tsplcam-main-job-"))
            atexit.register(shutil.rmtree, folder, ignore_errors=True)
            res = run_tsplcam(MAIN_JOB, folder, seed=MAIN_JOB_SEED, workers=MAIN_JOB_WORKERS)
            _RUNS["main"] = JobRun(MAIN_JOB, folder, os.path.join(folder, MAIN_JOB[3]), res)
        return _RUNS["main"]


def assert_same_files(test, a: str, b: str, names: list, report: str | None, also_in_b=()) -> None:
    """Folders ``a`` and ``b`` hold exactly the files ``names`` (sorted; a folder among them,
    the report's pictures, compared file by file) with the same bytes, except ``report``: a
    report.json whose ``timing`` blocks may differ (the same keys, non-negative floats) and
    whose rest is the same, byte for byte, written out sorted. ``also_in_b``: files ``b``
    holds besides (a batch's record), not compared."""
    import json
    test.assertEqual(sorted(os.listdir(a)), names)
    test.assertEqual(sorted(os.listdir(b)), sorted([*names, *also_in_b]))
    for name in names:
        if os.path.isdir(os.path.join(a, name)):         # the report's pictures
            inner = sorted(os.listdir(os.path.join(a, name)))
            test.assertGreater(len(inner), 0, name)
            assert_same_files(test, os.path.join(a, name), os.path.join(b, name), inner, None)
            continue
        with open(os.path.join(a, name), "rb") as fa, open(os.path.join(b, name), "rb") as fb:
            da, db = fa.read(), fb.read()
        if name != report:
            test.assertEqual(da, db, name)
            continue
        ra, rb = json.loads(da), json.loads(db)
        ta, tb = ra.pop("timing"), rb.pop("timing")
        test.assertEqual(set(ta), set(tb))
        test.assertTrue(all(isinstance(v, float) and v >= 0 for v in ta.values()), ta)
        # the run times live in the timing block only; the rest is the same, byte for byte
        test.assertNotIn("seconds", json.dumps(ra))
        test.assertEqual(json.dumps(ra, indent=2, sort_keys=True), json.dumps(rb, indent=2, sort_keys=True))


def keep_for_a_look(name: str, folders: dict) -> str:
    """Copy folders (label -> folder) to the artifact folder ``name`` after a failure; its path."""
    from conftest import artifact_path
    keep = artifact_path(name)
    shutil.rmtree(keep, ignore_errors=True)
    for label, folder in folders.items():
        shutil.copytree(folder, os.path.join(keep, label))
    return keep
