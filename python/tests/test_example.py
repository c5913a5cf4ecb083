"""examples/python/controller.py runs (without matplotlib) and warm steps are cheap."""

import pathlib
import subprocess
import sys

import numpy as np

from conftest import ROOT

EXAMPLE = ROOT / "examples" / "python" / "controller.py"


def test_controller_example_runs():
    out = subprocess.run(
        [sys.executable, str(EXAMPLE), "--steps", "5", "--no-plot"],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    lines = [l for l in out.stdout.splitlines() if l.startswith("step")]
    assert len(lines) == 5 and "µs" in lines[0]


def test_controller_returns_a_smooth_path():
    import importlib.util

    spec = importlib.util.spec_from_file_location("controller", EXAMPLE)
    controller = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(controller)
    q, rows = controller.run(steps=6, plot=False)
    assert q.shape == (6, 6) and np.isfinite(q).all()
    # Warm steps take fewer iterations than the cold first one.
    assert rows[1:, 2].max() < rows[0, 2]
