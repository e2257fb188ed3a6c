"""Orientation stage: tool files, collision geometry against closed forms and fcl primitives,
the DP against brute force, the machine reach against the post's inverse kinematics."""
import itertools
import json
import os
import tempfile
import unittest

import numpy as np

from tsplcam.errors import CollisionError, InputError
from tsplcam.model import samples
from tsplcam.model.cage import cage_model
from tsplcam.orientation import CollisionChecker, HolderSegment, Reach, Tool, load_tool, orient
from tsplcam.orientation.collision import tessellate_model
from tsplcam.orientation.viterbi import viterbi
from tsplcam.orientation.tool import parse_length, read_fctb, read_tool, shipped_tools_dir
from tsplcam.toolpath.path import Move, ToolPath

try:
    import fcl
except ImportError:                                       # pragma: no cover
    fcl = None


def plane_mesh(size=40.0, z=0.0):
    V = np.array([[-size, -size, z], [size, -size, z], [size, size, z], [-size, size, z]], float)
    return ("plane", V, np.array([[0, 1, 2], [0, 2, 3]]))


class ToolFiles(unittest.TestCase):
    def test_shipped_tools_and_parts(self):
        for name in ("ball1_keycap", "ball5_impeller", "ball6_freecad_holder"):
            tool = load_tool(name)
            parts = tool.parts()
            self.assertAlmostEqual(parts[-1].z1 + tool.ball_radius, tool.length)
            for a, b in zip(parts, parts[1:]):                # stacked without gaps
                self.assertAlmostEqual(a.z1, b.z0)
        t = load_tool("ball6_freecad_holder")
        # exact by construction: decimal lengths in mm parsed from the file (and halved)
        self.assertEqual((t.ball_radius, t.flute_length, t.shank_diameter, t.shank_length), (3.0, 20.0, 6.0, 40.0))
        self.assertEqual(len(t.holder), 2)

    def test_units_and_errors(self):
        self.assertAlmostEqual(parse_length("6.0000 mm"), 6.0)
        self.assertAlmostEqual(parse_length("0.25 in"), 6.35)
        self.assertAlmostEqual(parse_length("1/8 in"), 3.175)
        with tempfile.TemporaryDirectory() as d:
            bad = os.path.join(d, "bit.fctb")
            with open(bad, "w") as f:
                json.dump({"version": 2, "shape": "ballend.fcstd",
                           "parameter": {"Diameter": "2 mm", "Length": "30 mm"}}, f)
            with self.assertRaises(InputError) as cm:
                read_fctb(bad)
            self.assertIn("bit.fctb", str(cm.exception))
            self.assertIn("CuttingEdgeHeight", str(cm.exception))
            flat = os.path.join(d, "flat.fctb")
            with open(flat, "w") as f:
                json.dump({"shape": "endmill.fcstd", "parameter": {}}, f)
            with self.assertRaises(InputError) as cm:
                read_fctb(flat)
            self.assertIn("ball end", str(cm.exception))
            js = os.path.join(d, "t.json")
            with open(js, "w") as f:
                json.dump({"format": "tsplcam-tool", "version": 1, "ball_radius": 1, "flute_length": 3,
                           "shank_diameter": 2, "shank_length": 10,
                           "holder": [{"type": "cone", "length": 5, "diameter_bottom": 4}]}, f)
            with self.assertRaises(InputError) as cm:
                read_tool(js)
            self.assertIn("t.json", str(cm.exception))
            self.assertIn("diameter_top", str(cm.exception))
        self.assertTrue(os.path.isdir(shipped_tools_dir()))


def _worst_distance(patch, V, T, seed: int, n: int) -> float:
    """The largest fcl distance from the mesh (V, T) of ``patch``'s points at 2.75 n random
    (u, v): n spread evenly, the rest crowded toward the corners and edges."""
    m = fcl.BVHModel()
    m.beginModel(len(T), len(V))
    m.addSubModel(V, T)
    m.endModel()
    wp = fcl.CollisionObject(m, fcl.Transform())
    rng = np.random.default_rng(seed)
    h, q = n // 2, n // 4
    u = np.concatenate([rng.random(n), rng.random(h) ** 4, 1 - rng.random(h) ** 4, rng.random(q) ** 8])
    v = np.concatenate([rng.random(n), rng.random(h) ** 4, rng.random(h) ** 4, 1 - rng.random(q) ** 8])
    s = fcl.CollisionObject(fcl.Sphere(1e-7), fcl.Transform())
    worst = 0.0
    for p in patch.evaluate(u, v, second=False).P:
        s.setTranslation(p)
        worst = max(worst, fcl.distance(s, wp, fcl.DistanceRequest(), fcl.DistanceResult()))
    return worst


