"""FK and IK: round trip, warm starts, per-call options, the analysis, the batch."""

import threading
import time

import numpy as np

import tdpcr
from conftest import DESIGNS, Q6


def test_fk_ik_round_trip(robot):
    fk = robot.fk(Q6)
    ik = robot.ik(fk.position, fk.rotvec)
    np.testing.assert_allclose(ik.q, Q6, atol=1e-9)
    np.testing.assert_allclose(ik.position, fk.position, atol=1e-12)
    assert fk.residual_norm <= 1e-10 and ik.residual_norm <= 1e-10


def test_solution_fields(robot):
    s = robot.fk(Q6)
    assert s.position.shape == (3,) and s.position.dtype == np.float64
    assert s.rotvec.shape == (3,)
    assert s.rotation.shape == (3, 3)
    np.testing.assert_allclose(s.rotation @ s.rotation.T, np.eye(3), atol=1e-12)
    np.testing.assert_array_equal(s.q, Q6)
    assert s.tensions.shape == (3, 2) and (s.tensions >= 0).all()
    assert s.iterations >= 1 and s.residual_evaluations >= s.iterations
    assert s.state.q.shape == (6,) and s.state.y_u.shape == (24,)


def test_warm_start_from_state(robot):
    cold = robot.fk(Q6)
    q = np.array(Q6) + 1e-4
    warm = robot.fk(q, init=cold.state)
    again_cold = robot.fk(q)
    assert warm.iterations < again_cold.iterations
    np.testing.assert_allclose(warm.position, again_cold.position, atol=1e-10)
    # A Solution works as init too, and a state survives JSON.
    robot.fk(q, init=cold)
    state = tdpcr.State.from_json(cold.state.to_json())
    np.testing.assert_array_equal(state.y_u, cold.state.y_u)


def test_per_call_options_do_not_stick(robot):
    loose = robot.fk(Q6, tolerance=1e-4)
    assert loose.residual_norm <= 1e-4
    fd = robot.fk(Q6, jacobian="fd-central")
    np.testing.assert_allclose(fd.position, robot.fk(Q6).position, atol=1e-9)
    assert robot.fk(Q6).residual_norm <= 1e-10


def test_wrench_moves_the_platform_down(robot):
    free = robot.fk(Q6)
    loaded = robot.fk(Q6, wrench=[0, 0, -0.5, 0, 0, 0])
    assert loaded.position[2] < free.position[2]


def test_analyze(robot):
    a = robot.analyze(robot.fk(Q6))
    assert a["j_fk"].shape == (6, 6) and a["j_ik"].shape == (6, 6)
    np.testing.assert_allclose(a["j_fk"] @ a["j_ik"], np.eye(6), atol=1e-6)
    assert a["compliance"].shape == (6, 6) and a["compliance"][2, 2] > 0
    assert set(a["rcond"]) == {"raw", "scaled"} and a["rcond"]["raw"]["b_xu"] > 0
    assert set(a["singularity"]) >= {"type_i", "type_ii", "leg"}
    assert a["stability"]["stable"] is True
    assert a["min_tension"] >= 0


def test_redundant_ik_within_limits(redundant_robot):
    fk = redundant_robot.fk(np.zeros(9))
    position = fk.position + [0.002, 0.0, 0.0]
    free = redundant_robot.ik(position)
    strict = redundant_robot.ik(position, limits="strict", reference=np.zeros(9))
    for s in (free, strict):
        np.testing.assert_allclose(s.position, position, atol=1e-9)
    assert strict.q.shape == (9,)


def test_least_norm_steps_from_the_last_factorization():
    robot = tdpcr.Robot(tdpcr.Design.load(DESIGNS / "lilge2022_redundant.ron"))
    assert robot.reuse_least_norm_factorization is False
    robot.reuse_least_norm_factorization = True
    assert robot.reuse_least_norm_factorization is True
    last = robot.ik(np.zeros(3))
    home = last.state
    jacobians = []
    for x in [0.001, 0.0] * 4:
        last = robot.ik(home.position + [x, 0.0, 0.0], last.rotvec, init=last)
        np.testing.assert_allclose(last.position, home.position + [x, 0.0, 0.0], atol=1e-9)
        jacobians.append(last.jacobian_evaluations)
    # After the first round trip, chord steps on the first factorization only.
    assert sum(jacobians[2:]) == 0, jacobians


