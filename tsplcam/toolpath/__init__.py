"""Toolpath stage: isoparametric zigzag paths with scallop-height control."""
from .path import Move, ToolPath  # noqa: F401
