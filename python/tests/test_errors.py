"""Every error type: DesignError, ConvergenceError, ValueError naming the argument."""

import numpy as np
import pytest

import tdpcr
from conftest import DESIGNS, Q6


def test_design_error_lists_every_bad_field():
    text = (DESIGNS / "lilge2022.ron").read_text()
    text = text.replace("length: 0.145", "length: -0.145").replace(
        "mass: 0.0344", "mass: -1.0"
    )
    with pytest.raises(tdpcr.DesignError) as e:
        tdpcr.Design.from_ron(text)
    assert isinstance(e.value, ValueError)
    message = str(e.value)
    assert "leg.length" in message and "platform.mass" in message


def test_design_error_for_parse_and_io():
    with pytest.raises(tdpcr.DesignError, match="<string>"):
        tdpcr.Design.from_ron("Tdpcr(")
    with pytest.raises(tdpcr.DesignError, match="no_such.ron"):
        tdpcr.Design.load("no_such.ron")


def test_convergence_error_carries_reason_and_residual(robot):
    with pytest.raises(tdpcr.ConvergenceError) as e:
        robot.fk(Q6, max_iterations=1)
    assert e.value.reason == "iteration_limit"
    assert e.value.iterations == 1
    assert e.value.residual_norm > 1e-10
    assert isinstance(e.value, RuntimeError)


def test_a_diverged_solve_names_the_input_beyond_its_range(robot):
    with pytest.raises(tdpcr.ConvergenceError) as e:
        robot.fk([1.0] * 6)
    assert e.value.reason == "diverged"
    assert "q[0] = 1 m is 100 times" in str(e.value)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda r: r.fk(Q6[:5]), "q"),
        (lambda r: r.fk([Q6]), "q"),
        (lambda r: r.fk(Q6[:5] + [np.nan]), "q"),
        (lambda r: r.fk(Q6[:5] + [np.inf]), "q"),
        (lambda r: r.fk(["a"] * 6), "q"),
        (lambda r: r.fk(Q6, wrench=[0, 0, 1]), "wrench"),
        (lambda r: r.fk(Q6, init=Q6), "init"),
        (lambda r: r.fk(Q6, jacobian="magic"), "jacobian"),
        (lambda r: r.ik([0, 0]), "position"),
        (lambda r: r.ik([0, 0, -0.1], [0, np.nan, 0]), "rotvec"),
        # Its length overflowed (the rotation became NaN) or is beyond 1000 rad.
        (lambda r: r.ik([0, 0, -0.1], [1e200, 0, 0]), "rotvec"),
        (lambda r: r.ik([0, 0, -0.1], [0, 0, 1001.0]), "rotvec"),
        (lambda r: r.ik_many([[0, 0, -0.1, 0, 0, 0], [0, 0, -0.1, 1e300, 0, 0]]), "poses"),
        (lambda r: r.ik([0, 0, -0.1], limits="loose"), "limits"),
        (lambda r: r.ik([0, 0, -0.1], reference=np.zeros(6)), "reference"),
        (lambda r: r.fk_many(np.zeros((3, 5))), "q"),
        (lambda r: r.fk_many(np.zeros(6)), "q"),
    ],
)
def test_bad_arrays_raise_value_error_naming_the_argument(robot, call, name):
    with pytest.raises(ValueError, match=f"^{name}:"):
        call(robot)


def test_bad_settings_are_value_errors(robot):
    with pytest.raises(ValueError, match="tolerance"):
        robot.fk(Q6, tolerance=-1.0)


def test_analysis_of_another_designs_solution_is_a_value_error(robot, redundant_robot):
    other = redundant_robot.fk(np.zeros(9))
    with pytest.raises(ValueError, match="solution: a solution of another design"):
        robot.analyze(other)
    # The same size (the ψ = 0 twin): analysed, it gave numbers of neither design.
    twin = tdpcr.Robot(tdpcr.Design.load(str(DESIGNS / "lilge2022_psi0.ron")))
    with pytest.raises(ValueError, match="solution: a solution of another design"):
        robot.analyze(twin.fk(Q6))
    # Another Robot of the same design is the same robot.
    same = tdpcr.Robot(tdpcr.Design.load(str(DESIGNS / "lilge2022.ron")))
    a, b = robot.analyze(same.fk(Q6)), robot.analyze(robot.fk(Q6))
    np.testing.assert_array_equal(a["j_fk"], b["j_fk"])
    # An exactly singular analysis raises AnalysisError (not reachable from a converged
    # solution of the shipped designs); it is a RuntimeError like ConvergenceError.
    assert issubclass(tdpcr.AnalysisError, RuntimeError)
