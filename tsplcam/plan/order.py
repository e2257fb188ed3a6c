"""Patch order (shang2020 section 3.3): a TSP over patches solved with LKH (``elkai``).

Weights: a boundary link costs 1, a corner link n (more than all the boundary links a
path holds), a pair of patches that touch nowhere n^2 (more than all its corner links):
the order avoids unlinked neighbours first, then corner links (the scale stops growing at
200 patches to keep LKH's integers small; the order of preference stays).

The paper closes the Hamiltonian path into a tour with a zero-weight link between the
start patch and the suggested finish patch and opens the tour there. Here that link is
drawn through a virtual city: zero-weight edges from it to the start patch and the finish
patch. When neither end is pinned every patch (but those pinned to an interior position)
gets a zero-weight edge to it, so LKH also chooses both ends; when one end is pinned, only
that patch does and every other edge of the virtual city weighs more than any path, a
constant that every tour pays once, so LKH still chooses the free end. The tour opened at
the virtual city is the order, reversed when the pinned start comes last (or the pinned
finish first).

LKH is a heuristic. :func:`exact_order` is a Held-Karp dynamic programme over (set of
patches done, last patch, its finish corner) with the corner rules of section 3.4 folded
in; the planner runs it on small layouts to certify (or replace) LKH's answer.
"""
from __future__ import annotations

import numpy as np

from .corners import Rules, cost_weights, min_retraction_corners
from .graph import CORNER, NONE, PatchGraph
from .steps import Pins


def link_weights(n: int) -> tuple[int, int, int]:
    """(boundary, corner, no link) weights of the TSP for n patches."""
    s = min(max(n, 2), 200)
    return 1, s, s * s


def pair_weights(graph: PatchGraph, forbid=()) -> np.ndarray:
    """n x n symmetric TSP weights from the link kinds; ``forbid`` pairs weigh as unlinked."""
    b, c, p = link_weights(graph.n)
    table = np.array([p, c, b], dtype=np.int64)  # indexed by NONE, CORNER, BOUNDARY
    w = table[graph.kind.astype(np.int64)]
    for a, z in forbid:
        w[a, z] = w[z, a] = p
    np.fill_diagonal(w, 0)
    return w


def tsp_matrix(graph: PatchGraph, pins: Pins, forbid=()) -> np.ndarray:
    """(n+1) x (n+1) weights with the virtual city (index n) closing the path."""
    n = graph.n
    w = pair_weights(graph, forbid)
    big = (n + 1) * link_weights(n)[2]
    m = np.zeros((n + 1, n + 1), dtype=np.int64)
    m[:n, :n] = w
    first, last = pins.start_patch, pins.finish_patch
    ends = np.zeros(n, dtype=bool)
    if first is None and last is None:
        # LKH picks both ends among the patches not pinned to an interior position
        ends[:] = True
        for p, k in pins.positions.items():
            if 0 < k < n - 1:
                ends[p] = False
    else:
        # a pinned end has the only zero-weight edge; the other edge of the virtual city
        # then weighs ``big`` whichever patch takes it: a constant, so LKH still chooses it
        for p in (first, last):
            if p is not None:
                ends[p] = True
    m[n, :n] = m[:n, n] = np.where(ends, 0, big)
    return m


def open_tour(tour: list[int], virtual: int, start: int | None = None,
              finish: int | None = None) -> list[int]:
    """The order from a closed tour: cut at the virtual city, oriented start -> finish.

    ``tour`` may repeat its first city at the end (elkai does). The path is reversed when
    the pinned start patch comes last or the pinned finish patch comes first.
    """
    t = list(tour)
    if len(t) > 1 and t[0] == t[-1]:
        t = t[:-1]
    k = t.index(virtual)
    path = t[k + 1:] + t[:k]
    if (start is not None and path and path[0] != start) or \
            (start is None and finish is not None and path and path[-1] != finish):
        path.reverse()
    return path


def path_weight(w: np.ndarray, order: list[int]) -> int:
    o = np.asarray(order)
    return int(w[o[:-1], o[1:]].sum()) if len(o) > 1 else 0


