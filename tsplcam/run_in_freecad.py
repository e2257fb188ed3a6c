"""The tsplcam command line under FreeCAD's own Python, for machines where only FreeCAD
brings numpy and friends:

    freecadcmd /path/to/tsplcam/run_in_freecad.py -- job keycap --out DIR [--config JOB.json]

runs ``python3 -m tsplcam job keycap --out DIR ...`` inside ``freecadcmd`` and exits with its
exit code (0, or 2 with one line on stderr). Everything after ``--`` goes to tsplcam: without
it, freecadcmd reads options such as ``--scallop`` as its own and refuses them. Any command
works (``path``, ``plan``, ``machines``, ``info``); inside FreeCAD the engine stays in one
process (no forked workers), so ``batch`` is for plain ``python3``.

freecadcmd runs the file as a module named after it, not as ``__main__``; importing it as
``tsplcam.run_in_freecad`` does nothing.
"""
import os
import sys


def main(argv: list) -> int:
    """Run the tsplcam command line on ``argv`` (the arguments after ``--``)."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if root not in sys.path:
        sys.path.insert(0, root)
    from tsplcam.cli import main as cli_main
    try:
        return int(cli_main(argv) or 0)
    except SystemExit as exc:             # argparse's refusals and --help
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)


def _arguments(argv: list) -> list:
    """What follows ``--`` (or the script's name) on freecadcmd's command line."""
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    return argv[1:]


if __name__ != "tsplcam.run_in_freecad":
    code = main(_arguments(sys.argv))
    sys.stdout.flush()
    sys.stderr.flush()
    # freecadcmd would go on to open the arguments as documents: leave now, with the code
    os._exit(code)
