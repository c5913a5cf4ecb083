"""Shared fixtures: the repository's designs, robots of them, and the CLI binary."""

import os
import pathlib
import subprocess

import pytest

import tdpcr

ROOT = pathlib.Path(__file__).resolve().parents[2]
DESIGNS = ROOT / "designs"
# An actuation of the reference 6-DoF design (README's quick start) [m].
Q6 = [0.004, 0.02, -0.003, -0.01, 0.002, 0.03]


@pytest.fixture(scope="session")
def design():
    return tdpcr.Design.load(DESIGNS / "lilge2022.ron")


@pytest.fixture()
def robot(design):
    return tdpcr.Robot(design)


@pytest.fixture()
def redundant_robot():
    return tdpcr.Robot(tdpcr.Design.load(DESIGNS / "lilge2022_redundant.ron"))


@pytest.fixture(scope="session")
def cli():
    """The `tdpcr` binary: $TDPCR_BIN, else target/debug/tdpcr (cargo brings it up to date)."""
    if "TDPCR_BIN" in os.environ:
        return os.environ["TDPCR_BIN"]
    subprocess.run(["cargo", "build", "--quiet", "--bin", "tdpcr"], cwd=ROOT, check=True)
    return str(ROOT / "target" / "debug" / "tdpcr")
