"""Machine kinematics of the post stage against independent references.

References: LinuxCNC's own kinematics formulas (xyzac-trt, xyzbc-trt, 5axiskins, maxkins as
transcribed in docs/post.md section 2.2 from src/emc/kinematics), the worked example of
docs/post.md section 2.3, and round trips forward(inverse(x)) on thousands of random poses.
"""
import unittest

import numpy as np

from tsplcam.errors import KinematicsError
from tsplcam.post import load_machine
from tsplcam.post.kinematics import (angle_between, forward, inverse_orientation, linear_joints,
                                     linearise, joint_deviation, orientation, solve_joints)
from tsplcam.post.machine import machine_from_dict
from tsplcam.post.synthetic import helix, pole_pass

D = np.pi / 180


def make_machine(kind="table-table", tilt="A", tilt_sign=-1, rot_sign=-1, zeros=(0.0, 0.0),
                 tilt_pivot=(0.0, 0.0, 0.0), rot_pivot=(0.0, 0.0, 0.0), tilt_range=(-120.0, 120.0),
                 rot_range=None, linuxcnc=None, tool_length=0.0, part_origin=(0.0, 0.0, 0.0)):
    """A machine document built in the test, so every kind and sign is covered."""
    big = {"min": -1e5, "max": 1e5, "max_velocity": 10000.0, "max_acceleration": 1000.0}
    t = {"about": "X" if tilt == "A" else "Y", "min": tilt_range[0], "max": tilt_range[1],
         "max_velocity": 3600.0, "max_acceleration": 600.0}
    c = {"about": "Z", "max_velocity": 3600.0, "max_acceleration": 600.0}
    if rot_range is None:
        c["continuous"] = True
    else:
        c.update(min=rot_range[0], max=rot_range[1])
    if linuxcnc is None:
        t.update(sign=tilt_sign, zero=zeros[0], pivot=list(tilt_pivot))
        c.update(sign=rot_sign, zero=zeros[1], pivot=list(rot_pivot))
    doc = {"format": "tsplcam-machine", "version": 1, "name": f"test-{kind}-{tilt}C", "kind": kind,
           "controller": "linuxcnc", "linear_axes": {"X": big, "Y": big, "Z": big},
           "rotary_axes": {tilt: t, "C": c}, "tool_length": tool_length, "safe_z": 1e4,
           "part_origin": list(part_origin)}
    if linuxcnc is not None:
        doc["linuxcnc"] = linuxcnc
    return machine_from_dict(doc, "<test>")


def random_unit(rng, n, zmin=-0.2):
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v[:, 2] = np.maximum(v[:, 2], zmin)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def all_kinds():
    """(label, machine) for every kind, tilt axis and sign, with pivots and zero offsets."""
    out = []
    for kind in ("table-table", "head-table", "head-head"):
        for tilt in ("A", "B"):
            for st, sc in ((1, 1), (-1, -1), (1, -1)):
                out.append((f"{kind} {tilt}C signs {st:+d}{sc:+d}",
                            make_machine(kind, tilt, st, sc, zeros=(7.5, -20.0),
                                         tilt_pivot=(3.0, -12.0, 85.0), rot_pivot=(-4.0, 9.0, 30.0),
                                         tool_length=55.0, part_origin=(11.0, -5.0, 40.0),
                                         tilt_range=(-200.0, 200.0))))
    return out


