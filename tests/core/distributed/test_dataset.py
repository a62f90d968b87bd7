"""triangulate_dataset on a LocalCluster of 2 worker processes: per source id the same
triangles as one triangulate_packed call in this process; a killed worker loses nothing;
empty input and a partition of invalid polygons."""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")
pytest.importorskip("dask_geopandas")
pytest.importorskip("pyarrow")
pytest.importorskip("pyogrio")
geopandas = pytest.importorskip("geopandas")
pd = pytest.importorskip("pandas")
shapely = pytest.importorskip("shapely")

from bsp_triangulate import PackedPolygons, triangulate_packed  # noqa: E402
from bsp_triangulate.distributed import triangulate_dataset  # noqa: E402
from bsp_triangulate.distributed.__main__ import main as cli_main  # noqa: E402
from bsp_triangulate.terrain.raster_sampling import PreparedGrid, fill_along_ring  # noqa: E402

from ...conftest import SHARED_DATA  # noqa: E402

SWELLENDAM = SHARED_DATA / "swellendam"
FARMS = SWELLENDAM / "farms_33S.shp"
DEM = SWELLENDAM / "srtm_41_19.tif"
EPSG = 32733
GENERATED = 20_000
KILLED = 8_000  # the first polygons of the generated set, for the run that loses a worker


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    with distributed.Client(cluster) as connection:
        yield connection
    cluster.close()


def star_polygons(count: int, seed: int = 32) -> np.ndarray:
    """``count`` 3D star polygons (12 vertices; every other one with a 4-vertex island) on a
    grid of 100 m, z rolling with x and y; some MultiPolygons of two stars."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(count)))
    index = np.arange(count)
    centre = np.column_stack(
        [500_000 + (index % side) * 100.0, 6_000_000 + (index // side) * 100.0]
    )

    def stars(vertices: int, outer: float, inner: float) -> np.ndarray:
        angle = rng.uniform(0, np.pi, (count, 1)) + 2 * np.pi * np.arange(vertices) / vertices
        radius = np.where(np.arange(vertices) % 2 == 0, outer, inner)
        radius = radius * rng.uniform(0.85, 1.15, (count, vertices))
        xy = centre[:, None, :] + radius[..., None] * np.stack([np.cos(angle), np.sin(angle)], -1)
        z = 200 + 50 * np.sin(xy[..., 0] / 900.0) + 20 * np.cos(xy[..., 1] / 700.0)
        return np.concatenate([xy, z[..., None]], axis=-1)

    shells = shapely.linearrings(stars(12, 40.0, 22.0))
    islands = shapely.linearrings(stars(4, 8.0, 6.0)[:, ::-1])
    with_island = shapely.polygons(shells, islands[:, None])
    plain = shapely.polygons(shells)
    polygons = np.where(index % 2 == 0, with_island, plain)
    small = shapely.affinity.scale
    multi = index % 97 == 5
    polygons[multi] = [
        shapely.MultiPolygon(
            [small(p, 0.4, 0.4, origin=(x - 20, y, 0)), small(p, 0.4, 0.4, origin=(x + 20, y, 0))]
        )
        for p, (x, y) in zip(polygons[multi], centre[multi])
    ]
    return polygons


def polygon_parts(geometry) -> list:
    if geometry is None or geometry.is_empty:
        return []
    if geometry.geom_type == "Polygon":
        return [geometry]
    if geometry.geom_type not in ("MultiPolygon", "GeometryCollection"):
        return []
    return [p for member in shapely.get_parts(geometry) for p in polygon_parts(member)]


def rings_xyz(polygon) -> list[np.ndarray]:
    rings = [polygon.exterior, *polygon.interiors]
    out = []
    for ring in rings:
        coordinates = shapely.get_coordinates(ring, include_z=True)
        out.append(np.nan_to_num(coordinates, nan=0.0))
    return out


def reference(geometries, ids, rule="first", z_of=None, repair=True, plane="auto") -> dict:
    """Per source id: the triangle corners (M, 3, 3), parent, depth, side of one
    triangulate_packed call in this process over every polygon."""
    if repair:
        valid = shapely.is_valid(geometries)
        geometries = np.where(valid, geometries, shapely.make_valid(geometries))
    owners, polygons = [], []
    for fid, geometry in zip(ids, geometries):
        for part in polygon_parts(geometry):
            rings = rings_xyz(part)
            if z_of is not None:
                rings = [z_of(ring) for ring in rings]
            owners.append(fid)
            polygons.append(rings)
    packed = PackedPolygons.of(polygons)
    result = triangulate_packed(packed, rule=rule, on_error="return", plane=plane)
    assert not result.errors
    out: dict = {}
    for fid, triangulation in zip(owners, result.to_list()):
        corners = triangulation.vertices[triangulation.triangles]
        tree = (triangulation.parent, triangulation.depth, triangulation.side)
        if fid in out:
            previous = out[fid]
            out[fid] = tuple(np.concatenate([a, b]) for a, b in zip(previous, (corners, *tree)))
        else:
            out[fid] = (corners, *tree)
    return out


def read_triangles(out_dir: Path) -> dict:
    """Per feature_id: the written triangles' corners, parent, depth, side (part, order)."""
    frame = geopandas.read_parquet(out_dir / "triangles")
    frame = frame.sort_values(["feature_id", "part", "order"], kind="stable")
    corners = shapely.get_coordinates(frame.geometry.values, include_z=True).reshape(-1, 4, 3)
    corners = corners[:, :3]
    ids = frame["feature_id"].to_numpy()
    cuts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1], True])
    columns = [frame[name].to_numpy() for name in ("parent", "depth", "side")]
    return {
        getattr(ids[a], "item", lambda a=a: ids[a])(): (
            corners[a:b],
            *(column[a:b] for column in columns),
        )
        for a, b in zip(cuts[:-1], cuts[1:])
    }


