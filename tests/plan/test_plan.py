"""Plan stage (shang2020 sections 3.2-3.4): order, transit corners, the processing-list file.

Answers are checked against independent references written here from the definitions:
brute force over orders (depth-first over prefixes), a plain dynamic programme over start
corners that is itself checked against full enumeration of corner assignments, and
depth-first search for Hamiltonian paths over boundary links.
"""
import itertools
import json
import os
import shutil
import subprocess
import tempfile
import unittest

import numpy as np

from tsplcam.errors import InputError
from tsplcam.layout import examples as ex
from tsplcam.layout.layout import CORNER_NAMES, EDGE_CORNERS, Layout
from tsplcam.plan import Pins, dumps, load, loads, plan, save
from tsplcam.plan.corners import (Rules, finish_choices, forward_pass,
                                  min_retraction_corners, situation)
from tsplcam.plan.graph import PatchGraph, preferred_crossfeeds
from tsplcam.plan.listfile import complete_file
from tsplcam.plan.order import open_tour, tsp_matrix
from tsplcam.plan.steps import crossfeeds_for
from conftest import REPO_DIR

UV = [(0, 0), (1, 0), (1, 1), (0, 1)]
SYSTEM_PYTHON = "/usr/bin/python3"


# -- independent references ---------------------------------------------------------------
def ref_kind(layout, a, b):
    if layout.edge_links_between(a, b):
        return "boundary"
    return "corner" if layout.shared_corners(a, b) else None


def ref_pairs(p, pins):
    """(start, finish) a zigzag on p may take: f != s, pins, crossfeed u needs u to change."""
    out = []
    for s in range(4):
        if p in pins.start_corner and pins.start_corner[p] != s:
            continue
        for f in range(4):
            if f == s or (p in pins.finish_corner and pins.finish_corner[p] != f):
                continue
            if p in pins.crossfeed:
                axis = 0 if pins.crossfeed[p] == "u" else 1
                if UV[s][axis] == UV[f][axis]:
                    continue
            out.append((s, f))
    return out


class RefMemo:
    """ref_pairs, ref_kind and the corner nodes of one (layout, pins), each worked out once:
    the brute force over orders asks them hundreds of thousands of times (the same answers)."""

    def __init__(self, layout, pins):
        self.layout, self.pins = layout, pins
        self.nodes = np.asarray(layout.corner_nodes).tolist()
        self._pairs, self._kinds = {}, {}

    def pairs(self, p):
        if p not in self._pairs:
            self._pairs[p] = ref_pairs(p, self.pins)
        return self._pairs[p]

    def kind(self, p, q):
        if (p, q) not in self._kinds:
            self._kinds[p, q] = ref_kind(self.layout, p, q)
        return self._kinds[p, q]


def ref_transition(layout, pins, p, vec, q, memo=None):
    """Best (retractions, corner links) per start corner of q after p (vec: per start of p)."""
    memo = memo or RefMemo(layout, pins)
    kind = memo.kind(p, q)
    out = [None] * 4
    q_starts = {s for s, _ in memo.pairs(q)}
    for s, cost in enumerate(vec):
        if cost is None:
            continue
        for s1, f in memo.pairs(p):
            if s1 != s:
                continue
            for s2 in q_starts:
                same = memo.nodes[p][f] == memo.nodes[q][s2]
                c = (cost[0], cost[1] + (kind == "corner")) if same else (cost[0] + 1, cost[1])
                if out[s2] is None or c < out[s2]:
                    out[s2] = c
    return out


def ref_first(p, pins, memo=None):
    starts = {s for s, _ in (memo.pairs(p) if memo else ref_pairs(p, pins))}
    return [(0, 0) if s in starts else None for s in range(4)]


def ref_close(vec, p, pins, memo=None):
    starts = {s for s, _ in (memo.pairs(p) if memo else ref_pairs(p, pins))}
    vals = [c for s, c in enumerate(vec) if c is not None and s in starts]
    return min(vals) if vals else None


def ref_order_cost(layout, order, pins):
    memo = RefMemo(layout, pins)
    vec = ref_first(order[0], pins, memo)
    for p, q in zip(order, order[1:]):
        vec = ref_transition(layout, pins, p, vec, q, memo)
    return ref_close(vec, order[-1], pins, memo)


def ref_enumerate(layout, order, pins):
    """Full enumeration of (start, finish) per step: min (retractions, corner links)."""
    best = None
    for choice in itertools.product(*[ref_pairs(p, pins) for p in order]):
        r = c = 0
        for i in range(1, len(order)):
            p, q = order[i - 1], order[i]
            if layout.corner_nodes[p, choice[i - 1][1]] != layout.corner_nodes[q, choice[i][0]]:
                r += 1
            elif ref_kind(layout, p, q) == "corner":
                c += 1
        if best is None or (r, c) < best:
            best = (r, c)
    return best


