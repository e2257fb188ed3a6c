"""The workbench's FreeCAD-free parts under plain pytest: the child-process protocol of the
long work (what the GUI runs out of FreeCAD's process), the --fcstd checks, the highlight of
a processing-list step, and the table of settings and properties.

References: the engine's own make_path / make_program in this process (the child must give
the same arrays and bytes), the patch evaluated at its corners, JobSettings' fields.
"""
import io
import os
import pickle
import signal
import subprocess
import sys
import tempfile
import time
import unittest

import numpy as np

from tsplcam import load_model
from tsplcam.errors import InputError
from tsplcam.program import make_path, processing_list
from tsplcam.settings import JobSettings
from tsplcam.workbench import display, headless, worker
from conftest import REPO_DIR


def run_child(task, args, kwargs, tmp, kill_after=None):
    """Run the worker as the GUI does; returns (lines of stdout, result tuple or None, seconds).
    With ``kill_after`` (seconds), its group is killed then as the GUI's Stop does: (the
    processes of its session still running 0.2 s later, None, seconds from the kill to its
    exit)."""
    result_file = os.path.join(tmp, "result.pickle")
    env = dict(os.environ, PYTHONPATH=REPO_DIR)
    proc = subprocess.Popen([sys.executable, "-m", "tsplcam.workbench.worker"], cwd=tmp, env=env,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)
    t0 = time.perf_counter()
    if kill_after is not None:
        proc.stdin.write(pickle.dumps((task, args, kwargs, result_file)))
        proc.stdin.close()
        time.sleep(kill_after)
        t1 = time.perf_counter()
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        latency = time.perf_counter() - t1
        time.sleep(0.2)
        return _running_in_session(proc.pid), None, latency
    out, err = proc.communicate(pickle.dumps((task, args, kwargs, result_file)), timeout=600)
    lines = out.decode().splitlines()
    result = None
    if os.path.exists(result_file):
        with open(result_file, "rb") as f:
            result = pickle.load(f)
    return lines, result, time.perf_counter() - t0


def _running_in_session(sid: int) -> list:
    """The command lines of the processes of session ``sid`` that still run (not zombies):
    the worker and whatever it started (``ps`` over the whole machine would also see the
    workers of the GUI tests that run beside this suite)."""
    left = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            if int(fields[3]) != sid or fields[0] == "Z":      # session, state
                continue
            with open(f"/proc/{pid}/cmdline", "rb") as fh:
                left.append(fh.read().replace(b"\0", b" ").decode(errors="replace").strip())
        except (OSError, ValueError, IndexError):
            continue                                          # (gone meanwhile)
    return left


class ChildProcess(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="tsplcam-worker-")

    def test_the_child_makes_the_same_path_and_reports_progress(self):
        model = load_model("keycap")
        s = JobSettings(model="keycap", tool=None, tool_radius=0.5, scallop=0.1)
        plist = processing_list(model, s)
        here = make_path(model, plist, s)
        lines, result, _ = run_child("path_task", (model, plist, s.to_dict()), {}, self.tmp)
        self.assertEqual(result[0], "ok", result)
        np.testing.assert_array_equal(result[1].contact, here.contact)     # same code, same data
        np.testing.assert_array_equal(result[1].move, here.move)
        progress = [ln.split("\t") for ln in lines if ln.startswith("P\t")]
        self.assertEqual(progress[-1], ["P", "path", "5", "5"])
        self.assertGreaterEqual(len(progress), 2)
        self.assertEqual(lines[-1], "D")

    def test_an_engine_error_comes_back_with_its_place(self):
        model = load_model("keycap_mold")
        s = JobSettings(model="keycap_mold", tool=None, tool_radius=5.0, scallop=0.05)
        plist = processing_list(model, s)
        lines, result, _ = run_child("path_task", (model, plist, s.to_dict()), {}, self.tmp)
        kind, exc, text, attrs = result
        self.assertEqual(kind, "error")
        self.assertIn("concave radius", str(exc))
        self.assertRegex(str(exc), r"patch \d+: .*\(u, v\) = \(")
        self.assertIn("Traceback", text)                     # for the Report view
        s = JobSettings(model="keycap_mold", tool=None, tool_radius=0.5, scallop=0.05, feed=72000.0,
                        machine="mikron_ucp600_heidenhain", orientation="normal")
        path = make_path(model, plist, s)
        lines, result, _ = run_child("program_task", (path, model, s.to_dict()), {}, self.tmp)
        kind, exc, text, attrs = result
        self.assertIsInstance(exc, InputError)
        self.assertEqual(attrs["item"], "feed")              # kept for the property's name
        self.assertIn("20000 mm/min", attrs["message"])

    def test_a_kill_stops_the_child_and_its_workers_at_once(self):
        model = load_model("figure4")
        s = JobSettings(model="figure4", tool=None, tool_radius=0.5, scallop=0.005)
        plist = processing_list(model, s)
        left, result, latency = run_child("path_task", (model, plist, s.to_dict()), {}, self.tmp, kill_after=1.0)
        self.assertIsNone(result)
        self.assertLess(latency, 1.0)
        self.assertEqual(left, [])               # no worker of the path is left running

    def test_progress_lines_are_rate_limited_but_every_end_is_written(self):
        buf = io.StringIO()
        p = worker.PipeProgress(buf, interval=10.0)
        for k in range(1000):
            p("tool axes", k, 1000)
        p("tool axes", 1000, 1000)
        p("program", 3, 3)
        lines = buf.getvalue().splitlines()
        self.assertEqual(lines, ["P\ttool axes\t0\t1000", "P\ttool axes\t1000\t1000", "P\tprogram\t3\t3"])


