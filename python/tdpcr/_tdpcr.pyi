"""Type stubs of the native module ``tdpcr._tdpcr`` (re-exported by ``tdpcr``).

Units: SI (m, rad, N, N·m). Arrays: float64 numpy arrays. Array arguments accept any
array-like of numbers (lists, int arrays, non-contiguous views); a wrong shape or a
NaN/infinite element raises ``ValueError`` naming the argument.
"""

from os import PathLike
from typing import Any, Callable, Literal, Optional, Union

import numpy as np
import numpy.typing as npt

__version__: str

ArrayLike = npt.ArrayLike
F64 = npt.NDArray[np.float64]
Jacobian = Literal["exact", "fd", "fd-central"]

class DesignError(ValueError):
    """A design that cannot be read, parsed or accepted; the message lists every bad field."""

class ConvergenceError(RuntimeError):
    """A solve that failed."""

    reason: str
    """Why it stopped, snake_case (the CLI's ``stop_reason``; ``"diverged"`` when the solve went non-finite,
    the message then names the inputs beyond the design's range)."""
    residual_norm: Optional[float]
    """Norm of the SI residual at the best point found (None if unknown)."""
    iterations: Optional[int]
    """Newton iterations done (None if unknown)."""

class AnalysisError(RuntimeError):
    """An analysis that cannot be carried out (an exactly singular matrix)."""

class Design:
    """A parallel-robot design (RON, as in ``designs/``), validated when loaded."""

    @staticmethod
    def load(path: Union[str, "PathLike[str]"]) -> "Design":
        """Loads and validates a RON design file. Raises DesignError."""
    @staticmethod
    def from_ron(text: str, source: str = "<string>") -> "Design":
        """Parses and validates RON text (``source`` names it in errors). Raises DesignError."""
    @property
    def n_actuators(self) -> int:
        """Length of q: 6 (6-DoF design) or 9 (9-DoF design)."""

class State:
    """A configuration (pose, q, the legs' base unknowns); pass it as ``init``."""

    @property
    def position(self) -> F64:
        """Platform position [m], world frame, shape (3,)."""
    @property
    def rotvec(self) -> F64:
        """Platform rotation vector (axis × angle) [rad], shape (3,)."""
    @property
    def q(self) -> F64:
        """Actuation [m], shape (n,)."""
    @property
    def y_u(self) -> F64:
        """The legs' unknowns at their bases, shape (3 (6 + n_t),)."""
    def to_json(self) -> str:
        """The state as JSON (what ``tdpcr fk --init`` reads)."""
    @staticmethod
    def from_json(text: str) -> "State":
        """A state from JSON (the CLI's ``state`` object)."""

class Solution:
    """A converged solve."""

    @property
    def position(self) -> F64:
        """Platform position [m], world frame, shape (3,)."""
    @property
    def rotation(self) -> F64:
        """Platform rotation, body to world, shape (3, 3)."""
    @property
    def rotvec(self) -> F64:
        """Platform rotation vector (axis × angle) [rad], shape (3,)."""
    @property
    def q(self) -> F64:
        """Actuation [m], shape (n,): per leg [bend_x, (bend_y), translation]."""
    @property
    def tensions(self) -> F64:
        """Tendon tensions [N], shape (3, n_t): one row per leg."""
    @property
    def iterations(self) -> int:
        """Newton iterations."""
    @property
    def residual_evaluations(self) -> int:
        """Residual evaluations."""
    @property
    def jacobian_evaluations(self) -> int:
        """Exact Jacobians evaluated."""
    @property
    def residual_norm(self) -> float:
        """Norm of the final SI residual."""
    @property
    def solve_time_us(self) -> float:
        """Wall time of the solve [µs]."""
    @property
    def state(self) -> State:
        """The configuration, usable as ``init`` of the next solve."""
    @property
    def shape(self) -> F64:
        """The legs' backbones for plotting [m], world frame, shape (3, n_disks + 1, 3):
        per leg its base point, then every disk centre (computed on each access)."""

