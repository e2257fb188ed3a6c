"""What the test files share: data locations, FreeCAD detection, test geometry and checks.

pytest loads this file first; ``TestTsplcam`` (freecadcmd) and ``tests/gui/run_gui_tests.py``
put ``tests/`` on ``sys.path`` so that test files, loaded by path, can ``from conftest import ...``.

External test data lives beside the checkout in ``../shared/data/external``
(or ``$TSPLCAM_SHARED/data/external``); tests that need it skip when it is absent.
"""
from __future__ import annotations

import os
import unittest

# realpath: under FreeCAD the checkout is reached through the Mod/tsplcam link
REPO_DIR = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
ARTIFACT_DIR = os.environ.get("TSPLCAM_ARTIFACTS", os.path.join(REPO_DIR, "build", "artifacts"))


# Test files that leave threads running in the test process (a Dask client's IO loop outlives
# it) run after the others of their process: the engine forks its workers in many tests, and
# a fork beside running threads can leave the child a lock that a thread gone there held
# (once, under load, test_parallel's worker took no piece in 10 s after test_batch: the
# likely cause).
THREAD_LEAVERS = ("tests/test_batch.py",)


def pytest_collection_modifyitems(session, config, items):
    items.sort(key=lambda item: item.nodeid.startswith(THREAD_LEAVERS))


def shared_dir() -> str:
    return os.environ.get("TSPLCAM_SHARED", os.path.join(os.path.dirname(REPO_DIR), "shared"))


def external(*parts: str) -> str:
    """Path of a file in ../shared/data/external; skips the calling test when absent."""
    path = os.path.join(shared_dir(), "data", "external", *parts)
    if not os.path.exists(path):
        raise unittest.SkipTest(f"external test data absent: {path}")
    return path


def artifact_path(name: str) -> str:
    """Where a test writes a picture or report for people to look at."""
    os.makedirs(ARTIFACT_DIR, exist_ok=True)
    return os.path.join(ARTIFACT_DIR, name)


def freecad_importable() -> bool:
    """True inside FreeCAD (freecadcmd or the GUI), where Part and OCCT are there too."""
    try:
        import FreeCAD  # noqa: F401
        import Part  # noqa: F401
    except ImportError:
        return False
    return True


def require_freecad():
    """The FreeCAD module, or skip the calling test (plain pytest has no FreeCAD)."""
    if not freecad_importable():
        raise unittest.SkipTest("FreeCAD is not importable here (run under freecadcmd)")
    import FreeCAD
    return FreeCAD


def needs_freecad(cls):
    """Class decorator: a TestCase that needs FreeCAD (document objects, OCCT comparisons).

    ``freecadcmd -t TestTsplcam`` runs exactly the classes marked so; plain pytest skips
    them. Every other test runs under pytest only, so each test runs once."""
    cls.needs_freecad = True
    return unittest.skipUnless(freecad_importable(), "needs FreeCAD: freecadcmd -t TestTsplcam runs it")(cls)


# -- test geometry several test files share (they cannot import one another) -------------
def ngon_prism(n: int, seed: int = 0, noise: float = 0.05):
    """A closed quad cage (Cage): two caps of n quads around a centre of valence n, joined by
    2n side quads (rim vertices alternate valence 4 and 3); perturbed by ``noise``."""
    import numpy as np
    from tsplcam.model.cage import Cage
    from tsplcam.model.quadmesh import QuadMesh
    rng = np.random.default_rng(seed)
    pts = [[0, 0, 1.2], [0, 0, -1.2]]
    for z in (1.0, -1.0):
        for j in range(2 * n):
            a = np.pi * j / n
            r = 1.0 if j % 2 == 0 else 1.25
            pts.append([r * np.cos(a), r * np.sin(a), z])

    def top(j):
        return 2 + (j % (2 * n))

    def bot(j):
        return 2 + 2 * n + (j % (2 * n))

    faces = []
    for j in range(n):
        faces.append([0, top(2 * j), top(2 * j + 1), top(2 * j + 2)])
        faces.append([1, bot(2 * j + 2), bot(2 * j + 1), bot(2 * j)])
    for j in range(2 * n):
        faces.append([top(j + 1), top(j), bot(j), bot(j + 1)])
    pts = np.array(pts, float) + noise * rng.standard_normal((len(pts), 3))
    return Cage(QuadMesh(np.array(faces), len(pts)), pts)


def arc_poles(a0: float, a1: float):
    """Rational quadratic arc of the unit circle from angle a0 to a1 (< 180 deg): poles, weights."""
    import numpy as np
    h = 0.5 * (a1 - a0)
    m = 0.5 * (a0 + a1)
    P = np.array([[np.cos(a0), np.sin(a0)], [np.cos(m) / np.cos(h), np.sin(m) / np.cos(h)],
                  [np.cos(a1), np.sin(a1)]])
    return P, np.array([1.0, np.cos(h), 1.0])


def cylinder_patch(R: float, H: float, beta: float = 0.6981317007977318, outward: bool = True):
    """Exact NURBS piece of a cylinder about z (a Patch): angle -beta..beta along u (default
    40 deg), z = 0..H along v; ``outward=False`` reverses u, so the normal points inward."""
    import numpy as np
    from tsplcam.model.bspline import bspline_patch
    az, wa = arc_poles(-beta, beta)
    poles = np.zeros((3, 2, 3))
    w = np.zeros((3, 2))
    for i in range(3):
        for j in range(2):
            poles[i, j] = [R * az[i, 0], R * az[i, 1], H * j]
            w[i, j] = wa[i]
    if not outward:
        poles, w = poles[::-1], w[::-1]
    return bspline_patch(poles, w, [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], 2, 1)


