"""Ctrl-C (SIGINT) stops long calls within a fraction of a second; it waited for the end
of a workspace sweep or a batch before. The robot stays usable after."""

import os
import signal
import threading
import time

import numpy as np
import pytest

from conftest import Q6

# The calls below take several seconds uninterrupted (the default Δ = 3 mm sweep about
# 20 s on 2 cores; 4 000 cold FKs about 3 s); each is interrupted after DELAY.
DELAY = 0.3
# Longest time to stop: the rays or rows under way finish, each in milliseconds.
STOP_WITHIN = 1.5


def interrupted(call):
    """Runs `call` with SIGINT sent to this process after DELAY; the seconds it took.
    Python's own SIGINT handler is installed for the call: a process started in the
    background by a non-interactive shell (a CI script's `cmd &`) inherits SIGINT
    ignored, and Python then leaves it ignored."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(DELAY, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.perf_counter()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            call()
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    return time.perf_counter() - start


@pytest.mark.skipif(os.name != "posix", reason="SIGINT to self")
def test_ctrl_c_stops_a_workspace_sweep(robot):
    took = interrupted(lambda: robot.workspace())
    assert took < DELAY + STOP_WITHIN, took
    # Usable after: a small sweep completes.
    small = robot.workspace(step=0.02, angle_step=0.6, z_range=[-0.02, 0.0])
    assert len(small["position"]) > 0


@pytest.mark.skipif(os.name != "posix", reason="SIGINT to self")
def test_ctrl_c_stops_batches_and_trajectories(robot):
    rng = np.random.default_rng(1)
    rows = np.array(Q6) + rng.uniform(-2e-3, 2e-3, size=(4000, 6))
    took = interrupted(lambda: robot.fk_many(rows))
    assert took < DELAY + STOP_WITHIN, took
    # A trajectory back and forth along x, 200 000 warm IK steps (several seconds).
    home = robot.fk(np.zeros(6))
    poses = np.zeros((200_000, 6))
    poses[:, :3] = home.position
    poses[:, 0] += 1e-3 * np.sin(np.arange(200_000) * 0.05)
    took = interrupted(lambda: robot.trajectory_ik(poses))
    assert took < DELAY + STOP_WITHIN, took
    assert robot.fk_many(rows[:20])["converged"].all()
