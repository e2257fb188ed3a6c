"""Machine definition files: shipped machines, schema errors, the machines command."""
import contextlib
import io
import json
import os
import subprocess
import tempfile
import unittest
from unittest import mock

from tsplcam.errors import InputError
from tsplcam.post import list_machines, load_machine
from tsplcam.post.machine import machine_from_dict, read_machine, shipped_dir
from conftest import REPO_DIR

SYSTEM_PYTHON = "/usr/bin/python3"
SHIPPED = ("mikron_ucp600_heidenhain", "bc_head_table_sinumerik", "linuxcnc_xyzac_trt", "bc_head_head_fanuc")
LINUXCNC_SIM_INI = ("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/"
                    "table-rotary-tilting/xyzac-trt.ini")


def ini_sections(path):
    """Minimal INI reader (LinuxCNC repeats keys; only first values are needed here)."""
    out, sec = {}, None
    for line in open(path):
        line = line.split("#")[0].strip()
        if line.startswith("[") and line.endswith("]"):
            sec = out.setdefault(line[1:-1], {})
        elif "=" in line and sec is not None:
            k, v = (x.strip() for x in line.split("=", 1))
            sec.setdefault(k, v)
    return out


class ShippedMachines(unittest.TestCase):
    def test_all_shipped_machines_load(self):
        names = dict(list_machines())
        for name in SHIPPED:
            self.assertIn(name, names)
            m = load_machine(name)
            self.assertEqual(m.name, name)
        kinds = {load_machine(n).kind for n in SHIPPED}
        self.assertEqual(kinds, {"table-table", "head-table", "head-head"})
        self.assertEqual(load_machine("mikron_ucp600_heidenhain").controller, "heidenhain")
        self.assertEqual(load_machine("mikron_ucp600_heidenhain").axis_names, ("X", "Y", "Z", "A", "C"))
        self.assertEqual(load_machine("bc_head_table_sinumerik").axis_names[3:], ("B", "C"))

    def test_linuxcnc_machine_carries_the_pin_names(self):
        m = load_machine("linuxcnc_xyzac_trt")
        for pin in ("x-rot-point", "y-rot-point", "z-rot-point", "y-offset", "z-offset",
                    "tool-offset", "conventional-directions"):
            self.assertIn(pin, m.linuxcnc)
        self.assertEqual(m.linuxcnc["kinematics"], "xyzac-trt-kins")
        # C about the rot-point line; A about rot-point + (0, y-offset, z-offset); pins' default
        # (unconventional) directions turn the table by +value. Exact by construction: sums of
        # the whole numbers the file gives.
        self.assertEqual(m.rotary.pivot, (0.0, 0.0, 0.0))
        self.assertEqual(m.tilt.pivot, (0.0, 20.0, 10.0))
        self.assertEqual((m.tilt.sign, m.rotary.sign), (1, 1))

    def test_linuxcnc_machine_matches_the_sim_config(self):
        if not os.path.exists(LINUXCNC_SIM_INI):
            raise unittest.SkipTest("LinuxCNC sim configs not installed")
        ini = ini_sections(LINUXCNC_SIM_INI)
        m = load_machine("linuxcnc_xyzac_trt")
        # exact by construction: the same decimal literals in both files (x 60: whole numbers)
        for n in "XYZ":
            a = ini[f"AXIS_{n}"]
            self.assertEqual(m.linear[n].min, float(a["MIN_LIMIT"]))
            self.assertEqual(m.linear[n].max, float(a["MAX_LIMIT"]))
            self.assertEqual(m.linear[n].max_velocity, 60 * float(a["MAX_VELOCITY"]))
            self.assertEqual(m.linear[n].max_acceleration, float(a["MAX_ACCELERATION"]))
        for ax in (m.tilt, m.rotary):
            a = ini[f"AXIS_{ax.name}"]
            self.assertEqual((ax.min, ax.max), (float(a["MIN_LIMIT"]), float(a["MAX_LIMIT"])))
            self.assertEqual(ax.max_velocity, 60 * float(a["MAX_VELOCITY"]))
        hal = open(LINUXCNC_SIM_INI).read()
        self.assertIn("sets :y-offset     20", hal)
        self.assertIn("sets :z-offset     10", hal)

    def test_json_round_trip(self):
        for name in SHIPPED:
            m = load_machine(name)
            m2 = machine_from_dict(json.loads(m.to_json()), "<json>")
            self.assertEqual(m2.to_dict(), m.to_dict())    # exact: JSON writes repr, reads it back
            for a in ("tilt", "rotary"):
                self.assertEqual(getattr(m2, a), getattr(m, a))