def plane_patch(W: float, H: float):
    """The rectangle [0, W] x [0, H] in z = 0 as a bilinear Patch."""
    import numpy as np
    from tsplcam.model.bspline import bspline_patch
    poles = np.array([[[0, 0, 0], [0, H, 0]], [[W, 0, 0], [W, H, 0]]], float)
    return bspline_patch(poles, None, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)


def one_patch_model(patch, name: str = "test patch"):
    """A Model of a single patch (its corners are nodes 0..3)."""
    from tsplcam.model.model import Model
    patch.corner_nodes = [0, 1, 2, 3]
    corners = patch.evaluate([0, 1, 1, 0], [0, 0, 1, 1]).P
    return Model([patch], corners, [], "bspline", name=name)


def keycap_mold_checker(tool: str = "ball1_keycap", **options):
    """(model, CollisionChecker) of the keycap_mold sample and its stock block with ``tool``;
    ``options``: the checker's (clearance, tolerance, ...)."""
    from tsplcam.model import samples
    from tsplcam.model.cage import cage_model
    from tsplcam.orientation import CollisionChecker, load_tool
    model = cage_model(samples.keycap_mold())
    V, T = samples.keycap_mold_stock()
    return model, CollisionChecker(model, load_tool(tool), meshes=[("stock", V, T)], **options)


def assert_finite_everywhere(test, named_models, samples: int = 17) -> None:
    """No evaluation returns NaN: position, derivatives, normal, principal curvatures and
    directions on a grid of every patch (corners included) of every (name, model)."""
    import numpy as np
    g = np.linspace(0, 1, samples)
    U, V = np.meshgrid(g, g)
    for name, model in named_models:
        for p in model.patches:
            s = p.evaluate(U.ravel(), V.ravel())
            for arr in (s.P, s.Pu, s.Pv, s.Puu, s.Puv, s.Pvv, s.normal,
                        *s.principal_curvatures, *s.principal_directions):
                test.assertTrue(np.all(np.isfinite(arr)), f"{name} {p.name}")


def edge_pair(model, link, tau):
    """Both sides of a shared patch edge (a layout EdgeLink) evaluated at the same points:
    (SurfacePoints of patch a, of patch b) at fractions ``tau`` along a's edge."""
    pa, pb = model.patches[link.a], model.patches[link.b]
    sa = pa.evaluate(*pa.edge_params(link.ea, tau))
    sb = pb.evaluate(*pb.edge_params(link.eb, 1 - tau if link.reversed else tau))
    return sa, sb


def faces_meet(model, mesh, tau):
    """Every interior edge of a T-mesh model sampled at fractions ``tau`` from the faces on
    both sides (faces of zero size left out): (SurfacePoints on one side, on the other)."""
    topo = mesh.topology
    fa, sa, ta, fb, sb, tb = [], [], [], [], [], []
    for (a, b), (f, i) in topo.edge_at.items():
        hit = topo.edge_at.get((b, a))
        if hit is None or a > b or min(model.face_size[f]) <= 0 or min(model.face_size[hit[0]]) <= 0:
            continue
        g, j = hit
        for face, k, ts, ss, tt in ((f, i, tau, sa, ta), (g, j, tau[::-1], sb, tb)):
            W, H = model.face_size[face]
            p0, p1 = topo.pos[face][k], topo.pos[face][(k + 1) % len(mesh.faces[face])]
            ss.extend((p0[0].real + (p1[0].real - p0[0].real) * ts) / W)
            tt.extend((p0[1].real + (p1[1].real - p0[1].real) * ts) / H)
        fa += [f] * len(tau)
        fb += [g] * len(tau)
    return model.evaluate_faces(fa, sa, ta), model.evaluate_faces(fb, sb, tb)


def curvature_gap(sa, sb):
    """(largest difference of the sorted principal curvatures of two evaluations of the same
    points, 1 + largest |curvature|), with b's signs turned to a's normal."""
    import numpy as np
    sign = np.sign(np.einsum("ij,ij->i", sa.normal, sb.normal))[:, None]
    ka = np.sort(np.column_stack(sa.principal_curvatures), axis=1)
    kb = np.sort(np.column_stack(sb.principal_curvatures) * sign, axis=1)
    return float(np.abs(ka - kb).max()), 1.0 + float(np.abs(ka).max())


# -- fuzzing the readers (tests/*/test_fuzz_*.py) --------------------------------------------
# A case is a seed file (a shipped sample, machine or tool, or a public file from
# ../shared/data/external) and one to three mutations. A mutation is four integers, so that
# hypothesis draws and shrinks them and a plain loop can replay them: the kind, then where
# and what, reduced modulo the size of the file. ``TSPLCAM_FUZZ_EXAMPLES=N`` makes every fuzz
# test draw N random cases (the long run); without it each draws its own short, fixed list.
FUZZ_EXAMPLES = int(os.environ.get("TSPLCAM_FUZZ_EXAMPLES", "0") or 0)
FUZZ_CASE_SECONDS = 20.0      # a case still running after this is a hang (normal: < 0.5 s)