@unittest.skipIf(fcl is None, "python-fcl missing")
class CollisionGeometry(unittest.TestCase):
    def test_tessellation_error_below_tolerance(self):
        """Random surface points are within the tolerance of the mesh (fcl distance of a tiny
        sphere, independent of how the tessellation measured itself)."""
        model = cage_model(samples.keycap_mold())
        tol = 0.01
        mesh = tessellate_model(model, tol, patches=[0, 4])
        self.assertLessEqual(mesh.chordal_error, tol)
        m = fcl.BVHModel()
        m.beginModel(len(mesh.triangles), len(mesh.vertices))
        m.addSubModel(mesh.vertices, mesh.triangles)
        m.endModel()
        wp = fcl.CollisionObject(m, fcl.Transform())
        rng = np.random.default_rng(1)
        worst = 0.0
        for k in (0, 4):
            P = model.patches[k].evaluate(rng.uniform(0, 1, 300), rng.uniform(0, 1, 300)).P
            s = fcl.CollisionObject(fcl.Sphere(1e-6), fcl.Transform())
            for p in P:
                s.setTranslation(p)
                worst = max(worst, fcl.distance(s, wp, fcl.DistanceRequest(), fcl.DistanceResult()))
        self.assertLess(worst, tol * 1.05)

    def test_graded_tessellation_next_to_extraordinary_points(self):
        """Where one spacing for the whole patch would pass GRADED_LINES lines (figure4's
        extraordinary corners asked 600-700 lines each way: 5.8 M triangles), the grid is
        graded: far fewer triangles, and random surface points, crowded toward the corners
        and edges, stay within the tolerance of the mesh (fcl's distance, independent of how
        the tessellation measured itself)."""
        from tsplcam import load_model
        from tsplcam.orientation import collision
        model = load_model("figure4")
        tol = 0.005
        graded = 0
        for k in (0, 2, 5):
            patch = model.patches[k]
            V, T, uv, err = collision.tessellate_patch(patch, tol)
            lines = max(len(np.unique(uv[:, 0])), len(np.unique(uv[:, 1])))
            graded += lines <= collision.GRADED_LINES and np.ptp(np.diff(np.unique(uv[:, 0]))) > 1e-9
            self.assertLessEqual(err, tol)
            self.assertLess(len(T), 40000)
            self.assertLessEqual(_worst_distance(patch, V, T, k, 150), tol)
        self.assertEqual(graded, 2)                     # patches 0 and 5 graded, 2 uniform

    def test_tessellation_lines_on_uneven_breaks(self):
        """A T-spline patch's uneven cell breaks (creases at triple knot lines) are grid lines:
        random surface points crowded toward the corners stay within the tolerance (evenly
        spaced lines crossed the breaks and missed it by 10-25 % at a corner)."""
        from tsplcam import load_model
        from tsplcam.orientation import collision
        patch = load_model("tjunction_mold").patches[0]
        tol = 0.005
        V, T, uv, err = collision.tessellate_patch(patch, tol)
        for b, col in ((patch.ubreaks, 0), (patch.vbreaks, 1)):
            lines = np.unique(uv[:, col])
            self.assertTrue(all(np.min(np.abs(lines - x)) < 1e-12 for x in b))
        self.assertLessEqual(_worst_distance(patch, V, T, 3, 400), tol)

    def test_tilted_tool_over_plane_closed_form(self):
        """Ball on the plane z = 0, axis tilted by beta: the shank (radius R from height t0
        above the ball centre) touches the plane when r + t0 cos(beta) < R sin(beta)."""
        r, R, t0 = 1.0, 4.0, 3.0          # flutes to 4 mm from the tip, then a 8 mm shank
        tool = Tool("t", r, t0 + r, 2 * R, 20.0, [])
        ch = CollisionChecker(None, tool, meshes=[plane_mesh()], tolerance=0.001, polygon_tolerance=0.001)
        crit = None
        for b in np.radians(np.linspace(1, 89, 8801)):
            if r + t0 * np.cos(b) < R * np.sin(b):
                crit = b
                break
        centre = np.array([[0.0, 0.0, r]])
        for db, expect in ((-0.3, False), (0.3, True)):
            b = crit + np.radians(db)
            a = np.array([[np.sin(b), 0.0, np.cos(b)]])
            self.assertEqual(bool(ch.collides(centre, a)[0]), expect, np.degrees(b))
            self.assertEqual(bool(ch.collides_exact(centre, a)[0]), expect)
            a2 = np.array([[np.sin(b) * np.cos(1.0), np.sin(b) * np.sin(1.0), np.cos(b)]])  # any azimuth
            self.assertEqual(bool(ch.collides(centre, a2)[0]), expect)
        hit = ch.hit(centre[0], [np.sin(crit + 0.01), 0, np.cos(crit + 0.01)])
        self.assertEqual((hit.part, hit.obstacle), ("shank", "plane"))
        # clearance of the vertical tool: the flutes start at the ball centre, r above the plane
        d = ch.clearance_of(centre, [[0.0, 0.0, 1.0]])[0] + ch.margin
        self.assertAlmostEqual(d, r, delta=2e-3)

    def test_ball_gouge(self):
        tool = Tool("t", 1.0, 2.0, 2.0, 10.0, [])
        ch = CollisionChecker(None, tool, meshes=[plane_mesh()], tolerance=0.001)
        C = np.array([[0, 0, 1.0], [0, 0, 1.0 - 0.5 * ch.gouge_tolerance], [0, 0, 1.0 - 0.01]])
        np.testing.assert_array_equal(ch.ball_gouges(C), [False, False, True])

    def test_workpiece_bvh_built_when_fcl_is_first_asked(self):
        """fcl's view of the workpiece is built at its first question, not before: balls the
        broad phase proves clear build nothing; one it cannot prove builds a BVH of the
        triangles near it (the whole workpiece's stays unbuilt), which a ball within those
        answers from; a batch of more balls than the near BVHs take builds the whole one, once."""
        from tsplcam.orientation.nearby import MAX_FRUSTUMS
        tool = Tool("t", 1.0, 2.0, 2.0, 10.0, [])
        ch = CollisionChecker(None, tool, meshes=[plane_mesh()], tolerance=0.001)
        self.assertIsNone(ch._wp_object)
        np.testing.assert_array_equal(ch.ball_gouges(np.array([[0, 0, 5.0]])), [False])
        self.assertIsNone(ch._wp_object)
        self.assertIsNone(getattr(ch, "_nearby", None))
        np.testing.assert_array_equal(ch.ball_gouges(np.array([[0, 0, 1.0 - 0.01]])), [True])
        self.assertIsNone(ch._wp_object)
        self.assertEqual(ch._nearby.builds, 1)
        np.testing.assert_array_equal(ch.ball_gouges(np.array([[0, 0, 0.5]])), [True])
        self.assertEqual(ch._nearby.builds, 1)                  # (its triangles were near the first)
        x = np.linspace(-4.0, 4.0, MAX_FRUSTUMS + 1)
        balls = np.column_stack([x, np.zeros_like(x), np.full_like(x, 0.5)])
        self.assertTrue(ch.ball_gouges(balls).all())
        built = ch._wp_object
        self.assertIsNotNone(built)
        ch.ball_gouges(np.array([[0, 0, 0.5]]))
        self.assertIs(ch._wp_object, built)

    def test_mesh_tool_agrees_with_primitives(self):
        """The circumscribed tool mesh finds every collision the fcl primitives find, and
        its extra hits are within the polygon tolerance of touching."""
        model = cage_model(samples.keycap_mold())
        tool = load_tool("ball1_keycap")
        V, T = samples.keycap_mold_stock()
        ch = CollisionChecker(model, tool, meshes=[("stock", V, T)], tolerance=0.01)
        rng = np.random.default_rng(3)
        n = 600
        C = np.column_stack([rng.uniform(-7, 7, n), rng.uniform(-7, 7, n), rng.uniform(2.5, 9, n)])
        A = rng.normal(size=(n, 3))
        A[:, 2] = np.abs(A[:, 2]) + 0.8
        A /= np.linalg.norm(A, axis=1, keepdims=True)
        mesh, exact = ch.collides(C, A), ch.collides_exact(C, A)
        self.assertTrue(mesh.any() and (~mesh).any())
        self.assertFalse(np.any(exact & ~mesh))
        extra = np.nonzero(mesh & ~exact)[0]
        if len(extra):
            self.assertLess(ch.clearance_of(C[extra], A[extra]).max(), ch.polygon_tolerance + 1e-6)


