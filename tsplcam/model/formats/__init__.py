"""Readers of model files, one module per format, and the one registry of them.

``READERS`` lists every reader: its name (kept with models in FreeCAD documents), the file
extensions it takes, a description for file dialogs, the function that reads a path, and
whether it makes a surface model (a :class:`tsplcam.model.model.Model`; other readers make
other things, such as triangle meshes for stock). ``load`` (``tsplcam.load``, the command
line), the workbench's File > Open types and import dialog, and the tests all take the
formats from here. A new format is a module here with a reading function and one entry in
``READERS``; reading modules are imported only when a file of theirs is read.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Callable

from ...errors import InputError


@dataclass(frozen=True)
class Reader:
    """One file format: ``read(path, **options)`` reads a file of it."""
    name: str
    extensions: tuple[str, ...]          # lower case, with the dot
    description: str
    read: Callable
    surface: bool = True                 # makes a surface Model

    @property
    def patterns(self) -> str:
        """Its extensions as file-dialog patterns ('*.obj')."""
        return " ".join("*" + e for e in self.extensions)


def _read_obj(path, **options):
    from ..cage import cage_model
    from .obj import read_obj
    return cage_model(read_obj(path, **options))


def _read_iga(path, **options):
    from .iga import iga_model
    return iga_model(path, **options)


def _read_tsm(path, **options):
    from .tsm import tsm_model
    return tsm_model(path, **options)


def _read_tspl(path, **options):
    from .native import native_model
    return native_model(path, **options)


def _read_mesh(path, **options):
    from .mesh import read_triangles
    return read_triangles(path, **options)


READERS: tuple[Reader, ...] = (
    Reader("obj", (".obj",), "subdivision cage (OBJ)", _read_obj),
    Reader("iga", (".iga",), "T-spline Bezier extraction (IGA)", _read_iga),
    Reader("tsm", (".tsm",), "T-Splines T-mesh (TSM)", _read_tsm),
    Reader("tspl", (".tspl",), "tsplcam native (TSPL)", _read_tspl),
    # stock, mold blocks and fixtures: (vertices, triangles), not a surface model
    Reader("mesh", (".obj",), "triangle mesh for stock and fixtures (OBJ)", _read_mesh, surface=False),
)


def surface_readers() -> list[Reader]:
    """The readers that make surface models, in the order dialogs list them."""
    return [r for r in READERS if r.surface]


def reader_for(path, surface: bool = True) -> Reader | None:
    """The reader of a file by its extension (among those that make a surface model, or
    among the others with ``surface=False``), or None."""
    ext = os.path.splitext(os.fspath(path))[1].lower()
    return next((r for r in READERS if r.surface == surface and ext in r.extensions), None)


def reader_named(name: str) -> Reader | None:
    """The reader called ``name`` ('obj', 'iga', ...), or None."""
    return next((r for r in READERS if r.name == name), None)


def load(path, **options):
    """A surface Model from a file, read by the reader its extension names."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError("no such file", path=path)
    reader = reader_for(path)
    if reader is None:
        known = ", ".join(e for r in surface_readers() for e in r.extensions)
        ext = os.path.splitext(path)[1].lower()
        raise InputError(f"unknown model file type {ext!r} (tsplcam reads {known})", path=path)
    from ...inputfile import naming
    with naming(path):                   # the kernel's errors about a whole surface name the file
        return reader.read(path, **options)