def ref_best(layout, pins):
    """Brute force over every order (shared prefixes): min (retractions, corner links)."""
    n = layout.n_patches
    pos = dict(pins.positions)
    if pins.start_patch is not None:
        pos[pins.start_patch] = 0
    if pins.finish_patch is not None:
        pos[pins.finish_patch] = n - 1
    at = {k: p for p, k in pos.items()}
    best = [None]
    memo = RefMemo(layout, pins)

    def rec(order, vec):
        k = len(order)
        if k == n:
            c = ref_close(vec, order[-1], pins, memo)
            if c is not None and (best[0] is None or c < best[0]):
                best[0] = c
            return
        cands = [at[k]] if k in at else [q for q in range(n) if q not in order and q not in pos]
        for q in cands:
            if q in order:
                continue
            v = ref_first(q, pins, memo) if k == 0 else ref_transition(layout, pins, order[-1], vec, q, memo)
            rec(order + [q], v)

    rec([], None)
    return best[0]


def ref_boundary_hamiltonian(layout, start=None, finish=None):
    n = layout.n_patches
    adj = [[q for q in range(n) if q != p and ref_kind(layout, p, q) == "boundary"]
           for p in range(n)]

    def rec(path, seen):
        if len(path) == n:
            return finish is None or path[-1] == finish
        return any(rec(path + [q], seen | {q}) for q in adj[path[-1]] if q not in seen)

    firsts = [start] if start is not None else range(n)
    return any(rec([p], {p}) for p in firsts)


def ref_extraordinary(layout):
    """{node: valence} of interior nodes (every edge at them has two patches) not of valence 4."""
    uses = {}
    for q in layout.corner_nodes:
        for a, b in EDGE_CORNERS:
            e = frozenset((int(q[a]), int(q[b])))
            uses[e] = uses.get(e, 0) + 1
    val, interior = {}, {}
    for e, k in uses.items():
        for node in e:
            val[node] = val.get(node, 0) + 1
            interior[node] = interior.get(node, True) and k == 2
    return {v: val[v] for v in val if interior[v] and val[v] != 4}


def rc(plist):
    return (plist.retractions, plist.corner_links)


def random_layouts(count, seed=0, sizes=(3, 4, 5, 6, 7)):
    rng = np.random.default_rng(seed)
    styles = ("grid", "fan", "pool")
    for i in range(count):
        n = int(rng.choice(sizes))
        yield ex.random_layout(int(rng.integers(1 << 30)), n, styles[i % 3])


def random_pins(layout, rng):
    n = layout.n_patches
    pins = Pins()
    r = rng.random()
    if r < 0.25:
        pins.start_patch = int(rng.integers(n))
    elif r < 0.4:
        a, b = rng.choice(n, 2, replace=False)
        pins.start_patch, pins.finish_patch = int(a), int(b)
    elif r < 0.55:
        pins.positions[int(rng.integers(n))] = int(rng.integers(n))
    if rng.random() < 0.4:
        p = int(rng.integers(n))
        pins.start_corner[p] = int(rng.integers(4))
    if rng.random() < 0.3:
        p = int(rng.integers(n))
        pins.crossfeed[p] = str(rng.choice(["u", "v"]))
    if rng.random() < 0.2:
        p = int(rng.integers(n))
        pins.finish_corner[p] = int(rng.integers(4))
        if pins.start_corner.get(p) == pins.finish_corner[p] or (
                p in pins.crossfeed and p in pins.start_corner
                and pins.crossfeed[p] not in crossfeeds_for(pins.start_corner[p],
                                                            pins.finish_corner[p])):
            del pins.finish_corner[p]
    return pins


def assert_valid(tc, layout, plist, pins=None):
    """Every patch once, zigzags possible, chained at corners unless retracting, pins kept."""
    pins = pins or Pins()
    tc.assertEqual(sorted(plist.order), list(range(layout.n_patches)))
    for i, s in enumerate(plist.steps):
        tc.assertIn((s.start, s.finish), ref_pairs(s.patch, pins))
        tc.assertIn(s.crossfeed, crossfeeds_for(s.start, s.finish))
        if i and not s.retract_before:
            prev = plist.steps[i - 1]
            tc.assertEqual(layout.corner_nodes[prev.patch, prev.finish],
                           layout.corner_nodes[s.patch, s.start])
            tc.assertEqual(s.link, ref_kind(layout, prev.patch, s.patch))
    if pins.start_patch is not None:
        tc.assertEqual(plist.order[0], pins.start_patch)
    if pins.finish_patch is not None:
        tc.assertEqual(plist.order[-1], pins.finish_patch)
    for p, k in pins.positions.items():
        tc.assertEqual(plist.order[k], p)


