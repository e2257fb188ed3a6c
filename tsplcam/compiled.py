"""Compiled kernels (numba) for the engine's sequential loops, with numpy as fallback.

A module below every stage (it imports none, so any stage may use its kernels); its callers
are the model's surface evaluation and the orientation's loops, whose warm-up (every kernel
called once through its callers, :func:`tsplcam.orientation.warmup.exercise`) :func:`prepare`
and :func:`warm` are handed.

Surface points (``cubic_points``, :mod:`tsplcam.model.cubic_points`): a patch of bicubic cells
evaluated point after point, each point one bicubic net (Bernstein values, the contraction
along a, then along b, the offset, the scales; homogeneous values divided out where the patch
has weights), the numpy route's operations in its order, so the same bits with the kernels or
without. A polynomial net's point (every sample's Bezier cells and the extraordinary cells'
nets; not at a vertex, cells of non-zero width) takes a written-out copy of those operations
(``bicubic_point``: no scratch arrays, no branch per derivative; the same bits): 0.07 us a
point with second derivatives (0.05 without) where the generic loop took 0.11 (0.08), against
0.65 us for numpy's group-by-group route on the path's calls (392k points a keycap path: 0.29
-> 0.05 -> 0.03 s; measured on random points of the five sample models' patches). It is used
wherever the kernels can be loaded (``kernels()`` without a work estimate: the ahead-of-time
module loads in about a millisecond), so a point's values never depend on what else a process
did; the collision checker's tessellation takes its grids' positions from it too
(:meth:`~tsplcam.model.patch.Patch.grids_points`).

The path's cusp heights at the line ends (``cusp_ends``, :func:`tsplcam.toolpath.lines._end_pass`:
for each gap and line end, 17 edge points' entries along their normals into the two lines' end
capsules, then the bracket of the crossing and its interpolation) are, in numpy, some sixty
array calls on G x 68 elements each (G gaps at once); the kernel makes the same operations per point in
the same order (np.minimum / np.maximum written out with numpy's nan and tie rules, the first
crossing as argmax finds it, divisions by zero as numpy's), so the same bits (but for the sign
of a peak 0 reached by both +0 and -0, see the kernel); keycap path:
0.062 -> 0.010 s (CPU, median of 6 pairs, load 3.3). Used, like ``cubic_points``, wherever the
kernels can be loaded.

The cusps between two lines themselves (``cusp_foot``, :func:`tsplcam.toolpath.lines._cusp_foot`:
the balls' centres, their spheres' intersection nearest the surface, one Gauss-Newton step
to its foot and the height by the second fundamental form) are some forty array calls on
G x m points; the kernel makes them point by point in their order, each dot product summed
as numpy's einsum sums it there: (x0 + x2) + x1 in its paired loop, where both operands'
coordinates lie next to each other in memory, else in order (the caller reads which from the
arrays' strides, ``lines._sum_orders``), so the same bits; the keycap path 0.135 -> 0.125 s
in one process, the same points bit for bit as before on the sample models.

The Viterbi recurrence (:mod:`tsplcam.orientation.viterbi`) is sequential along the path:
numpy spends one sequence of array calls per point, about 11 us for 36 x 36 states, and
cannot go lower. The kernel here does the same arithmetic per point, element for element (one
addition per move, the same minimum, the same relative tie tolerance, the same first-index
tie-breaking), so the chosen states and their costs are the numpy version's bit for bit, at
about a tenth of the time. For the smoothing's joint programme a second form of it
(``joint_steps``) computes each transition where the recurrence uses it instead of reading
it from an (n, S, S) block that numpy built (keycap_mold: the blocks 0.31 s, the recurrence 0.08 s):
the operations of the numpy block's, element for element in its order, on numpy's cos and
sin of the tilts (numba's libm may differ from numpy's by an ulp), so the same bits. Its
caller hands it 2048 points at a time with their cos and sin (the recurrence carries on
across the calls: the same bits), not the whole (n, S) tables of fresh memory after the fork.
The forced rotary travel's programme (``kind_steps``) reads each move's transition from one of
its two matrices (into a short block or not) by the move's kind, in one call where a call per
run of one kind took the keycap's 1,100 runs.

The smoothing's meridian grid (:func:`~tsplcam.orientation.smoothing.meridian_grid`: per point
and rotary value the admissible tilt range, 530k of them on the keycap) spends its time in
element-wise passes over (1024, M) blocks: the dot products with the meridians (numpy's three
passes, ``meridian_dots`` one) and each lead/tilt cone's arc (the branch nearest the
reference, then lo and hi: nine passes, ``cone_arcs`` one, with numpy's float mod, maximum
and minimum written out). The arctangents stay numpy's (its SIMD arctan2 is not libm's);
the same bits (tests/orientation/test_viterbi_compiled.py): a grid of the keycap's size
(14,734 points x 36, random cones) 20.8-24.8 -> 14.7 ms alone, the keycap job's 0.027-0.033 ->
0.022-0.026 s.

Two-state chains (the post's branch choice, :func:`~tsplcam.orientation.viterbi._two_states`:
plain Python floats, about 1.5 us a point) run in ``two_states``, the same float operations in
the same order, where the kernels are loaded already (they are not loaded for it).

The distance grids' read (:class:`~tsplcam.orientation.broadphase.DistanceGrid`, two million
points on the keycap_mold job) is a gather of eight nodes per point: numpy's temporaries
cost about 250 ns a point, the kernel a tenth of that, with the same operations in the same
order (the same bounds, bit for bit).

The broad phase's sphere loop (:meth:`~tsplcam.orientation.broadphase.BroadPhase.decide`:
each pose's tool parts covered by spheres, split level by level, bounded by the distance
grids, the grid nodes' samples of failing spheres tried as hits) is, in numpy, a sequence of
array calls per level over all poses with temporaries per sphere; ``sphere_loop`` takes the
poses one by one with the same operations per sphere in the same order (about 0.5 us a
pose on the keycap's candidates against 1.5-2 us), so the same decisions and bits. Its hit
test (``hit_pairs``: samples inside the tool, their pieces' anchors outside) serves the
broad phase's other passes too (keycap_mold: 0.32 CPU-s in numpy). The side pass's balls
are bounded by the grids in ``side_bounds`` (each ball's slab and centre and its grid reads,
the same operations; only the balls left open are listed), and the free cones are stored row
by row in ``store_cones`` (the rounds of numpy's gathers and masks, the same cones kept).
The ball centres' slots come from ``centre_slots`` (an open-addressing table on the centres'
three 64-bit words, each slot checked against its centre's: which rows share a slot, as the
numpy form's sorted hashes give it). The exact pass's narrow bands come from ``band_samples``
(a table of the samples by cubic cells, each point's cells scanned: the nearest sample, the
count and the set in the band, as the KD-tree's k nearest give them, the squared distances
summed in its order: about 0.3 us a point on the keycap against 2 us in the tree); the
triangles of the samples in the band are measured by ``measure_pairs`` (pair by pair, each
pair's plane test and closest point as ``closest_on_triangles`` takes them, with its dot
products summed x, y, z: the same distances; the keycap's ball gouge check 13 -> 1 ms there,
without the pairs' temporaries).

The broad phase's cylinder pass (``cylinder_clear``, :meth:`~tsplcam.orientation.broadphase.BroadPhase._cylinder_pass`)
has no numpy form: per (pose, part) it scans the cells of a table of the samples around the
axis, flags the samples within reach and clips their triangles to the cylinder (one polygon
clip per triangle, a few per pose), about 2.7 us a pose on the keycap's smallest clearance
where fcl took 10 us; without the kernels the parts are left to fcl (the same answers).

The verification's capsule entries (:meth:`tsplcam.verify.scallop.Swept.entry`: where the ray
along each surface sample's normal enters each of its candidate capsules) come from
``capsule_entries``, candidate by candidate with the numpy form's operations in its order (each
dot product summed (x + z) + y), so the same bits, reading the capsules by index instead of
numpy's gathers into (rows, candidates) temporaries; for a ridge's bisection the least entry of
each owner's candidates at once (the keycap's verification in one process 2.44 -> 1.54 s with
the ridges' ends taking their grid samples' candidates).

The verification's neighbour searches (each surface sample's 16 nearest capsule pieces,
:meth:`tsplcam.verify.scallop.Swept.candidates`, and each ball centre's two nearest grid
samples within reach, the gouge check) come from ``k_nearest`` on a table of cells
(:func:`cell_table`, sorted in one pass by ``cell_sort``): the cells scanned ring by ring around
the point until the (k + 1)-th nearest found lies nearer than every cell not scanned, each
squared distance summed as scipy's kd-tree sums it, so the same neighbours in the same order
and the same distances bit for bit; where two of the k + 1 nearest lie at the same distance
the tree's walk decides their order, so the kernel says so and the caller asks the tree for
those rows (none of tjunction_mold's 3.1 M capsule queries, 5 of its 138,499 gouge queries).
tjunction_mold's capsule queries 4.4 -> 1.8 s, the keycap's 0.73 -> 0.29 s, about 0.55 us a
query against 1.6 in the tree.

The banded Cholesky solve of the smoothing's polish (``_Banded.solve_box``, 57 solves on
the keycap, 215 before its problems started from the last active set) is latency-bound in
LAPACK as here; the kernel takes LAPACK's operations in LAPACK's reference order, with less
overhead per call. Where OpenBLAS's dtbsv keeps that
order x is the same bit for bit; its AVX-512 kernels sum otherwise, and as the polish's
systems are ill-conditioned the two x then differ by up to 1e-6 rad on the keycap (both
backward stable to a few machine epsilons), so the program's angles can move in their last
printed digit between a run with numba and one without. The kernel's own order does not
depend on the CPU (numba is not asked for fast-math, so no sums are reordered or fused).
Where the kernels are loaded already, ``solve_box`` runs the polish's whole active-set loop
(its numpy steps element for element, the solve as ``banded_solve``): the same x as the loop
calling ``banded_solve``, without numpy's overhead per iteration; an iteration takes again only
the steps of the factor and of the substitutions whose inputs changed since the last (a step on
the same bits gives the same bits: keycap 0.100 -> 0.019 s for its six solves of then; its
four of now, started warm, 0.017 -> 0.005 s).

Where the kernels come from, in this order: the ahead-of-time module ``_aot_kernels``
beside this file (built by ``scripts/install.sh`` through :func:`build_aot`, numba's pycc,
with the argument types of :data:`SIGNATURES`), loaded in about a millisecond without
importing numba, if it was built from this file's kernel source for this processor
(:func:`build_key`, stored in the module); else numba's JIT (``cache=True``: compiled on
first use and cached on disk, in ``__pycache__`` beside this file, else in the user's cache
directory; with neither writable compiled in each process, about 0.7 s), whose import and
cached kernels cost a process about 0.35 s; else none. Both compile the same Python
functions (:func:`_define`) for the same CPU without fast-math: the same bits. The module's
kernels check their arguments' types (:class:`_Exported`) and hand others to numba's.

The broad phase's nearest-sample calls (:meth:`~tsplcam.orientation.broadphase.SampleTree.query`,
k 1: the distance grids' nodes, most of the checker's build) go to a kd-tree of its own
(``kd_build``: median splits of the widest coordinate; ``kd_nearest2``: the two nearest below
a bound, each search starting from the previous point's answers, which a grid's next node
lies next to). The same squared distances as scipy's tree (summed x, y, z) and the same two
nearest, so the same answers bit for bit, ties left to scipy's default tree as before; the
keycap's two grids (50k nodes) 28.9 + 26.3 -> 13.7 + 8.6 ms against scipy's fast tree.

The kernels are optional: :func:`kernels` returns None when neither is there (a FreeCAD
without numba and no module) or when ``TSPLCAM_COMPILED=0`` is set, and the callers run
their numpy version. A process asks for them only once the work it has asked for reaches
``LOAD_WORK`` (about half numba's load in numpy's time: small paths stay in numpy; the
threshold is kept with the module, so that which paths run compiled, and so the bytes, do
not depend on where the kernels come from). The callers whose numpy version gives the
kernel's bits (minima, booleans, sums in one order) use that threshold; the smoothing's
banded solve, whose numpy version is LAPACK's, loads the kernels at its first call, so a
job's bytes do not depend on the work its process did before it.
"""
from __future__ import annotations

import os
import time
from collections.abc import Callable

import numpy as np

_STATE = {"work": 0.0}
#: work (elements of the Viterbi recurrence, S^2 per point, or their equivalent) after which
#: a process loads the kernels: about half the load's time in numpy (8.5 ns an element)
LOAD_WORK = 1.0e7


def _build():
    """The kernels: the ahead-of-time module where it is built from this source, else numba's
    (compiled lazily, or loaded from its cache); None without either or with
    ``TSPLCAM_COMPILED=0``."""
    if os.environ.get("TSPLCAM_COMPILED", "1") == "0":
        return None
    aot = _aot()
    return aot if aot is not None else _jit()


def _jit():
    """numba's kernels (compiled on first use, or loaded from numba's cache); None without
    numba. Built once a process (the ahead-of-time kernels ask for them on arguments of
    other types than :data:`SIGNATURES`')."""
    if "jit" not in _STATE:
        try:
            import numba
        except ImportError:
            _STATE["jit"] = None
        else:
            def jit(f):
                try:
                    return numba.njit(cache=True, nogil=True)(f)
                except RuntimeError:      # no writable cache location: compile in each process
                    return numba.njit(cache=False, nogil=True)(f)
            _STATE["jit"] = _define(jit)
    return _STATE["jit"]