class Robot:
    """FK and IK of one design. Holds its buffers: one Robot per Python thread."""

    def __init__(self, design: Design) -> None: ...
    @property
    def n_actuators(self) -> int:
        """Length of q."""
    @property
    def reuse_least_norm_factorization(self) -> bool:
        """Whether a least-norm ``ik`` of the 9-DoF design from this robot's last
        least-norm solution (``init``) starts with chord steps on the robot's latest
        least-norm factorization (default False): going back and forth, a 1 mm step then
        costs residuals only (about 2× less time), but lands elsewhere on the set of
        solutions than steps from each start's own Jacobian (q up to 2.3e-5 m apart after
        30 steps of 1 mm). See the README's library notes."""
    @reuse_least_norm_factorization.setter
    def reuse_least_norm_factorization(self, on: bool) -> None: ...
    @property
    def least_norm_gauss_newton(self) -> bool:
        """Whether a least-norm ``ik`` of the 9-DoF design takes every step with the
        Jacobian at its iterate (Gauss–Newton, the behaviour before 2026-11-28) instead of
        all with the Jacobian at its start (default False). From the start's Jacobian a
        1 mm step costs one Jacobian instead of two (0.75× the time) and lands on the
        one solution in the start's least-change directions; Gauss–Newton steps land
        elsewhere on the set of solutions (2.9e-9 m in q after one 1 mm step)."""
    @least_norm_gauss_newton.setter
    def least_norm_gauss_newton(self, on: bool) -> None: ...
    @property
    def across_kinks(self) -> bool:
        """Whether an ``ik`` of the 9-DoF design takes one-sided steps across tendon kinks
        (default True): the least-norm steps from the start, and a run (Gauss–Newton
        least-norm, within the limits) whose line search fails once more so. Warm 1 mm
        steps around circles failed where a tendon pair passes through both-slack, and
        converge with it; the least-norm steps there take 5–9× fewer evaluations. A
        retried solution's report counts the work of both runs."""
    @across_kinks.setter
    def across_kinks(self, on: bool) -> None: ...
    def fk(
        self,
        q: ArrayLike,
        wrench: Optional[ArrayLike] = None,
        init: Optional[Union[State, Solution]] = None,
        *,
        tolerance: Optional[float] = None,
        max_iterations: Optional[int] = None,
        jacobian: Jacobian = "exact",
    ) -> Solution:
        """Forward kinetostatics at actuation ``q`` (n,) [m].

        ``wrench`` (6,): extra [fx, fy, fz, mx, my, mz] [N, N·m] on the platform centre,
        world frame, added to its weight. ``init``: warm start. ``tolerance``: on the
        residual norm (default 1e-10). Raises ConvergenceError, ValueError.
        """
    def ik(
        self,
        position: ArrayLike,
        rotvec: Optional[ArrayLike] = None,
        *,
        wrench: Optional[ArrayLike] = None,
        init: Optional[Union[State, Solution]] = None,
        tolerance: Optional[float] = None,
        max_iterations: Optional[int] = None,
        jacobian: Jacobian = "exact",
        limits: Literal["free", "strict"] = "free",
        reference: Optional[ArrayLike] = None,
    ) -> Solution:
        """Inverse kinetostatics: q that holds the platform at ``position`` (3,) [m] and
        ``rotvec`` (3,) [rad]. For the 9-DoF design, ``limits="strict"`` keeps q within
        the design's limits (``reference``: a q to stay close to); a 6-DoF design has one
        q per pose and ignores both (its q may lie beyond the limits: check
        ``solution.q``). Raises ConvergenceError, ValueError.
        """
    def analyze(
        self,
        solution: Solution,
        *,
        type_i_threshold: Optional[float] = None,
        type_ii_threshold: Optional[float] = None,
        leg_threshold: Optional[float] = None,
    ) -> dict[str, Any]:
        """Kinetostatic analysis of ``solution`` under the wrench it was solved under.

        Keys: ``j_fk`` (6, n) [m/m, rad/m], ``j_ik`` (n, 6), ``compliance`` (6, 6)
        [m/N, rad/(N·m)], ``lambda_fk``, ``lambda_ik``, ``lambda_c`` (arrays);
        ``rcond`` ({"raw": {...}, "scaled": {...}}), ``singularity``, ``ellipsoids``,
        ``stability``, ``thresholds`` (dicts, as in ``tdpcr analyze --format json``);
        ``min_tension`` [N]. Raises AnalysisError.
        """
    def fk_many(
        self,
        q: ArrayLike,
        wrench: Optional[ArrayLike] = None,
        *,
        tolerance: Optional[float] = None,
        max_iterations: Optional[int] = None,
        jacobian: Jacobian = "exact",
        threads: Optional[int] = None,
    ) -> dict[str, Any]:
        """FK of every row of ``q`` (m, n), cold-started, in parallel, GIL released.

        ``threads``: rayon workers (None: all cores). Keys: ``position`` (m, 3) [m],
        ``rotation`` (m, 3, 3), ``rotvec`` (m, 3) [rad], ``q`` (m, n) [m], ``tensions``
        (m, 3, n_t) [N], ``iterations`` (m,) uint64, ``residual_norm`` (m,),
        ``solve_time_us`` (m,) [µs], ``converged`` (m,) bool, ``errors`` {row: message} and ``reasons`` {row: snake_case reason, as ``ConvergenceError.reason``} (rows in order).
        A failed row is 0 in every numeric output but ``iterations`` (never NaN): read
        rows through ``converged``.
        """
    def ik_many(
        self,
        poses: ArrayLike,
        wrench: Optional[ArrayLike] = None,
        *,
        tolerance: Optional[float] = None,
        max_iterations: Optional[int] = None,
        jacobian: Jacobian = "exact",
        limits: Literal["free", "strict"] = "free",
        reference: Optional[ArrayLike] = None,
        threads: Optional[int] = None,
    ) -> dict[str, Any]:
        """IK of every row of ``poses`` (m, 6) [x, y, z [m], rx, ry, rz [rad]],
        cold-started, in parallel, GIL released; options as ``ik``; the dict of
        ``fk_many``. Equals the loop of ``ik`` calls bit for bit.
        """
    def trajectory_fk(
        self,
        q: ArrayLike,
        wrench: Optional[ArrayLike] = None,
        *,
        tolerance: Optional[float] = None,
        max_iterations: Optional[int] = None,
        jacobian: Jacobian = "exact",
    ) -> dict[str, Any]:
        """FK along the rows of ``q`` (m, n) [m] in order, each step warm-started from
        the previous solution (the first, and a step after a failed one, cold), GIL
        released. Equals the loop ``s = robot.fk(q[k], wrench, init=s.state)`` bit for
        bit. The dict of ``fk_many`` without ``tensions``; failed rows 0, masked by
        ``converged``.
        """
    def trajectory_ik(
        self,
        poses: ArrayLike,
        wrench: Optional[ArrayLike] = None,
        *,
        tolerance: Optional[float] = None,
        max_iterations: Optional[int] = None,
        jacobian: Jacobian = "exact",
        limits: Literal["free", "strict"] = "free",
        reference: Optional[ArrayLike] = None,
    ) -> dict[str, Any]:
        """IK along the rows of ``poses`` (m, 6) [x, y, z [m], rx, ry, rz [rad]],
        warm-started in order as ``trajectory_fk``; options as ``ik``.
        """
    def workspace(
        self,
        *,
        step: Optional[float] = None,
        angle_step: Optional[float] = None,
        z_range: Optional[ArrayLike] = None,
        rotvec: Optional[ArrayLike] = None,
        collisions: Literal["stop", "continue"] = "stop",
        tolerance: Optional[float] = None,
        max_iterations: Optional[int] = None,
        progress: Optional[Callable[[int, int], Any]] = None,
        one_sided_kinks: bool = True,
        chord_contraction: Optional[float] = None,
        probe_iterations: Optional[int] = None,
    ) -> dict[str, Any]:
        """The workspace at the fixed orientation ``rotvec`` [rad] (the library's sweep:
        rays of IK steps of ``step`` [m], ``angle_step`` [rad] apart, planes z = k·step
        within ``z_range`` [m]), in parallel, GIL released. ``progress(rays_done,
        rays_total)`` is called on the calling thread, one call at a time, at most about
        four times a second and at the end; an exception it raises stops the sweep and is
        raised. Ctrl-C stops the sweep within a
        fraction of a second (``KeyboardInterrupt``), as it stops the batches of 16 rows
        or more.

        Keys, one row per cell: ``cell`` (m, 3) int64, ``position`` (m, 3) [m],
        ``rotvec`` (m, 3) [rad], ``q`` (m, n) [m], ``tensions`` (m, 3 n_t) [N],
        ``reachable``, ``collision`` (m,) bool, ``rcond``, ``rcond_scaled`` ({name:
        (m,)}), ``singularity`` ({"type_i", "type_ii", "leg": (m,) bool}),
        ``min_tension`` (m,) [N], ``stable`` (m,) bool, ``min_compliance_eigenvalue``
        (m,), ``leg_switch`` (m,) bool; ``summary``, ``settings`` (dicts, as the CLI's
        workspace JSON). ``one_sided_kinks=False`` solves every step with the
        Jacobian's taut slopes only (the CLI's ``--two-sided-kinks``: the maps of
        before, with more Newton Jacobians) and, for the 9-DoF design, does not retry
        a step whose run fails on a step across a tendon's kink with one-sided steps
        (its ray then ends there). ``chord_contraction`` in [0, 1) (default
        0.1): Newton keeps each step's Jacobian while its chord steps contract ‖b‖ by
        at least this factor (the CLI's ``--chord-contraction``; 0.5 saves work at
        coarse steps, cells at folds may move). ``probe_iterations`` ≥ 1 (default 15):
        Newton iterations a step gets before it must have reduced ‖b‖ tenfold to go on
        (the CLI's ``--probe-iterations``; fewer end steps past a fold sooner). Raises
        ValueError (bad settings), ConvergenceError.
        """

