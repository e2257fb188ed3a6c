"""Job files: everything one job needs in a JSON object (schema in ``tsplcam/JOBFILE.md``).

The keys are the :class:`tsplcam.settings.JobSettings` field names the ``job`` command takes
(``model``, ``tool``, ``scallop``, ``orientation``, ``machine``, ``dialect``, ``out``, ...).
File names in it are relative to the job file's folder, so a folder of job files and models
can move as a whole: ``model``, ``stock``, ``processing_list`` and ``out`` always, ``tool``
and ``machine`` when they name a file (a value with a file extension or a slash; a bare
name such as ``ball1_keycap`` is a shipped tool, sample or machine).

``job --config FILE`` and ``batch`` read job files through :func:`job_settings`: unknown
keys and bad values are refused naming the file and the key; options given on the command
line beside the file override its values and are named as the command line spells them.
:func:`input_files` lists the files a job reads, for the batch's content hash.
"""
from __future__ import annotations

import os
from dataclasses import fields

from .errors import InputError
from .inputfile import read_json
from .settings import JobSettings, _check_value

#: keys whose value is always a file or folder name, relative to the job file
PATH_KEYS = ("model", "stock", "processing_list", "out")
#: keys whose value is a file name when it has an extension or a slash, else a shipped name
NAME_OR_PATH_KEYS = ("tool", "machine")
#: keys a job file may hold: the job command's options
KEYS = tuple(JobSettings.option_names("job"))


def looks_like_file(value: str) -> bool:
    """A value naming a file rather than a shipped sample, tool or machine: it has a file
    extension or a folder in it (shipped names have neither)."""
    return "/" in value or os.sep in value or bool(os.path.splitext(value)[1])


def resolve(data: dict, folder: str) -> dict:
    """``data`` with its file names made relative to ``folder`` (absolute ones stay). The
    model is a file when it has an extension or a slash, else a shipped sample name."""
    out = dict(data)
    for key in PATH_KEYS + NAME_OR_PATH_KEYS:
        value = out.get(key)
        if not isinstance(value, str) or not value.strip():
            continue                                     # refused by the value check
        if key in NAME_OR_PATH_KEYS or key == "model":
            if not looks_like_file(value):
                continue
        out[key] = os.path.normpath(os.path.join(folder, os.path.expanduser(value)))
    return out


def read_job_file(path: str) -> dict:
    """The job file's settings as a dict of field names to values, file names resolved
    against the file's folder, each value checked on its own; unknown keys and bad values
    are InputErrors naming the file and the key."""
    data, _ = read_json(path, "job file")
    if not isinstance(data, dict):
        raise InputError("a job file is a JSON object of option names and values "
                         "(tsplcam/JOBFILE.md)", path=path)
    unknown = sorted(str(k) for k in data if k not in KEYS)
    if unknown:
        known = ", ".join(KEYS)
        other = [k for k in unknown if k in {f.name for f in fields(JobSettings)}]
        why = (f" ({', '.join(other)}: an output of the path command; a job writes into 'out')" if other else "")
        raise InputError(f"unknown key{'s' if len(unknown) > 1 else ''} {', '.join(repr(k) for k in unknown)}"
                         f"{why} (known: {known})", path=path)
    by_name = {f.name: f for f in fields(JobSettings)}
    for key, value in data.items():
        _check_value(by_name[key], value, key)
    return resolve(data, os.path.dirname(os.path.abspath(path)))


def job_settings(path: str, overrides: dict | None = None, defaults: dict | None = None,
                 label=None) -> JobSettings:
    """JobSettings of the job file ``path``: ``defaults`` (the command's), then the file's
    values, then ``overrides`` (options given on the command line), checked together. An
    error about an override is named by ``label(field name)`` (how the command line spells
    it); any other names the file and the key."""
    overrides = dict(overrides or {})
    try:
        data = read_job_file(path)
    except InputError as exc:
        if exc.path is None:
            raise InputError(exc.message, path=path, line=exc.line, item=exc.item) from None
        raise
    merged = {**(defaults or {}), **data, **overrides}

    def name(key):
        return label(key) if (label is not None and key in overrides) else key
    try:
        return JobSettings(**merged).check(name)
    except InputError as exc:
        typed = set(overrides) | {name(k) for k in overrides}
        if exc.item not in typed and exc.path is None:          # about the file's values
            raise InputError(exc.message, path=path, line=exc.line, item=exc.item) from None
        raise


def input_files(s: JobSettings) -> list[tuple[str, str]]:
    """(option, file) of every file the job reads: the model (a shipped sample's file too),
    stock, processing list, tool and machine files (shipped ones too). A missing file is
    listed as it is named; reading it later gives the error."""
    from .model.samples import SAMPLES, sample_path
    from .orientation.tool import shipped_tools_dir
    out = []
    if s.model:
        out.append(("model", s.model if os.path.exists(s.model) or s.model not in SAMPLES else sample_path(s.model)))
    for key in ("stock", "processing_list"):
        if getattr(s, key):
            out.append((key, getattr(s, key)))
    if s.tool:
        shipped = os.path.join(shipped_tools_dir(), s.tool + ".json")
        out.append(("tool", s.tool if os.path.exists(s.tool) or not os.path.exists(shipped) else shipped))
    if s.machine:
        from .post.machine import machine_files
        files = {} if looks_like_file(s.machine) else machine_files()
        out.append(("machine", files.get(s.machine, s.machine)))
    return out
