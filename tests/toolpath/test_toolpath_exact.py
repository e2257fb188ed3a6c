"""The path's shortcuts are the same arithmetic as the code they replace, so the path's points
stay the same bytes (issue 16: the keycap and keycap_mold programs must not change when the
path gets faster). Here, and only here, values are compared byte for byte: the claim under
test is identity, not closeness."""
import unittest
from unittest.mock import patch

import numpy as np

from tsplcam import compiled, load_model
from tsplcam.model.basis import bernstein_rows
from tsplcam.errors import GeometryError
from tsplcam.model.cells import DERIVS, BezierCells, LevelCells
from tsplcam.toolpath import lines as lines_module
from tsplcam.toolpath.lines import (ACCEPT, FIT, STAGE, LineFrame, Placer, Target, _capsule_entry, _capsule_segments, _cross, _norm3,
                                    _sum3, _unit_normal)


def same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and np.ascontiguousarray(a).tobytes() == np.ascontiguousarray(b).tobytes()


def bezier_run_by_run(cells: BezierCells, idx, a, b):
    """BezierCells.evaluate as it was written before issue 16: the sum along b run by run (a
    run of one point as a two-column product, as the cells compute it since gemv's rounding
    made a point's values depend on the other points of its call)."""
    n = len(a)
    q1, nc = cells.q + 1, cells.nc
    bs, bt = bernstein_rows(cells.p, a), bernstein_rows(cells.q, b)
    cuts = np.flatnonzero(idx[1:] != idx[:-1]) + 1
    out = np.empty((6, 4, n))
    if nc == 3:
        out[0, 3] = 1.0
        out[1:, 3] = 0.0
    tmp = np.empty((nc, n))
    for s0, e0 in zip(np.concatenate([[0], cuts]).tolist(), np.concatenate([cuts, [n]]).tolist()):
        m = e0 - s0
        cj = cells._cj[idx[s0]]
        T = [(cj @ bs[d][:, [s0, s0] if m == 1 else slice(s0, e0)])[:, :m].reshape(q1, nc, m) for d in range(3)]
        t = tmp[:, :m]
        for k, (ds, dt) in enumerate(DERIVS):
            o = out[k, :nc, s0:e0]
            w = bt[dt, :, s0:e0]
            np.multiply(w[0], T[ds][0], out=o)
            for j in range(1, q1):
                np.multiply(w[j], T[ds][j], out=t)
                o += t
        out[0, :nc, s0:e0] += cells._origin[idx[s0]][:, None]
    return out


def capsule_entry_before(p, n, a, b, r):
    """_capsule_entry as it was written before: the segment measured on every call, the two
    end spheres one after the other."""
    e = b - a
    L = np.sqrt(_sum3(e * e))
    eh = e / np.maximum(L, 1e-300)[..., None]
    w = p - a
    dn = _sum3(n * eh)
    wn = _sum3(w * eh)
    dp = n - dn[..., None] * eh
    wp = w - wn[..., None] * eh
    A = _sum3(dp * dp)
    B = _sum3(wp * dp)
    C = _sum3(wp * wp) - r * r
    disc = B * B - A * C
    lam = (-B - np.sqrt(np.where(disc >= 0, disc, np.nan))) / A
    ax = wn + lam * dn
    out = np.where((disc >= 0) & (A > 1e-14) & (ax >= 0) & (ax <= L), lam, np.inf)
    for c in (a, b):
        wc = p - c
        bb = _sum3(n * wc)
        cc = _sum3(wc * wc) - r * r
        d = bb * bb - cc
        out = np.minimum(out, np.where(d >= 0, -bb - np.sqrt(np.where(d >= 0, d, 0.0)), np.inf))
    return out