class FcstdOption(unittest.TestCase):
    def test_checks_before_the_work(self):
        with tempfile.TemporaryDirectory() as tmp:
            with self.assertRaises(InputError) as ctx:
                headless.check_fcstd(os.path.join(tmp, "out.txt"))
            self.assertIn(".FCStd", str(ctx.exception))
            old = os.environ.get("TSPLCAM_FREECADCMD")
            os.environ["TSPLCAM_FREECADCMD"] = os.path.join(tmp, "none")
            try:
                with self.assertRaises(InputError) as ctx:
                    headless.check_fcstd(os.path.join(tmp, "a", "b.FCStd"))
                self.assertIn("freecadcmd", str(ctx.exception))
            finally:
                if old is None:
                    del os.environ["TSPLCAM_FREECADCMD"]
                else:
                    os.environ["TSPLCAM_FREECADCMD"] = old
            self.assertTrue(headless.model_file("keycap").endswith("keycap.obj"))

    def test_the_option_is_a_job_output(self):
        from dataclasses import fields
        f = {x.name: x for x in fields(JobSettings)}["fcstd"]
        self.assertEqual((f.metadata["group"], f.metadata["command"]), ("outputs", "job"))
        self.assertIn("fcstd", JobSettings.option_names("job"))
        self.assertNotIn("fcstd", JobSettings.option_names("path"))


class SettingsTable(unittest.TestCase):
    def test_every_path_and_program_option_has_a_property(self):
        from tsplcam.settings import PATH_KEYS, PROGRAM_KEYS
        from tsplcam.workbench.fields import PATH_FIELDS, PROGRAM_FIELDS, PROPERTY_OF, from_property
        self.assertEqual({f.name for f in PATH_FIELDS}, {"tool_radius", *PATH_KEYS})
        self.assertEqual({f.name for f in PROGRAM_FIELDS}, set(PROGRAM_KEYS))
        props = [f.prop for f in PATH_FIELDS + PROGRAM_FIELDS]
        self.assertEqual(len(props), len(set(props)))
        self.assertEqual(PROPERTY_OF["feed"], "Feed")
        feed = next(f for f in PATH_FIELDS if f.name == "feed")
        self.assertEqual((feed.ptype, feed.unit), ("App::PropertyFloat", "mm/min"))   # not a FreeCAD speed
        point = next(f for f in PROGRAM_FIELDS if f.name == "point")
        self.assertEqual(from_property(point, " 1, 2,3 "), (1.0, 2.0, 3.0))
        self.assertIsNone(from_property(point, ""))
        with self.assertRaises(InputError) as ctx:
            from_property(point, "1, 2")
        self.assertIn("Point", str(ctx.exception))


class StepHighlight(unittest.TestCase):
    def test_outline_and_corners_lie_on_the_patch(self):
        from tsplcam.layout.layout import CORNER_UV
        from tsplcam.plan.steps import Step
        model = load_model("keycap")
        lift = 0.01
        outline, start, finish, curve = display.step_highlight(model, Step(3, 0, 2, "u"), lift=lift)
        patch = model.patches[3]
        for k, line in enumerate(outline):
            c = CORNER_UV[k]
            sp = patch.evaluate(np.array([c[0]]), np.array([c[1]]))
            np.testing.assert_allclose(line[0], sp.P[0] + lift * sp.normal[0] / np.linalg.norm(sp.normal[0]),
                                       atol=1e-9)
        for point, c in ((start, 0), (finish, 2)):
            sp = patch.evaluate(np.array([CORNER_UV[c][0]]), np.array([CORNER_UV[c][1]]))
            self.assertLess(np.linalg.norm(point[0] - sp.P[0]), lift + 1e-9)
        np.testing.assert_allclose(curve[0], start[0], atol=0.6 * lift)
        _, none_start, none_finish, no_curve = display.step_highlight(model, Step(3))
        self.assertIsNone(none_start)
        self.assertIsNone(no_curve)


if __name__ == "__main__":
    unittest.main()
