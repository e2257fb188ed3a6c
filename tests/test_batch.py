"""`batch`: job files in parallel processes, one failing without stopping the others, a
summary whose figures are the jobs' own, reruns that skip unchanged jobs, and the same
results from a Dask cluster (an in-process LocalCluster) as from the local run."""
import json
import os
import re
import shutil
import socket
import subprocess
import tempfile
import time
import unittest

from conftest import REPO_DIR
from _jobs import MAIN_JOB_FILE, MAIN_JOB_SEED, MAIN_JOB_WORKERS, assert_same_files, keep_for_a_look, main_job
from tsplcam.errors import InputError
from tsplcam.model.samples import sample_path

PY = "/usr/bin/python3"
COARSE = {"scallop": 0.2, "chord_tol": 0.01, "max_step": 2.0}
JOBS = {
    # the main job of tests/_jobs.py as a job file: the main machine and strategy, the surface
    # verification, the baseline and the report (compared with the job's command line)
    "cap_heidenhain": dict(MAIN_JOB_FILE),
    # another machine, closest axes, no report; the model a file beside the job file
    "cap_linuxcnc": dict(model="parts/cap.obj", machine="linuxcnc_xyzac_trt", orientation="closest",
                         verify=False, html_report=False, **COARSE),
    # the surface verification without the report: the job the Dask test runs with a measured scallop
    "mold_fanuc": dict(model="keycap_mold", machine="bc_head_table_sinumerik", dialect="fanuc",
                       orientation="closest", verify=True, html_report=False, name="cavity", **COARSE),
    # refused when read: a bad value
    "broken": dict(model="keycap", scallop="fine"),
    # fails in the work: the cavity is tighter than a 1 mm ball
    "too_big": dict(model="keycap_mold", tool=None, tool_radius=1.0, orientation="normal", scallop=0.05),
}
OK = ("cap_heidenhain", "cap_linuxcnc", "mold_fanuc")
#: the batch's PYTHONHASHSEED and engine workers (one process per job): other than the main
#: job's shared run (tests/_jobs.py), so that their comparison covers both
BATCH_SEED, BATCH_WORKERS = 4242, 1


def tsplcam(*args, cwd=None, env=None):
    env = dict(os.environ, PYTHONPATH=REPO_DIR, **(env or {}))
    return subprocess.run([PY, "-m", "tsplcam", *args], capture_output=True, text=True, env=env,
                          cwd=cwd or REPO_DIR, timeout=600)


def batch_here(*args):
    """``batch ARGS`` through the command line's entry point in this process (the job
    processes start fresh all the same): (exit code, stdout)."""
    import contextlib
    import io
    from tsplcam.cli import main
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["batch", *args])
    return code, out.getvalue()


def by_name(rows):
    return {r["name"]: r for r in rows}


