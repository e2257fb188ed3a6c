"""``python3 -m tsplcam job ... --fcstd OUT.FCStd``: the job's results as a FreeCAD document.

The document holds the model, the processing list, the tool path, the program and a FreeCAD
CAM job with the program's moves, each made by the workbench's own code
(``fcstd_script``) from the results the job already computed (handed over pickled: nothing is
computed twice), and it opens in the GUI with every object valid.

Why FreeCAD's ``freecadcmd`` in a child process, rather than importing FreeCAD here: the
command line runs under the system Python without FreeCAD on its path; where FreeCAD's
library lives differs between packagings (Debian's /usr/lib/freecad-python3/lib, AppImages,
other systems), and importing it into the job would run FreeCAD's start-up (every Mod
folder's Init.py, its console redirection) inside the job's process. ``freecadcmd`` is
FreeCAD's own headless interpreter, found on PATH (or given by ``TSPLCAM_FREECADCMD``), and
it runs the same Python the workbench runs in. When the command line itself runs inside
FreeCAD (``freecadcmd tsplcam/run_in_freecad.py -- job ...``), the document is made in that
process instead. This module never imports FreeCAD.
"""
from __future__ import annotations

import json
import os
import pickle
import shutil
import subprocess
import sys
import tempfile

from ..errors import InputError

SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "fcstd_script.py")


def inside_freecad() -> bool:
    """True when this process is FreeCAD (freecadcmd or the GUI)."""
    return "FreeCAD" in sys.modules


def freecadcmd() -> str | None:
    """FreeCAD's headless interpreter: ``$TSPLCAM_FREECADCMD``, else freecadcmd on PATH."""
    given = os.environ.get("TSPLCAM_FREECADCMD")
    if given:
        return given if os.path.isfile(given) and os.access(given, os.X_OK) else None
    for name in ("freecadcmd", "FreeCADCmd", "freecadcmd-daily"):
        found = shutil.which(name)
        if found:
            return found
    return None


def check_fcstd(path: str, item: str = "fcstd") -> None:
    """Refuse ``--fcstd`` before the long work: a name that is not .FCStd, a folder that cannot
    be written, or no freecadcmd to write it."""
    from ..outfile import check_folder
    if not str(path).lower().endswith(".fcstd"):
        raise InputError("a FreeCAD document's name ends in .FCStd", path=path, item=item)
    if os.path.isdir(path):
        raise InputError("cannot write the FreeCAD document: it is a folder", path=path, item=item)
    check_folder(os.path.dirname(os.path.abspath(path)), "folder of the FreeCAD document", item=item)
    if not inside_freecad() and freecadcmd() is None:
        raise InputError("needs FreeCAD's freecadcmd (on PATH, or TSPLCAM_FREECADCMD)", item=item)


def model_file(spec: str) -> str:
    """The file a model option names (a shipped sample's file for a sample name)."""
    if os.path.exists(spec):
        return os.path.abspath(spec)
    from ..model.samples import SAMPLES, sample_path
    if spec in SAMPLES:
        return sample_path(spec)
    raise InputError("no such file, nor a shipped sample", path=spec, item="model")


def write_fcstd(settings, plist, toolpath, program, path: str | None = None, timeout: float = 1200.0) -> str:
    """Write the document (module doc) to ``path`` (default ``settings.fcstd``); returns it.
    Raises InputError naming ``fcstd`` when freecadcmd fails, with its last words."""
    path = os.path.abspath(path or settings.fcstd)
    exe = None if inside_freecad() else freecadcmd()
    if exe is None and not inside_freecad():
        raise InputError("needs FreeCAD's freecadcmd (on PATH, or TSPLCAM_FREECADCMD)", item="fcstd")
    tmp = tempfile.mkdtemp(prefix="tsplcam-fcstd-")
    try:
        stock = None
        if settings.stock:
            from ..program import load_stock
            stock = load_stock(settings)
        from dataclasses import replace
        program = replace(program, checker=None) if hasattr(program, "checker") else program
        data = {"settings": settings.to_dict(), "model_file": model_file(settings.model), "plist": plist,
                "toolpath": toolpath, "program": program, "stock": stock}
        out = os.path.join(tmp, os.path.basename(path))
        if exe is None:                          # already inside FreeCAD
            from .fcstd_script import build_document
            try:
                build_document(data, out)
            except Exception as exc:
                raise InputError(f"the FreeCAD document was not written: {exc}", item="fcstd") from None
            os.makedirs(os.path.dirname(path), exist_ok=True)
            shutil.move(out, path)
            return path
        job = os.path.join(tmp, "job.pickle")
        with open(job, "wb") as f:
            pickle.dump(data, f, protocol=pickle.HIGHEST_PROTOCOL)
        result = os.path.join(tmp, "result.json")
        env = dict(os.environ, TSPLCAM_FCSTD_JOB=job, TSPLCAM_FCSTD_OUT=out, TSPLCAM_FCSTD_RESULT=result)
        run = subprocess.run([exe, SCRIPT], env=env, cwd=tmp, capture_output=True, text=True, timeout=timeout)
        try:
            with open(result) as f:
                done = json.load(f)
        except (OSError, ValueError):
            tail = " ".join((run.stdout + run.stderr).split()[-40:])
            raise InputError(f"freecadcmd ended (code {run.returncode}) without writing the document: {tail}",
                             item="fcstd") from None
        if not done.get("ok"):
            raise InputError(f"the FreeCAD document was not written: {done.get('error')}", item="fcstd")
        os.makedirs(os.path.dirname(path), exist_ok=True)
        shutil.move(out, path)
        return path
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
