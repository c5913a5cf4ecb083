"""A task for the worker-kill test of tdpcr.optim, importable by the test's workers
(they run with this directory on PYTHONPATH): the real evaluation, started late enough
that a worker can be killed while it runs, leaving a marker of which process started
which candidate."""

import json
import os
import pathlib
import time

from tdpcr.optim import evaluate

#: Where the markers go (set by the test in the workers' environment).
MARKERS = os.environ.get("TDPCR_TEST_MARKERS")
#: Seconds each task waits before evaluating.
DELAY_S = 1.0


def slow_evaluate(problem: str, candidate: str) -> str:
    if MARKERS:
        cid = json.loads(candidate)["id"]
        pathlib.Path(MARKERS, f"{cid}-{os.getpid()}").touch()
    time.sleep(DELAY_S)
    return evaluate(problem, candidate)
