"""Plan stage: the processing list (patch order, start/finish corners, crossfeed).

shang2020 sections 3.2 to 3.4. What the path generator calls::

    from tsplcam.plan import load, plan, save
    plist = plan(layout)                  # or load("list.json", layout): checked against it
    for step in plist.steps:              # step.patch, .start, .finish (corners 0..3),
        ...                               # .crossfeed ('u'/'v'), .retract_before

The file format is documented in :mod:`tsplcam.plan.listfile` and PROCESSING-LIST.md.
"""
from .listfile import complete_file, dumps, load, loads, save  # noqa: F401
from .solve import complete, normalise_pins, pins_of, plan  # noqa: F401
from .steps import CROSSFEEDS, Pins, ProcessingList, Step, crossfeeds_for  # noqa: F401
