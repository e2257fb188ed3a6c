"""The command line: ``path`` exits 0 with CL data and a report; every command takes a model
file or a shipped sample name; bad options, unknown names and unwritable outputs exit 2
with one line naming the option and leave no file; the same command gives the same bytes
under any PYTHONHASHSEED and any number of workers."""
import contextlib
import io
import json
import os
import subprocess
import tempfile
import unittest
from concurrent.futures import ThreadPoolExecutor

from tsplcam.cli import main
from tsplcam.model.samples import sample_path
from tsplcam.plan import save
from tsplcam.plan.steps import ProcessingList, Step
from conftest import REPO_DIR
from _jobs import assert_same_files, keep_for_a_look, run_tsplcam
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
            (["path", "keycap", "--tool-radius", "0.5", "--scallop", "1"], "must be smaller than the tool radius"),
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


def system_python_env():
    if not os.path.exists(SYSTEM_PYTHON):
        raise unittest.SkipTest("no /usr/bin/python3")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
    env["PYTHONPATH"] = REPO_DIR
    return env


class Refusals(unittest.TestCase):
    """Each bad option: exit code 2, one line on stderr naming the option, no file left
    (the outputs of every case point into an empty folder)."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.addCleanup(self.tmp.cleanup)
        self.out = os.path.join(self.tmp.name, "out")
        os.mkdir(self.out)
        self.afile = os.path.join(self.tmp.name, "a-file")
        with open(self.afile, "w") as fh:
            fh.write("not a folder\n")

    def f(self, name):
        return os.path.join(self.out, name)

    def path_cmd(self, *extra, radius="0.5", scallop="0.05"):
        return ["path", "keycap", "--tool-radius", radius, "--scallop", scallop, "--cl", self.f("k.cl"),
                "--json", self.f("k.json"), *extra]

    def cases(self):
        smooth = ["--tool", "ball1_keycap", "--orientation", "smooth"]
        mach = ["--machine", "linuxcnc_xyzac_trt", "--gcode", self.f("k.ngc")]
        return [
            (self.path_cmd(radius="-1"), "--tool-radius"),
            (self.path_cmd(radius="0"), "--tool-radius"),
            (self.path_cmd(radius="nan"), "--tool-radius"),
            (self.path_cmd(radius="inf"), "--tool-radius"),
            (self.path_cmd(scallop="-0.01"), "--scallop"),
            (self.path_cmd(scallop="0"), "--scallop"),
            (self.path_cmd(scallop="nan"), "--scallop"),
            (self.path_cmd(scallop="0.5"), "--scallop"),               # not below the ball radius
            (self.path_cmd("--chord-tol", "0"), "--chord-tol"),
            (self.path_cmd("--chord-tol", "-inf"), "--chord-tol"),
            (self.path_cmd("--max-step", "-1"), "--max-step"),
            (self.path_cmd("--feed", "0"), "--feed"),
            (self.path_cmd("--feed", "-1000"), "--feed"),
            (self.path_cmd("--feed", "nan"), "--feed"),
            (self.path_cmd("--clearance", "-5"), "--clearance"),
            (self.path_cmd(*smooth, "--holder-clearance", "-0.1"), "--holder-clearance"),
            (self.path_cmd(*smooth, "--smoothing-length", "0"), "--smoothing-length"),
            (self.path_cmd(*smooth, *mach, "--rotary-weight", "inf"), "--rotary-weight"),
            (self.path_cmd("--machine", "no_such_machine", "--gcode", self.f("k.ngc")), "--machine"),
            (self.path_cmd("--tool", "no_such_tool"), "--tool"),
            (self.path_cmd(*mach, "--dialect", "klingon"), "--dialect"),
            (self.path_cmd("--orientation", "sideways"), "--orientation"),
            (self.path_cmd("--orientation", "smooth"), "--orientation"),     # no tool for the collision checks
            (self.path_cmd("--gcode", self.f("k.ngc")), "--gcode"),          # no machine
            (self.path_cmd("--tool-radius", "0.7", *smooth), "--tool-radius"),  # not the tool's ball
            (self.path_cmd(*smooth, "--stock", self.f("none.obj")), "--stock"),
            (["path", "keycap", "--tool-radius", "0.5", "--scallop", "0.05", "--cl",
              os.path.join(self.out, "missing", "k.cl")], "--cl"),
            (["path", "keycap", "--tool-radius", "0.5", "--scallop", "0.05", "--json",
              os.path.join(self.afile, "k.json")], "--json"),
            (self.path_cmd(*mach[:2], "--gcode", self.out), "--gcode"),       # a folder
            (self.path_cmd("--processing-list", self.f("none.json")), "--processing-list"),
            (["path", self.f("none.obj"), "--tool-radius", "0.5", "--scallop", "0.05", "--cl", self.f("k.cl")],
             "none.obj"),
            (["job", "--out", os.path.join(self.afile, "job")], "--out"),
            (["job", "--out", self.f("job"), "--scallop", "0"], "--scallop"),
            (["job", "--out", self.f("job"), "--tool-radius", "-0.5"], "--tool-radius"),
            (["job", "--out", self.f("job"), "--feed", "inf"], "--feed"),
            (["job", "--out", self.f("job"), "--machine", "no_such_machine"], "--machine"),
            (["job", "--out", self.f("job"), "--tool", "no_such_tool"], "--tool"),
            (["job", "--out", self.f("job"), "--dialect", "klingon"], "--dialect"),
            (["job", "--out", self.f("job"), "--holder-clearance", "nan"], "--holder-clearance"),
            (["job", "--out", self.f("job"), "--max-lead", "95"], "--max-lead"),
            (["job", "--out", self.f("job"), "--max-axis-step", "0"], "--max-axis-step"),
            # the tool vector that LinuxCNC's dialect does not write: refused before the work, by its name
            (["job", "--out", self.f("job"), "--machine", "linuxcnc_xyzac_trt", "--axes-form", "vector"],
             "--axes-form"),
            (["plan", "keycap", "--out", os.path.join(self.out, "missing", "list.json")], "--out"),
        ]

    def test_each_refusal_is_one_line_naming_the_option_and_leaves_no_file(self):
        for argv, what in self.cases():
            with self.subTest(argv=" ".join(argv[:1] + argv[5:] if argv[0] == "path" else argv)):
                code, out, err = run(argv)
                self.assertEqual(code, 2, err)
                lines = err.strip("\n").split("\n")
                self.assertEqual(len(lines), 1, err)
                self.assertTrue(lines[0].startswith("error: "), err)
                self.assertIn(what, lines[0])
                self.assertNotIn("Traceback", err)
                self.assertEqual(os.listdir(self.out), [], "a refused run left a file")

    def test_a_refused_geometry_after_the_work_started_leaves_no_file(self):
        """The mold cavity is tighter than a 1 mm ball: refused by patch and (u, v), no CL data,
        no report, no program, no temporary file."""
        code, out, err = run(["path", "keycap_mold", "--tool-radius", "1", "--scallop", "0.05", "--cl",
                              self.f("m.cl"), "--json", self.f("m.json")])
        self.assertEqual(code, 2)
        self.assertIn("concave radius of curvature", err)
        self.assertEqual(len(err.strip().split("\n")), 1, err)
        self.assertEqual(os.listdir(self.out), [])

    def test_refusals_as_a_user_runs_them(self):
        """Two refusals through `python3 -m tsplcam` in its own process: the exit code and the
        one line are what the shell sees."""
        env = system_python_env()
        for argv, what in [(["path", "keycap", "--tool-radius", "0.5", "--scallop", "-1"], "--scallop"),
                           (["job", "--out", self.f("job"), "--machine", "nope"], "--machine")]:
            p = subprocess.run([SYSTEM_PYTHON, "-m", "tsplcam", *argv], cwd=REPO_DIR, env=env,
                               capture_output=True, text=True, timeout=300)
            self.assertEqual(p.returncode, 2)
            self.assertEqual(len(p.stderr.strip().split("\n")), 1, p.stderr)
            self.assertIn(what, p.stderr)
        self.assertEqual(os.listdir(self.out), [])


class NegativeNumbers(unittest.TestCase):
    """A vector or range whose first number is negative (``--tilt-range -30,30``) is the
    option's value, not an unknown option (argparse takes a word starting with a minus sign
    as an option unless it is one number)."""

    def test_joined_to_the_option_before(self):
        from tsplcam.cli import joined_negative_lists
        argv = ["job", "--tilt-range", "-30,30", "--point", "-5, 0,10.5", "--axis", "-.2,0,1e0", "--lead", "-5",
                "--out", "-x", "-h", "-1,2", "--scallop=-1,2"]
        self.assertEqual(joined_negative_lists(argv),
                         ["job", "--tilt-range=-30,30", "--point=-5, 0,10.5", "--axis=-.2,0,1e0", "--lead", "-5",
                          "--out", "-x", "-h", "-1,2", "--scallop=-1,2"])

    def test_parsed_as_numbers(self):
        from tsplcam.cli import build_parser
        args = build_parser().parse_args(["job", "--tilt-range", "-30,30", "--point", "-5,0,10",
                                          "--direction", "-1,0,0", "--lead", "-5"])
        self.assertEqual((args.tilt_range, args.point, args.direction, args.lead),
                         ((-30.0, 30.0), (-5.0, 0.0, 10.0), (-1.0, 0.0, 0.0), -5.0))


class ModelArgument(unittest.TestCase):
    def test_plan_takes_a_sample_name_like_path(self):
        """`plan keycap --out list.json` reads the shipped sample: the same list as the sample's
        file gives, and the same as the job's processing list."""
        with tempfile.TemporaryDirectory() as tmp:
            by_name, by_file = os.path.join(tmp, "a.json"), os.path.join(tmp, "b.json")
            code, out, err = run(["plan", "keycap", "--out", by_name])
            self.assertEqual(code, 0, err)
            code, out, err = run(["plan", sample_path("keycap"), "--out", by_file])
            self.assertEqual(code, 0, err)
            with open(by_name, "rb") as a, open(by_file, "rb") as b:
                self.assertEqual(a.read(), b.read())
            self.assertEqual(sorted(os.listdir(tmp)), ["a.json", "b.json"])     # no temporary file left


