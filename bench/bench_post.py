"""Post speed: 200,000 path points to a five-axis program.

    /usr/bin/python3 bench/bench_post.py

Prints, for each shipped machine and its dialect, the points per second of post_program
(kinematics, branch choice, unwinding, approach, linearisation, feeds, time estimate, text),
and the ratio of the vectorised kinematics (both solutions, joints, forward check) against
a per-point Python loop doing the same closed-form computation with the math module,
measured in the same run.
"""
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from tsplcam.post import load_machine, post_program  # noqa: E402
from tsplcam.post.kinematics import forward, inverse_orientation, linear_joints  # noqa: E402
from tsplcam.post.synthetic import hemisphere_sweep  # noqa: E402
from common import best_of  # noqa: E402

N = 200_000


def loop_reference(tips, axes, pivot_a, origin):
    """ISO A/C trunnion, per point: both solutions and the linear joints (Python floats)."""
    out = []
    ya, za = pivot_a[1], pivot_a[2]
    for (x, y, z), (kx, ky, kz) in zip(tips.tolist(), axes.tolist()):
        th = math.atan2(math.hypot(kx, ky), kz)
        ph = math.atan2(kx, -ky)
        for t, p in ((th, ph), (-th, ph + math.pi)):
            # part turns by -C about Z, then by -A about the A line (sign -1 table axes)
            px, py, pz = x + origin[0], y + origin[1], z + origin[2]
            c, s = math.cos(-p), math.sin(-p)
            px, py = c * px - s * py, s * px + c * py
            c, s = math.cos(-t), math.sin(-t)
            py, pz = py - ya, pz - za
            py, pz = c * py - s * pz + ya, s * py + c * pz + za
            out.append((px, py, pz, math.degrees(t), math.degrees(p)))
    return out


def main():
    tp = hemisphere_sweep(n=N, turns=80)
    print(f"post_program, {N} points:")
    for name in ("mikron_ucp600_heidenhain", "bc_head_table_sinumerik", "bc_head_head_fanuc", "linuxcnc_xyzac_trt"):
        t, r = best_of(lambda: post_program(tp, name), repeat=1)
        print(f"  {name:<26} {r.dialect:<10} {N / t:10.0f} points/s  ({len(r.motion)} blocks, "
              f"{len(r.text) / 1e6:.1f} MB, estimated {r.time.total_s:.0f} s of machining)")
    m = load_machine("mikron_ucp600_heidenhain")
    tips, axes = tp.tip, tp.axis

    def vectorised():
        tilt, rot, _ = inverse_orientation(m, axes)
        js = [np.column_stack([linear_joints(m, tips, tilt[:, b], rot[:, b]), tilt[:, b], rot[:, b]]) for b in range(2)]
        return js

    t_vec, js = best_of(vectorised)
    n_loop = 20_000
    t_loop, ref = best_of(lambda: loop_reference(tips[:n_loop], axes[:n_loop], m.tilt.pivot, m.part_origin), repeat=1)
    t_loop *= N / n_loop
    # Same numbers: the loop's first solution against the vectorised one.
    ref0 = np.array(ref[0::2])
    assert np.abs(ref0[:, :3] - js[0][:n_loop, :3]).max() < 1e-9
    tip_back, _ = forward(m, js[0])
    assert np.abs(tip_back - tips).max() < 1e-9
    print(f"inverse kinematics, both solutions: {N / t_vec:.0f} points/s vectorised, "
          f"{N / t_loop:.0f} points/s per-point loop: ratio {t_loop / t_vec:.1f}")


if __name__ == "__main__":
    main()
