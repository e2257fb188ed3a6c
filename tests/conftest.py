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