# what a number is replaced by: not-a-numbers, infinities, signs, zero, the largest and
# smallest doubles, huge counts, non-integers, a 5000-digit integer (beyond Python's int()
# limit) and a 400-digit float
FUZZ_NUMBERS = (b"nan", b"NaN", b"inf", b"-inf", b"Infinity", b"-Infinity", b"-1", b"0",
                b"-0", b"1e308", b"-1e308", b"1e309", b"1e-320", b"1000000000", b"4294967297",
                b"1e30", b"2.5", b"0.5", b"-2", b"3", b"1e15", b"9" * 5000,
                b"0." + b"3" * 400)
# what a JSON scalar (or a token of a text format) is replaced by: other JSON types
FUZZ_TOKENS = (b"null", b"true", b"false", b'""', b'"x"', b"[]", b"{}", b"[1, 2]",
               b'{"a": 1}', b'"\\u0000"', b'"\\ud800"', b"-", b"1/0", b"0x10", b"1_000")
# bytes that are not UTF-8, and some that are but are unusual in these files
FUZZ_BYTES = (b"\xff", b"\xfe\xff", b"\xc3", b"\x80", b"\xed\xa0\x80", b"\x00", b"\r", b"\x1a",
              b"\xef\xbb\xbf", b"\xe2\x80\xa8", b"\t\t")
_NUMBER = None
_SCALAR = None


