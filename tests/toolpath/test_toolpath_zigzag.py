"""The isoparametric zigzag path (shang2020 3.5): line placement against closed forms on a
plane and on cylinders, parity tuning, refusal of unreachable concave regions, and whole
models (keycap with valence-3 corners, its concave mold half, the head) measured by the
verification module: scallop never above h, cusp mean above 0.5 h, no gouge, patches joined
at their corners without retraction."""
import unittest

import numpy as np

from tsplcam import load
from tsplcam.errors import GeometryError, InputError
from tsplcam.layout.layout import CORNER_UV
from tsplcam.model.bspline import bspline_patch
from tsplcam.model.samples import sample_path
from tsplcam.plan.steps import ProcessingList, Step
from conftest import cylinder_patch, one_patch_model
from tsplcam.toolpath.baseline import baseline_path
from tsplcam.toolpath.lines import LineFrame, Placer, Target, parity_for
from tsplcam.toolpath.path import Move
from tsplcam.toolpath.zigzag import PathSettings, PathStep, build_path, default_plan, zigzag_path
from tsplcam.verify.metrics import path_metrics
from tsplcam.verify.scallop import measure




def plane(W, H):
    poles = np.array([[[0, 0, 0], [0, H, 0]], [[W, 0, 0], [W, H, 0]]], float)
    return one_patch_model(bspline_patch(poles, None, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1))




def check_joined_path(test, model, path, plist, h):
    """Retraction-free path facts that hold whatever the model."""
    test.assertEqual(path.retractions, 0)
    test.assertFalse(np.any(path.move[1:] == Move.RAPID))
    test.assertTrue(np.all(path.patch >= 0))
    steps = plist.steps
    starts = np.nonzero(np.diff(path.patch) != 0)[0] + 1
    test.assertEqual(len(starts), len(steps) - 1)
    test.assertEqual(list(path.patch[np.concatenate([[0], starts])]), [s.patch for s in steps])
    for i, s in enumerate(steps):
        sel = np.nonzero(path.patch == s.patch)[0]
        first, last = sel[0], sel[-1]
        # starts and finishes at the planned corners (the corner nodes' points)
        test.assertTrue(np.allclose(path.uv[first], CORNER_UV[s.start], atol=1e-12), (i, path.uv[first]))
        test.assertTrue(np.allclose(path.uv[last], CORNER_UV[s.finish], atol=1e-12), (i, path.uv[last]))
        node = model.patches[s.patch].corner_nodes[s.finish]
        test.assertLess(np.abs(path.contact[last] - model.node_points[node]).max(), 1e-9)
        if i + 1 < len(steps):
            # the next patch begins exactly where this one ends
            test.assertLess(np.abs(path.contact[last + 1] - path.contact[last]).max(), 1e-9)
            test.assertEqual(path.move[last + 1], Move.LINK)
        # every line is isoparametric, the first on the start's edge, the last on the far edge
        lines = np.unique(path.line[sel][path.line[sel] >= 0])
        a = 0 if s.crossfeed == "u" else 1
        for ln in lines:
            uvl = path.uv[path.line == ln, a]
            test.assertLess(np.ptp(uvl), 1e-15)
        s0 = path.uv[path.line == lines[0], a][0]
        s1 = path.uv[path.line == lines[-1], a][0]
        # the first and last lines lie on the patch's edges: to 1e-12 of the parameter range
        test.assertLess(abs(s0 - CORNER_UV[s.start][a]), 1e-12)
        test.assertLess(abs(s1 - (1 - CORNER_UV[s.start][a])), 1e-12)
        info = path.info["patches"][i]
        test.assertEqual(info["lines"], len(lines))
        test.assertLessEqual(info["scallop_used"], h)


def check_measured(test, rep, h, chord_tol):
    test.assertEqual(rep.uncovered, 0)
    test.assertLessEqual(rep.max_scallop, h, rep.max_at)
    test.assertGreater(rep.cusp_mean, 0.5 * h)
    test.assertLess(rep.gouge_points, 1e-4)
    test.assertLessEqual(rep.gouge_chords, chord_tol + 1e-9)
    test.assertLess(rep.gouge_air, 1e-4)
    # the mean height of the material left is about h/3 for a good path, far below h
    test.assertLess(rep.mean_material, 0.45 * h)


