"""Densification of ring edges."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from bsp_triangulate.terrain.densify import densify_ring, densify_rings

SQUARE = np.array([[0, 0, 0], [10, 0, 10], [10, 10, 10], [0, 10, 0]], dtype=float)


def _edge_lengths(ring: np.ndarray) -> np.ndarray:
    return np.hypot(*(np.roll(ring, -1, axis=0) - ring)[:, :2].T)


def test_square_with_max_3_gets_four_pieces_per_edge_and_linear_z():
    out = densify_ring(SQUARE, 3.0)
    assert len(out) == 16
    np.testing.assert_array_equal(out[::4], SQUARE)
    np.testing.assert_allclose(_edge_lengths(out), 2.5)
    np.testing.assert_allclose(out[1:4, 2], [2.5, 5.0, 7.5])
    np.testing.assert_allclose(out[13:16, 2], [0.0, 0.0, 0.0])


def test_exact_multiple_and_short_edges_add_nothing_extra():
    assert len(densify_ring(SQUARE, 5.0)) == 8
    np.testing.assert_array_equal(densify_ring(SQUARE, 10.0), SQUARE)


@pytest.mark.parametrize("off", [None, 0, 0.0, -1.0])
def test_disabled_returns_an_equal_copy(off):
    out = densify_ring(SQUARE, off)
    np.testing.assert_array_equal(out, SQUARE)
    assert out is not SQUARE


def test_open_polyline_and_closing_point_repeated():
    line = densify_ring(SQUARE[:2], 4.0, closed=False)
    np.testing.assert_allclose(line[:, 0], [0, 10 / 3, 20 / 3, 10])
    closed = np.vstack([SQUARE, SQUARE[:1]])
    out = densify_ring(closed, 3.0)
    assert len(out) == 17
    np.testing.assert_array_equal(out[-1], SQUARE[0])
    assert len(densify_rings([SQUARE, SQUARE[::-1]], 3.0)) == 2


@settings(max_examples=60, deadline=None)
@given(
    arrays(
        np.float64,
        st.tuples(st.integers(3, 12), st.just(3)),
        elements=st.floats(-1e4, 1e4, allow_nan=False),
    ),
    st.floats(0.5, 5e3),
)
def test_originals_kept_in_order_and_no_piece_longer_than_max(ring, max_length):
    out = densify_ring(ring, max_length)
    lengths = _edge_lengths(out)
    assert lengths.max() <= max_length * (1 + 1e-9) or lengths.max() <= 1e-9
    pieces = np.maximum(np.ceil(_edge_lengths(ring) / max_length), 1).astype(int)
    assert len(out) == pieces.sum()
    # The originals sit, unchanged and in order, where each edge's pieces begin.
    np.testing.assert_array_equal(out[np.cumsum(pieces) - pieces], ring)


def test_edges_touching_a_nan_vertex_are_not_split():
    ring = SQUARE.copy()
    ring[2] = np.nan
    out = densify_ring(ring, 3.0)
    assert len(out) == 4 + 2 * 3  # only the edges 3-0 and 0-1 get their 3 extra points each
    np.testing.assert_array_equal(out[4], [10, 0, 10])
