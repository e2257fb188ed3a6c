"""Job runs that several test files share, made once per test process.

The main job through the command line (:data:`MAIN_JOB`: the keycap with the default machine
and strategy, coarse, with the surface verification, the baseline and the HTML report) takes
about 12 s of CPU, most of it the report's pictures. tests/test_pipeline.py (MainJob: the
files and the page) and tests/test_cli.py (Determinism: the same bytes from another process)
both need it, so :func:`main_job` runs it once, on first use, in a folder kept until the
process ends. Its files are the tests' to read, not to change. Tests that need other options
keep their own runs.

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
#: the shared run's PYTHONHASHSEED and TSPLCAM_WORKERS (one process: the orientation stage
#: builds the collision checker); tests/test_cli.py runs the same command with other values
MAIN_JOB_SEED, MAIN_JOB_WORKERS = 0, 1


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