class ClosedForms(unittest.TestCase):

    def test_plane_line_count_and_flat_cusps(self):
        """On a plane every gap is at most the flat side step 2 sqrt(2 r h - h^2) and at least
        sqrt(0.97) of it (the accept window), so the count is the smallest that fits or one more."""
        W, H, r, h = 20.0, 8.0, 1.0, 0.01
        model = plane(W, H)
        g = 2 * np.sqrt(2 * r * h - h * h)
        fr = LineFrame(model.patches[0], "u", 0)
        pl = Placer(fr, Target(r, h, 0.0, 1.0)).tuned(None, balance=False)
        gaps = np.diff(pl.s) * W
        self.assertTrue(np.all(gaps <= g * (1 + 1e-9)))
        self.assertTrue(np.all(gaps[:-1] >= (0.97 * 0.995) ** 0.5 * g))
        self.assertIn(pl.count, (int(np.ceil(W / g)) + 1, int(np.ceil(W / g)) + 2))

    def test_cylinder_cusps_closed_form(self):
        """Lines along a cylinder's axis: the cusp between lines at angles a1, a2 is where the
        circles of radius r about the ball centres meet (computed here in 2D)."""
        R, H, r, h = 10.0, 5.0, 1.0, 0.005
        for outward in (True, False):
            model = one_patch_model(cylinder_patch(R, H, outward=outward))
            path = build_path(model, [PathStep(0, 0, None, "u")], PathSettings(r, h, balance=False))
            sgn = 1.0 if outward else -1.0
            ang = []
            for ln in np.unique(path.line[path.line >= 0]):
                P = path.contact[path.line == ln]
                ang.append(np.arctan2(P[0, 1], P[0, 0]))
            dth = np.abs(np.diff(np.array(ang)))
            Rc = R + sgn * r
            half = Rc * np.sin(dth / 2)
            root = np.sqrt(r * r - half * half)
            cusp = Rc * np.cos(dth / 2) - root - R if outward else R - (Rc * np.cos(dth / 2) + root)
            self.assertTrue(np.all(cusp <= h * (1 + 1e-9)), (outward, cusp.max() / h))
            self.assertGreater(cusp.mean(), 0.9 * h)
            # every gap but the last is at least the exact side step (docs/method.md 3.2) for the
            # bottom of the accept window (0.97 of the 0.995 h the generator aims under)
            from tsplcam.toolpath.sidestep import side_step
            g_lo = float(side_step(r, 0.97 * 0.995 * h, -sgn / R))
            self.assertTrue(np.all(dth[:-1] * R >= g_lo * (1 - 1e-9)))

    def test_sheared_parametrisation(self):
        """A plane parametrised with a shear (F != 0; the paper's eq. (6) as printed gives no
        step here): lines meet the edges at an angle, one line's end ball faces the next
        line's side, and the largest scallop sits on the edge. Measured, it stays under h."""
        W, H, r, h = 10.0, 6.0, 1.0, 0.01
        poles = np.array([[[0, 0, 0], [4, H, 0]], [[W, 0, 0], [W + 4, H, 0]]], float)
        model = one_patch_model(bspline_patch(poles, None, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1))
        path = build_path(model, [PathStep(0, 0, None, "u")], PathSettings(r, h, balance=False))
        lines = [path.contact[path.line == k] for k in np.unique(path.line)]
        xs = np.array([ln[0, 0] - 4 * ln[0, 1] / H for ln in lines])       # where each line meets y = 0
        gaps = np.diff(xs) * H / np.hypot(4, H)                             # distance between lines
        g = 2 * np.sqrt(2 * r * h - h * h)
        self.assertTrue(np.all(gaps <= g * (1 + 1e-9)))
        rep = measure(path, model, scallop=h)
        self.assertLessEqual(rep.max_scallop, h)
        self.assertGreater(rep.max_scallop, 0.95 * h)
        self.assertAlmostEqual(rep.max_at[2] * (1 - rep.max_at[2]), 0.0, places=5)   # on an edge
        self.assertGreater(rep.cusp_mean, 0.5 * h)