def _fuzz_regexes():
    global _NUMBER, _SCALAR
    if _NUMBER is None:
        import re
        _NUMBER = re.compile(rb"(?<![A-Za-z_0-9.])-?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
        _SCALAR = re.compile(rb'"(?:[^"\\\n]|\\.)*"|-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?'
                             rb'|\btrue\b|\bfalse\b|\bnull\b')
    return _NUMBER, _SCALAR


def _replace_match(data: bytes, regex, index: int, new: bytes) -> bytes:
    hits = list(regex.finditer(data))
    if not hits:
        return data
    m = hits[index % len(hits)]
    return data[:m.start()] + new + data[m.end():]


def _lines(data: bytes) -> list:
    return data.split(b"\n")


def _m_truncate(d, a, b, c):
    return d[:a % (len(d) + 1)]


def _m_delete_line(d, a, b, c):
    ls = _lines(d)
    del ls[a % len(ls)]
    return b"\n".join(ls)


def _m_duplicate_line(d, a, b, c):
    ls = _lines(d)
    i = a % len(ls)
    ls.insert(i, ls[i])
    return b"\n".join(ls)


def _m_swap_lines(d, a, b, c):
    ls = _lines(d)
    i, j = a % len(ls), b % len(ls)
    ls[i], ls[j] = ls[j], ls[i]
    return b"\n".join(ls)


def _m_number(d, a, b, c):
    return _replace_match(d, _fuzz_regexes()[0], a, FUZZ_NUMBERS[b % len(FUZZ_NUMBERS)])


def _m_number_in_line(d, a, b, c):
    """Every number of one line replaced (a whole vertex, node or record at once)."""
    ls = _lines(d)
    i = a % len(ls)
    ls[i] = _fuzz_regexes()[0].sub(FUZZ_NUMBERS[b % len(FUZZ_NUMBERS)], ls[i])
    return b"\n".join(ls)


def _m_token(d, a, b, c):
    return _replace_match(d, _fuzz_regexes()[1], a, FUZZ_TOKENS[b % len(FUZZ_TOKENS)])


def _m_random_bytes(d, a, b, c):
    import random
    junk = random.Random(c).randbytes(1 + b % 64)
    i = a % (len(d) + 1)
    return d[:i] + junk + d[i:]


def _m_random_line(d, a, b, c):
    import random
    ls = _lines(d)
    ls[a % len(ls)] = random.Random(c).randbytes(1 + b % 200)
    return b"\n".join(ls)


def _m_odd_bytes(d, a, b, c):
    i = a % (len(d) + 1)
    return d[:i] + FUZZ_BYTES[b % len(FUZZ_BYTES)] + d[i:]


def _m_long_line(d, a, b, c):
    """A line of 200 000 characters: a line repeated, a long number, a long token list."""
    ls = _lines(d)
    i = a % len(ls)
    kind = b % 3
    if kind == 0:
        long = (ls[i] + b" ") * (1 + 200_000 // (len(ls[i]) + 1))
    elif kind == 1:
        long = ls[i] + b" " + b"7" * 200_000
    else:
        long = ls[i] + b" 1" * 100_000
    ls[i] = long[:200_000 + len(ls[i])]
    return b"\n".join(ls)


def _m_shift_number(d, a, b, c):
    """A number moved by a small amount or multiplied: a wrong index, a slightly wrong count."""
    regex = _fuzz_regexes()[0]
    hits = list(regex.finditer(d))
    if not hits:
        return d
    m = hits[a % len(hits)]
    text = m.group().decode()
    delta = (-2, -1, 1, 2, 10)[b % 5]
    try:
        new = str(int(text) + delta) if text.lstrip("-").isdigit() else repr(float(text) * (1 + delta))
    except ValueError:
        return d
    return d[:m.start()] + new.encode() + d[m.end():]


FUZZ_MUTATIONS = (_m_truncate, _m_delete_line, _m_duplicate_line, _m_swap_lines, _m_number,
                  _m_number_in_line, _m_token, _m_random_bytes, _m_random_line, _m_odd_bytes,
                  _m_long_line, _m_shift_number)


def mutate(data: bytes, ops) -> bytes:
    """``data`` after the mutations ``ops`` ((kind, a, b, c) integers), in order."""
    for kind, a, b, c in ops:
        data = FUZZ_MUTATIONS[kind % len(FUZZ_MUTATIONS)](data, a, b, c)
    return data


def fuzz_ops():
    """The hypothesis strategy of a list of one to three mutations."""
    from hypothesis import strategies as st
    word = st.integers(0, 2 ** 32 - 1)
    op = st.tuples(st.integers(0, len(FUZZ_MUTATIONS) - 1), word, word, word)
    return st.lists(op, min_size=1, max_size=3)


def fuzz_settings(examples: int):
    """hypothesis settings of a fuzz test: ``examples`` fixed (derandomised) cases in the
    short run, ``$TSPLCAM_FUZZ_EXAMPLES`` random ones in the long run. No example database
    (nothing written beside the checkout), no deadline (time is bounded per case instead)."""
    from hypothesis import HealthCheck, settings
    from hypothesis.configuration import set_hypothesis_home_dir
    # hypothesis keeps a cache of constants even without a database: in build/, not beside
    # the checkout's files
    set_hypothesis_home_dir(os.path.join(REPO_DIR, "build", "hypothesis"))
    return settings(max_examples=FUZZ_EXAMPLES or examples, derandomize=not FUZZ_EXAMPLES,
                    database=None, deadline=None, suppress_health_check=list(HealthCheck),
                    print_blob=True)


def fuzz_seeds(shipped=(), external_globs=()):
    """(name, bytes) of the seed files: ``shipped`` paths relative to tsplcam/data, and the
    files of ../shared/data/external matching ``external_globs`` (none when it is absent)."""
    import glob
    out = []
    for rel in shipped:
        path = os.path.join(REPO_DIR, "tsplcam", "data", rel)
        with open(path, "rb") as fh:
            out.append((os.path.basename(path), fh.read()))
    root = os.path.join(shared_dir(), "data", "external")
    for pattern in external_globs:
        for path in sorted(glob.glob(os.path.join(root, pattern))):
            with open(path, "rb") as fh:
                out.append((os.path.basename(path), fh.read()))
    return out


class FuzzTimeout(Exception):
    """A fuzz case ran longer than FUZZ_CASE_SECONDS."""


def fuzz_read(test, read, data: bytes, name: str, companions=None):
    """Write ``data`` to a fresh folder as ``name`` (with ``companions``, name -> bytes, beside
    it), call ``read(path)`` under a time limit and return what it returns, or None when it
    raised InputError naming the file and a line or key. Any other exception propagates
    (the test fails with it); a case over the time limit fails the test."""
    import re
    import signal
    import tempfile
    from tsplcam.errors import InputError

    def alarm(signum, frame):
        raise FuzzTimeout(f"{name}: still reading after {FUZZ_CASE_SECONDS:g} s")

    with tempfile.TemporaryDirectory(prefix="tsplcam-fuzz-") as folder:
        path = os.path.join(folder, name)
        for other, content in (companions or {}).items():
            with open(os.path.join(folder, other), "wb") as fh:
                fh.write(content)
        with open(path, "wb") as fh:
            fh.write(data)
        previous = signal.signal(signal.SIGALRM, alarm)
        signal.setitimer(signal.ITIMER_REAL, FUZZ_CASE_SECONDS)
        try:
            return read(path)
        except InputError as exc:
            named = os.path.realpath(str(exc.path)) if exc.path else ""
            test.assertEqual(os.path.dirname(named), os.path.realpath(folder),
                             f"the error does not name the file (or its companion): {exc}")
            # the line as an attribute, a key or record as ``item``, or the line in the text
            # (errors the kernel raises name the face or vertex with its line: "face 3 (line 12)")
            test.assertTrue(exc.line is not None or exc.item or re.search(r"\bline \d+", str(exc)),
                            f"the error names no line or key: {exc}")
            test.assertLess(len(str(exc)), 2000, "an error message should be one readable line")
            return None
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)


def assert_model_finite(test, model, samples: int = 3) -> None:
    """A few points of every patch (corners, edge middles, centre by default) have finite
    positions, first derivatives and normals."""
    import numpy as np
    g = np.linspace(0.0, 1.0, samples)
    U, V = np.meshgrid(g, g)
    test.assertGreater(len(model.patches), 0)
    for p in model.patches:
        s = p.evaluate(U.ravel(), V.ravel())
        for what, arr in (("position", s.P), ("Pu", s.Pu), ("Pv", s.Pv), ("normal", s.normal)):
            test.assertTrue(np.all(np.isfinite(arr)), f"{p.name}: {what} not finite")


def assert_fields_finite(test, obj, where: str = "") -> None:
    """Every number in ``obj`` (a dataclass, dict, list or tuple, walked through) is finite."""
    import dataclasses
    import math
    import numpy as np
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        for f in dataclasses.fields(obj):
            assert_fields_finite(test, getattr(obj, f.name), f"{where}.{f.name}")
    elif isinstance(obj, dict):
        for k, v in obj.items():
            assert_fields_finite(test, v, f"{where}[{k!r}]")
    elif isinstance(obj, (list, tuple)):
        for k, v in enumerate(obj):
            assert_fields_finite(test, v, f"{where}[{k}]")
    elif isinstance(obj, np.ndarray) and obj.dtype.kind == "f":
        test.assertTrue(np.all(np.isfinite(obj)), f"{where} is not finite")
    elif isinstance(obj, float):
        test.assertTrue(math.isfinite(obj), f"{where} = {obj!r}")


def read_refused(test, read, name: str, data: bytes, *fragments: str):
    """Write ``data`` as ``name`` in a fresh folder and assert that ``read(path)`` raises
    InputError naming that file, with each of ``fragments`` in its text; returns the error."""
    import tempfile
    from tsplcam.errors import InputError
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, name)
        with open(path, "wb") as fh:
            fh.write(data)
        with test.assertRaises(InputError) as cm:
            read(path)
    test.assertEqual(cm.exception.path, path)
    for f in fragments:
        test.assertIn(f, str(cm.exception))
    return cm.exception