class SameBytes(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.model = load_model("keycap")
        cls.rng = np.random.default_rng(16)

    def test_bezier_cells_all_runs_at_once(self):
        """Runs of one point (a matrix-vector product in BLAS) and long runs alike."""
        g = self.model.patches[4].groups[0]
        self.assertIsInstance(g, BezierCells)
        for n in (1, 2, 5, 170, 1400):
            idx = np.sort(self.rng.integers(0, len(g), n))
            idx[: n // 3] = 0                                    # one long run, many short ones
            a, b = self.rng.random(n), self.rng.random(n)
            a[: n // 7] = 0.0
            self.assertTrue(same(g.evaluate(np.sort(idx), a, b)[0], bezier_run_by_run(g, np.sort(idx), a, b)),
                            f"{n} points")

    def test_patch_points_sorted_or_not(self):
        """Points given in cell order skip the sort and the scatter back: the same values as
        the general route (the points of each cell in the same order, one run per cell)."""
        p = self.model.patches[4]
        u = np.repeat([0.02, 0.4], 170)                          # two lines, in cell order
        v = np.tile(np.linspace(0.0, 1.0, 170), 2)
        sorted_ = p.evaluate(u, v)
        key = np.clip(np.searchsorted(p.ubreaks, u, side="right") - 1, 0, p.shape[0] - 1) * p.shape[1] \
            + np.clip(np.searchsorted(p.vbreaks, v, side="right") - 1, 0, p.shape[1] - 1)
        self.assertTrue(np.all(np.diff(key) >= 0))
        # the same points with the second line first: sorted back into the same runs
        swap = np.r_[170:340, 0:170]
        other = p.evaluate(u[swap], v[swap])
        for name in ("P", "Pu", "Pv", "Puu", "Puv", "Pvv", "normal"):
            self.assertTrue(same(getattr(other, name)[np.argsort(swap)], getattr(sorted_, name)), name)

    def test_extraordinary_groups_in_one_call(self):
        """The patch's LevelCells groups evaluated together give what each group gives alone,
        near the irregular corners too (points below the nets' deepest level included). A
        group holds the cells of one subdivision scheme, one per kind of irregular vertex
        (the keycap's patches have one kind each); figure4's first patch has two kinds."""
        p = load_model("figure4").patches[0]
        levels = p._level_set()
        self.assertIsNotNone(levels)
        n = 300
        corner = self.rng.integers(0, 2, (n, 2)).astype(float)
        d = self.rng.random((n, 2)) * 10.0 ** self.rng.integers(-12, -1, (n, 1))
        uv = np.abs(corner - d)
        uv[:10] = corner[:10]                                     # at the vertices themselves
        together = p.evaluate(uv[:, 0], uv[:, 1])
        p._levels = (tuple(id(g) for g in p.groups), None)        # each group on its own
        try:
            alone = p.evaluate(uv[:, 0], uv[:, 1])
        finally:
            p._levels = None
        for name in ("P", "Pu", "Pv", "Puu", "Puv", "Pvv", "normal"):
            self.assertTrue(same(getattr(together, name), getattr(alone, name)), name)

    def test_nets_xyz_alone(self):
        """A polynomial patch's extraordinary cells make x, y, z alone from their nets: the
        same values as the four rows of the homogeneous route, weight rows 1 and 0."""
        p = self.model.patches[4]
        self.assertTrue(p._polynomial())
        g = next(grp for grp in p.groups if isinstance(grp, LevelCells))
        n = 200
        idx = np.zeros(n, int)
        a, b = self.rng.random(n), self.rng.random(n)
        a[:5], b[:5] = g._corner[0, 0], g._corner[1, 0]          # at the irregular corner too
        for nd in (6, 3):
            H4 = g.evaluate(idx, a, b, nd=nd)[0]
            H3 = g.evaluate(idx, a, b, nd=nd, nc=3)[0]
            self.assertTrue(same(H3[:, :3], H4[:, :3]), nd)
            self.assertTrue(np.all(H3[0, 3] == 1.0) and np.all(H3[1:, 3] == 0.0))

    def test_bezier_and_nets_together(self):
        """Points of Bezier and extraordinary cells in one call (one Bernstein evaluation for
        both, each group writing its block) give what each kind gives in a call of its own."""
        p = self.model.patches[4]
        n = 600
        uv = self.rng.random((n, 2))
        uv[:20] = self.rng.integers(0, 2, (20, 2))              # irregular corners among them
        both = p.evaluate(uv[:, 0], uv[:, 1])
        iu = np.clip(np.searchsorted(p.ubreaks, uv[:, 0], side="right") - 1, 0, p.shape[0] - 1)
        iv = np.clip(np.searchsorted(p.vbreaks, uv[:, 1], side="right") - 1, 0, p.shape[1] - 1)
        bez = isinstance(p.groups[0], BezierCells) & (p.cell_group[iu, iv] == 0)
        self.assertTrue(0 < bez.sum() < n)
        for sel in (bez, ~bez):
            alone = p.evaluate(uv[sel, 0], uv[sel, 1])
            for name in ("P", "Pu", "Pv", "Puu", "Puv", "Pvv", "normal"):
                self.assertTrue(same(getattr(alone, name), getattr(both, name)[sel]), name)

    def test_first_derivatives_alone(self):
        """``second=False`` (the cusps' edge pass, the chord placement): the position, first
        derivatives and normal of the full evaluation, on Bezier and extraordinary points
        together and apart, at small and large batches (both sums of BezierCells), and in
        the line frame with its s flipped."""
        p = self.model.patches[4]
        for n in (40, 600):
            uv = self.rng.random((n, 2))
            uv[:6] = self.rng.integers(0, 2, (6, 2))             # irregular corners among them
            for sel in (slice(None), uv[:, 0] > 0.5):
                full = p.evaluate(uv[sel, 0], uv[sel, 1])
                first = p.evaluate(uv[sel, 0], uv[sel, 1], second=False)
                self.assertIsNone(first.Puu)
                for name in ("P", "Pu", "Pv", "normal"):
                    self.assertTrue(same(getattr(first, name), getattr(full, name)), (n, name))
        frame = LineFrame(self.model.patches[0], "v", 2)          # s = 1 - v
        s, t = self.rng.random(300), self.rng.random(300)
        full, first = frame.evaluate(s, t), frame.evaluate(s, t, second=False)
        for name in ("P", "n", "Ss", "St", "u", "v"):
            self.assertTrue(same(getattr(first, name), getattr(full, name)), name)

    def test_quiet_is_errstate(self):
        """npfast.quiet sets the modes np.errstate sets, nests, and restores the caller's."""
        from tsplcam.npfast import quiet
        before = np.geterr()
        for kinds in (("divide", "invalid"), ("invalid",), ("invalid", "divide", "over")):
            with np.errstate(**dict.fromkeys(kinds, "ignore")):
                want = np.geterr()
            with quiet(*kinds):
                self.assertEqual(np.geterr(), want)
                with quiet("under"):
                    self.assertEqual(np.geterr()["under"], "ignore")
                self.assertEqual(np.geterr(), want)
            self.assertEqual(np.geterr(), before)

    def test_frame_normal_and_cross(self):
        p = self.model.patches[0]
        sp = p.evaluate(self.rng.random(300), self.rng.random(300))
        self.assertTrue(same(_unit_normal(sp.Pu, sp.Pv), sp.normal))
        # the compiled unit_normals (rows of coordinate-major arrays) and numpy's route, also on
        # a zero and a nan normal: the same bytes
        H = np.stack([sp.Pu.T, sp.Pv.T])
        H[0, :, :2] = 0.0
        H[0, 1, 2] = np.nan
        with patch.object(compiled, "kernels", lambda work=None: None):
            want = _unit_normal(H[0].T, H[1].T)
        self.assertTrue(same(_unit_normal(H[0].T, H[1].T), want))
        self.assertTrue(same(_cross(sp.Pu, sp.Puu), np.cross(sp.Pu, sp.Puu)))
        self.assertTrue(same(_norm3(sp.Puv), np.linalg.norm(sp.Puv, axis=-1, keepdims=True)))
        # the frame's normal where the patch has exact normals (its extraordinary corners)
        fr = LineFrame(p, "u", 0)
        g = fr.evaluate([0.0, 0.5, 1.0, 0.0], [0.0, 0.5, 1.0, 1.0])
        self.assertTrue(same(g.n, p.evaluate([0.0, 0.5, 1.0, 0.0], [0.0, 0.5, 1.0, 1.0]).normal))

    def test_placer_caches(self):
        """A line's target and first-order step, cached, are what they are computed afresh."""
        fr = LineFrame(self.model.patches[2], "v", 3)
        target = Target(0.5, 0.005, 0.0005, 1.0)
        pl = Placer(fr, target)
        geoms = pl.lines([0.1, 0.2, 0.3])
        th = pl.target_at(0.2, target)
        self.assertTrue(same(th, target.at(geoms[1])))
        self.assertTrue(same(pl.first_order_at(0.2, target), pl.first_order(geoms[1], target.at(geoms[1]))))
        # the forms computed on first use from the frame's own derivatives
        g = geoms[0]
        self.assertTrue(same(g.E, np.einsum("ij,ij->i", g.Ss, g.Ss)))
        self.assertTrue(same(g.M, np.einsum("ij,ij->i", g.n, g.Sst)))


    def test_capsule_entry_segments_once(self):
        """The end capsules measured with their segments made once, both end spheres in one
        call: the same entries as before (hits, misses and the end spheres alike)."""
        G, k, r = 5, 17, 0.5
        p = self.rng.normal(size=(G, 1, 2, k, 3)) * 0.6
        n = self.rng.normal(size=(G, 1, 2, k, 3))
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        a = self.rng.normal(size=(G, 2, 2, 1, 3)) * 0.3
        b = a + 4 * r * self.rng.normal(size=(G, 2, 2, 1, 3))
        with np.errstate(invalid="ignore", divide="ignore"):
            want = capsule_entry_before(p, n, a, b, r)
            got = _capsule_entry(p, n, a, b, r, _capsule_segments(a, b))
        self.assertTrue(np.isfinite(want).any() and np.isinf(want).any())
        self.assertTrue(same(got, want))

    def test_batch_first_order_steps(self):
        """The first-order steps of a batch's predicted lines, made together, are what each
        line gives on its own (keycap patch 4, next to its extraordinary corners)."""
        fr = LineFrame(self.model.patches[4], "u", 0)
        target = Target(0.5, 0.005, 0.0005, 1.0)
        pl = Placer(fr, target)
        S, D, _, _, _ = pl._run(0.0, 1.0, target, 8, ([0.0], [pl.first_order_at(0.0, target)]))
        self.assertGreater(len(D), 2)
        alone = Placer(fr, target)
        for x in S[1:len(D)]:
            batch = pl._first[(float(x), target.h, target.undercut, target.max_step)]
            self.assertTrue(same(batch, alone.first_order_at(x, target)), x)

    def test_trials_in_lockstep_are_trials_alone(self):
        """Parity trials run together (their lines in one evaluation, their gaps in one cusp
        measurement) place the same lines, bytes and all, as each alone; a batch measured a
        stage at a time gives the same ratios as measured whole, up to its first miss (keycap
        patch 4)."""
        fr = LineFrame(self.model.patches[4], "u", 0)
        target = Target(0.5, 0.005, 0.0005, 1.0)
        pl = Placer(fr, target)
        factors = (0.9, 0.95)
        got = pl._lockstep([pl._place_g(target.scaled(f)) for f in factors])
        for f, (ok, (pos, ratios, full)) in zip(factors, got):
            self.assertTrue(ok)
            want = Placer(fr, target).place(target.scaled(f))
            self.assertTrue(same(pos, want[0]) and same(ratios, want[1]) and same(full, want[2]), f)
        # a 32-line batch: staged, it stops measuring after the stage with its first miss
        known = ([0.0], [pl.first_order_at(0.0, target)])
        S, D, R, _, _ = Placer(fr, target)._run(0.0, 1.03, target, 32, known)
        with patch.object(lines_module, "STAGE", 1000):
            S2, D2, R2, _, _ = Placer(fr, target)._run(0.0, 1.03, target, 32, known)
        self.assertTrue(same(S, S2) and same(D, D2))
        self.assertLess(len(R), len(D))                  # a stage left unmeasured
        self.assertTrue(same(R, R2[:len(R)]))
        miss = np.nonzero((R2 < ACCEPT) | (R2 > FIT))[0]
        self.assertTrue(len(miss) and len(R) == min(len(R2), (miss[0] // STAGE + 1) * STAGE), (len(R), miss))

    def test_trials_run_ahead_change_nothing(self):
        """The tuning with the trials the first one predicts run ahead gives the placement it
        gives with none run ahead: the same trials, lines and ratios."""
        fr = LineFrame(self.model.patches[4], "u", 0)
        target = Target(0.5, 0.005, 0.0005, 1.0)
        n0 = len(Placer(fr, target).place(target)[0])
        ahead = Placer(fr, target).tuned(1 - n0 % 2)
        with patch.object(lines_module, "AHEAD_MAX", 0):
            alone = Placer(fr, target).tuned(1 - n0 % 2)
        self.assertGreaterEqual(len(ahead.trials), 3)
        self.assertEqual(ahead.trials, alone.trials)
        self.assertTrue(same(ahead.s, alone.s) and same(ahead.ratio, alone.ratio))

    def test_secant_with_the_batch_ahead_is_the_secant(self):
        """The secant's first candidate measured with the next batch's gaps places the lines
        it places measured alone, whether the secant takes it or goes on (with the accept
        window narrowed to [0.99, 1] it goes on at about half the misses; keycap patch 4)."""
        fr = LineFrame(self.model.patches[4], "u", 0)
        target = Target(0.5, 0.005, 0.0005, 1.0)

        def alone(self, s, g1, th, d, d0, target, known):       # the candidate alone, no batch
            return float((yield "ratios", g1, np.array([d]), th)[0]), None

        for accept in (ACCEPT, 0.99):
            with patch.object(lines_module, "ACCEPT", accept):
                got = Placer(fr, target).place(target)
                with patch.object(Placer, "_measure_ahead_g", alone):
                    want = Placer(fr, target).place(target)
            self.assertTrue(all(same(a, b) for a, b in zip(got, want)), accept)

    def test_lockstep_keeps_each_trials_error(self):
        """A trial that fails in a lockstep fails alone: its error is its result, the others
        run on; a line out of reach among several trials' lines goes to the trial that asked
        for it."""
        fr = LineFrame(self.model.patches[4], "u", 0)
        pl = Placer(fr, Target(0.5, 0.005, 0.0005, 1.0))
        check = lines_module.check_reachable

        def out_of_reach_at_quarter(frame, geom, r):
            if (geom.s == 0.25).any():
                raise GeometryError("out of reach")
            check(frame, geom, r)

        def fails():
            yield from pl._line_g(0.25)
            return "reached"

        def raises():
            yield "lines", [0.75]
            raise GeometryError("no side step")

        def measures():
            g = yield from pl._line_g(0.5)
            r = yield "ratios", g, np.array([0.01]), np.full(len(g.t), 0.005)
            return float(r[0])

        with patch.object(lines_module, "check_reachable", out_of_reach_at_quarter):
            (ok1, e1), (ok2, e2), (ok3, r) = pl._lockstep([fails(), raises(), measures()])
        self.assertFalse(ok1 or ok2)
        self.assertEqual((str(e1), str(e2)), ("out of reach", "no side step"))
        self.assertTrue(ok3 and r > 0)
        self.assertNotIn(0.25, pl._lines)
        self.assertIn(0.5, pl._lines)
        self.assertIn(0.75, pl._lines)

if __name__ == "__main__":
    unittest.main()


class SameBytesAsNumpy(unittest.TestCase):
    """The path's own forms of numpy calls (made for many curves or rows at once) give numpy's
    bytes."""

    def test_sum3_is_the_reduction(self):
        vals = [0.0, -0.0, 1.0, -1.0, 1e-300, -1e300, 3.0, 2.0 ** -60, np.inf]
        x = np.array(np.meshgrid(vals, vals, vals)).reshape(3, -1).T        # every triple
        self.assertTrue(same(_sum3(x), np.add.reduce(x, axis=-1)))
        y = np.random.default_rng(3).standard_normal((7, 2, 2, 17, 3))
        self.assertTrue(same(_sum3(y), np.add.reduce(y, axis=-1)))
        self.assertTrue(same(_norm3(y), np.linalg.norm(y, axis=-1, keepdims=True)))

    def test_linspaces_and_interp_many(self):
        from tsplcam.toolpath.chord import _interp_many, _linspaces
        rng = np.random.default_rng(7)
        k = 40
        lo = rng.random(k)
        hi = lo + rng.random(k) * 0.5
        hi[3] = lo[3]                                            # a zero step
        num = rng.integers(3, 70, k)
        y, cid, first = _linspaces(lo, hi, num)
        for j in range(k):
            self.assertTrue(same(y[first[j]:first[j] + num[j]], np.linspace(lo[j], hi[j], num[j])), j)
        xs = [np.cumsum(rng.random(n)) * (rng.random() < 0.9) for n in num]   # some all zero
        fps = [rng.standard_normal(n) for n in num]
        q = [np.concatenate([rng.random(15) * x[-1] * 1.2 - 0.05, x[:4]]) for x in xs]
        qc = np.repeat(np.arange(k), [len(a) for a in q])
        got = _interp_many(np.concatenate(q), qc, np.concatenate(xs), np.concatenate(fps), first, num)
        for j in range(k):
            self.assertTrue(same(got[qc == j], np.interp(q[j], xs[j], fps[j])), j)

    def test_split_points_merged_in_sorted_order(self):
        """place_curves puts each segment's middle between its ends (``_merge_rows``): the
        order the sort by (curve, x) it replaces gives, payload rows included."""
        from tsplcam.toolpath.chord import _merge_rows
        rng = np.random.default_rng(11)
        num = rng.integers(1, 30, 25)
        x = np.concatenate([np.sort(rng.random(k)) for k in num])
        cid = np.repeat(np.arange(len(num)), num)
        P = rng.standard_normal((len(x), 3))
        for _ in range(4):                                       # a few splitting rounds
            seg = np.flatnonzero(cid[1:] == cid[:-1])
            split = np.sort(rng.choice(seg, len(seg) // 2, replace=False))
            xm = 0.5 * (x[split] + x[split + 1])
            Pm = rng.standard_normal((len(split), 3))
            order = np.lexsort((np.concatenate([x, xm]), np.concatenate([cid, cid[split]])))
            ref = [np.concatenate(a)[order] for a in ((x, xm), (cid, cid[split]), (P, Pm))]
            new = np.zeros(len(x) + len(split), bool)
            new[split + 1 + np.arange(len(split))] = True
            x, cid, P = _merge_rows(x, xm, new), _merge_rows(cid, cid[split], new), _merge_rows(P, Pm, new)
            for got, want in zip((x, cid, P), ref):
                self.assertTrue(same(got, want))


class CompiledCuspFoot(unittest.TestCase):
    """The cusps between two lines in the compiled kernel (``cusp_foot``) give the numpy
    form's bytes: balls meeting and apart, centres that coincide, zero normals, singular
    forms (det <= 0), points beyond the line's end, nan / inf coordinates; the derivatives in
    the layouts the evaluations give them (coordinates next to each other or not, rows one
    array or not), on which einsum's order of the three products turns."""

    @staticmethod
    def layout(x, kind, rng):
        """x (G, m, 3) in a layout: 'C' contiguous, 'S' rows of a longer C array, 'F' rows of
        a coordinate-major array (as a patch's evaluation returns them)."""
        G, m, _ = x.shape
        if kind == "C":
            return np.ascontiguousarray(x)
        extra = int(rng.integers(0, 4))
        if kind == "S":
            buf = np.empty((G, m + extra, 3))
            buf[:, :m] = x
            return buf[:, :m]
        buf = np.empty((3, G, m + extra))
        buf[:, :, :m] = np.moveaxis(x, 2, 0)
        return np.moveaxis(buf, 0, 2)[:, :m]

    def test_kernel_is_numpy(self):
        from tsplcam import compiled
        from tsplcam.toolpath.lines import _cusp_foot, _rows_together
        kern = compiled.kernels()
        if kern is None:
            self.skipTest("no compiled kernels (numba absent or TSPLCAM_COMPILED=0)")
        rng = np.random.default_rng(7)
        specials = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 1e-300])
        r = 0.5
        seen, orders = set(), set()
        for mode in [m for m in range(6) for _ in range(30)]:
            G, m = int(rng.choice([1, 1, 2, 3])), int(rng.integers(1, 9))
            P1 = rng.normal(size=(G, m, 3)) * 0.2
            N1 = rng.normal(size=(G, m, 3))
            N1 /= np.linalg.norm(N1, axis=-1, keepdims=True)
            P2 = P1 + rng.normal(size=(G, m, 3)) * rng.choice([0.05, 0.3, 1.5])   # near, far apart
            N2 = N1 + rng.normal(size=(G, m, 3)) * 0.1
            N2 /= np.linalg.norm(N2, axis=-1, keepdims=True)
            mid = [0.5 * (P1 + P2), 0.5 * (N1 + N2)] + [rng.normal(size=(G, m, 3)) for _ in range(5)]
            if mode == 1:                                      # coincident centres, opposite normals
                P2, N2 = P1.copy(), -N1
            if mode == 2:                                      # zero normals
                N1[rng.random((G, m)) < 0.5] = 0.0
                N2[rng.random((G, m)) < 0.5] = 0.0
            if mode == 3:                                      # singular forms: St along Ss, or zero
                mid[3] = mid[2] * rng.choice([0.0, 2.0], size=(G, m, 1))
            if mode == 4:                                      # nan / inf / 0 coordinates
                for x in (P1, N1, P2, mid[0], mid[2]):
                    bad = rng.random(x.shape) < 0.05
                    x[bad] = rng.choice(specials, bad.sum())
            if mode == 5:                                      # grid values: ties and exact zeros
                P1, N1, P2, N2 = (np.round(x * 4) / 4 for x in (P1, N1, P2, N2))
                mid = [np.round(x * 4) / 4 for x in mid]
            P1, P2 = (self.layout(x, rng.choice(["C", "S", "F"]), rng) for x in (P1, P2))
            N1, N2 = (self.layout(x, rng.choice(["C", "S"]), rng) for x in (N1, N2))
            mid = [self.layout(x, rng.choice(["C", "S", "F"]), rng) for x in mid]
            beyond = rng.random((G, m)) < 0.2
            args = (P1, N1, P2, N2, *mid, beyond, r)
            with np.errstate(all="ignore"):
                want = _cusp_foot(*args)
            got = _cusp_foot(*args, kern)
            self.assertTrue(same(want, got), mode)
            seen |= {"inf" if np.isinf(x) else "nan" if np.isnan(x) else "x" for x in want.ravel()}
            orders |= {tuple(x.strides[-1] == 8 for x in mid[2:4])}
            for x in mid:                                      # the flags read without reshaping
                self.assertEqual(_rows_together(x), x.reshape(-1, 3).strides[-1] == 8)
        self.assertEqual(seen, {"inf", "nan", "x"})          # apart, beyond (or nan in), meeting
        self.assertEqual(len(orders), 4)                       # paired and in order, each operand

    def test_path_in_numpy_is_the_kernels(self):
        """A whole keycap path with the kernels and without (``TSPLCAM_COMPILED=0`` as the
        kernels' absence): the same points, bit for bit."""
        from tsplcam import compiled
        from tsplcam.toolpath.zigzag import zigzag_path
        if compiled.kernels() is None:
            self.skipTest("no compiled kernels (numba absent or TSPLCAM_COMPILED=0)")
        model = load_model("keycap")
        with_kernels = zigzag_path(model, tool_radius=0.5, scallop=0.02)
        with patch.object(compiled, "kernels", lambda *a, **k: None):
            without = zigzag_path(model, tool_radius=0.5, scallop=0.02)
        self.assertTrue(same(with_kernels.contact, without.contact))
        self.assertTrue(same(with_kernels.normal, without.normal))


class CompiledEndPass(unittest.TestCase):
    """The line ends' pass of the cusp heights in the compiled kernel (``cusp_ends``) gives the
    numpy pass's bytes: ends, bracket and step, on random capsules and edge points with misses
    (negative discriminants), segments of length 0, grid values, points exactly on the end
    spheres (entries 0), zero normals, and nan / inf coordinates."""

    def test_kernel_is_numpy(self):
        from tsplcam import compiled
        from tsplcam.toolpath.lines import END_SAMPLES, _end_pass
        kern = compiled.kernels()
        if kern is None:
            self.skipTest("no compiled kernels (numba absent or TSPLCAM_COMPILED=0)")
        rng = np.random.default_rng(21)
        k, r, G, off = END_SAMPLES, 0.5, 6, 3
        specials = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 1e-300])
        checked, seen = 0, set()
        for mode in [m for m in range(7) for _ in range(25)]:
            P = rng.normal(size=(G, off + 2 * k, 3)) * rng.choice([0.3, 0.6, 1.5])
            n = rng.normal(size=P.shape)
            n /= np.linalg.norm(n, axis=-1, keepdims=True)
            ca = rng.normal(size=(G, 2, 2, 1, 3)) * 0.3
            tin = rng.normal(size=ca.shape)
            if mode == 1:                                  # degenerate segments (L = 0)
                tin[rng.random(tin.shape[:-1]) < 0.5] = 0.0
            cb = ca + 4 * r * tin
            if mode == 2:                                  # grid values
                P, n, ca, cb = (np.round(x * 4) / 4 for x in (P, n, ca, cb))
            if mode == 6:                                  # on line 1's first end sphere, tangent
                ca, cb = np.round(ca * 4) / 4, np.round(ca * 4) / 4 + np.round(4 * r * tin)
                ax = np.eye(3)[rng.integers(0, 3, P.shape[:-1])] * rng.choice([1.0, -1.0], P.shape[:-1] + (1,))
                P, n = ca[:, 0, 0] + r * ax, np.roll(ax, 1, axis=-1)
            if mode == 3:                                  # nan / inf / 0 coordinates
                for x in (P, n):
                    bad = rng.random(x.shape) < 0.02
                    x[bad] = rng.choice(specials, bad.sum())
            if mode == 4:                                  # zero normals
                n[rng.random(n.shape[:-1]) < 0.2] = 0.0
            if mode == 5:                                  # both lines' capsules alike: d = 0
                ca[:, 1] = ca[:, 0]
                cb[:, 1] = cb[:, 0]
            ends, lo, width = rng.choice([0.0, -0.0, 0.1], size=(G, 2)), rng.random((G, 2)), np.full((G, 2), 1 / 16)
            with np.errstate(all="ignore"):
                seg = _capsule_segments(ca, cb)
                want = _end_pass(P, n, off, ca, cb, r, seg, ends.copy(), lo.copy(), width.copy())
                h = _capsule_entry(P[:, off:].reshape(G, 1, 2, k, 3), n[:, off:].reshape(G, 1, 2, k, 3), ca, cb, r, seg)
            got = _end_pass(P, n, off, ca, cb, r, seg, ends.copy(), lo.copy(), width.copy(), kern)
            # (not compared: the sign of a peak 0 reached by both +0 and -0, which numpy's
            # vector reduction takes in an order of its own)
            low = np.minimum(h[:, 0], h[:, 1])
            zero = low == 0
            tie = (low.max(axis=2) == 0) & (zero & np.signbit(low)).any(axis=2) & (zero & ~np.signbit(low)).any(axis=2)
            for a, b in zip(want, got):
                self.assertTrue(same(a[~tie], b[~tie]), mode)
            checked += (~tie).sum()
            seen |= {"inf" if np.isinf(x) else "nan" if np.isnan(x) else "0" if x == 0 else "x" for x in h.ravel()}
        self.assertEqual(seen, {"inf", "nan", "0", "x"})         # misses, inf inputs, on spheres, hits
        self.assertGreater(checked, 0.95 * 7 * 25 * G * 2)
