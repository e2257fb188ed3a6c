"""``python3 -m tsplcam plan``: plan, complete or check a processing list and print it as a table.

Examples::

    python3 -m tsplcam plan --example keycap --out list.json
    python3 -m tsplcam plan --example figure4 --start-patch 0 --finish-patch 11
    python3 -m tsplcam plan --example keycap --complete edited.json --out list.json
    python3 -m tsplcam plan --example keycap --check list.json

The layout comes from a model (a file or a shipped sample name, ``tsplcam.load_model``;
the preferred crossfeed then uses the surface's true edge lengths) or from a named example
layout (``--example``).
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
        from .. import load_model
        from .graph import model_edge_lengths
        model = load_model(args.model)
        from ..layout.layout import Layout
        return Layout.from_model(model), model_edge_lengths(model), getattr(model, "name", "") or os.path.basename(args.model)
    if not args.example:
        raise InputError("give a model file or --example NAME (one of "
                         + ", ".join(EXAMPLES) + ")")
    return EXAMPLES[args.example](), None, f"example:{args.example}"


def _cmd_plan(args) -> int:
    from . import listfile
    from .solve import plan
    from .steps import Pins
    if args.out:
        from ..outfile import check_writable
        check_writable(args.out, "processing list", item="--out")
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
        listfile.save(plist, args.out)      # whole or not at all
        print(f"wrote {args.out}")
    return 0


def register(subparsers) -> None:
    """Add the ``plan`` subcommand to the top-level parser's subparsers."""
    from ..layout.examples import EXAMPLES
    from .solve import EXACT_LIMIT
    from ..model.samples import SAMPLES
    p = subparsers.add_parser("plan", help="plan the processing list: the order of the patches, where each "
                                           "zigzag starts and ends, and its crossfeed direction",
                              description="Plan, complete or check a processing list: patch order, start and "
                                          "finish corner and crossfeed direction of each patch's zigzag, chosen "
                                          "so the tool passes from patch to patch without retracting wherever "
                                          "the layout allows. Prints the list as a table.")
    p.add_argument("model", nargs="?", metavar="MODEL",
                   help=f"the part: a model file or a shipped sample ({', '.join(SAMPLES)})")
    p.add_argument("--example", choices=sorted(EXAMPLES), help="plan a built-in patch layout instead of a model")
    p.add_argument("--out", metavar="FILE", help="write the processing list (JSON) to this file")
    p.add_argument("--complete", metavar="LIST",
                   help="read an edited list, keep what it pins (order, corners, crossfeed), plan the rest")
    p.add_argument("--check", metavar="LIST", help="check a list against the part's layout and print it")
    p.add_argument("--start-patch", type=int, metavar="N", help="machine patch N first")
    p.add_argument("--finish-patch", type=int, metavar="N", help="machine patch N last")
    p.add_argument("--exact-limit", type=int, default=EXACT_LIMIT, metavar="N",
                   help="up to this many patches the order is checked against an exact search (fewest "
                        f"retractions, then fewest corner links; default {EXACT_LIMIT}, at most 16)")
    p.set_defaults(func=_cmd_plan)
