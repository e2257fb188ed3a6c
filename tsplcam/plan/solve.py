"""The planner: layout (+ pins) -> processing list (shang2020 sections 3.3 and 3.4).

1. Order the patches with LKH (:func:`~tsplcam.plan.order.lkh_order`).
2. Choose transit corners by the paper's forward pass with back tracking; when it finds
   no retraction-free choice, the exact programme marks the fewest retractions and where
   (:func:`~tsplcam.plan.corners.choose_corners`).
3. On small layouts (``exact_limit`` patches or fewer) a Held-Karp programme with the
   corner rules folded in certifies the result and replaces it if it is worse; on larger
   ones, each corner link that cost a retraction is forbidden and LKH asked once more, then
   short runs next to the remaining retractions are reversed while that removes any.

A result's quality is judged by (1) fewest retractions, (2) fewest corner links; pins are
hard constraints; among equals, fewest steps whose crossfeed is not the preferred one.
"""
from __future__ import annotations

from dataclasses import replace

from ..errors import InputError
from .corners import Rules, build_steps, choose_corners, cost_weights
from .graph import NONE, PatchGraph, layout_hash, preferred_crossfeeds
from .order import exact_order, lkh_order, polish_retractions
from .steps import CROSSFEEDS, Pins, ProcessingList, crossfeeds_for

EXACT_LIMIT = 12
MAX_EXACT = 16      # Held-Karp's table has 2^n * n * 4 entries: 32 MB at 16 patches


def normalise_pins(pins: Pins | None, n: int) -> Pins:
    """Pins with start/finish folded into positions; contradictory pins are refused.

    Raises :class:`InputError` (item 'pins') naming the patches whose pins conflict.
    """
    pins = pins or Pins()

    def patch_ok(p, what):
        if isinstance(p, bool) or not isinstance(p, int) or not 0 <= p < n:
            raise InputError(f"{what}: patch {p!r} is not a patch of this layout "
                             f"(0..{n - 1})", item="pins")

    positions = {}
    for p, k in dict(pins.positions).items():
        patch_ok(p, "position pin")
        if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < n:
            raise InputError(f"patch {p} is pinned to position {k!r}, outside 1..{n}",
                             item="pins")
        positions[p] = k
    for p, k, what in ((pins.start_patch, 0, "start patch"), (pins.finish_patch, n - 1,
                                                              "finish patch")):
        if p is None:
            continue
        patch_ok(p, what)
        if p in positions and positions[p] != k:
            raise InputError(f"patch {p} is pinned as {what} and to position "
                             f"{positions[p] + 1}", item="pins")
        positions[p] = k
    if n > 1 and pins.start_patch is not None and pins.start_patch == pins.finish_patch:
        raise InputError(f"patch {pins.start_patch} is pinned as both start and finish patch",
                         item="pins")
    seen = {}
    for p, k in positions.items():
        if k in seen:
            raise InputError(f"patches {seen[k]} and {p} are both pinned to position {k + 1}",
                             item="pins")
        seen[k] = p
    for table, what in ((pins.start_corner, "start corner"), (pins.finish_corner,
                                                              "finish corner")):
        for p, c in table.items():
            patch_ok(p, what + " pin")
            if isinstance(c, bool) or not isinstance(c, int) or not 0 <= c < 4:
                raise InputError(f"patch {p}: {what} {c!r} is not a corner 0..3", item="pins")
    for p, d in pins.crossfeed.items():
        patch_ok(p, "crossfeed pin")
        if d not in CROSSFEEDS:
            raise InputError(f"patch {p}: crossfeed {d!r} is not 'u' or 'v'", item="pins")
    for p in set(pins.start_corner) | set(pins.finish_corner) | set(pins.crossfeed):
        s, f, d = pins.start_corner.get(p), pins.finish_corner.get(p), pins.crossfeed.get(p)
        if s is not None and f is not None:
            if s == f:
                raise InputError(f"patch {p}: start and finish are pinned to the same corner "
                                 f"{s}; a zigzag cannot end where it began", item="pins")
            if d is not None and d not in crossfeeds_for(s, f):
                raise InputError(f"patch {p}: a zigzag with crossfeed {d} cannot run from "
                                 f"corner {s} to corner {f} (pinned)", item="pins")
    start = next((p for p, k in positions.items() if k == 0), None)
    finish = next((p for p, k in positions.items() if k == n - 1), None) if n > 1 else start
    return Pins(start, finish, positions, dict(pins.start_corner), dict(pins.finish_corner),
                dict(pins.crossfeed))