def random_walk_order(layout, rng):
    n = layout.n_patches
    order = [int(rng.integers(n))]
    while len(order) < n:
        nb = [q for q in range(n) if q not in order and ref_kind(layout, order[-1], q)]
        pool = nb or [q for q in range(n) if q not in order]
        order.append(int(rng.choice(pool)))
    return order


# -- tests --------------------------------------------------------------------------------
class ZigzagRules(unittest.TestCase):
    def test_crossfeeds_follow_the_definition(self):
        for s in range(4):
            for f in range(4):
                want = tuple(d for d, axis in (("u", 0), ("v", 1)) if UV[s][axis] != UV[f][axis])
                self.assertEqual(crossfeeds_for(s, f), want)
        self.assertEqual(crossfeeds_for(0, 0), ())
        self.assertEqual(crossfeeds_for(0, 2), ("u", "v"))   # diagonal: both
        self.assertEqual(crossfeeds_for(0, 1), ("u",))       # along the bottom edge: u only

    def test_preferred_crossfeed_gives_fewer_lines(self):
        # flat rectangles Lu x Lv, side step g: crossfeed u makes ceil(Lu/g)+1 lines along v,
        # crossfeed v ceil(Lv/g)+1 lines along u; same length, fewer reversals wins
        g = 0.7
        for lu, lv in ((100.0, 10.0), (10.0, 100.0), (30.0, 31.0), (31.0, 30.0)):
            pts = [(0, 0, 0), (lu, 0, 0), (lu, lv, 0), (0, lv, 0)]
            lay = Layout.from_quads([(0, 1, 2, 3)], pts)
            lines = {"u": np.ceil(lu / g) + 1, "v": np.ceil(lv / g) + 1}
            length = {"u": lines["u"] * lv + lu, "v": lines["v"] * lu + lv}
            want = min(lines, key=lines.get)
            self.assertEqual(preferred_crossfeeds(lay), [want], (lu, lv))
            self.assertLessEqual(length[want], min(length.values()) + g * max(lu, lv))

    def test_preferred_crossfeed_defaults_and_overrides(self):
        lay = Layout.from_quads([(0, 1, 2, 3), (1, 4, 5, 2)])     # no points: lengths unknown
        self.assertEqual(preferred_crossfeeds(lay), ["u", "u"])
        self.assertEqual(preferred_crossfeeds(lay, edge_lengths=lambda p: [5, 1, 5, 1]),
                         ["v", "v"])
        self.assertEqual(preferred_crossfeeds(lay, edge_lengths=lambda p: [5, 1, 5, 1],
                                              hints={1: "u"}), ["v", "u"])


class FigureSixSituations(unittest.TestCase):
    """The five situations of figure 6 on a 3 x 3 grid around the centre patch."""

    def setUp(self):
        self.lay = ex.grid(3, 3)
        self.g = PatchGraph(self.lay)
        self.centre, self.right, self.upper_right = 4, 5, 8   # cells (1,1), (2,1), (2,2)

    def test_boundary_link(self):
        # the right neighbour shares the centre's right edge: corners 1 and 2
        for s in range(4):
            got = finish_choices(self.g, self.centre, s, self.right)
            if s in (1, 2):
                self.assertEqual(situation(self.g, self.centre, s, self.right), 1)
                self.assertEqual(got, [3 - s])        # the other corner of the shared edge
            else:
                self.assertEqual(situation(self.g, self.centre, s, self.right), 2)
                self.assertEqual(got, [1, 2])

    def test_corner_link(self):
        # the upper-right neighbour shares only the centre's corner 2
        expect = {2: (3, []), 1: (4, [2]), 3: (4, [2]), 0: (5, [2])}
        for s, (sit, choices) in expect.items():
            self.assertEqual(situation(self.g, self.centre, s, self.upper_right), sit)
            self.assertEqual(finish_choices(self.g, self.centre, s, self.upper_right), choices)
        # next to the shared corner: one crossfeed; diagonal to it: both
        self.assertEqual(len(crossfeeds_for(1, 2)), 1)
        self.assertEqual(len(crossfeeds_for(0, 2)), 2)

    def test_back_tracking_out_of_situation_three(self):
        # order centre -> right -> (1,2): the right patch and cell (1,2) = 7 share only the
        # node (2,2), which is the right patch's corner 3
        order = [4, 5, 7]
        pref = ["u"] * 9
        pref[4] = "v"
        # from corner 0 the centre prefers the diagonal finish 2 (crossfeed v); the right
        # patch would then start at the corner it shares with 7 (situation 3): back track
        res = forward_pass(Rules(self.g, pref, Pins(start_corner={4: 0})), order)
        self.assertEqual(res.dead_ends, 1)
        self.assertEqual((res.starts, res.finishes[:2]), ([0, 0, 1], [1, 3]))
        # started on the shared edge the centre is forced to that corner: no way out
        pins = Pins(start_corner={4: 1})
        self.assertIsNone(forward_pass(Rules(self.g, pref, pins), order))
        dp, _ = min_retraction_corners(Rules(self.g, pref, pins), order)
        self.assertEqual(dp.retractions, 1)


