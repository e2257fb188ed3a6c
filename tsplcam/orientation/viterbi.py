"""Minimum-cost state sequences along a chain: the Viterbi algorithm (dynamic programming).

Every point ``i`` of a path has the same ``S`` states (candidate tool axes, or machine
poses); a sequence costs the sum of its node costs ``node[i, s_i]`` and of its transition
costs ``T_i[s_i, s_{i+1}]``; ``inf`` marks a state or a move that is not allowed. One
forward pass keeps, per state, the cheapest way to reach it and where it came from; the
backward pass reads the best sequence off. Exact, ``O(n S^2)``, one array operation per
point (the recurrence is sequential, each step is vectorised over the ``S x S`` moves).

The tool-orientation smoothing (candidate axes per point) and the post's choice of machine
poses (inverse-kinematics branches and C representatives per point) both use this one
function. Ties, and costs equal up to a relative ``TIE``, go to the lowest state: vectorised
sums may differ in the last bits with memory alignment from run to run, and no decision
(and so no program byte) may hang on them.

The recurrence runs in a compiled kernel (:mod:`tsplcam.compiled`, numba) when
numba is installed: the same arithmetic, so the same states and costs bit for bit; this
module's numpy loop is the reference and the fallback. A transition function may bring its
own compiled steps (:func:`from_blocks`), which compute the transitions inside the kernel.
Where the work is below that at which a process loads the kernels (``compiled.kernels``) but
a set was put aside for it (``compiled.prepare``: the job's), that set runs the recurrence:
the same states, and the process's choice for its other callers is left as it was.
"""
from __future__ import annotations

import numpy as np

from .. import compiled

TIE = 1e-9
BLOCK = 32               # transitions fetched this many points at a time (arrays that stay in cache)


def first_min(v: np.ndarray, axis: int = 0) -> np.ndarray:
    """Index of the smallest value along ``axis``; values within ``TIE`` (relative) of it
    count as equal and the first of them wins."""
    m = v.min(axis=axis, keepdims=True)
    return np.argmax(v <= m + TIE * np.maximum(1.0, np.abs(m)), axis=axis)


def _le(x: float, y: float) -> bool:
    """x <= y up to the relative tie tolerance (infinite costs compare exactly)."""
    if x == np.inf or y == np.inf:
        return x <= y
    return x <= y + TIE * max(1.0, abs(x), abs(y))


def _two_states(node: np.ndarray, trans: np.ndarray):
    """S = 2 with every transition given: plain floats beat array calls on 2 x 2 steps."""
    n = len(node)
    nd = node.tolist()
    t = trans.reshape(-1, 4).tolist()
    a0, a1 = nd[0]
    bk = [None] * n
    for i in range(1, n):
        c00, c01, c10, c11 = t[i - 1]
        x0, x1 = a0 + c00, a1 + c10
        y0, y1 = a0 + c01, a1 + c11
        b0 = 0 if _le(x0, x1) else 1
        b1 = 0 if _le(y0, y1) else 1
        n0, n1 = nd[i]
        a0 = (x0 if b0 == 0 else x1) + n0
        a1 = (y0 if b1 == 0 else y1) + n1
        if a0 == np.inf and a1 == np.inf:
            return None, i - 1
        bk[i] = (b0, b1)
    if a0 == np.inf and a1 == np.inf:
        return None, -1
    state = np.zeros(n, np.int64)
    s = 0 if _le(a0, a1) else 1
    for i in range(n - 1, 0, -1):
        state[i] = s
        s = bk[i][s]
    state[0] = s
    return state, None


def from_blocks(block, steps=None):
    """A transition function ``i -> (S, S)`` from ``block(i0, i1)``, the transitions into
    points i0 .. i1 - 1 as one (i1 - i0, S, S) array, which :func:`viterbi` then calls.
    ``steps(k, acc, node, i0, i1, tie, back)``, if given: the compiled recurrence over those
    points with the transitions computed inside the kernel (the same bits as ``block``'s,
    see ``viterbi_steps`` in :mod:`~tsplcam.compiled` for its contract), which
    :func:`viterbi` uses instead of the blocks when the kernels are loaded."""
    def trans(i: int) -> np.ndarray:
        return block(i, i + 1)[0]
    trans.block = block
    trans.steps = steps
    return trans


