"""tsplcam: five-axis finishing tool paths for T-spline mold surfaces.

The engine (everything here except :mod:`tsplcam.workbench`) is pure Python over
numpy/scipy and never imports FreeCAD. Pipeline, one subpackage per stage:
model -> layout -> plan -> toolpath -> orientation -> post, with verify beside.
"""
import os
import sys

__version__ = "0.1.0"

if "numpy" not in sys.modules:          # one BLAS thread: same bytes on any machine (numerics.py)
    from .numerics import blas_environment
    blas_environment()

_PKG_DIR = os.path.dirname(os.path.abspath(__file__))


def resource_dir() -> str:
    """The checkout's ``resources`` folder (icons, Qt .ui files)."""
    return os.path.join(os.path.dirname(_PKG_DIR), "resources")


def data_dir() -> str:
    """Data shipped with the engine (sample models, machines, tools)."""
    return os.path.join(_PKG_DIR, "data")


def load(path, **options):
    """Read a surface model from ``path``; the format follows the file's extension.

    Returns a :class:`tsplcam.model.model.Model`. Errors name the file and line.
    """
    from .model.formats import load as _load
    return _load(path, **options)


def load_model(spec, **options):
    """A model from a file, or from the name of a shipped sample (keycap, keycap_mold, head,
    figure4, tjunction_mold, fusion_mold) when no file of that name exists. Errors name the file and line."""
    from .errors import InputError
    from .model.samples import SAMPLES, sample_path
    spec = os.fspath(spec)
    if not os.path.exists(spec):
        if spec in SAMPLES:
            return load(sample_path(spec), **options)
        raise InputError(f"no such file, nor a shipped sample ({', '.join(SAMPLES)})", path=spec)
    return load(spec, **options)