class DynamicProgramme(unittest.TestCase):
    def test_viterbi_matches_brute_force(self):
        """The one programme (orientation.viterbi) against enumerating every sequence, with
        forbidden states and moves, for the two-state fast path and the general one, given
        as an array and as a function."""
        rng = np.random.default_rng(7)
        for S in (2, 4):
            for trial in range(6):
                n = 6
                node = rng.uniform(size=(n, S))
                node[rng.uniform(size=(n, S)) < 0.2] = np.inf
                node[:, trial % S] = rng.uniform(size=n)        # keep a way through
                trans = rng.uniform(size=(n - 1, S, S))
                trans[rng.uniform(size=trans.shape) < 0.2] = np.inf
                trans[:, trial % S, trial % S] = 0.5

                def cost(s):
                    return sum(node[i, s[i]] for i in range(n)) + sum(trans[i, s[i], s[i + 1]] for i in range(n - 1))
                best = min(itertools.product(range(S), repeat=n), key=cost)
                for form in (trans, lambda i: trans[i - 1]):
                    states, broke = viterbi(node, form)
                    self.assertIsNone(broke)
                    self.assertAlmostEqual(cost(tuple(states)), cost(best), places=12)
        # a chain that cannot continue says where it breaks
        node = np.zeros((4, 3))
        trans = np.zeros((3, 3, 3))
        trans[1] = np.inf
        self.assertEqual(viterbi(node, trans), (None, 1))