def _define(jit):
    """The kernels, each as ``jit`` makes it of its Python function (numba's ``njit``; the
    identity for the ahead-of-time build, which compiles the functions themselves).
    :func:`build_key` reads this function's text: the ahead-of-time module is used only
    while it is the text the module was built from."""
    import math

    import numba
    import numpy as np

    # the kernels' inlined helpers are module globals, not closure cells: numba's cache keys a
    # closure by its cells, and a dispatcher in a cell differs in every process, so a kernel
    # calling one was compiled again in every process (cusp_foot: 1.2-1.6 s)
    global viterbi_step, dot3, meets_cylinder, ieee_quotient, to_finite, bicubic_point, bernstein_row, comb4, \
        sq_dist, keep_two, union_root

    @numba.njit(inline="always")
    def viterbi_step(acc, node, X, q, i, tie, back, tot, m, nan):
        """One step of the Viterbi recurrence into point ``i`` with the transitions ``X[q]``
        (S, S): ``acc`` (S,) and ``back[i]`` updated in place (``tot``, ``m``, ``nan`` its
        scratch); whether a state is still reachable. Inlined into its callers."""
        S = acc.shape[0]
        m[:] = np.inf
        nan[:] = False
        for a in range(S):
            x = acc[a]
            for b in range(S):
                v = x + X[q, a, b]
                tot[a, b] = v
                if v < m[b]:
                    m[b] = v
                elif v != v:
                    nan[b] = True
        live = False
        for b in range(S):
            mb = np.nan if nan[b] else m[b]
            lim = mb + tie * max(1.0, abs(mb))
            k = 0
            for a in range(S):
                if tot[a, b] <= lim:
                    k = a
                    break
            back[i, b] = k
            v = tot[k, b] + node[i, b]
            acc[b] = v
            if np.isfinite(v):
                live = True
        return live

    @jit
    def viterbi_steps(acc, node, T, i0, tie, back):
        """The Viterbi recurrence for points ``i0 .. i0 + len(T) - 1``: ``T[r]`` (S, S) the
        transitions into point ``i0 + r``; updates ``acc`` (S,) and ``back`` (n, S) in place.
        Returns -1, or the point at which no state is reachable any more."""
        B, S = T.shape[0], T.shape[1]
        tot = np.empty((S, S))
        m = np.empty(S)
        nan = np.empty(S, np.bool_)
        for r in range(B):
            if not viterbi_step(acc, node, T, r, i0 + r, tie, back, tot, m, nan):
                return i0 + r
        return -1

    @jit
    def meridian_dots(V, m, out):
        """``smoothing._meridian_dots`` where the meridians are horizontal: ``out[i, k] =
        V[i, 0] m[k, 0] + V[i, 1] m[k, 1] + 0.0``, each product and sum rounded as numpy's
        three passes round them (the same bits) in one pass."""
        for i in range(V.shape[0]):
            v0 = V[i, 0]
            v1 = V[i, 1]
            for k in range(m.shape[0]):
                r = v0 * m[k, 0]
                r += v1 * m[k, 1]
                r += 0.0
                out[i, k] = r

    @jit
    def cone_arcs(al, ref, half, lo, hi):
        """``theta_interval``'s half-arc of one constraint on a meridian grid, in place: per
        element the arc's centre ``al`` taken on the branch nearest ``ref``, ``ref + (pi -
        mod(pi - (al - ref), 2 pi))`` (numpy's float mod: fmod (exact), then the divisor added
        where the two signs differ, +0 where it is 0), then ``lo = maximum(lo, centre -
        half)`` and ``hi = minimum(hi, centre + half)`` (numpy's maximum and minimum: a nan
        wins, lo's or hi's first): the same operations in the same order, so the same bits.
        All (rows, M)."""
        two_pi = 2 * np.pi
        for i in range(al.shape[0]):
            for j in range(al.shape[1]):
                r = ref[i, j]
                t = np.pi - (al[i, j] - r)
                # (fmod returns t itself where |t| < 2 pi: exactly, so not asked there)
                md = t if -two_pi < t < two_pi else np.fmod(t, two_pi)
                # (2 pi > 0: added where md < 0; +0 for a zero of either sign; a nan kept)
                md = md + two_pi if md < 0.0 else (md if md != 0.0 else 0.0)
                c = r + (np.pi - md)
                # (selects, not branches: which bound wins is data, not predictable)
                a = c - half
                b = lo[i, j]
                v = a if a > b else b
                if b != b:
                    v = b
                elif a != a:
                    v = a
                lo[i, j] = v
                a = c + half
                b = hi[i, j]
                v = a if a < b else b
                if b != b:
                    v = b
                elif a != a:
                    v = a
                hi[i, j] = v

    @jit
    def kind_steps(acc, node, both, kind, i0, i1, tie, back):
        """:func:`viterbi_steps` for points ``i0 .. i1 - 1`` whose transitions are one of a
        few matrices: ``both[kind[i - 1]]`` (S, S) into point i (the forced rotary travel's
        moves, into a short block or not), read in place rather than from a block per run
        (the same step, :func:`viterbi_step`)."""
        S = both.shape[1]
        tot = np.empty((S, S))
        m = np.empty(S)
        nan = np.empty(S, np.bool_)
        for i in range(i0, i1):
            if not viterbi_step(acc, node, both, kind[i - 1], i, tie, back, tot, m, nan):
                return i
        return -1

    @jit
    def joint_steps(acc, node, i0, i1, th, cth, sth, D2, D1, cosD, swing, alpha, beta, travel,
                    lds, hard, short, cmin, tie, back):
        """:func:`viterbi_steps` for points ``i0 .. i1 - 1`` with the smoothing programme's
        joint-space transitions computed move by move instead of read from a block: the
        operations of :func:`~tsplcam.orientation.smoothing.joint_transitions`'s numpy block,
        element for element in its order (so the same bits; ``cth``, ``sth`` numpy's cos and
        sin of the tilts ``th``). ``lds`` (n-1,) L / ds; ``hard`` (n,) the tool-axis step
        limit applies (``dots < cmin`` forbidden); ``short`` (n,) a rotary ``swing`` is
        forbidden; ``beta``, ``travel`` 0: their terms left out, as numpy does."""
        S = th.shape[1]
        tot = np.empty((S, S))
        t = np.empty(S)
        m = np.empty(S)
        nan = np.empty(S, np.bool_)
        use_beta = beta != 0.0
        use_travel = travel != 0.0
        for i in range(i0, i1):
            f = lds[i - 1]
            hi = hard[i]
            sh = short[i]
            m[:] = np.inf
            nan[:] = False
            for a in range(S):
                x = acc[a]
                if x == np.inf:
                    # a state out of reach (excluded, or behind one): inf + any transition
                    # (0 to inf) is inf, so its row is inf without computing the transitions
                    # (the keycap's 15 % excluded states: 16 -> 14 ms)
                    for b in range(S):
                        tot[a, b] = np.inf
                    continue
                ta = th[i - 1, a]
                ca = cth[i - 1, a]
                sa = sth[i - 1, a]
                for b in range(S):
                    dots = ca * cth[i, b]
                    dots += (sa * sth[i, b]) * cosD[a, b]
                    dt = ta - th[i, b]
                    dt *= dt
                    dt += D2[a, b]
                    c = alpha * dt
                    if use_beta:
                        c += beta * (2.0 - 2.0 * dots)
                    c *= f
                    if use_travel:
                        c += D1[a, b]
                    if (hi and dots < cmin) or (sh and swing[a, b]):
                        c = np.inf
                    t[b] = c
                # from here on viterbi_step's arithmetic, written out again: fused with the
                # transitions (each row's in registers) it takes 15 ms on the keycap, through
                # the helper on a block of them 20 ms
                for b in range(S):
                    v = x + t[b]
                    tot[a, b] = v
                    if v < m[b]:
                        m[b] = v
                    elif v != v:
                        nan[b] = True
            live = False
            for b in range(S):
                mb = np.nan if nan[b] else m[b]
                lim = mb + tie * max(1.0, abs(mb))
                k = 0
                for a in range(S):
                    if tot[a, b] <= lim:
                        k = a
                        break
                back[i, b] = k
                v = tot[k, b] + node[i, b]
                acc[b] = v
                if np.isfinite(v):
                    live = True
            if not live:
                return i
        return -1

    @jit
    def viterbi_path(back, last, states):
        """Read the states off the back pointers, from ``last`` at the final point."""
        s = last
        n = states.shape[0]
        states[n - 1] = s
        for i in range(n - 1, 0, -1):
            s = back[i, s]
            states[i - 1] = s

    @jit
    def two_states(node, t, tie, states):
        """``viterbi._two_states`` (S = 2), the same float operations in the same order: fills
        ``states``; returns -2, or the point before which the chain breaks as that function's
        second value (-1: none at the last point). Its ``_le`` (x <= y up to the relative tie;
        Python's max passes a NaN over) is written out at each use: a kernel that calls
        another is compiled again in every process, not loaded from the cache."""
        n = node.shape[0]
        back = np.zeros((n, 2), np.int8)
        a0 = node[0, 0]
        a1 = node[0, 1]
        for i in range(1, n):
            x0 = a0 + t[i - 1, 0, 0]
            x1 = a1 + t[i - 1, 1, 0]
            y0 = a0 + t[i - 1, 0, 1]
            y1 = a1 + t[i - 1, 1, 1]
            if x0 == np.inf or x1 == np.inf:
                le = x0 <= x1
            else:
                m = 1.0
                if abs(x0) > m:
                    m = abs(x0)
                if abs(x1) > m:
                    m = abs(x1)
                le = x0 <= x1 + tie * m
            b0 = 0 if le else 1
            if y0 == np.inf or y1 == np.inf:
                le = y0 <= y1
            else:
                m = 1.0
                if abs(y0) > m:
                    m = abs(y0)
                if abs(y1) > m:
                    m = abs(y1)
                le = y0 <= y1 + tie * m
            b1 = 0 if le else 1
            a0 = (x0 if b0 == 0 else x1) + node[i, 0]
            a1 = (y0 if b1 == 0 else y1) + node[i, 1]
            if a0 == np.inf and a1 == np.inf:
                return i - 1
            back[i, 0] = b0
            back[i, 1] = b1
        if a0 == np.inf and a1 == np.inf:
            return -1
        if a0 == np.inf or a1 == np.inf:
            le = a0 <= a1
        else:
            m = 1.0
            if abs(a0) > m:
                m = abs(a0)
            if abs(a1) > m:
                m = abs(a1)
            le = a0 <= a1 + tie * m
        s = 0 if le else 1
        for i in range(n - 1, 0, -1):
            states[i] = s
            s = back[i, s]
        states[0] = s
        return -2

    @jit
    def banded_solve(ab, rhs):
        """Solve H x = rhs for a symmetric positive definite band matrix H in LAPACK's upper
        band form ``ab`` (u + 1, N) (``ab[u + i - j, j] = H[i, j]``), by the Cholesky
        factorisation H = U^T U and two triangular solves in the order of LAPACK's dpbtf2
        and the reference dtbsv (scipy's ``solveh_banded``): the same x, bit for bit where a
        BLAS keeps that order, within the system's conditioning where it does not. ``ab`` and ``rhs``
        are overwritten (with U and x). Returns 0, or the 1-based leading minor that is not
        positive definite."""
        u, N = ab.shape[0] - 1, ab.shape[1]
        for j in range(N):
            d = ab[u, j]
            if not d > 0.0:
                return j + 1
            d = np.sqrt(d)
            ab[u, j] = d
            # U^T y = rhs, row j (the dot product first), as soon as column j of U is final:
            # the two recurrences overlap in the processor, the arithmetic is unchanged
            t = 0.0
            for i in range(max(0, j - u), j):
                t += ab[u + i - j, j] * rhs[i]
            rhs[j] = (rhs[j] - t) / d
            kn = min(u, N - 1 - j)
            r = 1.0 / d
            for c in range(1, kn + 1):              # row j of U right of the diagonal
                ab[u - c, j + c] *= r
            for c in range(1, kn + 1):              # the trailing block -= row^T row
                t = -ab[u - c, j + c]
                for a in range(1, c + 1):
                    ab[u + a - c, j + c] += ab[u - a, j + a] * t
        for j in range(N - 1, -1, -1):              # U x = y
            if rhs[j] != 0.0:
                rhs[j] /= ab[u, j]
                t = rhs[j]
                for i in range(j - 1, max(0, j - u) - 1, -1):
                    rhs[i] -= t * ab[u + i - j, j]
        return 0

    @jit
    def solve_box(ab0, g, lo, hi, iterations, x, at):
        """``smoothing._Banded.solve_box`` whole for u = 2: its active-set loop, each step's
        numpy operations element for element in their order (the matvec's sum per element:
        the diagonal, then per band the term above and the one below) and ``banded_solve``'s
        arithmetic, so the same x bit for bit. ``x`` (N,) receives the result before the final
        clip; ``at`` (N,) the active set to start from (-1 at lo, +1 at hi, 0 free), left as
        the loop ends. Returns 0, or the leading minor ``banded_solve`` reports.

        An iteration changes the active set in a few rows, and the right-hand side, the
        factor, the forward and the back substitution are recurrences along the rows whose
        steps read the few rows before (after) them: a step whose inputs have the same bits as
        in the last iteration gives the same bits, so only the steps downstream of a change
        are taken again, each until its values come out the same again (two fixed rows in a
        row cut the system apart; elsewhere the recurrences settle in some hundred rows), and
        the passes jump over the rows between (the rows changed, and those whose factor
        column or y changed, are listed). The factor is formed column by column (all updates
        of column j from the columns before it, in the order the reference applies them),
        the back substitution row by row (the rows after it in the reference's order, passed
        on only where the value was not 0, as the reference passes on). A free row whose x and
        bound did not change is not checked again: it was inside its bounds at the last
        check. On the keycap about a seventh of the factor's columns and a quarter of the back
        substitution's rows change per iteration. Values are compared with their sign (-0 is
        not +0); NaN always counts as changed."""
        N = ab0.shape[1]
        cxf = np.zeros(N, np.bool_)         # at[i] (so xf[i]) changed since the last iteration
        chg = np.empty(N, np.int64)         # those rows, ascending
        nchg = 0
        new = np.empty(N, np.int64)         # the rows this iteration changes
        evb = np.empty(N, np.int64)         # rows whose U column or y changed this iteration
        xf = np.zeros(N)
        rhs = np.empty(N)
        U = np.zeros((3, N))                # the factor: the reference's ab after banded_solve
        rc = np.empty(N)                    # 1 / U[2, j]
        y = np.empty(N)                     # U^T y = rhs
        xs = np.empty(N)                    # U xs = y
        nz = np.zeros(N, np.bool_)          # xs[j] was not 0 before its division (passed on)
        sU = np.full(N, -1, np.int64)       # the iteration that last changed column j of U, y[j]
        sY = np.full(N, -1, np.int64)
        x[:] = 0.0
        for i in range(N):
            xf[i] = lo[i] if at[i] < 0 else (hi[i] if at[i] > 0 else 0.0)
        for it in range(iterations):
            first = it == 0
            for q in range(nchg):
                i = chg[q]
                a = at[i]
                cxf[i] = True
                xf[i] = lo[i] if a < 0 else (hi[i] if a > 0 else 0.0)
            # rhs, the factor and U^T y = rhs row by row; with nothing carried from rows j - 1,
            # j - 2, on to the first row that reads a changed one (rhs[j]: rows j - 2 .. j + 2)
            ne = 0
            p = 0
            cU1 = cU2 = cy1 = cy2 = False
            j = 0
            while j < N:
                if not first and not (cU1 or cU2 or cy1 or cy2):
                    while p < nchg and chg[p] < j - 2:
                        p += 1
                    if p == nchg:
                        break
                    if chg[p] - 2 > j:
                        j = chg[p] - 2
                w3 = first or cxf[j] or (j >= 1 and cxf[j - 1]) or (j >= 2 and cxf[j - 2])
                w5 = w3 or (j + 1 < N and cxf[j + 1]) or (j + 2 < N and cxf[j + 2])
                f = at[j] != 0
                cr = False
                if w5:                          # rhs = -g - H xf (matvec's order), 0 where fixed
                    if f:
                        v = 0.0
                    else:
                        s = ab0[2, j] * xf[j]
                        if j + 1 < N:
                            s += ab0[1, j + 1] * xf[j + 1]
                        if j >= 1:
                            s += ab0[1, j] * xf[j - 1]
                        if j + 2 < N:
                            s += ab0[0, j + 2] * xf[j + 2]
                        if j >= 2:
                            s += ab0[0, j] * xf[j - 2]
                        v = -g[j] - s
                    cr = first or v != rhs[j] or np.copysign(1.0, v) != np.copysign(1.0, rhs[j])
                    rhs[j] = v
                # column j: the system's (a fixed row or column 0, its diagonal 1), less the
                # updates of columns j - 2 and j - 1 (the scaled row, then its products)
                cUj = False
                if w3 or cU1 or cU2:
                    e0 = 0.0
                    e1 = 0.0
                    e2 = 1.0
                    if not f:
                        e2 = ab0[2, j]
                        if not (j >= 1 and at[j - 1] != 0):
                            e1 = ab0[1, j]
                        if not (j >= 2 and at[j - 2] != 0):
                            e0 = ab0[0, j]
                    if j >= 2:
                        e0 *= rc[j - 2]
                        t = -e0
                        e1 += U[1, j - 1] * t
                        e2 += e0 * t
                    if j >= 1:
                        e1 *= rc[j - 1]
                        t = -e1
                        e2 += e1 * t
                    if not e2 > 0.0:
                        return j + 1
                    d = np.sqrt(e2)
                    cUj = first or d != U[2, j] or e1 != U[1, j] or e0 != U[0, j] \
                        or np.copysign(1.0, e1) != np.copysign(1.0, U[1, j]) \
                        or np.copysign(1.0, e0) != np.copysign(1.0, U[0, j])
                    if cUj:
                        U[0, j] = e0
                        U[1, j] = e1
                        U[2, j] = d
                        rc[j] = 1.0 / d
                        sU[j] = it
                cyj = False
                if cr or cUj or cy1 or cy2:
                    t = 0.0
                    if j >= 2:
                        t += U[0, j] * y[j - 2]
                    if j >= 1:
                        t += U[1, j] * y[j - 1]
                    v = (rhs[j] - t) / U[2, j]
                    cyj = first or v != y[j] or np.copysign(1.0, v) != np.copysign(1.0, y[j])
                    y[j] = v
                    if cyj:
                        sY[j] = it
                if cUj or cyj:
                    evb[ne] = j
                    ne += 1
                cU2, cU1 = cU1, cUj
                cy2, cy1 = cy1, cyj
                j += 1
            # U xs = y from the end (the terms of rows j + 2, then j + 1), x = xs + xf where
            # either changed and such a free row beyond a bound fixed; with nothing carried
            # from rows j + 1, j + 2, on to the next row listed
            change = False
            nnew = 0
            cx1 = cx2 = cUa = cUb = False
            pb = ne - 1
            pc = nchg - 1
            j = N - 1
            while j >= 0:
                cUj = sU[j] == it
                cyj = sY[j] == it
                xfj = cxf[j]
                if not (first or cx1 or cx2 or cUa or cUb or cUj or cyj or xfj):
                    while pb >= 0 and evb[pb] >= j:
                        pb -= 1
                    while pc >= 0 and chg[pc] >= j:
                        pc -= 1
                    e = -1
                    if pb >= 0:
                        e = evb[pb]
                    if pc >= 0 and chg[pc] > e:
                        e = chg[pc]
                    if e < 0:
                        break
                    j = e
                    continue
                cxj = False
                if first or cyj or cUj or cx1 or cx2 or cUa or cUb:
                    v = y[j]
                    if j + 2 < N and nz[j + 2]:
                        v -= xs[j + 2] * U[0, j + 2]
                    if j + 1 < N and nz[j + 1]:
                        v -= xs[j + 1] * U[1, j + 1]
                    nzj = v != 0.0
                    if nzj:
                        v /= U[2, j]
                    cxj = first or nzj != nz[j] or v != xs[j] or np.copysign(1.0, v) != np.copysign(1.0, xs[j])
                    xs[j] = v
                    nz[j] = nzj
                cx2, cx1 = cx1, cxj
                cUb, cUa = cUa, cUj
                if cxj or xfj:
                    xj = xs[j] + xf[j]
                    x[j] = xj
                    if at[j] == 0:
                        a = 0
                        if xj < lo[j] - 1e-12:
                            a = -1
                        if xj > hi[j] + 1e-12:
                            a = 1
                        if a != 0:
                            at[j] = a
                            change = True
                            new[nnew] = j
                            nnew += 1
                j -= 1
            if not change:
                # grad = H x + g at the fixed rows; a bound whose gradient pulls inward is released
                for i in range(N):
                    if at[i] == 0:
                        continue
                    s = ab0[2, i] * x[i]
                    if i + 1 < N:
                        s += ab0[1, i + 1] * x[i + 1]
                    if i >= 1:
                        s += ab0[1, i] * x[i - 1]
                    if i + 2 < N:
                        s += ab0[0, i + 2] * x[i + 2]
                    if i >= 2:
                        s += ab0[0, i] * x[i - 2]
                    gi = s + g[i]
                    if (at[i] < 0 and gi < -1e-12) or (at[i] > 0 and gi > 1e-12):
                        at[i] = 0
                        change = True
                        new[nnew] = i
                        nnew += 1
            if not change:
                break
            for q in range(nchg):
                cxf[chg[q]] = False
            # the rows changed, ascending (the checks found them from the end, the releases from the start)
            if nnew > 1 and new[0] > new[nnew - 1]:
                for q in range(nnew):
                    chg[q] = new[nnew - 1 - q]
            else:
                for q in range(nnew):
                    chg[q] = new[q]
            nchg = nnew
        return 0

    @jit
    def grid_read(x, origin, h, shape, stride, offsets, lbn, idx, lb, near, ins):
        """:meth:`~tsplcam.orientation.broadphase.DistanceGrid._read` point by point, the same
        operations in the same order (so the same bits): per point the cell (clamped into the
        grid), the eight nodes' bounds less their distances, the best of them, the nearest
        node's sample; 0 and -1 outside the grid. Fills ``lb``, ``near``, ``ins``."""
        f = np.empty(3)
        r = np.empty(3)
        k = np.empty(3, np.int64)
        sq = np.empty((3, 2))
        for p in range(x.shape[0]):
            inside = True
            base = 0
            nb = 0
            for i in range(3):
                f[i] = (x[p, i] - origin[i]) / h
                k[i] = np.int64(np.floor(f[i]))
                if k[i] < 0 or k[i] >= shape[i] - 1:
                    inside = False
                k[i] = min(max(k[i], 0), shape[i] - 2)
                r[i] = f[i] - np.float64(k[i])
                base += k[i] * stride[i]
                if r[i] >= 0.5:
                    nb += stride[i]
                sq[i, 0] = r[i] * r[i]
                sq[i, 1] = (1.0 - r[i]) * (1.0 - r[i])
            best = -np.inf
            c = 0
            for a in range(2):
                for b in range(2):
                    for e in range(2):
                        d = h * np.sqrt(sq[0, a] + sq[1, b] + sq[2, e])
                        v = lbn[base + offsets[c]] - d
                        if v > best:
                            best = v
                        c += 1
            ins[p] = inside
            lb[p] = best if inside else 0.0
            near[p] = idx[base + nb] if inside else -1

    @jit
    def sphere_loop(C, A, todo, asked, z0, z1, rout0, rout1, rin0, rin1, max_level, parts,
                    box_lo, box_hi, g_origin, g_h, g_shape, g_stride, g_offsets, g_base, g_lb, g_idx,
                    samples, sample_comp, anchors, eps, cone_want, status, unresolved, phi, hits):
        """The sphere loop of :meth:`~tsplcam.orientation.broadphase.BroadPhase.decide` pose by
        pose instead of level by level over all poses, the same operations in the same order
        per sphere (so the same bits): the sphere of each slab, its bound from the box and the
        fine grid (``g_*[0]``; the coarse grid ``g_*[1]`` where that bound is short of the
        need), cleared / split / unresolved, and at each level the grid nodes' samples of the
        failing spheres tried as hits (``_hits``: inside a part asked, then the piece's
        anchors one direction at a time). The grids' node arrays are concatenated
        (``g_base`` where each begins); their read is :func:`grid_read`'s, written out here
        (a kernel calling another misses numba's cache). Updates ``status``, ``unresolved``,
        ``phi``; ``hits`` (rows level, pose, sample: what ``_hits`` returns per level) is
        filled from row 0; returns the rows used, or -1 when ``hits`` is too short (the
        caller asks again with a longer one). Each (part, level, slab)'s sphere is computed
        once, into a table, and the read's coordinates are kept in scalars (the same
        operations; on the all-candidates batch 47 ms on one thread, 78 ms per sphere with
        small arrays)."""
        K = z0.shape[0]
        width = 0
        for k in range(K):
            w = 1 << max_level[k]
            if w > width:
                width = w
        cap = asked.shape[0] * width
        a_part = np.empty(cap, np.int64)
        a_seg = np.empty(cap, np.int64)
        b_part = np.empty(cap, np.int64)
        b_seg = np.empty(cap, np.int64)
        split = np.empty(cap, np.bool_)
        cand = np.empty(cap, np.int64)
        comp_j = np.empty(cap, np.int64)
        comp_c = np.empty(cap, np.int64)
        nd = anchors.shape[1]
        nh = 0
        # per (part, level, seg) the sphere: row k * tw + 2^level + seg (the parts asked, as
        # the loop below asks them)
        tw = 2 * width
        tab = np.empty((K * tw, 3))
        for q in range(asked.shape[0]):
            k = asked[q]
            for level in range(max_level[k] + 1):
                for seg in range(1 << level):
                    length = (z1[k] - z0[k]) / (1 << level)
                    za = z0[k] + seg * length
                    zb = za + length
                    fa = (za - z0[k]) / (z1[k] - z0[k])
                    ra = rout0[k] + fa * (rout1[k] - rout0[k])
                    fb = (zb - z0[k]) / (z1[k] - z0[k])
                    rb = rout0[k] + fb * (rout1[k] - rout0[k])
                    rmax = ra if ra >= rb else rb
                    ti = k * tw + (1 << level) + seg
                    tab[ti, 0] = 0.5 * (za + zb)
                    tab[ti, 1] = np.sqrt(rmax * rmax + 0.25 * length * length)
                    tab[ti, 2] = rmax
        for t in range(todo.shape[0]):
            p = todo[t]
            n = asked.shape[0]
            for i in range(n):
                a_part[i] = asked[i]
                a_seg[i] = 0
            level = 0
            while n > 0:
                nc = 0
                for i in range(n):
                    k = a_part[i]
                    seg = a_seg[i]
                    ti = k * tw + (1 << level) + seg
                    zc = tab[ti, 0]
                    s = tab[ti, 1]
                    rmax = tab[ti, 2]
                    # lower_bound: the box, the fine grid, the coarse one where short of the need
                    x0 = C[p, 0] + zc * A[p, 0]
                    x1 = C[p, 1] + zc * A[p, 1]
                    x2 = C[p, 2] + zc * A[p, 2]
                    o0 = max(max(box_lo[0] - x0, x0 - box_hi[0]), 0.0)
                    o1 = max(max(box_lo[1] - x1, x1 - box_hi[1]), 0.0)
                    o2 = max(max(box_lo[2] - x2, x2 - box_hi[2]), 0.0)
                    bound = np.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
                    need = s + eps + cone_want * zc
                    jg = -1
                    for g in range(2):
                        if g == 1 and not bound < need:
                            break
                        h = g_h[g]
                        # grid_read's cell, axis by axis (scalars: the same operations)
                        f0 = (x0 - g_origin[g, 0]) / h
                        f1 = (x1 - g_origin[g, 1]) / h
                        f2 = (x2 - g_origin[g, 2]) / h
                        k0 = np.int64(np.floor(f0))
                        k1 = np.int64(np.floor(f1))
                        k2 = np.int64(np.floor(f2))
                        inside = (k0 >= 0 and k0 < g_shape[g, 0] - 1 and k1 >= 0 and k1 < g_shape[g, 1] - 1
                                  and k2 >= 0 and k2 < g_shape[g, 2] - 1)
                        if inside:
                            r0 = f0 - np.float64(k0)
                            r1 = f1 - np.float64(k1)
                            r2 = f2 - np.float64(k2)
                            base = g_base[g] + k0 * g_stride[g, 0] + k1 * g_stride[g, 1] + k2 * g_stride[g, 2]
                            nb = 0
                            if r0 >= 0.5:
                                nb += g_stride[g, 0]
                            if r1 >= 0.5:
                                nb += g_stride[g, 1]
                            if r2 >= 0.5:
                                nb += g_stride[g, 2]
                            a0 = r0 * r0
                            a1 = (1.0 - r0) * (1.0 - r0)
                            b0 = r1 * r1
                            b1 = (1.0 - r1) * (1.0 - r1)
                            c0 = r2 * r2
                            c1 = (1.0 - r2) * (1.0 - r2)
                            best = g_lb[base + g_offsets[g, 0]] - h * np.sqrt(a0 + b0 + c0)
                            v = g_lb[base + g_offsets[g, 1]] - h * np.sqrt(a0 + b0 + c1)
                            if v > best:
                                best = v
                            v = g_lb[base + g_offsets[g, 2]] - h * np.sqrt(a0 + b1 + c0)
                            if v > best:
                                best = v
                            v = g_lb[base + g_offsets[g, 3]] - h * np.sqrt(a0 + b1 + c1)
                            if v > best:
                                best = v
                            v = g_lb[base + g_offsets[g, 4]] - h * np.sqrt(a1 + b0 + c0)
                            if v > best:
                                best = v
                            v = g_lb[base + g_offsets[g, 5]] - h * np.sqrt(a1 + b0 + c1)
                            if v > best:
                                best = v
                            v = g_lb[base + g_offsets[g, 6]] - h * np.sqrt(a1 + b1 + c0)
                            if v > best:
                                best = v
                            v = g_lb[base + g_offsets[g, 7]] - h * np.sqrt(a1 + b1 + c1)
                            if v > best:
                                best = v
                            near = g_idx[base + nb]
                        else:
                            best = 0.0
                            near = -1
                        if best > bound:
                            bound = best
                        if g == 0 or jg < 0:
                            jg = near
                    split[i] = False
                    if bound >= s + eps:
                        v = (bound - s - eps) / zc
                        if v < phi[p]:
                            phi[p] = v
                    else:
                        if jg >= 0:
                            cand[nc] = jg
                            nc += 1
                        if bound < rmax + eps:
                            unresolved[p, k] = True
                        else:
                            split[i] = True
                if nc > 0:
                    # _hits: the candidates inside a part asked, the least sample per piece
                    ncomp = 0
                    for i in range(nc):
                        j = cand[i]
                        w0 = samples[j, 0] - C[p, 0]
                        w1 = samples[j, 1] - C[p, 1]
                        w2 = samples[j, 2] - C[p, 2]
                        z = w0 * A[p, 0] + w1 * A[p, 1] + w2 * A[p, 2]
                        rad2 = max(w0 * w0 + w1 * w1 + w2 * w2 - z * z, 0.0)
                        ins = False
                        for k in range(K):
                            if not (parts >> k) & 1:
                                continue
                            zz = min(max(z, z0[k]), z1[k])
                            fz = (zz - z0[k]) / (z1[k] - z0[k])
                            rr = rin0[k] + fz * (rin1[k] - rin0[k]) - eps
                            if z >= z0[k] + eps and z <= z1[k] - eps and rad2 < rr * rr:
                                ins = True
                        if not ins:
                            continue
                        cc = sample_comp[j]
                        known = False
                        for q in range(ncomp):
                            if comp_c[q] == cc:
                                known = True
                                if j < comp_j[q]:
                                    comp_j[q] = j
                        if not known:
                            comp_c[ncomp] = cc
                            comp_j[ncomp] = j
                            ncomp += 1
                    # _outside: the pieces' anchors, one direction at a time
                    for a in range(nd):
                        hit = False
                        for q in range(ncomp):
                            w0 = anchors[comp_c[q], a, 0] - C[p, 0]
                            w1 = anchors[comp_c[q], a, 1] - C[p, 1]
                            w2 = anchors[comp_c[q], a, 2] - C[p, 2]
                            z = w0 * A[p, 0] + w1 * A[p, 1] + w2 * A[p, 2]
                            rad2 = max(w0 * w0 + w1 * w1 + w2 * w2 - z * z, 0.0)
                            out = True
                            for k in range(K):
                                zz = min(max(z, z0[k]), z1[k])
                                fz = (zz - z0[k]) / (z1[k] - z0[k])
                                rr = rout0[k] + fz * (rout1[k] - rout0[k]) + eps
                                if not (z < z0[k] - eps or z > z1[k] + eps or rad2 > rr * rr):
                                    out = False
                            if out:
                                if nh >= hits.shape[0]:
                                    return -1
                                hits[nh, 0] = level
                                hits[nh, 1] = p
                                hits[nh, 2] = comp_j[q]
                                nh += 1
                                hit = True
                        if hit:
                            status[p] = 1
                            break
                if status[p] == 1:
                    break
                # the next level: split spheres of parts still open, up to the part's finest
                m = 0
                for i in range(n):
                    k = a_part[i]
                    if not split[i] or unresolved[p, k]:
                        continue
                    if level >= max_level[k]:
                        unresolved[p, k] = True
                        continue
                    b_part[m] = k
                    b_seg[m] = 2 * a_seg[i]
                    b_part[m + 1] = k
                    b_seg[m + 1] = 2 * a_seg[i] + 1
                    m += 2
                for i in range(m):
                    a_part[i] = b_part[i]
                    a_seg[i] = b_seg[i]
                n = m
                level += 1
        return nh

    @jit
    def hit_pairs(samples, j, pose, order, C, A, z0, z1, rin0, rin1, rout0, rout1, parts, sample_comp,
                  anchors, eps, status, found):
        """:meth:`~tsplcam.orientation.broadphase.BroadPhase._hits` pose by pose (``order``:
        the pairs sorted by pose, stably), the same operations per point (so the same
        answers): the samples ``j`` inside a part asked at their pose, the least one per piece
        of the mesh, the pieces' anchors tried one direction at a time; a pose with an anchor
        outside the tool is hit. ``found`` (rows pose, sample, at least as many as pairs)
        receives the witnesses; returns their number. Poses already hit are left out."""
        K = z0.shape[0]
        nd = anchors.shape[1]
        n = order.shape[0]
        comp_c = np.empty(n, np.int64)
        comp_j = np.empty(n, np.int64)
        nf = 0
        i = 0
        while i < n:
            p = pose[order[i]]
            e = i
            while e < n and pose[order[e]] == p:
                e += 1
            if status[p] == 1:
                i = e
                continue
            ncomp = 0
            for t in range(i, e):
                jj = j[order[t]]
                w0 = samples[jj, 0] - C[p, 0]
                w1 = samples[jj, 1] - C[p, 1]
                w2 = samples[jj, 2] - C[p, 2]
                z = w0 * A[p, 0] + w1 * A[p, 1] + w2 * A[p, 2]
                rad2 = max(w0 * w0 + w1 * w1 + w2 * w2 - z * z, 0.0)
                ins = False
                for k in range(K):
                    if not (parts >> k) & 1:
                        continue
                    zz = min(max(z, z0[k]), z1[k])
                    fz = (zz - z0[k]) / (z1[k] - z0[k])
                    rr = rin0[k] + fz * (rin1[k] - rin0[k]) - eps
                    if z >= z0[k] + eps and z <= z1[k] - eps and rad2 < rr * rr:
                        ins = True
                if not ins:
                    continue
                cc = sample_comp[jj]
                known = False
                for q in range(ncomp):
                    if comp_c[q] == cc:
                        known = True
                        if jj < comp_j[q]:
                            comp_j[q] = jj
                if not known:
                    comp_c[ncomp] = cc
                    comp_j[ncomp] = jj
                    ncomp += 1
            for a in range(nd if ncomp > 0 else 0):
                hit = False
                for q in range(ncomp):
                    w0 = anchors[comp_c[q], a, 0] - C[p, 0]
                    w1 = anchors[comp_c[q], a, 1] - C[p, 1]
                    w2 = anchors[comp_c[q], a, 2] - C[p, 2]
                    z = w0 * A[p, 0] + w1 * A[p, 1] + w2 * A[p, 2]
                    rad2 = max(w0 * w0 + w1 * w1 + w2 * w2 - z * z, 0.0)
                    out = True
                    for k in range(K):
                        zz = min(max(z, z0[k]), z1[k])
                        fz = (zz - z0[k]) / (z1[k] - z0[k])
                        rr = rout0[k] + fz * (rout1[k] - rout0[k]) + eps
                        if not (z < z0[k] - eps or z > z1[k] + eps or rad2 > rr * rr):
                            out = False
                    if out:
                        found[nf, 0] = p
                        found[nf, 1] = comp_j[q]
                        nf += 1
                        hit = True
                if hit:
                    status[p] = 1
                    break
            i = e
        return nf

    @jit
    def side_bounds(C, A, pose, part, seg, level, nseg, z0, z1, rout0, rout1, box_lo, box_hi,
                    g_origin, g_h, g_shape, g_stride, g_offsets, g_base, g_lb, g_idx, eps, phi,
                    f_ball, f_t, f_R, f_x, f_bound):
        """The side pass's balls bounded by the grids
        (:meth:`~tsplcam.orientation.broadphase.BroadPhase._side_level`), ball by ball, the same
        operations in the same order (so the same bits): row i stands for the ``nseg`` slabs
        ``seg[i] * nseg + s`` of ``part[i]`` at ``level`` at pose ``pose[i]``; each slab's ball
        (``side_balls``), its bound from the box, the fine grid and the coarse one where short
        of R + eps (``lower_bound``, :func:`grid_read`'s read written out). A ball cleared
        narrows ``phi`` of its pose; the others are listed in order (``f_ball`` row * nseg + s,
        the ball's height ``f_t``, radius ``f_R``, centre ``f_x`` and bound ``f_bound``).
        Returns how many are listed."""
        nf = 0
        for i in range(pose.shape[0]):
            p = pose[i]
            k = part[i]
            for sg in range(nseg):
                # side_balls
                length = (z1[k] - z0[k]) / (1 << level)
                za = z0[k] + (seg[i] * nseg + sg) * length
                zb = za + length
                fa = (za - z0[k]) / (z1[k] - z0[k])
                ra = rout0[k] + fa * (rout1[k] - rout0[k])
                fb = (zb - z0[k]) / (z1[k] - z0[k])
                rb = rout0[k] + fb * (rout1[k] - rout0[k])
                slope = (rout1[k] - rout0[k]) / (z1[k] - z0[k])
                t = 0.5 * (za + zb) + slope * 0.5 * (ra + rb)
                da = t - za
                db = t - zb
                Ra = np.sqrt(ra * ra + da * da)
                Rb = np.sqrt(rb * rb + db * db)
                R = Ra if Ra >= Rb else Rb
                # lower_bound: the box, the fine grid, the coarse one where short of R + eps
                x0 = C[p, 0] + t * A[p, 0]
                x1 = C[p, 1] + t * A[p, 1]
                x2 = C[p, 2] + t * A[p, 2]
                o0 = max(max(box_lo[0] - x0, x0 - box_hi[0]), 0.0)
                o1 = max(max(box_lo[1] - x1, x1 - box_hi[1]), 0.0)
                o2 = max(max(box_lo[2] - x2, x2 - box_hi[2]), 0.0)
                bound = np.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
                need = R + eps
                for g in range(2):
                    if g == 1 and not bound < need:
                        break
                    h = g_h[g]
                    f0 = (x0 - g_origin[g, 0]) / h
                    f1 = (x1 - g_origin[g, 1]) / h
                    f2 = (x2 - g_origin[g, 2]) / h
                    k0 = np.int64(np.floor(f0))
                    k1 = np.int64(np.floor(f1))
                    k2 = np.int64(np.floor(f2))
                    if not (k0 >= 0 and k0 < g_shape[g, 0] - 1 and k1 >= 0 and k1 < g_shape[g, 1] - 1
                            and k2 >= 0 and k2 < g_shape[g, 2] - 1):
                        continue                    # outside the grid: its bound 0 adds nothing
                    r0 = f0 - np.float64(k0)
                    r1 = f1 - np.float64(k1)
                    r2 = f2 - np.float64(k2)
                    base = g_base[g] + k0 * g_stride[g, 0] + k1 * g_stride[g, 1] + k2 * g_stride[g, 2]
                    a0 = r0 * r0
                    a1 = (1.0 - r0) * (1.0 - r0)
                    b0 = r1 * r1
                    b1 = (1.0 - r1) * (1.0 - r1)
                    c0 = r2 * r2
                    c1 = (1.0 - r2) * (1.0 - r2)
                    best = g_lb[base + g_offsets[g, 0]] - h * np.sqrt(a0 + b0 + c0)
                    v = g_lb[base + g_offsets[g, 1]] - h * np.sqrt(a0 + b0 + c1)
                    if v > best:
                        best = v
                    v = g_lb[base + g_offsets[g, 2]] - h * np.sqrt(a0 + b1 + c0)
                    if v > best:
                        best = v
                    v = g_lb[base + g_offsets[g, 3]] - h * np.sqrt(a0 + b1 + c1)
                    if v > best:
                        best = v
                    v = g_lb[base + g_offsets[g, 4]] - h * np.sqrt(a1 + b0 + c0)
                    if v > best:
                        best = v
                    v = g_lb[base + g_offsets[g, 5]] - h * np.sqrt(a1 + b0 + c1)
                    if v > best:
                        best = v
                    v = g_lb[base + g_offsets[g, 6]] - h * np.sqrt(a1 + b1 + c0)
                    if v > best:
                        best = v
                    v = g_lb[base + g_offsets[g, 7]] - h * np.sqrt(a1 + b1 + c1)
                    if v > best:
                        best = v
                    if best > bound:
                        bound = best
                if bound >= R + eps:
                    at = abs(t)
                    v = (bound - R - eps) / (at if at >= 1e-12 else 1e-12)
                    if v < phi[p]:
                        phi[p] = v
                else:
                    f_ball[nf] = i * nseg + sg
                    f_t[nf] = t
                    f_R[nf] = R
                    f_x[nf, 0] = x0
                    f_x[nf, 1] = x1
                    f_x[nf, 2] = x2
                    f_bound[nf] = bound
                    nf += 1
        return nf

    @numba.njit(inline="always")
    def ieee_quotient(a, b):
        """a / b with IEEE's quotients by zero (numpy's; numba's Python error model raises)."""
        if b == 0.0:
            if a != a or a == 0.0:
                return np.nan
            return np.inf if (a > 0.0) == (np.copysign(1.0, b) > 0.0) else -np.inf
        return a / b

    @numba.njit(inline="always")
    def to_finite(t):
        """``np.nan_to_num`` of one value: nan 0, infinities the largest finite values."""
        if t != t:
            return 0.0
        if t == np.inf:
            return 1.7976931348623157e308
        if t == -np.inf:
            return -1.7976931348623157e308
        return t

    @jit
    def measure_pairs(x, R, V, T, nrm, row, tri, slack, out):
        """:meth:`~tsplcam.orientation.broadphase.BroadPhase._measure_into` pair by pair: where
        triangle ``tri[k]``'s plane lies within ``R[row[k]] + slack`` of point ``x[row[k]]``,
        its distance to the triangle's closest point (``broadphase.closest_on_triangles``:
        the same operations in the same order, its regions in its order of precedence) lowers
        ``out[row[k]]`` (a NaN wins, as in ``np.minimum``). Pairs may repeat (a minimum does
        not change)."""
        for k in range(row.shape[0]):
            q = row[k]
            t = tri[k]
            ia = T[t, 0]
            ib = T[t, 1]
            ic = T[t, 2]
            px = x[q, 0]
            py = x[q, 1]
            pz = x[q, 2]
            ax = V[ia, 0]
            ay = V[ia, 1]
            az = V[ia, 2]
            apx = px - ax
            apy = py - ay
            apz = pz - az
            gap = apx * nrm[t, 0] + apy * nrm[t, 1] + apz * nrm[t, 2]
            if not abs(gap) < R[q] + slack:
                continue
            bx = V[ib, 0]
            by = V[ib, 1]
            bz = V[ib, 2]
            cx = V[ic, 0]
            cy = V[ic, 1]
            cz = V[ic, 2]
            abx = bx - ax
            aby = by - ay
            abz = bz - az
            acx = cx - ax
            acy = cy - ay
            acz = cz - az
            d1 = abx * apx + aby * apy + abz * apz
            d2 = acx * apx + acy * apy + acz * apz
            bpx = px - bx
            bpy = py - by
            bpz = pz - bz
            d3 = abx * bpx + aby * bpy + abz * bpz
            d4 = acx * bpx + acy * bpy + acz * bpz
            cpx = px - cx
            cpy = py - cy
            cpz = pz - cz
            d5 = abx * cpx + aby * cpy + abz * cpz
            d6 = acx * cpx + acy * cpy + acz * cpz
            va = d3 * d6 - d5 * d4
            vb = d5 * d2 - d1 * d6
            vc = d1 * d4 - d3 * d2
            if d1 <= 0 and d2 <= 0:
                qx, qy, qz = ax, ay, az
            elif d3 >= 0 and d4 <= d3:
                qx, qy, qz = bx, by, bz
            elif d6 >= 0 and d5 <= d6:
                qx, qy, qz = cx, cy, cz
            elif vc <= 0 and d1 >= 0 and d3 <= 0:
                u = to_finite(ieee_quotient(d1, d1 - d3))
                qx, qy, qz = ax + u * abx, ay + u * aby, az + u * abz
            elif vb <= 0 and d2 >= 0 and d6 <= 0:
                u = to_finite(ieee_quotient(d2, d2 - d6))
                qx, qy, qz = ax + u * acx, ay + u * acy, az + u * acz
            elif va <= 0 and d4 - d3 >= 0 and d5 - d6 >= 0:
                u = to_finite(ieee_quotient(d4 - d3, (d4 - d3) + (d5 - d6)))
                qx, qy, qz = bx + u * (cx - bx), by + u * (cy - by), bz + u * (cz - bz)
            else:
                den = va + vb + vc
                v = 0.0
                w = 0.0
                if den != 0:
                    v = vb / den
                    w = vc / den
                qx = ax + v * abx + w * acx
                qy = ay + v * aby + w * acy
                qz = az + v * abz + w * acz
            dx = qx - px
            dy = qy - py
            dz = qz - pz
            d = np.sqrt(dx * dx + dy * dy + dz * dz)
            if d < out[q] or d != d:
                out[q] = d

    @jit
    def band_samples(x, ub, pts, items, start, origin, h, shape, k, d0, j0, cnt, lst, tie):
        """The mesh samples in each point's band (:meth:`~tsplcam.orientation.broadphase.BroadPhase.exact_bound`),
        from a table of cells (edge ``h``, ``shape`` cells from ``origin``; cell c's samples
        ``items[start[c]:start[c + 1]]`` at ``pts`` in the same rows), as the sample tree's
        k-nearest query within ``ub`` gives them: each squared distance summed x, y, z in
        that order (scipy's kd-tree sums from 0 in the coordinates' order: the same bits),
        a sample counted where it is below ub^2 as there, and in the band where its square
        root is below ub. Per point: ``d0`` the nearest distance (inf: none below ub), ``j0``
        its sample (-1: none), ``tie`` where another sample lies at that distance (the tree's
        walk picks among those: the caller asks the tree), ``cnt`` the samples in the band up
        to k, ``lst`` the first k of them (-1 after)."""
        for i in range(x.shape[0]):
            u = ub[i]
            u2 = u * u
            w = u * (1.0 + 1e-9) + 1e-12        # (the cells' range widened past rounding)
            lo0 = 0
            hi0 = 0
            lo1 = 0
            hi1 = 0
            lo2 = 0
            hi2 = 0
            for a in range(3):
                f = (x[i, a] - w - origin[a]) / h
                g = (x[i, a] + w - origin[a]) / h
                top = shape[a] - 1
                # (clamped to the table: a band beyond it scans its border cells for nothing)
                lo = 0 if not f >= 0.0 else (top if f >= top else np.int64(f))
                hi = 0 if not g >= 0.0 else (top if g >= top else np.int64(g))
                if a == 0:
                    lo0, hi0 = lo, hi
                elif a == 1:
                    lo1, hi1 = lo, hi
                else:
                    lo2, hi2 = lo, hi
            best = np.inf
            jb = -1
            t = False
            c = 0
            for a in range(lo0, hi0 + 1):
                for b in range(lo1, hi1 + 1):
                    base = (a * shape[1] + b) * shape[2]
                    for p in range(start[base + lo2], start[base + hi2 + 1]):
                        q0 = x[i, 0] - pts[p, 0]
                        q1 = x[i, 1] - pts[p, 1]
                        q2 = x[i, 2] - pts[p, 2]
                        dd = q0 * q0
                        dd += q1 * q1
                        dd += q2 * q2
                        if dd < u2:
                            if dd < best:
                                best = dd
                                jb = items[p]
                                t = False
                            elif dd == best:
                                t = True
                            if np.sqrt(dd) < u:
                                if c < k:
                                    lst[i, c] = items[p]
                                c += 1
            d0[i] = np.sqrt(best)
            j0[i] = jb
            tie[i] = t
            cnt[i] = c if c < k else k
            for m in range(cnt[i], k):
                lst[i, m] = -1

    @jit
    def store_cones(slot, rows, A, c, rounds, cone_a, cone_c):
        """:meth:`~tsplcam.orientation.broadphase.BroadPhase._store_cones` row by row (row i's
        axis ``A[rows[i]]``): its
        ``rounds`` rounds each put, per slot, the first row (in row order) whose cone is wider
        than the slot's narrowest (the first largest cos) in the narrowest's place; a row
        before a slot's pick is not wider than the narrowest then, nor than any later
        narrowest (the narrowest only widens), so taking the rows in order, each slot at most
        ``rounds`` times, puts the same cones in the same places."""
        taken = np.zeros(cone_c.shape[0], np.int64)
        K = cone_c.shape[1]
        for i in range(slot.shape[0]):
            s = slot[i]
            if taken[s] >= rounds:
                continue
            worst = 0
            most = cone_c[s, 0]
            for k in range(1, K):
                if cone_c[s, k] > most:
                    worst = k
                    most = cone_c[s, k]
            if c[i] < most:
                cone_a[s, worst, 0] = A[rows[i], 0]
                cone_a[s, worst, 1] = A[rows[i], 1]
                cone_a[s, worst, 2] = A[rows[i], 2]
                cone_c[s, worst] = c[i]
                taken[s] += 1

    @jit
    def centre_slots(keys, tab, rows, size, slot, first):
        """:class:`~tsplcam.orientation.broadphase.CentreTable`'s slots by open addressing:
        row i's three 64-bit words ``keys[i]`` (a centre's bytes) looked up in ``tab`` (-1
        empty, else a slot; its length a power of two, at least twice the slots) by a hash of
        them, each slot found checked against its centre's words ``rows[slot]``; a centre not
        there gets the next slot (``size``, then counted on), its words put in ``rows`` and its
        row in ``first``. Returns the new size."""
        mask = np.uint64(tab.shape[0] - 1)
        size0 = size
        for i in range(keys.shape[0]):
            a, b, c = keys[i, 0], keys[i, 1], keys[i, 2]
            if i > 0 and a == keys[i - 1, 0] and b == keys[i - 1, 1] and c == keys[i - 1, 2]:
                slot[i] = slot[i - 1]
                continue
            # (each word folded in by a multiply-xorshift mix: a float's low bits are often all
            # zero, its high ones carry it)
            h = np.uint64(0)
            for w in (a, b, c):
                h ^= np.uint64(w)
                h ^= h >> np.uint64(33)
                h *= np.uint64(0xFF51AFD7ED558CCD)
                h ^= h >> np.uint64(29)
                h *= np.uint64(0xC4CEB9FE1A85EC53)
                h ^= h >> np.uint64(32)
            p = np.int64(h & mask)
            while True:
                s = tab[p]
                if s < 0:
                    tab[p] = size
                    rows[size, 0] = a
                    rows[size, 1] = b
                    rows[size, 2] = c
                    first[size - size0] = i
                    slot[i] = size
                    size += 1
                    break
                if rows[s, 0] == a and rows[s, 1] == b and rows[s, 2] == c:
                    slot[i] = s
                    break
                p = np.int64((np.uint64(p) + np.uint64(1)) & mask)
        return size

    @numba.njit(inline="always")
    def bernstein_row(t):
        """``basis._bernstein3`` at t, its operations in its order: the cubic Bernstein values
        and their first and second derivatives, (B0..B3, B'0..B'3, B''0..B''3)."""
        s = 1.0 - t
        t2 = t * t
        s2 = s * s
        ts = t * s
        d13 = 3.0 * t2
        tmp = 3.0 * s2
        ts = 6.0 * ts
        tmp2 = 18.0 * t
        return (s2 * s, (3.0 * t) * s2, d13 * s, t2 * t,
                -tmp, tmp - ts, ts - d13, d13,
                6.0 * s, tmp2 - 12.0, 6.0 - tmp2, 6.0 * t)

    @numba.njit(inline="always")
    def comb4(w0, w1, w2, w3, x0, x1, x2, x3):
        """w0 x0 + w1 x1 + w2 x2 + w3 x3, summed in that order (the kernel's contractions)."""
        acc = w0 * x0
        acc += w1 * x1
        acc += w2 * x2
        acc += w3 * x3
        return acc

    @numba.njit(inline="always")
    def bicubic_point(q, off, a, b, sc, wu, wv, H, p, nd):
        """:func:`cubic_points`' operations for one point of a polynomial net (three
        coordinates, no extraordinary vertex, cells of non-zero width), written out: the
        Bernstein bases of a and b, the rows' products along a, the derivatives along b, the
        offset, the scales and the widths' divisions, each sum in the generic loop's order (the
        same bits, without its scratch arrays and its branches per derivative)."""
        a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11 = bernstein_row(a)
        b0, b1, b2, b3, b4, b5, b6, b7, b8, b9, b10, b11 = bernstein_row(b)
        ss = sc * sc
        for c in range(3):
            # the net's rows j along a: order 0 (x0j), 1 (x1j), 2; then along b
            x00 = comb4(q[c, 0, 0], q[c, 0, 1], q[c, 0, 2], q[c, 0, 3], a0, a1, a2, a3)
            x01 = comb4(q[c, 1, 0], q[c, 1, 1], q[c, 1, 2], q[c, 1, 3], a0, a1, a2, a3)
            x02 = comb4(q[c, 2, 0], q[c, 2, 1], q[c, 2, 2], q[c, 2, 3], a0, a1, a2, a3)
            x03 = comb4(q[c, 3, 0], q[c, 3, 1], q[c, 3, 2], q[c, 3, 3], a0, a1, a2, a3)
            x10 = comb4(q[c, 0, 0], q[c, 0, 1], q[c, 0, 2], q[c, 0, 3], a4, a5, a6, a7)
            x11 = comb4(q[c, 1, 0], q[c, 1, 1], q[c, 1, 2], q[c, 1, 3], a4, a5, a6, a7)
            x12 = comb4(q[c, 2, 0], q[c, 2, 1], q[c, 2, 2], q[c, 2, 3], a4, a5, a6, a7)
            x13 = comb4(q[c, 3, 0], q[c, 3, 1], q[c, 3, 2], q[c, 3, 3], a4, a5, a6, a7)
            H[0, c, p] = comb4(b0, b1, b2, b3, x00, x01, x02, x03) + off[c]
            H[1, c, p] = comb4(b0, b1, b2, b3, x10, x11, x12, x13) * sc / wu
            H[2, c, p] = comb4(b4, b5, b6, b7, x00, x01, x02, x03) * sc / wv
            if nd == 6:
                x20 = comb4(q[c, 0, 0], q[c, 0, 1], q[c, 0, 2], q[c, 0, 3], a8, a9, a10, a11)
                x21 = comb4(q[c, 1, 0], q[c, 1, 1], q[c, 1, 2], q[c, 1, 3], a8, a9, a10, a11)
                x22 = comb4(q[c, 2, 0], q[c, 2, 1], q[c, 2, 2], q[c, 2, 3], a8, a9, a10, a11)
                x23 = comb4(q[c, 3, 0], q[c, 3, 1], q[c, 3, 2], q[c, 3, 3], a8, a9, a10, a11)
                H[3, c, p] = comb4(b0, b1, b2, b3, x20, x21, x22, x23) * ss / (wu * wu)
                H[4, c, p] = comb4(b4, b5, b6, b7, x10, x11, x12, x13) * ss / (wu * wv)
                H[5, c, p] = comb4(b8, b9, b10, b11, x00, x01, x02, x03) * ss / (wv * wv)

    @jit
    def cubic_points(u, v, ub, vb, kind, ref, nets, origin, limit, corner, swap, vertex, nb, net_levels,
                     max_level, H, flag):
        """Bicubic patches point by point (:mod:`tsplcam.model.cubic_points`, whose numpy
        route makes the same operations in the same order): H (nd, 3, n) the position and
        derivatives in (u, v) (with 4 coordinates in ``nets``, homogeneous ones divided out),
        flag 0, 1 (at an extraordinary vertex: its values) or 2 (below the nets' levels: left
        to the caller); returns the number of those. A division by zero (a weight 0, a cell
        of width 0) gives what numpy's does, x * copysign(inf, 0) (numba's would raise)."""
        n = u.shape[0]
        nd = H.shape[0]
        nc = nets.shape[1]
        deep = 0
        inf = math.inf
        B = np.empty((2, 3, 4))
        T = np.empty((3, 4))
        h = np.empty(6)
        cell = np.empty(2, np.int64)
        for p in range(n):
            x, y = u[p], v[p]
            for w in range(2):                    # the cell: searchsorted(side="right") - 1, clipped
                br = ub if w == 0 else vb
                z = x if w == 0 else y
                lo, hi = 0, br.shape[0]
                while lo < hi:
                    mid = (lo + hi) // 2
                    if z < br[mid]:
                        hi = mid
                    else:
                        lo = mid + 1
                cell[w] = min(max(lo - 1, 0), br.shape[0] - 2)
            iu, iv = cell[0], cell[1]
            wu = ub[iu + 1] - ub[iu]
            wv = vb[iv + 1] - vb[iv]
            a = (x - ub[iu]) / wu if wu != 0.0 else (x - ub[iu]) * math.copysign(inf, wu)
            b = (y - vb[iv]) / wv if wv != 0.0 else (y - vb[iv]) * math.copysign(inf, wv)
            r = ref[iu, iv]
            f = 0
            sc = 1.0
            if kind[iu, iv] == 0:
                key = r
                off = origin[r]
            else:                                 # as LevelCells._net_params
                c0, c1 = corner[0, r], corner[1, r]
                e0 = abs(min(max(a, 0.0), 1.0) - c0)
                e1 = abs(min(max(b, 0.0), 1.0) - c1)
                mx = max(e0, e1)
                level = min(max(1 - math.frexp(mx)[1], 1), max_level)
                if level > net_levels:
                    f = 2
                if mx <= 0.0:
                    f = 1
                sc = math.ldexp(1.0, level)
                e0 *= sc
                e1 *= sc
                p0 = e0 >= 1.0
                p1 = e1 >= 1.0
                if not (p0 or p1):
                    if swap[r]:
                        p1 = True
                    else:
                        p0 = True
                if p0:
                    e0 -= 1.0
                if p1:
                    e1 -= 1.0
                a = abs(min(max(e0, 0.0), 1.0) - c0)
                b = abs(min(max(e1, 0.0), 1.0) - c1)
                key = nb + (r * net_levels + min(level, net_levels) - 1) * 3 + p0 + 2 * p1 - 1
                off = limit[r]
            flag[p] = f
            if f == 2:
                deep += 1
            if nc == 3 and f != 1 and wu * wu != 0.0 and wv * wv != 0.0 and wu * wv != 0.0:
                bicubic_point(nets[key], off, a, b, sc, wu, wv, H, p, nd)
                continue
            for w in range(2):                    # basis._bernstein3 along a, then b: its operations
                t = a if w == 0 else b
                s = 1.0 - t
                t2 = t * t
                s2 = s * s
                ts = t * s
                B[w, 0, 0] = s2 * s
                B[w, 0, 1] = (3.0 * t) * s2
                B[w, 1, 3] = 3.0 * t2
                B[w, 0, 2] = B[w, 1, 3] * s
                B[w, 0, 3] = t2 * t
                tmp = 3.0 * s2
                B[w, 1, 0] = -tmp
                ts = 6.0 * ts
                B[w, 1, 1] = tmp - ts
                B[w, 1, 2] = ts - B[w, 1, 3]
                B[w, 2, 0] = 6.0 * s
                tmp = 18.0 * t
                B[w, 2, 1] = tmp - 12.0
                B[w, 2, 2] = 6.0 - tmp
                B[w, 2, 3] = 6.0 * t
            ss = sc * sc
            W0 = W1 = W2 = W3 = W4 = W5 = 0.0
            for cc in range(nc):                  # each coordinate (the weight row first)
                c = (cc + 3) % 4 if nc == 4 else cc
                q = nets[key, c]
                for d in range(3 if nd == 6 else 2):      # along a: row j of the net, order d
                    for j in range(4):
                        acc = q[j, 0] * B[0, d, 0]
                        acc += q[j, 1] * B[0, d, 1]
                        acc += q[j, 2] * B[0, d, 2]
                        acc += q[j, 3] * B[0, d, 3]
                        T[d, j] = acc
                for m in range(nd):               # along b (cells.DERIVS), the offset, the scales
                    ds = 1 if m == 1 or m == 4 else (2 if m == 3 else 0)
                    dt = 1 if m == 2 or m == 4 else (2 if m == 5 else 0)
                    acc = B[1, dt, 0] * T[ds, 0]
                    acc += B[1, dt, 1] * T[ds, 1]
                    acc += B[1, dt, 2] * T[ds, 2]
                    acc += B[1, dt, 3] * T[ds, 3]
                    if m == 0:
                        acc += off[c]
                    else:
                        acc *= sc if m < 3 else ss
                    if f == 1:
                        acc = vertex[r, m, c]
                    if m > 0:
                        dv = wu if m == 1 else (wv if m == 2 else (wu * wu if m == 3 else (wu * wv if m == 4 else wv * wv)))
                        acc = acc / dv if dv != 0.0 else acc * math.copysign(inf, dv)
                    h[m] = acc
                if c == 3:
                    W0, W1, W2, W3, W4, W5 = h[0], h[1], h[2], h[3], h[4], h[5]
                    continue
                if nc == 3:
                    for m in range(nd):
                        H[m, c, p] = h[m]
                    continue
                # diffgeom.rational_from_homogeneous (numpy's x / 0 where the weight is 0)
                iw = math.copysign(inf, W0)
                S = h[0] / W0 if W0 != 0.0 else h[0] * iw
                Su = (h[1] - W1 * S) / W0 if W0 != 0.0 else (h[1] - W1 * S) * iw
                Sv = (h[2] - W2 * S) / W0 if W0 != 0.0 else (h[2] - W2 * S) * iw
                H[0, c, p] = S
                H[1, c, p] = Su
                H[2, c, p] = Sv
                if nd == 6:
                    x3 = h[3] - 2.0 * W1 * Su - W3 * S
                    x4 = h[4] - W4 * S - W1 * Sv - W2 * Su
                    x5 = h[5] - 2.0 * W2 * Sv - W5 * S
                    H[3, c, p] = x3 / W0 if W0 != 0.0 else x3 * iw
                    H[4, c, p] = x4 / W0 if W0 != 0.0 else x4 * iw
                    H[5, c, p] = x5 / W0 if W0 != 0.0 else x5 * iw
        return deep

    @jit
    def unit_normals(a, b, out):
        """:func:`tsplcam.toolpath.lines._unit_normal` of the rows a[:, i], b[:, i] (the
        derivatives of a surface point, coordinate-major (3, n) as ``cubic_points`` writes
        them) into out (n, 3): the cross product's products and differences in
        ``npfast.cross_rows``' order, the squares summed x, y, z, the length 1 where it is not
        positive (nan too), as numpy's operations there (the same bits)."""
        n = a.shape[1]
        for i in range(n):
            a0, a1, a2 = a[0, i], a[1, i], a[2, i]
            b0, b1, b2 = b[0, i], b[1, i], b[2, i]
            c0 = a1 * b2 - a2 * b1
            c1 = a2 * b0 - a0 * b2
            c2 = a0 * b1 - a1 * b0
            q = c0 * c0 + c1 * c1
            q += c2 * c2
            ln = math.sqrt(q)
            d = ln if ln > 0.0 else 1.0
            out[i, 0] = c0 / d
            out[i, 1] = c1 / d
            out[i, 2] = c2 / d

    @jit
    def cusp_ends(P, N, off, k, ca, cb, eh, L, r, ends, lo, width):
        """The line ends' pass of :func:`tsplcam.toolpath.lines._cusp_heights` (its
        ``end_pass``, whose numpy operations these are, in their order: the same bits) for each
        gap g and line end e: the entries along the normals N[g, off + e k + j] from the edge
        points P[...] (j < k) into the capsules of lines 1 and 2 (ca, cb (G, line, end, 3): the
        segments' two ends; eh, L their unit directions and lengths), the crossing of the two
        entries bracketed and interpolated; ends, lo, width (G, 2) updated in place (width
        becomes the next pass's step). np.minimum / np.maximum written out (a nan in either
        argument is the result, the first one's if both; on ties the second argument), a
        division by zero as numpy's (numba's would raise)."""
        G = P.shape[0]
        inf = math.inf
        nan = math.nan
        rr = r * r
        h = np.empty((2, k))
        d = np.empty(k)
        low = np.empty(k)
        for g in range(G):
            for e in range(2):
                for j in range(k):
                    q = off + e * k + j
                    p0, p1, p2 = P[g, q, 0], P[g, q, 1], P[g, q, 2]
                    n0, n1, n2 = N[g, q, 0], N[g, q, 1], N[g, q, 2]
                    for ln in range(2):
                        # lines._capsule_entry
                        a0, a1, a2 = ca[g, ln, e, 0], ca[g, ln, e, 1], ca[g, ln, e, 2]
                        e0, e1, e2 = eh[g, ln, e, 0], eh[g, ln, e, 1], eh[g, ln, e, 2]
                        w0 = p0 - a0
                        w1 = p1 - a1
                        w2 = p2 - a2
                        dn = n0 * e0 + n1 * e1
                        dn += n2 * e2
                        dn += 0.0
                        wn = w0 * e0 + w1 * e1
                        wn += w2 * e2
                        wn += 0.0
                        dp0 = n0 - dn * e0
                        dp1 = n1 - dn * e1
                        dp2 = n2 - dn * e2
                        wp0 = w0 - wn * e0
                        wp1 = w1 - wn * e1
                        wp2 = w2 - wn * e2
                        A = dp0 * dp0 + dp1 * dp1
                        A += dp2 * dp2
                        A += 0.0
                        B = wp0 * dp0 + wp1 * dp1
                        B += wp2 * dp2
                        B += 0.0
                        C = wp0 * wp0 + wp1 * wp1
                        C += wp2 * wp2
                        C += 0.0
                        C = C - rr
                        disc = B * B - A * C
                        sq = math.sqrt(disc) if disc >= 0 else nan
                        num = -B - sq
                        lam = num / A if A != 0.0 else num * math.copysign(inf, A)
                        ax = wn + lam * dn
                        out = lam if (A > 1e-14 and ax >= 0 and ax <= L[g, ln, e]) else inf
                        for c in range(2):
                            cs = ca if c == 0 else cb
                            c0 = p0 - cs[g, ln, e, 0]
                            c1 = p1 - cs[g, ln, e, 1]
                            c2 = p2 - cs[g, ln, e, 2]
                            bb = n0 * c0 + n1 * c1
                            bb += n2 * c2
                            bb += 0.0
                            cc = c0 * c0 + c1 * c1
                            cc += c2 * c2
                            cc += 0.0
                            cc = cc - rr
                            dd = bb * bb - cc
                            cap = -bb - math.sqrt(dd) if dd >= 0 else inf
                            # np.minimum(out, cap)
                            out = out if (out < cap or out != out) else cap
                        h[ln, j] = out
                    hd = h[0, j] - h[1, j]
                    d[j] = hd
                    x1, x2 = h[0, j], h[1, j]
                    low[j] = x1 if (x1 < x2 or x1 != x1) else x2
                # the crossing: the first sample where line 1's entry reaches line 2's
                kk = k - 1
                for j in range(k):
                    if d[j] >= 0:
                        kk = j
                        break
                kk = min(max(kk, 1), k - 1)
                d0, d1 = d[kk - 1], d[kk]
                den = d0 - d1
                x = d0 / den if den != 0.0 else d0 * math.copysign(inf, den)
                x = x if (x > 0.0 or x != x) else 0.0
                x = x if (x < 1.0 or x != x) else 1.0
                hk0, hk1 = h[0, kk - 1], h[0, kk]
                cross = hk0 + x * (hk1 - hk0)
                # np.maximum.reduce: a nan gives numpy's default nan (its vector reduction
                # returns that where a lane holds a nan; with k - 1 = 16, a multiple of
                # every vector width, every sample passes through one). Ties in the order
                # here (the later sample): where the peak is 0, reached by both +0 and -0,
                # numpy's lanes may give the other zero (an order of its own per processor)
                peak = low[0]
                for j in range(1, k):
                    y = low[j]
                    if y != y or peak != peak:
                        peak = nan
                        break
                    peak = peak if peak > y else y
                if math.isfinite(cross) and d0 < 0 and d1 >= 0:
                    y = low[kk]
                    y = cross if (cross > y or cross != cross) else y
                else:
                    y = peak
                z = ends[g, e]
                ends[g, e] = z if (z > y or z != z) else y
                step = width[g, e] / (k - 1)
                width[g, e] = step
                z = lo[g, e] + step * (kk - 1)
                z = z if (z > 0.0 or z != z) else 0.0
                lo[g, e] = z if (z < 1.0 or z != z) else 1.0

    @numba.njit(inline="always")
    def dot3(x0, x1, x2, y0, y1, y2, paired):
        """x . y as numpy's einsum sums it: (x0 y0 + x2 y2) + x1 y1 in its paired loop, else in
        order; onto +0 (which turns only a sum of -0 into +0). Inlined into its callers."""
        v = x0 * y0 + (x2 * y2 if paired else x1 * y1)
        v += x1 * y1 if paired else x2 * y2
        return v + 0.0

    @jit
    def cusp_foot(P1, N1, P2, N2, mP, mN, Ss, St, Sss, Sst, Stt, beyond, r, order, out):
        """The cusps between two lines of :func:`tsplcam.toolpath.lines._cusp_foot` (its
        numpy operations, in their order: the same bits), per gap g and sample i: the balls'
        centres on line 1 (P1 + r N1) and on line 2 (P2 + r N2), their spheres' intersection
        nearest the surface, one Gauss-Newton step to its foot from the mid point (mP, mN, the
        first and second derivatives Ss .. Stt) and the height there by the second fundamental
        form; inf where the balls do not meet, nan where ``beyond``. Each dot product summed
        as numpy's einsum sums it there: w.w and down.w (x0 + x2) + x1, the forms E, F, G, L,
        M, N and Ss.rel, St.rel, n.rel so where ``order`` (9) says, else x0 + x1 + x2 in
        order, onto +0 both; a nan kept by the maxima as by np.maximum. All arrays (G, m, 3)
        but beyond and out (G, m)."""
        G = P1.shape[0]
        m = P1.shape[1]
        four = 4 * r * r
        rr = r * r
        for g in range(G):
            for i in range(m):
                c10 = P1[g, i, 0] + r * N1[g, i, 0]
                c11 = P1[g, i, 1] + r * N1[g, i, 1]
                c12 = P1[g, i, 2] + r * N1[g, i, 2]
                c20 = P2[g, i, 0] + r * N2[g, i, 0]
                c21 = P2[g, i, 1] + r * N2[g, i, 1]
                c22 = P2[g, i, 2] + r * N2[g, i, 2]
                w0 = c20 - c10
                w1 = c21 - c11
                w2 = c22 - c12
                d2 = dot3(w0, w1, w2, w0, w1, w2, True)
                a0 = -(N1[g, i, 0] + N2[g, i, 0])
                a1 = -(N1[g, i, 1] + N2[g, i, 1])
                a2 = -(N1[g, i, 2] + N2[g, i, 2])
                f = dot3(a0, a1, a2, w0, w1, w2, True) / (d2 if d2 > 0 else 1.0)
                a0 = a0 - f * w0
                a1 = a1 - f * w1
                a2 = a2 - f * w2
                nd = a0 * a0 + a1 * a1
                nd += a2 * a2
                nd = math.sqrt(nd)
                nd = nd if (nd >= 1e-300 or nd != nd) else 1e-300
                a0 = a0 / nd
                a1 = a1 / nd
                a2 = a2 / nd
                s = rr - 0.25 * d2
                s = math.sqrt(s if (s >= 0.0 or s != s) else 0.0)
                e0 = (0.5 * (c10 + c20) + s * a0) - mP[g, i, 0]
                e1 = (0.5 * (c11 + c21) + s * a1) - mP[g, i, 1]
                e2 = (0.5 * (c12 + c22) + s * a2) - mP[g, i, 2]
                s0, s1, s2 = Ss[g, i, 0], Ss[g, i, 1], Ss[g, i, 2]
                t0, t1, t2 = St[g, i, 0], St[g, i, 1], St[g, i, 2]
                n0, n1, n2 = mN[g, i, 0], mN[g, i, 1], mN[g, i, 2]
                E = dot3(s0, s1, s2, s0, s1, s2, order[0])
                F = dot3(s0, s1, s2, t0, t1, t2, order[1])
                Gf = dot3(t0, t1, t2, t0, t1, t2, order[2])
                Lf = dot3(n0, n1, n2, Sss[g, i, 0], Sss[g, i, 1], Sss[g, i, 2], order[3])
                Mf = dot3(n0, n1, n2, Sst[g, i, 0], Sst[g, i, 1], Sst[g, i, 2], order[4])
                Nf = dot3(n0, n1, n2, Stt[g, i, 0], Stt[g, i, 1], Stt[g, i, 2], order[5])
                ra = dot3(s0, s1, s2, e0, e1, e2, order[6])
                rb = dot3(t0, t1, t2, e0, e1, e2, order[7])
                hn = dot3(n0, n1, n2, e0, e1, e2, order[8])
                det = E * Gf - F * F
                x = 0.0
                y = 0.0
                if det > 0:
                    x = (Gf * ra - F * rb) / det
                    y = (E * rb - F * ra) / det
                h = hn - 0.5 * (Lf * x * x + 2 * Mf * x * y + Nf * y * y)
                if not d2 < four:
                    h = math.inf
                if beyond[g, i]:
                    h = math.nan
                out[g, i] = h

    @jit
    def k_nearest(x, pts, items, start, origin, h, shape, k, ub, out, dist, tie):
        """The ``k`` nearest of a table's points to each point x[i] within ``ub`` (inf: any),
        nearest first, as scipy's kd-tree query (``distance_upper_bound=ub``) gives them (the
        table holds more than k): the table's cells (edge ``h``, ``shape`` cells from
        ``origin``; cell c's points ``pts[start[c]:start[c + 1]]``, their indices ``items`` in
        the same rows) scanned ring by ring around x's cell, each squared distance summed x,
        y, z in that order (the tree's bits) and counted where below ub^2 as there, until the
        (k + 1)-th nearest found, or ub, lies nearer than every cell not scanned and than the
        table's box (less a billionth of the edge, for the cells' rounding); into out[i, :k]
        (the table's size after the last found) and, where ``dist`` has rows, their distances
        (inf after).
        ``tie[i]``: two of the k + 1 nearest lie at the same distance (the tree's walk orders
        those, or picks the k-th among them: the caller asks the tree for those points)."""
        n0 = shape[0]
        n1 = shape[1]
        n2 = shape[2]
        bd = np.empty(k + 1)
        bi = np.empty(k + 1, np.int64)
        slack = 1e-9 * h
        u2 = ub * ub
        reach = ub * (1.0 + 1e-9) + slack
        size = items.shape[0]
        with_dist = dist.shape[0] > 0
        for i in range(x.shape[0]):
            x0 = x[i, 0]
            x1 = x[i, 1]
            x2 = x[i, 2]
            f = (x0 - origin[0]) / h
            c0 = 0 if not f >= 0.0 else (n0 - 1 if f >= n0 - 1 else np.int64(f))
            f = (x1 - origin[1]) / h
            c1 = 0 if not f >= 0.0 else (n1 - 1 if f >= n1 - 1 else np.int64(f))
            f = (x2 - origin[2]) / h
            c2 = 0 if not f >= 0.0 else (n2 - 1 if f >= n2 - 1 else np.int64(f))
            # the distance to the table's box, a bound of every point's too (far from it,
            # nothing lies within ub: the gouge check asks every path point of each patch)
            out2 = 0.0
            for a in range(3):
                o = origin[a] - x[i, a]
                if o < x[i, a] - (origin[a] + shape[a] * h):
                    o = x[i, a] - (origin[a] + shape[a] * h)
                if o > 0.0:
                    out2 += o * o
            box = np.sqrt(out2) - slack
            filled = 0
            m = 0 if box <= reach else -1
            while m >= 0:
                lo0 = c0 - m if c0 - m > 0 else 0
                hi0 = c0 + m if c0 + m < n0 - 1 else n0 - 1
                lo1 = c1 - m if c1 - m > 0 else 0
                hi1 = c1 + m if c1 + m < n1 - 1 else n1 - 1
                lo2 = c2 - m if c2 - m > 0 else 0
                hi2 = c2 + m if c2 + m < n2 - 1 else n2 - 1
                for a in range(lo0, hi0 + 1):
                    ea = a == c0 - m or a == c0 + m
                    for b in range(lo1, hi1 + 1):
                        base = (a * n1 + b) * n2
                        # the ring's cells in this row: the whole row on the ring's faces in a or
                        # b, else its two ends (one where m is 0)
                        s0 = s1 = t0 = t1 = 0
                        if ea or b == c1 - m or b == c1 + m:
                            s0 = start[base + lo2]
                            s1 = start[base + hi2 + 1]
                        else:
                            if c2 - m >= 0:
                                s0 = start[base + c2 - m]
                                s1 = start[base + c2 - m + 1]
                            if m > 0 and c2 + m <= n2 - 1:
                                t0 = start[base + c2 + m]
                                t1 = start[base + c2 + m + 1]
                        for seg in range(2):
                            u0 = s0 if seg == 0 else t0
                            u1 = s1 if seg == 0 else t1
                            for p in range(u0, u1):
                                q0 = x0 - pts[p, 0]
                                q1 = x1 - pts[p, 1]
                                q2 = x2 - pts[p, 2]
                                dd = q0 * q0
                                dd += q1 * q1
                                dd += q2 * q2
                                if not dd < u2:
                                    continue
                                if filled <= k:
                                    j = filled
                                    filled += 1
                                elif dd < bd[k]:
                                    j = k
                                else:
                                    continue
                                while j > 0 and bd[j - 1] > dd:
                                    bd[j] = bd[j - 1]
                                    bi[j] = bi[j - 1]
                                    j -= 1
                                bd[j] = dd
                                bi[j] = items[p]
                # every cell scanned, or none left nearer than the (k + 1)-th nearest
                if lo0 == 0 and lo1 == 0 and lo2 == 0 and hi0 == n0 - 1 and hi1 == n1 - 1 and hi2 == n2 - 1:
                    break
                bound = np.inf
                if c0 - m > 0:
                    bound = min(bound, x0 - (origin[0] + (c0 - m) * h))
                if c0 + m < n0 - 1:
                    bound = min(bound, origin[0] + (c0 + m + 1) * h - x0)
                if c1 - m > 0:
                    bound = min(bound, x1 - (origin[1] + (c1 - m) * h))
                if c1 + m < n1 - 1:
                    bound = min(bound, origin[1] + (c1 + m + 1) * h - x1)
                if c2 - m > 0:
                    bound = min(bound, x2 - (origin[2] + (c2 - m) * h))
                if c2 + m < n2 - 1:
                    bound = min(bound, origin[2] + (c2 + m + 1) * h - x2)
                bound = max(bound - slack, box)
                if bound > reach or (filled > k and bound > 0.0 and bd[k] < bound * bound):
                    break
                m += 1
            t = False
            for j in range(k):
                if j + 1 < filled and bd[j] == bd[j + 1]:
                    t = True
                out[i, j] = bi[j] if j < filled else size
                if with_dist:
                    dist[i, j] = np.sqrt(bd[j]) if j < filled else np.inf
            tie[i] = t

    @jit
    def cell_sort(P, lo, h, shape, start, order, pts):
        """:func:`cell_table`'s sort: each point's cell (``floor((P - lo) / h)`` per axis, the last
        cell holding what lies on the box's far side), the cells' first rows (``start``, zeros
        in, as long as the cells and one), the points' indices by cell, rows of one cell in
        their order (a stable counting sort: numpy's stable argsort of the cells), and those
        points."""
        n = P.shape[0]
        key = np.empty(n, np.int64)
        for i in range(n):
            c = np.int64(0)
            for a in range(3):
                f = np.int64(np.floor((P[i, a] - lo[a]) / h))
                if f > shape[a] - 1:
                    f = shape[a] - 1
                c = c * shape[a] + f
            key[i] = c
            start[c + 1] += 1
        for c in range(1, start.shape[0]):
            start[c] += start[c - 1]
        pos = start[:-1].copy()
        for i in range(n):
            p = pos[key[i]]
            pos[key[i]] += 1
            order[p] = i
            pts[p, 0] = P[i, 0]
            pts[p, 1] = P[i, 1]
            pts[p, 2] = P[i, 2]

    @numba.njit(inline="always")
    def meets_cylinder(V, T, t, c, a, u, w, lo, hi, R2, px, py, pz, qx, qy, qz):
        """Whether triangle t (rows of V by T) may meet the solid cylinder about the axis a
        through c (frame a, u, w), between the heights lo and hi, of squared radius R2: the
        triangle clipped to the slab (Sutherland-Hodgman, into the scratch rows px.. and
        qx..), then the axis through the clipped polygon seen along a, or a polygon edge within
        the radius of it. Only an answer False is a proof (the caller widens lo, hi and R2)."""
        zmin, zmax = np.inf, -np.inf
        for i in range(3):
            v = T[t, i]
            dx, dy, dz = V[v, 0] - c[0], V[v, 1] - c[1], V[v, 2] - c[2]
            pz[i] = dx * a[0] + dy * a[1] + dz * a[2]
            px[i] = dx * u[0] + dy * u[1] + dz * u[2]
            py[i] = dx * w[0] + dy * w[1] + dz * w[2]
            zmin, zmax = min(zmin, pz[i]), max(zmax, pz[i])
        if zmax < lo or zmin > hi:
            return False
        m = 3
        for side in range(2):
            lim, sg = (lo, 1.0) if side == 0 else (hi, -1.0)
            n = 0
            for i in range(m):
                j = i + 1 if i + 1 < m else 0
                ini, inj = sg * (pz[i] - lim) >= 0.0, sg * (pz[j] - lim) >= 0.0
                if ini:
                    qx[n], qy[n], qz[n] = px[i], py[i], pz[i]
                    n += 1
                if ini != inj:
                    f = (lim - pz[i]) / (pz[j] - pz[i])
                    qx[n], qy[n], qz[n] = px[i] + f * (px[j] - px[i]), py[i] + f * (py[j] - py[i]), lim
                    n += 1
            m = n
            for i in range(m):
                px[i], py[i], pz[i] = qx[i], qy[i], qz[i]
            if m == 0:
                return False
        if m >= 3:                                  # the axis inside the polygon (either turn)
            pos, neg = True, True
            for i in range(m):
                j = i + 1 if i + 1 < m else 0
                cr = (px[j] - px[i]) * -py[i] + (py[j] - py[i]) * px[i]
                if cr < 0.0:
                    pos = False
                if cr > 0.0:
                    neg = False
            if pos or neg:
                return True
        for i in range(m):
            j = i + 1 if i + 1 < m else 0
            dx, dy = px[j] - px[i], py[j] - py[i]
            ll = dx * dx + dy * dy
            f = 0.0
            if ll > 0.0:
                f = min(max(-(px[i] * dx + py[i] * dy) / ll, 0.0), 1.0)
            ex, ey = px[i] + f * dx, py[i] + f * dy
            if ex * ex + ey * ey <= R2:
                return True
        return False

    @jit
    def cylinder_clear(C, A, pose, part, z0, z1, ro, lo, h, shape, start, order, pts, se, emax,
                       tris_start, tris_flat, V, T, eps, max_cells, out):
        """:meth:`~tsplcam.orientation.broadphase.BroadPhase._cylinder_pass`: per (pose, part)
        row whether the part, a cylinder of circumscribed radius ro between heights z0 and z1
        on the axis, is proven clear of the mesh (out True). The samples (``pts`` by cells of
        ``h`` from ``lo``, their indices ``order``) within ro + their spacing ``se`` + eps of the
        axis segment and within their spacing of its heights are flagged, and their triangles
        (``tris_flat`` runs) tested whole (:func:`meets_cylinder`, heights and radius widened
        by eps); a row whose cells number more than ``max_cells`` is left open. Returns the
        rows cleared."""
        px, py, pz = np.empty(8), np.empty(8), np.empty(8)
        qx, qy, qz = np.empty(8), np.empty(8), np.empty(8)
        c, a, u, w = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
        cl, ch = np.empty(3, np.int64), np.empty(3, np.int64)
        cleared = 0
        for k in range(pose.shape[0]):
            out[k] = False
            i, j = pose[k], part[k]
            for d in range(3):
                c[d], a[d] = C[i, d], A[i, d]
            zlo, zhi = z0[j], z1[j]
            R = ro[j] + eps
            R2 = R * R
            reach = R + emax + eps
            cells = 1
            for d in range(3):
                e0, e1 = c[d] + zlo * a[d], c[d] + zhi * a[d]
                l0 = np.int64(np.floor((min(e0, e1) - reach - lo[d]) / h))
                l1 = np.int64(np.floor((max(e0, e1) + reach - lo[d]) / h))
                cl[d], ch[d] = max(l0, 0), min(l1, shape[d] - 1)
                cells *= max(ch[d] - cl[d] + 1, 0)
            if cells > max_cells:
                continue
            if abs(a[0]) < 0.9:                          # a frame across the axis
                u[0], u[1], u[2] = 0.0, a[2], -a[1]
            else:
                u[0], u[1], u[2] = -a[2], 0.0, a[0]
            ln = math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
            u[0], u[1], u[2] = u[0] / ln, u[1] / ln, u[2] / ln
            w[0], w[1], w[2] = a[1] * u[2] - a[2] * u[1], a[2] * u[0] - a[0] * u[2], a[0] * u[1] - a[1] * u[0]
            cull = reach + 0.8660254037844387 * h + eps    # a cell's centre: its samples in reach
            meets = False
            for i0 in range(cl[0], ch[0] + 1):
                for i1 in range(cl[1], ch[1] + 1):
                    for i2 in range(cl[2], ch[2] + 1):
                        cell = (i0 * shape[1] + i1) * shape[2] + i2
                        if start[cell] == start[cell + 1]:  # (an empty cell: nothing to cull)
                            continue
                        dx = lo[0] + (i0 + 0.5) * h - c[0]
                        dy = lo[1] + (i1 + 0.5) * h - c[1]
                        dz = lo[2] + (i2 + 0.5) * h - c[2]
                        z = min(max(dx * a[0] + dy * a[1] + dz * a[2], zlo), zhi)
                        dx, dy, dz = dx - z * a[0], dy - z * a[1], dz - z * a[2]
                        if dx * dx + dy * dy + dz * dz > cull * cull:
                            continue
                        for s in range(start[cell], start[cell + 1]):
                            dx, dy, dz = pts[s, 0] - c[0], pts[s, 1] - c[1], pts[s, 2] - c[2]
                            z = dx * a[0] + dy * a[1] + dz * a[2]
                            sid = order[s]
                            e = se[sid]
                            if z < zlo - e - eps or z > zhi + e + eps:
                                continue
                            z = min(max(z, zlo), zhi)
                            dx, dy, dz = dx - z * a[0], dy - z * a[1], dz - z * a[2]
                            if dx * dx + dy * dy + dz * dz > R2 + e * e / 3.0 + eps:
                                continue
                            for q in range(tris_start[sid], tris_start[sid + 1]):
                                if meets_cylinder(V, T, tris_flat[q], c, a, u, w, zlo - eps, zhi + eps, R2,
                                                  px, py, pz, qx, qy, qz):
                                    meets = True
                                    break
                            if meets:
                                break
                        if meets:
                            break
                    if meets:
                        break
                if meets:
                    break
            if not meets:
                out[k] = True
                cleared += 1
        return cleared

    @jit
    def capsule_entries(p, n, idx, length, a, e, b, r, of_a, of_b, lam, low_a, low_b):
        """:meth:`~tsplcam.verify.scallop.Swept.entry` of rows of candidates: for point p[q]
        (unit normal n[q]) and capsule idx[q, c] (length, start a, unit axis e, end b), the
        distance along the normal to where the ray enters the capsule (inf where it misses,
        negative inside), into lam[q, c]; the same operations in the same order as the numpy
        form (each dot product summed (x + z) + y), so the same bits, without its gathers and
        (rows, candidates) temporaries (the keycap's verification: 0.73 s of numpy). With
        masks ``of_a`` and ``of_b`` (rows, candidates; else (0, 0)) instead the least entry
        per row among the candidates each marks, into low_a[q] and low_b[q] (inf where none:
        :meth:`~tsplcam.verify.scallop.Swept.heights_among`; lam is not written)."""
        rr = r * r
        masked = of_a.shape[0] > 0
        for q in range(idx.shape[0]):
            ma = np.inf
            mb = np.inf
            px = p[q, 0]
            py = p[q, 1]
            pz = p[q, 2]
            nx = n[q, 0]
            ny = n[q, 1]
            nz = n[q, 2]
            for c in range(idx.shape[1]):
                if masked and not (of_a[q, c] or of_b[q, c]):
                    continue                            # (a row's padding: no owner's)
                j = idx[q, c]
                L = length[j]
                ex = e[j, 0]
                ey = e[j, 1]
                ez = e[j, 2]
                wx = px - a[j, 0]
                wy = py - a[j, 1]
                wz = pz - a[j, 2]
                dn = nx * ex + nz * ez + ny * ey
                wn = wx * ex + wz * ez + wy * ey
                dpx = nx - dn * ex
                dpy = ny - dn * ey
                dpz = nz - dn * ez
                wpx = wx - wn * ex
                wpy = wy - wn * ey
                wpz = wz - wn * ez
                A = dpx * dpx + dpz * dpz + dpy * dpy
                B = wpx * dpx + wpz * dpz + wpy * dpy
                Cc = (wpx * wpx + wpz * wpz + wpy * wpy) - rr
                disc = B * B - A * Cc
                out = np.inf
                if disc >= 0 and A > 1e-14 and L > 0:
                    t = (-B - np.sqrt(disc)) / A
                    axial = wn + t * dn
                    if axial >= 0 and axial <= L:
                        out = t
                # the balls at both ends (np.minimum: a nan wins)
                for end in range(2):
                    if end == 0:
                        cx = wx
                        cy = wy
                        cz = wz
                    else:
                        cx = px - b[j, 0]
                        cy = py - b[j, 1]
                        cz = pz - b[j, 2]
                    bb = nx * cx + nz * cz + ny * cy
                    cc = (cx * cx + cz * cz + cy * cy) - rr
                    d = bb * bb - cc
                    ls = -bb - np.sqrt(d) if d >= 0 else np.inf
                    if ls < out or ls != ls:
                        out = ls
                if not masked:
                    lam[q, c] = out
                else:                                   # (np.min: a nan wins)
                    if of_a[q, c] and (out < ma or out != out):
                        ma = out
                    if of_b[q, c] and (out < mb or out != out):
                        mb = out
            if masked:
                low_a[q] = ma
                low_b[q] = mb

    @numba.njit(inline="always")
    def sq_dist(x0, x1, x2, y0, y1, y2):
        """Squared distance of two points, the differences' squares summed x, y, z in that
        order (scipy's kd-tree's bits). Inlined into its callers."""
        a = x0 - y0
        b = x1 - y1
        e = x2 - y2
        return a * a + b * b + e * e

    @numba.njit(inline="always")
    def keep_two(dd, j, d1, j1, d2, j2):
        """The two nearest so far, (d1, j1) and (d2, j2), with point j at squared distance dd
        kept where it is nearer than the second (a tie with the second: not kept). Inlined into
        :func:`kd_nearest2`."""
        if dd < d2:
            if dd < d1:
                return dd, j, d1, j1
            return d1, j1, dd, j
        return d1, j1, d2, j2

    @numba.njit(inline="always")
    def union_root(parent, a):
        """The root of ``a`` in the union-find forest ``parent``, halving the path walked
        (each node on it pointed at its grandparent). Inlined into :func:`mesh_labels`."""
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    @jit
    def mesh_labels(nv, T, label):
        """Connected component of every vertex of a triangle mesh (vertices joined by the
        triangles' edges) into ``label``: union-find over two edges of each triangle (they
        join its three corners), then the components numbered in the order of their lowest
        vertex, as scipy's ``connected_components`` numbers them. Returns the count."""
        parent = np.arange(nv)
        for t in range(T.shape[0]):
            for e in range(2):
                a = union_root(parent, T[t, e])
                b = union_root(parent, T[t, e + 1])
                if a < b:
                    parent[b] = a
                elif b < a:
                    parent[a] = b
        count = 0
        for v in range(nv):
            r = union_root(parent, v)
            if r == v:
                label[v] = count
                count += 1
            else:
                label[v] = label[r]
        return count

    @jit
    def kd_build(P, leaf, idx, lo, hi, first, last, child):
        """A kd-tree over the points ``P`` (n, 3) for :func:`kd_nearest2`: a node's points
        split at the median of their widest coordinate (Wirth's selection) until at most
        ``leaf`` are left; node k holds ``idx[first[k]:last[k]]``, its box ``lo[k]``-``hi[k]``
        is its points' own, its children are ``child[k]`` and ``child[k] + 1`` (-1: a leaf).
        Node 0 is the root. Returns the count of nodes (the arrays hold at least
        4 n / leaf + 8: every leaf keeps at least half of ``leaf``)."""
        n = P.shape[0]
        for i in range(n):
            idx[i] = i
        first[0] = 0
        last[0] = n
        count = 1
        stack = np.empty(256, np.int64)
        stack[0] = 0
        sp = 1
        while sp > 0:
            sp -= 1
            k = stack[sp]
            s = first[k]
            e = last[k]
            for d in range(3):
                lo[k, d] = np.inf
                hi[k, d] = -np.inf
            for i in range(s, e):
                j = idx[i]
                for d in range(3):
                    v = P[j, d]
                    if v < lo[k, d]:
                        lo[k, d] = v
                    if v > hi[k, d]:
                        hi[k, d] = v
            child[k] = -1
            if e - s <= leaf:
                continue
            dim = 0
            w = hi[k, 0] - lo[k, 0]
            for d in range(1, 3):
                if hi[k, d] - lo[k, d] > w:
                    w = hi[k, d] - lo[k, d]
                    dim = d
            if not w > 0.0:                     # (one point many times: a leaf)
                continue
            m = (s + e) // 2
            a = s
            b = e - 1
            while a < b:                        # Wirth: idx[m] the median, none larger left of it
                piv = P[idx[m], dim]
                i = a
                j = b
                while i <= j:
                    while P[idx[i], dim] < piv:
                        i += 1
                    while piv < P[idx[j], dim]:
                        j -= 1
                    if i <= j:
                        t = idx[i]
                        idx[i] = idx[j]
                        idx[j] = t
                        i += 1
                        j -= 1
                if j < m:
                    a = i
                if m < i:
                    b = j
            c = count
            count += 2
            child[k] = c
            first[c] = s
            last[c] = m
            first[c + 1] = m
            last[c + 1] = e
            stack[sp] = c
            stack[sp + 1] = c + 1
            sp += 2
        return count

    @jit
    def kd_nearest2(x, P, pts, idx, lo, hi, first, last, child, wide, D, U):
        """The two nearest of the points ``P`` to each point x[i] at distances below ``wide``,
        nearest first, into ``D[i]`` (inf where none) and ``U[i]`` (their rows of P; P's
        size where none): scipy's kd-tree query (k 2, ``distance_upper_bound`` wide) but for
        the order of two at one distance. Each squared distance summed x, y, z in that order
        (the tree's bits), then its root. The tree is :func:`kd_build`'s over P, ``pts`` P's
        rows in the tree's order (``P[idx]``). The previous point's two answers are measured
        first (a grid's nodes in their order: a bound near the answer from the start), then
        every node whose box lies nearer than the second found (or the bound), nearer child
        first. A box's squared distance (its gaps outside it, squared and summed in order) is
        never more than that of a point in it summed as here (each rounded gap and square is at
        most the point's; the sums add the same or larger terms in the same order), so no point
        that would be kept is passed over; the gaps taken as max(lo - v, v - hi, 0), without a
        branch (the keycap's fine grid 16.5 -> 13.7 ms)."""
        n = P.shape[0]
        b2 = wide * wide
        stk = np.empty(256, np.int64)
        p1 = -1
        p2 = -1
        for q in range(x.shape[0]):
            x0 = x[q, 0]
            x1 = x[q, 1]
            x2 = x[q, 2]
            d1 = b2                             # (b2 with no point: the bound)
            d2 = b2
            j1 = -1
            j2 = -1
            for t in range(2):
                j = p1 if t == 0 else p2
                if j >= 0:
                    d1, j1, d2, j2 = keep_two(sq_dist(x0, x1, x2, P[j, 0], P[j, 1], P[j, 2]), j,
                                              d1, j1, d2, j2)
            stk[0] = 0
            sp = 1
            while sp > 0:
                sp -= 1
                k = stk[sp]
                m = 0.0
                for d in range(3):                  # (max: no branch, the same gap)
                    v = x[q, d]
                    g = max(lo[k, d] - v, v - hi[k, d], 0.0)
                    m += g * g
                if m >= d2:
                    continue
                c = child[k]
                if c < 0:
                    for r in range(first[k], last[k]):
                        j = idx[r]
                        if j != j1 and j != j2:
                            d1, j1, d2, j2 = keep_two(sq_dist(x0, x1, x2, pts[r, 0], pts[r, 1], pts[r, 2]), j,
                                                      d1, j1, d2, j2)
                    continue
                m0 = 0.0
                m1 = 0.0
                for d in range(3):
                    v = x[q, d]
                    g = max(lo[c, d] - v, v - hi[c, d], 0.0)
                    m0 += g * g
                    g = max(lo[c + 1, d] - v, v - hi[c + 1, d], 0.0)
                    m1 += g * g
                if m0 <= m1:                    # (the nearer popped first)
                    stk[sp] = c + 1
                    stk[sp + 1] = c
                else:
                    stk[sp] = c
                    stk[sp + 1] = c + 1
                sp += 2
            D[q, 0] = np.sqrt(d1) if j1 >= 0 else np.inf
            D[q, 1] = np.sqrt(d2) if j2 >= 0 else np.inf
            U[q, 0] = j1 if j1 >= 0 else n
            U[q, 1] = j2 if j2 >= 0 else n
            if j1 >= 0:
                p1 = j1
            if j2 >= 0:
                p2 = j2

    return {"hit_pairs": hit_pairs, "viterbi_steps": viterbi_steps, "kind_steps": kind_steps, "cone_arcs": cone_arcs,
            "meridian_dots": meridian_dots,
            "joint_steps": joint_steps, "viterbi_path": viterbi_path,
            "banded_solve": banded_solve, "grid_read": grid_read, "two_states": two_states,
            "solve_box": solve_box, "sphere_loop": sphere_loop, "side_bounds": side_bounds,
            "store_cones": store_cones, "centre_slots": centre_slots,
            "cubic_points": cubic_points, "unit_normals": unit_normals, "cusp_ends": cusp_ends,
            "cusp_foot": cusp_foot,
            "band_samples": band_samples, "measure_pairs": measure_pairs,
            "capsule_entries": capsule_entries, "k_nearest": k_nearest, "cell_sort": cell_sort,
            "cylinder_clear": cylinder_clear, "kd_build": kd_build, "kd_nearest2": kd_nearest2,
            "mesh_labels": mesh_labels}


