"""An HTML report of a job with pictures: :func:`write_report` (see :mod:`.report`).

Reads every stage and :mod:`tsplcam.verify`; nothing in the pipeline imports it.
"""
from .report import write_report

__all__ = ["write_report"]
