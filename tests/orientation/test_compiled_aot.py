"""The kernels compiled ahead of time (``tsplcam.compiled``'s ``_aot_kernels``, built by
``scripts/install.sh``) against numba's JIT kernels of the same source: every call of a small
workload (each kernel, on tiny and on random inputs with forbidden states, ties and hits)
made again in the JIT kernel gives the same return value and leaves the same bytes in every
array. Also: the signatures fit the kernels, a module of another source is not used, and
arguments of other types go to numba's kernel."""
import importlib.util
import os
import unittest
from unittest import mock

import numpy as np

from tsplcam import compiled
from tsplcam.orientation.warmup import exercise

HAVE_NUMBA = importlib.util.find_spec("numba") is not None and os.environ.get("TSPLCAM_COMPILED") != "0"


def copy(a):
    """A copy of an argument, an array read-only where it was (numba's JIT types it so: the
    types ``compiled.warm`` compiled, nothing compiled here)."""
    if not isinstance(a, np.ndarray):
        return a
    c = a.copy()
    c.flags.writeable = a.flags.writeable
    return c


def snapshot(args) -> tuple:
    return tuple(copy(a) for a in args)


class Recorder:
    """A kernel that records each call: (name, arguments before, result, arguments after)."""

    def __init__(self, name, fn, calls):
        self.name, self.fn, self.calls = name, fn, calls

    def __call__(self, *args):
        before = snapshot(args)
        r = self.fn(*args)
        self.calls.append((self.name, before, r, snapshot(args)))
        return r


