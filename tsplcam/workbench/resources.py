"""Paths of the workbench's icons and Qt .ui files."""
import os

import tsplcam


def icon(name: str) -> str:
    return os.path.join(tsplcam.resource_dir(), "icons", name + ".svg")


def ui_file(name: str) -> str:
    return os.path.join(tsplcam.resource_dir(), "ui", name + ".ui")
