"""``python3 -m tsplcam plan``: plan, complete or check a processing list and print it as a table.

Examples::

    python3 -m tsplcam plan --example keycap --out list.json
    python3 -m tsplcam plan --example figure4 --start-patch 0 --finish-patch 11
    python3 -m tsplcam plan --example keycap --complete edited.json --out list.json
    python3 -m tsplcam plan --example keycap --check list.json

The layout comes from a model file (``tsplcam.load``; the preferred crossfeed then uses
the surface's true edge lengths) or from a named example layout (``--example``).
"""
from __future__ import annotations

import os

from ..errors import InputError


def _layout(args):
    """(layout, edge-length callable or None, model name) from --example or a model file."""
    from ..layout.examples import EXAMPLES
    if args.model and args.example:
        raise InputError("give a model file or --example, not both")
    if args.model:
        from .. import load
        from .graph import model_edge_lengths
        model = load(args.model)
        return model.layout(), model_edge_lengths(model), os.path.basename(args.model)
    if not args.example:
        raise InputError("give a model file or --example NAME (one of "
                         + ", ".join(EXAMPLES) + ")")
    return EXAMPLES[args.example](), None, f"example:{args.example}"


def _cmd_plan(args) -> int:
    from . import listfile
    from .solve import plan
    from .steps import Pins
    layout, edge_lengths, model = _layout(args)
    if args.check:
        plist = listfile.load(args.check, layout)
        print(plist.table(layout))
        print(f"{args.check}: the list is valid for {model}")
        return 0
    options = dict(exact_limit=args.exact_limit, edge_lengths=edge_lengths)
    if args.complete:
        plist = listfile.complete_file(args.complete, layout, **options)
        plist.model = plist.model or model
    else:
        pins = Pins(start_patch=args.start_patch, finish_patch=args.finish_patch)
        plist = plan(layout, pins, model=model, **options)
    print(plist.table(layout))
    if args.out:
        listfile.save(plist, args.out)
        print(f"wrote {args.out}")
    return 0


def register(subparsers) -> None:
    """Add the ``plan`` subcommand to the top-level parser's subparsers."""
    from ..layout.examples import EXAMPLES
    from .solve import EXACT_LIMIT
    p = subparsers.add_parser("plan", help="plan the processing list: patch order, transit "
                                           "corners, crossfeed (paper sections 3.2-3.4)")
    p.add_argument("model", nargs="?", help="model file (e.g. a .obj quad cage)")
    p.add_argument("--example", choices=sorted(EXAMPLES), help="plan a built-in layout")
    p.add_argument("--out", help="write the processing list (JSON) here")
    p.add_argument("--complete", metavar="LIST",
                   help="read an edited list, keep its pinned fields, solve the rest")
    p.add_argument("--check", metavar="LIST", help="check a list against the layout and print it")
    p.add_argument("--start-patch", type=int, help="pin the first patch")
    p.add_argument("--finish-patch", type=int, help="pin the last patch")
    p.add_argument("--exact-limit", type=int, default=EXACT_LIMIT,
                   help="certify LKH's order exactly up to this many patches "
                        f"(default {EXACT_LIMIT})")
    p.set_defaults(func=_cmd_plan)
