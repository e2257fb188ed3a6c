"""Helpers the test files share (they are loaded by path, so they cannot import each other).

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


def require_freecad():
    """Import FreeCAD or skip: engine tests under plain pytest skip the OCCT comparisons."""
    try:
        import FreeCAD  # noqa: F401
        import Part  # noqa: F401
    except ImportError:
        raise unittest.SkipTest("FreeCAD is not importable here (run under freecadcmd)")
    return FreeCAD