class RoundTrips(unittest.TestCase):
    def test_forward_of_inverse_on_random_poses_all_kinds_both_branches(self):
        rng = np.random.default_rng(8)
        n = 3000
        worst_tip = worst_axis = 0.0
        for label, m in all_kinds():
            tip = rng.uniform(-80, 80, (n, 3))
            K = random_unit(rng, n)
            tilt, rot, _ = inverse_orientation(m, K)
            for b in range(2):
                xyz = linear_joints(m, tip, tilt[:, b], rot[:, b])
                t2, k2 = forward(m, np.column_stack([xyz, tilt[:, b], rot[:, b]]))
                e_tip = np.linalg.norm(t2 - tip, axis=1).max()
                e_axis = angle_between(k2, K).max()
                worst_tip, worst_axis = max(worst_tip, e_tip), max(worst_axis, e_axis)
                self.assertLess(e_tip, 1e-9, f"{label} branch {b}")
                self.assertLess(e_axis, 1e-12, f"{label} branch {b}")
            # The two branches are the same pose reached two ways: (theta, C) and (-theta, C+180).
            d = np.mod(rot[:, 1] - rot[:, 0], 360.0)
            self.assertTrue(np.allclose(d, 180.0), label)
        print(f"\n  FK(IK) over {len(all_kinds())} machines x 2 branches x {n} poses: "
              f"tip {worst_tip:.2e} mm, axis {worst_axis:.2e} rad")

    def test_inverse_of_forward_recovers_the_joints(self):
        rng = np.random.default_rng(9)
        for label, m in all_kinds():
            n = 2000
            j = np.column_stack([rng.uniform(-50, 50, (n, 3)), rng.uniform(-150, 150, n),
                                 rng.uniform(-400, 400, n)])
            tip, K = forward(m, j)
            tilt, rot, theta = inverse_orientation(m, K)
            ok = theta > 1e-6
            dt = np.abs(tilt - j[:, 3:4])
            dc = np.abs((rot - j[:, 4:5] + 180.0) % 360.0 - 180.0)
            hit = ((dt < 1e-9) & (dc < 1e-9)).any(axis=1)
            self.assertTrue(hit[ok].all(), label)
            xyz = linear_joints(m, tip, j[:, 3], j[:, 4])
            self.assertLess(np.abs(xyz - j[:, :3]).max(), 1e-9, label)

    def test_closed_form_orientation_equals_the_chain(self):
        rng = np.random.default_rng(10)
        for label, m in all_kinds():
            j = np.column_stack([np.zeros((500, 3)), rng.uniform(-150, 150, 500), rng.uniform(-400, 400, 500)])
            _, k = forward(m, j)
            self.assertLess(np.abs(orientation(m, j[:, 3], j[:, 4]) - k).max(), 1e-14, label)


