"""The whole job through the command line: path -> tool axes -> program, and the main job;
the job, the `path` command and the program builder give the same program for the same
settings."""
import json
import os
import subprocess
import tempfile
import unittest

import numpy as np

from conftest import REPO_DIR, needs_freecad
from _jobs import main_job

PY = "/usr/bin/python3"


def run(*args, cwd=None):
    env = dict(os.environ, PYTHONPATH=REPO_DIR)
    return subprocess.run([PY, "-m", "tsplcam", *args], capture_output=True, text=True, env=env,
                          cwd=cwd or REPO_DIR, timeout=900)


def run_here(*args):
    """``tsplcam.cli.main(args)`` in this process: (returncode, stdout, stderr) as ``run``'s
    CompletedProcess has them."""
    import contextlib
    import io
    from types import SimpleNamespace
    from tsplcam.cli import main
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(args))
        except SystemExit as exc:             # argparse refusals
            code = exc.code
    return SimpleNamespace(returncode=code, stdout=out.getvalue(), stderr=err.getvalue())


class PathCommand(unittest.TestCase):
    def test_keycap_to_linuxcnc_program_that_rs274_runs(self):
        from tsplcam.post import load_machine, rs274
        from tsplcam.post.kinematics import forward
        from tsplcam.toolpath.cldata import read_cl
        with tempfile.TemporaryDirectory() as tmp:
            ngc, cl, js = (os.path.join(tmp, n) for n in ("k.ngc", "k.cl", "k.json"))
            res = run("path", "keycap", "--tool-radius", "0.5", "--scallop", "0.05", "--tool", "ball1_keycap",
                      "--orientation", "smooth", "--machine", "linuxcnc_xyzac_trt", "--gcode", ngc,
                      "--cl", cl, "--json", js)
            self.assertEqual(res.returncode, 0, res.stderr)
            report = json.load(open(js))
            self.assertEqual(report["path"]["metrics"]["retractions"], 0)
            self.assertEqual(report["orientation"]["collisions"], 0)
            self.assertGreaterEqual(report["orientation"]["min_clearance"], 0.3 - 1e-6)
            self.assertGreater(report["machining_time_s"], 0)
            if rs274.executable() is None:
                self.skipTest("rs274 (linuxcnc-uspace) not installed")
            out = rs274.run(open(ngc).read())
            self.assertEqual(out.returncode, 0)
            self.assertEqual(out.errors, "")
            # every CL point (tip and axis) is one of the program's moves as LinuxCNC reads
            # them, through the machine's forward kinematics (docs/post.md section 1)
            from scipy.spatial import cKDTree
            machine = load_machine("linuxcnc_xyzac_trt")
            joints = out.precise[:, [0, 1, 2, 3, 5]]
            tips, axes = forward(machine, joints)
            cldata = read_cl(cl).to_toolpath()
            d, idx = cKDTree(tips).query(cldata.tip, k=3)
            self.assertLess(d[:, 0].max(), 1e-3, "a CL tip missing from the program (mm)")
            # CL points a hair apart (a line's end and the next line's start) may swap: of the
            # program's moves at the tip, the one with the CL point's axis
            angle = np.arctan2(np.linalg.norm(np.cross(axes[idx], cldata.axis[:, None]), axis=2),
                               np.einsum("nki,ni->nk", axes[idx], cldata.axis))
            angle = np.where(d < 1e-3, angle, np.inf).min(axis=1)
            # near the pole of the A/C table (axis along C = +Z here) the post holds C and
            # interpolates (docs/post.md section 4): there the axis may move by up to the cone
            cone = np.radians(0.5)
            near_pole = np.arccos(np.clip(cldata.axis[:, 2], -1, 1)) < cone
            self.assertLess(angle[~near_pole].max(), 2e-6, "tool axis off (rad)")
            if near_pole.any():
                self.assertLessEqual(angle[near_pole].max(), cone + 1e-9)

    def test_bad_arguments_exit_2_with_a_message(self):
        """The first in a process of its own, as the shell sees it; the others through the
        same entry point in this process (tests/test_cli.py runs every refusal so)."""
        res = run("path", "keycap", "--tool-radius", "0.5", "--scallop", "0.05", "--gcode", "/tmp/x.ngc")
        self.assertEqual(res.returncode, 2)
        self.assertIn("--gcode: needs --machine", res.stderr)
        res = run_here("path", "keycap", "--tool-radius", "0.5", "--scallop", "0.05", "--orientation", "smooth")
        self.assertEqual(res.returncode, 2)
        self.assertIn("needs a tool", res.stderr)
        res = run_here("path", "keycap", "--tool-radius", "0.7", "--scallop", "0.05", "--tool", "ball1_keycap",
                       "--orientation", "smooth")
        self.assertEqual(res.returncode, 2)
        self.assertIn("differs from the ball radius", res.stderr)
        res = run_here("path", "no_such_model.obj", "--tool-radius", "0.5", "--scallop", "0.05")
        self.assertEqual(res.returncode, 2)
        self.assertIn("no_such_model.obj", res.stderr)