class Tdcr:
    """One tendon-driven continuum robot alone (``designs/tdcr_*.ron``), base at the
    world origin. Holds its buffers: one Tdcr per Python thread."""

    @staticmethod
    def load(path: Union[str, "PathLike[str]"]) -> "Tdcr":
        """Loads and validates a RON file. Raises DesignError."""
    @staticmethod
    def from_ron(text: str, source: str = "<string>") -> "Tdcr":
        """Parses and validates RON text. Raises DesignError."""
    @property
    def n_tendons(self) -> int:
        """Number of tendons n_t."""
    def solve(
        self,
        tensions: Optional[ArrayLike] = None,
        displacements: Optional[ArrayLike] = None,
        *,
        tip_force: Optional[ArrayLike] = None,
        tip_moment: Optional[ArrayLike] = None,
        init: Optional[dict[str, Any]] = None,
        tolerance: Optional[float] = None,
        max_iterations: Optional[int] = None,
    ) -> dict[str, Any]:
        """Equilibrium under ``tensions`` (n_t,) [N] or tendon length changes
        ``displacements`` (n_t,) [m] (negative = pulled; exactly one), a tip force [N]
        and moment [N·m] (world frame), warm from ``init`` (an earlier result's
        ``state``). Keys as ``tdpcr tdcr --format json``: ``tip_position`` (3,) [m],
        ``tip_rotation`` (3, 3), ``tensions`` (n_t,) [N], ``slacks`` (n_t,) [m],
        ``iterations``, ``residual_evaluations``, ``residual_norm``, ``shape`` (n_disks,
        3) [m] (disk centres, base excluded), ``shape_arcs`` (n_disks,) [m], ``state``
        ({"u0", "v0", "gammas"}). Raises ConvergenceError, ValueError.
        """