class ExternalReferences(unittest.TestCase):
    """docs/post.md 2.3's worked example and LinuxCNC's trt/5axis/max kinematics formulas."""

    K = np.array([[0.25, 0.5, 0.829156]])

    def angles(self, m):
        tilt, rot, _ = inverse_orientation(m, self.K / np.linalg.norm(self.K))
        return [(float(tilt[0, b]), float((rot[0, b] + 180) % 360 - 180)) for b in range(2)]

    def assertIn(self, want, branches):
        """``want`` (tilt, rotary), given to 4 decimals, is one of the two solution branches:
        within 0.5e-4 deg of it (plus rounding)."""
        near = [b for b in branches if abs(b[0] - want[0]) <= 0.5e-4 + 1e-9
                and abs(b[1] - want[1]) <= 0.5e-4 + 1e-9]
        self.assertTrue(near, f"{want} is not among {branches}")

    def test_worked_example(self):
        iso_ac = make_machine("table-table", "A", -1, -1)
        self.assertIn((33.9878, 153.4349), self.angles(iso_ac))
        self.assertIn((-33.9878, -26.5651), self.angles(iso_ac))
        lc_ac = make_machine("table-table", "A", 1, 1)       # LinuxCNC default (unconventional)
        self.assertIn((33.9878, 26.5651), self.angles(lc_ac))
        iso_bc = make_machine("table-table", "B", -1, -1)
        self.assertIn((33.9878, 63.4349), self.angles(iso_bc))
        lc_bc = make_machine("table-table", "B", 1, 1)
        self.assertIn((33.9878, 116.5651), self.angles(lc_bc))
        five = make_machine("head-head", "B", -1, 1)          # 5axiskins: K = (-sinB cosC, -sinB sinC, cosB)
        self.assertIn((33.9878, -116.5651), self.angles(five))
        # The shipped LinuxCNC machine has the pins' default directions.
        self.assertIn((33.9878, 26.5651), self.angles(load_machine("linuxcnc_xyzac_trt")))

    @staticmethod
    def trt_ac(p, A, C, xr, yr, zr, dy, dz, con):
        """xyzacKinematicsInverse (trtfuncs.c), docs/post.md section 2.2."""
        x, y, z = p[:, 0] - xr, p[:, 1] - yr, p[:, 2] - zr
        sA, cA, sC, cC = np.sin(A), np.cos(A), np.sin(C), np.cos(C)
        X = cC * x + con * sC * y + xr
        Y = -con * sC * cA * x + cC * cA * y + con * sA * z - cA * dy - con * sA * dz + dy + yr
        Z = sC * sA * x - con * cC * sA * y + cA * z + con * sA * dy - cA * dz + dz + zr
        return np.column_stack([X, Y, Z])

    @staticmethod
    def trt_bc(p, B, C, xr, yr, zr, dx, dz, con):
        """xyzbcKinematicsInverse with the con-aware dpx/dpz of docs/post.md 2.4 (= bookworm at con=-1)."""
        x, y, z = p[:, 0] - xr, p[:, 1] - yr, p[:, 2] - zr
        sB, cB, sC, cC = np.sin(B), np.cos(B), np.sin(C), np.cos(C)
        dpx = -cB * dx + con * sB * dz + dx
        dpz = -con * sB * dx - cB * dz + dz
        X = cC * cB * x + con * sC * cB * y - con * sB * z + dpx + xr
        Y = -con * sC * x + cC * y + yr
        Z = con * cC * sB * x + sC * sB * y + cB * z + dpz + zr
        return np.column_stack([X, Y, Z])

    @staticmethod
    def trt_bc_bookworm(p, B, C, xr, yr, zr, dx, dz):
        """Bookworm f1270d6ed7 xyzbc inverse (con = -1 only), docs/post.md section 2.4."""
        x, y, z = p[:, 0] - xr, p[:, 1] - yr, p[:, 2] - zr
        sB, cB, sC, cC = np.sin(B), np.cos(B), np.sin(C), np.cos(C)
        dpx = -cB * dx - sB * dz + dx
        dpz = sB * dx - cB * dz + dz
        X = cC * cB * x - sC * cB * y + sB * z + dpx + xr
        Y = sC * x + cC * y + yr
        Z = -cC * sB * x + sC * sB * y + cB * z + dpz + zr
        return np.column_stack([X, Y, Z])

    def test_linuxcnc_trt_inverse_kinematics(self):
        rng = np.random.default_rng(11)
        n = 3000
        worst = 0.0
        for kins in ("xyzac-trt-kins", "xyzbc-trt-kins"):
            for con in (0, 1):
                for _ in range(5):
                    xr, yr, zr = rng.uniform(-30, 30, 3)
                    do, dz = rng.uniform(-40, 40, 2)
                    pins = {"kinematics": kins, "x-rot-point": xr, "y-rot-point": yr, "z-rot-point": zr,
                            "z-offset": dz, "tool-offset": 0.0, "conventional-directions": con}
                    pins["y-offset" if kins.startswith("xyzac") else "x-offset"] = do
                    m = make_machine("table-table", "A" if kins.startswith("xyzac") else "B",
                                     linuxcnc=pins, tilt_range=(-180, 180))
                    p = rng.uniform(-100, 100, (n, 3))
                    a = rng.uniform(-180, 180, n)
                    c = rng.uniform(-720, 720, n)
                    ours = linear_joints(m, p, a, c)
                    s = 1 if con else -1
                    if kins.startswith("xyzac"):
                        ref = self.trt_ac(p, a * D, c * D, xr, yr, zr, do, dz, s)
                    else:
                        ref = self.trt_bc(p, a * D, c * D, xr, yr, zr, do, dz, s)
                        if not con:
                            bw = self.trt_bc_bookworm(p, a * D, c * D, xr, yr, zr, do, dz)
                            self.assertLess(np.abs(bw - ref).max(), 1e-9)
                    err = np.abs(ours - ref).max()
                    worst = max(worst, err)
                    self.assertLess(err, 1e-9, f"{kins} con={con}")
        print(f"\n  LinuxCNC trt inverse kinematics vs tsplcam: {worst:.2e} mm")

    def test_linuxcnc_5axiskins_and_maxkins(self):
        rng = np.random.default_rng(12)
        n = 3000
        Lp = 137.5
        p = rng.uniform(-100, 100, (n, 3))
        B = rng.uniform(-120, 120, n)
        C = rng.uniform(-360, 360, n)
        # 5axiskins: r = s2r(L, C, 180 - B), joints = (x - r.x, y - r.y, z - L - r.z), W = 0.
        ph = (180.0 - B) * D
        r = Lp * np.column_stack([np.sin(ph) * np.cos(C * D), np.sin(ph) * np.sin(C * D), np.cos(ph)])
        ref = p - r - np.array([0.0, 0.0, Lp])
        m = make_machine("head-head", "B", -1, 1, tilt_pivot=(0, 0, Lp), rot_pivot=(0, 0, Lp),
                         tilt_range=(-180, 180))
        self.assertLess(np.abs(linear_joints(m, p, B, C) - ref).max(), 1e-9)
        # maxkins (U = V = W = 0): rho, theta = atan2(y, x) - C; J0 = rho cos theta + con L sin B,
        # J1 = rho sin theta, J2 = z + L cos B - L.
        for con in (1, -1):
            rho = np.hypot(p[:, 0], p[:, 1])
            th = np.arctan2(p[:, 1], p[:, 0]) - C * D
            ref = np.column_stack([rho * np.cos(th) + con * Lp * np.sin(B * D), rho * np.sin(th),
                                   p[:, 2] + Lp * np.cos(B * D) - Lp])
            m = make_machine("head-table", "B", con, -1, tilt_pivot=(0, 0, Lp), tilt_range=(-180, 180))
            self.assertLess(np.abs(linear_joints(m, p, B, C) - ref).max(), 1e-9, f"maxkins con={con}")