class Tuning(unittest.TestCase):

    def test_parity_tuning_follows_the_paper(self):
        """Wrong parity: the scallop drops in steps of 0.1 h, bisecting after an overshoot,
        until n + 1 lines come out; the zigzag then ends at the wanted corner."""
        W, H, r, h = 20.0, 8.0, 1.0, 0.01
        model = plane(W, H)
        fr = LineFrame(model.patches[0], "u", 0)
        n0 = Placer(fr, Target(r, h, 0.0, 1.0)).tuned(None).count
        for finish in (1, 2):                       # same v-side, other v-side
            par = parity_for(fr, finish)
            pl = Placer(fr, Target(r, h, 0.0, 1.0)).tuned(par)
            self.assertEqual(pl.count % 2, par)
            if n0 % 2 == par:             # exact by construction: the first trial is h as given
                self.assertEqual(pl.trials, [(h, n0)])
            else:
                self.assertEqual(pl.count, n0 + 1)
                hs = [t[0] for t in pl.trials]
                self.assertEqual(hs[0], h)          # exact: h as given
                self.assertAlmostEqual(hs[1], 0.9 * h)
                self.assertLess(pl.scallop, h)
            path = build_path(model, [PathStep(0, 0, finish, "u")], PathSettings(r, h))
            self.assertTrue(np.allclose(path.uv[-1], CORNER_UV[finish]))

    def test_batched_gaps_are_measured_gaps(self):
        """Lines placed a batch at a time (predicted, kept up to the first miss): every gap
        but the last lies in the accept window, and the ratio recorded for each gap is the one
        measured again on the placed lines, one gap at a time (keycap patch 4, next to four
        extraordinary points, and its steeper side patch)."""
        from tsplcam.toolpath.lines import ACCEPT, FIT
        model = load(sample_path("keycap"))
        for patch, crossfeed in ((4, "u"), (0, "v")):
            fr = LineFrame(model.patches[patch], crossfeed, 0)
            target = Target(0.5, 0.005, 0.0005, 1.0)
            placer = Placer(fr, target)
            pos, ratios, full = placer.place(target)
            self.assertEqual(len(ratios), len(pos) - 1)
            self.assertTrue(np.all(ratios[:-1] >= ACCEPT) and np.all(ratios <= FIT), ratios)
            again = Placer(fr, target)
            for k in range(len(pos) - 1):
                g1 = again.line(pos[k])
                r = again.ratio(g1, pos[k + 1] - pos[k], target.at(g1))
                self.assertAlmostEqual(r, ratios[k], delta=1e-6 * r)
            self.assertGreaterEqual(full, 1.0 - pos[-2] - 1e-12)

    def test_unreachable_finish_is_refused(self):
        model = plane(10, 10)
        with self.assertRaises(InputError) as cm:
            build_path(model, [PathStep(0, 0, 3, "u")], PathSettings(1.0, 0.01))
        self.assertIn("crossfeed u cannot reach", str(cm.exception))


class Refusals(unittest.TestCase):

    def test_concave_radius_below_tool_radius(self):
        """The mold's concave fillets have a radius of about 0.86 mm: a 1 mm ball cannot."""
        model = load(sample_path("keycap_mold"))
        with self.assertRaises(GeometryError) as cm:
            zigzag_path(model, None, tool_radius=1.0, scallop=0.01)
        msg = str(cm.exception)
        self.assertRegex(msg, r"patch \d+: concave radius of curvature 0\.8\d+ mm at \(u, v\) = \(")
        self.assertIn("tool radius 1 mm", msg)
        self.assertIn("use a tool of radius below 0.8", msg)

    def test_a_crease_is_named_a_crease(self):
        """OpenSubdiv's single crease: a concave radius of 6e-7 mm at the crease, which no ball
        follows; the refusal says so rather than asking for a ball that small."""
        from conftest import external
        model = load(external("opensubdiv", "catmark_single_crease.obj"))
        with self.assertRaises(GeometryError) as cm:
            zigzag_path(model, None, tool_radius=0.5, scallop=0.05)
        msg = str(cm.exception)
        self.assertRegex(msg, r"concave radius of curvature \d\.\d+e-0\d mm")
        self.assertIn("a sharp concave edge or corner (a crease) that no ball can follow", msg)
        self.assertNotIn("use a tool of radius below", msg)

    def test_bad_settings(self):
        model = plane(10, 10)
        for kw in ({"tool_radius": -1.0, "scallop": 0.01}, {"tool_radius": 1.0, "scallop": 0.0},
                   {"tool_radius": 1.0, "scallop": 2.0}, {"tool_radius": 1.0, "scallop": 0.01, "chord_tol": np.nan}):
            with self.assertRaises(InputError):
                zigzag_path(model, ProcessingList([Step(0, 0, 2, "u")]), **kw)


