"""Solution.shape, tdpcr.Tdcr and Robot.workspace."""

import time

import numpy as np
import pytest

import tdpcr
from conftest import DESIGNS, Q6


def test_shape_runs_from_the_bases_to_the_platform(robot):
    s = robot.fk(Q6)
    shape = s.shape
    assert shape.shape[0] == 3 and shape.shape[2] == 3 and shape.dtype == np.float64
    assert np.isfinite(shape).all()
    # Each leg's last disk is near the platform (within the coupling radius), its base far.
    tips = np.linalg.norm(shape[:, -1] - s.position, axis=1)
    bases = np.linalg.norm(shape[:, 0] - s.position, axis=1)
    assert (tips < bases).all()
    # Consecutive points are one disk spacing apart (inextensible up to strain).
    steps = np.linalg.norm(np.diff(shape, axis=1), axis=2)
    np.testing.assert_allclose(steps[:, 1:], steps[0, 1], rtol=1e-2)


def tdcr():
    return tdpcr.Tdcr.load(DESIGNS / "tdcr_one_segment.ron")


def test_tdcr_tension_and_displacement_control_agree():
    robot = tdcr()
    assert robot.n_tendons == 2
    by_tension = robot.solve(tensions=[1.0, 0.0])
    assert by_tension["tip_position"].shape == (3,)
    assert by_tension["shape"].shape[1] == 3
    assert by_tension["shape"].shape[0] == by_tension["shape_arcs"].shape[0]
    np.testing.assert_allclose(by_tension["shape"][-1], by_tension["tip_position"], atol=1e-12)
    # A warm start from the state converges at once to the same tip.
    warm = robot.solve(tensions=[1.0, 0.0], init=by_tension["state"])
    assert warm["iterations"] <= 1
    np.testing.assert_allclose(warm["tip_position"], by_tension["tip_position"], atol=1e-12)


