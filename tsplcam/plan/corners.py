"""Transit corners for a patch order (shang2020 section 3.4, figure 6).

Given the order, each step needs a start and a finish corner such that every step starts
at the node where the step before finished. Two methods:

* :func:`forward_pass` is the paper's: walk the order, pick for each patch a finish corner
  from which the next patch can start (figure 6's five situations), preferring the one
  compatible with the patch's preferred crossfeed, and back track when a patch has no
  possible finish (a corner link whose shared corner is the patch's own start). Dead ends
  (step, start corner) are remembered, so the search visits each of the 4n states once.
* :func:`min_retraction_corners` is an exact dynamic programme over (step, start corner)
  that also allows a retraction before any step. It gives the fewest retractions the order
  needs (then the fewest corner links crossed, then the fewest crossfeed directions other
  than the preferred one), and so says where to retract when the forward pass fails.

Both honour pinned corners and crossfeed (:class:`~tsplcam.plan.steps.Pins`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .graph import BOUNDARY, CORNER, KIND_NAMES, PatchGraph
from .steps import Pins, Step, crossfeeds_for, is_diagonal

# Figure 6's situations: what the next patch shares and where the start corner lies.
SITUATIONS = {
    1: "boundary link, start on the shared edge: one finish corner",
    2: "boundary link, start off the shared edge: two finish corners",
    3: "corner link, start at the shared corner: no finish corner (back track)",
    4: "corner link, start next to the shared corner: one finish corner",
    5: "corner link, start diagonal to the shared corner: one finish corner",
}


class Rules:
    """Which (start, finish) each patch may take under the pins, and what it costs.

    ``ok[p, s, f]``: the step on p may run from s to f (f != s, pinned corners and pinned
    crossfeed respected). ``miss[p, s, f]`` is 1 when that pair forces a crossfeed other
    than p's preferred one (section 3.3: the preferred direction decides when both are
    possible). ``can_start[p, s]``: some finish is allowed from s.
    """

    def __init__(self, graph: PatchGraph, preferred: list[str], pins: Pins | None = None):
        self.graph = graph
        self.pins = pins or Pins()
        self.preferred = list(preferred)
        n = graph.n
        ok = np.zeros((n, 4, 4), dtype=bool)
        miss = np.zeros((n, 4, 4), dtype=np.int64)
        pin_s, pin_f, pin_d = self.pins.start_corner, self.pins.finish_corner, self.pins.crossfeed
        for p in range(n):
            for s in range(4):
                if p in pin_s and pin_s[p] != s:
                    continue
                for f in range(4):
                    if f == s or (p in pin_f and pin_f[p] != f):
                        continue
                    dirs = crossfeeds_for(s, f)
                    if p in pin_d:
                        if pin_d[p] not in dirs:
                            continue
                    elif self.preferred[p] not in dirs:
                        miss[p, s, f] = 1
                    ok[p, s, f] = True
        self.ok = ok
        self.miss = miss
        self.can_start = ok.any(axis=2)
        # best mismatch over finishes for a free start (used after a retraction)
        self.n = n

    def crossfeed(self, p: int, s: int, f: int) -> str:
        dirs = crossfeeds_for(s, f)
        if p in self.pins.crossfeed:
            return self.pins.crossfeed[p]
        return self.preferred[p] if self.preferred[p] in dirs else dirs[0]

    def handovers(self, p: int, s: int, q: int) -> list[tuple[int, int]]:
        """(finish of p, start of q) pairs possible after starting p at s, preferred first."""
        out = []
        for f in range(4):
            if self.ok[p, s, f]:
                for s2 in self.graph.entries(p, f, q):
                    if self.can_start[q, s2]:
                        out.append((int(self.miss[p, s, f]), f, s2))
        out.sort()
        return [(f, s2) for _, f, s2 in out]

    def last_finishes(self, p: int, s: int) -> list[int]:
        fs = [f for f in range(4) if self.ok[p, s, f]]
        fs.sort(key=lambda f: (int(self.miss[p, s, f]), f))
        return fs


def situation(graph: PatchGraph, p: int, s: int, q: int) -> int:
    """Figure 6's situation (1..5) of patch p started at corner s, q next; 0 if unlinked."""
    edges = graph.shared_edge_corners(p, q)
    if edges:
        return 1 if any(s in e for e in edges) else 2
    shared = [f for f in range(4) if graph.entries(p, f, q)]
    if not shared:
        return 0
    c = shared[0]
    if s == c:
        return 3
    return 5 if is_diagonal(s, c) else 4


def finish_choices(graph: PatchGraph, p: int, s: int, q: int) -> list[int]:
    """Finish corners of p (started at s, any crossfeed) from which q can start."""
    return [f for f in range(4) if f != s and graph.entries(p, f, q)]


@dataclass
class CornerResult:
    """Start/finish per step, where retractions go, and how the answer was found."""
    starts: list[int]
    finishes: list[int]
    retract_before: list[bool]
    method: str
    dead_ends: int = 0

    @property
    def retractions(self) -> int:
        return sum(self.retract_before)