class ChoosingSolutions(unittest.TestCase):
    def test_unwinding_a_path_circling_the_c_axis(self):
        m = load_machine("mikron_ucp600_heidenhain")
        for turns in (3.0, -4.5):
            tp = helix(n=900, turns=turns, tilt=35.0)
            sol, tip = solve_joints(m, tp.tip, tp.axis)
            c = sol.joints[:, 4]
            steps = np.abs(np.diff(c))
            self.assertLess(steps.max(), 180.0)
            self.assertLess(steps.max(), 360.0 * abs(turns) / 899 * 1.01)   # follows the axis, no swings
            self.assertAlmostEqual(abs(c[-1] - c[0]), 360.0 * abs(turns), delta=1e-6)
            self.assertEqual(sol.flips, 0)
            t2, k2 = forward(m, sol.joints)
            self.assertLess(np.linalg.norm(t2 - tp.tip, axis=1).max(), 1e-9)
            self.assertLess(angle_between(k2, tp.axis).max(), 1e-12)

    def test_branch_kept_within_tilt_limits(self):
        # Mikron-like A range -30..115: tilts beyond 30 deg exist only on one branch.
        m = load_machine("mikron_ucp600_heidenhain")
        tp = helix(n=300, turns=1.0, tilt=60.0)
        sol, _ = solve_joints(m, tp.tip, tp.axis)
        self.assertTrue(((sol.joints[:, 3] >= -30) & (sol.joints[:, 3] <= 115)).all())
        self.assertEqual(len(set(sol.branch.tolist())), 1)

    def test_path_through_the_singular_pose(self):
        m = load_machine("mikron_ucp600_heidenhain")
        tp = pole_pass(miss=0.0, tilt=20.0)
        sol, tip = solve_joints(m, tp.tip, tp.axis, radius=tp.tool_radius)
        c, a = sol.joints[:, 4], sol.joints[:, 3]
        # Straight through the pole: the other branch keeps C, the tilt passes through zero.
        self.assertLess(np.abs(np.diff(c)).max(), 1e-9)
        self.assertLess(np.abs(np.diff(a)).max(), 0.2 + 1e-9)
        t2, k2 = forward(m, sol.joints)
        self.assertLess(np.linalg.norm(t2 - tp.tip, axis=1).max(), 1e-9)     # tip exact
        self.assertLess(angle_between(k2, tp.axis).max(), 1e-12)             # and the axis

    def test_path_beside_the_singular_pose_inside_the_cone(self):
        m = load_machine("mikron_ucp600_heidenhain")
        cone = 0.5
        for miss in (0.02, 0.1, 0.25):
            tp = pole_pass(miss=miss, tilt=20.0)
            step = np.degrees(angle_between(tp.axis[1:], tp.axis[:-1]).max())
            # Outside the cone C moves at most (axis step) / sin(distance to the pole).
            bound = np.degrees(np.radians(step) / np.sin(np.radians(cone))) * 1.1
            exact, _ = solve_joints(m, tp.tip, tp.axis, singular_cone=0.0)
            sol, tip = solve_joints(m, tp.tip, tp.axis, radius=tp.tool_radius, singular_cone=cone)
            c = sol.joints[:, 4]
            # Exact angles swing C faster near the pole than the bound allows; holding and
            # interpolating the free angle inside the cone keeps every step within it ...
            self.assertGreater(np.abs(np.diff(exact.joints[:, 4])).max(), bound)
            self.assertLess(np.abs(np.diff(c)).max(), bound)
            self.assertLess(np.abs(np.diff(sol.joints[:, 3])).max(), step + 1.0)
            # ... moves the tool axis by at most the cone, keeps the ball centre, and the tip
            # follows the new axis exactly.
            self.assertLessEqual(np.degrees(sol.deviation.max()), cone + 1e-9)
            t2, k2 = forward(m, sol.joints)
            self.assertLess(np.linalg.norm(t2 - tip, axis=1).max(), 1e-9)
            centre = tip + tp.tool_radius * k2
            self.assertLess(np.linalg.norm(centre - tp.center, axis=1).max(), 1e-9)
            outside = ~sol.singular
            self.assertLess(angle_between(k2[outside], tp.axis[outside]).max(), 1e-12)

    def test_vertical_tool_holds_c(self):
        m = load_machine("mikron_ucp600_heidenhain")
        tp = pole_pass(miss=0.0, tilt=0.0)                   # a three-axis path: K = Z everywhere
        sol, tip = solve_joints(m, tp.tip, tp.axis)
        self.assertTrue(sol.singular.all())
        # exact by construction: at a singular pose the solver holds the rotary value it had
        self.assertTrue(np.all(sol.joints[:, 4] == sol.joints[0, 4]))
        self.assertTrue(np.allclose(sol.joints[:, 3], 0.0))
        self.assertLess(np.linalg.norm(tip - tp.tip, axis=1).max(), 1e-12)

    def test_limits_violation_names_the_point(self):
        m = load_machine("mikron_ucp600_heidenhain")
        tp = helix(n=50, turns=0.5, tilt=30.0)
        axis = tp.axis.copy()
        axis[37] = [np.sin(2.1), 0.0, np.cos(2.1)]           # 120 deg tilt: beyond A max 115 either way
        tp.uv[37] = (0.25, 0.75)
        tp.patch[37] = 4
        with self.assertRaises(KinematicsError) as cm:
            solve_joints(m, tp.tip, axis, patch=tp.patch, uv=tp.uv)
        msg = str(cm.exception)
        self.assertIn("point 37", msg)
        self.assertIn("patch 4, u=0.2500, v=0.7500", msg)
        self.assertIn("A=", msg)
        # Linear travel: move one tip far outside X.
        tip = tp.tip.copy()
        tip[12, 0] = 5000.0
        with self.assertRaises(KinematicsError) as cm:
            solve_joints(m, tip, tp.axis)
        self.assertIn("point 12", str(cm.exception))
        self.assertIn("X=", str(cm.exception))

    def test_limited_c_range(self):
        # A C axis of -200..200 cannot follow three turns: the solver never clips, it stays in
        # range and the rewinds show as steps (the post turns them into retracts).
        m = make_machine("head-head", "B", 1, 1, tilt_range=(-100, 100), rot_range=(-200, 200),
                         tilt_pivot=(0, 0, 150), rot_pivot=(0, 0, 150), tool_length=100.0)
        tp = helix(n=600, turns=3.0, tilt=30.0)
        sol, _ = solve_joints(m, tp.tip, tp.axis)
        c = sol.joints[:, 4]
        self.assertTrue(((c >= -200) & (c <= 200)).all())
        big = np.abs(np.diff(c)) > 90
        self.assertGreaterEqual(big.sum(), 2)
        self.assertLessEqual(big.sum(), 3)
        t2, k2 = forward(m, sol.joints)
        self.assertLess(np.linalg.norm(t2 - tp.tip, axis=1).max(), 1e-9)