def html_tables(text: str) -> dict:
    """Tables of report.html by id: rows of cell texts (tags stripped, entities unescaped)."""
    import html
    import re
    out = {}
    for ident, body in re.findall(r'<table[^>]*id="([^"]+)"[^>]*>(.*?)</table>', text, flags=re.S):
        out[ident] = [[html.unescape(re.sub(r"<[^>]+>", "", c)).strip()
                       for c in re.findall(r"<t[hd][^>]*>(.*?)</t[hd]>", row, flags=re.S)]
                      for row in re.findall(r"<tr>(.*?)</tr>", body, flags=re.S)]
    return out


def number(text: str) -> float:
    return float(text.replace(",", ""))


class MainJob(unittest.TestCase):
    """`job MODEL --out DIR` writes the program, CL data, processing list, report.json and
    report.html with its pictures; the page carries report.json's measured figures. The run
    is tests/_jobs.py's main job (`job keycap --out new/job --scallop 0.2 --chord-tol 0.01
    --baseline`: two folders to make), made once for the test process and shared with
    tests/test_cli.py (read only)."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="tsplcam-job-")
        job = main_job()
        cls.out, cls.res = job.out, job.res

    @classmethod
    def tearDownClass(cls):
        import shutil
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_files_program_and_figures(self):
        self.assertEqual(self.res.returncode, 0, self.res.stderr)
        self.assertEqual(sorted(os.listdir(self.out)), ["keycap.cl", "keycap.h", "processing-list.json",
                                                        "report.html", "report.json", "report_files"])
        report = json.load(open(os.path.join(self.out, "report.json")))
        self.assertEqual(report["path"]["retractions"], 0)
        self.assertEqual(report["orientation"]["collisions"], 0)
        self.assertEqual(report["files"], {"program": "keycap.h", "cl": "keycap.cl"})
        self.assertNotIn("out", report["settings"])          # the report does not depend on where it is
        program = open(os.path.join(self.out, "keycap.h")).read()
        self.assertTrue(program.startswith("0 BEGIN PGM"))
        self.assertIn("FUNCTION TCPM", program)
        self.assertIn("machining time", self.res.stdout)
        # the scallop measured on the surface stays under the limit, and not far under it
        v = report["verification"]
        self.assertLessEqual(v["max_scallop"], 0.2 * (1 + 1e-9))
        self.assertGreater(v["max_scallop"], 0.8 * 0.2)
        self.assertLess(v["gouge_points"], 1e-6)
        # the baseline retracts between faces, the T-spline path does not
        self.assertGreater(report["baseline"]["path"]["retractions"], 0)
        timing = report["timing"]
        for k in ("model_s", "path_s", "orientation_s", "post_s", "verify_s", "baseline_s", "report_s", "total_s"):
            self.assertGreater(timing[k], 0.0, k)
        parts = sum(v for k, v in timing.items() if k != "total_s")
        self.assertLessEqual(parts, timing["total_s"] * (1 + 1e-6))

    def test_report_page_carries_the_figures(self):
        self.assertEqual(self.res.returncode, 0, self.res.stderr)
        page = os.path.join(self.out, "report.html")
        self.assertIn(f"report: {os.path.abspath(page)}", self.res.stdout)
        report = json.load(open(os.path.join(self.out, "report.json")))
        text = open(page, encoding="utf-8").read()
        pictures = sorted(os.listdir(os.path.join(self.out, "report_files")))
        self.assertEqual(pictures, sorted(f"{n}.png" for n in ("layout", "path", "scallop", "axis", "machine",
                                                               "clearance", "time", "baseline")))
        for name in pictures:
            self.assertIn(f'src="report_files/{name}"', text)
            with open(os.path.join(self.out, "report_files", name), "rb") as fh:
                self.assertEqual(fh.read(8), b"\x89PNG\r\n\x1a\n", name)
        tables = html_tables(text)
        kv = {r[0]: r[1] for r in tables["scallop-figures"] if len(r) == 2}
        self.assertAlmostEqual(number(kv["largest scallop (µm)"]), report["verification"]["max_scallop"] * 1000,
                               delta=5e-4)
        self.assertEqual(number(kv["surface samples"]), report["verification"]["samples"])
        kv = {r[0]: r[1] for r in tables["path-figures"] if len(r) == 2}
        self.assertEqual(number(kv["points"]), report["path"]["points"])
        baseline = {r[0]: r[1:] for r in tables["baseline"][1:]}
        self.assertEqual(number(baseline["retractions"][1]), report["baseline"]["path"]["retractions"])
        settings = {r[0]: r[1] for r in tables["job-settings"]}
        self.assertEqual(settings["scallop"], "0.2")
        self.assertEqual(settings["baseline"], "True")
        clearance = {r[0]: number(r[1]) for r in tables["clearance"][1:]}
        self.assertGreaterEqual(min(clearance.values()), 0.3 - 0.01)      # the holder clearance kept
        # a bar per stage on stderr, the verification and report among them
        for stage in ("path", "tool axes", "program", "scallop", "baseline", "baseline axes", "report"):
            self.assertRegex(self.res.stderr, rf"(?m)^{stage} +\[#+\] 100 %")
        self.assertEqual([n for n in os.listdir(self.out) if n.startswith(".")], [])   # no draft left

    def test_without_report_or_verification(self):
        from tsplcam.job import run_job
        from tsplcam.settings import JobSettings
        with tempfile.TemporaryDirectory() as tmp:
            figures = run_job(JobSettings(out=tmp, scallop=0.2, chord_tol=0.01, orientation="normal",
                                          html_report=False, verify=False), log=None,
                              progress=lambda stage, done, total: None)
            self.assertEqual(sorted(os.listdir(tmp)), ["keycap.cl", "keycap.h", "processing-list.json",
                                                       "report.json"])
            self.assertNotIn("verification", figures)
            self.assertNotIn("verify_s", figures["timing"])
            self.assertNotIn("report_s", figures["timing"])

    def test_a_failed_report_leaves_no_file(self):
        """The report is drawn before any file is written: when it fails, the folders the
        job made are gone and an existing folder keeps what it had."""
        from unittest import mock
        from tsplcam.errors import InputError
        from tsplcam.job import run_job
        from tsplcam.settings import JobSettings
        with tempfile.TemporaryDirectory() as tmp:
            with open(os.path.join(tmp, "keep.txt"), "w") as fh:
                fh.write("x")
            for out in (os.path.join(tmp, "a", "b"), tmp):
                with mock.patch("tsplcam.report.write_report", side_effect=InputError("disk full")):
                    with self.assertRaises(InputError):
                        run_job(JobSettings(out=out, scallop=0.3, chord_tol=0.02, orientation="normal", verify=False),
                                log=None, progress=lambda stage, done, total: None)
                self.assertEqual(sorted(os.listdir(tmp)), ["keep.txt"])

    def test_model_given_twice(self):
        res = run("job", "keycap", "--model", "head", "--out", os.path.join(self.tmp, "twice"))
        self.assertEqual(res.returncode, 2)
        self.assertIn("--model", res.stderr)
        self.assertIn("twice", res.stderr)
        self.assertEqual(len(res.stderr.strip().split("\n")), 1, res.stderr)


class OneProgramBuilder(unittest.TestCase):
    """Fast settings (a coarse path on the keycap): the main job's program and the `path`
    command's program are the same bytes, both made by tsplcam.program.make_program (the
    workbench's program object is compared with the job in
    tests/workbench/test_workbench_program.py). The job runs without the surface
    verification and the HTML report: both come after the program and change none of its
    bytes (measured once: the same program and CL data with and without them)."""

    def test_job_and_path_command_agree(self):
        import contextlib
        import io
        from tsplcam.cli import main
        from tsplcam.job import run_job
        from tsplcam.settings import JobSettings
        options = dict(scallop=0.2, chord_tol=0.01, max_step=2.0, feed=800.0, holder_clearance=0.25,
                       smoothing_length=4.0, machine="bc_head_table_sinumerik", dialect="fanuc")
        with tempfile.TemporaryDirectory() as tmp:
            figures = run_job(JobSettings(out=os.path.join(tmp, "job"), verify=False, html_report=False, **options),
                              log=lambda *a: None, progress=lambda stage, done, total: None)
            with open(os.path.join(tmp, "job", "keycap.nc"), "rb") as fh:
                job_program = fh.read()
            with open(os.path.join(tmp, "job", "keycap.cl"), "rb") as fh:
                job_cl = fh.read()
            argv = ["path", "keycap", "--tool-radius", "0.5", "--tool", "ball1_keycap", "--orientation", "smooth",
                    "--gcode", os.path.join(tmp, "path.nc"), "--cl", os.path.join(tmp, "path.cl")]
            for k, v in options.items():
                argv += ["--" + k.replace("_", "-"), str(v)]
            err = io.StringIO()
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
                self.assertEqual(main(argv), 0, err.getvalue())
            with open(os.path.join(tmp, "path.nc"), "rb") as fh:
                self.assertEqual(fh.read(), job_program)
            # (both CL texts made while the forked process measured the axes' clearance; their
            # comments and PARTNO name the model as each was given: keycap.obj, keycap)
            with open(os.path.join(tmp, "path.cl"), "rb") as fh:
                path_cl = fh.read()
            body = [[ln for ln in t.splitlines() if not ln.startswith((b"$$", b"PARTNO"))] for t in (path_cl, job_cl)]
            self.assertGreater(len(body[0]), 1000)
            self.assertEqual(body[0], body[1])
        self.assertEqual(figures["orientation"]["collisions"], 0)
        self.assertGreaterEqual(figures["orientation"]["min_clearance"], 0.25 - 1e-6)
        self.assertIn(b"G43.4", job_program)             # Fanuc's tool centre point control
        self.assertEqual(figures["settings"]["feed"], 800.0)   # the value given, not computed
        # the forced C travel, left by the orientation for that wait, is there
        self.assertIsNotNone(figures["machine_motion"].get("c_travel_forced_deg"))


@needs_freecad
class JobUnderFreecadcmd(unittest.TestCase):
    """`freecadcmd tsplcam/run_in_freecad.py -- job ...` as a user types it: FreeCAD's Python
    runs the job, its exit code is the command's, and the program, CL data and report figures
    are those of the same job run here."""

    def test_job_through_freecadcmd(self):
        import shutil
        from tsplcam.job import run_job
        from tsplcam.settings import JobSettings
        exe = shutil.which("freecadcmd")
        if exe is None:
            self.skipTest("freecadcmd not on PATH")
        script = os.path.join(REPO_DIR, "tsplcam", "run_in_freecad.py")
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "fc")
            res = subprocess.run([exe, script, "--", "job", "keycap", "--out", out, "--scallop", "0.2",
                                  "--chord-tol", "0.01", "--machine", "linuxcnc_xyzac_trt"],
                                 capture_output=True, text=True, timeout=600, cwd=tmp)
            self.assertEqual(res.returncode, 0, res.stdout[-2000:] + res.stderr[-2000:])
            self.assertIn("report: " + os.path.join(out, "report.html"), res.stdout)
            self.assertEqual(sorted(os.listdir(out)), ["keycap.cl", "keycap.ngc", "processing-list.json",
                                                       "report.html", "report.json", "report_files"])
            self.assertEqual(len(os.listdir(os.path.join(out, "report_files"))), 7)
            here = os.path.join(tmp, "here")
            # (its HTML report left out: the page is compared nowhere; the files and figures are)
            run_job(JobSettings(out=here, scallop=0.2, chord_tol=0.01, machine="linuxcnc_xyzac_trt",
                                html_report=False), log=None, progress=lambda stage, done, total: None)
            for name in ("keycap.ngc", "keycap.cl", "processing-list.json"):
                with open(os.path.join(out, name), "rb") as a, open(os.path.join(here, name), "rb") as b:
                    self.assertEqual(a.read(), b.read(), name)
            a, b = (json.load(open(os.path.join(d, "report.json"))) for d in (out, here))
            self.assertLessEqual(a["verification"]["max_scallop"], 0.2 * (1 + 1e-9))
            self.assertAlmostEqual(a["verification"]["max_scallop"], b["verification"]["max_scallop"], delta=1e-9)
            self.assertEqual(a["path"]["points"], b["path"]["points"])
            # a refusal: exit code 2 and one line, as from python3 -m tsplcam
            res = subprocess.run([exe, script, "--", "job", "--out", os.path.join(tmp, "bad"), "--scallop", "-1"],
                                 capture_output=True, text=True, timeout=300, cwd=tmp)
            self.assertEqual(res.returncode, 2, res.stdout[-2000:] + res.stderr[-2000:])
            self.assertIn("error: --scallop: must be a positive number (mm), not -1", res.stderr)
            self.assertFalse(os.path.exists(os.path.join(tmp, "bad")))


if __name__ == "__main__":
    unittest.main()
