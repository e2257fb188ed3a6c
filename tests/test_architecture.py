"""The engine's layering, read from the source with ``ast`` (nothing is imported).

Package imports flow down the pipeline model -> layout -> plan -> toolpath -> orientation ->
post: a stage imports its own package and the stages before it. ``verify`` measures the
stages' results, so it may import all of them, and no stage imports it. ``tsplcam`` itself
(the package's ``load``, ``data_dir``), ``tsplcam.errors`` and the file helpers
``tsplcam.outfile`` (atomic writes), ``tsplcam.inputfile`` (reading text and JSON),
``tsplcam.numtext`` (numbers as text for the CL data and the programs), ``tsplcam.npfast``
(numpy's C functions for hot small calls) and ``tsplcam.compiled`` (the numba kernels; the
orientation's warm-up of them is handed in, so it imports no stage) are below everything. The settings, the program builder, the job, job files, batch runs and the command line
(``settings``, ``program``, ``job``, ``jobfile``, ``batch``, ``cli``, ``__main__``,
``run_in_freecad``) and the FreeCAD workbench sit on top. FreeCAD and its GUI modules are imported under ``tsplcam/workbench`` only.

Every import counts: module level and inside functions, absolute and relative, and
``importlib.import_module`` with a constant name.
"""
import ast
import os
import tempfile
import unittest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = "tsplcam"
STAGES = ("model", "layout", "plan", "toolpath", "orientation", "post")
BASE = {PACKAGE, f"{PACKAGE}.errors", f"{PACKAGE}.outfile", f"{PACKAGE}.inputfile", f"{PACKAGE}.progress",
        f"{PACKAGE}.numerics", f"{PACKAGE}.numtext", f"{PACKAGE}.npfast",
        f"{PACKAGE}.compiled"}  # importable from anywhere
TOP = ("settings", "program", "job", "jobfile", "batch", "report", "cli", "__main__", "run_in_freecad",
       "workbench")  # may import anything
FREECAD_MODULES = {"FreeCAD", "FreeCADGui", "Part", "Path", "CAM", "Mesh", "MeshPart", "Draft",
                   "Import", "ImportGui", "Sketcher", "pivy", "PySide", "PySide2", "PySide6"}

# Imports that break the rules; each entry must still exist (a stale one fails), so this
# list only ever shrinks. Empty: none today.
KNOWN: set = set()


def engine_modules():
    """(module name, path) of every Python file of the package."""
    root = os.path.join(REPO, PACKAGE)
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                rel = os.path.relpath(path, REPO)[:-3].split(os.sep)
                if rel[-1] == "__init__":
                    rel = rel[:-1]
                yield ".".join(rel), path


def imports(module: str, path: str):
    """(imported module, line) for every import in the file, relative ones resolved."""
    with open(path, encoding="utf-8") as fh:
        tree = ast.parse(fh.read(), path)
    package = module if path.endswith("__init__.py") else module.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = parts[:len(parts) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            yield target, node.lineno
            for alias in node.names:                # "from . import x" may name a module
                yield f"{target}.{alias.name}", node.lineno
        elif (isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", None))
              in ("import_module", "__import__") and node.args
              and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)):
            yield node.args[0].value, node.lineno


def part_of(module: str) -> str | None:
    """The first level under the package ('model', 'verify', 'pipeline', ...), or None for
    the package itself and errors."""
    if module in BASE or not module.startswith(PACKAGE + "."):
        return None
    return module.split(".")[1]


def known_module(name: str) -> bool:
    path = os.path.join(REPO, *name.split("."))
    return os.path.isdir(path) or os.path.isfile(path + ".py")


def violation(importer: str, target: str) -> str | None:
    """Why ``importer`` may not import ``target`` (None when it may)."""
    if not target.startswith(PACKAGE + ".") or not known_module(target):
        return None                                   # outside the package, or a name in it
    src, dst = part_of(importer), part_of(target)
    if src is None or dst is None or src == dst or src in TOP:
        return None
    if dst == "verify":
        return "the pipeline does not import verify"
    if dst in TOP:
        return f"{dst} is above every stage"
    if src == "verify":
        return None
    if src in STAGES and dst in STAGES and STAGES.index(dst) > STAGES.index(src):
        return f"{dst} comes after {src} in the pipeline"
    if src not in STAGES or dst not in STAGES:
        return f"{src} and {dst} are not stages of the pipeline"
    return None


class Layering(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.modules = list(engine_modules())
        cls.found = [(m, t, line, path) for m, path in cls.modules for t, line in imports(m, path)]

    def test_the_scan_sees_the_package(self):
        names = {m for m, _ in self.modules}
        for stage in STAGES + ("verify", "workbench"):
            self.assertIn(f"{PACKAGE}.{stage}", names)
        self.assertGreater(len(self.found), 300)

    def test_imports_flow_down_the_pipeline(self):
        bad, seen = [], set()
        for module, target, line, path in self.found:
            why = violation(module, target)
            if why is None:
                continue
            key = (module, target)
            seen.add(key)
            if key not in KNOWN:
                bad.append(f"{os.path.relpath(path, REPO)}:{line} imports {target}: {why}")
        self.assertEqual(bad, [], "\n".join(bad))
        stale = sorted(KNOWN - seen)
        self.assertEqual(stale, [], f"remove these mended imports from KNOWN: {stale}")

    def test_freecad_only_in_the_workbench(self):
        bad = [f"{os.path.relpath(path, REPO)}:{line} imports {target}"
               for module, target, line, path in self.found
               if target.split(".")[0] in FREECAD_MODULES and part_of(module) != "workbench"]
        self.assertEqual(bad, [], "\n".join(bad))

    def test_rules_catch_what_they_should(self):
        """The checker itself: upward, verify and sideways imports are refused."""
        self.assertIsNotNone(violation("tsplcam.model.cage", "tsplcam.layout.layout"))
        self.assertIsNotNone(violation("tsplcam.plan.solve", "tsplcam.verify.metrics"))
        self.assertIsNotNone(violation("tsplcam.post.post", "tsplcam.program"))
        self.assertIsNone(violation("tsplcam.plan.graph", "tsplcam.layout.layout"))
        self.assertIsNone(violation("tsplcam.verify.scallop", "tsplcam.toolpath.path"))
        self.assertIsNone(violation("tsplcam.job", "tsplcam.verify.metrics"))
        self.assertIsNone(violation("tsplcam.model.cage", "tsplcam.errors"))
        text = ("import numpy\n"
                "def f():\n    from ..layout.layout import Layout\n    import tsplcam.orientation\n"
                "    import importlib\n    importlib.import_module('tsplcam.verify.metrics')\n")
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "probe.py")
            with open(path, "w") as fh:
                fh.write(text)
            found = dict(imports("tsplcam.model.probe", path))
        self.assertIn("tsplcam.layout.layout", found)       # relative, inside a function
        self.assertIn("tsplcam.orientation", found)         # absolute
        self.assertIn("tsplcam.verify.metrics", found)      # import_module
        self.assertIsNotNone(violation("tsplcam.model.probe", "tsplcam.layout.layout"))


if __name__ == "__main__":
    unittest.main()