class HalfTurnAtThePole(unittest.TestCase):
    def test_the_c_half_turn_goes_where_the_axis_is_nearest_the_pole(self):
        """The axis swings from 40 deg one side to 40 deg the other, 3 deg beside the pole: on
        the Mikron (A -30..115) no branch flip can carry it, C must turn half a turn. It turns
        where the axis passes the pole (the only place where that does not sweep the tool),
        and the post needs no retract."""
        from tsplcam.post import post_program
        m = load_machine("mikron_ucp600_heidenhain")
        tp = pole_pass(n=201, tilt=40.0, miss=3.0)
        sol, _ = solve_joints(m, tp.tip, tp.axis, move=tp.move)
        c = sol.joints[:, 4]
        self.assertGreater(abs(c[-1] - c[0]), 150.0)
        tilt = np.degrees(np.arccos(np.clip(tp.axis[:, 2], -1, 1)))
        turn = np.abs(np.diff(c))
        steep = (tilt[1:] < 15.0) & (tilt[:-1] < 15.0)
        self.assertGreater(turn[steep].sum(), 140.0)       # turned while within 15 deg of the pole
        self.assertTrue((sol.joints[:, 3] > 0).all())       # never the other branch (A >= -30)
        self.assertLess(turn[~steep].sum(), 35.0)
        self.assertEqual(post_program(tp, m, "heidenhain").reorientations, 0)