def workload(rng) -> None:
    """Every kernel on small inputs, through the callers (the kernels set in compiled._STATE)."""
    from scipy.spatial import cKDTree

    from tsplcam.orientation.broadphase import BroadPhase, DistanceGrid, Profile
    from tsplcam.orientation.smoothing import _Banded
    from tsplcam.orientation.viterbi import viterbi
    exercise()                                             # each kernel, the job's types
    from tsplcam.toolpath.lines import END_SAMPLES, _capsule_segments, _end_pass
    G = 4                                                  # cusp_ends: hits, misses, degenerate
    ca = rng.normal(size=(G, 2, 2, 1, 3)) * 0.3
    cb = ca + 2.0 * rng.normal(size=ca.shape) * (rng.random(ca.shape[:-1] + (1,)) < 0.8)
    E, nE = rng.normal(size=(G, 2 * END_SAMPLES + 3, 3)) * 0.6, rng.normal(size=(G, 2 * END_SAMPLES + 3, 3))
    nE /= np.linalg.norm(nE, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        _end_pass(E, nE, 3, ca, cb, 0.5, _capsule_segments(ca, cb), np.zeros((G, 2)), rng.random((G, 2)),
                  np.ones((G, 2)), compiled.kernels())
    from tsplcam.toolpath.lines import _cusp_foot             # cusp_foot: meeting, apart, beyond
    x = [rng.normal(size=(3, 5, 3)) * 0.3 for _ in range(11)]
    _cusp_foot(*x, rng.random((3, 5)) < 0.2, 0.5, compiled.kernels())
    for S, n in ((12, 120), (2, 80)):                      # viterbi_steps / _path, two_states
        node = rng.random((n, S))
        node[rng.random((n, S)) < 0.15] = np.inf
        trans = np.round(rng.random((n - 1, S, S)) * 4) / 4      # ties
        trans[rng.random((n - 1, S, S)) < 0.3] = np.inf
        viterbi(node, trans)
    from tsplcam.orientation.smoothing import MeridianGrid, forced_rotary_travel
    n, M = 90, 12                                          # kind_steps: short blocks, excluded states
    ok = rng.random((n, M)) < 0.7
    th = np.zeros((n, M))
    forced_rotary_travel(MeridianGrid(2 * np.pi * np.arange(M) / M, th, th, th, th, ok),
                         np.where(rng.random((n, M)) < 0.1, 2, -1), np.where(rng.random(n - 1) < 0.4, 0.05, 1.0))
    N, u = 40, 3                                           # banded_solve, solve_box
    box = _Banded(N, u)
    box.ab[:] = rng.normal(size=(u + 1, N)) * 0.1
    box.ab[u] = 2.0 + rng.random(N)
    box.g[:] = rng.normal(size=N)
    compiled.kernels()["banded_solve"](box.ab.copy(), rng.normal(size=N))
    box.solve_box(-0.3 * np.ones(N), 0.3 * np.ones(N))
    P = rng.random((50, 3))                                # grid_read
    DistanceGrid(cKDTree(P), 0.0, P.min(axis=0), P.max(axis=0), 0.1, 0.2, 0.5, 4000)(rng.random((300, 3)) * 1.4 - 0.2)
    g = np.linspace(0, 4, 9)                               # sphere_loop, hit_pairs: a wavy sheet
    X, Y = np.meshgrid(g, g, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), 0.3 * np.sin(X.ravel()) * np.cos(Y.ravel())])
    T = np.array([t for i in range(8) for j in range(8)
                  for t in ([i * 9 + j, i * 9 + j + 9, i * 9 + j + 10], [i * 9 + j, i * 9 + j + 10, i * 9 + j + 1])])
    two = np.ones(2)
    prof = lambda grow: Profile(np.array([0.3, 3.0]), np.array([3.0, 9.0]), (0.5 + grow) * two,   # noqa: E731
                                (np.array([0.5, 1.5]) + grow), (0.55 + grow) * two, np.array([0.55, 1.6]) + grow)
    broad = BroadPhase(V, T, prof, 0.5)
    C = np.column_stack([rng.random(400) * 4, rng.random(400) * 4, 0.3 + rng.random(400) * 1.5])
    th = rng.random(400) * 1.3
    ph = rng.random(400) * 2 * np.pi
    A = np.column_stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    for grow in (0.0, 0.2):
        broad.decide(C, A, grow)
    from tsplcam.toolpath.path import ToolPath                # capsule_entries: hits, misses, inside
    from tsplcam.verify.scallop import Swept
    c = np.column_stack([np.linspace(0, 4, 30), np.zeros(30), np.full(30, 0.5)])
    up = np.tile([0.0, 0.0, 1.0], (30, 1))
    sw = Swept(ToolPath(c, up, up, np.zeros(30, np.int8), np.zeros(30, int), np.zeros((30, 2)), np.zeros(30, int),
                        0.5), 0.3)
    q = np.column_stack([rng.random(50) * 4, rng.normal(size=50) * 0.4, rng.normal(size=50) * 0.4])
    up = np.tile([0.0, 0.0, 1.0], (50, 1))
    near = sw.candidates(q, up, 6)
    sw.entry(q, up, near)
    sw.heights_among(q, up, (near, rng.random(near.shape) < 0.5, rng.random(near.shape) < 0.5))


