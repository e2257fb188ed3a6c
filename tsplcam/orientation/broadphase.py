"""Broad phase for tool poses: most collision questions answered in numpy, conservatively.

The collision checker (:mod:`tsplcam.orientation.collision`) asks fcl whether the tool
(flutes, shank and holder above the ball centre, each part a circumscribed polygon frustum
grown by its margin) touches the workpiece triangle mesh. This module answers the same
question for whole arrays of poses at once with *free*, *hit* or *unknown*; only the unknown
poses go to fcl. Both answers are proofs, never estimates.

**Free.** Every part is covered by spheres on the tool axis (a frustum slab of length l and
largest circumscribed radius R lies in the sphere of radius sqrt(R^2 + l^2/4) about the
slab's centre; one sphere per part first, halved where it does not decide), and every sphere
is shown to miss the mesh with a lower bound of the distance from its centre to the mesh.
The bound comes from samples of the mesh (the vertices, and points spread over triangles
longer than ``e_cap``): if every sample lies at least d from x, every point of the mesh lies
at least sqrt(d^2 - e^2/3) from x, e the longest edge of the (sub)triangles the samples span
(the nearest mesh point w is a convex combination sum l_i v_i of a triangle's corners, and
|x - w|^2 = sum l_i |x - v_i|^2 - sum_{i<j} l_i l_j |v_i - v_j|^2 >= d^2 - e^2/3). The bound
is kept at the nodes of two grids (fine near the mesh, coarse over the tool's reach) and
read at the eight nodes around x, less the distance to each (the distance to a set is
1-Lipschitz). That read loses up to half a cell's diagonal, too much next to the surface
(the flutes sit a ball radius from it at the contact) and under a wide holder.

**Exact pass.** The parts the grids leave open are asked again (:meth:`BroadPhase.exact_bound`):
the samples in the band sqrt(R^2 + e^2/3) around each sphere centre from the KD-tree, and
where fewer than eight lie there, the exact distances to their triangles (every triangle that
reaches within R has a corner or sample in that band), from one sphere per part, split while a
smaller sphere might still clear (its bound plus half the slab reaches the slab's narrow end)
and at most ``EXACT_LEVELS`` times. A pose is given up to fcl at its first sphere that cannot
clear; the nearest samples of failing spheres are tried as hits. Where the last calls decided
less than a pose per ``EXACT_COST`` spheres (deep in a cavity most poses collide, and fcl is
cheaper there), and in cells where a wall already stopped poses, the pass is left out; after
a pause it is tried again. Within a call it runs on groups of poses of doubling size, and stops
at the first group after which the call's poses no longer pay. Nor does it run for a grown tool (the clearance
measurement's poses lie within a hair of the surface, where it seldom decides).

**Cone sides.** A sphere about a slab's middle reaches r (1 - cos a) beyond a cone part's
side (a its half-angle: 0.2-0.4 mm on ball1_keycap's holder cone), so next to a wall it fails
where fcl finds a clear gap. The side pass (:meth:`BroadPhase._side_pass`) covers the slabs of
such a part with balls that contain the slab's two circumscribed rings (so the slab: a ball is
convex, the slab the rings' hull) but are centred where a ball is tangent to the cone's side
(``slope * radius`` along the axis from the slab's middle): beyond the side they reach a hair
(0.026 mm at 2^3 slabs of that cone). Their centres lie a few mm from the mesh, beyond the
fine grid's cap, where the coarse grid loses up to 1.7 mm: their bounds come from a grid of
their own (:class:`LazyGrid`, 0.4 mm, made node by node where first read), else from the
exact bound, which is not asked where the grid node's sample lies inside the ball (the ball
cannot clear; that sample is tried as a hit). 2^3 slabs first, a failing ball split down to
2^5. On the keycap_mold job fcl is left 11k queries of 78k (about 45k had been the holder
cone's alone), for about 0.7 CPU-s here (24k exact bounds; the grid's nodes cost 5-11 us
each, 5.7k of them read, where bricks of 6^3 cells made whole had cost 24.7k).

**Cylinders of a grown tool.** The smallest clearance asks the shank and holder grown by a
few tenths of a mm, of poses whose shank passes that close to the surface; there the spheres
lose too much and the exact pass is not run, so the keycap's search at 0.30 mm left 3,618
of its 14,734 poses to fcl (35 ms). The cylinder pass (:meth:`BroadPhase._cylinder_pass`,
``cylinder_clear``) asks each cylinder part still open whether it meets a triangle: a point
w of the mesh inside the cylinder (radius R, heights z0 to z1) lies in a (sub)triangle whose
corners are samples within e_t of w, and by the identity above one of them lies within
sqrt(R^2 + e_t^2/3) of the axis segment and within e_t of the heights; so only the triangles
of such samples are tested, whole: clipped to the heights and seen along the axis, the axis
inside the clipped polygon or an edge within R of it (heights and radius widened by ``EPS``;
R the circumscribed polygon's). A part that meets none is clear; one that does is left to fcl.
The keycap's 3,618 poses: 3,607 cleared in 9-10 ms (2-3 samples a pose flagged, 11
triangles tested), the 11 left are fcl's 11 hits. Only for a grown tool, and only with the
compiled kernels (without them fcl answers, the same answers), and only up to a growth of
``SIDE_GROWN_MAX``: grown more, a shank's cylinder holds the surface near every pose, and the
pass scans its many samples for nothing (figure4's smallest clearance asks 52,344 poses at
4 mm: 0.72 s more, no pose cleared). A part whose box around its axis spans more than
``CYL_MAX_CELLS`` cells of the pass's table is left to fcl too, and a pose a part of it was
cleared this way keeps no free cone.

**Free cones.** Turning the axis by an angle phi about the ball centre moves a point at
distance l from it by at most l phi. A pose cleared with that much to spare leaves a cone of
free axes at its centre, from the spheres above (phi = min_j (bound_j - radius_j) / z_j).
Later poses at the same centre inside a cone are free without further work: the smoothing's
small moves.

**Hit.** A sample of the mesh lies strictly inside a part's inscribed circular frustum (the
polygon's inradius is the grown radius), and a point of the same connected piece of the mesh
lies strictly outside the whole tool's circumscribed solid: the piece then crosses the
tool's surface, so a mesh triangle meets a tool triangle, which is what fcl reports. The
samples tried are the nearest samples of the grid nodes around spheres that did not clear,
and the *witnesses* of earlier hits near the same ball centre (a wall that stops one axis
stops its neighbours).

The gouge check's ball B(c, r0) is proven clear by the same exact bound, once per ball
centre and only when asked (:meth:`BroadPhase.ball_free`); where more than ``BAND`` samples
lie in its band (next to the surface the ball touches), by the *band pass*
(:meth:`BroadPhase.band_clear`): every sample in the band, and the triangles a sample can
bring within r0 (its distance below sqrt(r0^2 + e_t^2/3) with e_t the triangle's own
subtriangle edge; in a crease's strip of small triangles few can), measured exactly. On the
keycap job it decides the 206 of 14,734 balls the exact bound left (3 ms, where fcl and its
workpiece BVH took 0.14 s), on the Fusion mold 5,583 of 11,110 (0.08 s against 0.85 s): the
ball check asks fcl only of balls that come within r0 + EPS of the mesh.

Every comparison keeps ``EPS`` (1e-6 mm) on the safe side, for fcl's own rounding. The tests
compare the decisions with fcl on random poses (tests/orientation).

**Compiled.** With numba (:mod:`~tsplcam.compiled`) the sphere loop runs pose by
pose in one kernel (``sphere_loop``: each pose's spheres level by level, its grid reads and
hit tests), with the same operations per sphere as numpy's level-by-level loop
(:meth:`BroadPhase._sphere_loop`, the fallback): the same decisions, open parts, free cones
and hit witnesses, bit for bit (tests/orientation/test_broadphase.py compares them). So do the
side pass's first read of its balls (``side_bounds``: 155k balls on the all-candidates batch,
28 ms in numpy, each ball's slab, centre and grid bounds; only the balls the grids leave open
come back) and the free cones' store (``store_cones``: row by row where numpy takes two rounds
of gathers and masks over every free pose, 16 ms there). The exact pass's narrow bands
(:meth:`BroadPhase._band`, R up to 4 e) come from a table of the samples in cubic cells of
2 e (``band_samples``; made with the grids where the kernels are loaded, else at the first
band), not from the KD-tree's eight nearest: the same squared distances (summed x, y, z as
scipy's tree sums them), the same strict comparisons with the bound, so the same nearest
distance, the same count and set of samples in the band, and the same bounds bit for bit; where two samples tie for the nearest, the tree is asked
which it gives. On the keycap's questions most bands hold no sample at all, which the tree
took about 2 us a point to find (its leaves' boxes reach within the bound) and the table
0.3 us (the 4,385 spheres 10.7 -> 1.5 ms).

**Threads.** The kernels take the poses one by one, each writing only its own rows; numba's
JIT kernel and the ahead-of-time module's release the GIL, as scipy's KD-tree queries do:
where a core is idle (:func:`threads`) a batch's poses go to it in two halves (the side
pass's rows cut between two poses), and KD queries
of ``KD_THREADS`` points or more are split between two threads (each point's answer is the
one a single thread gives). Every thread ends before the call returns, so none is
alive when the path or fcl workers fork.

**KD queries.** The samples' KD-tree (:class:`SampleTree`) answers as scipy's default tree
(median splits, nodes shrunk to their points) always has, bit for bit, but asks for the
nearest sample (k = 1) a sliding-midpoint tree over the distinct samples first (its two
nearest; where they, or one and the bound, lie closer in squared distance than
1e-9 (1 + bound)^2, or a repeated sample's copies lie in several of the default tree's
leaves, the default tree is asked): the keycap_mold job's wide exact bounds (R 3-6 mm in the
cavity) cost 16 us a point in the default tree, 4 in the other (:meth:`SampleTree._use_fast`).

**Per centre.** The free cones are kept per ball centre, found by the centre's bytes
(:class:`CentreTable`): with the kernels, in an open-addressing table of the centres' words
(``centre_slots``, slots numbered as the centres come: the keycap replay's 24k centres 0.6 ms
against 3.8 ms in numpy); in numpy through a 64-bit hash of them, sorted about ten times
faster than the 24-byte keys, each slot checked against its centre's bytes. The witness cells
keep the bytes' order, which decides what a cell keeps (the kernel finds their distinct rows,
numpy orders only those).
"""
from __future__ import annotations

import itertools
import os
import threading
import time
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..npfast import cross_rows, row_norms
from .. import compiled

FREE, HIT, UNKNOWN = 0, 1, -1
EPS = 1e-6
MAX_LEVEL = 7                 # finest sphere cover: 2^7 slabs per part
SLAB_EXCESS = 0.005           # mm: a part's finest cover sticks out at most this much
BAND = 8                      # samples examined exactly around a gouge-check ball
LEAFSIZE = 32
FINE = (0.4, 250_000)         # fine grid: finest spacing (mm), most nodes
COARSE = (2.0, 150_000)       # coarse grid, over the tool's reach around the mesh
CONES = 2                     # free cones kept per ball centre
WITNESSES = 6                 # hit witnesses kept per cell of ball centres
WITNESS_CELL = 1.0            # mm
CONE_WANT = np.radians(2.0)   # free cones the bounds are refined for
EXACT_LEVELS = 3              # the exact pass splits a part's sphere this often at most
SIDE_LEVELS = (3, 5)          # the side pass's balls: 2^3 slabs of a cone part first, split up to 2^5
SIDE_GRID = 0.4               # the side pass's own grid: spacing (mm)
# mm: a tool grown more than this (the smallest clearance's growths) leaves a pose a cylinder
# part keeps open to fcl whole (BroadPhase._side_pass); grown less, its cones are cleared
# too, so fcl asks only the cylinder (it asks part by part): the keycap's smallest clearance
# at 0.30 mm, 3,136 holder questions spared, 0.085 -> 0.065 s; figure4's at 4-7 mm would
# cost seconds of side-grid bounds for nothing decided. Nor does the cylinder pass run past
# it (BroadPhase._cylinder_pass: figure4's 52,344 poses at 4 mm, 0.72 s for none cleared)
SIDE_GROWN_MAX = 1.0
EXACT_COST = 3                # spheres of the exact pass that cost about as much as one fcl query
EXACT_PROBE = 2000            # spheres the exact pass is tried on before its gain counts
PLANE_SLACK = 1e-9            # mm: a triangle's plane distance counts only this much beyond R (rounding)
GRID_ROWS = 16384             # points a distance grid reads at a time
BAND_ROWS = (256, 4096, 500_000)   # the band pass (BroadPhase.band_distance): points at a time,
                                   # first and most, and the samples in their bands to aim at
READ_WORK = 30.0              # a grid read in numpy costs about as much as this many Viterbi elements
HIT_WORK = 100.0              # a sample tried as a hit in numpy: about this many Viterbi elements
SPHERE_WORK = 300.0           # a pose's part in the numpy sphere loop: about this many Viterbi elements
BAND_CELL = 2.0               # the band kernel's cells: this many sample spacings on a side
BAND_CELLS = 4_000_000        # at most this many cells (a large part: larger cells)
BAND_WORK = 200.0             # a band asked of the kd-tree: about this many Viterbi elements
MEASURE_WORK = 50.0           # a (point, triangle) pair measured in numpy: about this many Viterbi elements
CYL_CELL = 4.0                # the cylinder pass's table (BroadPhase._cylinder_pass): cells of this many
                              # sample spacings on a side
