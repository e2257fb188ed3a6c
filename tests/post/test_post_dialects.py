"""The four controller dialects: read each program back from its text alone, put its moves
through the machine's forward kinematics and compare with the CL data (tip within 1 um, axis
within 1e-6 rad, or the resolution of the control's number format where that is coarser)."""
import hashlib
import os
import subprocess
import unittest

import numpy as np

from tsplcam.errors import InputError
from tsplcam.post import post_program
from tsplcam.post import dialects, rs274
from tsplcam.post.kinematics import angle_between, linear_joints
from tsplcam.post.synthetic import helix, hemisphere_sweep, pole_pass
from conftest import REPO_DIR, artifact_path

CASES = [  # machine, dialect, orientation
    ("mikron_ucp600_heidenhain", "heidenhain", "angles"),
    ("mikron_ucp600_heidenhain", "heidenhain", "vector"),
    ("bc_head_table_sinumerik", "sinumerik", "angles"),
    ("bc_head_table_sinumerik", "sinumerik", "vector"),
    ("bc_head_head_fanuc", "fanuc", "angles"),
    ("bc_head_head_fanuc", "fanuc", "vector"),
    ("mikron_ucp600_heidenhain", "fanuc", "angles"),
    ("mikron_ucp600_heidenhain", "sinumerik", "angles"),
    ("bc_head_table_sinumerik", "heidenhain", "angles"),
    ("linuxcnc_xyzac_trt", "linuxcnc", "angles"),
]


_ORIENTED = []


def oriented_keycap():
    """A real job's path: the keycap's top and a side wall, tool axes smoothed for the A/C
    table (the keycap job at a coarse scallop, cut short)."""
    if not _ORIENTED:
        from tsplcam.orientation import CollisionChecker, load_tool, orient
        from tsplcam.post import load_machine
        from tsplcam.toolpath import zigzag_path
        from tsplcam import load_model
        from tsplcam.toolpath.zigzag import default_plan
        model = load_model("keycap")
        tool = load_tool("ball1_keycap")
        path = zigzag_path(model, default_plan(model), tool.ball_radius, 0.2, 0.001)
        keep = np.isin(path.patch, (0, 4))
        first, last = np.argmax(keep), len(keep) - np.argmax(keep[::-1])
        from dataclasses import replace
        path = replace(path, contact=path.contact[first:last], normal=path.normal[first:last],
                       axis=path.axis[first:last], move=path.move[first:last], patch=path.patch[first:last],
                       uv=path.uv[first:last], line=path.line[first:last])
        out, _ = orient(path, strategy="smooth", checker=CollisionChecker(model, tool, clearance=0.3),
                        machine=load_machine("mikron_ucp600_heidenhain"))
        _ORIENTED.append(out)
    return _ORIENTED[0]


def paths():
    return {"hemisphere": hemisphere_sweep(n=300), "helix": helix(n=400, turns=2.5, tilt=25.0, radius=30.0),
            "pole": pole_pass(miss=0.1, tilt=15.0, length=40.0), "keycap job": oriented_keycap()}


def interpret_linuxcnc(case, r):
    """Every LinuxCNC program of these tests also goes through LinuxCNC's interpreter."""
    if r.dialect != "linuxcnc" or rs274.executable() is None:
        return
    res = rs274.run(r.text, precise=False)
    case.assertTrue(res.ok, res.errors)
    case.assertEqual(len(res.moves), len(dialects.get("linuxcnc").read(r.text)))


def angle_bound(decimals):
    """Largest tool-axis error (rad) from rounding both angles to ``decimals`` places (deg)."""
    return np.sqrt(2.0) * 0.5 * 10.0 ** -decimals * np.pi / 180.0 * (1 + 1e-6)