@unittest.skipUnless(HAVE_NUMBA, "numba is not installed (the numpy versions run)")
class AheadOfTime(unittest.TestCase):
    def test_same_as_jit(self):
        """Each call of the workload in the ahead-of-time kernels, made again in numba's JIT
        kernel on the same arguments: the same result and the same bytes in every array."""
        aot = compiled._aot()
        if aot is None:
            self.skipTest("no ahead-of-time module of this source (scripts/install.sh builds it)")
        calls = []
        rec = {name: Recorder(name, f, calls) for name, f in aot.items()}
        with mock.patch.dict(compiled._STATE, {"k": rec}):
            workload(np.random.default_rng(5))
        self.assertEqual({c[0] for c in calls}, set(compiled.SIGNATURES))
        jit = compiled._jit()
        for name, before, result, after in calls:
            args = snapshot(before)
            self.assertEqual(jit[name](*args), result, name)
            for a, b in zip(args, after):
                if isinstance(a, np.ndarray):
                    self.assertEqual(a.tobytes(), b.tobytes(), name)

    def test_releases_gil(self):
        """The module's wrappers release the GIL around a kernel (as numba's ``nogil``), so the
        broad phase's two halves run at once: the module calls CPython's
        ``PyEval_SaveThread``/``PyEval_RestoreThread`` (a module built with pycc's default
        flags imports neither), and its kernels say so as numba's do."""
        if compiled._aot() is None:
            self.skipTest("no ahead-of-time module of this source (scripts/install.sh builds it)")
        with open(compiled._aot_path(), "rb") as f:
            text = f.read()
        self.assertIn(b"PyEval_SaveThread", text)
        self.assertIn(b"PyEval_RestoreThread", text)
        self.assertTrue(compiled._aot()["sphere_loop"].targetoptions["nogil"])

    def test_stale_or_other_types(self):
        """A module built from another source (or for another processor) is not used; arguments of other types than the
        signature's (here a float32 array, a non-contiguous one, a read-only one written to,
        an int for a float) go to numba's kernel, not the module's."""
        if compiled._aot() is None:
            self.skipTest("no ahead-of-time module of this source (scripts/install.sh builds it)")
        with mock.patch.dict(compiled._STATE, clear=True), \
                mock.patch.object(compiled, "build_key", lambda: 1):
            self.assertIsNone(compiled._aot())
        f = compiled._aot()["two_states"]
        node, t, states = np.zeros((3, 2)), np.ones((2, 2, 2)), np.zeros(3, np.int64)
        ro = states.copy()
        ro.flags.writeable = False
        seen = []
        jit = {"two_states": lambda *a: seen.append(a) or -2}
        with mock.patch.object(compiled, "_jit", lambda: jit):
            self.assertEqual(f(node, t, 1e-9, states), -2)
            self.assertEqual(len(seen), 0)                 # the module's kernel
            for args in ((node.astype(np.float32), t, 1e-9, states), (node, t[:, :, ::-1], 1e-9, states),
                         (node, t, 1e-9, ro), (node, t, 1, states), (node, t, 1e-9)):
                f(*args)
            self.assertEqual(len(seen), 5)


class Signatures(unittest.TestCase):
    def test_signatures_fit_kernels(self):
        """Every kernel has a signature with as many arguments as it takes, arrays and
        scalars named in the codes the build knows."""
        funcs = compiled._define(lambda f: f)
        self.assertEqual(set(funcs), set(compiled.SIGNATURES))
        for name, sig in compiled.SIGNATURES.items():
            ret, args = compiled._arguments(sig)
            self.assertEqual(len(args), funcs[name].__code__.co_argcount, name)
            self.assertIn(ret, ("i8", "void"), name)
            for code, nd, _ in args:
                self.assertIn(code, ("f8", "i8", "i4", "i1", "b1"), name)
                self.assertIn(nd, (0, 1, 2, 3, 4), name)

    def test_no_kernel_in_a_closure(self):
        """No kernel holds a compiled function in its closure: numba's cache keys a closure by
        its cells, and a dispatcher there differs in every process, so such a kernel is never
        found in the cache and is compiled again in each (cusp_foot with a helper in a cell:
        1.2-1.6 s a process); helpers are module globals, which the cache does not key."""
        import numba
        funcs = compiled._define(lambda f: f)
        for name, f in funcs.items():
            for cell in f.__closure__ or ():
                self.assertNotIsInstance(cell.cell_contents, numba.core.dispatcher.Dispatcher, name)

    def test_compiled_off(self):
        """``TSPLCAM_COMPILED=0``: no kernels, numpy runs."""
        with mock.patch.dict(os.environ, {"TSPLCAM_COMPILED": "0"}), mock.patch.dict(compiled._STATE, clear=True):
            self.assertIsNone(compiled.kernels())


if __name__ == "__main__":
    unittest.main()