def cell_table(points: np.ndarray, edge: float, max_cells: int, coarsest: float = np.inf) -> tuple | None:
    """``points`` sorted into cubic cells for the kernels' neighbour searches (``band_samples``,
    ``k_nearest``): cells of ``edge`` (larger where the points' box would need more than
    ``max_cells``) from the points' lowest corner; (that corner, the edge, the cells per axis,
    each cell's first row and the end, the points' indices by cell, rows of one cell in their
    order, those points); None where the cells would be larger than ``coarsest``. In numpy (a
    stable argsort of the cells), or with the kernels loaded in one pass of ``cell_sort`` (the
    same arrays; tjunction_mold's two tables, 2.4 M grid samples and 342k capsules, 0.55 ->
    0.19 s)."""
    P = np.ascontiguousarray(points, float)
    if not np.isfinite(P).all():             # (the kernels index by the cells unchecked)
        raise ValueError("cell_table: a point is not finite")
    lo, hi = P.min(axis=0), P.max(axis=0)
    h = max(edge, float(np.prod(hi - lo + 1e-9)) ** (1.0 / 3.0) / max_cells ** (1.0 / 3.0), 1e-6)
    if h > coarsest:
        return None
    shape = np.floor((hi - lo) / h).astype(np.int64) + 1
    start = np.zeros(int(np.prod(shape)) + 1, np.int64)
    k = loaded()
    if k is not None:
        order, pts = np.empty(len(P), np.int64), np.empty_like(P)
        k["cell_sort"](P, lo, float(h), shape, start, order, pts)
        return lo, float(h), shape, start, order, pts
    c = np.minimum(np.floor((P - lo) / h).astype(np.int64), shape - 1)
    key = (c[:, 0] * shape[1] + c[:, 1]) * shape[2] + c[:, 2]
    np.cumsum(np.bincount(key, minlength=len(start) - 1), out=start[1:])
    order = np.argsort(key, kind="stable").astype(np.int64)
    return lo, float(h), shape, start, order, np.ascontiguousarray(P[order])


