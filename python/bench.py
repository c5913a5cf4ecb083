"""Speed of the Python package (issue 15), figures for BENCHMARKS.md.

    target/py-venv/bin/python python/bench.py [--repeat 200]

(a) Python overhead of a single call: the wall time of ``robot.fk(q, init=...)`` (a warm
    FK, a few µs of Rust work) minus the Rust solve time the library measures inside the
    same call (``Solution.solve_time_us``): what the binding adds (argument conversion,
    checks, the Solution object), per call, median over the calls.
(b) A warm IK step from Python vs Rust: ``robot.ik(target, init=state)`` along a path,
    wall time per step, against ``solve_time_us`` of the same steps.
(c) ``fk_many`` on 1 vs 2 rayon threads (``threads=``), same rows, best of 3.
(d) Two Python threads each running a batch (``trajectory_fk``) vs the two batches
    one after the other: GIL released if the ratio approaches 2.
Everything is measured within one run, so ratios hold on a loaded machine.
"""

import argparse
import os
import pathlib
import sys
import threading
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
# This script's directory holds the package's sources (without the built module): import
# the installed package instead.
sys.path = [p for p in sys.path if pathlib.Path(p or ".").resolve() != HERE]
import tdpcr  # noqa: E402

Q6 = np.array([0.004, 0.02, -0.003, -0.01, 0.002, 0.03])


def median(x):
    return float(np.median(x))


def single_call_overhead(robot, repeat):
    base = robot.fk(Q6)
    walls, rust = [], []
    for k in range(repeat):
        q = Q6 + 1e-6 * (k % 2)
        start = time.perf_counter_ns()
        s = robot.fk(q, init=base.state)
        walls.append((time.perf_counter_ns() - start) / 1e3)
        rust.append(s.solve_time_us)
    return median(walls), median(rust), median(np.subtract(walls, rust))


def warm_ik_steps(robot, repeat):
    phi = np.linspace(0.0, 2.0 * np.pi, repeat)
    targets = np.column_stack([0.002 * np.cos(phi), 0.002 * np.sin(phi), np.full(repeat, -0.02)])
    state = robot.ik(targets[0]).state
    walls, rust = [], []
    for t in targets[1:]:
        start = time.perf_counter_ns()
        s = robot.ik(t, init=state)
        walls.append((time.perf_counter_ns() - start) / 1e3)
        rust.append(s.solve_time_us)
        state = s.state
    return median(walls), median(rust)


def best_of(n, f):
    """The shortest wall time [s] of n runs of f, and the process CPU time over wall
    time of that run (about 2 when two threads ran at once, 1 when one ran at a time)."""
    runs = []
    for _ in range(n):
        start, cpu = time.perf_counter(), time.process_time()
        f()
        wall = time.perf_counter() - start
        runs.append((wall, (time.process_time() - cpu) / wall))
    return min(runs)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=200)
    parser.add_argument("--rows", type=int, default=64)
    args = parser.parse_args()
    design = tdpcr.Design.load(ROOT / "designs" / "lilge2022.ron")
    robot = tdpcr.Robot(design)
    print(f"tdpcr {tdpcr.__version__}, {os.cpu_count()} CPUs, load average {os.getloadavg()}")

    wall, rust, overhead = single_call_overhead(robot, args.repeat)
    print(f"(a) warm fk: Python call {wall:.1f} µs, Rust solve {rust:.1f} µs, overhead {overhead:.1f} µs (median of {args.repeat})")

    wall, rust = warm_ik_steps(robot, args.repeat)
    print(f"(b) warm ik step: Python {wall:.1f} µs, Rust {rust:.1f} µs, ratio {wall / rust:.3f}")

    Q = Q6 + np.linspace(0.0, 2e-3, args.rows)[:, None]
    (one, cpu1), (two, cpu2) = (best_of(3, lambda t=t: robot.fk_many(Q, threads=t)) for t in (1, 2))
    print(
        f"(c) fk_many {args.rows} rows: 1 thread {one * 1e3:.1f} ms (CPU/wall {cpu1:.2f}), "
        f"2 threads {two * 1e3:.1f} ms (CPU/wall {cpu2:.2f}), speedup {one / two:.2f}x"
    )

    robots = [tdpcr.Robot(design), tdpcr.Robot(design)]
    Qt = Q6 + np.linspace(0.0, 2e-3, args.rows)[:, None]

    def serial():
        for r in robots:
            r.trajectory_fk(Qt)

    def parallel():
        threads = [threading.Thread(target=r.trajectory_fk, args=(Qt,)) for r in robots]
        for t in threads:
            t.start()
        for t in threads:
            t.join()

    (s, cpu_s), (p, cpu_p) = best_of(3, serial), best_of(3, parallel)
    print(
        f"(d) two trajectory_fk batches of {args.rows} steps: serial {s * 1e3:.1f} ms "
        f"(CPU/wall {cpu_s:.2f}), two Python threads {p * 1e3:.1f} ms (CPU/wall {cpu_p:.2f}), "
        f"speedup {s / p:.2f}x"
    )
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
