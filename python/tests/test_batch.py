"""Batches: ik_many (parallel, cold) and trajectory_fk/ik (warm, in order) equal the loop
of single calls bit for bit; failed rows are zeros behind the `converged` mask."""

import numpy as np
import pytest

import tdpcr
from conftest import Q6

KEYS = ("position", "rotation", "rotvec", "q")


def path(m=4):
    """Poses (m, 6) along a short line of the reference design [m, rad]."""
    poses = np.zeros((m, 6))
    poses[:, 0] = np.linspace(0.0, 0.002, m)
    poses[:, 2] = -0.02
    poses[:, 3] = 0.02
    return poses


def assert_row_is(batch, k, s):
    for key in KEYS:
        np.testing.assert_array_equal(batch[key][k], getattr(s, key), err_msg=key)
    assert batch["iterations"][k] == s.iterations
    assert batch["residual_norm"][k] == s.residual_norm


def test_ik_many_equals_the_loop(design):
    poses = path(3)
    batch = tdpcr.Robot(design).ik_many(poses)
    assert batch["converged"].all() and batch["errors"] == {}
    assert batch["tensions"].shape == (3, 3, 2)
    robot = tdpcr.Robot(design)
    for k, p in enumerate(poses):
        s = robot.ik(p[:3], p[3:])
        assert_row_is(batch, k, s)
        np.testing.assert_array_equal(batch["tensions"][k], s.tensions)


def test_trajectory_ik_equals_the_warm_loop(design):
    poses = path(4)
    batch = tdpcr.Robot(design).trajectory_ik(poses)
    assert batch["converged"].all()
    robot, s = tdpcr.Robot(design), None
    for k, p in enumerate(poses):
        s = robot.ik(p[:3], p[3:], init=None if s is None else s.state)
        assert_row_is(batch, k, s)
    # Warm steps need fewer iterations than the cold first one.
    assert batch["iterations"][1:].max() < batch["iterations"][0]


def test_trajectory_fk_equals_the_warm_loop(design):
    Q = np.array(Q6) + np.linspace(0.0, 1e-3, 4)[:, None]
    batch = tdpcr.Robot(design).trajectory_fk(Q)
    assert batch["converged"].all()
    robot, s = tdpcr.Robot(design), None
    for k, q in enumerate(Q):
        s = robot.fk(q, init=None if s is None else s.state)
        assert_row_is(batch, k, s)
    assert batch["solve_time_us"].shape == (4,) and (batch["solve_time_us"] > 0).all()


def test_batches_accept_threads_and_give_the_same_bits(robot):
    Q = np.array(Q6) + np.linspace(0.0, 1e-3, 4)[:, None]
    one = robot.fk_many(Q, threads=1)
    two = robot.fk_many(Q, threads=2)
    for key in KEYS + ("tensions", "iterations"):
        np.testing.assert_array_equal(one[key], two[key])
    with pytest.raises(ValueError, match="^threads:"):
        robot.fk_many(Q, threads=0)
    # A typo's 30 000 threads loaded the machine for minutes (one row).
    with pytest.raises(ValueError, match="^threads: 30000: expected 1 to 1024"):
        robot.fk_many(Q[:1], threads=30000)
    # More threads than rows: the rows' own.
    np.testing.assert_array_equal(robot.fk_many(Q, threads=64)["q"], one["q"])


def test_failed_steps_are_zero_masked_and_the_next_starts_cold(design):
    Q = np.array([Q6, [1.0] * 6, Q6])
    batch = tdpcr.Robot(design).trajectory_fk(Q)
    np.testing.assert_array_equal(batch["converged"], [True, False, True])
    assert set(batch["errors"]) == {1} and "converge" in batch["errors"][1]
    # The row's reason is the one the equivalent warm solve raises.
    loop = tdpcr.Robot(design)
    first = loop.fk(Q[0])
    with pytest.raises(tdpcr.ConvergenceError) as single:
        loop.fk(Q[1], init=first.state)
    assert batch["reasons"] == {1: single.value.reason}
    for key in KEYS + ("residual_norm", "solve_time_us"):
        assert not np.isnan(batch[key]).any()
        np.testing.assert_array_equal(batch[key][1], 0.0, err_msg=key)
    # Recovery rule: the step after the failure starts cold, as the first did.
    np.testing.assert_array_equal(batch["position"][2], batch["position"][0])
    assert batch["iterations"][2] == batch["iterations"][0]


