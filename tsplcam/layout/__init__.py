"""Layout stage: the patch adjacency graph (boundary links and corner links)."""
from .layout import CORNER_UV, EDGE_CORNERS, EdgeLink, Layout  # noqa: F401
