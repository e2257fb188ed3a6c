"""Post stage: machine kinematics, controller dialects, feeds and machining time.

Small API::

    from tsplcam.post import post_program, load_machine
    result = post_program(toolpath, "mikron_ucp600_heidenhain", "heidenhain")
    result.write("part.h"); print(result.summary())

``post_program`` returns a :class:`PostResult` (program ``text``, motion rows, machine poses,
``time`` report). Machines: :func:`load_machine` (a shipped name, a name on
``$TSPLCAM_MACHINE_PATH`` or a ``.json`` path), :func:`list_machines`; schema in
``tsplcam/post/MACHINES.md``. Dialects: ``DIALECTS``.
"""
from .dialects import NAMES as DIALECTS  # noqa: F401
from .machine import Machine, load_machine, machine_files, read_machine  # noqa: F401
from .post import PostResult, post_program  # noqa: F401
from .timing import TimeReport  # noqa: F401


def list_machines() -> list:
    """(name, path) of every machine found by name, user folders first."""
    return sorted(machine_files().items())
