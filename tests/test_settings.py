"""JobSettings: one default per option, a check that names the option, and a JSON form
that refuses unknown keys by name."""
import json
import math
import unittest

from tsplcam.errors import InputError
from tsplcam.settings import JobSettings


class Settings(unittest.TestCase):
    def test_defaults_are_the_main_job(self):
        s = JobSettings().check()
        self.assertEqual((s.model, s.tool, s.orientation, s.machine, s.dialect),
                         ("keycap", "ball1_keycap", "smooth", "mikron_ucp600_heidenhain", None))
        # 0.005 and 0.3 are the values written in the dataclass: the same float literal
        self.assertEqual((s.scallop, s.chord_tol, s.holder_clearance, s.smoothing_length), (0.005, 0.001, 0.3, 5.0))

    def test_json_round_trip_and_unknown_keys(self):
        s = JobSettings(model="head", scallop=0.01, orientation="closest-z", dialect="fanuc", balance=False)
        text = json.dumps(s.to_dict())
        self.assertEqual(JobSettings.from_dict(json.loads(text)), s)
        with self.assertRaises(InputError) as cm:
            JobSettings.from_dict({"scallop": 0.01, "scalop": 0.01, "tool_diameter": 1}, path="job.json")
        msg = str(cm.exception)
        self.assertIn("job.json", msg)
        self.assertIn("'scalop'", msg)
        self.assertIn("'tool_diameter'", msg)
        with self.assertRaises(InputError) as cm:
            JobSettings.from_dict({"feed": -1}, path="job.json")
        self.assertIn("job.json", str(cm.exception))
        self.assertIn("feed", str(cm.exception))
        with self.assertRaises(InputError):
            JobSettings.from_dict(["scallop", 0.01])

    def test_check_names_the_option(self):
        bad = [("tool_radius", -1.0), ("tool_radius", 0), ("scallop", math.nan), ("scallop", math.inf),
               ("chord_tol", 0.0), ("max_step", -2.0), ("feed", 0), ("clearance", -1.0),
               ("holder_clearance", -0.1), ("smoothing_length", 0.0), ("rotary_weight", -1.0),
               ("scallop", "0.01"), ("feed", True), ("orientation", "sideways"), ("clearance_mode", "cube"),
               ("dialect", "klingon"), ("balance", "yes"), ("model", ""), ("model", None),
               ("scallop", 0.6),                          # not below the 0.5 mm ball radius
               ("max_lead", 95.0), ("max_lead", -1.0), ("max_side_tilt", 90.0), ("max_axis_step", 0.0),
               ("max_axis_step", 200.0)]
        for name, value in bad:
            with self.subTest(name=name, value=value):
                s = JobSettings(**{"tool_radius": 0.5, name: value})
                with self.assertRaises(InputError) as cm:
                    s.check(lambda n: "--" + n.replace("_", "-"))
                self.assertEqual(cm.exception.item, "--" + name.replace("_", "-"))

    def test_tool_axis_limits_reach_the_orientation(self):
        """The job's lead, side-tilt and axis-step limits are the orientation stage's cone and
        step (its own names: lead_max, tilt_max, max_step)."""
        o = JobSettings(max_lead=20.0, max_side_tilt=25.0, max_axis_step=4.0).check().orientation_settings()
        self.assertEqual((o.lead_max, o.tilt_max, o.max_step), (20.0, 25.0, 4.0))
        d = JobSettings().orientation_settings()
        self.assertEqual((d.lead_max, d.tilt_max, d.max_step), (60.0, 60.0, 10.0))

    def test_options_that_need_each_other(self):
        with self.assertRaises(InputError) as cm:
            JobSettings(tool=None, tool_radius=0.5).check()
        self.assertEqual(cm.exception.item, "orientation")          # smooth axes need the tool's holder
        with self.assertRaises(InputError) as cm:
            JobSettings(tool=None, orientation="normal").check()
        self.assertEqual(cm.exception.item, "tool_radius")          # no radius at all
        JobSettings(tool=None, tool_radius=0.5, orientation="normal", machine=None).check()
        for name, value in (("gcode", "x.ngc"), ("dialect", "fanuc"), ("rotary_weight", 1.0)):
            with self.assertRaises(InputError) as cm:
                JobSettings(machine=None, **{name: value}).check()
            self.assertEqual(cm.exception.item, name)

    def test_option_names_per_command(self):
        job, path = JobSettings.option_names("job"), JobSettings.option_names("path")
        self.assertIn("out", job)
        self.assertNotIn("gcode", job)
        self.assertIn("gcode", path)
        self.assertNotIn("out", path)
        # the job's outputs are a folder, the program's name, the HTML report and the FreeCAD document; the rest is shared
        self.assertEqual(set(job) & set(path), set(job) - {"out", "name", "html_report", "fcstd"})
        self.assertIn("verify", job)
        self.assertIn("baseline", job)
        self.assertNotIn("baseline_cl", job)


if __name__ == "__main__":
    unittest.main()