class Determinism(unittest.TestCase):
    """The same command in two processes that differ in PYTHONHASHSEED and in the number of
    path workers (TSPLCAM_WORKERS 1 or 2), both factors at once: the program, CL data and
    report are the same bytes (report.json apart from its timing block). (A difference from
    either shows: the two would have to cancel to the last bit to hide one another.) The
    job's program, CL data, processing list, report.json, report.html and pictures are
    compared so in tests/test_batch.py (Batch.test_a_batch_job_is_the_job_command: the main
    job's command line, PYTHONHASHSEED 0 and two path workers, against its job file through
    `batch`, PYTHONHASHSEED 4242 and one process)."""
    maxDiff = None                   # (a failure shows every line that differs)
    PATH = ["path", "keycap", "--tool-radius", "0.5", "--scallop", "0.2", "--chord-tol", "0.01", "--tool",
            "ball1_keycap", "--orientation", "closest-z", "--machine", "bc_head_table_sinumerik", "--gcode",
            "out/k.mpf", "--cl", "out/k.cl", "--json", "out/k.json"]

    def run_in(self, cwd, argv, seed, workers):
        """The same command line (the same relative file names) in its own folder, with
        PYTHONHASHSEED ``seed`` and TSPLCAM_WORKERS ``workers``."""
        system_python_env()                          # (skips without /usr/bin/python3)
        os.makedirs(os.path.join(cwd, "out"), exist_ok=True)
        return run_tsplcam(argv, cwd, seed=seed, workers=workers, timeout=600)

    def test_path_bytes_do_not_depend_on_the_hash_seed_or_the_workers(self):
        """The path command with closest-z axes and a Sinumerik program: PYTHONHASHSEED 0 and
        one process against PYTHONHASHSEED 4242 and two path workers."""
        with tempfile.TemporaryDirectory() as tmp:
            runs = [(os.path.join(tmp, f"seed{seed}-workers{workers}"), self.PATH, seed, workers)
                    for seed, workers in ((0, 1), (4242, 2))]
            with ThreadPoolExecutor(2) as pool:
                results = list(pool.map(lambda r: self.run_in(*r), runs))
            for r in results:
                self.assertEqual(r.returncode, 0, r.stderr)
            try:
                assert_same_files(self, *(os.path.join(cwd, "out") for cwd, _, _, _ in runs),
                                  ["k.cl", "k.json", "k.mpf"], "k.json")
            except AssertionError:         # keep both runs' files for a look
                keep_for_a_look("determinism-failure", {os.path.basename(cwd): cwd for cwd, _, _, _ in runs})
                raise


