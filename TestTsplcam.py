"""FreeCAD unit-test entry of tsplcam: ``freecadcmd -t TestTsplcam``.

Loads every ``tests/test_*.py`` of this checkout by path, under module names prefixed
``tsplcam_test_``, so no module called ``tests`` ever lands on FreeCAD's global
``sys.path`` (other addons ship one). GUI tests live in ``tests/gui`` and run from
``tests/gui/run_gui_tests.py`` under a real FreeCAD GUI, not here.
"""
import glob
import importlib.util
import os
import sys
import unittest

_ROOT = os.path.dirname(os.path.abspath(__file__))


def _load_file(path):
    name = "tsplcam_test_" + os.path.splitext(os.path.basename(path))[0]
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def suite(pattern="test_*.py", folder="tests"):
    """All tests of ``folder`` (relative to the checkout) as one unittest suite."""
    if _ROOT not in sys.path:
        sys.path.insert(0, _ROOT)
    loader = unittest.defaultTestLoader
    result = unittest.TestSuite()
    for path in sorted(glob.glob(os.path.join(_ROOT, folder, pattern))):
        result.addTests(loader.loadTestsFromModule(_load_file(path)))
    return result


def load_tests(loader, standard_tests, pattern):
    return suite()