CYL_MAX_CELLS = 2000          # a part whose box around its axis spans more cells is left to fcl
CYL_WORK = 300.0              # a part asked of the cylinder pass: about this many Viterbi elements
CPU_WINDOW = 0.05             # s: the shortest window over which others_busy measures the cores
KD_THREADS = 256              # KD-tree queries of at least this many points run on two threads
KD_LEAF = 32                  # the compiled kd-tree's leaves: at most this many points
KD_WORK = 100.0               # a nearest-sample query of scipy's tree: about this many Viterbi elements
KERNEL_THREADS = 1024         # sphere loops of at least this many poses run on two threads
_CORNERS = np.array([(i, j, k) for i in (0, 1) for j in (0, 1) for k in (0, 1)], np.int64)
DIRECTIONS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)
                       if (i, j, k) != (0, 0, 0)], float)


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def threads() -> int:
    """Threads the broad phase may use for work that releases the GIL (KD-tree queries, the
    compiled sphere loop): two where this process may run on two cores (``TSPLCAM_WORKERS``,
    when set, caps it) and the other processes left one of them idle over the last moments
    (:func:`others_busy`; where that cannot be measured, the last minute's load average
    leaves one idle), else one (on cores shared with other work two threads only wait for
    each other: at load 4 on two cores they were slower), and one while this process's
    forked workers are busy; two once they are done while this process still works beside
    them (the molds' collision checker, built beside the path, outlasts it: keycap_mold's by
    0.14 s): a thread on the core a worker left keeps the job at the two it had (the window of
    :func:`others_busy` still holds that worker's time). The answers are the same either way.
    Every thread is joined before the call that started it returns, so none is alive when
    workers fork."""
    from ..toolpath import parallel
    waiting = getattr(parallel, "_WAITING", False)
    if waiting and not parallel.workers_idle():
        return 1
    env = os.environ.get("TSPLCAM_WORKERS", "").strip()
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if env:
        cores = min(cores, max(1, int(env)))
    if cores < 2:
        return 1
    if waiting:
        return 2
    others = others_busy()
    if others is not None:
        return 2 if others < cores - 1.5 else 1
    try:
        busy = os.getloadavg()[0]
    except OSError:                                   # pragma: no cover - no load average
        busy = 0.0
    return 2 if busy < cores - 0.5 else 1


_OTHERS = {"at": None, "busy": 0.0, "own": 0.0, "use": None}
if hasattr(os, "register_at_fork"):             # (a forked child's CPU time starts again at 0)
    os.register_at_fork(after_in_child=lambda: _OTHERS.update(at=None, use=None))


