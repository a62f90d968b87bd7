"""number_text: float tokens read back bit for bit (Python and C strtod), equal repr whenever
repr has at most 15 significant digits; integer tokens equal str; rows join as text would.

The default run is deterministic; ``HYPOTHESIS_PROFILE=fuzz`` runs many more random examples.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import math
import os
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from bsp_triangulate.formats.number_text import (
    float_field,
    float_tokens,
    int_field,
    int_tokens,
    join_rows,
)

FUZZ = os.environ.get("HYPOTHESIS_PROFILE") == "fuzz"


def examples(count: int) -> settings:
    """``count`` deterministic examples, or many random ones under the fuzz profile."""
    if FUZZ:
        return settings(max_examples=20 * count, deadline=None)
    return settings(
        max_examples=count,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow],
    )


_LIBC = ctypes.CDLL(ctypes.util.find_library("c"))
_LIBC.strtod.restype = ctypes.c_double
_LIBC.strtod.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_void_p)]


def c_strtod(token: str) -> float:
    """The C library's strtod (what MDAL's atof calls); it must read the whole token."""
    text = ctypes.create_string_buffer(token.encode("ascii"))
    end = ctypes.c_void_p()
    value = _LIBC.strtod(text, ctypes.byref(end))
    assert end.value - ctypes.addressof(text) == len(token), token
    return value


def bits(value: float) -> int:
    return struct.unpack("<Q", struct.pack("<d", value))[0]


def significant_digits(text: str) -> int:
    mantissa = text.lstrip("-").split("e")[0].replace(".", "")
    return len(mantissa.lstrip("0").rstrip("0")) or 1


def check_tokens(values: list[float]) -> None:
    tokens = float_tokens(np.array(values, dtype=np.float64))
    assert len(tokens) == len(values)
    for value, token in zip(values, tokens):
        assert token == token.strip() and " " not in token and token, (value, token)
        if math.isnan(value):
            assert token == "nan"
            continue
        # Bit for bit, so -0.0 keeps its sign.
        assert bits(float(token)) == bits(value), (value, token)
        assert bits(c_strtod(token)) == bits(value), (value, token)
        expected = repr(value)
        if significant_digits(expected) <= 15:
            assert token == expected, (value, token)
        else:
            assert significant_digits(token) <= 17, (value, token)
        if not 1e-4 <= abs(value) < 1e16:  # outside the vectorised path: repr itself
            assert token == expected, (value, token)


def from_bits(pattern: int) -> float:
    return struct.unpack("<d", struct.pack("<Q", pattern))[0]


SPECIAL = [
    0.0,
    -0.0,
    0.1,
    0.2,
    0.30000000000000004,
    1 / 3,
    2 / 3,
    1e-7,
    1e-5,
    1e-4,
    math.nextafter(1e-4, 0),
    math.nextafter(1e-4, 1),
    0.001,
    1.0,
    12.0,
    351182.162,
    6_000_000.5,
    99999.99999999999,
    1e15,
    123456789012345.6,
    9999999999999998.0,
    math.nextafter(1e16, 0),
    1e16,
    1e22,
    2.0**53 - 1,
    2.0**53,
    2.0**53 + 2,
    2.0**-1074,  # smallest subnormal
    2.2250738585072014e-308,
    1.7976931348623157e308,
    math.inf,
    -math.inf,
    math.nan,
    -351182.162,
    -1e-4,
]


def test_special_values_read_back_and_match_repr_when_short():
    check_tokens(SPECIAL)
    tokens = float_tokens(np.array(SPECIAL))
    assert tokens[:2] == ["0.0", "-0.0"]
    assert tokens[SPECIAL.index(351182.162)] == "351182.162"
    assert tokens[SPECIAL.index(12.0)] == "12.0"
    assert tokens[SPECIAL.index(1e22)] == "1e+22"
    assert tokens[SPECIAL.index(1e-7)] == "1e-07"


def test_powers_of_ten_and_their_neighbours():
    powers = [10.0**k for k in range(-8, 24)] + [float(f"1e{k}") for k in range(-8, 24)]
    values = []
    for power in powers:
        values += [power, math.nextafter(power, 0), math.nextafter(power, math.inf)]
    check_tokens(values + [-v for v in values])


def test_powers_of_two_and_their_neighbours():
    values = []
    for k in range(-30, 60):
        power = 2.0**k
        values += [power, math.nextafter(power, 0), math.nextafter(power, math.inf)]
    check_tokens(values)


@examples(300)
@given(st.floats(allow_nan=True, allow_infinity=True))
def test_any_double_reads_back(value):
    check_tokens([value])


@examples(300)
@given(st.integers(0, 2**64 - 1))
def test_bit_pattern_random_doubles_read_back(pattern):
    check_tokens([from_bits(pattern)])


@examples(300)
@given(st.integers(-(10**15) + 1, 10**15 - 1), st.integers(0, 19))
def test_decimals_of_up_to_15_digits_equal_repr(digits, decimals):
    value = digits / 10**decimals
    check_tokens([value])
    assert significant_digits(repr(value)) > 15 or float_tokens(np.array([value])) == [repr(value)]


@examples(200)
@given(
    st.sampled_from([(3e5, 4e5), (6.0e6, 6.1e6), (0.0, 2000.0), (-180.0, 180.0), (1e-4, 1.0)]),
    st.floats(0, 1),
    st.one_of(st.none(), st.integers(0, 6)),
)
def test_coordinates_read_back(bounds, fraction, decimals):
    value = bounds[0] + fraction * (bounds[1] - bounds[0])
    if decimals is not None:
        value = round(value, decimals)
    check_tokens([value, -value])


@examples(100)
@given(arrays(np.float64, st.integers(1, 40), elements=st.floats(width=64)))
def test_arrays_mixing_fast_and_repr_values(values):
    # One field holds tokens of every kind and length side by side.
    check_tokens(values.tolist())


def test_integers_of_every_magnitude_equal_str():
    values = [0, 1, -1, 9, 10, 99, 100, 9999, 10000, 123456789, -(2**31), 2**31 - 1]
    values += [10**k for k in range(19)] + [10**k - 1 for k in range(1, 19)]
    values += [-(2**63), 2**63 - 1, -(10**18)]
    assert int_tokens(np.array(values, dtype=np.int64)) == [str(v) for v in values]
    assert int_tokens(np.array([0, 2**63, 2**64 - 1], dtype=np.uint64)) == [
        "0",
        str(2**63),
        str(2**64 - 1),
    ]
    assert int_tokens(np.array([True, False])) == ["1", "0"]
    for dtype in (np.int8, np.uint8, np.int16, np.uint16, np.int32, np.uint32):
        info = np.iinfo(dtype)
        column = np.array([info.min, 0, info.max], dtype=dtype)
        assert int_tokens(column) == [str(v) for v in column.tolist()]
    with pytest.raises(TypeError):
        int_field(np.array([1.5]))


@examples(200)
@given(arrays(np.int64, st.integers(1, 40)))
def test_integer_arrays_equal_str(values):
    assert int_tokens(values) == [str(v) for v in values.tolist()]


@examples(100)
@given(
    arrays(np.int64, st.integers(1, 30), elements=st.integers(-(10**9), 10**9)),
    st.data(),
)
def test_rows_join_like_python_formatting(ids, data):
    rows = len(ids)
    xs = data.draw(arrays(np.float64, rows, elements=st.floats(width=64)))
    ys = data.draw(arrays(np.float64, rows, elements=st.floats(-1e7, 1e7)))
    text = join_rows([b"ND ", int_field(ids), b" ", float_field(xs), b"\t", float_field(ys), b"\n"])
    lines = text.decode("ascii").split("\n")
    assert lines[-1] == "" and len(lines) == rows + 1
    for line, i, x, y in zip(lines, ids.tolist(), xs.tolist(), ys.tolist()):
        head, first, second = line.split(" ")[0], line.split(" ")[1], line.split(" ", 2)[2]
        assert head == "ND" and first == str(i)
        x_token, y_token = second.split("\t")
        assert x_token == float_tokens(np.array([x]))[0]
        assert bits(float(y_token)) == bits(y)


def test_join_rows_edge_cases():
    column = np.array([1.5, -2.0, math.nan])
    assert join_rows([float_field(column), b"\n"]) == b"1.5\n-2.0\nnan\n"
    assert join_rows([b"<", float_field(column), b">"]) == b"<1.5><-2.0><nan>"
    assert join_rows([int_field(np.array([7])), b",", int_field(np.array([-8]))]) == b"7,-8"
    assert join_rows([float_field(np.zeros(0)), b"\n"]) == b""
    with pytest.raises(ValueError, match="different lengths"):
        join_rows([int_field(np.arange(2)), float_field(np.zeros(3))])
    with pytest.raises(ValueError, match="at least one field"):
        join_rows([b"x"])


def test_large_blocks_match_repr_for_decimal_coordinates():
    rng = np.random.default_rng(11)
    for low, high, decimals in [(3e5, 4e5, 3), (6.0e6, 6.1e6, 2), (0.0, 2000.0, 3), (-1, 1, 6)]:
        values = np.round(rng.uniform(low, high, 20_000), decimals)
        assert float_tokens(values) == [repr(v) for v in values.tolist()]


def test_large_blocks_of_full_precision_read_back():
    rng = np.random.default_rng(12)
    values = np.concatenate(
        [
            rng.uniform(3e5, 4e5, 10_000),
            rng.uniform(0, 2000, 10_000),
            10 ** rng.uniform(-6, 18, 10_000),
            rng.integers(0, 2**64, 10_000, dtype=np.uint64).view(np.float64),
        ]
    )
    tokens = float_tokens(values)
    back = np.array([float(t) for t in tokens])
    finite = ~np.isnan(values)
    assert np.array_equal(back[finite].view(np.uint64), values[finite].view(np.uint64))
    assert all(t == "nan" for t in np.array(tokens)[~finite])


@examples(30)
@given(
    st.integers(0, 6),
    st.lists(st.tuples(st.integers(0, 2047), st.floats(width=64)), max_size=40),
)
def test_columns_with_a_usual_number_of_decimals_and_outliers(decimals, outliers):
    # Long enough for the sample that guesses the number of decimals; the outliers (any
    # double, so also other decimals, 17 digits, zeros, -0.0, inf, nan) take the exact path.
    rng = np.random.default_rng(decimals)
    values = np.round(rng.uniform(-1e6, 1e6, 2048), decimals)
    for row, value in outliers:
        values[row] = value
    check_tokens(values.tolist())