class Models(unittest.TestCase):
    """Whole sample models, each as one path, measured by tsplcam.verify."""

    def run_model(self, name, r, h, chord_tol=0.001):
        model = load(sample_path(name))
        plist = default_plan(model)
        path = zigzag_path(model, plist, r, h, chord_tol)
        check_joined_path(self, model, path, plist, h)
        rep = measure(path, model)
        check_measured(self, rep, h, chord_tol)
        return model, plist, path, rep

    def test_keycap(self):
        """The keycap: five patches, four extraordinary corners of valence 3."""
        model, plist, path, rep = self.run_model("keycap", 0.5, 0.02)
        self.assertEqual(len(model.extraordinary), 4)
        self.assertEqual(path_metrics(path).air_length, 0.0)   # exact: a sum of no air moves
        # the tool axis is the surface normal for now
        np.testing.assert_allclose(path.axis, path.normal)
        np.testing.assert_allclose(path.tip, path.contact, atol=1e-12)

    def test_keycap_mold(self):
        self.run_model("keycap_mold", 0.5, 0.02)

    def test_head(self):
        self.run_model("head", 5.0, 0.4, chord_tol=0.002)

    def test_paper_scallop_on_a_region(self):
        """The paper's r = 0.5 mm, h = 0.005 mm on the keycap's top patch, measured next to an
        extraordinary corner and in the middle of the dish."""
        model = load(sample_path("keycap"))
        path = build_path(model, [PathStep(4, 0, 2, "u")], PathSettings(0.5, 0.005))
        for region in ((0.0, 0.12, 0.0, 0.12), (0.45, 0.55, 0.3, 0.7)):
            rep = measure(path, model, patches=[4], region=region)
            check_measured(self, rep, 0.005, 0.001)


class Retractions(unittest.TestCase):

    def test_retract_before_makes_air_moves(self):
        """A step marked retract_before: RETRACT up to the clearance plane, RAPID across,
        an approach LINK down to the step's start; nothing in the air touches the part."""
        model = load(sample_path("keycap"))
        plist = default_plan(model)
        steps = [Step(s.patch, s.start, s.finish, s.crossfeed, s.retract_before) for s in plist.steps]
        steps[2].retract_before = True
        r, h = 0.5, 0.05
        path = zigzag_path(model, ProcessingList(steps), r, h, clearance=3.0)
        self.assertEqual(path.retractions, 1)
        air = np.nonzero(path.patch < 0)[0]
        self.assertEqual(list(path.move[air]), [Move.RETRACT, Move.RAPID])
        self.assertEqual(path.move[air[-1] + 1], Move.LINK)
        self.assertTrue(np.all(np.isnan(path.uv[air])))
        top = model.bounding_box(17)[1][2]
        self.assertTrue(np.all(path.center[air, 2] - r >= top + 3.0 - 1e-9))
        rep = measure(path, model, spacing=0.2)
        self.assertEqual(rep.gouge_air, 0.0)                 # exact: depth clamped at 0, air 3 mm clear
        self.assertEqual(path.info["clearance_mode"], "plane")

    def test_baseline_retracts_between_faces(self):
        """The compound-NURBS baseline on the head (normals all round: clearance sphere)."""
        model = load(sample_path("head"))
        r, h = 5.0, 1.0
        base = baseline_path(model, r, h, 0.005)
        self.assertEqual(base.retractions, len(model.patches) - 1)
        self.assertEqual(base.info["clearance_mode"], "sphere")
        m = path_metrics(base)
        self.assertGreater(m.air_length, 0.0)
        for d in base.info["patches"]:
            self.assertEqual(d["start"], "lower-left")
            self.assertEqual(len(d["trials"]), 1)             # no scallop tuning
        rep = measure(base, model, spacing=2.0)
        self.assertEqual(rep.uncovered, 0)
        self.assertLess(rep.gouge_air, 1e-9)
        ts = zigzag_path(model, None, r, h, 0.005)
        self.assertEqual(ts.retractions, 0)
        self.assertEqual(path_metrics(ts).air_length, 0.0)   # exact: a sum of no air moves


if __name__ == "__main__":
    unittest.main()