class MachineReach(unittest.TestCase):
    def test_reach_matches_post_kinematics(self):
        from tsplcam.post import load_machine
        from tsplcam.post.kinematics import inverse_orientation
        rng = np.random.default_rng(5)
        K = rng.normal(size=(2000, 3))
        K /= np.linalg.norm(K, axis=1, keepdims=True)
        for name in ("mikron_ucp600_heidenhain", "bc_head_head_fanuc", "linuxcnc_xyzac_trt"):
            m = load_machine(name)
            tilt, rot, _ = inverse_orientation(m, K)
            ok = np.zeros(len(K), bool)
            for b in range(2):
                okc = np.zeros(len(K), bool)
                for k in range(-2, 3):
                    okc |= m.rotary.within(rot[:, b] + 360.0 * k)
                ok |= m.tilt.within(tilt[:, b]) & okc
            np.testing.assert_array_equal(Reach.from_machine(m).ok(K), ok, err_msg=name)
        self.assertAlmostEqual(np.degrees(Reach.from_machine(load_machine("mikron_ucp600_heidenhain")).theta_max), 115.0)


class Errors(unittest.TestCase):
    def test_no_axis_names_patch_uv_and_obstacle(self):
        """A fat holder on a short stick-out cannot reach the cavity bottom at any axis."""
        model = cage_model(samples.keycap_mold())
        tool = Tool("fat", 0.5, 1.0, 1.0, 2.0, [HolderSegment(10.0, 30.0, 30.0)])
        ch = CollisionChecker(model, tool, tolerance=0.01)
        sp = model.patches[4].evaluate([0.5, 0.55], [0.5, 0.5])
        path = ToolPath(sp.P, sp.normal, sp.normal, [Move.CUT] * 2, [4, 4], [[0.5, 0.5], [0.55, 0.5]],
                        [0, 0], tool_radius=0.5)
        for strategy in ("fixed", "closest-z", "smooth"):
            with self.assertRaises(CollisionError) as cm:
                orient(path, checker=ch, strategy=strategy)
            text = str(cm.exception)
            self.assertIn("patch 4", text)
            self.assertIn("u=0.5", text)
            self.assertIn("holder", text)
        # what the holder keeps, and what would give it room
        ch = CollisionChecker(model, tool, tolerance=0.01, clearance=0.3)
        with self.assertRaises(CollisionError) as cm:
            orient(path, checker=ch, strategy="smooth")
        self.assertIn("comes within the 0.3 mm clearance it keeps of", str(cm.exception))
        self.assertIn("a smaller holder clearance", str(cm.exception))
        with self.assertRaises(InputError):
            orient(path, checker=ch, strategy="sideways")


if __name__ == "__main__":
    unittest.main()