class CornersForAnOrder(unittest.TestCase):
    def test_reference_dp_equals_full_enumeration(self):
        rng = np.random.default_rng(5)
        checked = 0
        for lay in random_layouts(30, seed=11, sizes=(3, 4)):
            pins = random_pins(lay, rng)
            order = random_walk_order(lay, rng)
            self.assertEqual(ref_order_cost(lay, order, pins), ref_enumerate(lay, order, pins))
            checked += 1
        self.assertEqual(checked, 30)

    def test_backtracking_and_dp_agree_with_the_reference(self):
        rng = np.random.default_rng(7)
        outcomes = {True: 0, False: 0}
        for lay in random_layouts(150, seed=3, sizes=(3, 4, 5, 6, 8, 10)):
            pins = random_pins(lay, rng)
            pins = Pins(start_corner=pins.start_corner, finish_corner=pins.finish_corner,
                        crossfeed=pins.crossfeed)
            g = PatchGraph(lay)
            rules = Rules(g, preferred_crossfeeds(lay), pins)
            order = random_walk_order(lay, rng)
            ref = ref_order_cost(lay, order, pins)
            dp, _ = min_retraction_corners(rules, order)
            got = (dp.retractions, sum(1 for i in range(1, len(order)) if not dp.retract_before[i]
                                       and ref_kind(lay, order[i - 1], order[i]) == "corner"))
            self.assertEqual(got, ref)
            fw = forward_pass(rules, order)
            self.assertEqual(fw is not None, ref[0] == 0)
            outcomes[fw is not None] += 1
            for res in (dp, fw):
                if res is None:
                    continue
                for i, p in enumerate(order):
                    self.assertIn((res.starts[i], res.finishes[i]), ref_pairs(p, pins))
                    if i and not res.retract_before[i]:
                        self.assertEqual(lay.corner_nodes[order[i - 1], res.finishes[i - 1]],
                                         lay.corner_nodes[p, res.starts[i]])
        # both kinds of order occurred, so the agreement means something
        self.assertGreater(outcomes[True], 30)
        self.assertGreater(outcomes[False], 15)


class OrderOptimality(unittest.TestCase):
    def test_random_small_layouts_match_brute_force(self):
        rng = np.random.default_rng(1)
        agree = 0
        for lay in random_layouts(45, seed=2):
            pins = random_pins(lay, rng)
            try:
                pl = plan(lay, pins)
            except InputError:
                continue
            self.assertEqual(rc(pl), ref_best(lay, pins), pins)
            assert_valid(self, lay, pl, pins)
            agree += 1
        self.assertGreater(agree, 40)

    def test_boundary_links_wherever_a_boundary_hamiltonian_path_exists(self):
        seen = {True: 0, False: 0}
        for lay in random_layouts(60, seed=9, sizes=(4, 5, 6, 7, 8)):
            exists = ref_boundary_hamiltonian(lay)
            pl = plan(lay)
            if exists:
                self.assertEqual(rc(pl), (0, 0))
                self.assertTrue(all(s.link in ("first", "boundary") for s in pl.steps))
            else:
                self.assertNotEqual(rc(pl), (0, 0))
            seen[exists] += 1
        self.assertGreater(seen[True], 8)
        self.assertGreater(seen[False], 8)

    def test_fewest_retractions_where_none_free_exists(self):
        found = 0
        for lay in list(random_layouts(40, seed=21, sizes=(4, 5, 6))) + [ex.propeller(),
                                                                           ex.twin()]:
            ref = ref_best(lay, Pins())
            if ref[0] == 0:
                continue
            pl = plan(lay)
            self.assertEqual(rc(pl), ref)
            assert_valid(self, lay, pl)
            found += 1
        self.assertGreater(found, 5)