#: each kernel's types for the ahead-of-time module, as the callers pass them (numba's JIT
#: specialises on the same): ``ret(arg, ...)``, an argument a scalar (f8 float64, i8 int64)
#: or an array ``dtype[ndim]`` (C-contiguous; ``w`` written by the kernel, the others
#: read-only); ``void`` returns None. A kernel's argument changed is to be changed here too.
SIGNATURES = {
    "viterbi_steps": "i8(f8[1]w, f8[2], f8[3], i8, f8, i4[2]w)",
    "kind_steps": "i8(f8[1]w, f8[2], f8[3], i8[1], i8, i8, f8, i4[2]w)",
    "cone_arcs": "void(f8[2], f8[2], f8, f8[2]w, f8[2]w)",
    "meridian_dots": "void(f8[2], f8[2], f8[2]w)",
    "joint_steps": "i8(f8[1]w, f8[2], i8, i8, f8[2], f8[2], f8[2], f8[2], f8[2], f8[2], b1[2], f8, f8, f8,"
                   " f8[1], b1[1], b1[1], f8, f8, i4[2]w)",
    "viterbi_path": "void(i4[2], i8, i8[1]w)",
    "two_states": "i8(f8[2], f8[3], f8, i8[1]w)",
    "banded_solve": "i8(f8[2]w, f8[1]w)",
    "solve_box": "i8(f8[2], f8[1], f8[1], f8[1], i8, f8[1]w, i1[1]w)",
    "grid_read": "void(f8[2], f8[1], f8, i8[1], i8[1], i8[1], f8[1], i8[1], f8[1]w, i8[1]w, b1[1]w)",
    "sphere_loop": "i8(f8[2], f8[2], i8[1], i8[1], f8[1], f8[1], f8[1], f8[1], f8[1], f8[1], i8[1], i8,"
                   " f8[1], f8[1], f8[2], f8[1], i8[2], i8[2], i8[2], i8[1], f8[1], i8[1], f8[2], i4[1],"
                   " f8[3], f8, f8, i1[1]w, b1[2]w, f8[1]w, i8[2]w)",
    "hit_pairs": "i8(f8[2], i8[1], i8[1], i8[1], f8[2], f8[2], f8[1], f8[1], f8[1], f8[1], f8[1], f8[1], i8,"
                 " i4[1], f8[3], f8, i1[1]w, i8[2]w)",
    "side_bounds": "i8(f8[2], f8[2], i8[1], i8[1], i8[1], i8, i8, f8[1], f8[1], f8[1], f8[1], f8[1], f8[1],"
                   " f8[2], f8[1], i8[2], i8[2], i8[2], i8[1], f8[1], i8[1], f8, f8[1]w, i8[1]w, f8[1]w, f8[1]w,"
                   " f8[2]w, f8[1]w)",
    "store_cones": "void(i8[1], i8[1], f8[2], f8[1], i8, f8[3]w, f8[2]w)",
    "centre_slots": "i8(i8[2], i8[1]w, i8[2]w, i8, i8[1]w, i8[1]w)",
    "unit_normals": "void(f8[2], f8[2], f8[2]w)",
    "cubic_points": "i8(f8[1], f8[1], f8[1], f8[1], i8[2], i8[2], f8[4], f8[2], f8[2], f8[2], b1[1], f8[3], i8, i8,"
                    " i8, f8[3]w, i1[1]w)",
    "cusp_ends": "void(f8[3], f8[3], i8, i8, f8[4], f8[4], f8[4], f8[3], f8, f8[2]w, f8[2]w, f8[2]w)",
    "cusp_foot": "void(f8[3], f8[3], f8[3], f8[3], f8[3], f8[3], f8[3], f8[3], f8[3], f8[3], f8[3], b1[2], f8,"
                 " b1[1], f8[2]w)",
    "measure_pairs": "void(f8[2], f8[1], f8[2], i8[2], f8[2], i8[1], i8[1], f8, f8[1]w)",
    "band_samples": "void(f8[2], f8[1], f8[2], i8[1], i8[1], f8[1], f8, i8[1], i8, f8[1]w, i8[1]w, i8[1]w, i8[2]w,"
                    " b1[1]w)",
    "capsule_entries": "void(f8[2], f8[2], i8[2], f8[1], f8[2], f8[2], f8[2], f8, b1[2], b1[2], f8[2]w, f8[1]w,"
                       " f8[1]w)",
    "k_nearest": "void(f8[2], f8[2], i8[1], i8[1], f8[1], f8, i8[1], i8, f8, i8[2]w, f8[2]w, b1[1]w)",
    "cell_sort": "void(f8[2], f8[1], f8, i8[1], i8[1]w, i8[1]w, f8[2]w)",
    "cylinder_clear": "i8(f8[2], f8[2], i8[1], i8[1], f8[1], f8[1], f8[1], f8[1], f8, i8[1], i8[1], i8[1],"
                      " f8[2], f8[1], f8, i8[1], i8[1], f8[2], i8[2], f8, i8, b1[1]w)",
    "kd_build": "i8(f8[2], i8, i8[1]w, f8[2]w, f8[2]w, i8[1]w, i8[1]w, i8[1]w)",
    "mesh_labels": "i8(i8, i8[2], i8[1]w)",
    "kd_nearest2": "void(f8[2], f8[2], f8[2], i8[1], f8[2], f8[2], i8[1], i8[1], i8[1], f8, f8[2]w, i8[2]w)",
}
#: the ahead-of-time module's name (beside this file, built by :func:`build_aot`)
AOT_MODULE = "_aot_kernels"


