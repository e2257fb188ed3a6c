"""``python3 -m tsplcam machines``: list the machine definitions, or show one.

``machines`` lists every machine found by name ($TSPLCAM_MACHINE_PATH folders first, then
the shipped ones); ``machines show NAME`` prints one (NAME may also be a .json path),
``--json`` as a version-1 machine document that reads back to the same machine.
"""
from __future__ import annotations

import sys

from ..errors import TsplcamError
from .machine import load_machine, machine_files, read_machine


def _cmd_machines(args) -> int:
    if getattr(args, "machines_command", None) == "show":
        m = load_machine(args.name)
        sys.stdout.write(m.to_json() if args.json else m.summary() + "\n")
        return 0
    status = 0
    rows = []
    for name, path in sorted(machine_files().items()):
        try:
            m = read_machine(path)
        except TsplcamError as exc:
            print(f"error: {exc}", file=sys.stderr)
            status = 2
            continue
        rows.append((name, m.kind, m.controller, "".join(m.axis_names), m.title))
    if rows:
        w = max(len(r[0]) for r in rows)
        for name, kind, ctl, axes, title in rows:
            print(f"{name:<{w}}  {kind:<11} {ctl:<10} {axes}  {title}")
    return status


def register(subparsers) -> None:
    """Add the ``machines`` command to the tsplcam command line."""
    p = subparsers.add_parser("machines", help="list the five-axis machine definitions, or show one")
    sub = p.add_subparsers(dest="machines_command")
    s = sub.add_parser("show", help="print one machine definition")
    s.add_argument("name", help="machine name (see 'machines') or path to a .json machine file")
    s.add_argument("--json", action="store_true", help="print the machine as a tsplcam-machine JSON document")
    p.set_defaults(func=_cmd_machines)