class ExampleLayouts(unittest.TestCase):
    def chained_in_space(self, lay, pl):
        for prev, s in zip(pl.steps, pl.steps[1:]):
            if not s.retract_before:
                d = np.linalg.norm(lay.corner_point(prev.patch, prev.finish)
                                   - lay.corner_point(s.patch, s.start))
                self.assertLess(d, 1e-9)

    def test_keycap_and_head_need_no_retraction(self):
        for fn, n, n_extra in ((ex.keycap, 5, 4), (ex.head, 6, 8)):
            lay = fn()
            self.assertEqual(lay.n_patches, n)
            val = ref_extraordinary(lay)
            self.assertEqual(sorted(lay.extraordinary), sorted(val))
            self.assertEqual(set(val.values()), {3})
            self.assertEqual(len(lay.extraordinary), n_extra)
            pl = plan(lay)
            self.assertEqual(rc(pl), (0, 0))
            assert_valid(self, lay, pl)
            self.chained_in_space(lay, pl)
            # every distinct start patch also works
            for p in range(n):
                pl = plan(lay, Pins(start_patch=p))
                self.assertEqual((pl.order[0], rc(pl)), (p, (0, 0)))
                self.chained_in_space(lay, pl)

    def test_figure4_design(self):
        lay = ex.figure4()
        self.assertEqual(lay.n_patches, 12)
        kinds = [ref_kind(lay, 0, q) for q in range(1, 12)]
        self.assertEqual(kinds.count("boundary"), 4)
        self.assertEqual(kinds.count("corner"), 5)
        self.assertEqual(kinds.count(None), 2)
        val = ref_extraordinary(lay)
        self.assertEqual(sorted(lay.extraordinary), sorted(val))
        self.assertEqual(sorted(val.values()), [3, 3, 5, 5])
        # patches are convex quads seen from +z (counter-clockwise)
        for q in lay.corner_nodes:
            xy = lay.node_points[q][:, :2]
            for k in range(4):
                a, b, c = xy[k], xy[(k + 1) % 4], xy[(k + 2) % 4]
                self.assertGreater(np.cross(b - a, c - b), 0)

    def test_figure4_uses_boundary_links_only(self):
        lay = ex.figure4()
        self.assertTrue(ref_boundary_hamiltonian(lay))
        pl = plan(lay)
        self.assertEqual(rc(pl), (0, 0))
        assert_valid(self, lay, pl)
        self.chained_in_space(lay, pl)
        # pinned ends: boundary links whenever a boundary path joins them (brute force)
        for start, finish in ((0, 11), (0, 10), (2, 5), (10, 11), (3, 9)):
            pins = Pins(start_patch=start, finish_patch=finish)
            pl = plan(lay, pins)
            assert_valid(self, lay, pl, pins)
            exists = ref_boundary_hamiltonian(lay, start, finish)
            self.assertEqual(pl.corner_links + pl.retractions == 0, exists, (start, finish))

    def test_figure5c_needs_corner_links(self):
        for fn, corners in ((ex.figure5c, 2), (ex.tee, 1)):
            lay = fn()
            self.assertFalse(ref_boundary_hamiltonian(lay))
            self.assertEqual(ref_best(lay, Pins()), (0, corners))
            pl = plan(lay)
            self.assertEqual(rc(pl), (0, corners))
            assert_valid(self, lay, pl)
            self.chained_in_space(lay, pl)

    def test_propeller_and_twin_retract_once(self):
        for fn in (ex.propeller, ex.twin):
            lay = fn()
            pl = plan(lay)
            self.assertEqual(pl.retractions, 1)
            self.assertEqual(ref_best(lay, Pins())[0], 1)
            assert_valid(self, lay, pl)
            # the list with its retraction mark loads back
            again = loads(dumps(pl), lay)
            self.assertEqual(again.retraction_steps(), pl.retraction_steps())

    def test_grid_of_100_patches(self):
        lay = ex.grid(10, 10)
        pl = plan(lay)
        self.assertEqual(rc(pl), (0, 0))      # a snake exists: LKH must find boundary links
        assert_valid(self, lay, pl)
        self.chained_in_space(lay, pl)
        pins = Pins(start_patch=0, finish_patch=99, positions={45: 50})
        pl = plan(lay, pins)
        assert_valid(self, lay, pl, pins)


class TspConstruction(unittest.TestCase):
    def test_open_tour(self):
        v = 5
        self.assertEqual(open_tour([0, 1, 5, 2, 3, 4, 0], v), [2, 3, 4, 0, 1])
        self.assertEqual(open_tour([5, 4, 3, 2, 1, 0, 5], v, start=0), [0, 1, 2, 3, 4])
        self.assertEqual(open_tour([5, 0, 1, 2, 3, 4, 5], v, finish=0), [4, 3, 2, 1, 0])
        self.assertEqual(open_tour([2, 5, 3, 4, 0, 1, 2], v, start=3, finish=2), [3, 4, 0, 1, 2])

    def test_virtual_city_weights(self):
        lay = ex.figure4()
        g = PatchGraph(lay)
        m = tsp_matrix(g, Pins())
        self.assertTrue((m[12, :12] == 0).all())
        m = tsp_matrix(g, Pins(start_patch=3, finish_patch=7))
        self.assertEqual(sorted(np.flatnonzero(m[12, :12] == 0)), [3, 7])
        self.assertTrue((m == m.T).all())
        # unlinked > every corner path, corner > every boundary path
        b, c, p = m[0, 1], m[0, 2], m[0, 10]
        self.assertEqual(b, 1)
        self.assertGreater(c, 11 * b)
        self.assertGreater(p, 11 * c)