def lkh_order(graph: PatchGraph, pins: Pins, forbid=(), runs: int = 1) -> list[int]:
    """The patch order from LKH (via elkai), with start/finish pins and position pins.

    One LKH run by default: on the layouts measured (grids with holes, fans of corner
    links, 100 patches) 2, 5 or 10 runs never found a lighter path, and each run costs
    about as much as the first. Interior position pins are placed afterwards by
    :func:`fit_positions`.
    """
    n = graph.n
    if n == 0:
        return []
    if n == 1:
        return [0]
    import elkai
    m = tsp_matrix(graph, pins, forbid)
    tour = elkai.DistanceMatrix(m.tolist()).solve_tsp(runs=max(1, int(runs)))
    order = _honour_ends(open_tour(tour, n, pins.start_patch, pins.finish_patch), pins)
    if any(0 < k < n - 1 for k in pins.positions.values()):
        order = fit_positions(order, pins.positions, m[:n, :n])
    return order


def _honour_ends(order: list[int], pins: Pins) -> list[int]:
    """Move pinned end patches to the ends should LKH's tour not have put them there."""
    o = list(order)
    if pins.start_patch is not None and o[0] != pins.start_patch:
        o.remove(pins.start_patch)
        o.insert(0, pins.start_patch)
    if pins.finish_patch is not None and o[-1] != pins.finish_patch:
        o.remove(pins.finish_patch)
        o.append(pins.finish_patch)
    return o


def fit_positions(order: list[int], positions: dict, w: np.ndarray,
                  max_passes: int = 50) -> list[int]:
    """Put pinned patches at their positions, then improve the free ones by local search.

    The free patches keep LKH's relative order; then swaps of two free patches and
    reversals of runs of free positions (2-opt) are applied while they lower the path
    weight. A heuristic for large layouts: small ones are solved exactly.
    """
    n = len(order)
    fixed = {k: p for p, k in positions.items()}
    free = [p for p in order if p not in positions]
    it = iter(free)
    o = [fixed[k] if k in fixed else next(it) for k in range(n)]
    is_free = [k not in fixed for k in range(n)]

    def edge(i, j):
        return int(w[o[i], o[j]])

    def around(idx):
        s = 0
        for i in sorted(set(idx)):
            if i > 0:
                s += edge(i - 1, i)
        for i in sorted(set(idx)):
            if i + 1 < n and (i + 1) not in idx:
                s += edge(i, i + 1)
        return s

    for _ in range(max_passes):
        improved = False
        free_idx = [k for k in range(n) if is_free[k]]
        for a_i, i in enumerate(free_idx):
            for j in free_idx[a_i + 1:]:
                before = around({i, j})
                o[i], o[j] = o[j], o[i]
                if around({i, j}) < before:
                    improved = True
                else:
                    o[i], o[j] = o[j], o[i]
        # 2-opt inside runs of free positions
        k = 0
        while k < n:
            if not is_free[k]:
                k += 1
                continue
            e = k
            while e + 1 < n and is_free[e + 1]:
                e += 1
            for i in range(k, e + 1):
                for j in range(i + 1, e + 1):
                    old = (edge(i - 1, i) if i > 0 else 0) + (edge(j, j + 1) if j + 1 < n else 0)
                    new = (int(w[o[i - 1], o[j]]) if i > 0 else 0) + \
                          (int(w[o[i], o[j + 1]]) if j + 1 < n else 0)
                    if new < old:
                        o[i:j + 1] = o[i:j + 1][::-1]
                        improved = True
            k = e + 1
        if not improved:
            break
    return o


def polish_retractions(rules: Rules, order: list[int], window: int = 12,
                       max_evals: int = 200):
    """Reverse short runs next to retractions between linked patches while that helps.

    For a large layout where a corner link cost a retraction (the corner rules of section
    3.4 are not in LKH's weights), try 2-opt reversals of up to ``window`` patches ending
    or starting at the retraction, each scored exactly by
    :func:`~tsplcam.plan.corners.min_retraction_corners`; keep the first that lowers
    (retractions, corner links). Pinned positions are not moved. Returns (order, result,
    cost).
    """
    n = len(order)
    w_c = cost_weights(n)[1]
    fixed = set(rules.pins.positions)
    res, cost = min_retraction_corners(rules, order)
    evals = 0
    kind = rules.graph.kind
    improved = True
    while improved and evals < max_evals:
        improved = False
        for i in range(1, n):
            if not res.retract_before[i] or kind[order[i - 1], order[i]] == NONE:
                continue
            moves = [(j, i - 1) for j in range(max(0, i - window), i - 1)] + \
                    [(i, j) for j in range(i + 1, min(n, i + window))]
            for a, b in moves:
                if any(p in fixed for p in order[a:b + 1]) or evals >= max_evals:
                    continue
                o = order[:a] + order[a:b + 1][::-1] + order[b + 1:]
                r2, c2 = min_retraction_corners(rules, o)
                evals += 1
                if c2 // w_c < cost // w_c:
                    order, res, cost, improved = o, r2, c2, True
                    break
            if improved:
                break
    return order, res, cost


