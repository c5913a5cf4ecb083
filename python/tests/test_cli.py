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