def assert_same(written: dict, expected: dict) -> None:
    assert written.keys() == expected.keys()
    for fid, (corners, parent, depth, side) in expected.items():
        got = written[fid]
        np.testing.assert_array_equal(got[0], corners, err_msg=f"feature {fid}")
        np.testing.assert_array_equal(got[1], parent)
        np.testing.assert_array_equal(got[2], depth)
        np.testing.assert_array_equal(got[3], side)


@pytest.fixture(scope="module")
def generated(tmp_path_factory) -> tuple[Path, np.ndarray]:
    """GeoParquet of GENERATED star polygons in row groups of 2,500."""
    polygons = star_polygons(GENERATED)
    frame = geopandas.GeoDataFrame(
        {"name": [f"star {i}" for i in range(GENERATED)], "height": np.arange(GENERATED) % 7},
        geometry=polygons,
        crs=EPSG,
    )
    path = tmp_path_factory.mktemp("generated") / "stars.parquet"
    frame.to_parquet(path, row_group_size=2_500)
    return path, polygons


@pytest.fixture(scope="module")
def generated_reference(generated) -> dict:
    _path, polygons = generated
    return reference(polygons, range(GENERATED), rule="first")


def test_generated_polygons_give_the_single_process_triangles(
    client, generated, generated_reference, tmp_path
):
    path, _polygons = generated
    summary = triangulate_dataset(path, tmp_path, rule="first", client=client, npartitions=6)
    assert summary["read"] == GENERATED
    assert summary["triangulated"] == GENERATED
    assert summary["failed"] == summary["empty"] == 0
    assert summary["partitions"] == 6
    written = read_triangles(tmp_path)
    assert_same(written, generated_reference)
    assert summary["triangles"] == sum(len(v[0]) for v in written.values())
    index = json.loads((tmp_path / "index.json").read_text())["partitions"]
    assert [entry["partition"] for entry in index] == list(range(6))
    assert sum(entry["read"] for entry in index) == GENERATED
    for entry in index:
        assert (tmp_path / entry["triangles_file"]).is_file()
        header = (tmp_path / entry["mesh_file"]).read_bytes().split(b"end_header")[0]
        assert f"element face {entry['triangles']}\n".encode() in header
    # Hilbert partitions are spatially coherent: together their extents cover about the
    # layer's once (row-group strips of a shuffled layer would each span all of it)
    area = sum((e[2] - e[0]) * (e[3] - e[1]) for e in (x["extent"] for x in index))
    xmin, ymin, xmax, ymax = shapely.total_bounds(_polygons)
    assert area < 2.0 * (xmax - xmin) * (ymax - ymin)
    # attributes travel with their triangles
    frame = pd.read_parquet(tmp_path / "triangles", columns=["feature_id", "name"])
    assert (frame["name"] == "star " + frame["feature_id"].astype(str)).all()


