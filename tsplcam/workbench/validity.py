"""A result is valid only if every input it depends on recomputed successfully.

FreeCAD marks an object whose recompute failed ``Invalid`` (its State) but leaves what
depends on it as it was: a program would stay "Up-to-date" over a tool path that failed, and
export the previous G-code. Here:

* every tsplcam object's ``execute`` first calls :func:`check_inputs`, which raises
  :class:`StaleInput` when an input failed, so the object fails too;
* a document observer, after every recompute, recomputes (only) the tsplcam objects whose
  inputs failed: their execute raises at once and FreeCAD marks them ``Invalid`` with the
  reason ("input ... failed to recompute: ..."), down the whole chain (processing list ->
  tool path -> program -> CAM operation). Fixing the input and recomputing makes them valid
  again;
* :func:`problem` says why a result must not be used (an invalid or touched object in its
  chain, or a stored result older than its inputs); export refuses with that reason.
"""
from __future__ import annotations

import FreeCAD

from ..errors import InputError

TSPLCAM_TYPES = ("TsplcamModel", "TsplcamProcessingList", "TsplcamToolPath", "TsplcamProgram",
                 "TsplcamCamOperation")


class StaleInput(InputError):
    """An input of the object failed to recompute or is out of date."""


def is_tsplcam(obj) -> bool:
    return getattr(getattr(obj, "Proxy", None), "Type", None) in TSPLCAM_TYPES


def failed(obj) -> bool:
    return "Invalid" in obj.State or "Error" in obj.State


def status_text(obj) -> str:
    try:
        text = obj.getStatusString()
    except Exception:
        text = ""
    return "" if text in ("", "Valid", "Touched") else text


def _failure(obj) -> str:
    why = status_text(obj)
    return f"{obj.Label} failed to recompute" + (f": {why}" if why else "")


def _root_failure(objs) -> str | None:
    """The failure of the deepest failed object among ``objs`` (the cause, not its echoes)."""
    bad = [o for o in objs if failed(o)]
    if not bad:
        return None
    return _failure(min(bad, key=lambda o: len(o.OutListRecursive)))


def input_problem(obj) -> str | None:
    """Why an input of ``obj`` (a direct link, or what it depends on) cannot be used, or None."""
    if not any(failed(o) for o in obj.OutList):
        return None
    return "input " + _root_failure(obj.OutListRecursive)


def check_inputs(obj) -> None:
    """Raise StaleInput when an input of ``obj`` failed (call first in ``execute``)."""
    why = input_problem(obj)
    if why is not None:
        raise StaleInput(why)


def problem(obj) -> str | None:
    """Why the result of ``obj`` must not be used, or None: ``obj`` or anything it depends on
    failed, was changed and not recomputed, or holds a result older than its inputs."""
    chain = [obj] + [o for o in obj.OutListRecursive]
    why = _root_failure(chain)
    if why is not None:
        return why
    for o in chain:
        if "Touched" in o.State:
            return f"{o.Label} was changed and not recomputed (recompute first)"
    for o in chain:
        stale = getattr(getattr(o, "Proxy", None), "stale", None)
        if callable(stale):
            why = stale(o)
            if why:
                return f"{o.Label}: {why}"
    return None


def _order(doc) -> list:
    """Objects of ``doc``, inputs before what depends on them."""
    objs = list(doc.Objects)
    rank = {o.Name: len(o.OutListRecursive) for o in objs}
    return sorted(objs, key=lambda o: rank[o.Name])


class _Observer:
    """After each recompute of a document: the tsplcam objects whose inputs failed fail too."""
    busy = False

    def slotRecomputedDocument(self, doc):
        if _Observer.busy:
            return
        _Observer.busy = True
        try:
            for o in _order(doc):
                if is_tsplcam(o) and not failed(o) and input_problem(o):
                    try:
                        o.recompute()
                    except Exception:
                        pass
                    _redraw(o)
                elif is_tsplcam(o):
                    _redraw(o, only_if_changed=True)
        finally:
            _Observer.busy = False


def _redraw(obj, only_if_changed: bool = False) -> None:
    """Let the view show whether the object is valid (views that draw it keep ``drawn_valid``)."""
    vp = getattr(getattr(obj, "ViewObject", None), "Proxy", None)
    if vp is None or not hasattr(vp, "rebuild"):
        return
    if only_if_changed and getattr(vp, "drawn_valid", not failed(obj)) == (not failed(obj)):
        return
    try:
        vp.rebuild()
    except Exception:
        pass


_observer = None


def install() -> None:
    """Register the document observer once per FreeCAD session."""
    global _observer
    if _observer is None:
        _observer = _Observer()
        FreeCAD.addDocumentObserver(_observer)
