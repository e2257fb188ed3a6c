"""Readers and writers of surface files; ``load`` picks one by the file's extension."""
from __future__ import annotations

import os

from ...errors import InputError


def load(path, **options):
    """A Model from a file: .obj (quad cage), and the formats later readers add."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError("no such file", path=path)
    ext = os.path.splitext(path)[1].lower()
    if ext == ".obj":
        from ..cage import cage_model
        from .obj import read_obj
        return cage_model(read_obj(path, **options))
    if ext == ".iga":
        from .iga import iga_model
        return iga_model(path, **options)
    if ext == ".tsm":
        from .tsm import tsm_model
        return tsm_model(path, **options)
    if ext == ".tspl":
        from .native import native_model
        return native_model(path, **options)
    raise InputError(f"unknown model file type {ext!r}", path=path)
