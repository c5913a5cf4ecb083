"""Agreement with the CLI's JSON (`tdpcr fk/ik --format json`) to 1e-12."""

import json
import subprocess

import numpy as np

import tdpcr
from conftest import DESIGNS, Q6

DESIGN = str(DESIGNS / "lilge2022.ron")
FIELDS = ("position", "rotation", "rotvec", "q", "tensions", "residual_norm")


def run(cli, *args):
    out = subprocess.run([cli, *args, "--format", "json"], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def assert_agrees(solution, expected):
    for name in FIELDS:
        np.testing.assert_allclose(getattr(solution, name), expected[name], rtol=0, atol=1e-12, err_msg=name)
    assert solution.iterations == expected["iterations"]
    np.testing.assert_allclose(solution.state.y_u, expected["state"]["y_u"], rtol=0, atol=1e-12)


def test_fk_agrees_with_cli(cli, robot):
    q = ",".join(map(str, Q6))
    expected = run(cli, "fk", DESIGN, "--q", q, "--wrench", "0.1,0,-0.2,0,0.01,0")
    assert_agrees(robot.fk(Q6, wrench=[0.1, 0, -0.2, 0, 0.01, 0]), expected)


def test_ik_agrees_with_cli(cli, robot):
    expected = run(cli, "ik", DESIGN, "--position", "0.005,-0.003,-0.02", "--rotvec", "0.1,0,0.05")
    assert_agrees(robot.ik([0.005, -0.003, -0.02], [0.1, 0, 0.05]), expected)


def test_warm_fk_agrees_with_cli(cli, design, tmp_path):
    path = tmp_path / "state.json"
    path.write_text(tdpcr.Robot(design).fk(Q6).state.to_json())
    q = np.array(Q6) + 5e-4
    expected = run(cli, "fk", DESIGN, "--q", ",".join(repr(float(x)) for x in q), "--init", str(path))
    # A fresh robot, as the CLI: warm from the state read back, without the tangent
    # predictor a robot keeps from its own last solve.
    init = tdpcr.State.from_json(path.read_text())
    assert_agrees(tdpcr.Robot(design).fk(q, init=init), expected)


def test_analyze_agrees_with_cli(cli, robot):
    q = ",".join(map(str, Q6))
    expected = run(cli, "analyze", DESIGN, "--q", q)
    a = robot.analyze(robot.fk(Q6))
    for name in ("j_fk", "j_ik", "compliance", "lambda_fk", "lambda_ik", "lambda_c"):
        np.testing.assert_allclose(a[name], expected[name], rtol=1e-12, atol=1e-12, err_msg=name)
    for variant in ("raw", "scaled"):
        got, want = a["rcond"][variant], expected["rcond"][variant]
        assert set(got) == set(want)
        for k in want:
            np.testing.assert_allclose(got[k], want[k], rtol=1e-12, atol=0, err_msg=k)
    assert a["singularity"] == expected["singularity"]
    assert a["thresholds"] == expected["thresholds"]
    np.testing.assert_allclose(a["min_tension"], expected["min_tension"], rtol=0, atol=1e-12)


def test_trajectory_ik_agrees_with_cli(cli, robot, tmp_path):
    poses = np.array([[0.0, 0.0, -0.02, 0.0, 0.0, 0.0], [0.001, 0.0, -0.02, 0.0, 0.0, 0.01]])
    path = tmp_path / "poses.csv"
    path.write_text("x,y,z,rx,ry,rz\n" + "\n".join(",".join(repr(float(x)) for x in p) for p in poses) + "\n")
    expected = run(cli, "trajectory", DESIGN, "--ik", str(path))["steps"]
    batch = robot.trajectory_ik(poses)
    for k, step in enumerate(expected):
        assert step["converged"] and batch["converged"][k]
        for name in ("position", "rotvec", "q", "residual_norm"):
            np.testing.assert_allclose(batch[name][k], step[name], rtol=0, atol=1e-12, err_msg=name)
        assert batch["iterations"][k] == step["iterations"]


def test_tdcr_agrees_with_cli(cli):
    robot_file = str(DESIGNS / "tdcr_one_segment.ron")
    expected = run(cli, "tdcr", robot_file, "--tensions", "1.5,0.2", "--tip-force", "0,0.1,0")
    got = tdpcr.Tdcr.load(robot_file).solve(tensions=[1.5, 0.2], tip_force=[0, 0.1, 0])
    for name in ("tip_position", "tip_rotation", "tensions", "slacks", "shape", "shape_arcs", "residual_norm"):
        np.testing.assert_allclose(got[name], expected[name], rtol=0, atol=1e-12, err_msg=name)
    assert got["iterations"] == expected["iterations"]
    for name in ("u0", "v0", "gammas"):
        np.testing.assert_allclose(got["state"][name], expected["state"][name], rtol=0, atol=1e-12)