class FusionSampleJob(unittest.TestCase):
    def test_fusion_tsm_job_end_to_end(self):
        """The Fusion-dialect sample (a .tsm: stars of valence 3 and 5, a crease) through the
        one reader registry: path, tool axes and program in one run, no retraction, no
        collision or gouge. Without the surface verification and the HTML report, which come
        after the program (they took two thirds of the run; the main job's are checked in
        tests/test_pipeline.py and tests/report)."""
        with tempfile.TemporaryDirectory(prefix="tsplcam-fusion-job-") as out:
            code, stdout, err = run(["job", "--model", sample_path("fusion_mold"), "--tool-radius", "0.5",
                                     "--scallop", "0.1", "--max-step", "2", "--no-verify", "--no-html-report",
                                     "--out", out])
            self.assertEqual(code, 0, err)
            self.assertEqual(sorted(os.listdir(out)), ["fusion_mold.cl", "fusion_mold.h", "processing-list.json",
                                                       "report.json"])
            with open(os.path.join(out, "report.json")) as fh:
                report = json.load(fh)
            self.assertEqual(report["path"]["patches"], 32)
            self.assertEqual(report["path"]["retractions"], 0)
            self.assertEqual((report["orientation"]["collisions"], report["orientation"]["gouges"]), (0, 0))
            with open(os.path.join(out, "fusion_mold.h")) as fh:
                blocks = fh.read().splitlines()
            self.assertGreater(len(blocks), report["path"]["points"])
            self.assertIn("0 retractions", stdout)


if __name__ == "__main__":
    unittest.main()