# The design search's steps for the distributed driver `tdpcr.optim` (issue 16).
class DesignSearch:
    """One search of ``tdpcr-optim`` in the run directory ``out``, driven step by step."""

    def __init__(
        self,
        config: Union[str, PathLike[str]],
        out: Union[str, PathLike[str]],
        *,
        seed: Optional[int] = None,
        budget_evals: Optional[int] = None,
        resume: bool = False,
    ) -> None: ...
    @property
    def problem(self) -> str:
        """The effective config and base design (RON) for ``SearchProblem``."""
    @property
    def population(self) -> int: ...
    @property
    def termination(self) -> Optional[str]: ...
    def ask(self) -> list[str]:
        """The candidates to evaluate next (JSON); empty when the search has ended."""
    def tell(self, results: list[str]) -> None:
        """Logs the results (JSON, any order) in candidate order and tells CMA-ES."""
    def finish(self, command: str, workers: int) -> dict[str, Any]:
        """Writes the outputs of the ended search; returns a summary."""
    def close(self) -> None:
        """Releases the run directory (its log stays, to resume); the search ends here.
        Also on leaving a ``with`` block."""
    def __enter__(self) -> "DesignSearch": ...
    def __exit__(self, *args: object) -> bool: ...

class SearchProblem:
    """The evaluation of a search's candidates, built from ``DesignSearch.problem``."""

    def __init__(self, problem: str) -> None: ...
    def evaluate(self, candidate: str) -> str:
        """The result (JSON) of one candidate (JSON), GIL released."""