def others_busy() -> float | None:
    """Cores kept busy by everything but this process (other processes, this one's forked
    children, the hypervisor's steal) over the last window of at least ``CPU_WINDOW``
    seconds: the machine's busy time in /proc/stat less this process's CPU time, per second
    of the window; the last window's figure until a new one is complete. None where
    /proc/stat cannot be read, or before a window is complete (the first call starts one).

    The one-minute load average lags a minute behind (the bench's replay of the keycap's
    questions, right after the job and OpenCAMLib's two threads, saw 1.5-1.7 on an idle
    machine), and on this kind of virtual machine it idles near 1 with nothing running."""
    now = time.monotonic()
    st = _OTHERS
    if st["at"] is not None and now - st["at"] < CPU_WINDOW:
        return st["use"]
    try:
        with open("/proc/stat", "rb") as f:
            v = [int(x) for x in f.readline().split()[1:9]]
        busy = (sum(v) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")     # all but idle and iowait
    except (OSError, ValueError, IndexError):
        return None
    own = time.process_time()
    if st["at"] is not None:
        st["use"] = max(busy - st["busy"] - (own - st["own"]), 0.0) / (now - st["at"])
    st.update(at=now, busy=busy, own=own)
    return st["use"]


def on_threads(fn, n: int) -> list:
    """``[fn(0), ..., fn(n - 1)]`` with ``fn(1)`` on a second thread when n is 2 (n is 1 or 2:
    the callers split their rows in two where :func:`threads` allows). For kernels that
    release the GIL and write only their own rows; the thread is joined before this returns
    (none alive when workers fork), and an exception of either is raised here."""
    out: list = [None] * n

    def run(i):
        try:
            out[i] = fn(i)
        except BaseException as exc:                  # raised again in the calling thread
            out[i] = exc
    if n > 1:
        other = threading.Thread(target=run, args=(1,))
        other.start()
        try:
            run(0)
        finally:
            other.join()
    else:
        run(0)
    for got in out:
        if isinstance(got, BaseException):
            raise got
    return out


def any_row(a: np.ndarray) -> np.ndarray:
    """``a.any(axis=1)`` of a 2-d array, column by column (numpy's reduction over a short row
    costs about 10 ns a row, or 1.6 ms for the all-candidates batch's 182k poses; the ors of
    its few columns a tenth of that)."""
    if a.ndim != 2 or a.shape[1] == 0:
        return a.any(axis=1)
    out = a[:, 0] != 0
    for k in range(1, a.shape[1]):
        out |= a[:, k] != 0
    return out


def row_bits(a: np.ndarray) -> np.ndarray:
    """Per row of the 2-d bool array ``a`` the integer with bit k set where ``a[:, k]`` is (the
    same as ``a @ (1 << arange(K))``, without the matrix product's conversions)."""
    out = np.zeros(len(a), np.int64)
    for k in range(a.shape[1]):
        out |= a[:, k].astype(np.int64) << k
    return out


def nonzero_pairs(a: np.ndarray, rows: np.ndarray | None = None, cols: np.ndarray | None = None):
    """``np.nonzero(a & rows[:, None] & cols[None, :])`` of a 2-d bool array ``a`` (``rows``,
    ``cols`` bool masks, None: all): the same pairs in the same (row-major) order, through the
    rows that have any (np.nonzero over the whole array costs about 6 ns an element, 4.5 ms for
    the all-candidates batch's unresolved parts, of which few rows have any)."""
    live = np.zeros(len(a), bool)
    for k in range(a.shape[1]) if cols is None else np.flatnonzero(cols):
        live |= a[:, k]
    if rows is not None:
        live &= rows
    r = np.flatnonzero(live)
    sub = a[r] if cols is None else a[r] & cols[None, :]
    i, j = np.nonzero(sub)
    return r[i], j


class SampleTree:
    """``cKDTree.query`` on the samples, the same answers bit for bit, about four times faster
    where they lie on a surface (a cavity's wide bounds: 16 us a point, 4 here).

    Its answers are those of the tree ``ref`` (leaves of ``LEAFSIZE``, median splits, nodes
    shrunk to their points: scipy's default, which the broad phase has always asked). The
    points are asked first of a second tree over the same samples (sliding-midpoint splits,
    nodes not shrunk), for their k + 1 nearest within the bound widened by a hair. Both trees
    sum each squared distance alike (the same bits) and search exactly up to the rounding of
    their boxes' distances (a few ulps of the bound squared), so where the k + 1 nearest lie
    apart by more than a margin and none lies that close to the bound, the k nearest within
    the bound are one set in one order, whichever tree walks: the second tree's answer is
    ``ref``'s (:meth:`query`: the margin on squared distances, which the trees compare). The
    few points where they do not (two samples at one distance, as where neighbouring
    triangles' subdivisions share an edge) are asked of ``ref`` (its order of ties is its
    walk's)."""

    def __init__(self, samples: np.ndarray):
        samples = np.ascontiguousarray(samples, float)
        self.ref = cKDTree(samples, leafsize=LEAFSIZE)
        self.n = self.ref.n
        self.asked_ref = 0                   # points the fast tree left to ref (ties)
        # the second tree over the distinct points (a mesh's samples repeat: the mold's 97k
        # hold 78k points), each standing for the sample ref gives where it is the nearest:
        # of a point whose samples share one leaf of ref, the first in the leaf (ref's walk
        # keeps the first of equal distances, and a leaf is read in order); else none (-1)
        first, inv, cnt = self._distinct(samples)
        rep = first.astype(np.int64)
        if (cnt > 1).any():
            pos = np.empty(self.n, np.int64)
            pos[self.ref.indices] = np.arange(self.n)
            leaf = np.empty(self.n, np.int64)
            stack, nl = [self.ref.tree], 0
            while stack:
                node = stack.pop()
                if node.split_dim == -1:
                    leaf[node.start_idx:node.end_idx] = nl
                    nl += 1
                else:
                    stack += [node.lesser, node.greater]
            m = np.nonzero(cnt[inv] > 1)[0]
            g, lm, pm = inv[m], leaf[pos[m]], pos[m]
            lo, hi = np.full(len(cnt), -1, np.int64), np.full(len(cnt), -1, np.int64)
            np.maximum.at(hi, g, lm)
            lo[:] = hi
            np.minimum.at(lo, g, lm)
            best = np.full(len(cnt), self.n, np.int64)
            np.minimum.at(best, g, pm)
            dup = np.nonzero(cnt > 1)[0]
            rep[dup] = np.where(lo[dup] == hi[dup], self.ref.indices[np.minimum(best[dup], self.n - 1)], -1)
        self.rep, self.mult = rep, cnt
        self.distinct = np.ascontiguousarray(samples[first])
        self._fast = None                    # scipy's tree over them, made when first asked
        self._kd = None                      # the compiled one (kd_build's arrays), the same
        self.mode = None                     # "fast" or "ref": always that tree; None: by k

    @property
    def fast(self) -> cKDTree:
        """scipy's tree over the distinct points (sliding-midpoint splits, nodes not shrunk),
        made when first asked: where the kernels are loaded the compiled tree answers its
        nearest-sample calls (:meth:`_two_nearest`)."""
        if self._fast is None:
            self._fast = cKDTree(self.distinct, leafsize=LEAFSIZE, balanced_tree=False, compact_nodes=False)
        return self._fast

    def _use_fast(self, k: int) -> bool:
        """Which tree answers a call (the same answers either way): the fast one for the
        nearest sample alone, the default one for the k nearest (the narrow bands: the checks
        over k + 1 columns cost more; on the sample jobs 2.2-2.6 times the default tree's
        time). The nearest sample's calls in one process, fast tree against default tree
        (s): keycap distance grids 0.063 / 0.077; keycap_mold (as the bench runs it) grids
        0.097 / 0.093, wide exact bounds 0.111 / 0.265, side grid 0.023 / 0.043; Fusion mold
        grids 0.091 / 0.096, exact bounds 0.225 / 1.157, side grid 0.029 / 0.095; deep_mold
        grids 0.148 / 0.132, exact bounds 0.129 / 0.172; tjunction_mold grids 0.146 / 0.237;
        head grids 0.275 / 0.443, exact bounds 0.081 / 0.069. (The tree that took less time
        on the first 512 points asked, 64 of each call, answered before: on keycap_mold in
        one process those were the distance grids' far rows, the default tree won, and the
        bench's keycap_mold job took 1.35 s against 1.21 s now, medians of 4 alternate pairs;
        in two processes 1.09 against 1.00 s, 6 pairs.)"""
        if self.mode is not None:
            return self.mode == "fast"
        return k == 1

    @staticmethod
    def _distinct(P: np.ndarray):
        """(first row, group per row, rows per group) of the distinct rows of P (bytes): sorted
        by a 64-bit hash of each row (a third of the time of sorting the 24-byte rows), each
        group checked to hold one row's bytes (else the bytes sorted)."""
        bits = P.view(np.uint64)
        order = np.argsort(CentreTable._hash(bits), kind="stable")
        b = bits[order]
        step = np.concatenate(([True], (b[1:] != b[:-1]).any(axis=1)))
        h = CentreTable._hash(b)
        if not np.array_equal(step, np.concatenate(([True], h[1:] != h[:-1]))):
            # (two rows share a hash: the bytes sorted)
            _, first, inv, cnt = np.unique(P.view(np.dtype((np.void, 24))).ravel(), return_index=True,
                                           return_inverse=True, return_counts=True)
            return first, inv, cnt
        grp = np.cumsum(step) - 1
        inv = np.empty(len(P), np.int64)
        inv[order] = grp
        return order[step], inv, np.diff(np.append(np.flatnonzero(step), len(P)))

    def query(self, x, k: int = 1, distance_upper_bound: float = np.inf, workers: int = 1):
        """``cKDTree.query(x, k, distance_upper_bound=..., workers=...)`` of ``ref``, for x
        (m, 3) and an integer k: distances (m,) or (m, k), indices ``n`` where none. Ties are
        judged on squared distances (the trees compare those), within ``1e-9 (1 + u)^2``
        (u the bound; without one, the farthest distance found), where the trees' rounding is
        below 1e-13 of it."""
        x = np.asarray(x, float)
        u = float(distance_upper_bound)
        if self._use_fast(k):
            return self._query_fast(x, k, u, workers)
        return self.ref.query(x, k=k, distance_upper_bound=u, workers=workers)

    def _query_fast(self, x, k: int, u: float, workers: int):
        """:meth:`query` by the fast tree (ambiguous points by ``ref``)."""
        if np.isfinite(u):
            tol2 = 1e-9 * (1.0 + u) ** 2
            wide = float(np.sqrt(u * u + 2.0 * tol2))
        else:
            tol2, wide = None, u
        kern = compiled.kernels(work=KD_WORK * len(x)) if k == 1 and len(x) else None
        if kern is not None:
            D, U = self._two_nearest(x, wide, workers, kern)
        else:
            D, U = self.fast.query(x, k=k + 1, distance_upper_bound=wide, workers=workers)
        nu = len(self.rep)
        Uk = np.minimum(U[:, :k], nu - 1)
        J = np.where(U[:, :k] < nu, self.rep[Uk], self.n)
        # a repeated point among the k nearest: its samples' order is ref's walk's (k > 1), or
        # they lie in several leaves of ref
        many = (U[:, :k] < nu) & (self.mult[Uk] > 1)
        amb0 = (J < 0).any(axis=1) | (many.any(axis=1) if k > 1 else False)
        with np.errstate(invalid="ignore"):                 # (inf - inf: none found, not a tie)
            D2 = D * D
            if tol2 is None:
                far = D2[np.isfinite(D2)]
                tol2 = 1e-9 * (1.0 + float(np.sqrt(far.max())) if len(far) else 1.0) ** 2
            # ambiguous: two of the k + 1 nearest found within tol2, or one within tol2 of u^2
            amb = amb0 | (np.abs(D2[:, 0] - u * u) <= tol2)
            for t in range(1, k + 1):
                amb |= (np.abs(D2[:, t] - u * u) <= tol2) | (D2[:, t] - D2[:, t - 1] <= tol2)
        D = D[:, :k]
        out = D >= u                          # (found between the bound and the widened one)
        D[out], J[out] = np.inf, self.n
        a = np.nonzero(amb)[0]
        if len(a):
            self.asked_ref += len(a)
            d, j = self.ref.query(x[a], k=k, distance_upper_bound=u)
            D[a], J[a] = np.reshape(d, (len(a), k)), np.reshape(j, (len(a), k))
        return (np.ascontiguousarray(D[:, 0]), np.ascontiguousarray(J[:, 0])) if k == 1 else (D, J)

    def _two_nearest(self, x: np.ndarray, wide: float, workers: int, kern) -> tuple:
        """The fast tree's ``query(x, k=2, distance_upper_bound=wide)`` from the compiled
        kd-tree over the same points (``kd_build``, ``kd_nearest2``): the same distances and,
        but for the order of two at one distance (which :meth:`_query_fast` leaves to ``ref``),
        the same indices. Each point's search starts from the previous point's answers, so a
        grid's nodes in their order cost a third to a half of the scipy tree's time (the keycap's
        distance grids, 50k nodes: 55 -> 22 ms); the rows in two halves on two threads where
        ``workers`` is 2."""
        if self._kd is None:
            P = self.distinct
            cap = 4 * (len(P) // KD_LEAF) + 8
            idx, lo, hi = np.empty(len(P), np.int64), np.empty((cap, 3)), np.empty((cap, 3))
            first, last, child = (np.empty(cap, np.int64) for _ in range(3))
            m = kern["kd_build"](P, KD_LEAF, idx, lo, hi, first, last, child)
            self._kd = (np.ascontiguousarray(P[idx]), idx, lo[:m].copy(), hi[:m].copy(), first[:m].copy(),
                        last[:m].copy(), child[:m].copy())
        x = np.ascontiguousarray(x, float)
        D, U = np.empty((len(x), 2)), np.empty((len(x), 2), np.int64)
        pts, idx, lo, hi, first, last, child = self._kd
        parts = 2 if workers > 1 and len(x) >= KD_THREADS else 1
        cut = [0, len(x) // 2, len(x)] if parts == 2 else [0, len(x)]

        def run(i):
            a, b = cut[i], cut[i + 1]
            kern["kd_nearest2"](x[a:b], self.distinct, pts, idx, lo, hi, first, last, child, float(wide),
                                D[a:b], U[a:b])
        on_threads(run, parts)
        return D, U


def min_into(out: np.ndarray, idx: np.ndarray, vals: np.ndarray) -> None:
    """``np.minimum.at(out, idx, vals)``: the same values (a minimum does not round, so the
    order it is taken in does not matter), by ``np.minimum.reduceat`` over the runs of equal
    indices where ``idx`` is sorted (the broad phase's pose lists are: numpy 1.24's ufunc.at
    costs about 50 ns an element, this a tenth); else ``np.minimum.at`` itself."""
    if len(idx) == 0:
        return
    if len(idx) > 1 and not (idx[1:] >= idx[:-1]).all():
        np.minimum.at(out, idx, vals)
        return
    start = np.flatnonzero(np.concatenate(([True], idx[1:] != idx[:-1])))
    at = idx[start]
    out[at] = np.minimum(out[at], np.minimum.reduceat(vals, start))


def first_of_each(v: np.ndarray) -> np.ndarray:
    """``np.unique(v, return_index=True)[1]``: the index of each value's first occurrence, in
    the values' order; sorted over the starts of runs of equal values only (a batch asks
    several axes per centre one after the other: a few runs per hundred rows)."""
    if len(v) < 2:
        return np.arange(len(v))
    start = np.flatnonzero(np.concatenate(([True], v[1:] != v[:-1])))
    return start[np.unique(v[start], return_index=True)[1]]


def _dot_xyz(a, b):
    """a . b over the last axis, the products summed x, y, z in that order (einsum's order
    varies with the processor; the compiled ``measure_pairs`` sums so: the same bits)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def closest_on_triangles(P, A, B, C):
    """Closest points of triangles ABC to points P (all (n, 3)): Ericson, Real-Time
    Collision Detection (2005), section 5.1.5, vectorised."""
    ab, ac, ap = B - A, C - A, P - A
    d1, d2 = _dot_xyz(ab, ap), _dot_xyz(ac, ap)
    bp = P - B
    d3, d4 = _dot_xyz(ab, bp), _dot_xyz(ac, bp)
    cp = P - C
    d5, d6 = _dot_xyz(ab, cp), _dot_xyz(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        den = va + vb + vc
        v = np.where(den != 0, vb / den, 0.0)
        w = np.where(den != 0, vc / den, 0.0)
        out = A + v[..., None] * ab + w[..., None] * ac                       # face region
        # edge regions, then vertex regions: a later assignment wins
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        e_bc = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
        out = np.where(e_bc[..., None], B + np.nan_to_num(t_bc)[..., None] * (C - B), out)
        t_ac = d2 / (d2 - d6)
        e_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        out = np.where(e_ac[..., None], A + np.nan_to_num(t_ac)[..., None] * ac, out)
        t_ab = d1 / (d1 - d3)
        e_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        out = np.where(e_ab[..., None], A + np.nan_to_num(t_ab)[..., None] * ab, out)
    out = np.where(((d6 >= 0) & (d5 <= d6))[..., None], C, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[..., None], B, out)
    out = np.where(((d1 <= 0) & (d2 <= 0))[..., None], A, out)
    return out


def longest_edges(V: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Length of every triangle's longest edge: ``|V[T[:, [1, 2, 0]]] - V[T]|`` per row's
    largest, the same operations coordinate by coordinate (the squares summed x, y, z as
    ``np.linalg.norm`` sums them, so the same bits) without the (n, 3, 3) temporaries: a
    fifth of the time on the keycap's 38k triangles."""
    V = np.asarray(V, float)
    T = np.asarray(T)
    X, Y, Z = (np.ascontiguousarray(V[:, a]) for a in range(3))
    t0, t1, t2 = (np.ascontiguousarray(T[:, a]) for a in range(3))

    def length(a, b):
        dx, dy, dz = X[a] - X[b], Y[a] - Y[b], Z[a] - Z[b]
        return np.sqrt(dx * dx + dy * dy + dz * dz)
    return np.maximum(np.maximum(length(t1, t0), length(t2, t1)), length(t0, t2))


def mesh_samples(V: np.ndarray, T: np.ndarray, e_cap: float):
    """Points on the triangles: the vertices, and for every triangle longer than ``e_cap``
    the inner vertices of its uniform barycentric subdivision into k^2 triangles
    (k = ceil(edge / e_cap)). Returns (points, triangle of each extra point (-1 for the
    vertices), e = longest (sub)triangle edge, per triangle the longest edge of its
    subtriangles)."""
    V = np.asarray(V, float)
    T = np.asarray(T, np.int64)
    if len(T) == 0:
        return V.copy(), np.full(len(V), -1), 0.0, np.zeros(0)
    edge = longest_edges(V, T)
    k = np.maximum(1, np.ceil(edge / e_cap - 1e-9)).astype(int)
    pts, tri_of = [V], [np.full(len(V), -1)]
    sub = edge / k
    e = float(sub.max())
    for kk in np.unique(k[k > 1]):
        sel = np.nonzero(k == kk)[0]
        i, j = np.meshgrid(np.arange(kk + 1), np.arange(kk + 1), indexing="ij")
        keep = (i + j <= kk) & ~(((i == 0) & (j == 0)) | ((i == kk) & (j == 0)) | ((i == 0) & (j == kk)))
        a, b = i[keep] / kk, j[keep] / kk
        A, B, C = V[T[sel, 0]], V[T[sel, 1]], V[T[sel, 2]]
        P = A[:, None] * (1 - a - b)[None, :, None] + B[:, None] * a[None, :, None] + C[:, None] * b[None, :, None]
        pts.append(P.reshape(-1, 3))
        tri_of.append(np.repeat(sel, len(a)))
    return np.concatenate(pts), np.concatenate(tri_of), e, sub


def mesh_components(nv: int, T: np.ndarray) -> np.ndarray:
    """Connected component of every vertex (vertices joined by triangle edges), numbered in
    the order of each one's lowest vertex (int32, scipy's ``connected_components``); with the
    kernels loaded by union-find (``compiled.mesh_labels``: the same numbers, the keycap's
    38k triangles 3.7 -> 0.3 ms)."""
    T = np.asarray(T, np.int64)
    if len(T) == 0:
        return np.arange(nv)
    k = compiled.loaded()
    if k is not None and T.ndim == 2 and T.shape[1] == 3 and T.min() >= 0 and T.max() < nv:
        label = np.empty(nv, np.int64)
        k["mesh_labels"](int(nv), np.ascontiguousarray(T), label)
        return label.astype(np.int32)
    rows = np.concatenate([T[:, 0], T[:, 1], T[:, 2]])
    cols = np.concatenate([T[:, 1], T[:, 2], T[:, 0]])
    g = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(nv, nv))
    return connected_components(g, directed=False)[1]


@dataclass
class Profile:
    """The tool's parts as fcl sees them, per part: heights above the ball centre, the
    inscribed radius (the grown radius: the polygon's inradius, and the fcl Cylinder's
    radius) and the circumscribed radius (the polygon's corners) at both ends."""
    z0: np.ndarray
    z1: np.ndarray
    rin0: np.ndarray
    rin1: np.ndarray
    rout0: np.ndarray
    rout1: np.ndarray

    def rout(self, k, z):
        f = (z - self.z0[k]) / (self.z1[k] - self.z0[k])
        return self.rout0[k] + f * (self.rout1[k] - self.rout0[k])

    def rin(self, k, z):
        f = (z - self.z0[k]) / (self.z1[k] - self.z0[k])
        return self.rin0[k] + f * (self.rin1[k] - self.rin0[k])

    @property
    def reach(self) -> float:
        """Distance from the ball centre to the farthest point of the tool."""
        return float(np.hypot(self.z1.max(), max(self.rout0.max(), self.rout1.max())))


class SphereCover:
    """Spheres on the tool axis covering each part, level by level (level L: 2^L slabs)."""

    def __init__(self, prof: Profile):
        self.prof = prof
        K = len(prof.z0)
        self.max_level = np.zeros(K, int)
        for k in range(K):
            length = prof.z1[k] - prof.z0[k]
            r = max(min(prof.rout0[k], prof.rout1[k]), 1e-3)
            for L in range(MAX_LEVEL + 1):
                half = 0.5 * length / 2 ** L
                if np.sqrt(r * r + half * half) - r <= SLAB_EXCESS:
                    break
            self.max_level[k] = L

    def spheres(self, part: np.ndarray, level: int, seg: np.ndarray):
        """(centre height, radius, the slab's largest circumscribed radius) of slab ``seg``
        of ``part`` at ``level``."""
        p = self.prof
        length = (p.z1[part] - p.z0[part]) / 2 ** level
        za = p.z0[part] + seg * length
        zb = za + length
        rmax = np.maximum(p.rout(part, za), p.rout(part, zb))
        return 0.5 * (za + zb), np.sqrt(rmax * rmax + 0.25 * length * length), rmax


class DistanceGrid:
    """Lower bounds of the distance to the mesh at the nodes of a regular grid (capped), and
    the nearest sample of each node (-1 beyond the cap).

    Most nodes lie beyond the cap (on the keycap 73% of the fine grid's, 92% of the coarse
    one's), and a KD query that finds nothing still costs about half of one that does. So
    blocks of ``BLOCK``^3 nodes are asked first, at their centres: a block whose centre lies
    farther than the cap plus its half-diagonal (and ``EPS``, for rounding) from every sample
    has every node beyond the cap, which is what the node's own query answers; so has a node
    of another block farther than the cap (and ``EPS``) from the sample nearest to the
    block's centre, less its distance from the centre; the other nodes are queried, each
    point's answer the same bits as in any batch (the keycap's two grids: 50k nodes queried of
    230k, 0.11 CPU-s; 53k before the nodes' own test). The queries run on :func:`threads`
    (one while the path's workers run)."""

    BLOCK = 3

    def __init__(self, tree: cKDTree, e2: float, lo: np.ndarray, hi: np.ndarray, spacing: float,
                 pad: float, cap: float, nodes: int):
        self.h = self.spacing(lo, hi, spacing, pad, nodes)
        self.origin = lo - pad
        self.shape = np.ceil((hi - lo + 2 * pad) / self.h).astype(np.int64) + 1
        axes = [self.origin[i] + self.h * np.arange(self.shape[i]) for i in range(3)]
        self.cap = float(cap)
        b, (n0, n1, n2) = self.BLOCK, self.shape
        D, cen = self._block_distances(tree)
        ask = np.isfinite(D).repeat(b, 0).repeat(b, 1).repeat(b, 2)[:n0, :n1, :n2]
        q = np.flatnonzero(ask)
        i, j, k = np.unravel_index(q, ask.shape)
        X = np.column_stack([axes[0][i], axes[1][j], axes[2][k]])
        # a node farther from its block centre's nearest sample than the cap, by the distance
        # between them (the distance to the samples is 1-Lipschitz) and EPS, is beyond the cap
        # too: what its own query answers
        r = row_norms(X - np.column_stack([cen[0][i // b], cen[1][j // b], cen[2][k // b]]))
        near = D[i // b, j // b, k // b] - r <= self.cap + EPS
        q, X = q[near], X[near]
        d = np.full(ask.size, np.inf)
        jn = np.full(ask.size, tree.n, np.int64)
        d[q], jn[q] = tree.query(X, distance_upper_bound=cap, workers=threads() if len(q) >= KD_THREADS else 1)
        far = ~np.isfinite(d)
        self.lb = np.where(far, np.sqrt(max(cap * cap - e2, 0.0)), np.sqrt(np.maximum(d * d - e2, 0.0)))
        self.idx = np.where(far, -1, jn)
        self.stride = np.array([self.shape[1] * self.shape[2], self.shape[2], 1])
        self._offsets = _CORNERS @ self.stride

    @staticmethod
    def spacing(lo: np.ndarray, hi: np.ndarray, spacing: float, pad: float, nodes: int) -> float:
        """The node spacing of a grid over the box (lo, hi) padded by ``pad``: ``spacing``, or
        coarser where that would make more than ``nodes`` nodes."""
        ext = hi - lo + 2 * pad
        return max(float(spacing), float(np.prod(ext) / nodes) ** (1 / 3))

    def _near_blocks(self, tree: cKDTree) -> np.ndarray:
        """Per block of ``BLOCK``^3 nodes: False where every node is proven beyond the cap (no
        sample within cap + the block's half-diagonal + EPS of its centre)."""
        return np.isfinite(self._block_distances(tree)[0])

    def _block_distances(self, tree: cKDTree):
        """(per block of ``BLOCK``^3 nodes the distance from its centre to the nearest sample,
        inf beyond the cap + the block's half-diagonal + EPS; the centres' coordinates per
        axis)."""
        b = self.BLOCK
        nb = -(-self.shape // b)
        half = 0.5 * self.h * (b - 1) * np.sqrt(3.0)
        cen = [self.origin[a] + self.h * (b * np.arange(nb[a]) + 0.5 * (b - 1)) for a in range(3)]
        C = np.stack(np.meshgrid(*cen, indexing="ij"), axis=-1).reshape(-1, 3)
        d, _ = tree.query(C, distance_upper_bound=self.cap + half + EPS,
                          workers=threads() if len(C) >= KD_THREADS else 1)
        return d.reshape(tuple(nb)), cen

    def __call__(self, x: np.ndarray):
        """(lower bound, sample index or -1, inside the grid) at points x: the best over the
        eight nodes around x of the node's bound less the distance to it; the sample is the
        nearest node's. With the compiled kernel (:mod:`~tsplcam.compiled`, the
        same bits) point by point, else ``GRID_ROWS`` points at a time (the (rows, 8)
        temporaries then stay in the processor's cache)."""
        k = compiled.kernels(work=READ_WORK * len(x))
        if k is not None:
            x = np.ascontiguousarray(x, float)
            lb, near, ins = np.empty(len(x)), np.empty(len(x), np.int64), np.empty(len(x), bool)
            k["grid_read"](x, self.origin, self.h, self.shape, self.stride, self._offsets, self.lb,
                           self.idx, lb, near, ins)
            return lb, near, ins
        if len(x) > GRID_ROWS:
            parts = [self._read(x[s:s + GRID_ROWS]) for s in range(0, len(x), GRID_ROWS)]
            return tuple(np.concatenate(c) for c in zip(*parts))
        return self._read(x)

    def _read(self, x: np.ndarray):
        f = (x - self.origin) / self.h
        k0 = np.floor(f).astype(np.int64)
        ins = np.all((k0 >= 0) & (k0 < self.shape - 1), axis=1)
        k0 = np.minimum(np.maximum(k0, 0), self.shape - 2)
        r = f - k0                                                    # (n, 3) in [0, 1)
        base = k0 @ self.stride
        # squared distances to the eight nodes, axis by axis: r^2 to the lower node, (1-r)^2
        # to the upper one (corner order i, j, k as _CORNERS)
        sq = np.stack([r * r, (1.0 - r) * (1.0 - r)], axis=2)        # (n, 3, 2)
        d2 = sq[:, 0, :, None, None] + sq[:, 1, None, :, None] + sq[:, 2, None, None, :]
        dist = self.h * np.sqrt(d2.reshape(len(x), 8))
        lb = (self.lb[base[:, None] + self._offsets] - dist).max(axis=1)
        near = base + (r >= 0.5).astype(np.int64) @ self.stride
        return np.where(ins, lb, 0.0), np.where(ins, self.idx[near], -1), ins


class LazyGrid:
    """Lower bounds of the distance to the mesh at the nodes of a regular grid of spacing
    ``h`` (capped at ``cap``) and the nearest sample of each node, as :class:`DistanceGrid`,
    but unbounded and computed node by node where first read (the eight nodes around each
    point asked): for the side pass's ball centres, a few mm from the mesh in a region no box
    known beforehand describes well. Its KD-tree queries there cost 5-11 us a node; bricks of
    6^3 cells made whole where first read asked about 12 nodes per point read (all-candidates
    on the keycap: 41.5k nodes for 3.5k points), this only the nodes read, with the same
    value at each node (the same query of the same point)."""

    OFF = 1 << 20                    # node coordinates are keyed in 21 bits each

    def __init__(self, tree: cKDTree, e2: float, h: float, cap: float):
        self.tree, self.e2, self.h, self.cap = tree, float(e2), float(h), float(cap)
        self.keys = np.zeros(0, np.int64)          # sorted node keys
        self.lb = np.zeros(0)                      # per key: the bound
        self.idx = np.zeros(0, np.int64)           # per key: the nearest sample (-1 beyond the cap)

    @property
    def nodes(self) -> int:
        return len(self.keys)

    def _values(self, k: np.ndarray):
        """(bound, sample) at the nodes of integer coordinates k (m, 3), computed where new."""
        if len(k) and (np.abs(k).max() >= self.OFF):
            raise ValueError(f"LazyGrid: a point more than {self.OFF * self.h:.0f} mm from the origin")
        o = k + self.OFF
        key = (o[:, 0] << 42) | (o[:, 1] << 21) | o[:, 2]
        # every key looked up in the table (sorted), and only the new ones sorted: most nodes
        # read are known (the eight around each point, shared with its neighbours)
        pos = np.searchsorted(self.keys, key)
        known = np.zeros(len(key), bool)
        if len(self.keys):
            known = self.keys[np.minimum(pos, len(self.keys) - 1)] == key
        new = np.unique(key[~known])
        if len(new):
            nk = np.column_stack([new >> 42, (new >> 21) & ((1 << 21) - 1), new & ((1 << 21) - 1)]) - self.OFF
            d, j = self.tree.query(nk * self.h, distance_upper_bound=self.cap,
                                   workers=threads() if len(new) >= KD_THREADS else 1)
            far = ~np.isfinite(d)
            lb = np.where(far, np.sqrt(max(self.cap * self.cap - self.e2, 0.0)), np.sqrt(np.maximum(d * d - self.e2, 0.0)))
            keys = np.concatenate([self.keys, new])
            order = np.argsort(keys, kind="stable")
            self.keys = keys[order]
            self.lb = np.concatenate([self.lb, lb])[order]
            self.idx = np.concatenate([self.idx, np.where(far, -1, j)])[order]
            pos = np.searchsorted(self.keys, key)
        return self.lb[pos], self.idx[pos]

    def __call__(self, x: np.ndarray):
        """(lower bound, sample index or -1) at points x: as :meth:`DistanceGrid._read`, the best
        over the eight nodes around x of the node's bound less the distance to it."""
        f = x / self.h
        k0 = np.floor(f).astype(np.int64)
        r = f - k0
        lbn, idn = self._values((k0[:, None, :] + _CORNERS[None]).reshape(-1, 3))
        lbn, idn = lbn.reshape(len(x), 8), idn.reshape(len(x), 8)
        sq = np.stack([r * r, (1.0 - r) * (1.0 - r)], axis=2)
        d2 = sq[:, 0, :, None, None] + sq[:, 1, None, :, None] + sq[:, 2, None, None, :]
        dist = self.h * np.sqrt(d2.reshape(len(x), 8))
        lb = (lbn - dist).max(axis=1)
        near = (r >= 0.5).astype(np.int64) @ np.array([4, 2, 1])          # _CORNERS' order
        return lb, idn[np.arange(len(x)), near]


class CentreTable:
    """Per ball centre: a slot found by the centre's exact bytes (sorted keys, vectorised).

    ``ordered``: new slots are numbered in the order of their keys' bytes (the witness cells:
    which witnesses a cell keeps follows that order); else in the order of a 64-bit hash of
    the bytes, which sorts about ten times faster than the 24-byte keys (the ball centres:
    only their identity matters). Every hashed slot is checked against its centre's bytes; the
    table takes the bytes as keys from the first hash that two centres share (never seen)."""

    def __init__(self, ordered: bool = True):
        self.ordered = bool(ordered)
        self.keys = np.zeros(0, np.uint64 if not ordered else np.dtype((np.void, 24)))
        self.slot_of_key = np.zeros(0, np.int64)
        self._rows = np.zeros((0, 3))           # per slot: its centre (while hashed), with room to grow
        self.size = 0
        self._keyed = 0                         # slots in keys (the numpy form's sorted table)
        self._tab = None                        # the kernel's open-addressing table (slot or -1)
        self._tabbed = 0                        # slots in it

    @staticmethod
    def _hash(bits: np.ndarray) -> np.ndarray:
        """A 64-bit hash per row of three 64-bit words (multiply, xor, shift: wrapping)."""
        h = bits[:, 0] * np.uint64(0x9E3779B97F4A7C15)
        h ^= (h >> np.uint64(29)) ^ bits[:, 1]
        h *= np.uint64(0xBF58476D1CE4E5B9)
        h ^= (h >> np.uint64(31)) ^ bits[:, 2]
        h *= np.uint64(0x94D049BB133111EB)
        return h ^ (h >> np.uint64(32))

    @property
    def rows(self) -> np.ndarray:
        """Per slot its centre (while hashed)."""
        return self._rows[:self.size]

    def _exact_keys(self) -> None:
        """Key the table by the centres' bytes from now on (two centres shared a hash)."""
        keys = np.ascontiguousarray(self.rows).view(np.dtype((np.void, 24))).ravel()
        order = np.argsort(keys, kind="stable")
        self.keys, self.slot_of_key = keys[order], order.astype(np.int64)

    def _room(self, end: int) -> None:
        """Room for ``end`` centres in the rows' buffer (doubling: copied a few times, not
        each call)."""
        if end > len(self._rows):
            grown = np.empty((max(end, 2 * len(self._rows)), 3))
            grown[:self.size] = self.rows
            self._rows = grown

    def _slots_kernel(self, k, C: np.ndarray):
        """:meth:`slots` by ``compiled.centre_slots`` (open addressing on the centres' words,
        each slot checked against its centre's): the same slot for the same bytes, new
        centres numbered in the order they come (the numpy form numbers them in its hash's
        order: only which rows share a slot matters to the callers)."""
        end = self.size + len(C)
        if self._tab is None or self._tabbed != self.size or 2 * end > len(self._tab):
            # (room for the runs of equal rows only: a batch asks several axes per centre)
            bits = C.view(np.uint64)
            b0, b1, b2 = bits[:, 0], bits[:, 1], bits[:, 2]
            end = self.size + 1 + int(np.count_nonzero((b0[1:] != b0[:-1]) | (b1[1:] != b1[:-1]) | (b2[1:] != b2[:-1])))
        self._room(end)
        rows = self._rows.view(np.int64)
        if self._tab is None or self._tabbed != self.size or 2 * end > len(self._tab):
            # (made anew from the slots' centres, distinct: they keep their numbers)
            self._tab = np.full(1 << max(4, (4 * end - 1).bit_length()), -1, np.int64)
            if self.size:
                k["centre_slots"](rows[:self.size].copy(), self._tab, rows, np.int64(0),
                                  np.empty(self.size, np.int64), np.empty(self.size, np.int64))
        slot, first = np.empty(len(C), np.int64), np.empty(len(C), np.int64)
        size = int(k["centre_slots"](C.view(np.int64), self._tab, rows, np.int64(self.size), slot, first))
        first = first[:size - self.size]
        self.size = self._tabbed = size
        return slot, first

    def slots(self, C: np.ndarray):
        """(slot per row of C, the new slots' first rows in C). With the kernels loaded and
        the table hashed, by :meth:`_slots_kernel` (about a sixth of the time: the keycap
        replay's 24k new centres 3.8 ms in numpy)."""
        C = np.ascontiguousarray(C, float).reshape(-1, 3)
        hashed = self.keys.dtype == np.uint64
        if self.ordered and len(C) > 1:
            k = compiled.loaded()
            if k is not None:
                # the distinct rows first (the kernel on a table of this call's own, in the
                # order they come), then the bytes' order over those only: the same slots,
                # numbered the same, and each new slot's first row the same
                tab = np.full(1 << max(4, (4 * len(C) - 1).bit_length()), -1, np.int64)
                one, first1 = np.empty(len(C), np.int64), np.empty(len(C), np.int64)
                m = int(k["centre_slots"](C.view(np.int64), tab, np.empty((len(C), 3), np.int64), np.int64(0),
                                          one, first1))
                slot_u, first_u = self._slots_np(C[first1[:m]])
                return slot_u[one], first1[first_u]
        if not self.ordered and hashed:
            k = compiled.loaded()
            if k is not None:
                return self._slots_kernel(k, C)
            if self._keyed != self.size:
                # (slots the kernel added: the sorted keys made anew from the centres)
                keys = self._hash(self.rows.view(np.uint64))
                order = np.argsort(keys)
                self.keys, self.slot_of_key, self._keyed = keys[order], order.astype(np.int64), self.size
                if len(keys) > 1 and (self.keys[1:] == self.keys[:-1]).any():
                    self._exact_keys()            # two centres share a hash
        return self._slots_np(C)

    def _slots_np(self, C: np.ndarray):
        """:meth:`slots` in numpy (C contiguous, (n, 3))."""
        hashed = self.keys.dtype == np.uint64
        bits = C.view(np.uint64)
        # runs of equal rows (a batch asks several axes per centre, one after the other) taken
        # once: sorting costs about 0.4 us a row for the bytes, 0.05 us for a hash
        if len(C) > 1:
            # (column by column: numpy's any over a row of three is slower than two ors)
            b0, b1, b2 = bits[:, 0], bits[:, 1], bits[:, 2]
            step = (b0[1:] != b0[:-1]) | (b1[1:] != b1[:-1]) | (b2[1:] != b2[:-1])
            start = np.flatnonzero(np.concatenate(([True], step)))
        else:
            start = np.arange(len(C))
        runs = bits[start]
        if hashed:
            keys = self._hash(runs)
            order = np.argsort(keys)
            ks = keys[order]
            flag = np.concatenate(([True], ks[1:] != ks[:-1])) if len(ks) else np.zeros(0, bool)
            uk, first = ks[flag], order[flag]
            inv = np.empty(len(keys), np.int64)
            inv[order] = np.cumsum(flag) - 1
            # (every run's centre is its key's: else two centres share a hash; only the runs
            # whose key an earlier run has are compared, the others are their key's first)
            fi = first[inv]
            other = np.flatnonzero(fi != np.arange(len(fi)))
            same = np.array_equal(runs[other], runs[fi[other]])
        else:
            uk, first, inv = np.unique(runs.view(np.dtype((np.void, 24))).ravel(), return_index=True,
                                       return_inverse=True)
        first = start[first]
        inv = np.repeat(inv, np.diff(np.append(start, len(C))))
        if len(self.keys):
            pos = np.searchsorted(self.keys, uk)
            known = (pos < len(self.keys)) & (self.keys[np.minimum(pos, len(self.keys) - 1)] == uk)
        else:
            pos, known = np.zeros(len(uk), np.int64), np.zeros(len(uk), bool)
        slot_u = np.empty(len(uk), np.int64)
        slot_u[known] = self.slot_of_key[pos[known]]
        if hashed and not (same and np.array_equal(self.rows[slot_u[known]].view(np.uint64), bits[first[known]])):
            self._exact_keys()                    # two centres share a hash
            return self._slots_np(C)
        new = np.nonzero(~known)[0]
        slot_u[new] = self.size + np.arange(len(new))
        if len(new):
            if hashed:
                end = self.size + len(new)
                self._room(end)
                self._rows[self.size:end] = C[first[new]]
            self.size += len(new)
            if hashed:
                # uk is sorted: its new keys go in at their positions, the table stays sorted
                at = pos[new] + np.arange(len(new))
                old = np.ones(len(self.keys) + len(new), bool)
                old[at] = False
                keys_all = np.empty(len(old), np.uint64)
                keys_all[at], keys_all[old] = uk[new], self.keys
                slots_all = np.empty(len(old), np.int64)
                slots_all[at], slots_all[old] = slot_u[new], self.slot_of_key
                self.keys, self.slot_of_key = keys_all, slots_all
            else:
                keys_all = np.concatenate([self.keys, uk[new]])
                order = np.argsort(keys_all, kind="stable")
                self.keys = keys_all[order]
                self.slot_of_key = np.concatenate([self.slot_of_key, slot_u[new]])[order]
        self._keyed = self.size
        return slot_u[inv], first[new]


class BroadPhase:
    """Decisions for batches of poses against one triangle mesh (see the module doc).

    ``profile(grow)`` gives the tool as fcl sees it with ``grow`` mm more (the checker's
    margins already in); ``r0``: radius of the gouge check's ball; ``e_cap``: longest
    sample spacing (mm) along the triangles (default: the median of the triangles' longest
    edges; longer triangles get points inside)."""

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, profile, r0: float,
                 e_cap: float | None = None):
        V = np.asarray(vertices, float)
        T = np.asarray(triangles, np.int64)
        V, T = np.ascontiguousarray(V), np.ascontiguousarray(T)
        self.V, self.T = V, T
        if e_cap is None:
            edge = longest_edges(V, T) if len(T) else np.ones(1)
            e_cap = max(0.1, float(np.quantile(edge, 0.5)))
        self.samples, tri_of, self.e, sub = mesh_samples(V, T, e_cap)
        self.e2 = self.e * self.e / 3.0
        self.tri_e2 = sub * sub / 3.0             # per triangle: its own e^2 / 3 (the band pass)
        self.tree = SampleTree(self.samples)
        # triangles to measure exactly per sample: a vertex's incident ones, else its own, as
        # runs of one flat array (sample k's: tris_flat[tris_start[k]:tris_start[k + 1]]; a
        # table as wide as the most triangles at one vertex costs 0.3 GB and a second to fill
        # on the impeller, whose hub pole has 180)
        nv = len(V)
        inc_n = np.bincount(T.ravel(), minlength=nv) if len(T) else np.zeros(nv, int)
        extra = tri_of >= 0
        count = np.zeros(len(self.samples), np.int64)
        count[:nv] = inc_n
        count[extra] = 1
        self.tris_start = np.concatenate([[0], np.cumsum(count)])
        self.tris_flat = np.empty(int(self.tris_start[-1]), np.int64)
        if len(T):
            # each vertex's corners in the order of the flat index (triangle * 3 + corner): the
            # vertices are the first samples, so their runs are the sorted corners in order
            # (vertex numbers below 2^16 as uint16: numpy sorts those stably by radix, the same
            # order, 1.5 -> 0.4 ms on the keycap's 115k corners)
            key = T.ravel()
            order = np.argsort(key.astype(np.uint16) if nv <= 1 << 16 else key, kind="stable")
            self.tris_flat[:len(order)] = order // 3
        self.tris_flat[self.tris_start[:-1][extra]] = tri_of[extra]
        # unit normals of the triangles (0 for a degenerate one: its plane test never skips it)
        nrm = cross_rows(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]) if len(T) else np.zeros((0, 3))
        ln = row_norms(nrm)
        self.tri_normal = np.where((ln > 1e-300)[:, None], nrm / np.where(ln > 1e-300, ln, 1.0)[:, None], 0.0)
        comp = mesh_components(nv, T)
        first_corner = T[np.maximum(tri_of, 0), 0] if len(T) else np.zeros(len(tri_of), int)
        self.sample_comp = comp[np.where(extra, first_corner, np.arange(len(self.samples)))]
        # anchors: per component its vertices extreme along 26 directions
        ncomp = int(comp.max()) + 1 if len(comp) else 0
        proj = V @ DIRECTIONS.T
        self.anchors = np.zeros((ncomp, len(DIRECTIONS), 3))
        order = np.argsort(comp, kind="stable")
        starts = np.searchsorted(comp[order], np.arange(ncomp))
        ends = np.append(starts[1:], len(order))
        for c in range(ncomp):                                   # components are few
            idx = order[starts[c]:ends[c]]
            self.anchors[c] = V[idx[np.argmax(proj[idx], axis=0)]]
        self.profile = profile
        self.r0 = float(r0)
        lo, hi = self.samples.min(axis=0), self.samples.max(axis=0)
        self.box = (lo, hi)
        reach = profile(0.0).reach
        h = DistanceGrid.spacing(lo, hi, FINE[0], 3.0, FINE[1])
        if h > FINE[0]:                            # a large part: pad and cap with the spacing
            fine = DistanceGrid(self.tree, self.e2, lo, hi, h, 8 * h, 4 * h, FINE[1])
        else:
            fine = DistanceGrid(self.tree, self.e2, lo, hi, FINE[0], 3.0, 1.5, FINE[1])
        self.grids = [fine, DistanceGrid(self.tree, self.e2, lo, hi, COARSE[0], reach + COARSE[0],
                                         10 * COARSE[0], COARSE[1])]
        self._covers: dict[float, SphereCover] = {}
        self._side_grid = None                    # LazyGrid, made when the side pass first needs it
        self._stacked = None                      # the grids' arrays for the compiled sphere loop
        self.centres = CentreTable(ordered=False)
        self._gouge = np.zeros(0, np.int8)        # per centre: 1 clear, 0 not proven, -1 not asked yet
        self._cone_a = {}                         # per grow: (slots, CONES, 3) axes
        self._cone_c = {}                         # per grow: (slots, CONES) cos of the cone angle
        self._wit_cells = CentreTable()
        self._wit = np.zeros((0, WITNESSES), np.int64)
        self._exact_gain = (0.0, 0.0)             # poses decided, spheres asked (_exact_pass)
        self._sample_e2 = None                    # per sample: its triangles' largest e_t^2 / 3
        self._cyl_cells = None                    # the samples by cells of the cylinder pass
        # the samples by cells (_band_table): made with the grids where this process has the
        # kernels already, else at the first band they answer (never in numpy alone: 0.8 s
        # for 2 M samples)
        self._band_cells = None
        if len(self.samples) and compiled.loaded() is not None:
            self._band_table()
        self.stats = {"poses": 0, "free": 0, "hit": 0, "unknown": 0, "cone": 0, "witness": 0,
                      "queries": 0, "exact": 0, "band": 0, "cylinder": 0}

    # --- distances ------------------------------------------------------------------------
    def lower_bound(self, x: np.ndarray, need=None):
        """(lower bound of the distance to the mesh, a sample near x or -1, x inside the fine
        grid) at points x: the best bound of the two grids and the box of the mesh; the sample
        is the nearest one to x's nearest node in the fine grid, else in the coarse grid.
        ``need``: where the fine grid's bound reaches it, the coarse grid is not asked."""
        lo, hi = self.box
        o = np.maximum(np.maximum(lo - x, x - hi), 0.0)
        lb = np.sqrt(o[:, 0] * o[:, 0] + o[:, 1] * o[:, 1] + o[:, 2] * o[:, 2])
        lbf, idx, ins = self.grids[0](x)
        lb = np.maximum(lb, lbf)
        ask = slice(None) if need is None else np.nonzero(lb < need)[0]
        lbc, idc, _ = self.grids[1](x[ask])
        lb[ask] = np.maximum(lb[ask], lbc)
        idx[ask] = np.where(idx[ask] >= 0, idx[ask], idc)
        return lb, idx, ins

    def nearest(self, x: np.ndarray, ub: np.ndarray, k: int = 1, rows=None):
        """(distances, indices) of the k nearest samples to each x, inf / n where none is
        closer than ``ub`` (per point; the tree takes one bound per call, so the points are
        grouped by bounds within a factor of two, each group asked with its largest).
        ``rows``: only these points are asked (the others left inf / n), each with its
        group's bound over every point, so each gets the answer of the call without ``rows``
        (the tree's choice among ties too)."""
        shape = (len(x),) if k == 1 else (len(x), k)
        d = np.full(shape, np.inf)
        j = np.full(shape, len(self.samples))
        ask = np.arange(len(x)) if rows is None else np.asarray(rows, np.int64)
        self.stats["queries"] += len(ask)
        if len(ask) == 0:
            return d, j
        grp = np.floor(np.log2(np.clip(ub, 1e-9, 1e12))).astype(int)
        for g in np.unique(grp[ask]):
            sel = ask[grp[ask] == g]
            bound = float(ub[sel].max() if rows is None else ub[grp == g].max())
            d[sel], j[sel] = self.tree.query(x[sel], k=k, distance_upper_bound=bound,
                                             workers=threads() if len(sel) >= KD_THREADS else 1)
        return d, j

    def exact_bound(self, o: np.ndarray, R: np.ndarray, nearest: bool = False):
        """Lower bounds of the distance from points o to the mesh, exact below R: every
        triangle that reaches within R of o has a corner or sample in the band
        sqrt(R^2 + e^2/3) (module doc); with none there the distance is at least R, with
        fewer than ``BAND`` there their triangles are measured exactly, with more the nearest
        sample's bound stands. ``nearest``: also the nearest sample in the band (or -1)."""
        R = np.asarray(R, float)
        ub = np.sqrt(R * R + self.e2)
        out = R.copy()
        near = np.full(len(o), -1, np.int64)
        # a band wider than a few sample spacings holds more than BAND samples wherever it
        # meets the mesh: there the nearest sample is enough
        wide = R > 4.0 * self.e
        if wide.any():
            w = np.nonzero(wide)[0]
            d1, j1 = self.nearest(o[w], ub[w])
            inb = d1 < ub[w]
            out[w] = np.where(inb, np.sqrt(np.maximum(d1 * d1 - self.e2, 0.0)), R[w])
            near[w] = np.where(inb, j1, -1)
        nw = np.nonzero(~wide)[0]
        if len(nw):
            d0, j0, full, rows, js = self._band(o[nw], ub[nw])
            near[nw] = np.where(d0 < ub[nw], j0, -1)
            out[nw[full]] = np.sqrt(np.maximum(d0[full] ** 2 - self.e2, 0.0))
            if len(rows):
                r2, ti = self._triangles_of(js)
                self._measure_into(out, o, R, nw[rows[r2]], ti)
        return (out, near) if nearest else out

    def _band(self, x: np.ndarray, ub: np.ndarray):
        """The samples within ``ub`` of each point x, as :meth:`exact_bound` uses them: (the
        nearest one's distance, its index, whether ``BAND`` or more lie in the band, and where
        fewer do, each one as (point, sample) pairs). By the kd-tree's ``BAND`` nearest, or
        with the kernels by ``compiled.band_samples`` on a table of cells (about 0.3 us a
        point against 2 on the keycap's exact pass, where most bands hold no sample): the
        same distances bit for bit, the same sets; where two samples tie for the nearest the
        tree's choice is taken (asked of it)."""
        k = compiled.kernels(work=BAND_WORK * len(x)) if len(self.samples) else None
        if k is None:
            d, j = self.nearest(x, ub, k=BAND)
            inb = d < ub[:, None]
            full = inb.all(axis=1)
            rows, cols = np.nonzero(inb & ~full[:, None])
            return d[:, 0], j[:, 0], full, rows, j[rows, cols]
        origin, h, shape, start, items, pts = self._band_table()
        m = len(x)
        d0, j0 = np.empty(m), np.empty(m, np.int64)
        cnt, lst, tie = np.empty(m, np.int64), np.empty((m, BAND), np.int64), np.empty(m, bool)
        k["band_samples"](np.ascontiguousarray(x, float), np.ascontiguousarray(ub, float), pts, items, start,
                          origin, h, shape, np.int64(BAND), d0, j0, cnt, lst, tie)
        t = np.nonzero(tie & (d0 < ub))[0]
        self.stats["queries"] += m - len(t)                  # (the ties counted by nearest())
        if len(t):
            j0[t] = self.nearest(x, ub, k=BAND, rows=t)[1][t, 0]
        full = cnt >= BAND
        rows, cols = np.nonzero(lst >= 0)
        keep = ~full[rows]
        return d0, j0, full, rows[keep], lst[rows[keep], cols[keep]]

    def _band_table(self):
        """The samples sorted into cubic cells of ``BAND_CELL`` sample spacings (fewer, larger
        cells on a part that would need more than ``BAND_CELLS``), for ``band_samples``:
        (origin, edge, shape, each cell's first row, the samples' indices, their points)."""
        if self._band_cells is None:
            self._band_cells = compiled.cell_table(self.samples, BAND_CELL * self.e, BAND_CELLS)
        return self._band_cells

    def _triangles_of(self, js: np.ndarray):
        """The triangles of samples ``js`` (a vertex's incident ones, another sample's own):
        (position in ``js``, triangle) pairs."""
        cnt = self.tris_start[js + 1] - self.tris_start[js]
        at = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt) + np.repeat(self.tris_start[js], cnt)
        return np.repeat(np.arange(len(js)), cnt), self.tris_flat[at]

    def _measure_into(self, out: np.ndarray, x: np.ndarray, R: np.ndarray, row: np.ndarray, ti: np.ndarray) -> None:
        """Lower ``out[row]`` to the exact distance from ``x[row]`` to triangle ``ti``, each pair
        once (neighbouring samples share their triangles). A triangle whose plane lies
        PLANE_SLACK farther than ``R[row]`` cannot lower a bound below R: only the others are
        measured (the same minima, for a fifth of the work next to the gouge check's balls).
        With the compiled kernels pair by pair (``measure_pairs``: the same distances bit for
        bit, without the pairs' temporaries: the keycap's gouge check 13 -> 1 ms in its forked
        process, whose page faults they were); ``out`` is written in place either way."""
        k = compiled.kernels(work=MEASURE_WORK * len(row)) if len(row) else None
        if k is not None and out.dtype == np.float64 and out.flags.c_contiguous and out.flags.writeable:
            R = np.ascontiguousarray(np.broadcast_to(R, (len(x),)), float)
            k["measure_pairs"](np.ascontiguousarray(x, float), R, self.V, self.T, self.tri_normal,
                               np.ascontiguousarray(row, np.int64), np.ascontiguousarray(ti, np.int64),
                               PLANE_SLACK, out)
            return
        key = np.unique(row * len(self.T) + ti)
        q, ti = key // len(self.T), key % len(self.T)
        tt = self.T[ti]
        gap = np.abs(_dot_xyz(x[q] - self.V[tt[:, 0]], self.tri_normal[ti]))
        near_plane = np.nonzero(gap < R[q] + PLANE_SLACK)[0]
        q, tt = q[near_plane], tt[near_plane]
        P = closest_on_triangles(x[q], self.V[tt[:, 0]], self.V[tt[:, 1]], self.V[tt[:, 2]])
        min_into(out, q, row_norms(P - x[q]))

    def _clear_exact(self, o: np.ndarray, R: np.ndarray) -> np.ndarray:
        """True where the ball B(o, R) is shown to hold no part of the mesh."""
        return self.exact_bound(o, R + EPS) >= R + EPS

    def band_clear(self, o: np.ndarray, R: np.ndarray) -> np.ndarray:
        """True where no point of the mesh lies closer than R to o: not where a sample (a point of
        the mesh) lies inside the ball (its nearest sample, one KD query; a wide ball through a
        fine mesh holds thousands, none of them worth measuring), else by :meth:`band_distance`,
        whose band then holds only the samples between R and sqrt(R^2 + e^2/3)."""
        o = np.asarray(o, float).reshape(-1, 3)
        R = np.broadcast_to(np.asarray(R, float), (len(o),))
        d, _ = self.nearest(o, R)
        rest = np.nonzero(~(d < R))[0]
        clear = np.zeros(len(o), bool)
        clear[rest] = self.band_distance(o[rest], R[rest]) >= R[rest]
        return clear

    def band_distance(self, o: np.ndarray, R: np.ndarray) -> np.ndarray:
        """The distance from points o to the mesh where it is below R (exact), else R: every
        sample of the band sqrt(R^2 + e^2/3), however many (:meth:`exact_bound` stops at
        ``BAND``), and of their triangles those that can reach within R measured exactly. A
        triangle reaches within R of o only through a sample of it (a corner, or a point of its
        subdivision) at most sqrt(R^2 + e_t^2/3) from o, e_t its own subtriangles' longest edge
        (module doc), so a sample farther than that from o is passed over for triangle t: next
        to the dense strips of small triangles at a crease nearly all of them are. Samples
        inside the ball are measured too (:meth:`band_clear` asks only where there are none)."""
        o = np.asarray(o, float).reshape(-1, 3)
        R = np.broadcast_to(np.asarray(R, float), (len(o),))
        out = R.copy()
        if len(o) == 0 or len(self.T) == 0:
            return out
        self._sample_e2_table()
        lo, rows = 0, BAND_ROWS[0]
        while lo < len(o):
            x, r = o[lo:lo + rows], R[lo:lo + rows]
            r2 = r * r + 1e-9 * (1.0 + r * r)      # (a hair wider: rounding of the squares)
            lists = self.tree.ref.query_ball_point(x, np.sqrt(r * r + self.e2) * (1.0 + 1e-9), return_sorted=False)
            cnt = np.fromiter(map(len, lists), np.int64, len(lists))
            # the next points as many as keep the samples' lists about BAND_ROWS[2] long (a wide
            # ball next to a fine mesh holds thousands)
            nxt = int(BAND_ROWS[2] * len(x) / max(1, int(cnt.sum())))
            js = np.fromiter(itertools.chain.from_iterable(lists), np.int64, int(cnt.sum()))
            row = np.repeat(np.arange(len(x)), cnt)
            w = self.samples[js] - x[row]
            d2 = w[:, 0] * w[:, 0] + w[:, 1] * w[:, 1] + w[:, 2] * w[:, 2]
            near = np.nonzero(d2 <= r2[row] + self._sample_e2[js])[0]
            k, ti = self._triangles_of(js[near])
            row, d2 = row[near][k], d2[near][k]
            keep = np.nonzero(d2 <= r2[row] + self.tri_e2[ti])[0]
            self._measure_into(out[lo:lo + rows], x, r, row[keep], ti[keep])
            lo += rows
            rows = min(max(nxt, BAND_ROWS[0]), BAND_ROWS[1])
        return out

    # --- per ball centre: gouge check, cones ----------------------------------------------------
    def _slots(self, C: np.ndarray) -> np.ndarray:
        """Slots of the centres C, with the gouge verdicts of the new ones."""
        slot, first = self.centres.slots(C)
        if len(first):
            self._gouge = np.concatenate([self._gouge, np.full(len(first), -1, np.int8)])
            for g in self._cone_a:
                self._grow_cones(g)
        return slot

    def _grow_cones(self, grow: float):
        a = self._cone_a.setdefault(grow, np.zeros((0, CONES, 3)))
        c = self._cone_c.setdefault(grow, np.zeros((0, CONES)))
        m = self.centres.size - len(a)
        if m > 0:
            self._cone_a[grow] = np.concatenate([a, np.zeros((m, CONES, 3))])
            self._cone_c[grow] = np.concatenate([c, np.full((m, CONES), 2.0)])   # cos > 1: none

    def ball_free(self, C: np.ndarray) -> np.ndarray:
        """True where the gouge check's ball (radius r0) at C is proven clear of the mesh."""
        C = np.asarray(C, float).reshape(-1, 3)
        slot = self._slots(C)
        ask = self._gouge[slot] < 0
        if ask.any():                             # measured once per centre, when first asked
            su, first = np.unique(slot[ask], return_index=True)
            Cn = C[np.nonzero(ask)[0][first]]
            clear = self._clear_exact(Cn, np.full(len(Cn), self.r0))
            if not clear.all():                   # next to a surface: every sample of the band
                rest = np.nonzero(~clear)[0]
                R = np.full(len(rest), self.r0 + EPS)
                clear[rest] = self.band_clear(Cn[rest], R)
                self.stats["band"] += len(rest)
            self._gouge[su] = clear
        return self._gouge[slot] == 1

    # --- poses ---------------------------------------------------------------------------------
    def _sample_e2_table(self) -> np.ndarray:
        """Per sample the largest e_t^2 / 3 of its triangles (made when first asked)."""
        if self._sample_e2 is None:
            cnt = self.tris_start[1:] - self.tris_start[:-1]
            self._sample_e2 = np.zeros(len(self.samples))
            has = np.nonzero(cnt > 0)[0]
            if len(has):
                self._sample_e2[has] = np.maximum.reduceat(self.tri_e2[self.tris_flat], self.tris_start[has])
        return self._sample_e2

    def _cover(self, grow: float) -> SphereCover:
        cov = self._covers.get(grow)
        if cov is None:
            cov = self._covers[grow] = SphereCover(self.profile(grow))
        return cov

    @staticmethod
    def _tool_frame(q, C, A):
        """(height along the axis, squared distance from it) of points q at poses (C, A)."""
        w = q - C
        z = _dot(w, A)
        return z, np.maximum(_dot(w, w) - z * z, 0.0)

    def _inside(self, q, C, A, prof: Profile, parts: int = -1) -> np.ndarray:
        """Points q strictly inside some part's inscribed frustum at poses (C, A), of the parts
        in the bit mask ``parts`` (-1 all)."""
        z, rad2 = self._tool_frame(q, C, A)
        out = np.zeros(z.shape, bool)
        for k in range(len(prof.z0)):
            if not (parts >> k) & 1:
                continue
            r = prof.rin(k, np.clip(z, prof.z0[k], prof.z1[k])) - EPS
            out |= (z >= prof.z0[k] + EPS) & (z <= prof.z1[k] - EPS) & (rad2 < r * r)
        return out

    def _outside(self, q, C, A, prof: Profile) -> np.ndarray:
        """Points q strictly outside every part's circumscribed frustum at poses (C, A)."""
        z, rad2 = self._tool_frame(q, C, A)
        out = np.ones(z.shape, bool)
        for k in range(len(prof.z0)):
            r = prof.rout(k, np.clip(z, prof.z0[k], prof.z1[k])) + EPS
            out &= (z < prof.z0[k] - EPS) | (z > prof.z1[k] + EPS) | (rad2 > r * r)
        return out

    def _hits(self, status, q, j, pose, C, A, prof, parts: int = -1) -> np.ndarray:
        """Mark HIT the poses where sample q (index j) lies inside the tool and its piece of
        the mesh reaches outside the tool (module doc): the piece's anchors are tried one
        direction at a time until one lies outside. Returns the witnesses (pose, sample)."""
        live = status[pose] != HIT
        q, j, pose = q[live], j[live], pose[live]
        if len(pose) == 0:
            return np.zeros((0, 2), np.int64)
        k = compiled.kernels(work=HIT_WORK * len(pose))
        if k is not None:
            found = np.empty((len(pose), 2), np.int64)
            j = np.ascontiguousarray(j, np.int64)
            pose = np.ascontiguousarray(pose, np.int64)
            nf = k["hit_pairs"](self.samples, j, pose, np.argsort(pose, kind="stable"),
                                np.ascontiguousarray(C, float), np.ascontiguousarray(A, float),
                                prof.z0, prof.z1, prof.rin0, prof.rin1, prof.rout0, prof.rout1, np.int64(parts),
                                self.sample_comp, self.anchors, EPS, status, found)
            return found[:nf]
        cand = self._inside(q, C[pose], A[pose], prof, parts)
        if not cand.any():
            return np.zeros((0, 2), np.int64)
        # distinct (pose, component, sample) rows in row order, then the first of each (pose,
        # component): one int64 key per row (np.unique(axis=0) sorts structured rows, 3x slower)
        ns, nc = len(self.samples), len(self.anchors)
        key = np.unique((pose[cand] * nc + self.sample_comp[j[cand]]) * ns + j[cand])
        key = key[np.unique(key // ns, return_index=True)[1]]
        pairs = np.column_stack([key // ns // nc, key // ns % nc, key % ns])
        found = []
        for a in range(len(DIRECTIONS)):
            out = self._outside(self.anchors[pairs[:, 1], a], C[pairs[:, 0]], A[pairs[:, 0]], prof)
            status[pairs[out, 0]] = HIT
            found.append(pairs[out][:, [0, 2]])
            pairs = pairs[status[pairs[:, 0]] != HIT]
            if len(pairs) == 0:
                break
        return np.concatenate(found)

    def _witness_cells(self, C: np.ndarray) -> np.ndarray:
        """The witness cell (slot) of each ball centre. A run of equal centres (a batch asks
        several axes per centre in a row: the all-candidates batch 182k rows in 1.5k runs) is
        one cell, floored and looked up once: the same cells, numbered the same (the table
        numbers new cells in the order of their bytes, whatever rows they come in)."""
        C = np.ascontiguousarray(C, float).reshape(-1, 3)
        if len(C) > 1:
            bits = C.view(np.uint64)
            b0, b1, b2 = bits[:, 0], bits[:, 1], bits[:, 2]
            start = np.flatnonzero(np.concatenate(([True], (b0[1:] != b0[:-1]) | (b1[1:] != b1[:-1])
                                                   | (b2[1:] != b2[:-1]))))
        else:
            start = np.arange(len(C))
        slot, first = self._wit_cells.slots(np.floor((C if len(start) == len(C) else C[start]) / WITNESS_CELL))
        if len(first):
            self._wit = np.concatenate([self._wit, np.full((len(first), WITNESSES), -1, np.int64)])
        return slot if len(start) == len(C) else np.repeat(slot, np.diff(np.append(start, len(C))))

    def _remember(self, cell: np.ndarray, found: np.ndarray):
        """Keep the samples of new hits as witnesses of their poses' cells (newest first)."""
        if len(found) == 0:
            return
        cs, samp = cell[found[:, 0]], found[:, 1]
        ns = len(self.samples)
        # distinct (cell, sample) pairs, the last few: a handful per call is enough
        key = np.unique(cs * ns + samp)[-4 * WITNESSES:]
        cells = key // ns
        rows = {c: r for c, r in zip(cells.tolist(), self._wit[cells].tolist())}
        for c, s in zip(cells.tolist(), (key % ns).tolist()):
            row = rows[c]
            if s not in row:
                rows[c] = [s] + row[:-1]
        at = list(rows)
        self._wit[at] = [rows[c] for c in at]

    def part_lower_bounds(self, C: np.ndarray, A: np.ndarray, level: int = 3) -> np.ndarray:
        """(poses, parts): lower bounds of each part's distance to the mesh (its spheres at
        ``level``, each a bound at its centre less its radius; 0 where they touch)."""
        C = np.asarray(C, float).reshape(-1, 3)
        A = np.asarray(A, float).reshape(-1, 3)
        cov = self._cover(0.0)
        K = len(cov.prof.z0)
        nseg = 2 ** level
        pose = np.repeat(np.arange(len(C)), K * nseg)
        part = np.tile(np.repeat(np.arange(K), nseg), len(C))
        seg = np.tile(np.arange(nseg), len(C) * K)
        zc, s, _ = cov.spheres(part, level, seg)
        x = C[pose] + zc[:, None] * A[pose]
        lb, _, _ = self.lower_bound(x)
        return np.maximum(lb - s, 0.0).reshape(len(C), K, nseg).min(axis=2)

    def _store_cones(self, slot, A, c, grow, rows=None):
        """Keep cone (axis A, cos of its angle c) at each slot, replacing the slot's narrowest;
        ``rows``: the axes are ``A[rows]`` (taken there by the kernel, not gathered)."""
        cone_a, cone_c = self._cone_a[grow], self._cone_c[grow]
        k = compiled.loaded()
        if k is not None and len(slot):
            # row by row, each slot at most twice (the kernel's doc: the same cones, in place)
            rows = np.arange(len(slot)) if rows is None else np.ascontiguousarray(rows, np.int64)
            k["store_cones"](np.ascontiguousarray(slot, np.int64), rows, np.ascontiguousarray(A, float),
                             np.ascontiguousarray(c, float), np.int64(2), cone_a, cone_c)
            return
        if rows is not None:
            A = A[rows]
        for _ in range(2):                        # a slot may come twice in one batch
            # (np.argmax over a row of CONES, column by column: the first largest)
            cs = cone_c[slot]
            worst = np.zeros(len(slot), np.int64)
            most = cs[:, 0]
            for k in range(1, cs.shape[1]):
                up = cs[:, k] > most
                worst[up] = k
                most = np.where(up, cs[:, k], most)
            better = c < most
            sel = np.nonzero(better)[0][first_of_each(slot[better])]
            cone_a[slot[sel], worst[sel]] = A[sel]
            cone_c[slot[sel], worst[sel]] = c[sel]
            keep = np.ones(len(slot), bool)
            keep[sel] = False
            slot, A, c = slot[keep], A[keep], c[keep]
            if len(slot) == 0:
                break

    def _exact_pass(self, C, A, cov: SphereCover, status, unresolved, phi, cell, parts: int = -1):
        """The parts the grids left unresolved, asked again with exact bounds
        (:meth:`exact_bound`: the samples, and near the mesh their triangles), level by level
        from one sphere per part: a sphere is split while no smaller one is known to fail
        (its bound plus half the slab below the slab's narrow end). A pose is given up (to
        fcl, its parts as they were) at its first sphere that cannot clear; the nearest
        samples of failing spheres are tried as hits. Updates ``status``, ``unresolved`` and
        the free cones ``phi`` in place."""
        # not next to a wall that stopped poses before (a hit witness in the centre's cell):
        # there most poses collide, and fcl settles them in fewer steps
        near_wall = any_row(self._wit >= 0)[cell]
        pose, part = nonzero_pairs(unresolved, (status != HIT) & ~near_wall)
        # only while it pays: a pose fcl answers costs about as much as EXACT_COST spheres
        # here; the pass stops while the last calls decided fewer poses per sphere (decayed
        # sums, so it is tried again later; the answers are the same either way)
        decided, asked = self._exact_gain
        if len(pose) == 0 or (asked > EXACT_PROBE and decided * EXACT_COST < asked):
            self._exact_gain = (0.5 * decided, 0.5 * asked)
            return
        members = pose[first_of_each(pose)]        # (np.nonzero's rows: sorted)
        # in groups of doubling size (few, 2 few, 4 few ...), stopped at the first group after
        # which the call's poses decided no longer pay for its spheres: the poses of a batch
        # come in the order the caller made them, and where the pass stops paying it seldom
        # pays again further on (keycap_mold: 20.8k spheres instead of 52.1k, for 5% more fcl)
        few = EXACT_PROBE // 10
        edges = [0]
        while edges[-1] < len(members):
            edges.append(min(len(members), edges[-1] + few * 2 ** (len(edges) - 1)))
        got = spent = 0
        for k in range(len(edges) - 1):
            if k and got * EXACT_COST < spent:                 # the poses so far did not pay
                break
            grp = members[edges[k]:edges[k + 1]]
            sel = slice(np.searchsorted(pose, grp[0]), np.searchsorted(pose, grp[-1], "right"))
            g, a = self._exact_run(C, A, cov, status, unresolved, phi, cell, pose[sel], part[sel], grp, parts)
            got, spent = got + g, spent + a
        self._exact_gain = (0.5 * decided + got, 0.5 * asked + spent)

    def _exact_run(self, C, A, cov, status, unresolved, phi, cell, pose, part, members, parts: int = -1):
        """One run of the exact pass over the (pose, part) pairs given, all of the poses
        ``members``; returns (poses decided, spheres asked)."""
        prof = cov.prof
        before = int((status[members] == HIT).sum())
        asked0 = self.stats["exact"]
        lost = np.zeros(len(C), bool)
        seg = np.zeros(len(pose), np.int64)
        level = 0
        while len(pose):
            zc, s, _ = cov.spheres(part, level, seg)
            half = 0.5 * (prof.z1[part] - prof.z0[part]) / 2 ** level
            rmin = np.minimum(prof.rout(part, zc - half), prof.rout(part, zc + half))
            x = C[pose] + zc[:, None] * A[pose]
            eb, near = self.exact_bound(x, s + EPS, nearest=True)
            self.stats["exact"] += len(x)
            cert = eb >= s + EPS
            ok = np.nonzero(cert)[0]
            min_into(phi, pose[ok], (eb[ok] - s[ok] - EPS) / zc[ok])
            bad = np.nonzero(~cert)[0]
            has = bad[near[bad] >= 0]
            if len(has):
                found = self._hits(status, self.samples[near[has]], near[has], pose[has], C, A, prof, parts)
                self._remember(cell, found)
            hopeless = bad[(eb[bad] + half[bad] < rmin[bad] + EPS)
                           | (level >= np.minimum(cov.max_level[part[bad]], EXACT_LEVELS))]
            lost[pose[hopeless]] = True
            keep = np.zeros(len(pose), bool)
            keep[bad] = True
            keep &= ~lost[pose] & (status[pose] != HIT)
            m = int(keep.sum())
            pose, part = np.repeat(pose[keep], 2), np.repeat(part[keep], 2)
            seg = 2 * np.repeat(seg[keep], 2) + np.tile([0, 1], m)
            level += 1
        done = members[any_row(unresolved[members]) & ~lost[members] & (status[members] != HIT)]
        unresolved[done] = False
        return len(done) + int((status[members] == HIT).sum()) - before, self.stats["exact"] - asked0

    def _sphere_loop(self, C, A, cov: SphereCover, todo, asked, parts, status, unresolved, phi, cell):
        """The sphere cover of the poses ``todo`` (parts ``asked``), level by level over all
        of them: a sphere the grids clear narrows the pose's free cone ``phi``; one they do not
        is split while a smaller one might clear, else its part is left ``unresolved``; the
        grid nodes' samples of failing spheres are tried as hits. Updates ``status``,
        ``unresolved`` and ``phi`` in place (:meth:`_sphere_kernel` is the same, compiled)."""
        prof = cov.prof
        pose = np.repeat(todo, len(asked))
        part = np.tile(asked, len(todo))
        seg = np.zeros(len(pose), np.int64)
        level = 0
        while len(pose):
            zc, s, rmax = cov.spheres(part, level, seg)
            x = C[pose] + zc[:, None] * A[pose]
            # (the coarse grid only where the fine one leaves less than a cone of CONE_WANT)
            bound, jg, _ = self.lower_bound(x, s + EPS + CONE_WANT * zc)
            cert = bound >= s + EPS
            split = np.zeros(len(pose), bool)
            rest = np.nonzero(~cert)[0]
            if len(rest):
                # the grid node's sample: inside the tool (hit)
                jr = jg[rest]
                has = jr >= 0
                found = self._hits(status, self.samples[jr[has]], jr[has], pose[rest[has]], C, A, prof, parts)
                self._remember(cell, found)
                # the sphere is split while it can be, and a pose left with spheres the grids
                # cannot clear is asked again with exact bounds (_exact_pass), else of fcl
                hopeless = bound[rest] < rmax[rest] + EPS      # no smaller sphere can clear
                unresolved[pose[rest[hopeless]], part[rest[hopeless]]] = True
                split[rest[~hopeless]] = True
            ok = np.nonzero(cert)[0]
            min_into(phi, pose[ok], (bound[ok] - s[ok] - EPS) / zc[ok])
            keep = split & (status[pose] != HIT) & ~unresolved[pose, part]
            last = keep & (level >= cov.max_level[part])
            unresolved[pose[last], part[last]] = True
            keep &= ~last
            m = int(keep.sum())
            pose, part = np.repeat(pose[keep], 2), np.repeat(part[keep], 2)
            seg = 2 * np.repeat(seg[keep], 2) + np.tile([0, 1], m)
            level += 1

    def _grid_arrays(self):
        """The two distance grids' parameters stacked and their nodes concatenated, for the
        compiled sphere loop."""
        if self._stacked is None:
            g = self.grids
            self._stacked = (np.array([x.origin for x in g], float), np.array([x.h for x in g], float),
                             np.array([x.shape for x in g], np.int64), np.array([x.stride for x in g], np.int64),
                             np.array([x._offsets for x in g], np.int64),
                             np.array([0, len(g[0].lb)], np.int64), np.concatenate([x.lb for x in g]),
                             np.concatenate([x.idx for x in g]).astype(np.int64))
        return self._stacked

    def _sphere_kernel(self, kern, C, A, cov: SphereCover, todo, asked, parts, status, unresolved, phi, cell):
        """:meth:`_sphere_loop` by the compiled kernel (``compiled.sphere_loop``: pose by pose,
        the same operations per sphere, so the same bits); the hits' witnesses are remembered
        level by level as the loop does."""
        prof = cov.prof
        C = np.ascontiguousarray(C, float)
        A = np.ascontiguousarray(A, float)
        lo, hi = self.box
        todo = np.ascontiguousarray(todo, np.int64)
        # the kernel takes the poses one by one, each writing only its own rows: two halves of
        # them on two threads (the kernel releases the GIL) give the same rows, and the hits'
        # witnesses, remembered level by level as a set, the same table (a kernel that held the
        # GIL would have the two threads only take turns)
        nogil = bool(getattr(kern, "targetoptions", {}).get("nogil", False))
        halves = np.array_split(todo, 2) if nogil and len(todo) >= KERNEL_THREADS and threads() > 1 else [todo]
        args = (np.ascontiguousarray(asked, np.int64), prof.z0, prof.z1, prof.rout0, prof.rout1, prof.rin0,
                prof.rin1, np.ascontiguousarray(cov.max_level, np.int64), np.int64(parts),
                np.ascontiguousarray(lo, float), np.ascontiguousarray(hi, float), *self._grid_arrays(),
                self.samples, self.sample_comp, self.anchors, EPS, CONE_WANT)
        rows = max(16, 2 * len(todo))
        while True:
            st, un, ph = status.copy(), unresolved.copy(), phi.copy()
            hits = [np.empty((rows, 3), np.int64) for _ in halves]
            nh = on_threads(lambda i: kern(C, A, halves[i], *args, st, un, ph, hits[i]), len(halves))
            if min(nh) >= 0:
                break
            rows *= 4
        status[:], unresolved[:], phi[:] = st, un, ph
        hits = np.concatenate([h[:n] for h, n in zip(hits, nh)])
        for lev in np.unique(hits[:, 0]):
            self._remember(cell, hits[hits[:, 0] == lev, 1:])

    @staticmethod
    def side_balls(prof: Profile, part: np.ndarray, level: int, seg: np.ndarray):
        """(centre height, radius) of a ball containing slab ``seg`` of ``part`` at ``level``
        (both circumscribed rings), centred where a ball is tangent to the part's side: the
        slab's middle moved by slope * middle radius along the axis (for a cylinder, the
        middle: the sphere cover's ball)."""
        length = (prof.z1[part] - prof.z0[part]) / 2 ** level
        za = prof.z0[part] + seg * length
        zb = za + length
        ra, rb = prof.rout(part, za), prof.rout(part, zb)
        slope = (prof.rout1[part] - prof.rout0[part]) / (prof.z1[part] - prof.z0[part])
        t = 0.5 * (za + zb) + slope * 0.5 * (ra + rb)
        return t, np.maximum(np.sqrt(ra * ra + (t - za) ** 2), np.sqrt(rb * rb + (t - zb) ** 2))

    def _side_bound(self, x: np.ndarray, R: np.ndarray):
        """(lower bound, a sample near x or -1) from the side grid (:class:`LazyGrid`, made
        on first use, capped a millimetre beyond the largest ball asked so far)."""
        g = self._side_grid
        if g is None or g.cap < R.max() + EPS:
            cap = float(np.ceil(R.max() + 1.0))
            g = self._side_grid = LazyGrid(self.tree, self.e2, SIDE_GRID, cap)
        return g(x)

    def _side_level(self, C, A, prof: Profile, pose, part, seg, level: int, nseg: int, phi):
        """The side pass's balls at ``level`` bounded by the grids (:meth:`lower_bound`): row i
        stands for the ``nseg`` slabs ``seg[i] * nseg + s`` of ``part[i]`` at pose ``pose[i]``.
        A ball the grids clear narrows its pose's free cone ``phi`` (in place); returns the
        others in row order: (pose, part, seg, height t, radius R, centre x, bound). With the
        kernels ``compiled.side_bounds`` (ball by ball, the same bits), the rows in two parts
        on two threads where they are many (the parts split between poses: each thread
        writes only its own poses' ``phi``)."""
        # (only where the kernels are loaded already: the numpy form's grid reads ask for them
        # by their work, as before, so the kernels load when they did)
        k = compiled.loaded()
        if k is None:
            pose, part = np.repeat(pose, nseg), np.repeat(part, nseg)
            seg = nseg * np.repeat(seg, nseg) + np.tile(np.arange(nseg), len(seg))
            t, R = self.side_balls(prof, part, level, seg)
            x = C[pose] + t[:, None] * A[pose]
            bound, _, _ = self.lower_bound(x, R + EPS)
            cert = bound >= R + EPS
            ok = np.nonzero(cert)[0]
            # (turning the axis by phi moves the ball's centre by at most |t| phi)
            min_into(phi, pose[ok], (bound[ok] - R[ok] - EPS) / np.maximum(np.abs(t[ok]), 1e-12))
            f = np.nonzero(~cert)[0]
            return pose[f], part[f], seg[f], t[f], R[f], x[f], bound[f]
        lo, hi = self.box
        pose = np.ascontiguousarray(pose, np.int64)
        part = np.ascontiguousarray(part, np.int64)
        seg = np.ascontiguousarray(seg, np.int64)
        cut = [0, len(pose)]
        if len(pose) * nseg >= KERNEL_THREADS and threads() > 1:
            # (np.nonzero's pairs: sorted by pose, so a pose's rows lie on one side of the cut)
            mid = len(pose) // 2
            cut.insert(1, mid + int(np.searchsorted(pose[mid:], pose[mid], "right")))
        args = (np.int64(level), np.int64(nseg), prof.z0, prof.z1, prof.rout0, prof.rout1,
                np.ascontiguousarray(lo, float), np.ascontiguousarray(hi, float), *self._grid_arrays(), EPS, phi)
        C = np.ascontiguousarray(C, float)
        A = np.ascontiguousarray(A, float)
        outs: list = []
        for a, b in zip(cut[:-1], cut[1:]):
            m = (b - a) * nseg
            outs.append((np.empty(m, np.int64), np.empty(m), np.empty(m), np.empty((m, 3)), np.empty(m)))
        nf = on_threads(lambda i: k["side_bounds"](C, A, pose[cut[i]:cut[i + 1]], part[cut[i]:cut[i + 1]],
                                                   seg[cut[i]:cut[i + 1]], *args, *outs[i]), len(outs))
        ball = np.concatenate([o[0][:m] + cut[i] * nseg for i, (o, m) in enumerate(zip(outs, nf))])
        t, R, x, bound = (np.concatenate([o[j][:m] for o, m in zip(outs, nf)]) for j in range(1, 5))
        row = ball // nseg
        return pose[row], part[row], nseg * seg[row] + ball % nseg, t, R, x, bound

    def _side_pass(self, C, A, prof: Profile, status, unresolved, phi, cell, parts: int = -1,
                   grown: bool = False):
        """The cone parts the spheres left unresolved, asked with :meth:`side_balls` (module
        doc): a part is cleared when each of its slabs is, at 2^``SIDE_LEVELS[0]`` slabs or,
        a failing slab split, finer down to 2^``SIDE_LEVELS[1]``; the bounds are the grids'
        (:meth:`_side_level`), else the side grid's or :meth:`exact_bound`'s, whose nearest
        samples are tried as hits. Updates ``status``, ``unresolved`` and the free cones
        ``phi`` in place.

        ``grown`` (a tool grown more than ``SIDE_GROWN_MAX``: the clearance measurement's
        larger growths): a pose that a cylinder part keeps open is left to fcl whole
        (clearing its cones cannot make it free, and the side grid's bounds for balls that
        large cost the most: figure4's clearance, every pose open by its shank at 3-7 mm, 7.9
        s of the side pass for no pose decided)."""
        cone = np.abs(prof.rout1 - prof.rout0) > 1e-9
        if not cone.any():
            return
        pose, part = nonzero_pairs(unresolved, status != HIT, cone)
        if grown and len(pose) and not cone.all():
            keep = ~any_row(unresolved[pose][:, ~cone])
            pose, part = pose[keep], part[keep]
        if len(pose) == 0:
            return
        first, last = SIDE_LEVELS
        lost = np.zeros(unresolved.shape, bool)
        asked_pose, asked_part = pose, part
        seg, nseg = np.zeros(len(pose), np.int64), 2 ** first
        level = first
        while len(pose):
            # the balls the grids leave open (the others have narrowed phi)
            pose, part, seg, t, R, x, bound = self._side_level(C, A, prof, pose, part, seg, level, nseg, phi)
            cert = np.zeros(len(pose), bool)
            near = np.full(len(x), -1, np.int64)
            rest = np.arange(len(pose))
            if len(rest):
                # the side grid's bound, and its node's sample: where that lies within the
                # ball (so does the mesh), the exact bound cannot clear it
                gb, gj = self._side_bound(x, R)
                bound = np.maximum(bound, gb)
                cert = bound >= R + EPS
                near = gj
                rest = rest[~cert]
                q = self.samples[np.maximum(near[rest], 0)] - x[rest]
                inside = (near[rest] >= 0) & (_dot(q, q) - self.e2 < (R[rest] + EPS) ** 2)
                rest = rest[~inside]
            if len(rest):
                eb, near[rest] = self.exact_bound(x[rest], R[rest] + EPS, nearest=True)
                self.stats["exact"] += len(rest)
                bound[rest] = np.maximum(bound[rest], eb)
                cert[rest] = bound[rest] >= R[rest] + EPS
            bad = np.nonzero(~cert)[0]
            has = bad[near[bad] >= 0]
            if len(has):
                found = self._hits(status, self.samples[near[has]], near[has], pose[has], C, A, prof, parts)
                self._remember(cell, found)
            ok = np.nonzero(cert)[0]
            min_into(phi, pose[ok], (bound[ok] - R[ok] - EPS) / np.maximum(np.abs(t[ok]), 1e-12))
            if level >= last:
                lost[pose[bad], part[bad]] = True
                break
            keep = bad[status[pose[bad]] != HIT]
            pose, part, seg, nseg = pose[keep], part[keep], seg[keep], 2
            level += 1
        done = ~lost[asked_pose, asked_part] & (status[asked_pose] != HIT)
        unresolved[asked_pose[done], asked_part[done]] = False

    def _cylinder_pass(self, C, A, prof: Profile, status, unresolved, phi, parts: int = -1) -> None:
        """The cylinder parts that a grown tool's spheres and balls left unresolved, tested
        against the triangles near their axis (module doc, "Cylinders"; ``cylinder_clear``):
        ``unresolved`` cleared in place where a part is proven clear. Without the compiled
        kernels the parts stay open (fcl answers them, the same answers). A pose with a part
        cleared here keeps no free cone (``phi`` 0): the test proves its axis alone."""
        K = len(prof.z0)
        cyl = (np.abs(prof.rout1 - prof.rout0) <= 1e-12) & ((int(parts) >> np.arange(K)) & 1).astype(bool)
        if not cyl.any() or len(self.T) == 0:
            return
        pose, part = nonzero_pairs(unresolved, status != HIT, cyl)
        if len(pose) == 0:
            return
        k = compiled.kernels(work=CYL_WORK * len(pose))
        if k is None:
            return
        if self._cyl_cells is None:
            table = compiled.cell_table(self.samples, CYL_CELL * self.e, BAND_CELLS)
            se = np.sqrt(3.0 * self._sample_e2_table())
            self._cyl_cells = (table, se, float(se.max()))
        table, se, emax = self._cyl_cells
        lo, h, shape, start, order, pts = table
        out = np.empty(len(pose), bool)
        n = k["cylinder_clear"](np.ascontiguousarray(C, float), np.ascontiguousarray(A, float),
                                np.ascontiguousarray(pose, np.int64), np.ascontiguousarray(part, np.int64),
                                prof.z0, prof.z1, np.maximum(prof.rout0, prof.rout1), lo, h, shape, start, order,
                                pts, se, emax, self.tris_start, self.tris_flat, self.V, self.T, EPS, CYL_MAX_CELLS,
                                out)
        self.stats["cylinder"] += int(n)
        unresolved[pose[out], part[out]] = False
        phi[pose[out]] = 0.0

    def decide(self, C: np.ndarray, A: np.ndarray, grow: float = 0.0, parts: int = -1) -> np.ndarray:
        """FREE (0), HIT (1) or UNKNOWN (-1) per pose (ball centre, unit axis), for the tool
        parts in the bit mask ``parts`` (-1 all: the others are left out of the question; its
        free cones are then neither kept nor given, its hits hold for the whole tool)."""
        C = np.asarray(C, float).reshape(-1, 3)
        A = np.asarray(A, float).reshape(-1, 3)
        n = len(C)
        grow = float(grow)
        parts = int(parts)
        status = np.full(n, UNKNOWN, np.int8)
        cov = self._cover(grow)
        self.open_parts = np.ones((n, len(cov.prof.z0)), bool)
        if n == 0:
            return status
        prof = cov.prof
        known = self.centres.size
        slot = self._slots(C)
        self._grow_cones(grow)
        cone_a, cone_c = self._cone_a[grow], self._cone_c[grow]
        # free cones of earlier free poses at the same centre (only centres known before this
        # call have any)
        old = np.nonzero(slot < known)[0]
        within = np.einsum("nki,ni->nk", cone_a[slot[old]], A[old]) >= cone_c[slot[old]]
        inc = np.zeros(n, bool)
        inc[old] = any_row(within)
        status[inc] = FREE
        self.stats["cone"] += int(inc.sum())
        # witnesses of earlier hits near the same centre (in cells that have any)
        cell = self._witness_cells(C)
        todo = np.nonzero(~inc & any_row(self._wit >= 0)[cell])[0]
        wit = self._wit[cell[todo]]
        r, k = np.nonzero(wit >= 0)
        if len(r):
            before = status == HIT
            self._hits(status, self.samples[wit[r, k]], wit[r, k], todo[r], C, A, prof, parts)
            self.stats["witness"] += int((~before & (status == HIT)).sum())
        todo = np.nonzero(status == UNKNOWN)[0]
        phi = np.full(n, np.inf)                 # free cone of each pose, from its spheres
        K = len(prof.z0)
        unresolved = np.zeros((n, K), bool)      # parts the spheres could not clear
        asked = np.nonzero((parts >> np.arange(K)) & 1)[0]
        k = compiled.kernels(work=SPHERE_WORK * len(todo) * len(asked))
        if k is not None:
            self._sphere_kernel(k["sphere_loop"], C, A, cov, todo, asked, parts, status, unresolved, phi, cell)
        else:
            self._sphere_loop(C, A, cov, todo, asked, parts, status, unresolved, phi, cell)
        self._side_pass(C, A, prof, status, unresolved, phi, cell, parts, grown=grow > SIDE_GROWN_MAX)
        if grow == 0.0:
            # (a grown tool is what the clearance measurement asks, of poses within a hair
            # of the surface by construction: there the pass decided one pose in 70 spheres)
            self._exact_pass(C, A, cov, status, unresolved, phi, cell, parts)
        elif grow <= SIDE_GROWN_MAX:
            self._cylinder_pass(C, A, prof, status, unresolved, phi, parts)
        free = np.zeros(n, bool)
        free[todo] = True
        opened = any_row(unresolved)
        free &= (status != HIT) & ~opened
        status[free] = FREE
        # what fcl still has to answer for the poses left open: their unresolved parts
        self.open_parts = unresolved
        # remember the new free cones (replacing each centre's narrower one)
        fi = np.nonzero(free & (phi > 0))[0] if parts == -1 or parts == (1 << K) - 1 else np.zeros(0, int)
        if len(fi):
            self._store_cones(slot[fi], A, np.cos(np.minimum(phi[fi], np.pi)), grow, rows=fi)
        st = self.stats
        st["poses"] += n
        st["free"] += int((status == FREE).sum())
        st["hit"] += int((status == HIT).sum())
        st["unknown"] += int((status == UNKNOWN).sum())
        return status
