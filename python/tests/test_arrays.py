"""Inputs of any array-like form give the same bits; outputs are float64 arrays."""

import numpy as np

from conftest import Q6


def test_lists_int_and_float32_and_noncontiguous_inputs(robot):
    ref = robot.fk(np.array(Q6))
    wide = np.zeros((6, 2))
    wide[:, 0] = Q6
    strided = wide[:, 0]
    assert not strided.flags["C_CONTIGUOUS"]
    for q in (Q6, tuple(Q6), strided, np.array(Q6)[::-1][::-1]):
        np.testing.assert_array_equal(robot.fk(q).position, ref.position)
    zero = robot.fk(np.zeros(6, dtype=np.int64))
    np.testing.assert_array_equal(zero.position, robot.fk(np.zeros(6)).position)


def test_noncontiguous_batch(robot):
    Q = np.asfortranarray(np.array([Q6, Q6]))
    batch = robot.fk_many(Q)
    np.testing.assert_array_equal(batch["position"][1], robot.fk(Q6).position)


def test_outputs_are_writable_float64_copies(robot):
    s = robot.fk(Q6)
    p = s.position
    assert p.dtype == np.float64 and p.flags["C_CONTIGUOUS"]
    p[0] = 1.0
    assert s.position[0] != 1.0
