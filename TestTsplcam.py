"""FreeCAD unit-test entry of tsplcam: ``freecadcmd -t TestTsplcam``.

Runs the test classes that need FreeCAD (marked ``@needs_freecad`` in ``tests/conftest.py``:
document objects, OCCT comparisons); plain pytest runs all the others, so each test runs
once. Test files ``tests/**/test_*.py`` are loaded by path under module names prefixed
``tsplcam_test_``, so no module called ``tests`` lands on FreeCAD's global ``sys.path``
(other addons ship one). GUI tests live in ``tests/gui`` and run from
``tests/gui/run_gui_tests.py`` under a real FreeCAD GUI, not here.
"""
import glob
import importlib.util
import os
import sys
import unittest

_ROOT = os.path.dirname(os.path.abspath(__file__))
_TESTS = os.path.join(_ROOT, "tests")


def _load_file(path, prefix="tsplcam_test_"):
    name = prefix + os.path.splitext(os.path.basename(path))[0]
    if name in sys.modules:
        return sys.modules[name]
    folder = os.path.dirname(os.path.abspath(path))
    if folder not in sys.path:               # a test may import a sibling's helpers, as under pytest
        sys.path.append(folder)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def _flat(suite):
    for t in suite:
        if isinstance(t, unittest.TestSuite):
            yield from _flat(t)
        else:
            yield t


def test_files(folder="tests"):
    """``folder``'s test files (relative to the checkout), subfolders included, gui excepted
    unless ``folder`` is the gui folder itself."""
    root = os.path.join(_ROOT, folder)
    paths = sorted(glob.glob(os.path.join(root, "**", "test_*.py"), recursive=True))
    gui = os.path.join(_TESTS, "gui") + os.sep
    if not root.rstrip(os.sep).endswith(os.path.join("tests", "gui")):
        paths = [p for p in paths if not p.startswith(gui)]
    return paths


def suite(folder="tests", only_freecad=True):
    """The tests of ``folder`` as one unittest suite; with ``only_freecad`` just the classes
    marked ``needs_freecad`` (the rest is pytest's)."""
    for p in (_ROOT, _TESTS):
        if p not in sys.path:
            sys.path.insert(0, p)
    loader = unittest.defaultTestLoader
    result = unittest.TestSuite()
    for path in test_files(folder):
        tests = loader.loadTestsFromModule(_load_file(path))
        if only_freecad:
            tests = [t for t in _flat(tests) if getattr(type(t), "needs_freecad", False)
                     or isinstance(t, unittest.loader._FailedTest)]
        result.addTests(tests)
    return result


def load_tests(loader, standard_tests, pattern):
    return suite()