class UnwindingAtLineEnds(unittest.TestCase):
    def test_a_limited_c_rewinds_where_a_line_ends(self):
        """Five zigzag-like lines whose tool axis (30 deg tilt) turns on by 150 deg each: a C
        axis of -200..200 deg must rewind every second or third line. The rewinds (and the
        post's retract around them) fall on the links between lines, never inside a cut."""
        from tsplcam.toolpath.path import Move, ToolPath
        m = make_machine("head-head", "B", 1, 1, tilt_range=(-100, 100), rot_range=(-200, 200),
                         tilt_pivot=(0, 0, 150), rot_pivot=(0, 0, 150), tool_length=100.0)
        lines, per = 5, 60
        az = np.radians(np.arange(lines * per) * 150.0 / (per - 1) * (per - 1) / per)
        th = np.radians(30.0)
        K = np.column_stack([np.sin(th) * np.cos(az), np.sin(th) * np.sin(az), np.full(len(az), np.cos(th))])
        tip = np.column_stack([np.arange(len(az)) * 0.2, np.zeros(len(az)), np.zeros(len(az))])
        move = np.full(len(az), Move.CUT, np.int8)
        move[per::per] = Move.LINK
        sol, _ = solve_joints(m, tip, K, move=move)
        c = sol.joints[:, 4]
        self.assertTrue(((c >= -200 - 1e-9) & (c <= 200 + 1e-9)).all())
        jumps = np.nonzero(np.abs(np.diff(c)) > 90.0)[0] + 1          # the block arriving at the point
        self.assertGreaterEqual(len(jumps), 1)
        self.assertTrue(np.all(move[jumps] == Move.LINK), f"rewinds at {jumps}, links at {np.nonzero(move == 1)[0]}")
        tp = ToolPath(contact=tip, normal=K, axis=K, move=move, patch=np.zeros(len(az), int),
                      uv=np.zeros((len(az), 2)), line=np.repeat(np.arange(lines), per), tool_radius=0.0)
        from tsplcam.post import post_program
        r = post_program(tp, m, "fanuc")
        self.assertEqual(r.reorientations, len(jumps))


class Linearisation(unittest.TestCase):
    def test_joint_space_tip_stays_within_tolerance(self):
        m = load_machine("linuxcnc_xyzac_trt")
        tp = helix(n=120, turns=1.0, tilt=30.0, radius=30.0)
        sol, tip = solve_joints(m, tp.tip, tp.axis)
        feed = np.ones(len(tip), bool)
        feed[0] = False
        before = joint_deviation(m, sol.joints, tip, np.arange(len(tip) - 1)).max()
        tol = 0.001
        j2, t2, src, f2, ins, worst = linearise(m, sol.joints, tip, np.arange(len(tip), dtype=float), feed, tol)
        self.assertGreater(before, 10 * tol)
        self.assertGreater(ins, 0)
        self.assertLessEqual(worst, tol)
        # Dense check, independent of the three samples the linearisation uses.
        dense = joint_deviation(m, j2, t2, np.arange(len(t2) - 1), samples=np.linspace(0.02, 0.98, 49))
        self.assertLessEqual(dense.max(), 1.05 * tol)
        # Inserted points lie on the programmed segments and their poses reach them.
        fk, _ = forward(m, j2)
        self.assertLess(np.linalg.norm(fk - t2, axis=1).max(), 1e-9)
        print(f"\n  linearisation: {ins} points inserted into {len(tip) - 1} blocks, deviation "
              f"{before * 1000:.1f} um -> {dense.max() * 1000:.4f} um (dense check)")


if __name__ == "__main__":
    unittest.main()
