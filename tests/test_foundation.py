"""The foundation: package metadata, engine/FreeCAD separation, command line."""
import os
import pkgutil
import subprocess
import unittest
import xml.etree.ElementTree as ET

import tsplcam
from conftest import REPO_DIR, needs_freecad

SYSTEM_PYTHON = "/usr/bin/python3"
NS = {"p": "https://wiki.freecad.org/Package_Metadata"}


def engine_modules():
    names = []
    for info in pkgutil.walk_packages(tsplcam.__path__, "tsplcam."):
        if info.name == "tsplcam.workbench" or info.name.startswith("tsplcam.workbench."):
            continue
        if info.name == "tsplcam.__main__":  # runs the command line when imported
            continue
        names.append(info.name)
    return names


class PackageMetadata(unittest.TestCase):
    def setUp(self):
        self.root = ET.parse(os.path.join(REPO_DIR, "package.xml")).getroot()

    def text(self, path):
        node = self.root.find(path, NS)
        self.assertIsNotNone(node, path)
        return node.text.strip()

    def test_fields_addon_manager_needs(self):
        self.assertEqual(self.text("p:name"), "tsplcam")
        self.assertEqual(self.text("p:version"), tsplcam.__version__)
        self.assertTrue(self.text("p:description"))
        self.assertEqual(self.text("p:license"), "LGPL-2.1-or-later")
        self.assertTrue(self.text("p:maintainer"))
        self.assertTrue(self.text("p:url").startswith("https://"))
        icon = self.text("p:icon")
        self.assertTrue(os.path.isfile(os.path.join(REPO_DIR, icon)), icon)
        self.assertTrue(os.path.isfile(os.path.join(REPO_DIR, "LICENSE")))

    def test_workbench_entry_loads_on_020(self):
        wb = self.root.find("p:content/p:workbench", NS)
        self.assertEqual(wb.find("p:classname", NS).text, "TsplcamWorkbench")
        self.assertEqual(wb.find("p:subdirectory", NS).text, "./")
        # A higher freecadmin makes FreeCAD 0.20.2 skip the workbench.
        self.assertEqual(wb.find("p:freecadmin", NS).text, "0.20")
        with open(os.path.join(REPO_DIR, "InitGui.py")) as f:
            self.assertIn("class TsplcamWorkbench", f.read())


@needs_freecad
class MetadataInFreeCAD(unittest.TestCase):
    def test_freecad_reads_the_metadata(self):
        import FreeCAD
        md = FreeCAD.Metadata(os.path.join(REPO_DIR, "package.xml"))
        self.assertEqual(md.Name, "tsplcam")
        self.assertEqual(md.Version, tsplcam.__version__)
        wbs = md.Content["workbench"]
        self.assertEqual(wbs[0].Classname, "TsplcamWorkbench")
        self.assertIn(wbs[0].FreeCADMin, ("0.20", "0.20.0"))


class EngineSeparation(unittest.TestCase):
    def test_engine_modules_do_not_import_freecad(self):
        modules = engine_modules()
        self.assertIn("tsplcam.cli", modules)
        code = ("import importlib, sys\n"
                f"for m in {modules!r}:\n"
                "    importlib.import_module(m)\n"
                "bad = sorted(k for k in sys.modules if k.split('.')[0] in "
                "('FreeCAD', 'FreeCADGui', 'Part', 'Path', 'CAM'))\n"
                "print(len(" + repr(modules) + "), bad)\n"
                "sys.exit(1 if bad else 0)\n")
        env = dict(os.environ, PYTHONPATH=REPO_DIR)
        res = subprocess.run([SYSTEM_PYTHON, "-c", code], capture_output=True, text=True,
                             env=env, cwd=REPO_DIR)
        self.assertEqual(res.returncode, 0, res.stdout + res.stderr)

    def test_workbench_is_the_only_freecad_code(self):
        offenders = []
        pkg = os.path.join(REPO_DIR, "tsplcam")
        for dirpath, dirnames, filenames in os.walk(pkg):
            if os.path.relpath(dirpath, pkg).split(os.sep)[0] == "workbench":
                continue
            for fn in filenames:
                if fn.endswith(".py"):
                    with open(os.path.join(dirpath, fn)) as f:
                        for line in f:
                            s = line.strip()
                            if s.startswith(("import FreeCAD", "from FreeCAD", "import Part",
                                             "import FreeCADGui")):
                                offenders.append(os.path.join(dirpath, fn))
        self.assertEqual(offenders, [])


class CommandLine(unittest.TestCase):
    def run_cli(self, *args):
        env = dict(os.environ, PYTHONPATH=REPO_DIR)
        return subprocess.run([SYSTEM_PYTHON, "-m", "tsplcam", *args], capture_output=True,
                              text=True, env=env, cwd=REPO_DIR)

    def test_info_reports_versions(self):
        res = self.run_cli("info")
        self.assertEqual(res.returncode, 0, res.stderr)
        self.assertIn(f"tsplcam {tsplcam.__version__}", res.stdout)
        for dep in ("numpy", "scipy", "python-fcl", "elkai"):
            self.assertRegex(res.stdout, rf"{dep}\s+\d+\.\d+")

    def test_unknown_command_is_an_error(self):
        res = self.run_cli("no-such-command")
        self.assertEqual(res.returncode, 2)


_FAULTS = """
import resource, sys
if sys.argv[1] == "1":
    from tsplcam.allocator import keep_freed_memory
    assert keep_freed_memory()
import numpy as np
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for mb in [2, 24, 6, 30, 1, 12] * 8:          # numpy temporaries of many sizes, made and freed
    x = np.empty(mb * 131072)
    x[:] = 1.0
    del x
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


class Allocator(unittest.TestCase):
    """tsplcam.allocator keeps freed memory for the next arrays: fewer page faults for the
    same temporaries (glibc only), and nothing at all inside FreeCAD."""

    def test_fewer_page_faults(self):
        import sys
        if not sys.platform.startswith("linux"):
            self.skipTest("glibc's mallopt")
        faults = [int(subprocess.run(["/usr/bin/python3", "-c", _FAULTS, k], cwd=REPO_DIR, check=True,
                                     capture_output=True, text=True).stdout) for k in ("0", "1")]
        self.assertLess(faults[1], 0.75 * faults[0], faults)

    def test_not_inside_freecad(self):
        import sys
        from unittest import mock
        from tsplcam import allocator
        with mock.patch.dict(sys.modules, {"FreeCAD": object()}), mock.patch.object(allocator, "_DONE", False):
            self.assertFalse(allocator.keep_freed_memory())
