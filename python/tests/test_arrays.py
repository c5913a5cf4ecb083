"""Inputs of any array-like form give the same bits; outputs are float64 arrays."""

import numpy as np
import pytest

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


def test_packed_record_fields_and_unaligned_buffers_read_their_values(robot):
    # A float64 field of a packed record (a float and a byte: strides of 9 bytes) and a
    # buffer at an odd offset: such views were read as other numbers.
    rec = np.zeros(6, dtype=[("q", "f8"), ("flag", "i1")])
    rec["q"] = Q6
    assert rec["q"].strides == (9,)
    raw = np.zeros(6 * 8 + 1, dtype=np.uint8)
    odd = np.frombuffer(raw.data, dtype=np.float64, count=6, offset=1)
    assert not odd.flags["ALIGNED"]
    raw[1:] = np.array(Q6, dtype=np.float64).view(np.uint8)
    ref = robot.fk(np.array(Q6))
    for q in (rec["q"], odd):
        np.testing.assert_array_equal(robot.fk(q).q, ref.q)
        np.testing.assert_array_equal(robot.fk(q).position, ref.position)
    rows = np.zeros((2, 6), dtype=[("q", "f8"), ("flag", "i1")])
    rows["q"] = [Q6, Q6]
    batch = robot.fk_many(rows["q"])
    np.testing.assert_array_equal(batch["position"][1], ref.position)


def test_masked_arrays_bytes_and_bad_rows_are_named(robot):
    # A masked array's masked values were used; bytes in an object array were parsed as
    # numbers where strings are refused; a batch's bad entry had a flat index.
    masked = np.ma.masked_array(Q6, mask=[0, 1, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="^q: a masked array with masked entries"):
        robot.fk(masked)
    np.testing.assert_array_equal(
        robot.fk(np.ma.masked_array(Q6)).q, robot.fk(np.array(Q6)).q
    )
    with pytest.raises(ValueError, match="^q: strings"):
        robot.fk(np.array([b"0.004"] + Q6[1:], dtype=object))
    rows = np.tile(Q6, (3, 1))
    rows[2, 4] = np.nan
    with pytest.raises(ValueError, match=r"^q: row 2, column 4 is NaN"):
        robot.fk_many(rows)


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


@pytest.mark.parametrize(
    "q, what",
    [
        (np.array(Q6) + 1e-3j, "complex numbers"),
        ([str(x) for x in Q6], "strings"),
        (np.array([str(x) for x in Q6], dtype=object), "strings"),
        ([0.004, "0.02", -0.003, -0.01, 0.002, 0.03], "strings"),
        (np.array(Q6).astype("datetime64[s]"), "dates"),
    ],
)
def test_complex_strings_and_dates_are_refused(robot, q, what):
    # numpy would drop the imaginary parts (with a warning) or parse the strings.
    with pytest.raises(ValueError, match=f"^q: {what}.*expected real numbers"):
        robot.fk(q)


def test_an_interrupt_during_conversion_is_not_a_value_error(robot):
    class Interrupting:
        def __float__(self):
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        robot.fk([Interrupting()] * 6)
    # An element that is no number stays a ValueError naming the argument.
    with pytest.raises(ValueError, match="^q: not an array of numbers"):
        robot.fk([object()] * 6)
