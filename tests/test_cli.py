"""``python3 -m tsplcam path``: exit 0 with CL data and a report, exit 2 with a clear message
on bad input."""
import contextlib
import io
import json
import os
import subprocess
import tempfile
import unittest

from tsplcam.cli import main
from tsplcam.model.samples import sample_path
from tsplcam.plan import save
from tsplcam.plan.steps import ProcessingList, Step
from conftest import REPO_DIR
from tsplcam.toolpath.cldata import read_cl
from tsplcam.toolpath.path import Move

SYSTEM_PYTHON = "/usr/bin/python3"


def run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:             # argparse refusals
            code = exc.code
    return code, out.getvalue(), err.getvalue()


class PathCommand(unittest.TestCase):

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.addCleanup(self.tmp.cleanup)

    def f(self, name):
        return os.path.join(self.tmp.name, name)

    def test_keycap_to_cl_with_baseline_and_json(self):
        code, out, err = run(["path", "keycap", "--tool-radius", "0.5", "--scallop", "0.1", "--cl", self.f("k.cl"),
                              "--baseline", "--json", self.f("k.json")])
        self.assertEqual(code, 0, err)
        self.assertIn("0 retractions", out)
        self.assertIn("baseline", out)
        cl = read_cl(self.f("k.cl"))
        self.assertEqual(cl.tool_radius, 0.5)       # exact: --tool-radius 0.5, written and read back
        self.assertFalse(any(k in (Move.RETRACT, Move.RAPID) for k in cl.kind[1:-1]))
        with open(self.f("k.json")) as fh:
            doc = json.load(fh)
        self.assertEqual(doc["path"]["metrics"]["retractions"], 0)
        self.assertEqual(doc["baseline"]["metrics"]["retractions"], 4)
        self.assertEqual(len(doc["path"]["patches"]), 5)

    def test_processing_list_file_is_followed(self):
        steps = [Step(0, 0, 2, "u"), Step(1, 0, 3, "v"), Step(2, 0, 2, "u"), Step(3, 0, 1, "u"),
                 Step(4, 0, 2, "v")]
        for i in range(1, 5):
            steps[i].retract_before = True
            steps[i].link = "retract"
        save(ProcessingList(steps, model="keycap.obj"), self.f("list.json"))
        code, out, err = run(["path", sample_path("keycap"), "--tool-radius", "0.5", "--scallop", "0.1",
                              "--processing-list", self.f("list.json"), "--cl", self.f("k.cl")])
        self.assertEqual(code, 0, err)
        self.assertIn("4 retractions", out)
        cl = read_cl(self.f("k.cl"))
        self.assertEqual(int((cl.kind == Move.RETRACT).sum()), 4)

    def test_bad_input_exits_2(self):
        cases = [
            (["path", "keycap", "--tool-radius", "-1", "--scallop", "0.01"], "must be a positive number"),
            (["path", "keycap", "--tool-radius", "0.5"], "--scallop"),
            (["path", "keycap", "--tool-radius", "0.5", "--scallop", "1"], "smaller than the tool radius"),
            (["path", self.f("none.obj"), "--tool-radius", "0.5", "--scallop", "0.01"], "no such file"),
            (["path", "keycap_mold", "--tool-radius", "1", "--scallop", "0.01"], "concave radius of curvature"),
            (["path", "keycap", "--tool-radius", "0.5", "--scallop", "0.01", "--processing-list",
              self.f("missing.json")], "cannot read the processing list"),
        ]
        for argv, what in cases:
            code, out, err = run(argv)
            self.assertEqual(code, 2, argv)
            self.assertIn(what, err, argv)
            self.assertNotIn("Traceback", err)
        with open(self.f("bad.json"), "w") as fh:
            fh.write('{"format": "tsplcam-processing-list", "version": 1, "steps": [{"patch": 9}]}')
        code, out, err = run(["path", "keycap", "--tool-radius", "0.5", "--scallop", "0.01",
                              "--processing-list", self.f("bad.json")])
        self.assertEqual(code, 2)
        self.assertIn("bad.json", err)

    def test_runs_without_freecad(self):
        """The command in the system Python, as a user runs it (no FreeCAD on the path)."""
        if not os.path.exists(SYSTEM_PYTHON):
            self.skipTest("no /usr/bin/python3")
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
        env["PYTHONPATH"] = REPO_DIR
        p = subprocess.run([SYSTEM_PYTHON, "-c", "import sys; sys.modules['FreeCAD'] = None\n"
                            "from tsplcam.cli import main; sys.exit(main())", "path", "keycap",
                            "--tool-radius", "0.5", "--scallop", "0.2", "--cl", self.f("k.cl")],
                           cwd=REPO_DIR, env=env, capture_output=True, text=True, timeout=300)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("wrote", p.stdout)
        self.assertGreater(len(read_cl(self.f("k.cl"))), 100)
        p = subprocess.run([SYSTEM_PYTHON, "-m", "tsplcam", "path", "keycap", "--tool-radius", "0.5",
                            "--scallop", "zero"], cwd=REPO_DIR, env=env, capture_output=True, text=True, timeout=300)
        self.assertEqual(p.returncode, 2)
        self.assertIn("not a number", p.stderr)


if __name__ == "__main__":
    unittest.main()