def forward_pass(rules: Rules, order: list[int]) -> CornerResult | None:
    """Section 3.4's main loop with back tracking; None when no retraction-free choice exists.

    The first start corner is tried in index order (the paper picks it at random); each
    finish follows figure 6 with the preferred-crossfeed choice first. A (step, start)
    that failed once is marked unusable, which is what makes the back tracking linear.
    """
    n = len(order)
    if n == 0:
        return CornerResult([], [], [], "forward pass")
    dead: set[tuple[int, int]] = set()

    def cands(i, s):
        if i == n - 1:
            return [(f, None) for f in rules.last_finishes(order[i], s)]
        return rules.handovers(order[i], s, order[i + 1])

    for s0 in range(4):
        if not rules.can_start[order[0], s0] or (0, s0) in dead:
            continue
        frames = [[0, s0, cands(0, s0), 0]]
        while frames:
            top = frames[-1]
            i, s, cs, k = top
            if i == n - 1 and cs:
                starts = [fr[1] for fr in frames]
                finishes = [fr[2][fr[3] - 1][0] for fr in frames[:-1]] + [cs[0][0]]
                return CornerResult(starts, finishes, [False] * n, "forward pass", len(dead))
            if k >= len(cs):
                dead.add((i, s))
                frames.pop()
                continue
            top[3] += 1
            f, s2 = cs[k]
            if (i + 1, s2) in dead:
                continue
            frames.append([i + 1, s2, cands(i + 1, s2), 0])
    return None


def cost_weights(n: int) -> tuple[int, int]:
    """(retraction, corner link) weights making the integer cost lexicographic.

    cost = retractions * W_R + corner links * W_C + crossfeed mismatches, with at most n
    mismatches and n - 1 corner links.
    """
    w_c = n + 1
    return w_c * w_c, w_c


def min_retraction_corners(rules: Rules, order: list[int]) -> tuple[CornerResult, int]:
    """Exact corners for an order: fewest retractions, then corner links, then mismatches.

    Dynamic programme over (step, start corner): 4 states per step, each moving to the
    next step's start through a shared node (no retraction) or anywhere (one retraction).
    Returns the assignment and its integer cost (see :func:`cost_weights`).
    """
    n = len(order)
    w_r, w_c = cost_weights(n)
    inf = float("inf")
    best = [[inf] * 4 for _ in range(n)]
    back: list[list] = [[None] * 4 for _ in range(n)]
    kind = rules.graph.kind
    for s in range(4):
        if rules.can_start[order[0], s]:
            best[0][s] = 0
    for i in range(n - 1):
        p, q = order[i], order[i + 1]
        link_cost = w_c if kind[p, q] == CORNER else 0
        retract = []
        for s in range(4):
            b = best[i][s]
            if b == inf:
                continue
            for f in range(4):
                if not rules.ok[p, s, f]:
                    continue
                c = b + int(rules.miss[p, s, f])
                for s2 in rules.graph.entries(p, f, q):
                    if rules.can_start[q, s2] and c + link_cost < best[i + 1][s2]:
                        best[i + 1][s2] = c + link_cost
                        back[i + 1][s2] = (s, f, False)
                retract.append((c + w_r, s, f))
        if retract:
            c, s, f = min(retract)
            for s2 in range(4):
                if rules.can_start[q, s2] and c < best[i + 1][s2]:
                    best[i + 1][s2] = c
                    back[i + 1][s2] = (s, f, True)
    last = order[-1]
    end = min(((best[n - 1][s] + int(rules.miss[last, s, f]), s, f)
               for s in range(4) for f in range(4)
               if best[n - 1][s] < inf and rules.ok[last, s, f]), default=None)
    if end is None:
        raise ValueError("no step assignment satisfies the pins")  # callers check pins first
    cost, s, f = end
    starts, finishes, retract = [0] * n, [0] * n, [False] * n
    starts[-1], finishes[-1] = s, f
    for i in range(n - 1, 0, -1):
        ps, pf, r = back[i][starts[i]]
        starts[i - 1], finishes[i - 1], retract[i] = ps, pf, r
    return CornerResult(starts, finishes, retract, "exact"), int(cost)


def assignment_cost(rules: Rules, order: list[int], res: CornerResult) -> int:
    """Integer cost (see :func:`cost_weights`) of a complete assignment."""
    w_r, w_c = cost_weights(len(order))
    cost = 0
    for i, p in enumerate(order):
        cost += int(rules.miss[p, res.starts[i], res.finishes[i]])
        if i:
            if res.retract_before[i]:
                cost += w_r
            elif rules.graph.kind[order[i - 1], p] == CORNER:
                cost += w_c
    return cost


def choose_corners(rules: Rules, order: list[int]) -> tuple[CornerResult, int]:
    """The paper's forward pass; the exact programme marks retractions when it fails."""
    res = forward_pass(rules, order)
    if res is None:
        return min_retraction_corners(rules, order)
    return res, assignment_cost(rules, order, res)


def build_steps(rules: Rules, order: list[int], res: CornerResult) -> list[Step]:
    """Steps of the processing list from an order and its corners."""
    pins = rules.pins
    positioned = set(pins.positions)
    for p in (pins.start_patch, pins.finish_patch):
        if p is not None:
            positioned.add(p)
    steps = []
    for i, p in enumerate(order):
        s, f = res.starts[i], res.finishes[i]
        if i == 0:
            link = "first"
        elif res.retract_before[i]:
            link = "retract"
        else:
            link = KIND_NAMES[int(rules.graph.kind[order[i - 1], p])] or "retract"
        pinned = set()
        if p in positioned:
            pinned.add("position")
        if p in pins.start_corner:
            pinned.add("start")
        if p in pins.finish_corner:
            pinned.add("finish")
        if p in pins.crossfeed:
            pinned.add("crossfeed")
        steps.append(Step(p, s, f, rules.crossfeed(p, s, f), bool(res.retract_before[i]),
                          link, frozenset(pinned)))
    return steps


__all__ = ["Rules", "SITUATIONS", "situation", "finish_choices", "forward_pass",
           "min_retraction_corners", "choose_corners", "build_steps", "CornerResult",
           "cost_weights", "assignment_cost", "BOUNDARY", "CORNER"]