def _rank(cost: int, n: int) -> int:
    """Retractions and corner links of an integer cost, as one comparable number."""
    return cost // cost_weights(n)[1]


def plan(layout, pins: Pins | None = None, *, preferred: list[str] | None = None,
         edge_lengths=None, hints: dict | None = None, exact_limit: int = EXACT_LIMIT,
         lkh_runs: int = 1, max_resolves: int = 1, model: str = "",
         units: str = "mm") -> ProcessingList:
    """The processing list of a layout: order, transit corners and crossfeed per patch.

    ``preferred`` gives the preferred crossfeed per patch; by default it is computed by
    :func:`~tsplcam.plan.graph.preferred_crossfeeds` from ``edge_lengths`` (a callable
    patch -> 4 edge lengths) or the corner chords, with per-patch ``hints``.
    """
    graph = PatchGraph(layout)
    n = graph.n
    pins = normalise_pins(pins, n)
    if preferred is None:
        preferred = preferred_crossfeeds(layout, edge_lengths, hints)
    rules = Rules(graph, preferred, pins)
    info = {"patches": n}
    if n == 0:
        return ProcessingList([], model, units, layout_hash(layout), info)

    order = lkh_order(graph, pins, runs=lkh_runs)
    res, cost = choose_corners(rules, order)
    method = "LKH"
    if n <= min(exact_limit, MAX_EXACT):
        ex_order, ex_cost = exact_order(rules, pins)
        info["exact_rank"] = _rank(ex_cost, n)
        if _rank(ex_cost, n) < _rank(cost, n):
            order = ex_order
            res, cost = choose_corners(rules, order)
            method = "exact (Held-Karp), LKH's order was worse"
        else:
            method = "LKH, certified optimal by Held-Karp"
    else:
        forbid: set = set()
        for _ in range(max_resolves):
            bad = {(order[i - 1], order[i]) for i in range(1, n)
                   if res.retract_before[i] and graph.kind[order[i - 1], order[i]] != NONE}
            if not bad or not res.retractions:
                break
            forbid |= bad
            o2 = lkh_order(graph, pins, forbid=forbid, runs=lkh_runs)
            r2, c2 = choose_corners(rules, o2)
            if _rank(c2, n) < _rank(cost, n):
                order, res, cost = o2, r2, c2
                method = "LKH, re-solved with retraction links forbidden"
        if res.retractions:
            o3, r3, c3 = polish_retractions(rules, order)
            if _rank(c3, n) < _rank(cost, n):
                order = o3
                res, cost = choose_corners(rules, order)
                method += ", polished by 2-opt at retractions"
    info.update(order_method=method, corner_method=res.method, dead_ends=res.dead_ends,
                crossfeed_mismatches=sum(int(rules.miss[p, res.starts[i], res.finishes[i]])
                                         for i, p in enumerate(order)))
    steps = build_steps(rules, order, res)
    return ProcessingList(steps, model, units, layout_hash(layout), info)


def pins_of(plist: ProcessingList) -> Pins:
    """The pins written in a processing list (each step's ``pinned`` fields)."""
    pins = Pins()
    n = len(plist.steps)
    for i, s in enumerate(plist.steps):
        if "position" in s.pinned:
            pins.positions[s.patch] = i
        if "start" in s.pinned and s.start is not None:
            pins.start_corner[s.patch] = s.start
        if "finish" in s.pinned and s.finish is not None:
            pins.finish_corner[s.patch] = s.finish
        if "crossfeed" in s.pinned and s.crossfeed is not None:
            pins.crossfeed[s.patch] = s.crossfeed
    if n:
        first = [p for p, k in pins.positions.items() if k == 0]
        last = [p for p, k in pins.positions.items() if k == n - 1]
        pins.start_patch = first[0] if first else None
        pins.finish_patch = last[0] if last else None
    return pins


def complete(plist: ProcessingList, layout, **options) -> ProcessingList:
    """Re-solve everything a person did not pin in ``plist`` (see :func:`plan`)."""
    out = plan(layout, pins_of(plist), model=plist.model, units=plist.units, **options)
    return replace(out, info=dict(out.info, completed_from=len(plist.steps)))