def farms_z(dem_path: Path):
    """z of ring points from the whole DEM band, as the plugin fills its gaps."""
    from osgeo import gdal

    dataset = gdal.Open(str(dem_path))
    band = dataset.GetRasterBand(1)
    grid = PreparedGrid(band.ReadAsArray(), dataset.GetGeoTransform(), band.GetNoDataValue())

    def z_of(ring: np.ndarray) -> np.ndarray:
        values = grid.sample(ring[:, 0], ring[:, 1])
        out = ring.copy()
        out[:, 2] = fill_along_ring(values, ring[:, :2]) if np.isnan(values).any() else values
        return out

    return z_of


def test_farms_from_a_geopackage_with_a_dem_give_the_single_process_triangles(client, tmp_path):
    pytest.importorskip("osgeo")
    farms = geopandas.read_file(FARMS)
    gpkg = tmp_path / "farms.gpkg"
    farms.to_file(gpkg, driver="GPKG", engine="pyogrio")
    summary = triangulate_dataset(
        gpkg, tmp_path / "out", dem=DEM, client=client, partition_rows=500
    )
    assert summary["read"] == len(farms)
    assert summary["triangulated"] + summary["failed"] + summary["empty"] == len(farms)
    assert summary["failed"] == 0
    assert summary["repaired"] > 0  # the layer has self-intersecting farms
    # GeoPackage fids count from 1, in the shapefile's order
    # draped on the DEM: triangulated in XY, as the plugin does
    ids = range(1, len(farms) + 1)
    expected = reference(farms.geometry.values, ids, z_of=farms_z(DEM), plane="xy")
    assert_same(read_triangles(tmp_path / "out"), expected)
    attributes = pd.read_parquet(tmp_path / "out" / "triangles", columns=["FARM_NO"])
    assert len(attributes) == summary["triangles"]


def test_an_empty_input_gives_an_empty_summary(client, tmp_path):
    empty = geopandas.GeoDataFrame({"name": []}, geometry=[], crs=EPSG)
    path = tmp_path / "empty.parquet"
    empty.to_parquet(path)
    summary = triangulate_dataset(path, tmp_path / "out", client=client)
    assert summary["read"] == summary["triangulated"] == summary["failed"] == 0
    assert summary["empty"] == summary["triangles"] == 0
    assert summary["failures"] == []
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["read"] == 0


def bowtie(x: float) -> shapely.Polygon:
    return shapely.Polygon([(x, 0), (x + 10, 10), (x + 10, 0), (x, 10)])


@pytest.mark.parametrize("invalid", ["fail", "repair"])
def test_a_partition_of_invalid_polygons(client, tmp_path, invalid):
    valid = [shapely.box(x, 0, x + 10, 10) for x in range(0, 200, 20)]
    broken = [bowtie(x) for x in range(0, 200, 20)]
    others = [None, shapely.Polygon(), shapely.Point(1, 1)]
    frame = geopandas.GeoDataFrame(
        {"n": np.arange(23)}, geometry=[*valid, *broken, *others], crs=EPSG
    )
    path = tmp_path / "mixed.parquet"
    frame.to_parquet(path, row_group_size=10)
    summary = triangulate_dataset(
        path, tmp_path / "out", client=client, partitioning="file", invalid=invalid
    )
    index = json.loads((tmp_path / "out" / "index.json").read_text())["partitions"]
    assert [entry["read"] for entry in index] == [10, 10, 3]
    assert summary["read"] == 23
    assert summary["triangulated"] + summary["failed"] + summary["empty"] == 23
    failures = {f["feature_id"]: f["reason"] for f in summary["failures"]}
    assert "Point has no polygon" in failures[22]
    assert index[2]["empty"] == 2
    triangles = geopandas.read_parquet(tmp_path / "out" / "triangles")
    if invalid == "fail":
        assert index[1]["failed"] == 10 and index[1]["triangles"] == 0
        assert all("invalid polygon" in failures[i] for i in range(10, 20))
        assert set(triangles["feature_id"]) == set(range(10))
    else:
        assert index[1]["repaired"] == 10 and index[1]["triangulated"] == 10
        assert set(triangles["feature_id"]) == set(range(20))
        assert len(triangles) == 10 * 2 + 10 * 2
        np.testing.assert_allclose(triangles["area_2d"].sum(), 10 * 100 + 10 * 50)


