"""The whole job against OpenCAMLib, and where its time goes.

    /usr/bin/python3 bench/bench_job.py [--repeat 3] [--quick]

First makes sure the bench's own reference is installed (``bench/requirements.txt``:
opencamlib, pinned; through ``bash scripts/install.sh --bench``; tsplcam never needs it).
Every figure is a ratio to a reference measured in the same run, best of ``--repeat`` runs
(the machine is shared: other processes only ever make a run slower). The process may run on
every core it is allowed (the path and fcl use both); the machine and its load are printed.

1. Reference: OpenCAMLib's ``BatchDropCutter`` (the drop-cutter behind FreeCAD CAM's 3D
   Surface: three axes, no holder) on a 51,200-triangle tessellation of the keycap with the
   same ball, CL points on an xy grid as dense as the job's path points: CL points/s.
2. The keycap main job (``python3 -m tsplcam job --no-verify --no-html-report``: model to
   G-code, smooth collision-checked five-axis axes) timed by the job's own clock (``seconds``
   in report.json: interpreter start-up and the loading of its modules excluded), run by
   turns with 1 (each best of ``--repeat``): path points/s against 1; then once with
   the job's default outputs (surface verification and HTML report), stage by stage.
3. The ``keycap_mold`` sample as the README runs it (ball1_keycap, scallop 0.02, LinuxCNC
   A/C table) and with a long tool (the same ball on a 15 mm stick-out), by the job's clock.
4. Tool-axis search: the keycap job's collision questions replayed on a checker with the
   broad phase and on one asking fcl alone: poses decided per second, and how they were
   decided; the same for every candidate axis of every tenth path point.
5. Path generation: seconds against points for scallops 0.05 .. 0.002 mm on the keycap
   (log-log slope: 1 is linear), one process against all cores (the same points); then the
   whole job of 2 at those scallops, its ratio to 1 at each, and its time split into a part
   every keycap job pays and a part per point.
6. Peak memory of the five-keycap job (25 patches, the main job's ball 0.5 mm and scallop
   0.005 mm; a 3 mm ball gouges the keycap's lower corners, so the whole job refuses it).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from common import REPO_DIR, best_of

PY = "/usr/bin/python3"


def machine() -> str:
    model = "unknown CPU"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return f"{model}, {os.cpu_count()} cores ({cores} usable), load {os.getloadavg()[0]:.1f}"


def ensure_reference():
    try:
        import opencamlib  # noqa: F401
    except ImportError:
        subprocess.run(["bash", os.path.join(REPO_DIR, "scripts", "install.sh"), "--bench"], check=True)


# --- 1. OpenCAMLib ----------------------------------------------------------------------------
def ocl_run(model, radius: float, points: int):
    """(run, triangles, grid step) of OpenCAMLib's BatchDropCutter on a 51,200-triangle
    tessellation of ``model`` (5 patches x 80 x 64 cells x 2), a ball of ``radius``, an xy
    grid of about ``points`` CL points over the model's footprint; ``run()`` computes them
    (its time is the reference's: the tree of the triangles, the points, the drop-cutter) and
    returns (CL points, threads)."""
    import opencamlib as ocl
    from tsplcam.orientation.collision import _grid_triangles
    per = 51200 // (2 * len(model.patches))
    nu = int(round(np.sqrt(per * 1.25)))
    nv = per // nu
    V, T, off = [], [], 0
    for p in model.patches:
        sp = p.evaluate_grid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1))
        V.append(sp.P)
        T.append(_grid_triangles(nu, nv) + off)
        off += len(sp.P)
    V, T = np.concatenate(V), np.concatenate(T)
    surf = ocl.STLSurf()
    for a, b, c in V[T]:
        surf.addTriangle(ocl.Triangle(ocl.Point(*a), ocl.Point(*b), ocl.Point(*c)))
    lo, hi = V.min(axis=0), V.max(axis=0)
    step = np.sqrt((hi[0] - lo[0]) * (hi[1] - lo[1]) / points)
    xs, ys = np.arange(lo[0], hi[0], step), np.arange(lo[1], hi[1], step)

    def run():
        bdc = ocl.BatchDropCutter()
        bdc.setSTL(surf)
        bdc.setCutter(ocl.BallCutter(2 * radius, 20.0))
        for y in ys:
            for x in xs:
                bdc.appendPoint(ocl.CLPoint(float(x), float(y), float(lo[2]) - 1.0))
        bdc.run()
        return len(bdc.getCLPoints()), bdc.getThreads()
    return run, len(T), step


# --- 2, 3, 6: jobs in their own process --------------------------------------------------------
# the job run by a wrapper that notes its peak memory (its own and its workers') on exit
# and the CPU seconds of the command (its own, its workers', once they have exited) after its
# imports (those import_ahead makes before the job's clock starts included)
WRAP = """import json, multiprocessing, resource, sys
from tsplcam.allocator import keep_freed_memory
from tsplcam.cli import build_parser, main
from tsplcam.job import import_ahead
keep_freed_memory()          # as python3 -m tsplcam sets its allocator (tsplcam/__main__.py)
build_parser()
import_ahead()
def cpu():
    # per process kind (its own, its workers'): CPU seconds, system seconds, page faults
    return [v for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
            for u in [resource.getrusage(w)] for v in (u.ru_utime + u.ru_stime, u.ru_stime, u.ru_minflt)]
before = cpu()
try:
    main(sys.argv[2:])
finally:
    for p in multiprocessing.active_children():    # (the job's processes exit by themselves)
        p.join(10)
    after = cpu()
    with open(sys.argv[1], 'w') as fh:
        json.dump([resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                   resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss]
                  + [a - b for a, b in zip(after, before)], fh)
"""


# model to G-code: the job's surface verification and HTML report (on by default) are timed
# apart (section 2b)
G_CODE_ONLY = ["--no-verify", "--no-html-report"]


def job(args: list, out: str, outputs=G_CODE_ONLY, env=None):
    """(report.json, peak RSS in MB of the job process, of its largest worker) of
    ``python3 -m tsplcam job`` (by default without verification and HTML report); the
    report's ``cpu`` holds the command's CPU seconds (its own, its workers')."""
    mem = os.path.join(os.path.dirname(out), os.path.basename(out) + "-memory.json")
    subprocess.run([PY, "-c", WRAP, mem, "job", "--out", out] + list(outputs) + args, cwd=REPO_DIR, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    with open(mem, encoding="utf-8") as fh:
        own, workers, cpu_own, sys_own, flt_own, cpu_workers, sys_workers, flt_workers = json.load(fh)
    with open(os.path.join(out, "report.json"), encoding="utf-8") as fh:
        rep = json.load(fh)
    rep["seconds"] = rep["timing"]["total_s"]        # the job's own clock
    rep["cpu"] = (cpu_own, cpu_workers)
    rep["system"] = (sys_own, sys_workers)           # of those, in the kernel (page faults, forks)
    rep["faults"] = (int(flt_own), int(flt_workers))
    return rep, own / 1024.0, workers / 1024.0


def best_job(args, tmp, repeat):
    best = None
    for k in range(repeat):
        rep, _, _ = job(args, os.path.join(tmp, f"run{k}"))
        if best is None or rep["seconds"] < best["seconds"]:
            best = rep
    return best


def job_and_reference(tmp, repeat: int):
    """(the main job's fastest report, OpenCAMLib's fastest points/s, CL points, triangles,
    grid step, threads): job and reference run by turns, ``repeat`` times each, so both
    meet the machine at the same speeds (it moves within minutes: run one after the other,
    the ratio of the same code swung 7.0-9.6)."""
    from tsplcam import load_model
    best, ocl, run = None, 0.0, None
    for k in range(repeat):
        rep, _, _ = job([], os.path.join(tmp, f"run{k}"))
        if best is None or rep["seconds"] < best["seconds"]:
            best = rep
        if run is None:
            run, tri, step = ocl_run(load_model("keycap"), 0.5, rep["path"]["points"])
        t, (n, threads) = best_of(run, 1)
        ocl = max(ocl, n / t)
    return best, ocl, n, tri, step, threads


def long_tool(tmp: str) -> str:
    from tsplcam.orientation import load_tool
    d = load_tool("ball1_keycap").to_dict()
    d["name"], d["shank_length"] = "ball1_long15", 15.0
    d["comment"] = "ball1_keycap's ball and holder on a 15 mm stick-out (bench only)"
    path = os.path.join(tmp, "ball1_long15.json")
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(d, fh)
    return path


def five_keycaps(tmp: str, pitch: float = 40.0) -> str:
    """The keycap's cage five times in a row, 40 mm apart (the holder clears the next one), as
    an OBJ quad cage."""
    from tsplcam.model import samples
    c = samples.keycap()
    lines = []
    for k in range(5):
        lines += [f"v {x + k * pitch:.9g} {y:.9g} {z:.9g}" for x, y, z in c.points]
    nv = len(c.points)
    for k in range(5):
        lines += ["f " + " ".join(str(i + 1 + k * nv) for i in f) for f in c.mesh.faces]
    path = os.path.join(tmp, "five_keycaps.obj")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("\n".join(lines) + "\n")
    return path


# --- 4. tool-axis search -------------------------------------------------------------------------
def record_queries(name, scallop, machine_name, stock):
    """(path, the smooth orientation's collision queries in order) of a job."""
    from tsplcam.orientation import CollisionChecker, load_tool, orient
    from tsplcam.post import load_machine
    from tsplcam import load_model
    from tsplcam.toolpath.zigzag import default_plan, zigzag_path
    model = load_model(name)
    path = zigzag_path(model, default_plan(model), 0.5, scallop, 0.001)
    tool = load_tool("ball1_keycap")
    meshes = [] if stock is None else [("stock",) + tuple(stock)]
    ch = CollisionChecker(model, tool, meshes=meshes, clearance=0.3)
    calls = []
    inner = ch.collides

    def collides(C, A, grow=0.0):
        calls.append((np.array(C), np.array(A), grow))
        return inner(C, A, grow)
    ch.collides = collides
    orient(path, model, tool, "smooth", checker=ch, machine=load_machine(machine_name))
    return model, path, meshes, calls


def replay(model, meshes, calls, broad: bool):
    """(seconds in the collision checks, checker, CPU-seconds of this process in them: its
    threads', not its forked fcl workers') for the recorded queries on a new checker."""
    from tsplcam.orientation import CollisionChecker, load_tool
    ch = CollisionChecker(model, load_tool("ball1_keycap"), meshes=meshes, clearance=0.3, broad_phase=broad)
    ch.build_bvh()                   # (else built at fcl's first question, inside the timing)
    t0, c0 = time.perf_counter(), time.process_time()
    for C, A, grow in calls:
        ch.collides(C, A, grow)
    return time.perf_counter() - t0, ch, time.process_time() - c0


def search_figures(name, scallop, machine_name, stock, repeat, fcl_calls=None):
    model, path, meshes, calls = record_queries(name, scallop, machine_name, stock)
    poses = sum(len(c[0]) for c in calls)
    runs = [replay(model, meshes, calls, True) for _ in range(repeat)]
    t_bp, ch, cpu = min(runs, key=lambda r: r[0])
    ref_calls = calls if fcl_calls is None else calls[:fcl_calls]
    ref_poses = sum(len(c[0]) for c in ref_calls)
    t_fcl = min(replay(model, meshes, ref_calls, False)[0] for _ in range(repeat))
    st = ch.broad.stats
    print(f"  {name}: {poses} poses asked in {len(calls)} batches by the smooth strategy")
    print(f"    broad phase + fcl   {poses / t_bp:10.0f} poses/s  ({t_bp:.2f} s, {cpu:.2f} CPU-s in this process, "
          f"load {os.getloadavg()[0]:.1f}; decided by the broad phase "
          f"{(st['free'] + st['hit']) / poses:.0%}: free cones {st['cone'] / poses:.0%}, hit witnesses "
          f"{st['witness'] / poses:.0%}, {st.get('exact', 0)} spheres of the exact pass; fcl {ch.fcl_checks} "
          f"queries)")
    print(f"    fcl alone           {ref_poses / t_fcl:10.0f} poses/s  ({t_fcl:.2f} s"
          f"{'' if fcl_calls is None else f' on the first {len(ref_calls)} batches, {ref_poses} poses'})")
    print(f"    ratio {poses / t_bp / (ref_poses / t_fcl):.1f}")
    return path, model, meshes


def all_candidates(path, model, meshes, repeat, every=10):
    from tsplcam.orientation import CollisionChecker, load_tool
    from tsplcam.orientation.candidates import DEG, Limits, candidate_axes, feed_directions
    feed = feed_directions(path.contact, path.normal)
    A, ok = candidate_axes(path.normal, feed, [0, 0, 1.0], Limits(60 * DEG, 60 * DEG, 10 * DEG))
    i, j = np.nonzero(ok[::every])
    i = i * every
    C, Ax = path.center[i], A[i, j]
    out = []
    for broad in (True, False):
        best = None
        for _ in range(repeat):
            ch = CollisionChecker(model, load_tool("ball1_keycap"), meshes=meshes, clearance=0.3, broad_phase=broad)
            ch.build_bvh()
            sel = slice(None) if broad else slice(0, min(len(C), 20000))
            t0, c0 = time.perf_counter(), time.process_time()
            ch.collides(C[sel], Ax[sel])
            rate = len(C[sel]) / (time.perf_counter() - t0)
            if best is None or rate > best[0]:
                best = (rate, ch, time.process_time() - c0)
        out.append(best)
    (r_bp, ch, cpu), (r_fcl, _, _) = out
    st = ch.broad.stats
    print(f"  every candidate axis of every {every}th point: {len(C)} poses; broad phase + fcl "
          f"{r_bp:.0f} poses/s ({len(C) / r_bp:.2f} s, {cpu:.2f} CPU-s in this process; decided by the broad "
          f"phase {(st['free'] + st['hit']) / len(C):.0%}), "
          f"fcl alone {r_fcl:.0f} poses/s: ratio {r_bp / r_fcl:.1f}")


# --- 5. path growth ------------------------------------------------------------------------------
#: the scallops (mm) the path's and the whole job's cost is measured at (0.005: the main job's)
GROWTH_SCALLOPS = (0.05, 0.02, 0.005, 0.002)


def path_growth(repeat):
    from tsplcam import load_model
    from tsplcam.toolpath.zigzag import default_plan, zigzag_path
    model = load_model("keycap")
    plan = default_plan(model)
    rows = []
    for h in GROWTH_SCALLOPS:
        t, p = best_of(lambda: zigzag_path(model, plan, 0.5, h, 0.001), repeat if h > 0.002 else 1)
        rows.append((h, len(p), t))
        print(f"    scallop {h:<6g} {len(p):7d} points  {t:6.2f} s  {len(p) / t:8.0f} points/s")
    n = np.log([r[1] for r in rows])
    t = np.log([r[2] for r in rows])
    print(f"    log-log slope of time against points: {np.polyfit(n, t, 1)[0]:.2f} (1 = linear)")
    env = os.environ.get("TSPLCAM_WORKERS")
    os.environ["TSPLCAM_WORKERS"] = "1"
    t1, p1 = best_of(lambda: zigzag_path(model, plan, 0.5, 0.005, 0.001), repeat)
    if env is None:
        del os.environ["TSPLCAM_WORKERS"]
    else:
        os.environ["TSPLCAM_WORKERS"] = env
    t2, p2 = best_of(lambda: zigzag_path(model, plan, 0.5, 0.005, 0.001), repeat)
    same = all(np.array_equal(getattr(p1, k), getattr(p2, k)) for k in ("contact", "normal", "uv", "move", "line"))
    print(f"    keycap 0.005 mm: one process {t1:.2f} s, {len(os.sched_getaffinity(0))} cores {t2:.2f} s "
          f"(ratio {t1 / t2:.2f}); the same points: {same}")


def job_growth(tmp: str, repeat: int, ocl: float, main_job: dict) -> None:
    """The whole keycap job (model to G-code, as in 1-2) against its size: the scallops of the
    path's growth, each job the fastest of ``repeat`` (the main job's scallop: 1-2's run), its ratio to
    OpenCAMLib's rate of this run, the log-log slope, and the least-squares split of its time
    into a part every job pays (model, collision checker, BVH: the keycap's whatever its
    points) and a part per point."""
    rows = []
    for h in GROWTH_SCALLOPS:
        r = main_job if h == main_job["settings"]["scallop"] else best_job(["--scallop", str(h)], tmp, repeat)
        n, t = r["path"]["points"], r["seconds"]
        rows.append((n, t))
        print(f"    scallop {h:<6g} {n:7d} points  {t:6.2f} s  {n / t:8.0f} points/s = {n / t / ocl:5.2f} x OpenCAMLib")
    n, t = np.array(rows, float).T
    slope = np.polyfit(np.log(n), np.log(t), 1)[0]
    per, fixed = np.polyfit(n, t, 1)
    print(f"    log-log slope of the job's time against points: {slope:.2f} (1 = linear); time = "
          f"{fixed:.2f} s + {per * 1e6:.1f} us a point (least squares)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="skip the mold jobs, the fcl-only replays and memory")
    args = ap.parse_args(argv)
    ensure_reference()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, os.sched_getaffinity(0))
    print(f"machine: {machine()}; python {sys.version.split()[0]}, numpy {np.__version__}")
    from tsplcam.model.samples import keycap_mold_stock
    tmp = tempfile.mkdtemp(prefix="tsplcam-bench-")

    print("\n1-2. keycap main job against OpenCAMLib's drop-cutter")
    rep, ocl, n_ocl, tri, step, threads = job_and_reference(tmp, args.repeat)
    points = rep["path"]["points"]
    rate = points / rep["seconds"]
    print(f"  OpenCAMLib BatchDropCutter, {tri} triangles, ball r 0.5 mm, {n_ocl} CL points "
          f"({step:.3f} mm grid), {threads} threads: {ocl:8.0f} points/s")
    print(f"  tsplcam job (report.json seconds {rep['seconds']:.2f} s, {points} points, smooth five-axis, "
          f"collision-checked, G-code): {rate:8.0f} points/s")
    print(f"  ratio {rate / ocl:.2f} (target 10); job {rep['seconds']:.2f} s (target 1)")
    tm = rep["timing"]
    print("  stages: " + ", ".join(f"{k[:-2]} {tm[k]:.2f} s" for k in ("model_s", "plan_s", "path_s", "orientation_s",
                                                                       "post_s") if k in tm)
          + " (tool axes: checker, smoothing, checks again)")
    # the work itself: two cores end it no sooner than in half the time one process takes
    one = min((job([], os.path.join(tmp, f"one{k}"), env=dict(os.environ, TSPLCAM_WORKERS="1"))[0]
               for k in range(args.repeat)), key=lambda r: r["seconds"])
    c_own, c_work = rep["cpu"]
    half = 0.5 * one["seconds"]
    print(f"  CPU: {c_own:.2f} s in the job's process + {c_work:.2f} s in its workers (the fastest run; "
          f"system {rep['system'][0]:.2f} + {rep['system'][1]:.2f} s, page faults {rep['faults'][0]:,d} + "
          f"{rep['faults'][1]:,d}: the forks' copy-on-write); one process: {one['seconds']:.2f} s by the "
          f"job's clock ({sum(one['cpu']):.2f} CPU-s, system {sum(one['system']):.2f} s, page faults "
          f"{sum(one['faults']):,d}), half of it {half:.2f} s: {points / half / ocl:.1f}x")
    full, _, _ = job([], os.path.join(tmp, "full"), outputs=[])
    tm = full["timing"]
    print(f"  2b. the same job with its default outputs (surface verification, HTML report): "
          f"{full['seconds']:.2f} s, of which verification {tm.get('verify_s', 0):.2f} s, report "
          f"{tm.get('report_s', 0):.2f} s (one run)")

    if not args.quick:
        print("\n3. keycap_mold sample by the job's clock (ball 0.5 mm, scallop 0.02 mm, linuxcnc_xyzac_trt)")
        common = ["--model", "keycap_mold", "--scallop", "0.02", "--machine", "linuxcnc_xyzac_trt"]
        for label, tool in (("ball1_keycap (5.5 mm stick-out)", "ball1_keycap"), ("long tool (15 mm stick-out)", long_tool(tmp))):
            r = best_job(common + ["--tool", tool], tmp, max(1, args.repeat - 1))
            print(f"  {label}: {r['seconds']:.2f} s, {r['path']['points']} points, "
                  f"{r['path']['points'] / r['seconds']:.0f} points/s = {r['path']['points'] / r['seconds'] / ocl:.2f}"
                  f" x OpenCAMLib (target 5 s)")

    print("\n4. tool-axis search (collision decisions, broad phase against fcl alone, same queries)")
    path, model, meshes = search_figures("keycap", 0.005, "mikron_ucp600_heidenhain", None, args.repeat)
    all_candidates(path, model, meshes, args.repeat)
    if not args.quick:
        search_figures("keycap_mold", 0.02, "linuxcnc_xyzac_trt", keycap_mold_stock(), 1, fcl_calls=12)

    print("\n5. path generation on the keycap (r 0.5 mm), cost against size")
    path_growth(args.repeat)
    print("  the whole job (as 1-2), cost against size")
    job_growth(tmp, max(1, args.repeat - 1), ocl, rep)

    if not args.quick:
        print("\n6. five keycaps (25 patches), the main job's tool and scallop (ball 0.5 mm, 0.005 mm)")
        r, own, worker = job(["--model", five_keycaps(tmp)], os.path.join(tmp, "five"))
        print(f"  {r['path']['points']} points in {r['seconds']:.1f} s ({r['path']['points'] / r['seconds']:.0f} "
              f"points/s); peak memory {own:.0f} MB in the job's process, {worker:.0f} MB in its largest "
              f"worker (forked: mostly shared pages); target 1500 MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