class Pinning(unittest.TestCase):
    def test_contradictory_pins_are_refused(self):
        lay = ex.figure4()
        bad = [Pins(positions={1: 3, 2: 3}), Pins(start_patch=4, finish_patch=4),
               Pins(start_patch=4, positions={5: 0}), Pins(positions={3: 12}),
               Pins(start_corner={2: 1}, finish_corner={2: 1}),
               Pins(start_corner={2: 0}, finish_corner={2: 1}, crossfeed={2: "v"}),
               Pins(start_patch=12), Pins(crossfeed={1: "w"})]
        for pins in bad:
            with self.assertRaises(InputError) as cm:
                plan(lay, pins)
            self.assertEqual(cm.exception.item, "pins")

    def test_pins_are_honoured(self):
        lay = ex.figure4()
        pins = Pins(start_patch=2, positions={0: 4}, start_corner={1: 0}, crossfeed={5: "u"},
                    finish_corner={11: 2})
        pl = plan(lay, pins)
        assert_valid(self, lay, pl, pins)
        step = {s.patch: s for s in pl.steps}
        self.assertEqual(step[1].start, 0)
        self.assertEqual(step[5].crossfeed, "u")
        self.assertEqual(step[11].finish, 2)
        self.assertEqual(step[0].pinned, frozenset({"position"}))


