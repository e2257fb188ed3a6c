"""Document changes that never leave a half-built object behind."""
from __future__ import annotations

from . import messages


def in_transaction(doc, title: str, what: str, work, on_failure=None):
    """Run ``work()`` inside an undoable transaction named ``title``; recompute and commit on
    success and return what it returned. On any error abort, remove every object ``work``
    added (also when undo is off), call ``on_failure``, report that ``what`` failed (file and
    line for InputErrors, no traceback dialog) and return None."""
    before = {o.Name for o in doc.Objects}
    doc.openTransaction(title)
    try:
        result = work()
        doc.recompute()
    except Exception as exc:
        doc.abortTransaction()
        for name in [o.Name for o in doc.Objects if o.Name not in before]:
            try:
                doc.removeObject(name)
            except Exception:
                pass
        if on_failure is not None:
            on_failure()
        messages.exception(title, exc, what)
        return None
    doc.commitTransaction()
    return result
