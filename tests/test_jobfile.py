"""Job files (tsplcam/JOBFILE.md): file names relative to the file, unknown keys and bad
values refused naming the file and the key, command-line options overriding the file, and
`job --config` giving the same program as the same options typed out."""
import contextlib
import io
import json
import os
import re
import shutil
import tempfile
import unittest
from dataclasses import fields

from conftest import REPO_DIR
from tsplcam.cli import main
from tsplcam.errors import InputError
from tsplcam.jobfile import KEYS, input_files, job_settings, read_job_file
from tsplcam.model.samples import sample_path
from tsplcam.orientation.tool import shipped_tools_dir
from tsplcam.post.machine import machine_files
from tsplcam.settings import JobSettings

# a coarse job: quick, and still five-axis with collision checks
COARSE = {"scallop": 0.2, "chord_tol": 0.01, "max_step": 2.0}


def cli(argv, cwd=None):
    """(exit code, stdout, stderr) of the command line in this process."""
    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    try:
        if cwd:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(argv)
            except SystemExit as exc:
                code = exc.code
    finally:
        os.chdir(here)
    return code, out.getvalue(), err.getvalue()


class JobFolder(unittest.TestCase):
    """A folder as a shop would send it: jobs/mold.json naming ../parts/cap.obj,
    ../tools/cutter.json, ../machines/mill.json, a processing list and a stock beside it."""

    def setUp(self):
        self.root = tempfile.mkdtemp(prefix="tsplcam-jobfile-")
        for sub in ("jobs", "parts", "tools", "machines"):
            os.makedirs(os.path.join(self.root, sub))
        shutil.copy(sample_path("keycap"), os.path.join(self.root, "parts", "cap.obj"))
        shutil.copy(os.path.join(shipped_tools_dir(), "ball1_keycap.json"), os.path.join(self.root, "tools",
                                                                                          "cutter.json"))
        shutil.copy(machine_files()["linuxcnc_xyzac_trt"], os.path.join(self.root, "machines", "mill.json"))
        with open(os.path.join(self.root, "parts", "block.obj"), "w") as fh:    # a plate far below the part
            fh.write("v -30 -30 -20\nv 30 -30 -20\nv 30 30 -20\nv -30 30 -20\nf 1 2 3\nf 1 3 4\n")
        code, _, err = cli(["plan", os.path.join(self.root, "parts", "cap.obj"), "--out",
                            os.path.join(self.root, "parts", "order.json")])
        self.assertEqual(code, 0, err)
        self.job = self.write("mold.json", {"model": "../parts/cap.obj", "stock": "../parts/block.obj",
                                            "processing_list": "../parts/order.json", "tool": "../tools/cutter.json",
                                            "machine": "../machines/mill.json", "out": "../results/mold",
                                            "name": "cavity", **COARSE})

    def tearDown(self):
        shutil.rmtree(self.root, ignore_errors=True)

    def write(self, name, data, text=None):
        path = os.path.join(self.root, "jobs", name)
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(text if text is not None else json.dumps(data, indent=2))
        return path

    def at(self, *parts):
        return os.path.join(self.root, *parts)

    def test_paths_are_relative_to_the_job_file(self):
        elsewhere = tempfile.mkdtemp()
        try:
            here = os.getcwd()
            os.chdir(elsewhere)
            try:
                s = job_settings(os.path.relpath(self.job))
            finally:
                os.chdir(here)
        finally:
            shutil.rmtree(elsewhere)
        self.assertEqual(s.model, self.at("parts", "cap.obj"))
        self.assertEqual(s.stock, self.at("parts", "block.obj"))
        self.assertEqual(s.processing_list, self.at("parts", "order.json"))
        self.assertEqual(s.tool, self.at("tools", "cutter.json"))
        self.assertEqual(s.machine, self.at("machines", "mill.json"))
        self.assertEqual(s.out, self.at("results", "mold"))
        self.assertEqual((s.scallop, s.name), (0.2, "cavity"))
        # shipped names stay names; absolute file names stay as they are
        s = job_settings(self.write("named.json", {"model": "keycap_mold", "tool": "ball1_keycap",
                                                   "machine": "linuxcnc_xyzac_trt",
                                                   "stock": self.at("parts", "block.obj")}))
        self.assertEqual((s.model, s.tool, s.machine), ("keycap_mold", "ball1_keycap", "linuxcnc_xyzac_trt"))
        self.assertEqual(s.stock, self.at("parts", "block.obj"))
        # every file the job reads, shipped ones included
        files = dict(input_files(s))
        self.assertEqual(files["model"], sample_path("keycap_mold"))
        self.assertEqual(files["tool"], os.path.join(shipped_tools_dir(), "ball1_keycap.json"))
        self.assertEqual(files["machine"], machine_files()["linuxcnc_xyzac_trt"])
        self.assertEqual(files["stock"], self.at("parts", "block.obj"))

    def test_unknown_keys_and_bad_values_name_the_file_and_key(self):
        cases = [({"scallop": 0.1, "scalop": 0.1}, "'scalop'"),
                 ({"gcode": "x.ngc"}, "'gcode'"),                    # an output of the path command
                 ({"scallop": -0.2}, "scallop"),
                 ({"scallop": "0.1"}, "scallop"),
                 ({"feed": None}, "feed"),
                 ({"orientation": "sideways"}, "orientation"),
                 ({"axis": [0, 1]}, "axis"),
                 ({"balance": "yes"}, "balance"),
                 ({"verify": 1}, "verify"),
                 ({"name": "a/b"}, "name"),
                 ({"model": ""}, "model"),
                 ({"scallop": 0.7, "tool_radius": 0.5}, "scallop"),   # not below the 0.5 mm ball
                 ({"tool": None, "orientation": "normal"}, "tool_radius")]
        for data, key in cases:
            with self.subTest(data=data):
                path = self.write("bad.json", data)
                with self.assertRaises(InputError) as cm:
                    job_settings(path)
                self.assertEqual(cm.exception.path, path)
                self.assertIn(key, str(cm.exception))
                self.assertTrue(str(cm.exception).startswith(path + ": "), str(cm.exception))
        for text, what in (("{\"scallop\": 0.1,\n \"feed\": }", "line 2"), ("[1, 2]", "JSON object"),
                           ("{\"scallop\": NaN}", "line 1"), ("", "")):
            with self.subTest(text=text):
                path = self.write("broken.json", None, text)
                with self.assertRaises(InputError) as cm:
                    read_job_file(path)
                self.assertIn(path, str(cm.exception))
                self.assertIn(what, str(cm.exception))
        with self.assertRaises(InputError) as cm:
            job_settings(self.at("jobs", "none.json"))
        self.assertIn("none.json", str(cm.exception))

    def test_command_line_overrides_the_file(self):
        label = {"scallop": "--scallop", "feed": "--feed"}.get
        s = job_settings(self.job, overrides={"scallop": 0.25, "feed": 700.0}, label=label)
        self.assertEqual((s.scallop, s.feed, s.chord_tol), (0.25, 700.0, 0.01))
        # a bad override is named as typed; a bad file value by the file and key
        with self.assertRaises(InputError) as cm:
            job_settings(self.job, overrides={"scallop": 0.0}, label=label)
        self.assertEqual((cm.exception.item, cm.exception.path), ("--scallop", None))
        bad = self.write("bad.json", {"feed": -5})
        with self.assertRaises(InputError) as cm:
            job_settings(bad, overrides={"scallop": 0.25}, label=label)
        self.assertEqual((cm.exception.item, cm.exception.path), ("feed", bad))
        # through the command line: the same one line, exit code 2, no file
        code, out, err = cli(["job", "--config", bad, "--scallop", "0.25", "--out", self.at("x")])
        self.assertEqual(code, 2)
        self.assertEqual(err.strip(), f"error: {bad}: feed: must be a positive number (mm/min), not -5")
        code, out, err = cli(["job", "--config", self.job, "--scallop", "nan", "--out", self.at("x")])
        self.assertEqual(code, 2)
        self.assertIn("--scallop", err)
        self.assertFalse(os.path.exists(self.at("x")))

    def test_config_gives_the_program_the_options_give(self):
        """`job --config mold.json` from another folder writes into the folder the file names,
        and its program is the same bytes as the same job with every option typed out."""
        code, out, err = cli(["job", "--config", self.job, "--no-verify", "--no-html-report"], cwd=tempfile.gettempdir())
        self.assertEqual(code, 0, err)
        folder = self.at("results", "mold")
        self.assertEqual(sorted(os.listdir(folder)), ["cavity.cl", "cavity.ngc", "processing-list.json", "report.json"])
        typed = self.at("typed")
        code, out, err = cli(["job", self.at("parts", "cap.obj"), "--stock", self.at("parts", "block.obj"),
                              "--processing-list", self.at("parts", "order.json"), "--tool",
                              self.at("tools", "cutter.json"), "--machine", self.at("machines", "mill.json"),
                              "--name", "cavity", "--out", typed, "--scallop", "0.2", "--chord-tol", "0.01",
                              "--max-step", "2", "--no-verify", "--no-html-report"])
        self.assertEqual(code, 0, err)
        for name in ("cavity.ngc", "cavity.cl", "processing-list.json"):
            with open(os.path.join(folder, name), "rb") as a, open(os.path.join(typed, name), "rb") as b:
                self.assertEqual(a.read(), b.read(), name)
        report = json.load(open(os.path.join(folder, "report.json")))
        self.assertEqual(report["orientation"]["collisions"], 0)
        self.assertEqual(report["settings"]["processing_list"], self.at("parts", "order.json"))


class Shipped(unittest.TestCase):
    def test_example_job_files_load(self):
        folder = os.path.join(REPO_DIR, "tsplcam", "data", "jobs")
        names = sorted(os.listdir(folder))
        self.assertIn("keycap.json", names)
        for name in names:
            s = job_settings(os.path.join(folder, name))
            for key, path in input_files(s):
                self.assertTrue(os.path.isfile(path), f"{name}: {key} {path}")
        main_job = job_settings(os.path.join(folder, "keycap.json"))
        defaults = JobSettings()
        for f in fields(JobSettings):             # the main job: every default, the baseline asked for
            if f.name != "baseline":
                self.assertEqual(getattr(main_job, f.name), getattr(defaults, f.name), f.name)
        self.assertTrue(main_job.baseline)

    def test_jobfile_md_lists_every_key(self):
        with open(os.path.join(REPO_DIR, "tsplcam", "JOBFILE.md"), encoding="utf-8") as fh:
            text = fh.read()
        listed = set(re.findall(r"^\| `(\w+)`(?:, `(\w+)`)?", text, flags=re.M))
        listed = {k for pair in listed for k in pair if k}
        self.assertEqual(listed, set(KEYS))


if __name__ == "__main__":
    unittest.main()