class Batch(unittest.TestCase):
    maxDiff = None                   # (a failure shows every line that differs)

    @classmethod
    def setUpClass(cls):
        cls.root = tempfile.mkdtemp(prefix="tsplcam-batch-")
        os.makedirs(os.path.join(cls.root, "jobs", "parts"))
        shutil.copy(sample_path("keycap"), os.path.join(cls.root, "jobs", "parts", "cap.obj"))
        cls.files = []
        for name, data in JOBS.items():
            path = os.path.join(cls.root, "jobs", name + ".json")
            with open(path, "w") as fh:
                json.dump(data, fh)
            cls.files.append(path)
        cls.out = os.path.join(cls.root, "out")
        t = time.perf_counter()
        cls.res = tsplcam("batch", *cls.files, "--workers", "2", "--out", cls.out,
                          env={"PYTHONHASHSEED": str(BATCH_SEED), "TSPLCAM_WORKERS": str(BATCH_WORKERS)})
        cls.wall = time.perf_counter() - t
        with open(os.path.join(cls.out, "summary.json")) as fh:
            cls.rows = json.load(fh)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.root, ignore_errors=True)

    def report(self, name, out=None):
        with open(os.path.join(out or self.out, name, "report.json")) as fh:
            return json.load(fh)

    def test_one_failure_does_not_stop_the_others(self):
        self.assertEqual(self.res.returncode, 1, self.res.stderr)     # some failed
        self.assertEqual([r["job"] for r in self.rows], self.files)   # in the order given
        rows = by_name(self.rows)
        for name in OK:
            self.assertEqual(rows[name]["status"], "ok", rows[name]["error"])
            self.assertIsNone(rows[name]["error"])
        broken, too_big = rows["broken"], rows["too_big"]
        self.assertEqual((broken["status"], too_big["status"]), ("failed", "failed"))
        self.assertIn("broken.json: scallop: must be a finite number", broken["error"])
        self.assertIn("concave radius of curvature", too_big["error"])
        self.assertFalse(os.path.exists(os.path.join(self.out, "broken")))
        self.assertFalse(os.path.exists(os.path.join(self.out, "too_big")))    # a failed job leaves no file
        # a line per job as it finished, then the table with every job and the errors
        done = re.findall(r"^\[(\d)/5\] (ok|FAILED) +(\w+)", self.res.stdout, flags=re.M)
        self.assertEqual(sorted(n for _, _, n in done), sorted(JOBS))
        self.assertEqual([int(i) for i, _, _ in done], [1, 2, 3, 4, 5])
        table = self.res.stdout[self.res.stdout.index("\njob "):]
        for name in JOBS:
            self.assertRegex(table, rf"(?m)^{name} +(ok|failed) ")
        self.assertIn("too_big: patch", table)
        self.assertIn("3 ok", self.res.stdout)

    def test_figures_are_the_jobs_own(self):
        for name in OK:
            row, rep = by_name(self.rows)[name], self.report(name)
            self.assertEqual(row["points"], rep["path"]["points"])
            self.assertEqual(row["retractions"], rep["path"]["retractions"])
            self.assertEqual(row["collisions"], rep["orientation"]["collisions"])
            self.assertEqual(row["collisions"], 0)
            self.assertAlmostEqual(row["machining_time_s"], rep["machining_time_s"], delta=1e-9)
            self.assertEqual(row["scallop"], 0.2)
            self.assertTrue(os.path.isfile(os.path.join(self.out, name, row["program"])), row["program"])
            self.assertGreater(row["wall_s"], 0.0)
        rows = by_name(self.rows)
        # measured only where the job asked for it; the scallop kept under the limit
        for name in ("cap_heidenhain", "mold_fanuc"):
            self.assertLessEqual(rows[name]["max_scallop"], 0.2 * (1 + 1e-9), name)
            self.assertGreater(rows[name]["max_scallop"], 0.1, name)
        self.assertIsNone(rows["cap_linuxcnc"]["max_scallop"])
        self.assertEqual(rows["mold_fanuc"]["program"], "cavity.nc")
        self.assertEqual(rows["cap_linuxcnc"]["program"], "cap.ngc")
        self.assertTrue(os.path.isfile(os.path.join(self.out, "cap_heidenhain", "report.html")))
        self.assertFalse(os.path.exists(os.path.join(self.out, "cap_linuxcnc", "report.html")))

    def test_a_batch_job_is_the_job_command(self):
        """The main job's command line (tests/_jobs.py, run once for the test process:
        PYTHONHASHSEED 0, two path workers, the collision checker built meanwhile) and its job
        file here (PYTHONHASHSEED 4242, one process per job, the batch's one BLAS thread): the
        same program, CL data and processing list, report.html and its pictures, and
        report.json apart from its timing block, byte for byte. This is also the job's check
        that its bytes depend neither on the hash seed nor on the workers (tests/test_cli.py,
        Determinism, checks the path command so)."""
        self.assertNotEqual((MAIN_JOB_SEED, MAIN_JOB_WORKERS), (BATCH_SEED, BATCH_WORKERS))
        self.assertEqual((MAIN_JOB_SEED, MAIN_JOB_WORKERS), (0, 2))
        job = main_job()
        self.assertEqual(job.res.returncode, 0, job.res.stderr)
        self.assertIn("collision checker built meanwhile", job.res.stdout)
        here = os.path.join(self.out, "cap_heidenhain")
        try:
            assert_same_files(self, job.out, here, ["keycap.cl", "keycap.h", "processing-list.json", "report.html",
                                                    "report.json", "report_files"], "report.json",
                              also_in_b=("batch.json",))
        except AssertionError:         # keep both runs' files for a look
            keep_for_a_look("batch-job-failure", {"job-command": job.out, "batch": here})
            raise

    def test_rerun_skips_unchanged_jobs(self):
        """Three reruns through the command line's entry point in this process (setUpClass
        and the next test run `batch` as a process of its own)."""
        before = {n: os.path.getmtime(os.path.join(self.out, n, "report.json")) for n in OK}
        code, stdout = batch_here(*self.files, "--out", self.out)
        self.assertEqual(code, 1)
        with open(os.path.join(self.out, "summary.json")) as fh:
            rows = by_name(json.load(fh))
        for name in OK:
            self.assertTrue(rows[name]["reused"], name)
            self.assertEqual(rows[name]["points"], by_name(self.rows)[name]["points"])
            self.assertEqual(os.path.getmtime(os.path.join(self.out, name, "report.json")), before[name])
        self.assertEqual(rows["too_big"]["status"], "failed")        # failures are tried again
        self.assertFalse(rows["too_big"]["reused"])
        self.assertIn("not run again", stdout)
        # a changed input file runs its job again, and only that one
        with open(os.path.join(self.root, "jobs", "parts", "cap.obj"), "a") as fh:
            fh.write("# edited\n")
        code, stdout = batch_here(*self.files[:3], "--out", self.out)
        self.assertEqual(code, 0, stdout)
        rows = by_name(json.load(open(os.path.join(self.out, "summary.json"))))
        self.assertEqual({n: rows[n]["reused"] for n in OK},
                         {"cap_heidenhain": True, "cap_linuxcnc": False, "mold_fanuc": True})
        # --force runs an unchanged job again (the quickest one)
        code, stdout = batch_here(self.files[1], "--out", self.out, "--force")
        self.assertEqual(code, 0, stdout)
        rows = json.load(open(os.path.join(self.out, "summary.json")))
        self.assertEqual([(r["name"], r["reused"]) for r in rows], [("cap_linuxcnc", False)])

    def test_job_files_of_one_name_are_refused(self):
        other = os.path.join(self.root, "other")
        os.makedirs(other)
        twin = os.path.join(other, "cap_linuxcnc.json")
        shutil.copy(self.files[1], twin)
        res = tsplcam("batch", self.files[1], twin, "--out", os.path.join(self.root, "twins"))
        self.assertEqual(res.returncode, 2)
        self.assertEqual(len(res.stderr.strip().split("\n")), 1, res.stderr)
        self.assertIn("cap_linuxcnc", res.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.root, "twins")))

    def test_dask_cluster_gives_the_local_results(self):
        """The same jobs on a two-worker LocalCluster: the same rows, program, CL data and
        report.json (its timing block apart). The jobs: one without and one with the surface
        verification (its measured scallop comes back through Dask too) and one refused when
        read; not the job with the HTML report, whose pictures (most of its time, and not
        compared here) would double the test."""
        import numpy
        from distributed import LocalCluster
        from tsplcam.batch import run_batch
        self.assertTrue(numpy.__file__.startswith("/usr/lib/python3/dist-packages/"), numpy.__file__)
        out = os.path.join(self.root, "dask")
        t = time.perf_counter()
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            t_cluster = time.perf_counter() - t
            rows = run_batch(self.files[1:4], out, scheduler=cluster.scheduler_address, log=None)
        print(f"\nDask: cluster up in {t_cluster:.1f} s, batch {time.perf_counter() - t:.1f} s "
              f"(local batch of {len(self.files)} jobs, 2 workers: {self.wall:.1f} s)")
        local = by_name(self.rows)
        self.assertEqual([r["name"] for r in rows], ["cap_linuxcnc", "mold_fanuc", "broken"])
        self.assertIsNotNone(local["mold_fanuc"]["max_scallop"])
        for row in rows:
            ref = local[row["name"]]
            self.assertEqual(row["status"], ref["status"], row["error"])
            self.assertEqual(row["error"], ref["error"])
            for key in ("points", "collisions", "gouges", "retractions", "scallop", "program"):
                self.assertEqual(row[key], ref[key], (row["name"], key))
            for key in ("machining_time_s", "max_scallop", "min_clearance"):
                if ref[key] is None:
                    self.assertIsNone(row[key])
                else:                                    # the same run: equal to the last bit in practice
                    self.assertAlmostEqual(row[key], ref[key], delta=1e-9 * max(1.0, abs(ref[key])))
        for name in OK[1:]:
            program = local[name]["program"]
            for f in (program, os.path.splitext(program)[0] + ".cl"):
                with open(os.path.join(self.out, name, f), "rb") as a, open(os.path.join(out, name, f), "rb") as b:
                    self.assertEqual(a.read(), b.read(), f"{name}/{f}")
            a, b = self.report(name), self.report(name, out)
            a.pop("timing"), b.pop("timing")
            self.assert_same_figures(a, b, name)

    def assert_same_figures(self, a, b, where):
        """The same document: keys, counts, names and flags equal, floats within 1e-9 relative
        (orientation metrics have been seen to move in the 13th digit between runs)."""
        if isinstance(a, dict):
            self.assertEqual(sorted(a), sorted(b), where)
            for k in a:
                self.assert_same_figures(a[k], b[k], f"{where}/{k}")
        elif isinstance(a, list):
            self.assertEqual(len(a), len(b), where)
            for i, (x, y) in enumerate(zip(a, b)):
                self.assert_same_figures(x, y, f"{where}[{i}]")
        elif isinstance(a, float):
            self.assertAlmostEqual(a, b, delta=1e-9 * max(1.0, abs(a)), msg=where)
        else:
            self.assertEqual(a, b, where)

    def test_no_scheduler_is_refused(self):
        from tsplcam.batch import prepare, run_dask
        with socket.socket() as s:                      # a port nothing listens on
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        spec = prepare(self.files[1], os.path.join(self.root, "nowhere"))
        with self.assertRaises(InputError) as cm:
            run_dask([spec], f"tcp://127.0.0.1:{port}", lambda row: None, timeout="1s")
        self.assertEqual(cm.exception.item, "--scheduler")
        self.assertIn(str(port), str(cm.exception))


class Install(unittest.TestCase):
    def test_distributed_pinned_beside_debian_numpy(self):
        """scripts/install.sh pins distributed and dask; they import in the system Python and
        numpy stays Debian's."""
        import importlib.metadata as md
        import numpy
        with open(os.path.join(REPO_DIR, "scripts", "install.sh")) as fh:
            text = fh.read()
        pins = dict(re.findall(r'"(distributed|dask)==([\w.]+):', text))
        self.assertEqual(sorted(pins), ["dask", "distributed"])
        import distributed
        self.assertEqual(md.version("distributed"), pins["distributed"])
        self.assertEqual(md.version("dask"), pins["dask"])
        self.assertTrue(distributed.__file__)
        self.assertTrue(numpy.__file__.startswith("/usr/lib/python3/dist-packages/"), numpy.__file__)


if __name__ == "__main__":
    unittest.main()