def test_the_command_line_runs_on_a_given_scheduler(client, tmp_path, capsys):
    frame = geopandas.GeoDataFrame(geometry=list(star_polygons(300)), crs=EPSG)
    path = tmp_path / "stars.parquet"
    frame.to_parquet(path)
    address = client.scheduler.address
    code = cli_main([str(path), str(tmp_path / "out"), "--scheduler", address, "--quiet"])
    assert code == 0
    assert "300 read: 300 triangulated, 0 failed, 0 empty" in capsys.readouterr().out
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["triangulated"] == 300


def test_geodataframes_keep_their_index_or_id_column(client, tmp_path):
    import dask_geopandas

    polygons = star_polygons(300)
    frame = geopandas.GeoDataFrame(
        {"code": [f"c{i}" for i in range(300)]},
        geometry=list(polygons),
        index=np.arange(1000, 1300),
        crs=EPSG,
    )
    expected = reference(polygons, range(1000, 1300))
    summary = triangulate_dataset(frame, tmp_path / "a", client=client, partition_rows=100)
    assert summary["partitions"] == 3 and summary["triangulated"] == 300
    assert_same(read_triangles(tmp_path / "a"), expected)
    lazy = dask_geopandas.from_geopandas(frame, npartitions=2)
    summary = triangulate_dataset(lazy, tmp_path / "b", client=client, id_column="code")
    assert summary["triangulated"] == 300
    written = read_triangles(tmp_path / "b")
    assert_same(written, {f"c{fid - 1000}": value for fid, value in expected.items()})


def test_glb_meshes(client, tmp_path):
    frame = geopandas.GeoDataFrame(geometry=list(star_polygons(200)), crs=EPSG)
    summary = triangulate_dataset(frame, tmp_path, client=client, mesh_format="glb")
    index = json.loads((tmp_path / "index.json").read_text())["partitions"]
    data = (tmp_path / index[0]["mesh_file"]).read_bytes()
    assert index[0]["mesh_file"].endswith(".glb") and data[:4] == b"glTF"
    length = int.from_bytes(data[12:16], "little")
    document = json.loads(data[20 : 20 + length])
    positions = document["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
    assert document["accessors"][positions]["count"] == 3 * summary["triangles"]


def test_a_killed_worker_loses_nothing(client, generated, generated_reference, tmp_path):
    # last in this module: its cluster's nanny starts a new worker for the killed one
    _path, polygons = generated
    path = tmp_path / "killed.parquet"
    geopandas.GeoDataFrame(geometry=polygons[:KILLED], crs=EPSG).to_parquet(
        path, row_group_size=KILLED // 8
    )
    expected = {fid: value for fid, value in generated_reference.items() if fid < KILLED}
    result: dict = {}

    def run() -> None:
        try:
            result["summary"] = triangulate_dataset(
                path,
                tmp_path,
                rule="first",
                client=client,
                partitioning="file",
                mesh_format="none",
            )
        except BaseException as error:  # reported by the assertion below
            result["error"] = error

    thread = threading.Thread(target=run)
    thread.start()
    killed = None
    deadline = time.monotonic() + 120
    while killed is None and thread.is_alive() and time.monotonic() < deadline:
        busy = [
            worker
            for worker, keys in client.processing().items()
            if any("bsp-triangulate-" in str(key) for key in keys)
        ]
        done = list((tmp_path / "triangles").glob("part.*.parquet"))
        if busy and done:
            killed = busy[0]
            pid = client.run(os.getpid, workers=[killed])[killed]
            os.kill(pid, signal.SIGKILL)
        time.sleep(0.05)
    thread.join(300)
    assert killed is not None, "no partition task was seen running"
    assert "error" not in result, result.get("error")
    summary = result["summary"]
    assert summary["read"] == summary["triangulated"] == KILLED
    assert summary["partitions"] == 8  # the file's row groups
    assert_same(read_triangles(tmp_path), expected)
    assert not list((tmp_path / "triangles").glob(".*"))  # no lost attempt's file left