def test_ik_many_failures_and_options(robot):
    poses = np.vstack([path(1), path(1)])
    batch = robot.ik_many(poses, max_iterations=1)
    assert not batch["converged"].any() and set(batch["errors"]) == {0, 1}
    assert batch["reasons"] == {0: "iteration_limit", 1: "iteration_limit"}
    np.testing.assert_array_equal(batch["q"], 0.0)


def test_redundant_batches_with_limits(redundant_robot):
    home = redundant_robot.fk(np.zeros(9))
    poses = np.zeros((2, 6))
    poses[:, :3] = home.position
    poses[1, 0] += 0.002
    strict = redundant_robot.trajectory_ik(poses, limits="strict", reference=np.zeros(9))
    assert strict["converged"].all() and strict["q"].shape == (2, 9)
    free = redundant_robot.ik_many(poses)
    np.testing.assert_allclose(free["position"], poses[:, :3], atol=1e-9)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda r: r.trajectory_fk(np.zeros((2, 5))), "q"),
        (lambda r: r.trajectory_fk(np.full((2, 6), np.nan)), "q"),
        (lambda r: r.trajectory_ik(np.zeros((2, 3))), "poses"),
        (lambda r: r.ik_many(np.zeros(6)), "poses"),
        (lambda r: r.ik_many(path(1), limits="tight"), "limits"),
        (lambda r: r.trajectory_ik(path(1), wrench=[1, 2]), "wrench"),
        (lambda r: r.ik_many([["a"] * 6]), "poses"),
    ],
)
def test_bad_batch_arguments_name_the_argument(robot, call, name):
    with pytest.raises(ValueError, match=f"^{name}:"):
        call(robot)


def test_non_contiguous_fortran_float32_and_int_batches(robot):
    wide = np.zeros((3, 12))
    wide[:, ::2] = np.array(Q6) + np.linspace(0.0, 1e-3, 3)[:, None]
    strided = wide[:, ::2]
    assert not strided.flags["C_CONTIGUOUS"]
    ref = robot.fk_many(np.ascontiguousarray(strided))
    for Q in (strided, np.asfortranarray(strided)):
        np.testing.assert_array_equal(robot.fk_many(Q)["position"], ref["position"])
    # float32 is widened (its values, not the float64 ones: compare with the widened copy).
    Q32 = strided.astype(np.float32)
    np.testing.assert_array_equal(
        robot.fk_many(Q32)["q"], Q32.astype(np.float64)
    )
    zeros = robot.trajectory_fk(np.zeros((2, 6), dtype=np.int32))
    assert zeros["converged"].all() and zeros["q"].dtype == np.float64


def test_bad_settings_raise_before_any_row_is_solved(robot):
    rows = np.tile(Q6, (3, 1))
    with pytest.raises(ValueError, match="settings.tolerance = -1"):
        robot.fk_many(rows, tolerance=-1.0)
    with pytest.raises(ValueError, match="settings.max_iterations = 0"):
        robot.trajectory_fk(rows, max_iterations=0)


def test_failed_rows_are_listed_in_row_order(robot):
    rows = np.tile(Q6, (6, 1))
    rows[[4, 1, 3]] = 1.0  # far beyond the limits: these rows fail
    d = robot.fk_many(rows)
    assert list(d["errors"]) == [1, 3, 4] and list(d["reasons"]) == [1, 3, 4]
    assert all(r.isidentifier() and r.islower() for r in d["reasons"].values())
    assert not d["converged"][[1, 3, 4]].any() and d["converged"][[0, 2, 5]].all()