class ListFile(unittest.TestCase):
    def setUp(self):
        self.lay = ex.figure4()
        self.pl = plan(self.lay, model="figure4")
        self.tmp = tempfile.mkdtemp()
        self.addCleanup(shutil.rmtree, self.tmp, True)
        self.path = os.path.join(self.tmp, "list.json")
        save(self.pl, self.path)

    def edited(self, edit):
        data = json.loads(open(self.path).read())
        edit(data)
        path = os.path.join(self.tmp, "edited.json")
        with open(path, "w") as f:
            f.write(json.dumps(data, indent=1))
        return path

    def refused(self, edit, *words, item=None):
        path = self.edited(edit)
        with self.assertRaises(InputError) as cm:
            load(path, self.lay)
        exc = cm.exception
        self.assertEqual(exc.path, path)
        for w in words:
            self.assertIn(w, str(exc))
        if item:
            self.assertEqual(exc.item, item)
        return exc

    def test_round_trip(self):
        again = load(self.path, self.lay)
        self.assertEqual(again.order, self.pl.order)
        for a, b in zip(again.steps, self.pl.steps):
            self.assertEqual((a.start, a.finish, a.crossfeed, a.retract_before, a.link),
                             (b.start, b.finish, b.crossfeed, b.retract_before, b.link))
        data = json.loads(open(self.path).read())
        self.assertEqual((data["format"], data["version"], data["units"]),
                         ("tsplcam-processing-list", 1, "mm"))
        self.assertIn(data["steps"][0]["start"], CORNER_NAMES)

    def test_orientation_block_per_step(self):
        """A step may carry tool-axis settings: they load, save back, survive a re-plan;
        a list without them loads as before; a block that is not an object is refused."""
        from tsplcam.plan.listfile import orientation_blocks
        block = {"strategy": "fixed", "target": "lead-tilt", "side_tilt": 10}

        def add(d):
            d["steps"][2]["orientation"] = block
        path = self.edited(add)
        pl = load(path, self.lay)
        p2 = pl.steps[2].patch
        self.assertEqual(pl.steps[2].orientation, block)
        self.assertTrue(all(s.orientation is None for i, s in enumerate(pl.steps) if i != 2))
        again = loads(dumps(pl), self.lay)
        self.assertEqual(again.steps[2].orientation, block)
        blocks = orientation_blocks(pl, path)
        self.assertEqual(list(blocks), [p2])
        self.assertIn("step 3", blocks[p2][1])
        self.assertIn("line", blocks[p2][1])
        self.assertEqual({s.patch: s.orientation for s in complete_file(path, self.lay).steps}[p2], block)
        self.assertNotIn("orientation", open(self.path).read())          # none written when absent
        self.refused(lambda d: d["steps"][1].update(orientation=[1, 2]), "'orientation' must be an object",
                     item=f"step 2 (patch {self.pl.steps[1].patch})")

    def test_corner_indices_are_accepted(self):
        def to_index(d):
            for s in d["steps"]:
                s["start"] = CORNER_NAMES.index(s["start"])
        self.assertEqual(load(self.edited(to_index), self.lay).order, self.pl.order)

    def test_unknown_patch(self):
        exc = self.refused(lambda d: d["steps"][3].update(patch=40), "unknown patch 40",
                           item="step 4 (patch 40)")
        lines = open(exc.path).read().split("\n")
        self.assertEqual(exc.line, 1 + next(i for i, l in enumerate(lines) if '"patch": 40' in l))

    def test_repeated_and_missing_patch(self):
        p0 = self.pl.steps[0].patch
        self.refused(lambda d: d["steps"][5].update(patch=p0), "repeated", "already step 1",
                     item=f"step 6 (patch {p0})")
        last = self.pl.steps[-1].patch
        self.refused(lambda d: d.update(steps=d["steps"][:-1], patches=None),
                     f"patch(es) {last}", "missing", item="steps")

    def test_start_not_at_previous_finish(self):
        s = self.pl.steps[4]
        wrong = next(c for c in range(4) if c != s.start and c != s.finish
                     and self.lay.corner_nodes[s.patch, c] != self.lay.corner_nodes[
                         self.pl.steps[3].patch, self.pl.steps[3].finish])
        exc = self.refused(lambda d: d["steps"][4].update(start=CORNER_NAMES[wrong]),
                           "not the point where step 4", "retract_before",
                           item=f"step 5 (patch {s.patch})")
        self.assertIsNotNone(exc.line)
        # marking the retraction makes it acceptable
        def fix(d):
            d["steps"][4].update(start=CORNER_NAMES[wrong], retract_before=True, link="retract",
                                 crossfeed=crossfeeds_for(wrong, s.finish)[0])
        self.assertEqual(load(self.edited(fix), self.lay).retractions, 1)

    def test_corner_link_where_patches_share_no_corner(self):
        lay = ex.twin()                        # patches 0,1 | 2,3: 1 and 2 share nothing
        text = dumps(plan(lay))
        data = json.loads(text)
        order = [s["patch"] for s in data["steps"]]
        i = next(k for k in range(1, 4) if data["steps"][k]["retract_before"])
        data["steps"][i].update(retract_before=False, link="corner")
        with self.assertRaises(InputError) as cm:
            loads(json.dumps(data), lay, path="twin.json")
        self.assertIn("a corner link is used where patches", str(cm.exception))
        self.assertIn("share no corner", str(cm.exception))
        self.assertEqual(cm.exception.item, f"step {i + 1} (patch {order[i]})")
        del data["steps"][i]["link"]
        with self.assertRaises(InputError) as cm:
            loads(json.dumps(data), lay, path="twin.json")
        self.assertIn("share no corner", str(cm.exception))

    def test_zigzag_that_cannot_reach_its_finish(self):
        s = self.pl.steps[2]
        adj = next(f for f in range(4) if f != s.start and len(crossfeeds_for(s.start, f)) == 1)
        wrong_d = "v" if crossfeeds_for(s.start, adj) == ("u",) else "u"

        def edit(d):
            d["steps"][2].update(finish=CORNER_NAMES[adj], crossfeed=wrong_d)
        self.refused(edit, f"crossfeed {wrong_d} cannot run", item=f"step 3 (patch {s.patch})")
        self.refused(lambda d: d["steps"][2].update(finish=d["steps"][2]["start"]),
                     "cannot end at the corner it started from")

    def test_form_errors(self):
        self.refused(lambda d: d.update(version=2), "version", item="version")
        self.refused(lambda d: d.update(format="gcode"), "format", item="format")
        self.refused(lambda d: d["steps"][1].update(crosfeed="u"), "unknown key", "crosfeed")
        self.refused(lambda d: d["steps"][1].update(start="middle"), "not a corner")
        self.refused(lambda d: d["steps"][1].update(pinned=["everything"]), "pinned")
        self.refused(lambda d: d.update(layout="sha256:0000000000000000"), "another model",
                     item="layout")
        path = os.path.join(self.tmp, "broken.json")
        with open(path, "w") as f:
            f.write('{\n "format": "tsplcam-processing-list",\n "version": 1,\n "steps": [\n'
                    '  {"patch": 0,}\n ]\n}\n')
        with self.assertRaises(InputError) as cm:
            load(path, self.lay)
        self.assertEqual(cm.exception.line, 5)

    def test_complete_keeps_the_pins(self):
        # a person moves patch 9 first, pins it and its start corner, blanks the rest
        def edit(d):
            steps = d["steps"]
            nine = next(s for s in steps if s["patch"] == 9)
            steps.remove(nine)
            steps.insert(0, nine)
            for s in steps:
                s.update(start=None, finish=None, crossfeed=None, link=None)
            nine.update(start="upper-left", pinned=["position", "start"])
            steps[-1]["pinned"] = ["crossfeed"]
            steps[-1]["crossfeed"] = "v"
        path = self.edited(edit)
        with self.assertRaises(InputError):
            load(path, self.lay)                 # not a complete list
        pl = complete_file(path, self.lay)
        last = json.loads(open(path).read())["steps"][-1]["patch"]
        pins = Pins(start_patch=9, start_corner={9: 3}, crossfeed={last: "v"})
        assert_valid(self, self.lay, pl, pins)
        self.assertEqual(pl.steps[0].start, 3)
        # from a start corner on any patch, boundary links always hand over: the list is
        # all boundary links exactly when a boundary path starts at patch 9 (brute force)
        self.assertEqual(rc(pl) == (0, 0), ref_boundary_hamiltonian(self.lay, start=9))


