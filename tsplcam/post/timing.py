"""Machining-time estimate from the per-axis velocity and acceleration limits.

Model (docs/post.md section 5.3): the program is a chain of straight blocks in joint space. Block k
moves axis j by ``d[k, j]`` and may not take less than ``t_min[k]`` (tip length over the
programmed feed; 0 for rapids). Each axis runs a trapezoidal profile per block, capped at
``min(v_j, |d_kj| / t_min_k)``; an axis keeps its speed across a junction only when it keeps
its direction (it must pass through zero where it reverses or stops), and a forward and a
backward pass limit the junction speeds to what the acceleration allows
(``w_k^2 <= w_{k-1}^2 + 2 a |d_k|``). A block takes the longest of its axes' times and of
``t_min``. The axes are treated as independent inside a block, so this is a lower bound
for a controller without look-ahead tolerance, and a fair yardstick for comparing paths.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _minplus_forward(cap: np.ndarray, e: np.ndarray) -> np.ndarray:
    """u_k = min(cap_k, u_{k-1} + e_k) with u_{-1} = 0 and u_0 <= cap_0, vectorised.

    ``cap`` (m+1,) are squared speed caps at the junctions 0..m, ``e`` (m,) the squared
    speed gains 2 a D of the blocks between them (the min-plus recursion unrolls into a
    running minimum of cap - cumulative gain).
    """
    E = np.concatenate([[0.0], np.cumsum(e)])
    return E + np.minimum.accumulate(cap - E)


def axis_block_times(d: np.ndarray, t_min: np.ndarray, vmax: float, amax: float) -> np.ndarray:
    """Time (s) each block needs for one axis moving ``d`` (m,) (signed units), see module."""
    d = np.asarray(d, float)
    m = len(d)
    if m == 0:
        return np.zeros(0)
    D = np.abs(d)
    with np.errstate(divide="ignore", invalid="ignore"):
        V = np.where(t_min > 0, np.minimum(vmax, D / np.where(t_min > 0, t_min, 1.0)), vmax)
    V = np.where(D > 0, V, 0.0)
    sgn = np.sign(d)
    same = (sgn[:-1] == sgn[1:]) & (sgn[:-1] != 0)
    cap = np.zeros(m + 1)
    cap[1:-1] = np.where(same, np.minimum(V[:-1], V[1:]), 0.0) ** 2
    e = 2.0 * amax * D
    u = _minplus_forward(cap, e)
    u = _minplus_forward(u[::-1], e[::-1])[::-1]
    w = np.sqrt(np.maximum(u, 0.0))
    w0, w1 = w[:-1], w[1:]
    # Trapezoid with entry w0, exit w1, cruise cap V over distance D.
    peak2 = amax * D + 0.5 * (w0 ** 2 + w1 ** 2)
    peak = np.sqrt(np.maximum(peak2, 0.0))
    tri = (2.0 * peak - w0 - w1) / amax
    with np.errstate(divide="ignore", invalid="ignore"):
        cruise = D - (2.0 * V ** 2 - w0 ** 2 - w1 ** 2) / (2.0 * amax)
        trap = (2.0 * V - w0 - w1) / amax + cruise / np.where(V > 0, V, 1.0)
    t = np.where(peak <= V, tri, trap)
    return np.where(D > 0, t, 0.0)


def hms(seconds: float) -> str:
    """Seconds as h:mm:ss, the way machine displays show run times."""
    s = int(round(seconds))
    return f"{s // 3600:d}:{s // 60 % 60:02d}:{s % 60:02d}"


@dataclass
class TimeReport:
    """Estimated machining time of a posted program and the axis figures behind it."""
    total_s: float
    cut_s: float                 # blocks arriving at CUT points
    air_s: float                 # everything else (approach, links, retracts, rapids)
    feed_only_s: float           # path length over feed plus rapids at full speed: the naive figure
    blocks: int
    axis_names: tuple
    travel: np.ndarray           # per axis, mm or deg
    average_speed: np.ndarray    # travel / total time, per minute
    peak_speed: np.ndarray       # largest block average speed, per minute
    limiting_blocks: np.ndarray  # blocks whose time a given axis sets (feed-limited ones not counted)
    feed_limited_blocks: int
    block_time: np.ndarray = field(repr=False, default=None)
    block_limit: np.ndarray = field(repr=False, default=None)   # per block: axis setting its time, -1 the feed

    def time_by_limit(self) -> dict:
        """Seconds of the blocks whose time the feed (key "feed") or each axis sets; the values
        add up to ``total_s``. An axis sets a block's time when its velocity and acceleration
        limits make it need longer than the programmed feed; an axis cruising at exactly the
        feed's pace counts as the feed (``block_limit`` allows a relative 1e-9 for rounding,
        ``limiting_blocks`` does not)."""
        if self.block_limit is None:
            raise ValueError("this TimeReport was made without per-block limits")
        out = {"feed": float(self.block_time[self.block_limit < 0].sum())}
        for j, n in enumerate(self.axis_names):
            out[n] = float(self.block_time[self.block_limit == j].sum())
        return out

    def as_dict(self) -> dict:
        axes = {n: {"travel": float(self.travel[j]), "average_speed_per_min": float(self.average_speed[j]),
                    "peak_speed_per_min": float(self.peak_speed[j]),
                    "limiting_blocks": int(self.limiting_blocks[j])}
                for j, n in enumerate(self.axis_names)}
        return {"total_s": self.total_s, "cut_s": self.cut_s, "air_s": self.air_s,
                "feed_only_s": self.feed_only_s, "blocks": self.blocks,
                "feed_limited_blocks": self.feed_limited_blocks, "axes": axes}

    def summary(self) -> str:
        """Lines to print for a job."""
        lines = [f"machining time {hms(self.total_s)} ({self.total_s:.1f} s: cutting {self.cut_s:.1f} s, "
                 f"air {self.air_s:.1f} s; length/feed alone {self.feed_only_s:.1f} s), {self.blocks} blocks"]
        for j, n in enumerate(self.axis_names):
            unit = "mm" if j < 3 else "deg"
            lines.append(f"  {n}: travel {self.travel[j]:.1f} {unit}, average {self.average_speed[j]:.1f} "
                         f"{unit}/min, peak {self.peak_speed[j]:.1f} {unit}/min, "
                         f"limits {int(self.limiting_blocks[j])} blocks")
        lines.append(f"  feed limits {self.feed_limited_blocks} blocks")
        return "\n".join(lines)


def estimate(joints: np.ndarray, t_min: np.ndarray, vmax: np.ndarray, amax: np.ndarray,
             axis_names=("X", "Y", "Z", "A", "C"), cut: np.ndarray | None = None,
             rapid: np.ndarray | None = None) -> TimeReport:
    """Time of the blocks between consecutive joint rows (m+1, naxes).

    ``t_min`` (m,) is each block's programmed minimum time in seconds (0 for rapids),
    ``vmax`` (units/s) and ``amax`` (units/s^2) the per-axis limits; ``cut`` marks cutting
    blocks for the cut/air split; ``rapid`` marks rapid blocks for the naive figure.
    """
    joints = np.asarray(joints, float)
    d = np.diff(joints, axis=0)
    m = len(d)
    t_min = np.asarray(t_min, float).reshape(m)
    per_axis = np.column_stack([axis_block_times(d[:, j], t_min, vmax[j], amax[j])
                                for j in range(d.shape[1])]) if m else np.zeros((0, d.shape[1]))
    t = np.maximum(t_min, per_axis.max(axis=1) if m else np.zeros(0))
    total = float(t.sum())
    cut = np.zeros(m, bool) if cut is None else np.asarray(cut, bool)
    rapid = np.zeros(m, bool) if rapid is None else np.asarray(rapid, bool)
    D = np.abs(d)
    travel = D.sum(axis=0) if m else np.zeros(d.shape[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        avg = np.where(total > 0, travel / total * 60.0, 0.0)
        block_speed = np.where(t[:, None] > 0, D / t[:, None] * 60.0, 0.0)
    peak = block_speed.max(axis=0) if m else np.zeros(d.shape[1])
    axis_lim = per_axis.argmax(axis=1) if m else np.zeros(0, int)
    feed_lim = t_min >= per_axis.max(axis=1) if m else np.zeros(0, bool)
    limiting = np.array([np.count_nonzero((axis_lim == j) & ~feed_lim) for j in range(d.shape[1])])
    naive_rapid = (D / vmax[None, :]).max(axis=1) if m else np.zeros(0)
    feed_only = float(np.where(rapid, naive_rapid, t_min).sum())
    return TimeReport(total_s=total, cut_s=float(t[cut].sum()), air_s=float(t[~cut].sum()),
                      feed_only_s=feed_only, blocks=m, axis_names=tuple(axis_names), travel=travel,
                      average_speed=avg, peak_speed=peak, limiting_blocks=limiting,
                      feed_limited_blocks=int(np.count_nonzero(feed_lim & (t_min > 0))), block_time=t,
                      block_limit=np.where(t_min >= (1.0 - 1e-9) * per_axis.max(axis=1), -1, axis_lim)
                      if m else np.zeros(0, int))