def test_tdcr_errors():
    robot = tdcr()
    with pytest.raises(ValueError, match="exactly one"):
        robot.solve()
    with pytest.raises(ValueError, match="tensions"):
        robot.solve(tensions=[1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="^tip_force:"):
        robot.solve(tensions=[1.0, 0.0], tip_force=[0, 0])
    with pytest.raises(ValueError, match="^init:"):
        robot.solve(tensions=[1.0, 0.0], init={"u0": 1})
    with pytest.raises(ValueError, match="tolerance"):
        robot.solve(tensions=[1.0, 0.0], tolerance=0.0)
    with pytest.raises(tdpcr.ConvergenceError) as e:
        robot.solve(tensions=[5.0, 0.0], max_iterations=1)
    assert e.value.reason == "iteration_limit" and e.value.iterations == 1
    with pytest.raises(tdpcr.DesignError):
        tdpcr.Tdcr.from_ron("Tdcr(")


def coarse(robot, **kw):
    return robot.workspace(step=0.01, angle_step=0.6, z_range=[-0.01, 0.0], **kw)


def test_workspace_columns_and_progress(robot):
    calls = []
    ws = coarse(robot, progress=lambda done, total: calls.append((done, total)))
    m = ws["position"].shape[0]
    assert m > 0 and ws["cell"].shape == (m, 3) and ws["q"].shape == (m, 6)
    assert ws["tensions"].shape == (m, 6)
    assert ws["reachable"].dtype == np.bool_ and ws["reachable"].any()
    assert set(ws["rcond"]) >= {"b_xu", "b_qu", "b_u"} and ws["rcond"]["b_xu"].shape == (m,)
    assert set(ws["singularity"]) == {"type_i", "type_ii", "leg"}
    assert ws["min_tension"].shape == (m,) and ws["stable"].dtype == np.bool_
    assert ws["summary"]["counts"]["reachable"] == int(ws["reachable"].sum())
    # Throttled: a start, at most a few per second, and the end.
    assert calls and calls[-1][0] == calls[-1][1] and len(calls) <= 50


def test_workspace_two_sided_kinks_same_cells_more_jacobians(robot):
    kw = dict(step=0.003, angle_step=0.4, z_range=[-0.003, 0.0])
    one = robot.workspace(**kw)
    two = robot.workspace(one_sided_kinks=False, **kw)
    assert one["settings"]["one_sided_kinks"] is True
    assert two["settings"]["one_sided_kinks"] is False
    np.testing.assert_array_equal(one["cell"], two["cell"])
    assert one["cell"].shape[0] > 500
    j1, j2 = (w["summary"]["jacobian_evaluations"] for w in (one, two))
    assert 2 * j1 < j2, (j1, j2)


def test_workspace_chord_contraction_same_cells_fewer_jacobians(robot):
    kw = dict(step=0.012, angle_step=0.6, z_range=[-0.036, 0.036], tolerance=1e-8)
    tight = robot.workspace(**kw)
    loose = robot.workspace(chord_contraction=0.5, **kw)
    assert tight["settings"]["chord_contraction"] == 0.1
    assert loose["settings"]["chord_contraction"] == 0.5
    np.testing.assert_array_equal(tight["cell"], loose["cell"])
    assert tight["cell"].shape[0] > 50
    j1, j2 = (w["summary"]["jacobian_evaluations"] for w in (tight, loose))
    assert j2 < j1, (j1, j2)
    with pytest.raises(ValueError, match="chord_contraction"):
        robot.workspace(chord_contraction=1.0, **kw)


def test_workspace_probe_iterations_same_cells_less_failed_work(robot):
    kw = dict(step=0.012, angle_step=0.6, z_range=[-0.036, 0.036], tolerance=1e-8,
              max_iterations=20)
    late = robot.workspace(**kw)
    early = robot.workspace(probe_iterations=8, **kw)
    assert late["settings"]["probe_iterations"] == 15
    assert early["settings"]["probe_iterations"] == 8
    np.testing.assert_array_equal(late["cell"], early["cell"])
    f1, f2 = (w["summary"]["failed_newton_iterations"] for w in (late, early))
    assert f2 < f1, (f1, f2)
    with pytest.raises(ValueError, match="probe_iterations"):
        robot.workspace(probe_iterations=0, **kw)


def test_workspace_errors(robot):
    with pytest.raises(ValueError, match="step"):
        robot.workspace(step=-1.0)
    with pytest.raises(ValueError, match="^collisions:"):
        robot.workspace(collisions="ignore")
    with pytest.raises(ValueError, match="^z_range:"):
        robot.workspace(z_range=[0.0])

    def fails(done, total):
        raise KeyError("from the callback")

    with pytest.raises(KeyError, match="from the callback"):
        coarse(robot, progress=fails)


def test_an_empty_workspace_has_every_column(robot):
    # No plane of the range is reached (the paths stop at the actuation limits long
    # before z = 0.3 m): every documented column is there, empty.
    ws = robot.workspace(step=0.003, angle_step=0.5, z_range=(0.3, 0.3))
    assert ws["position"].shape == (0, 3) and ws["reachable"].shape == (0,)
    assert set(ws["rcond"]) >= {"b_xu", "b_qu", "b_u"} and ws["rcond"]["b_xu"].shape == (0,)
    assert set(ws["rcond_scaled"]) >= {"b_xu", "b_qu", "b_u"}
    assert set(ws["singularity"]) == {"type_i", "type_ii", "leg"}
    for key in ("min_tension", "stable", "min_compliance_eigenvalue", "leg_switch"):
        assert ws[key].shape == (0,), key


def test_a_raising_progress_callback_stops_the_sweep(robot):
    # The default Δ = 3 mm sweep takes about 20 s on 2 cores; a callback that raises at
    # its first call (rays_done = 0) stops it within a fraction of a second.
    def fails(done, total):
        raise KeyError("stop here")

    start = time.perf_counter()
    with pytest.raises(KeyError, match="stop here"):
        robot.workspace(progress=fails)
    assert time.perf_counter() - start < 3.0


def test_a_progress_callback_runs_on_the_calling_thread_one_call_at_a_time(robot, design):
    # Called from the sweep's rayon workers, two calls ran at once, and a slow callback
    # that ran a batch itself (on rayon's pool) waited for the workers it blocked: the
    # sweep hung for good, Ctrl-C included.
    import threading

    Q = np.tile(Q6, (16, 1))
    seen = {"threads": set(), "active": 0, "overlap": False}

    def slow(done, total):
        seen["threads"].add(threading.get_ident())
        seen["active"] += 1
        seen["overlap"] |= seen["active"] > 1
        time.sleep(0.3)
        tdpcr.Robot(design).fk_many(Q)
        seen["active"] -= 1

    result = {}
    worker = threading.Thread(
        target=lambda: result.setdefault(
            "ws", robot.workspace(step=0.006, angle_step=0.4, z_range=[-0.012, 0.0], progress=slow)
        ),
        daemon=True,
    )
    worker.start()
    worker.join(timeout=120)
    assert not worker.is_alive(), "the sweep hung"
    assert result["ws"]["summary"]["counts"]["reachable"] > 0
    assert seen["threads"] == {worker.ident} and not seen["overlap"]