class CommandLine(unittest.TestCase):
    """The plan command: the refusal in its own process (exit code, stderr), the runs that
    succeed through the same entry point (tsplcam.cli.main) in this process."""

    def run_cli(self, *args):
        env = dict(os.environ, PYTHONPATH=REPO_DIR)
        return subprocess.run([SYSTEM_PYTHON, "-m", "tsplcam", "plan", *args],
                              capture_output=True, text=True, env=env, cwd=REPO_DIR)

    def run_here(self, *args):
        """(exit code, stdout, stderr) of ``tsplcam plan ARGS`` run by tsplcam.cli.main here."""
        import contextlib
        import io
        from tsplcam.cli import main
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(["plan", *args])
        return code, out.getvalue(), err.getvalue()

    def test_plan_writes_and_checks_a_list(self):
        tmp = tempfile.mkdtemp()
        self.addCleanup(shutil.rmtree, tmp, True)
        out = os.path.join(tmp, "keycap.json")
        code, stdout, stderr = self.run_here("--example", "keycap", "--out", out)
        self.assertEqual(code, 0, stderr)
        self.assertIn("0 corner links, 0 retractions", stdout)
        self.assertEqual(len(load(out, ex.keycap()).steps), 5)
        code, stdout, stderr = self.run_here("--example", "keycap", "--check", out)
        self.assertEqual(code, 0, stderr)
        res = self.run_cli("--example", "head", "--check", out)
        self.assertEqual(res.returncode, 2)
        self.assertIn("another model", res.stderr)
        self.assertNotIn("Traceback", res.stderr)


BOX_OBJ = """v -10 -10 0\nv 10 -10 0\nv 10 10 0\nv -10 10 0
v -9 -9 10\nv 9 -9 10\nv 9 9 10\nv -9 9 10
f 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8
"""
CUBE_OBJ = """v -40 -50 -60\nv 40 -50 -60\nv 40 50 -60\nv -40 50 -60
v -40 -50 60\nv 40 -50 60\nv 40 50 60\nv -40 50 60
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8
"""


class KernelModels(unittest.TestCase):
    """The kernel's cage models of an open box and a cube plan like the hand-built layouts."""

    def test_transit_corners_are_one_point_of_the_surface(self):
        import tsplcam
        from tsplcam.layout.layout import CORNER_UV
        from tsplcam.plan.graph import model_edge_lengths
        tmp = tempfile.mkdtemp()
        self.addCleanup(shutil.rmtree, tmp, True)
        for text, hand in ((BOX_OBJ, ex.keycap()), (CUBE_OBJ, ex.head())):
            path = os.path.join(tmp, "model.obj")
            with open(path, "w") as f:
                f.write(text)
            model = tsplcam.load(path)
            lay = Layout.from_model(model)
            self.assertEqual(lay.n_patches, hand.n_patches)
            self.assertEqual(sorted(ref_extraordinary(lay).values()),
                             sorted(ref_extraordinary(hand).values()))
            degrees = lambda L: sorted(  # noqa: E731
                tuple(sorted(str(ref_kind(L, p, q)) for q in range(L.n_patches) if q != p))
                for p in range(L.n_patches))
            self.assertEqual(degrees(lay), degrees(hand))
            pl = plan(lay, edge_lengths=model_edge_lengths(model))
            self.assertEqual(rc(pl), (0, 0))
            for a, b in zip(pl.steps, pl.steps[1:]):
                ua, va = CORNER_UV[a.finish]
                ub, vb = CORNER_UV[b.start]
                pa = model.evaluate(a.patch, np.array([ua]), np.array([va])).P
                pb = model.evaluate(b.patch, np.array([ub]), np.array([vb])).P
                self.assertLess(np.linalg.norm(np.asarray(pa) - np.asarray(pb)), 1e-9)