class RoundTrip(unittest.TestCase):
    def check_case(self, machine, dialect, orientation, tp, label, report):
        r = post_program(tp, machine, dialect, orientation=orientation)
        interpret_linuxcnc(self, r)
        mod = dialects.get(dialect)
        moves = mod.read(r.text)
        prog = [mv for mv in moves if mv.program]
        self.assertEqual(len(prog), len(r.motion), label)
        tips, axes = dialects.poses(r.machine, moves, r.settings, mod.JOINT_SPACE)
        s = r.settings
        lin = 0.5 * 10.0 ** -s["decimals"]["linear"] * np.sqrt(3) * (1 + 1e-6)
        if orientation == "vector":
            ang = 1e-6
        elif mod.JOINT_SPACE:
            ang = angle_bound(s["decimals"]["angle"])
        else:
            ang = max(1e-6, angle_bound(s["decimals"]["angle"]))
        # 1. the text gives back what the post meant
        e_tip = np.linalg.norm(tips - r.motion.tip, axis=1).max()
        e_ax = angle_between(axes, r.motion.axis).max()
        self.assertLess(e_tip, max(lin, 1e-3) if mod.JOINT_SPACE else lin, label)
        self.assertLess(e_ax, ang, label)
        # 2. and what the post meant is the CL data: path points exactly (outside the singular
        # cone), inserted points on the programmed segments, approach/retract on the tool axis.
        src = r.motion.source
        on = np.nonzero((src >= 0) & (src == np.floor(src)))[0]
        idx = src[on].astype(int)
        sing = r.solution.singular[idx]
        ok = ~sing if orientation == "angles" else np.ones(len(idx), bool)
        e_cl_tip = np.linalg.norm(tips[on][ok] - tp.tip[idx][ok], axis=1).max()
        e_cl_ax = angle_between(axes[on][ok], tp.axis[idx][ok]).max()
        self.assertLess(e_cl_tip, 1e-3, label)
        self.assertLess(e_cl_ax, ang, label)
        if sing.any() and orientation == "angles":
            # Inside the singular cone the axis moves at most the cone; the ball centre stays.
            centre = tips[on][sing] + tp.tool_radius * axes[on][sing]
            self.assertLess(np.linalg.norm(centre - tp.center[idx][sing], axis=1).max(), 1e-3, label)
            self.assertLess(np.degrees(angle_between(axes[on][sing], tp.axis[idx][sing]).max()),
                            s["singular_cone"] + 1e-4, label)
        ins = np.nonzero((src >= 0) & (src != np.floor(src)))[0]
        if len(ins):
            a, b = np.floor(src[ins]).astype(int), np.ceil(src[ins]).astype(int)
            f = (src[ins] - a)[:, None]
            row_of = {int(v): k for k, v in enumerate(src) if v >= 0 and v == np.floor(v)}
            ra, rb = [row_of[int(x)] for x in a], [row_of[int(x)] for x in b]
            expect = (1 - f) * r.motion.tip[ra] + f * r.motion.tip[rb]
            self.assertLess(np.linalg.norm(tips[ins] - expect, axis=1).max(), 1e-3, label)
        first = np.nonzero(src == 0)[0][0]
        for k in range(first):                     # approach rows: on the first tool axis, above it
            v = tips[k] - tp.tip[0]
            along = v @ tp.axis[0]
            self.assertGreaterEqual(along, s["approach_distance"] - 1e-3, label)
            self.assertLess(np.linalg.norm(v - along * tp.axis[0]), 2e-3 * max(1.0, along / 100), label)
        report.append(f"  {label:<58} tip {e_tip * 1000:7.4f} um  axis {e_ax:.2e} rad  "
                      f"(CL: {e_cl_tip * 1000:.4f} um, {e_cl_ax:.2e} rad), {len(r.motion)} blocks")
        return r, moves

    def test_every_dialect_round_trips(self):
        report = []
        for machine, dialect, orientation in CASES:
            for name, tp in paths().items():
                self.check_case(machine, dialect, orientation, tp,
                                f"{dialect}/{orientation} on {machine}, {name}", report)
        print("\n" + "\n".join(report))
        with open(artifact_path("post_round_trip.txt"), "w") as f:
            f.write("\n".join(report) + "\n")

    def test_feed_words(self):
        """The F words, read back from the program text with the machine file, give every feed
        block the time the post meant, t = max(L / feed, max over axes |dq| / v_max), L the
        tool tip's length (docs/post.md section 3.4). Inverse time (G93, F = 1 / t on every G1)
        by default only where the control cannot compute the tip's feed: LinuxCNC's
        joint-coordinate program. With tool centre point control on (Heidenhain FUNCTION TCPM
        F TCP, Sinumerik TRAORI, Fanuc G43.4/G43.5) G94 and F = L / t, the tip's feed in
        mm/min: the path feed wherever no axis limit slows the block. Either on request; a
        joint-coordinate G94 program's F is the joints' XYZ length (or rotary degrees) per
        minute, as LinuxCNC reads it."""
        tp = hemisphere_sweep(n=200)
        for machine, dialect, options, g93 in (
                ("mikron_ucp600_heidenhain", "heidenhain", {}, False),
                ("bc_head_table_sinumerik", "sinumerik", {}, False),
                ("bc_head_head_fanuc", "fanuc", {}, False),
                ("mikron_ucp600_heidenhain", "fanuc", {}, False),
                ("linuxcnc_xyzac_trt", "linuxcnc", {}, True),
                ("bc_head_table_sinumerik", "sinumerik", {"inverse_time": True}, True),
                ("bc_head_head_fanuc", "fanuc", {"inverse_time": True}, True),
                ("linuxcnc_xyzac_trt", "linuxcnc", {"inverse_time": False}, False)):
            label = f"{dialect} on {machine} {options}"
            r = post_program(tp, machine, dialect, **options)
            interpret_linuxcnc(self, r)
            self.assertEqual("G93" in r.text, g93, label)
            self.assertEqual(r.settings["inverse_time"], g93, label)
            m = r.machine
            mod = dialects.get(dialect)
            moves = [mv for mv in mod.read(r.text) if mv.program]
            tips, axes = dialects.poses(m, moves, r.settings, mod.JOINT_SPACE)
            names = m.axis_names
            rot = np.array([[mv.words[names[3]], mv.words[names[4]]] for mv in moves])
            if mod.JOINT_SPACE:
                J = np.array([[mv.words[n] for n in names] for mv in moves])
            else:
                J = np.column_stack([linear_joints(m, tips, rot[:, 0], rot[:, 1], r.settings["tool_length"],
                                                   r.settings["part_origin"]), rot])
            vmax = m.max_velocity * 60
            checked = at_feed = 0
            for i in range(1, len(moves)):
                mv = moves[i]
                if mv.rapid:
                    continue
                self.assertEqual(mv.inverse_time, g93, f"{label} line {mv.line}")
                self.assertIsNotNone(mv.feed, f"{label} line {mv.line}: feed block without F")
                L = np.linalg.norm(tips[i] - tips[i - 1])
                dq = np.abs(J[i] - J[i - 1])
                f_path = tp.feed                 # every block of this path runs at the path feed
                t = max(L / f_path, (dq / vmax).max())
                tol = 2e-3 * t + 1e-6
                if g93:
                    t_read = 1.0 / mv.feed
                elif mod.JOINT_SPACE:
                    lin = np.linalg.norm(dq[:3])
                    t_read = (lin if lin > 1e-9 else np.linalg.norm(dq[3:])) / mv.feed
                    tol += 2 * np.sqrt(3) * 0.5e-4 / mv.feed     # joints printed to 4 decimals
                else:
                    if L < 1e-3:
                        continue
                    t_read = L / mv.feed         # F: the tip's feed in mm/min
                    self.assertLessEqual(mv.feed, f_path + 1e-9, f"{label} line {mv.line}")
                    at_feed += abs(mv.feed - f_path) < 1e-9
                self.assertAlmostEqual(t_read, t, delta=tol, msg=f"{label} line {mv.line}")
                checked += 1
            self.assertGreater(checked, 100, label)
            if not g93 and not mod.JOINT_SPACE:
                self.assertGreater(at_feed, checked // 2, label)

    def test_inverse_time_setting(self):
        """inverse_time is true, false or "auto", in a call and in a machine file; the TNC has
        none (its F TCP is the tool point's feed already)."""
        tp = hemisphere_sweep(n=20)
        with self.assertRaises(InputError):
            post_program(tp, "mikron_ucp600_heidenhain", "heidenhain", inverse_time=True)
        with self.assertRaises(InputError):
            post_program(tp, "bc_head_head_fanuc", "fanuc", inverse_time="yes")
        r = post_program(tp, "bc_head_head_fanuc", "fanuc", inverse_time="auto")
        self.assertNotIn("G93", r.text)
        from tsplcam.post.machine import machine_from_dict
        import json
        doc = json.load(open(os.path.join(REPO_DIR, "tsplcam", "data", "machines", "bc_head_head_fanuc.json")))
        doc["post"]["inverse_time"] = True
        self.assertIn("G93 G1", post_program(tp, machine_from_dict(doc, "m.json"), "fanuc").text)
        doc["post"]["inverse_time"] = 1
        with self.assertRaises(InputError) as cm:
            machine_from_dict(doc, "m.json")
        self.assertIn("post.inverse_time", str(cm.exception))

    def test_same_input_same_bytes(self):
        tp = hemisphere_sweep(n=150)
        code = ("import hashlib\nfrom tsplcam.post import post_program\n"
                "from tsplcam.post.synthetic import hemisphere_sweep\n"
                "tp = hemisphere_sweep(n=150)\n"
                "for m, d in {cases!r}:\n"
                "    print(hashlib.sha256(post_program(tp, m, d).text.encode()).hexdigest())\n")
        cases = [(m, d) for m, d, o in CASES if o == "angles"]
        here = [hashlib.sha256(post_program(tp, m, d).text.encode()).hexdigest() for m, d in cases]
        again = [hashlib.sha256(post_program(tp, m, d).text.encode()).hexdigest() for m, d in cases]
        self.assertEqual(here, again)
        # a second process, and one whose memory layout is shifted first: the last bits of
        # vectorised sums may follow alignment, and no decision may hang on them
        shifted = "import numpy as _np\n_pad = [_np.empty(7 * k + 1) for k in range(40)]\n"
        for preamble in ("", shifted):
            res = subprocess.run(["/usr/bin/python3", "-c", preamble + code.format(cases=cases)],
                                 capture_output=True, text=True, cwd=REPO_DIR,
                                 env=dict(os.environ, PYTHONPATH=REPO_DIR, PYTHONHASHSEED="12345"))
            self.assertEqual(res.returncode, 0, res.stderr)
            self.assertEqual(res.stdout.split(), here)
        self.assertEqual(len(set(here)), len(here))


class SafeStartAndEnd(unittest.TestCase):
    """Units, work offset, tool call, spindle, coolant, rotaries, TCP, approach, retract, end
    appear in this order in each dialect."""

    ORDER = {
        "heidenhain": ["BEGIN PGM TSPLCAM MM", "BLK FORM 0.1 Z", "BLK FORM 0.2", "R0 FMAX M91",
                       "TOOL CALL 1 Z S12000", "R0 FMAX M91", "L A", "M3", "M8",
                       "FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS", "FMAX", "FUNCTION RESET TCPM",
                       "R0 FMAX M91", "M9", "M5", "M30", "END PGM TSPLCAM MM"],
        "sinumerik": ["G17 G90 G71", "G0 SUPA Z", "T1", "M6", "D1", "G54", "S15000 M3", "M8", "G0 B",
                      "TRAORI", "ORIWKS", "ORIAXES", "G0 X", "G1 X", "TRAFOOF", "M9", "M5",
                      "G0 SUPA Z", "M30"],
        "fanuc": ["%", "O1000", "G21 G17 G40 G49 G80 G90 G94", "G90 G53 G0 Z", "T1 M6", "G54",
                  "S14000 M3", "M8", "G0 B", "G0 G43.4 H1 X", "G1 X", "G49", "M9", "M5",
                  "G90 G53 G0 Z", "M30", "%"],
        "linuxcnc": ["G21 G90 G94 G17 G40 G49 G80", "G10 L2 P1 X0 Y0 Z0 A0 C0", "G54", "G92.1",
                     "T1 M6", "G53 G0 Z", "G0 A", "G43 H1", "S10000 M3", "M8", "G0 X", "G93", "G1 X",
                     "G94", "M9", "M5", "G49", "G53 G0 Z", "M2"],
    }

    def test_block_order(self):
        tp = hemisphere_sweep(n=50)
        for machine, dialect in (("mikron_ucp600_heidenhain", "heidenhain"), ("bc_head_table_sinumerik", "sinumerik"),
                                 ("bc_head_head_fanuc", "fanuc"), ("linuxcnc_xyzac_trt", "linuxcnc")):
            r = post_program(tp, machine, dialect)
            interpret_linuxcnc(self, r)
            lines = r.text.splitlines()
            pos = 0
            for want in self.ORDER[dialect]:
                while pos < len(lines) and want not in lines[pos]:
                    pos += 1
                self.assertLess(pos, len(lines), f"{dialect}: {want!r} missing or out of order")
                pos += 1
            with open(artifact_path(f"post_sample_{dialect}.txt"), "w") as f:
                f.write(r.text)

    def test_heidenhain_numbering_and_signs(self):
        r = post_program(hemisphere_sweep(n=30), "mikron_ucp600_heidenhain", "heidenhain")
        lines = r.text.splitlines()
        self.assertEqual([int(ln.split()[0]) for ln in lines], list(range(len(lines))))
        for ln in lines:
            if ln.split()[1] == "L":
                for tok in ln.split()[2:]:
                    if tok[0] in "XYZAC" and tok[1:2] not in ("",):
                        self.assertIn(tok[1], "+-", ln)

    def test_metrics_take_the_posts_poses(self):
        """The orientation's metrics given the post's poses of the path's points
        (post.metrics_solution: the machine's tool length and part origin, the default cone and
        swing limit) are the metrics that solve the poses themselves, field for field; a post
        with another tool length, part origin, cone or swing limit gives none to take."""
        from dataclasses import asdict
        from tsplcam.post.post import metrics_solution
        from tsplcam.verify.orientation import orientation_metrics
        for tp, machine in ((oriented_keycap(), "mikron_ucp600_heidenhain"), (helix(n=400, turns=2.5, tilt=25.0,
                                                                                     radius=30.0), "linuxcnc_xyzac_trt")):
            r = post_program(tp, machine)
            sol = metrics_solution(r)
            self.assertIs(sol, r.solution)
            own, taken = orientation_metrics(tp, None, r.machine), orientation_metrics(tp, None, r.machine, joints=sol)
            self.assertEqual(repr(asdict(own)), repr(asdict(taken)))
            for options in ({"tool_length": r.machine.tool_length + 10.0}, {"part_origin": (1.0, 0.0, 0.0)},
                            {"singular_cone": 1.0}, {"swing_limit": 7.0}):
                self.assertIsNone(metrics_solution(post_program(tp, machine, **options)), options)

    def test_approach_from_safe_height(self):
        # On the table-table machine the tool axis is machine Z: the first move in the program
        # frame puts the spindle gauge point at the safe Z, straight above the first point.
        r = post_program(hemisphere_sweep(n=40), "mikron_ucp600_heidenhain", "heidenhain")
        m = r.machine
        j0 = r.motion.joints[0]
        self.assertAlmostEqual(j0[2] + m.tool_length, m.safe_z, places=6)
        self.assertTrue(r.motion.rapid[0] and r.motion.rapid[1] and not r.motion.rapid[2])
        self.assertTrue(np.allclose(r.motion.joints[0, 3:], r.motion.joints[2, 3:]))

    def test_heidenhain_ball_centre_reference(self):
        # REFPNT CENTER-CENTER: the program holds ball centres; read back, centre - R K is the tip.
        tp = hemisphere_sweep(n=120)
        r = post_program(tp, "mikron_ucp600_heidenhain", "heidenhain", refpnt="CENTER-CENTER")
        self.assertIn("REFPNT CENTER-CENTER", r.text)
        moves = [mv for mv in dialects.get("heidenhain").read(r.text) if mv.program]
        raw = np.array([[mv.words[a] for a in "XYZ"] for mv in moves])
        tips, axes = dialects.poses(r.machine, moves, r.settings, False)
        src = r.motion.source
        on = src >= 0
        self.assertLess(np.linalg.norm(raw[on] - tp.center[src[on].astype(int)], axis=1).max(), 1e-4)
        self.assertLess(np.linalg.norm(tips[on] - tp.tip[src[on].astype(int)], axis=1).max(), 1e-3)

    def test_bad_options(self):
        tp = hemisphere_sweep(n=20)
        with self.assertRaises(InputError):
            post_program(tp, "linuxcnc_xyzac_trt", "linuxcnc", orientation="vector")
        with self.assertRaises(InputError):
            post_program(tp, "linuxcnc_xyzac_trt", "okuma")
        with self.assertRaises(InputError):
            post_program(tp, "linuxcnc_xyzac_trt", "linuxcnc", feedrate=3)
        with self.assertRaises(InputError):
            post_program(tp, "mikron_ucp600_heidenhain", "heidenhain", tcp="M999")


class Reorientation(unittest.TestCase):
    def test_rewind_at_the_c_limit_leaves_the_part(self):
        # The fork head's C (-200..200) cannot follow three turns of the tool axis: the post
        # retracts, turns C back at the safe height and approaches again; no cutting block
        # swings the tool axis.
        tp = helix(n=600, turns=3.0, tilt=30.0, radius=30.0)
        r = post_program(tp, "bc_head_head_fanuc", "fanuc")
        self.assertGreaterEqual(r.reorientations, 2)
        c = r.motion.joints[:, 4]
        self.assertTrue(((c >= -200) & (c <= 200)).all())
        feed = ~r.motion.rapid[1:]
        big = np.abs(np.diff(c)) > 30
        self.assertFalse((big & feed).any())
        moves = [mv for mv in dialects.get("fanuc").read(r.text) if mv.program]
        tips, axes = dialects.poses(r.machine, moves, r.settings, False)
        src = r.motion.source
        on = src >= 0
        self.assertLess(np.linalg.norm(tips[on] - tp.tip[src[on].astype(int)], axis=1).max(), 1e-3)


if __name__ == "__main__":
    unittest.main()