class SchemaErrors(unittest.TestCase):
    def setUp(self):
        with open(os.path.join(shipped_dir(), "mikron_ucp600_heidenhain.json")) as f:
            self.doc = json.load(f)
        self.tmp = tempfile.TemporaryDirectory()

    def tearDown(self):
        self.tmp.cleanup()

    def write(self, doc, text=None):
        path = os.path.join(self.tmp.name, "m.json")
        with open(path, "w") as f:
            f.write(text if text is not None else json.dumps(doc, indent=2))
        return path

    def error(self, doc=None, text=None):
        path = self.write(doc, text)
        with self.assertRaises(InputError) as cm:
            read_machine(path)
        msg = str(cm.exception)
        self.assertIn(path, msg)
        return msg

    def test_errors_name_file_and_key(self):
        d = json.loads(json.dumps(self.doc))
        d["rotary_axes"]["A"]["max"] = "lots"
        self.assertIn("rotary_axes.A.max", self.error(d))
        d = json.loads(json.dumps(self.doc))
        del d["linear_axes"]["Y"]["max_velocity"]
        self.assertIn("linear_axes.Y.max_velocity: missing", self.error(d))
        d = json.loads(json.dumps(self.doc))
        d["rotary_axes"]["C"]["maximum"] = 3
        self.assertIn("rotary_axes.C.maximum: unknown key", self.error(d))
        d = json.loads(json.dumps(self.doc))
        d["kind"] = "robot"
        self.assertIn("kind: must be one of", self.error(d))
        d = json.loads(json.dumps(self.doc))
        d["format"] = "something"
        self.assertIn("format", self.error(d))
        d = json.loads(json.dumps(self.doc))
        d["version"] = 2
        self.assertIn("version", self.error(d))
        d = json.loads(json.dumps(self.doc))
        d["rotary_axes"]["A"]["min"] = 200
        self.assertIn("rotary_axes.A.max: must be greater than min", self.error(d))
        d = json.loads(json.dumps(self.doc))
        d["rotary_axes"]["C"]["about"] = "Y"
        self.assertIn("rotary_axes", self.error(d))
        d = json.loads(json.dumps(self.doc))
        d["post"]["spindel"] = 3
        self.assertIn("post.spindel", self.error(d))

    def test_bad_json_names_the_line(self):
        text = json.dumps(self.doc, indent=2).replace('"kind": "table-table",', '"kind": "table-table"', 1)
        path = self.write(None, text)
        with self.assertRaises(InputError) as cm:
            read_machine(path)
        self.assertEqual(cm.exception.path, path)
        self.assertEqual(cm.exception.line, 8)      # the line after the missing comma
        self.assertIn("not valid JSON", str(cm.exception))

    def test_linuxcnc_pins_checked(self):
        d = json.load(open(os.path.join(shipped_dir(), "linuxcnc_xyzac_trt.json")))
        d["linuxcnc"]["tool-offset"] = 50
        self.assertIn("linuxcnc.tool-offset", self.error(d))
        d = json.load(open(os.path.join(shipped_dir(), "linuxcnc_xyzac_trt.json")))
        del d["linuxcnc"]["y-offset"]
        self.assertIn("linuxcnc.y-offset: missing", self.error(d))
        d = json.load(open(os.path.join(shipped_dir(), "linuxcnc_xyzac_trt.json")))
        d["rotary_axes"]["A"]["pivot"] = [0, 0, 0]
        self.assertIn("rotary_axes.A.pivot: unknown key", self.error(d))

    def test_unknown_machine_name(self):
        with self.assertRaises(InputError) as cm:
            load_machine("no_such_machine")
        self.assertIn("linuxcnc_xyzac_trt", str(cm.exception))


class MachinesCommand(unittest.TestCase):
    """The machines command: one run as its own process (the exit code and the error on
    stderr), the rest through the same entry point (tsplcam.cli.main) in this process,
    which saves a start of Python and numpy (about 0.5 CPU-s) per call."""

    def run_cli(self, *args, env=None):
        e = dict(os.environ, PYTHONPATH=REPO_DIR)
        e.update(env or {})
        return subprocess.run([SYSTEM_PYTHON, "-m", "tsplcam", *args], capture_output=True, text=True,
                              env=e, cwd=REPO_DIR)

    def run_here(self, *args, env=None):
        """The command through ``tsplcam.cli.main`` in this process: (exit code, stdout, stderr)."""
        from tsplcam.cli import main
        out, err = io.StringIO(), io.StringIO()
        with mock.patch.dict(os.environ, env or {}), contextlib.redirect_stdout(out), \
                contextlib.redirect_stderr(err):
            code = main(list(args))
        return code, out.getvalue(), err.getvalue()

    def test_list_and_show(self):
        code, out, err = self.run_here("machines")
        self.assertEqual(code, 0, err)
        for name in SHIPPED:
            self.assertIn(name, out)
        code, out, err = self.run_here("machines", "show", "linuxcnc_xyzac_trt", "--json")
        self.assertEqual(code, 0, err)
        m = machine_from_dict(json.loads(out))
        self.assertEqual(m.to_dict(), load_machine("linuxcnc_xyzac_trt").to_dict())   # repr round trip
        code, out, err = self.run_here("machines", "show", "mikron_ucp600_heidenhain")
        self.assertEqual(code, 0, err)
        self.assertIn("A: table, about X", out)

    def test_unknown_machine_in_its_own_process(self):
        res = self.run_cli("machines", "show", "nope")
        self.assertEqual(res.returncode, 2)
        self.assertIn("unknown machine", res.stderr)
        self.assertNotIn("Traceback", res.stderr)
        self.assertEqual(res.stdout, "")

    def test_user_machine_folder(self):
        with tempfile.TemporaryDirectory() as folder:
            doc = json.load(open(os.path.join(shipped_dir(), "bc_head_table_sinumerik.json")))
            doc["name"] = "my_mill"
            doc["rotary_axes"]["B"]["max"] = 95.0
            with open(os.path.join(folder, "my_mill.json"), "w") as f:
                json.dump(doc, f)
            code, out, err = self.run_here("machines", env={"TSPLCAM_MACHINE_PATH": folder})
            self.assertIn("my_mill", out)
            code, out, err = self.run_here("machines", "show", "my_mill", "--json",
                                           env={"TSPLCAM_MACHINE_PATH": folder})
            self.assertEqual(code, 0, err)
            self.assertEqual(json.loads(out)["rotary_axes"]["B"]["max"], 95.0)   # the literal, echoed


if __name__ == "__main__":
    unittest.main()