def _arguments(sig: str) -> tuple:
    """``(return code, ((code, ndim, written), ...))`` of a :data:`SIGNATURES` entry (ndim 0:
    a scalar)."""
    ret, _, rest = sig.partition("(")
    args = []
    for tok in rest.rstrip(")").split(","):
        tok = tok.strip()
        code, _, dims = tok.partition("[")
        args.append((code, int(dims[0]) if dims else 0, tok.endswith("w")))
    return ret, tuple(args)


def _processor() -> bytes:
    """This processor's feature flags (Linux: /proc/cpuinfo's first ``flags`` line, ARM's
    ``Features``), b"" where they cannot be read."""
    try:
        with open("/proc/cpuinfo", "rb") as f:
            for line in f:
                if line.startswith((b"flags", b"Features")):
                    return line.partition(b":")[2].strip()
    except OSError:
        pass
    return b""


def build_key() -> int | None:
    """A hash (60 bits) of the kernels' source (the text of :func:`_define`), their
    :data:`SIGNATURES` and this processor's feature flags (:func:`_processor`; the module is
    compiled for them): stored in the ahead-of-time module when it is built, compared when it
    is loaded. None when this file cannot be read."""
    import hashlib
    try:
        with open(__file__, "rb") as f:
            text = f.read()
    except OSError:
        return None
    i = text.find(b"\ndef _define(")
    j = text.find(b"\n\n\n", i)
    if i < 0 or j < 0:
        return None
    h = hashlib.sha256(text[i:j])
    h.update(repr(sorted(SIGNATURES.items())).encode())
    h.update(b"\0" + _processor())
    h.update(b"\0nogil")                          # modules built before their wrappers released the GIL
    return int(h.hexdigest()[:15], 16)


