"""Path figures (docs/post.md section 5.1): lengths by kind of move, retractions, points.

A move is *air* when either of its ends is off the surface (patch -1: retract, rapid and
the approach back down), *link* when it is a LINK between two surface points, *cut*
otherwise. Lengths are of the contact points on the surface and of the ball centres in
the air (the same thing the tool tip travels for a constant axis).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..toolpath.path import Move, ToolPath


@dataclass
class PathMetrics:
    points: int
    lines: int
    cut_length: float            # mm
    link_length: float           # mm, feed moves on the surface between lines and patches
    air_length: float            # mm, retract + rapid + approach
    air_moves: int
    retractions: int
    rapid_moves: int
    patches: int

    @property
    def length(self) -> float:
        return self.cut_length + self.link_length + self.air_length

    def as_dict(self) -> dict:
        d = asdict(self)
        d["length"] = self.length
        return d


def path_metrics(path: ToolPath) -> PathMetrics:
    mv = np.asarray(path.move)[1:]
    on = path.patch >= 0
    surf = on[1:] & on[:-1]
    seg_s = np.linalg.norm(np.diff(path.contact, axis=0), axis=1)
    seg_c = np.linalg.norm(np.diff(path.center, axis=0), axis=1)
    cut = surf & (mv == Move.CUT)
    link = surf & (mv != Move.CUT)
    air = ~surf
    lines = np.unique(path.line[path.line >= 0])
    return PathMetrics(points=len(path), lines=int(len(lines)),
                       cut_length=float(seg_s[cut].sum()), link_length=float(seg_s[link].sum()),
                       air_length=float(seg_c[air].sum()), air_moves=int(np.count_nonzero(air)),
                       retractions=path.retractions, rapid_moves=int(np.count_nonzero(mv == Move.RAPID)),
                       patches=int(len(np.unique(path.patch[on]))))


def compare_table(rows: dict) -> str:
    """Side-by-side text table of PathMetrics (column name -> metrics)."""
    names = list(rows)
    fields = [("points", "points", "{:d}"), ("lines", "lines", "{:d}"),
              ("cut length mm", "cut_length", "{:.1f}"), ("link length mm", "link_length", "{:.1f}"),
              ("air length mm", "air_length", "{:.1f}"), ("air moves", "air_moves", "{:d}"),
              ("retractions", "retractions", "{:d}"), ("total length mm", "length", "{:.1f}")]
    out = [["", *names]]
    for label, attr, fmt in fields:
        out.append([label, *(fmt.format(getattr(rows[n], attr)) for n in names)])
    widths = [max(len(r[k]) for r in out) for k in range(len(out[0]))]
    return "\n".join("  ".join(c.rjust(w) if j else c.ljust(w) for j, (c, w) in enumerate(zip(r, widths)))
                     for r in out)
