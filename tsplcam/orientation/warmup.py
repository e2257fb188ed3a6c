"""The engine's kernels warmed: :func:`exercise` calls every kernel of :mod:`tsplcam.compiled`
once, through its callers (the model's surface evaluation, the path's cusp heights at the line
ends, the orientation's loops), on a tiny input. It sits in the orientation, the last stage
that uses kernels (it imports the stages' modules).

Handed to :func:`tsplcam.compiled.prepare` (the job, ``program._load_numba``) and
:func:`tsplcam.compiled.warm` (``scripts/install.sh``), which may not import a stage
themselves (``compiled`` sits below every stage)."""
from __future__ import annotations

from .. import compiled


def exercise() -> None:
    """Call every kernel once on a tiny input, with the types the job uses, so numba's JIT
    compiles them (or loads them from its cache); the set called is the one
    :func:`tsplcam.compiled.kernels` gives (``prepare`` and ``warm`` choose it)."""
    import numpy as np

    from ..model.cells import BezierCells
    from ..model.patch import Patch
    ctrl = np.ones((1, 4, 4, 4))
    ctrl[0, :, :, 0] = np.arange(4)
    Patch(0, [0.0, 1.0], [0.0, 1.0], np.zeros((1, 1), int), np.zeros((1, 1), int),
          [BezierCells(ctrl)]).evaluate(np.array([0.5]), np.array([0.5]))
    from ..toolpath.lines import END_SAMPLES, _capsule_segments, _end_pass
    ca = np.zeros((1, 2, 2, 1, 3))
    cb = ca + 1.0
    E = np.ones((1, 2 * END_SAMPLES, 3))
    _end_pass(E, E, 0, ca, cb, 0.5, _capsule_segments(ca, cb), np.zeros((1, 2)), np.zeros((1, 2)),
              np.ones((1, 2)), compiled.kernels())
    from ..toolpath.lines import _cusp_foot, _unit_normal
    x = np.ones((1, 1, 3))
    _cusp_foot(x, x, x, x, x, x, x, x, x, x, x, np.zeros((1, 1), bool), 0.5, compiled.kernels())
    cm = np.eye(3)                                 # two points' derivatives, coordinate-major
    _unit_normal(cm[:, :2].copy().T, cm[:, 1:].copy().T)

    from .viterbi import viterbi
    node = np.zeros((3, 3))
    viterbi(node, np.ones((2, 3, 3)))
    from .rotary import Rotary
    from .smoothing import (MeridianGrid, SmoothingCost, _Banded, cone_halfspaces, forced_rotary_travel,
                            joint_transitions, meridian_grid)
    th = np.zeros((3, 3))
    grid = MeridianGrid(np.zeros(3), th, th, th, th, np.ones((3, 3), bool))
    viterbi(node, joint_transitions(grid, SmoothingCost(1.0, Rotary()), np.ones(2), 1.0, np.ones(3, bool)))
    forced_rotary_travel(grid, np.zeros((3, 3), np.int8), np.ones(2))
    up = np.array([[0.0, 0.6, 0.8]])
    meridian_grid(Rotary(), up, up, [(h, np.zeros(1)) for h in cone_halfspaces(up, np.array([[1.0, 0.0, 0.0]]),
                                                                                 0.5, 0.5)], 4)
    ab = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [2.0, 2.0, 2.0]])
    compiled.kernels()["banded_solve"](ab.copy(), np.ones(3))
    box = _Banded(3, 2)
    box.ab[:] = ab
    box.g[:] = 1.0
    box.solve_box(-np.ones(3), np.ones(3))
    viterbi(np.zeros((3, 2)), np.ones((2, 2, 2)))
    from scipy.spatial import cKDTree

    from .broadphase import DistanceGrid
    P = np.zeros((1, 3))
    DistanceGrid(cKDTree(P), 0.0, P[0], P[0] + 1.0, 0.5, 0.5, 1.0, 64)(np.full((2, 3), 0.25))
    from .broadphase import BroadPhase, Profile
    one = np.ones(1)
    # (a cone part, for the side pass's kernel; the pose far off is free: its cone is stored)
    tri = BroadPhase(np.eye(3), np.array([[0, 1, 2]]), lambda grow: Profile(0.5 * one, 3 * one, one, 2 * one, one, 2 * one), 0.5)
    C, A = np.array([[0.5, 0.5, 0.5], [0.5, 0.5, 0.5], [9.0, 9.0, 9.0]]), np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    tri.decide(C, A)
    tri.exact_bound(C, np.full(3, 0.1))
    tri._hits(np.full(3, -1, np.int8), tri.samples[[0, 1]], np.arange(2), np.arange(2), C, A, tri._cover(0.0).prof)
    # (the cylinder pass of a grown tool's questions: one cylinder part, every pose open)
    tri._cylinder_pass(C, A, Profile(0.5 * one, 3 * one, one, one, one, one), np.full(3, -1, np.int8),
                       np.ones((3, 1), bool), np.full(3, np.inf))
    # (the verification's capsule entries: one capsule, one point)
    compiled.kernels()["capsule_entries"](np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), np.zeros((1, 1), np.int64),
                                          np.ones(1), np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0]]),
                                          np.array([[1.0, 0.0, 0.0]]), 0.5, np.zeros((0, 0), bool),
                                          np.zeros((0, 0), bool), np.empty((1, 1)), np.zeros(0), np.zeros(0))
    # (the verification's neighbour searches: a table of two points, one query)
    table = compiled.cell_table(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), 0.5, 64)
    compiled.kernels()["k_nearest"](np.zeros((1, 3)), table[5], table[4], table[3], table[0], table[1], table[2], 1,
                                    np.inf, np.empty((1, 1), np.int64), np.empty((1, 1)), np.empty(1, bool))