class _Exported:
    """A kernel of the ahead-of-time module, called where the arguments have its
    :data:`SIGNATURES`' types (arrays: dtype, ndim, C order, aligned, writeable where it
    writes; scalars: float for f8, an integer for i8), else numba's kernel of the same name
    (the module's wrapper would convert other arguments silently, or misread them)."""

    __slots__ = ("name", "fn", "spec")
    targetoptions = {"nogil": True}       # the module's wrappers release the GIL (:func:`build_aot`)

    def __init__(self, name: str, fn, sig: str):
        self.name, self.fn = name, fn
        self.spec = tuple((np.dtype(code) if nd else code, nd, w) for code, nd, w in _arguments(sig)[1])

    def __call__(self, *args):
        if len(args) == len(self.spec):
            for a, (dt, nd, w) in zip(args, self.spec):
                if nd:
                    if type(a) is not np.ndarray or a.ndim != nd or a.dtype != dt:
                        break
                    f = a.flags
                    if not (f.c_contiguous and f.aligned and (f.writeable or not w)):
                        break
                elif dt == "f8":
                    if not isinstance(a, float):
                        break
                elif isinstance(a, (bool, np.bool_)) or not isinstance(a, (int, np.integer)):
                    break
            else:
                return self.fn(*args)
        jit = _jit()
        if jit is None:
            raise TypeError(f"compiled.{self.name}: arguments not of the types {SIGNATURES[self.name]} "
                            "of the ahead-of-time module, and numba is not there")
        return jit[self.name](*args)