def test_steps_of_the_9dof_design_cross_tendon_kinks():
    # The spiral out to a 10 mm circle of tests/redundant_kinks.rs: its 62nd step failed
    # where a tendon pair passes through both-slack (least-norm and within the limits).
    design = tdpcr.Design.load(DESIGNS / "lilge2022_redundant.ron")
    for limits in ("free", "strict"):
        failed = {}
        for across_kinks in (True, False):
            robot = tdpcr.Robot(design)
            assert robot.across_kinks is True
            robot.across_kinks = across_kinks
            state = robot.ik(np.zeros(3))
            rotvec = state.rotvec
            failed[across_kinks] = 0
            for k in range(1, 64):
                t = k / 63
                angle = 2 * np.pi * t
                target = 0.01 * t * np.array([np.cos(angle), np.sin(angle), 0.0])
                try:
                    state = robot.ik(target, rotvec, init=state, limits=limits)
                except tdpcr.ConvergenceError:
                    failed[across_kinks] += 1
        assert failed[True] == 0, limits
        assert failed[False] > 0, limits


def test_least_norm_steps_from_the_start_or_gauss_newton():
    design = tdpcr.Design.load(DESIGNS / "lilge2022_redundant.ron")
    runs = {}
    # One start for both (the cold solves' one-sided steps across the tendons' kinks at
    # the straight guess put the two rules' homes 4.2e-6 m apart in q).
    home = tdpcr.Robot(design).ik(np.zeros(3))
    for gauss_newton in (False, True):
        robot = tdpcr.Robot(design)
        assert robot.least_norm_gauss_newton is False
        robot.least_norm_gauss_newton = gauss_newton
        assert robot.least_norm_gauss_newton is gauss_newton
        target = home.state.position + [0.001, 0.0, 0.0]
        step = robot.ik(target, home.rotvec, init=home)
        np.testing.assert_allclose(step.position, target, atol=1e-9)
        runs[gauss_newton] = step
    assert runs[False].jacobian_evaluations == 1
    assert runs[True].jacobian_evaluations == 2
    # Two solutions of the same pose, a few nanometres apart in q.
    difference = np.abs(runs[False].q - runs[True].q).max()
    assert 1e-11 < difference < 1e-7, difference


def test_fk_many_equals_the_loop(robot):
    rng = np.random.default_rng(1)
    Q = np.array(Q6) + rng.uniform(-1e-3, 1e-3, size=(5, 6))
    batch = robot.fk_many(Q)
    assert batch["converged"].dtype == np.bool_ and batch["converged"].all()
    assert batch["rotation"].shape == (5, 3, 3) and batch["tensions"].shape == (5, 3, 2)
    for k, q in enumerate(Q):
        s = robot.fk(q)
        np.testing.assert_array_equal(batch["position"][k], s.position)
        np.testing.assert_array_equal(batch["q"][k], s.q)
        np.testing.assert_array_equal(batch["tensions"][k], s.tensions)
        assert batch["iterations"][k] == s.iterations


def test_fk_many_marks_failures(robot):
    Q = np.array([Q6, Q6])
    batch = robot.fk_many(Q, max_iterations=1)
    assert not batch["converged"].any()
    # Failed rows are zeros, never NaN; the mask says which rows hold results.
    assert not np.isnan(batch["position"]).any()
    np.testing.assert_array_equal(batch["position"], 0.0)
    np.testing.assert_array_equal(batch["iterations"], 1)
    assert set(batch["errors"]) == {0, 1}


def test_fk_many_releases_the_gil(robot):
    """The main thread keeps running Python while another thread is in fk_many: the
    longest pause between its loop turns stays well below the batch's duration (with the
    GIL held it would be the whole batch)."""
    # Long enough to see the pauses (128 rows took 46 ms on the 2-core machine once the
    # Jacobian got faster, 2026-11-28, under the 50 ms this test needs).
    Q = np.tile(Q6, (512, 1))
    worker = threading.Thread(target=robot.fk_many, args=(Q,))
    turns = []
    start = time.perf_counter()
    worker.start()
    while worker.is_alive():
        turns.append(time.perf_counter())
    duration = time.perf_counter() - start
    longest_pause = max(np.diff([start, *turns, start + duration]))
    assert duration > 0.05
    assert longest_pause < 0.5 * duration
