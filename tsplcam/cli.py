"""Command line of the engine: ``python3 -m tsplcam <command> ...``; runs without FreeCAD.

Commands: ``info``, ``job`` and ``path`` (:mod:`tsplcam.job`), ``batch``
(:mod:`tsplcam.batch`), ``plan`` (:mod:`tsplcam.plan.commands`), ``machines``
(:mod:`tsplcam.post.commands`).
Exit codes: 0 success, 2 bad input or a geometric refusal: one line on stderr naming the
option, file and line, or place on the part; no traceback, no file written.
"""
from __future__ import annotations

import argparse
import re
import sys

from . import __version__
from .errors import TsplcamError


def dependency_versions() -> dict[str, str]:
    """Versions of the Python packages the engine uses (or 'missing')."""
    import importlib.metadata as md
    out = {"python": sys.version.split()[0]}
    for dist in ("numpy", "scipy", "python-fcl", "elkai", "matplotlib", "distributed"):
        try:
            out[dist] = md.version(dist)
        except md.PackageNotFoundError:
            out[dist] = "missing"
    return out


def _cmd_info(args) -> int:
    print(f"tsplcam {__version__}")
    for name, version in dependency_versions().items():
        print(f"  {name:<11} {version}")
    return 0


class Parser(argparse.ArgumentParser):
    """argparse with a refusal on one line (usage is in --help), exit code 2; a list of
    numbers that starts with a minus sign is taken as the value of the option before it."""

    def error(self, message: str):
        self.exit(2, f"error: {message} (see `{self.prog} --help`)\n")

    def parse_known_args(self, args=None, namespace=None):
        return super().parse_known_args(joined_negative_lists(sys.argv[1:] if args is None else args), namespace)


_NUMBER = r"\s*-?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*"
_NEGATIVE_LIST = re.compile(rf"-(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*(?:,{_NUMBER})+")


def joined_negative_lists(argv: list[str]) -> list[str]:
    """``--tilt-range -30,30`` as ``--tilt-range=-30,30``: argparse reads a word that starts
    with a minus sign as an option unless it is one number, so a vector or range whose first
    number is negative (``--point -5,0,10``, ``--axis -1,0,0``) would be refused as a missing
    value; joined to the long option before it, it is that option's value."""
    out = list(argv)
    for i in range(1, len(out)):
        prev = out[i - 1]
        if (_NEGATIVE_LIST.fullmatch(out[i]) and prev.startswith("--") and "=" not in prev
                and len(prev) > 2):
            out[i - 1:i + 1] = [f"{prev}={out[i]}", None]
    return [a for a in out if a is not None]


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="python3 -m tsplcam",
                    description="Five-axis finishing paths for T-spline mold surfaces: model in, processing "
                                "list, tool path, tool axes and machine program out. Lengths in mm, angles "
                                "in degrees, feeds in mm/min.")
    parser.add_argument("--version", action="version", version=f"tsplcam {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("info", help="print the version and the installed dependency versions")
    p.set_defaults(func=_cmd_info)
    from .job import register
    register(sub, "job")
    from .plan.commands import register as register_plan
    register_plan(sub)
    register(sub, "path")
    from .batch import register as register_batch
    register_batch(sub)
    from .post.commands import register as register_post
    register_post(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except TsplcamError as exc:
        print("error: " + " ".join(str(exc).split()), file=sys.stderr)
        return 2
