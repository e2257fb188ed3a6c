"""Defaults of new tool paths and programs: the preferences page "T-spline CAM".

The values live in FreeCAD's parameters (``User parameter:BaseApp/Preferences/Mod/tsplcam/
Defaults``), one JSON value per option of :class:`tsplcam.settings.JobSettings` that differs
from the engine's default; an option never set there keeps the engine's default, so the
command line and a fresh workbench make the same program. The page (Edit > Preferences >
T-spline CAM) shows every option of ``fields.PATH_FIELDS`` and ``fields.PROGRAM_FIELDS``
with its unit, in the controls of the task panel (``controls``).
"""
from __future__ import annotations

import json

import FreeCAD

from . import messages
from .fields import PREFS_FIELDS as ALL_FIELDS, checked

PARAMS = "User parameter:BaseApp/Preferences/Mod/tsplcam/Defaults"


def _group():
    return FreeCAD.ParamGet(PARAMS)


def stored() -> dict:
    """The options set on the preferences page (name -> value)."""
    g = _group()
    out = {}
    for f in ALL_FIELDS:
        text = g.GetString(f.name, "")
        if not text:
            continue
        try:
            value = json.loads(text)
        except ValueError:
            continue
        out[f.name] = tuple(value) if isinstance(value, list) else value
    return out


def defaults(table=ALL_FIELDS) -> dict:
    """The default of every option of ``table``: the preferences page's value where set and
    valid, else JobSettings'. A stored value JobSettings refuses is reported and left out."""
    values = {f.name: f.default for f in ALL_FIELDS}
    for name, value in stored().items():
        try:
            checked({**values, name: value, "tool_radius": values.get("tool_radius") or 0.5})
        except Exception as exc:
            messages.warning("T-spline CAM preferences", f"default of {name} ignored: {messages.describe(exc)}")
            continue
        values[name] = value
    return {f.name: values[f.name] for f in table}


def store(values: dict) -> None:
    """Keep ``values`` (checked together first; errors name the property) as the defaults;
    an option equal to JobSettings' default is cleared, so later engine defaults apply."""
    merged = {f.name: f.default for f in ALL_FIELDS}
    merged.update(values)
    checked({**merged, "tool_radius": merged.get("tool_radius") or 0.5})
    g = _group()
    for f in ALL_FIELDS:
        if f.name not in values:
            continue
        v = values[f.name]
        if v == f.default:
            g.RemString(f.name)
        else:
            g.SetString(f.name, json.dumps(list(v) if isinstance(v, tuple) else v))


def clear() -> None:
    """Back to the engine's defaults."""
    g = _group()
    for f in ALL_FIELDS:
        g.RemString(f.name)