def exact_order(rules: Rules, pins: Pins) -> tuple[list[int], int]:
    """Optimal order and its cost: Held-Karp over (patch set, last patch, finish corner).

    Cost (see :func:`~tsplcam.plan.corners.cost_weights`): retractions first, corner
    links second, crossfeed mismatches third; pinned positions, corners and crossfeed are
    honoured. Memory and time grow as 2^n: for n <= ~14.
    """
    graph = rules.graph
    n = graph.n
    if n == 0:
        return [], 0
    w_r, w_c = cost_weights(n)
    inf = np.int64(1) << 60
    full = (1 << n) - 1
    at_pos = {k: p for p, k in pins.positions.items()}
    pinned = set(pins.positions)

    def allowed(k):
        if k in at_pos:
            return [at_pos[k]]
        return [p for p in range(n) if p not in pinned]

    ok, miss = rules.ok, rules.miss
    big = np.int64(1) << 40
    # cost of the step on q when it may start anywhere (first step or after a retraction)
    free_start = np.where(ok, miss, big).min(axis=1)                 # (n, 4) over f
    free_start = np.where(free_start >= big, inf, free_start)
    # handover tables A[p][q][f, f'] = link cost + best mismatch of q over valid starts
    hand = {}
    for p in range(n):
        for q in range(n):
            if p == q or graph.kind[p, q] == NONE:
                continue
            a = np.full((4, 4), inf, dtype=np.int64)
            link = w_c if graph.kind[p, q] == CORNER else 0
            for f in range(4):
                for s2 in graph.entries(p, f, q):
                    for f2 in range(4):
                        if ok[q, s2, f2]:
                            a[f, f2] = min(a[f, f2], link + miss[q, s2, f2])
            if (a < inf).any():
                hand[p, q] = a
    into = {q: [p for p in range(n) if (p, q) in hand] for q in range(n)}

    cost = np.full((1 << n, n, 4), inf, dtype=np.int64)
    for p in allowed(0):
        cost[1 << p, p] = free_start[p]
    masks = np.arange(1 << n, dtype=np.int64)
    pop = np.zeros(1 << n, dtype=np.int64)
    for b in range(n):
        pop += (masks >> b) & 1
    for k in range(1, n):
        prev = masks[pop == k]
        best_any = cost[prev].reshape(len(prev), -1).min(axis=1)
        for q in allowed(k):
            sel = ((prev >> q) & 1) == 0
            ms = prev[sel]
            if not len(ms):
                continue
            tgt = ms | (1 << q)
            cand = np.minimum(best_any[sel][:, None] + w_r + free_start[q][None, :], inf)
            for p in into[q]:
                src = cost[ms, p]                                      # (m, 4) over f
                via = (src[:, :, None] + hand[p, q][None, :, :]).min(axis=1)
                cand = np.minimum(cand, via)
            cost[tgt, q] = np.minimum(cost[tgt, q], np.minimum(cand, inf))

    ends = allowed(n - 1)
    finals = [(int(cost[full, q, f]), q, f) for q in ends for f in range(4)]
    total, q, f = min(finals)
    if total >= inf:
        raise ValueError("no order satisfies the pins")
    # walk back
    order = [q]
    mask, v = full, total
    while mask != (1 << q):
        prev_mask = mask ^ (1 << q)
        found = None
        for p in into[q]:
            if not (prev_mask >> p) & 1:
                continue
            for f0 in range(4):
                c0 = cost[prev_mask, p, f0]
                if c0 < inf and c0 + hand[p, q][f0, f] == v:
                    found = (p, f0, int(c0))
                    break
            if found:
                break
        if found is None:
            best = cost[prev_mask].reshape(-1)
            i = int(np.argmin(best))
            assert int(best[i]) + w_r + int(free_start[q, f]) == v
            found = (i // 4, i % 4, int(best[i]))
        q, f, v = found
        mask = prev_mask
        order.append(q)
    order.reverse()
    return order, total
