"""Kinetostatics of tendon-driven parallel continuum robots, from Python.

SI units throughout (m, rad, N, N·m); arrays are float64 numpy arrays; names follow the
JSON of the ``tdpcr`` command line. Every number comes from the Rust library.

>>> import tdpcr
>>> robot = tdpcr.Robot(tdpcr.Design.load("designs/lilge2022.ron"))
>>> sol = robot.fk([0.002, 0.01, -0.001, 0.0, 0.0, 0.005])
>>> sol.position.shape
(3,)
"""

from ._tdpcr import (
    AnalysisError,
    ConvergenceError,
    Design,
    DesignError,
    Robot,
    Solution,
    State,
    Tdcr,
    __version__,
)

__all__ = [
    "AnalysisError",
    "ConvergenceError",
    "Design",
    "DesignError",
    "Robot",
    "Solution",
    "State",
    "Tdcr",
    "__version__",
]