def viterbi(node: np.ndarray, transition, kernel: bool = True) -> tuple:
    """The cheapest state sequence.

    ``node``: (n, S) node costs (``inf``: the state is not allowed at that point);
    ``transition``: an (n-1, S, S) array, or a function ``i -> (S, S)`` array giving the cost
    of going from state a at point ``i - 1`` to state b at point ``i`` (``inf``: forbidden).
    Returns ``(states, None)`` with ``states`` (n,) int, or ``(None, i)`` when no allowed
    sequence reaches point ``i + 1`` (the chain breaks between ``i`` and ``i + 1``; ``i = -1``
    when the first point has no allowed state). ``kernel`` False: the numpy loop even where
    the compiled kernel is available.
    """
    node = np.asarray(node, float)
    n, S = node.shape
    if not np.isfinite(node[0]).any():
        return None, -1
    if n == 1:
        return np.array([int(first_min(node[0]))], np.int64), None
    if callable(transition):
        # a function with a ``block(i0, i1)`` attribute gives the transitions into points
        # i0 .. i1 - 1 at once, (i1 - i0, S, S): one array call per block instead of per point
        block = getattr(transition, "block", None) or (lambda i0, i1: np.stack([transition(i) for i in range(i0, i1)]))
    else:
        trans = np.asarray(transition, float)
        if S == 2:
            k = compiled.loaded() if kernel else None
            if k is None or trans.shape != (n - 1, 2, 2):
                return _two_states(node, trans)
            states = np.zeros(n, np.int64)
            broke = k["two_states"](np.require(node, np.float64, "C"), np.require(trans, np.float64, "C"), TIE, states)
            return (states, None) if broke == -2 else (None, int(broke))
        block = lambda i0, i1: trans[i0 - 1:i1 - 1]      # noqa: E731
    acc = node[0].copy()
    back = np.zeros((n, S), np.int32)
    k = compiled.kernels(work=float(n) * S * S) if kernel else None
    if k is None and kernel:
        # a set compiled.prepare loaded aside (the job does, while its path is computed):
        # the same states as the numpy loop, without loading it for the process (whose
        # other callers, e.g. the banded solves, keep to the work it asked for; keycap_mold:
        # its first programmes, 0.16 s in numpy)
        k = compiled.prepared()
    if k is not None:
        return _compiled(k, node, acc, back, block, getattr(transition, "steps", None))
    cols = np.arange(S)
    T, lo = np.zeros((0, S, S)), 1
    for i in range(1, n):
        if i >= lo + len(T):
            lo = i
            T = block(i, min(n, i + BLOCK))
        tot = acc[:, None] + T[i - lo]
        m = tot.min(axis=0)
        b = np.argmax(tot <= m + TIE * np.maximum(1.0, np.abs(m)), axis=0)      # first_min
        acc = tot[b, cols] + node[i]
        back[i] = b
        if not np.isfinite(acc).any():
            return None, i - 1
    states = np.zeros(n, np.int64)
    states[-1] = int(first_min(acc))
    for i in range(n - 1, 0, -1):
        states[i - 1] = back[i, states[i]]
    return states, None


def _compiled(k, node, acc, back, block, steps=None) -> tuple:
    """:func:`viterbi`'s forward and backward passes in the compiled kernels (the same
    arithmetic as its numpy loop): a block of transitions per call, or all points in one
    call of ``steps`` (transitions computed in the kernel, see :func:`from_blocks`)."""
    n = len(node)
    node = np.require(node, np.float64, ("C", "W"))
    if steps is not None:
        broke = steps(k, acc, node, 1, n, TIE, back)
        if broke >= 0:
            return None, int(broke) - 1
    for i0 in range(1, n if steps is None else 1, BLOCK):
        T = np.require(block(i0, min(n, i0 + BLOCK)), np.float64, ("C", "W"))
        broke = k["viterbi_steps"](acc, node, T, i0, TIE, back)
        if broke >= 0:
            return None, int(broke) - 1
    states = np.zeros(n, np.int64)
    k["viterbi_path"](back, int(first_min(acc)), states)
    return states, None
