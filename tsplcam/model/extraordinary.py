"""Extraordinary points (star points) of a T-mesh.

An extraordinary point is an interior vertex whose faces do not make a full turn. Around it
the T-NURCC rule applies (Sederberg et al. 1998, 2003): the two rings of faces around the
point are evaluated by subdividing to the regular level (``stars.py``), with uniform or
non-uniform knot intervals on its spokes and T-junctions beyond its second ring. What that
construction cannot take is refused with an error naming the vertex or face: star points on
the boundary, T-junctions on the faces at a star point or on its neighbours, and star points
closer than three edges to each other (``stars.StarsTooClose``, which ``tspline.py`` turns
into the Catmull-Clark limit where the neighbourhood is a uniform cage: ``cage.py``,
``close_stars.py``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .tmesh import TMesh


@dataclass
class Extraordinary:
    """The extraordinary points of a T-mesh: ``interval[v]`` the mean knot interval of vertex
    v's spokes, ``face_vertex[f]`` the extraordinary corner of face f, ``stars[v]`` the
    star's faces, spoke and diagonal vertices and spoke intervals (``stars.find_stars``)."""
    interval: dict = field(default_factory=dict)
    face_vertex: dict = field(default_factory=dict)
    stars: dict = field(default_factory=dict)


def find_extraordinary(mesh: TMesh, walker=None) -> Extraordinary:
    """The extraordinary points of ``mesh``, refusing those the kernel cannot evaluate."""
    from .stars import find_stars
    from .twalk import Walker
    stars = find_stars(walker or Walker(mesh))
    out = Extraordinary(stars=stars)
    for v, (faces, _, _, d) in stars.items():
        out.interval[v] = float(np.mean(d))
        for f in faces:
            out.face_vertex[f] = v
    return out
