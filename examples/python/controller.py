"""A warm-started IK control loop along a small circle, reading J and C at each step.

Each step solves IK warm from the previous solution, then analyses it: the forward
Jacobian J = dx/dq (6, n) [m/m, rad/m] gives the actuation step a resolved-rate
controller would command, the compliance C (6, 6) [m/N, rad/(N·m)] how far the platform
yields under a load. Prints the time per step [µs]; plots the path with matplotlib when
it is installed (pass --no-plot to skip).

    python examples/python/controller.py [--steps 12] [--no-plot]
"""

import argparse
import pathlib
import time

import numpy as np

import tdpcr

DESIGN = pathlib.Path(__file__).resolve().parents[2] / "designs" / "lilge2022.ron"


def circle(steps, radius=0.002, z=-0.02):
    """Platform positions [m] on a horizontal circle, (steps, 3)."""
    phi = np.linspace(0.0, 2.0 * np.pi, steps)
    return np.column_stack([radius * np.cos(phi), radius * np.sin(phi), np.full(steps, z)])


def run(steps=12, plot=True):
    robot = tdpcr.Robot(tdpcr.Design.load(DESIGN))
    targets = circle(steps)
    state, q_path, rows = None, [], []
    for k, target in enumerate(targets):
        start = time.perf_counter()
        sol = robot.ik(target, init=state)
        solved = time.perf_counter()
        a = robot.analyze(sol)
        analysed = time.perf_counter()
        J, C = a["j_fk"], a["compliance"]
        # The actuation change that moves the platform 0.1 mm in x (least squares).
        dq = np.linalg.lstsq(J[:3], [1e-4, 0.0, 0.0], rcond=None)[0]
        sag = C[2, 2] * 0.1  # z deflection [m] under an extra 0.1 N downwards
        rows.append(((solved - start) * 1e6, (analysed - solved) * 1e6, sol.iterations))
        print(
            f"step {k:2d}: ik {rows[-1][0]:8.1f} µs ({sol.iterations} it), "
            f"analyze {rows[-1][1]:8.1f} µs, |dq| {np.linalg.norm(dq) * 1e3:.3f} mm, "
            f"sag {sag * 1e6:.2f} µm, rcond {a['rcond']['raw']['b_xu']:.2e}"
        )
        state = sol.state
        q_path.append(sol.q)
    if plot:
        try:
            import matplotlib.pyplot as plt
        except ImportError:
            print("matplotlib not installed: no plot")
        else:
            fig = plt.figure()
            ax = fig.add_subplot(projection="3d")
            for leg in sol.shape:
                ax.plot(*leg.T, color="0.5")
            ax.plot(*targets.T, "o-", label="platform path")
            ax.set_xlabel("x [m]")
            ax.set_ylabel("y [m]")
            ax.set_zlabel("z [m]")
            ax.legend()
            plt.show()
    return np.array(q_path), np.array(rows)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=12)
    parser.add_argument("--no-plot", action="store_true")
    args = parser.parse_args()
    run(args.steps, plot=not args.no_plot)