# -- references shared by the kernel's tests (tests/model): a refinement of creased cages by
# OpenSubdiv's rules written out here, and a brute-force T-spline sum with rays cast on a grid of
# knot lines
import numpy as np  # noqa: E402
from scipy.interpolate import BSpline  # noqa: E402

from tsplcam.model.tmesh import TMesh, from_lines  # noqa: E402

INF = np.float32(10.0)


def decrement(s):
    s = np.asarray(s, np.float32)
    return np.where(s >= INF, INF, np.where(s > 1, s - np.float32(1), np.float32(0))).astype(np.float32)


def _add_at(out: np.ndarray, index, values) -> None:
    """np.add.at(out, index, values) by bincount per column (numpy 1.24's ufunc.at is some
    ten times slower); the sums' order may differ, within rounding."""
    index = np.asarray(index).reshape(-1)
    values = np.asarray(values, float)
    if out.ndim == 1:
        out += np.bincount(index, weights=np.broadcast_to(values, index.shape), minlength=len(out))
        return
    values = np.broadcast_to(values, (len(index),) + out.shape[1:])
    for c in range(out.shape[1]):
        out[:, c] += np.bincount(index, weights=values[:, c], minlength=len(out))


class RefMesh:
    """A cage with per-edge sharpness (float32), refined by the rules written out here."""

    def __init__(self, faces, points, sharp: dict, corner: dict, rule: str):
        self.F = np.asarray(faces, int)
        self.P = np.asarray(points, float)
        self.rule = rule
        nv = len(self.P)
        a = self.F.reshape(-1)
        b = np.roll(self.F, -1, axis=1).reshape(-1)
        key = np.minimum(a, b) * nv + np.maximum(a, b)
        self.ukey, self.einv = np.unique(key, return_inverse=True)
        self.E = np.column_stack([self.ukey // nv, self.ukey % nv])
        self.nfaces_e = np.bincount(self.einv, minlength=len(self.E))
        s = np.zeros(len(self.E), np.float32)
        if sharp:
            ab = np.array(list(sharp), int).reshape(-1, 2)
            s[np.searchsorted(self.ukey, ab.min(axis=1) * nv + ab.max(axis=1))] = list(sharp.values())
        self.s = s
        self.cs = np.zeros(nv, np.float32)
        for v, x in corner.items():
            self.cs[v] = x
        self.val = np.bincount(self.F.reshape(-1), minlength=nv)
        self.bnd_e = self.nfaces_e == 1
        bv = np.zeros(nv, bool)
        bv[self.E[self.bnd_e].reshape(-1)] = True
        self.bnd_v = bv

    def edge_s(self):
        return np.where(self.bnd_e, INF, self.s)

    def vertex_s(self):
        cs = self.cs.copy()
        if self.rule == "edge-and-corner":
            cs[self.bnd_v & (self.val == 1)] = INF
        return cs

    def _rules(self, es, vs):
        nv = len(self.P)
        sharp = es > 0
        count = np.bincount(self.E[sharp].reshape(-1), minlength=nv)
        ends = np.zeros((nv, 4))
        _add_at(ends, self.E[sharp, 0], self.P[self.E[sharp, 1]])
        _add_at(ends, self.E[sharp, 1], self.P[self.E[sharp, 0]])
        corner = (vs > 0) | (count > 2)
        crease = ~corner & (count == 2)
        return corner, crease, ends

    def refine(self) -> "RefMesh":
        F, P, E = self.F, self.P, self.E
        nv, ne, nf = len(P), len(E), len(F)
        FP = P[F].mean(axis=1)
        fsum = np.zeros((ne, 4))
        _add_at(fsum, self.einv, np.repeat(FP, 4, axis=0))
        es = self.edge_s()
        mid = 0.5 * (P[E[:, 0]] + P[E[:, 1]])
        smooth_e = 0.25 * (P[E[:, 0]] + P[E[:, 1]]) + 0.25 * fsum
        w = np.clip(es, 0, 1)[:, None].astype(float)
        EP = np.where((es >= 1)[:, None], mid, w * mid + (1 - w) * smooth_e)
        # vertex points
        n = self.val.astype(float)
        nsum = np.zeros((nv, 4))
        _add_at(nsum, E[:, 0], P[E[:, 1]])
        _add_at(nsum, E[:, 1], P[E[:, 0]])
        fpsum = np.zeros((nv, 4))
        _add_at(fpsum, F.reshape(-1), np.repeat(FP, 4, axis=0))
        with np.errstate(divide="ignore", invalid="ignore"):
            smooth_v = ((n - 2) / n)[:, None] * P + (nsum + fpsum) / (n * n)[:, None]
        vs = self.vertex_s()
        pc, pk, pends = self._rules(es, vs)
        ces, cvs = decrement(es), decrement(vs)
        cc, ck, cends = self._rules(ces, cvs)

        def mask(corner, crease, ends):
            return np.where(corner[:, None], P, np.where(crease[:, None], 0.75 * P + 0.125 * ends, smooth_v))

        mp, mc = mask(pc, pk, pends), mask(cc, ck, cends)
        same = (pc == cc) & (pk == ck)
        psmooth = ~pc & ~pk
        # fractional weight: edges becoming smooth (0 < s <= 1) and the vertex's own sharpness
        tr = (es > 0) & (es <= 1)
        tcount = np.bincount(E[tr].reshape(-1), minlength=nv).astype(float)
        tsum = np.zeros(nv)
        _add_at(tsum, E[tr, 0], es[tr])
        _add_at(tsum, E[tr, 1], es[tr])
        vt = (vs > 0) & (cvs <= 0)
        tcount += vt
        tsum += np.where(vt, vs, 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            fw = np.minimum(1.0, np.where(tcount > 0, tsum / tcount, 0.0))
        VP = np.where((psmooth | same)[:, None], mp, fw[:, None] * mp + (1 - fw)[:, None] * mc)
        # children
        e_of = self.einv.reshape(nf, 4)
        child = np.empty((4 * nf, 4), int)
        for k in range(4):
            child[k::4] = np.column_stack([F[:, k], nv + e_of[:, k], nv + ne + np.arange(nf), nv + e_of[:, (k + 3) % 4]])
        sharp = {}
        cs_e = decrement(self.s)
        for i in np.nonzero(cs_e > 0)[0]:
            a, b = E[i]
            sharp[(a, nv + i)] = cs_e[i]
            sharp[(b, nv + i)] = cs_e[i]
        corner = {int(v): decrement(self.cs[v]) for v in np.nonzero(decrement(self.cs) > 0)[0]}
        out = RefMesh(child, np.vstack([VP, EP, FP]), sharp, corner, self.rule)
        # where each child face lies in the root face: corner 0 and the two axes
        C = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
        O, X, Y = self.O, self.X, self.Y
        out.root = np.repeat(self.root, 4)
        out.O, out.X, out.Y = np.empty((4 * nf, 2)), np.empty((4 * nf, 2)), np.empty((4 * nf, 2))
        for k in range(4):
            def at(c):
                return O + X * c[0] + Y * c[1]
            ck, cn, cp = C[k], C[(k + 1) % 4], C[(k + 3) % 4]
            out.O[k::4] = at(ck)
            out.X[k::4] = at(ck + (cn - ck) / 2) - at(ck)
            out.Y[k::4] = at(ck + (cp - ck) / 2) - at(ck)
        return out

    def subset(self, keep: np.ndarray) -> "RefMesh":
        """The faces ``keep`` (mask) as a mesh of their own, with their places in the roots.
        Rules at the cut are wrong: use only what lies well inside."""
        F = self.F[keep]
        used = np.unique(F)
        new = np.full(len(self.P), -1)
        new[used] = np.arange(len(used))
        sharp = {}
        for i in np.nonzero(self.s > 0)[0]:
            a, b = self.E[i]
            if new[a] >= 0 and new[b] >= 0:
                sharp[(new[a], new[b])] = self.s[i]
        corner = {int(new[v]): self.cs[v] for v in np.nonzero(self.cs > 0)[0] if new[v] >= 0}
        out = RefMesh(new[F], self.P[used], sharp, corner, self.rule)
        out.root, out.O, out.X, out.Y = self.root[keep], self.O[keep], self.X[keep], self.Y[keep]
        out.ids = used
        return out

    def rings(self, v: int, count: int) -> np.ndarray:
        """Mask of the faces within ``count`` rings of vertex v (faces sharing a vertex)."""
        verts = np.zeros(len(self.P), bool)
        verts[v] = True
        faces = np.zeros(len(self.F), bool)
        for _ in range(count):
            faces |= verts[self.F].any(axis=1)
            verts[self.F[faces].reshape(-1)] = True
        return faces

    def start(self):
        nf = len(self.F)
        self.root = np.arange(nf)
        self.O = np.zeros((nf, 2))
        self.X = np.tile([1.0, 0.0], (nf, 1))
        self.Y = np.tile([0.0, 1.0], (nf, 1))
        return self

    def exact_limits(self):
        """Limit position of every vertex whose neighbourhood's rules no longer change, NaN
        elsewhere (semi-sharp edges or vertices left, darts, mixed creases)."""
        nv = len(self.P)
        es, vs = self.edge_s(), self.vertex_s()
        semi_e = (es > 0) & (es < INF)
        semi_v = (vs > 0) & (vs < INF)
        touch = np.zeros(nv, bool)
        touch[self.E[semi_e].reshape(-1)] = True
        out = np.full((nv, 3), np.nan)
        inf_e = es >= INF
        count = np.bincount(self.E[inf_e].reshape(-1), minlength=nv)
        ok = ~touch & ~semi_v
        corner = ok & ((vs >= INF) | (count > 2))
        out[corner] = self.P[corner, :3] / self.P[corner, 3:]
        crease = ok & ~corner & (count == 2)
        ends = np.zeros((nv, 4))
        _add_at(ends, self.E[inf_e, 0], self.P[self.E[inf_e, 1]])
        _add_at(ends, self.E[inf_e, 1], self.P[self.E[inf_e, 0]])
        Lc = (4 * self.P + ends) / 6
        out[crease] = Lc[crease, :3] / Lc[crease, 3:]
        smooth = ok & ~corner & (count == 0) & ~self.bnd_v
        n = self.val.astype(float)
        nsum = np.zeros((nv, 4))
        _add_at(nsum, self.E[:, 0], self.P[self.E[:, 1]])
        _add_at(nsum, self.E[:, 1], self.P[self.E[:, 0]])
        diag = np.zeros((nv, 4))
        for k in range(4):
            _add_at(diag, self.F[:, k], self.P[self.F[:, (k + 2) % 4]])
        with np.errstate(divide="ignore", invalid="ignore"):
            L = ((n * n)[:, None] * self.P + 4 * nsum + diag) / (n * (n + 5))[:, None]
        out[smooth] = L[smooth, :3] / L[smooth, 3:]
        return out

    def regular_jets(self, count: int = 4000, seed: int = 0):
        """At corner 0 of up to ``count`` random faces whose 3 x 3 control points around it
        are smooth, regular and unsharpened: (faces, P, Ps, Pt, Pss, Pst, Ptt) of the bicubic
        B-spline there, in the face's own parameters."""
        F, nv = self.F, len(self.P)
        es, vs = self.edge_s(), self.vertex_s()
        sharp_v = np.zeros(nv, bool)
        sharp_v[self.E[es > 0].reshape(-1)] = True
        good_v = (~sharp_v) & (vs <= 0) & (self.val == 4) & ~self.bnd_v
        # directed edge a -> b to (face, position of a), by one sorted search
        a = F.reshape(-1).astype(np.int64)
        b = np.roll(F, -1, axis=1).reshape(-1).astype(np.int64)
        keys = a * nv + b
        order = np.argsort(keys)
        skeys = keys[order]

        def across(x, y):                         # the face with directed edge x -> y, and x's place
            i = order[np.searchsorted(skeys, x.astype(np.int64) * nv + y)]
            return i // 4, i % 4

        cand = np.nonzero(good_v[F[:, 0]])[0]
        rng = np.random.default_rng(seed)
        cand = rng.permutation(cand)[:4 * count]
        v0, v1, v2, v3 = F[cand].T
        g, p = across(v0, v3)
        G = F[g]
        gp2, gp3 = G[np.arange(len(g)), (p + 2) % 4], G[np.arange(len(g)), (p + 3) % 4]
        h, r = across(v0, gp3)
        Hh = F[h]
        hr2, hr3 = Hh[np.arange(len(h)), (r + 2) % 4], Hh[np.arange(len(h)), (r + 3) % 4]
        k_, t = across(v0, hr3)
        kt2 = F[k_][np.arange(len(k_)), (t + 2) % 4]
        grid = {(0, 0): v0, (1, 0): v1, (1, 1): v2, (0, 1): v3, (-1, 1): gp2, (-1, 0): gp3,
                (-1, -1): hr2, (0, -1): hr3, (1, -1): kt2}
        ok = np.all([good_v[x] for x in grid.values()], axis=0)
        sel = np.nonzero(ok)[0][:count]
        Q = {key: self.P[x[sel], :3] / self.P[x[sel], 3:] for key, x in grid.items()}
        w = {-1: 1 / 6, 0: 4 / 6, 1: 1 / 6}
        P = sum(w[i] * w[j] * Q[(i, j)] for i in w for j in w)
        Ps = sum(w[j] * (Q[(1, j)] - Q[(-1, j)]) / 2 for j in w)
        Pt = sum(w[i] * (Q[(i, 1)] - Q[(i, -1)]) / 2 for i in w)
        Pss = sum(w[j] * (Q[(1, j)] - 2 * Q[(0, j)] + Q[(-1, j)]) for j in w)
        Ptt = sum(w[i] * (Q[(i, 1)] - 2 * Q[(i, 0)] + Q[(i, -1)]) for i in w)
        Pst = (Q[(1, 1)] - Q[(1, -1)] - Q[(-1, 1)] + Q[(-1, -1)]) / 4
        return cand[sel], P, Ps, Pt, Pss, Pst, Ptt


def grid_knots(X, Y, hsegs, vsegs, i, j):
    """Local knot vectors of the vertex at grid node (i, j), by the definition (Sederberg
    2003): walk along row j (column i) and collect the columns (rows) whose segments cross
    it; past the last one the last knot repeats. Independent of the kernel's mesh walk."""
    def crossing(segs, values, at, other, step):
        """The first two knot lines (from ``segs``) crossed walking from index ``at`` by
        ``step`` along the line at index ``other``; the last repeats past the end."""
        out, c = [], at + step
        while 0 <= c < len(values) and len(out) < 2:
            if any(ci == c and min(a, b) <= other <= max(a, b) for ci, a, b in segs):
                out.append(values[c])
            c += step
        while len(out) < 2:
            out.append(out[-1] if out else values[at])
        return out

    w, e = crossing(vsegs, X, i, j, -1), crossing(vsegs, X, i, j, 1)
    s, n = crossing(hsegs, Y, j, i, -1), crossing(hsegs, Y, j, i, 1)
    return np.array([w[1], w[0], X[i], e[0], e[1]]), np.array([s[1], s[0], Y[j], n[0], n[1]])


def basis(knots, x, nu=0):
    """B-spline basis function of ``knots`` (scipy), or its first derivative by
    N' = p (N_0 / (t_p - t_0) - N_1 / (t_(p+1) - t_1)) on its two sub-knot vectors."""
    if knots[-1] - knots[0] <= 0:
        return np.zeros_like(x)
    if nu == 0:
        return np.nan_to_num(BSpline.basis_element(knots, extrapolate=False)(x))
    p = len(knots) - 2
    out = np.zeros_like(x)
    for k, sign in ((knots[:-1], 1.0), (knots[1:], -1.0)):
        if k[-1] > k[0]:
            out += sign * p * basis(k, x) / (k[-1] - k[0])
    return out


def brute_force(mesh, X, Y, hsegs, vsegs, s, t):
    """S, S_s, S_t of sum w B P / sum w B with basis functions from scipy, (n, 3) each."""
    out = []
    K = [grid_knots(X, Y, hsegs, vsegs, i, j) for i, j in mesh.grid_index]
    w = mesh.weights
    for ds, dt in ((0, 0), (1, 0), (0, 1)):
        B = np.array([basis(xk, s, ds) * basis(yk, t, dt) for xk, yk in K]) * w[:, None]
        out.append(B)
    B, Bs, Bt = out
    W, Ws, Wt = B.sum(0), Bs.sum(0), Bt.sum(0)
    N = B.T @ mesh.points
    S = N / W[:, None]
    Ss = (Bs.T @ mesh.points - Ws[:, None] * S) / W[:, None]
    St = (Bt.T @ mesh.points - Wt[:, None] * S) / W[:, None]
    return S, Ss, St


def clamped_grid(nx, ny, seed=0, spacing=None):
    """Knot values of a clamped grid (zero outer intervals) with uneven spacing."""
    rng = np.random.default_rng(seed)
    gx = np.concatenate([[0.0], np.cumsum(rng.uniform(0.5, 2.0, nx - 3))])
    gy = np.concatenate([[0.0], np.cumsum(rng.uniform(0.5, 2.0, ny - 3))])
    X = np.concatenate([[0.0], gx, [gx[-1]]])
    Y = np.concatenate([[0.0], gy, [gy[-1]]])
    return X, Y


def t_junction_mesh(seed=1, analysis_suitable=True):
    """A clamped 12 x 10 grid of knot lines with T-junctions; with ``analysis_suitable`` the
    T-junctions' extensions do not cross (partition of unity and linear precision hold)."""
    X, Y = clamped_grid(12, 10, seed)
    nx, ny = len(X), len(Y)
    h = {j: (j, 0, nx - 1) for j in range(ny)}
    v = {i: (i, 0, ny - 1) for i in range(nx)}
    if analysis_suitable:
        h[4] = (4, 0, 5)             # a horizontal line stopping in the middle
        v[8] = (8, 5, ny - 1)        # a vertical line starting in the middle, far from it
        h[7] = (7, 6, nx - 1)
    else:
        h[4] = (4, 2, 7)
        v[5] = (5, 3, 8)
        v[7] = (7, 0, 6)
        h[6] = (6, 4, nx - 1)
    hsegs, vsegs = list(h.values()), list(v.values())
    rng = np.random.default_rng(seed + 7)
    P = rng.standard_normal((nx, ny, 3)) * 0.3
    P[..., 0] += X[:, None]
    P[..., 1] += Y[None, :]
    W = rng.uniform(0.5, 2.0, (nx, ny))
    mesh = from_lines(X, Y, hsegs, vsegs, P, W)
    return mesh, X, Y, hsegs, vsegs


def split_face(mesh: TMesh, f: int) -> TMesh:
    """Cut quad face f in two along the middle of its sides 0 and 2: two new vertices, the
    neighbours across those sides get T-junctions. Intervals halve."""
    loop = [int(x) for x in mesh.faces[f]]
    a, b, c, d = loop
    P = list(mesh.points)
    w = list(mesh.weights)
    m1, m2 = len(P), len(P) + 1
    P += [(P[a] + P[b]) / 2, (P[c] + P[d]) / 2]
    w += [1.0, 1.0]
    faces = [list(map(int, x)) for x in mesh.faces]
    corners = [list(x) for x in mesh.corners]
    iv = [list(map(float, x)) for x in mesh.intervals]
    da, db = iv[f][0], iv[f][1]

    def insert(u, v_, mid):
        for g, lp in enumerate(faces):
            n = len(lp)
            for k in range(n):
                if lp[k] == u and lp[(k + 1) % n] == v_:
                    half = iv[g][k] / 2
                    lp.insert(k + 1, mid)
                    iv[g][k:k + 1] = [half, half]
                    corners[g] = [x + 1 if x > k else x for x in corners[g]]
                    return

    insert(b, a, m1)
    insert(d, c, m2)
    faces[f], corners[f], iv[f] = [a, m1, m2, d], [0, 1, 2, 3], [da / 2, db, da / 2, db]
    faces.append([m1, b, c, m2])
    corners.append([0, 1, 2, 3])
    iv.append([da / 2, db, da / 2, db])
    return TMesh(np.array(P), np.array(w), faces, corners, iv)


def angle_between(a, b):
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.abs(np.einsum("ij,ij->i", a, b)))

