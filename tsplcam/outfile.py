"""Output files (and folders) written whole or not at all.

Every file tsplcam writes for a user (G-code, CL data, processing list, report) goes
through :func:`write_text`: the text is written to a hidden temporary file in the same
folder and renamed over the target with ``os.replace``, which is atomic on one file
system. A failure (full disk, missing or read-only folder, interrupted run) leaves the old
file or no file, never a truncated program a machine could run. :func:`write_texts`
writes several files so that none of them is replaced before all of them are written.
A folder made elsewhere (the report's pictures) is put in place by :func:`replace_folder`.
"""
from __future__ import annotations

import os
import shutil
import tempfile

from .errors import InputError


def check_writable(path: str, what: str = "file", item: str | None = None) -> None:
    """Refuse, before any work is done, an output whose folder is missing or not writable,
    or that names a folder."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        raise InputError(f"cannot write the {what}: it is a folder", path=path, item=item)
    if not os.path.isdir(folder):
        raise InputError(f"cannot write the {what}: no such folder {folder}", path=path, item=item)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"cannot write the {what}: the folder {folder} is not writable", path=path, item=item)


def check_folder(folder: str, what: str = "output folder", item: str | None = None) -> None:
    """Refuse a folder that cannot be made or written: the nearest existing one of it and
    its parents must be a writable folder (the rest is made when the files are written)."""
    folder = os.path.abspath(os.fspath(folder))
    probe = folder
    while not os.path.exists(probe):
        probe = os.path.dirname(probe)
    if not os.path.isdir(probe):
        raise InputError(f"cannot make the {what}: {probe} is a file, not a folder", path=folder, item=item)
    if not os.access(probe, os.W_OK | os.X_OK):
        raise InputError(f"cannot write the {what}: {probe} is not writable", path=folder, item=item)


def _temporary(path: str, text: str, encoding: str, what: str) -> str:
    """Write ``text`` to a new hidden file beside ``path``; returns its name."""
    folder, name = os.path.split(os.path.abspath(path))
    data = text.encode(encoding)
    for attempt in range(100):
        tmp = os.path.join(folder, f".{name}.{os.getpid()}.{attempt}.tmp")
        try:
            # 0o666 minus the umask, as open(path, "w") would give
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise InputError(f"cannot write the {what}: {exc.strerror}", path=path) from None
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
        except BaseException as exc:
            _remove(tmp)
            if isinstance(exc, OSError):
                raise InputError(f"cannot write the {what}: {exc.strerror}", path=path) from None
            raise
        return tmp
    raise InputError(f"cannot write the {what}: no free temporary name", path=path)


def _remove(tmp: str) -> None:
    try:
        os.unlink(tmp)
    except OSError:
        pass


def write_texts(files, encoding: str = "utf-8") -> list[str]:
    """Write ``files`` ((path, text, what) triples, or (path, text, what, encoding)): every
    text to its temporary file first, then every rename; on a failure no temporary file is
    left and no target is touched. Returns the paths. LF line ends, bytes exactly as given."""
    done = []
    try:
        for entry in files:
            path, text, what = entry[:3]
            enc = entry[3] if len(entry) > 3 else encoding
            done.append((os.fspath(path), _temporary(os.fspath(path), text, enc, what), what))
        for path, tmp, what in done:
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise InputError(f"cannot write the {what}: {exc.strerror}", path=path) from None
    except BaseException:
        for _, tmp, _ in done:          # the renamed ones are gone already
            _remove(tmp)
        raise
    return [path for path, _, _ in done]


def write_text(path, text: str, encoding: str = "utf-8", what: str = "file") -> None:
    """Write ``text`` to ``path`` atomically (see the module doc); errors are InputErrors
    naming the file."""
    write_texts([(path, text, what, encoding)])


def make_folders(folder: str) -> list[str]:
    """Make ``folder`` and its missing parents; returns the ones made, outermost first (to
    remove them again when the run fails)."""
    made, probe = [], os.path.abspath(os.fspath(folder))
    while not os.path.exists(probe):
        made.append(probe)
        probe = os.path.dirname(probe)
    os.makedirs(folder, exist_ok=True)
    return made[::-1]


def replace_folder(new: str, target: str, what: str = "folder") -> None:
    """Put the folder ``new`` where ``target`` is (both on one file system): an old
    ``target`` is renamed away first and removed after, so ``target`` is never a mix of the
    two; on a failure the old one is put back."""
    old = None
    if os.path.lexists(target):
        old = tempfile.mkdtemp(prefix=".old-", dir=os.path.dirname(os.path.abspath(target)))
        os.replace(target, os.path.join(old, "x"))
    try:
        os.replace(new, target)
    except OSError as exc:
        if old is not None:
            os.replace(os.path.join(old, "x"), target)
        raise InputError(f"cannot write the {what}: {exc.strerror}", path=target) from None
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