def _aot():
    """The ahead-of-time module's kernels (:class:`_Exported`), or None: not built, not
    importable, or built from another source or for another processor (:func:`build_key`).
    Importing it loads neither numba nor LLVM."""
    if "aot" not in _STATE:
        _STATE["aot"] = None
        try:
            from importlib import import_module
            mod = import_module(f"{__package__}.{AOT_MODULE}")
            built = mod.build_key()
        except (ImportError, OSError, AttributeError):
            return None
        want = build_key()
        if want is not None and built == want:
            _STATE["aot"] = {name: _Exported(name, getattr(mod, name), sig) for name, sig in SIGNATURES.items()}
    return _STATE["aot"]


def build_aot(force: bool = False) -> str | None:
    """Compile the kernels ahead of time (numba's ``pycc``, with :data:`SIGNATURES`) into the
    extension module :data:`AOT_MODULE` beside this file; returns its path (None without
    numba). Left alone when it is there and built from this source for this processor,
    unless ``force``.

    The module is compiled as numba's JIT compiles: for this processor (numba's host CPU
    name and feature flags, where pycc's default is the architecture's generic CPU: on
    x86-64 SSE2 only, a quarter slower in the Viterbi and sphere loops), and without
    fast-math, so every operation is the JIT kernels', in their order, rounding the same (no
    sums reordered, no fused multiply-adds). On another processor (other flags) the module
    is not loaded (:func:`build_key`); where the flags cannot be read it is built for the
    generic CPU. Written to a temporary name and moved into place, so a process that has
    the old module loaded keeps it (and its numba kernels): the new one serves the next."""
    import shutil
    import tempfile
    import warnings
    here = os.path.dirname(os.path.abspath(__file__))
    if not force and _aot() is not None:
        return _aot_path()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")       # pycc is pending deprecation in numba 0.59
            from numba.core import types
            from numba.core.codegen import AOTCPUCodegen
            from numba.pycc import CC
            from numba.pycc import compiler as pycc_compiler
    except ImportError:
        return None
    codes = {"f8": types.float64, "i8": types.int64, "i4": types.int32, "i1": types.int8,
             "b1": types.boolean, "void": types.void}
    funcs = _define(lambda f: f)
    key = build_key()
    tmp = tempfile.mkdtemp(prefix=".aot-build-", dir=here)
    features = AOTCPUCodegen._customize_tm_features
    flags = pycc_compiler.Flags

    class _NoGil(flags):
        """pycc's compile flags with ``release_gil`` set: each exported function's CPython
        wrapper then releases the GIL around the kernel, as ``njit(nogil=True)`` does (pycc
        has no option for it). The kernels touch no Python object."""

        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            self.release_gil = True
    try:
        pycc_compiler.Flags = _NoGil
        cc = CC(AOT_MODULE)
        cc.output_dir = tmp
        if _processor():                          # as the JIT: the host's name and flags
            cc.target_cpu = "host"
            AOTCPUCodegen._customize_tm_features = lambda self: self._get_host_cpu_features()
        for name, sig in SIGNATURES.items():
            ret, args = _arguments(sig)
            argtypes = [types.Array(codes[c], nd, "C", readonly=not w) if nd else codes[c] for c, nd, w in args]
            cc.export(name, codes[ret](*argtypes))(funcs[name])
        cc.export("build_key", "i8()")(lambda: key)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cc.compile()
        out = os.path.join(here, cc.output_file)
        os.replace(os.path.join(tmp, cc.output_file), out)
    finally:
        AOTCPUCodegen._customize_tm_features = features
        pycc_compiler.Flags = flags
        shutil.rmtree(tmp, ignore_errors=True)
    _STATE.pop("aot", None)
    return out


