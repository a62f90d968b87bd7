"""Raster sampling against GDAL's own resampling on the Swellendam SRTM DEM, and ring filling."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bsp_triangulate.terrain.raster_sampling import fill_along_ring, sample_grid, world_to_pixel

SRTM = (
    Path(__file__).resolve().parents[3].parent / "shared" / "data" / "swellendam" / "srtm_41_19.tif"
)
GT = (1000.0, 10.0, 0.0, 2000.0, 0.0, -10.0)  # 10 m cells, top-left corner at (1000, 2000)


@pytest.fixture(scope="module")
def srtm():
    from osgeo import gdal

    dataset = gdal.Open(str(SRTM))
    return dataset, dataset.ReadAsArray(), dataset.GetGeoTransform()


def test_bilinear_matches_gdal_warp_on_srtm_shifted_by_a_fraction_of_a_cell(srtm):
    from osgeo import gdal

    dataset, array, gt = srtm
    cols, rows = 120, 90
    left, top = gt[0] + 0.3 * gt[1] + 200 * gt[1], gt[3] + 0.7 * gt[5] + 300 * gt[5]
    warped = gdal.Warp(
        "",
        dataset,
        format="MEM",
        outputBounds=(left, top + rows * gt[5], left + cols * gt[1], top),
        xRes=gt[1],
        yRes=-gt[5],
        resampleAlg="bilinear",
        outputType=gdal.GDT_Float64,
    )
    expected = warped.ReadAsArray()
    wgt = warped.GetGeoTransform()
    c, r = np.meshgrid(np.arange(cols) + 0.5, np.arange(rows) + 0.5)
    got = sample_grid(array, gt, wgt[0] + c * wgt[1], wgt[3] + r * wgt[5])
    np.testing.assert_allclose(got, expected, atol=1e-6)


def test_nearest_on_srtm_is_the_containing_cell(srtm):
    _, array, gt = srtm
    rng = np.random.default_rng(7)
    col = rng.uniform(0, array.shape[1], 5000)
    row = rng.uniform(0, array.shape[0], 5000)
    xs, ys = gt[0] + col * gt[1], gt[3] + row * gt[5]
    got = sample_grid(array, gt, xs, ys, method="nearest")
    np.testing.assert_array_equal(got, array[row.astype(int), col.astype(int)])


def test_cell_centres_return_cell_values_and_outside_is_nan():
    grid = np.arange(12, dtype=np.int16).reshape(3, 4)
    c, r = np.meshgrid(np.arange(4) + 0.5, np.arange(3) + 0.5)
    xs, ys = GT[0] + c * GT[1], GT[3] + r * GT[5]
    for method in ("bilinear", "nearest"):
        np.testing.assert_array_equal(sample_grid(grid, GT, xs, ys, method=method), grid)
        outside = sample_grid(grid, GT, [999.0, 1041.0, 1010.0], [1990.0, 1990.0, 2000.1], method)
        assert np.isnan(outside).all()


def test_bilinear_border_and_nodata_use_the_valid_neighbours_weighted_mean():
    grid = np.array([[1.0, 2.0], [3.0, -9999.0]])
    # Between all four centres: the nodata cell is left out, equal weights on the other three.
    got = sample_grid(grid, GT, [1010.0], [1990.0], nodata=-9999.0)
    assert got[0] == pytest.approx(2.0)
    # In the half-cell border left of the first centre only the first column counts.
    got = sample_grid(grid, GT, [1001.0], [1995.0])
    assert got[0] == pytest.approx(1.0)
    # On the nodata cell's centre no neighbour has weight: no value.
    assert np.isnan(sample_grid(grid, GT, [1015.0], [1985.0], nodata=-9999.0)[0])
    # NaN cells of a float grid count as nodata too.
    nan_grid = np.array([[np.nan, 4.0], [4.0, 4.0]])
    assert sample_grid(nan_grid, GT, [1010.0], [1990.0])[0] == pytest.approx(4.0)


def test_rotated_geotransform_inverts_exactly():
    gt = (500.0, 8.0, 6.0, 700.0, 6.0, -8.0)
    col, row = np.array([0.25, 3.5, 10.0]), np.array([0.75, 2.0, 7.5])
    xs = gt[0] + col * gt[1] + row * gt[2]
    ys = gt[3] + col * gt[4] + row * gt[5]
    got_col, got_row = world_to_pixel(gt, xs, ys)
    np.testing.assert_allclose(got_col, col, atol=1e-12)
    np.testing.assert_allclose(got_row, row, atol=1e-12)


def test_unknown_method_raises():
    with pytest.raises(ValueError, match="method"):
        sample_grid(np.zeros((2, 2)), GT, [1005.0], [1995.0], method="cubic")


def test_fill_along_ring_interpolates_gaps_cyclically_by_index():
    values = np.array([np.nan, 10.0, np.nan, np.nan, 40.0, np.nan])
    filled = fill_along_ring(values)
    # Gap 2..3 between 10 (index 1) and 40 (index 4); gap 5..0 wraps from 40 back to 10.
    np.testing.assert_allclose(filled, [20.0, 10.0, 20.0, 30.0, 40.0, 30.0])


def test_fill_along_ring_by_arc_length_weights_by_distance():
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])
    values = np.array([0.0, np.nan, 8.0, 8.0, 8.0])
    filled = fill_along_ring(values, xy)
    assert filled[1] == pytest.approx(2.0)


def test_fill_along_ring_single_value_and_all_missing():
    np.testing.assert_array_equal(fill_along_ring([np.nan, 5.0, np.nan]), [5.0, 5.0, 5.0])
    with pytest.raises(ValueError, match="no valid value"):
        fill_along_ring([np.nan, np.nan])
