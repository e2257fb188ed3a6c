"""Run tsplcam's GUI tests inside a real FreeCAD GUI (under Xvfb), then exit.

Started by scripts/test.sh as
    QTWEBENGINE_DISABLE_SANDBOX=1 xvfb-run -a -s "-screen 0 1280x1024x24" freecad tests/gui/run_gui_tests.py
Loads tests/gui/test_*.py by path (module names prefixed tsplcam_guitest_), runs them with
unittest, prints the summary and writes it to $TSPLCAM_GUI_RESULT, and leaves with
os._exit(0 or 1): the FreeCAD window never waits for a person.
"""
import os
import sys
import traceback
import unittest


def _main():
    import FreeCAD
    here = os.path.dirname(os.path.abspath(os.environ.get("TSPLCAM_GUI_RUNNER", __file__)))
    repo = os.path.dirname(os.path.dirname(here))
    if repo not in sys.path:
        sys.path.insert(0, repo)
    import TestTsplcam
    suite = TestTsplcam.suite(folder=os.path.join("tests", "gui"), only_freecad=False)
    stream = sys.__stdout__  # not the Report view, which the tests read
    result = unittest.TextTestRunner(stream=stream, verbosity=2).run(suite)
    summary = (f"GUI tests: ran {result.testsRun}, failures {len(result.failures)}, "
               f"errors {len(result.errors)}, skipped {len(result.skipped)}")
    print(summary, file=stream)
    out = os.environ.get("TSPLCAM_GUI_RESULT")
    if out:
        with open(out, "w") as f:
            f.write(("OK " if result.wasSuccessful() else "FAILED ") + summary + "\n")
    return 0 if result.wasSuccessful() else 1


try:
    code = _main()
except Exception:
    traceback.print_exc()
    code = 1
sys.stdout.flush()
sys.stderr.flush()
os._exit(code)