def _aot_path() -> str:
    """Where the ahead-of-time module is (or would be) for this Python."""
    import sysconfig
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), AOT_MODULE + sysconfig.get_config_var("EXT_SUFFIX"))


def kernels(work: float | None = None):
    """The compiled kernels (a dict of callables by name: the ahead-of-time module's, else
    numba's), or None without either (see the module doc). ``work``: the
    size of the computation the caller would otherwise do in numpy; with it, the kernels are
    only loaded once the work asked of this process reaches :data:`LOAD_WORK` (None till
    then); without it, now. A set :func:`prepare` loaded ahead is the one given."""
    if "k" not in _STATE:
        if work is not None:
            _STATE["work"] += work
            if _STATE["work"] < LOAD_WORK:
                return None
        spare = _STATE.pop("spare", None)
        _STATE["k"] = spare if spare is not None else _build()
    return _STATE["k"]


def loaded():
    """The kernels if this process has loaded them already, else None (asks for no work:
    for callers whose numpy form costs too little to load numba for, e.g. two-state chains)."""
    return _STATE.get("k")


def prepared():
    """The set :func:`prepare` put aside, if any (not loaded for the process: :func:`kernels`'
    choice by the work asked stays as it was), else None."""
    return _STATE.get("spare")


def prepare(exercise: Callable[[], None] | None = None) -> None:
    """Load the kernels into a set kept aside, leaving :func:`kernels`' own choice (compiled
    or numpy, by the work asked) untouched: :func:`kernels` gives that set once it loads. A
    job does this while it would only wait (``program.CheckerAhead``) and still makes the
    same bytes (the same kernels). The ahead-of-time module loads in about a millisecond;
    numba's kernels cost numba's import and each kernel's first call (about 0.3-0.45 s and
    7-20 ms a kernel), taken here: ``exercise`` calls them (the caller's, e.g.
    :func:`tsplcam.orientation.warmup.exercise`, run with this set as :func:`kernels`'; this
    module imports no stage). None: numba's set is only loaded, its kernels' first calls left
    to their callers."""
    if "k" in _STATE or "spare" in _STATE:
        return
    spare = _build()
    if spare is None:
        return
    if spare is _STATE.get("aot"):    # loaded whole, nothing to call first
        _STATE["spare"] = spare
        return
    _STATE["k"] = spare               # (kernels() gives this set while the calls below run)
    try:
        if exercise is not None:
            exercise()
    finally:
        del _STATE["k"]
    _STATE["spare"] = spare


def warm(exercise: Callable[[], None] | None = None) -> float:
    """Compile (or load from numba's cache) every numba kernel that ``exercise`` calls on a
    tiny input (e.g. :func:`tsplcam.orientation.warmup.exercise`, run with numba's set as
    :func:`kernels`'; None: numba's set only loaded, nothing called); returns the seconds
    taken (0 without numba, or with ``TSPLCAM_COMPILED=0``). ``scripts/install.sh`` calls it
    (after :func:`build_aot`), so a job that runs numba's kernels (no ahead-of-time module,
    or a stale one) does not carry their compilation."""
    t0 = time.perf_counter()
    if os.environ.get("TSPLCAM_COMPILED", "1") == "0" or _jit() is None:
        return 0.0
    had = "k" in _STATE
    k = _STATE.get("k")
    _STATE["k"] = _jit()              # (the calls below run numba's set, whatever kernels() gives)
    try:
        if exercise is not None:
            exercise()
    finally:
        if had:
            _STATE["k"] = k
        else:
            del _STATE["k"]
    return time.perf_counter() - t0
