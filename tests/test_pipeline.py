"""The whole job through the command line: path -> tool axes -> program, and the main job;
the job, the `path` command and the program builder give the same program for the same
settings."""
import json
import os
import subprocess
import tempfile
import unittest

import numpy as np

from conftest import REPO_DIR

PY = "/usr/bin/python3"


def run(*args, cwd=None):
    env = dict(os.environ, PYTHONPATH=REPO_DIR)
    return subprocess.run([PY, "-m", "tsplcam", *args], capture_output=True, text=True, env=env,
                          cwd=cwd or REPO_DIR, timeout=900)


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
        res = run("path", "keycap", "--tool-radius", "0.5", "--scallop", "0.05", "--gcode", "/tmp/x.ngc")
        self.assertEqual(res.returncode, 2)
        self.assertIn("--gcode: needs --machine", res.stderr)
        res = run("path", "keycap", "--tool-radius", "0.5", "--scallop", "0.05", "--orientation", "smooth")
        self.assertEqual(res.returncode, 2)
        self.assertIn("needs a tool", res.stderr)
        res = run("path", "keycap", "--tool-radius", "0.7", "--scallop", "0.05", "--tool", "ball1_keycap",
                  "--orientation", "smooth")
        self.assertEqual(res.returncode, 2)
        self.assertIn("differs from the ball radius", res.stderr)
        res = run("path", "no_such_model.obj", "--tool-radius", "0.5", "--scallop", "0.05")
        self.assertEqual(res.returncode, 2)
        self.assertIn("no_such_model.obj", res.stderr)


class MainJob(unittest.TestCase):
    def test_job_writes_program_list_and_report(self):
        with tempfile.TemporaryDirectory() as tmp:
            res = run("job", "--out", tmp, "--scallop", "0.05")
            self.assertEqual(res.returncode, 0, res.stderr)
            names = sorted(os.listdir(tmp))
            self.assertEqual(names, ["keycap.cl", "keycap.h", "processing-list.json", "report.json"])
            report = json.load(open(os.path.join(tmp, "report.json")))
            self.assertEqual(report["path"]["retractions"], 0)
            self.assertEqual(report["orientation"]["collisions"], 0)
            program = open(os.path.join(tmp, "keycap.h")).read()
            self.assertTrue(program.startswith("0 BEGIN PGM"))
            self.assertIn("FUNCTION TCPM", program)
            self.assertIn("machining time", res.stdout)


class OneProgramBuilder(unittest.TestCase):
    """Fast settings (a coarse path on the keycap): the main job's program and the `path`
    command's program are the same bytes, both made by tsplcam.program.make_program (the
    workbench's program object is compared with the job in
    tests/workbench/test_workbench_program.py)."""

    def test_job_and_path_command_agree(self):
        import contextlib
        import io
        from tsplcam.cli import main
        from tsplcam.job import run_job
        from tsplcam.settings import JobSettings
        options = dict(scallop=0.2, chord_tol=0.01, max_step=2.0, feed=800.0, holder_clearance=0.25,
                       smoothing_length=4.0, machine="bc_head_table_sinumerik", dialect="fanuc")
        with tempfile.TemporaryDirectory() as tmp:
            figures = run_job(JobSettings(out=os.path.join(tmp, "job"), **options), log=lambda *a: None,
                              progress=lambda stage, done, total: None)
            with open(os.path.join(tmp, "job", "keycap.nc"), "rb") as fh:
                job_program = fh.read()
            argv = ["path", "keycap", "--tool-radius", "0.5", "--tool", "ball1_keycap", "--orientation", "smooth",
                    "--gcode", os.path.join(tmp, "path.nc")]
            for k, v in options.items():
                argv += ["--" + k.replace("_", "-"), str(v)]
            err = io.StringIO()
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
                self.assertEqual(main(argv), 0, err.getvalue())
            with open(os.path.join(tmp, "path.nc"), "rb") as fh:
                self.assertEqual(fh.read(), job_program)
        self.assertEqual(figures["orientation"]["collisions"], 0)
        self.assertGreaterEqual(figures["orientation"]["min_clearance"], 0.25 - 1e-6)
        self.assertIn(b"G43.4", job_program)             # Fanuc's tool centre point control
        self.assertEqual(figures["settings"]["feed"], 800.0)   # the value given, not computed
