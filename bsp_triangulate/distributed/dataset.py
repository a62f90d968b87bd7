"""``triangulate_dataset``: a whole layer triangulated on a Dask cluster, one task per
spatially coherent partition.

Dask does all the distributing: the partitions come from dask-geopandas (a Hilbert
``spatial_shuffle``, or the file's own row groups or row ranges), each is one task
(:func:`.partition.run_partition`), the scheduler places them on the workers, reruns the
tasks of a worker that dies and reports progress (``distributed.progress``, the dashboard).
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import time
import uuid
from pathlib import Path

import dask
import dask.dataframe as dd
import dask_geopandas
import geopandas
import numpy as np
import pandas as pd
from distributed import Client, LocalCluster, progress

from ..rules import get_rule
from . import dem as dem_window
from .partition import (
    ELEVATIONS,
    INVALID,
    MESH_FORMATS,
    SOURCE_ID,
    TRIANGLE_COLUMNS,
    Settings,
    run_partition,
)

PARTITIONING = ("hilbert", "file")
# rows per partition where the source does not say (GeoPackage, a GeoDataFrame in memory)
PARTITION_ROWS = 50_000
SOURCE_PREFIX = "src_"
_PARQUET_SUFFIXES = (".parquet", ".geoparquet", ".pq")


class _OgrPart:
    """Reads rows ``[offset, offset + count)`` of a vector layer (pyogrio), fid as index."""

    def __init__(self, path: str, layer) -> None:
        self.path = path
        self.layer = layer

    def __call__(self, part: tuple[int, int]) -> geopandas.GeoDataFrame:
        import pyogrio

        offset, count = part
        return pyogrio.read_dataframe(
            self.path,
            layer=self.layer,
            skip_features=offset,
            max_features=count,
            fid_as_index=True,
        )


def _read_ogr(path: str, layer, rows_per_partition: int) -> tuple[dd.DataFrame, list[int]]:
    """A GeoPackage (or any layer GDAL reads) in row ranges; the index is the fid."""
    import pyogrio

    total = int(pyogrio.read_info(path, layer=layer)["features"])
    meta = pyogrio.read_dataframe(path, layer=layer, max_features=1, fid_as_index=True).iloc[:0]
    step = max(int(rows_per_partition), 1)
    parts = [(offset, min(step, total - offset)) for offset in range(0, total, step)] or [(0, 0)]
    frame = dd.from_map(_OgrPart(path, layer), parts, meta=meta, enforce_metadata=False)
    return frame, [count for _offset, count in parts]


def _row_groups(path: Path) -> list[int] | None:
    """Rows of each row group of a GeoParquet file (None for a folder: counted instead)."""
    if path.is_dir():
        return None
    import pyarrow.parquet as pq

    metadata = pq.ParquetFile(path).metadata
    return [metadata.row_group(i).num_rows for i in range(metadata.num_row_groups)]


def _is_parquet(path: Path) -> bool:
    if path.is_dir():
        return any(path.glob("*.parquet"))
    return path.suffix.lower() in _PARQUET_SUFFIXES


def _with_ids(frame, offsets, id_column=None, partition_info=None):
    """The partition with its source ids: a column, the index, or the row number."""
    frame = frame.copy()
    if id_column is not None:
        frame[SOURCE_ID] = frame[id_column].to_numpy()
    elif offsets is None:
        frame[SOURCE_ID] = frame.index.to_numpy()
    else:
        start = offsets[partition_info["number"]]
        frame[SOURCE_ID] = np.arange(start, start + len(frame), dtype=np.int64)
    return frame


def _source_frame(source, id_column, layer, rows_per_partition, client):
    """(partitions with ``SOURCE_ID``, row count): GeoParquet rows are numbered in file order
    (unless ``id_column``), a GeoPackage's features keep their fid, a GeoDataFrame its index."""
    number_rows = False
    known_lengths = None
    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        if _is_parquet(path):
            frame = dask_geopandas.read_parquet(str(path), split_row_groups=True)
            number_rows = id_column is None
            known_lengths = _row_groups(path)
        else:
            frame, known_lengths = _read_ogr(str(path), layer, rows_per_partition)
    elif isinstance(source, geopandas.GeoDataFrame):
        parts = max(math.ceil(len(source) / rows_per_partition), 1)
        frame = dask_geopandas.from_geopandas(source, npartitions=parts, sort=False)
    elif isinstance(source, dd.DataFrame):
        frame = source
    else:
        raise TypeError(f"cannot read {type(source).__name__}: give a path or a GeoDataFrame")
    if id_column is not None and id_column not in frame.columns:
        raise ValueError(f"the source has no column {id_column!r}")
    lengths = known_lengths
    if lengths is None or len(lengths) != frame.npartitions:
        counted = client.compute(frame.map_partitions(len, meta=(None, "int64"))).result()
        lengths = [int(n) for n in counted]
    offsets = np.cumsum([0, *lengths])[:-1].tolist() if number_rows else None
    meta = frame._meta.assign(**{SOURCE_ID: pd.Series(dtype="int64")})
    frame = frame.map_partitions(_with_ids, offsets, id_column, meta=meta, align_dataframes=False)
    return frame, sum(lengths)


def _known_bounds(source, layer) -> list[float] | None:
    """The layer's extent as its file states it (GeoParquet metadata, GeoPackage extent)."""
    if not isinstance(source, (str, os.PathLike)) or Path(source).is_dir():
        return None
    try:
        if _is_parquet(Path(source)):
            import pyarrow.parquet as pq

            geo = json.loads(pq.read_schema(source).metadata[b"geo"])
            bbox = geo["columns"][geo["primary_column"]].get("bbox")
        else:
            import pyogrio

            bbox = pyogrio.read_info(str(source), layer=layer)["total_bounds"]
    except (KeyError, TypeError, ValueError):
        return None
    if bbox is None or len(bbox) != 4 or not np.isfinite(bbox).all():
        return None
    return [float(v) for v in bbox]


def _hilbert_shuffle(frame, source, layer, npartitions, shuffle_method):
    """dask-geopandas' Hilbert ``spatial_shuffle``, with the extent the file states where it
    does (else it is computed, a pass over the data)."""
    bounds = _known_bounds(source, layer)
    if bounds is None:
        return frame.spatial_shuffle(
            by="hilbert",
            npartitions=npartitions or frame.npartitions,
            calculate_partitions=False,
            shuffle_method=shuffle_method,
        )
    distance = frame.hilbert_distance(total_bounds=bounds, level=16)
    return frame.set_index(
        distance,
        sorted=False,
        npartitions=npartitions or frame.npartitions,
        shuffle_method=shuffle_method,
    )


def _attributes(columns, geometry: str) -> tuple[tuple[str, str], ...]:
    """Source columns copied to the triangles, renamed where they clash (prefix src_)."""
    taken = {"feature_id", "geometry", *(name for name, _dtype in TRIANGLE_COLUMNS)}
    renamed = []
    for name in columns:
        if name in (geometry, SOURCE_ID):
            continue
        out = str(name)
        while out.lower() in taken:
            out = SOURCE_PREFIX + out
        taken.add(out.lower())
        renamed.append((name, out))
    return tuple(renamed)


def _dem_settings(dem, band: int, crs) -> tuple[dem_window.DemInfo, str | None]:
    """The DEM's description, and the layer's CRS where the DEM's differs (else None)."""
    info = dem_window.DemInfo.open(str(dem), band)
    if crs is None or not info.crs_wkt:
        return info, None
    from pyproj import CRS

    if CRS.from_user_input(info.crs_wkt).equals(crs):
        return info, None
    return info, crs.to_wkt()


def _plane(elevation: str, crs) -> str:
    """The engine's working plane, as the plugin chooses it: steep faces in their own plane
    ("auto") only for the geometry's own z in a projected CRS in metres; else XY."""
    if elevation != "geometry" or crs is None or not crs.is_projected:
        return "xy"
    units = {axis.unit_name for axis in crs.axis_info}
    return "auto" if units and units <= {"metre", "meter"} else "xy"


def _check(rule, elevation, invalid, mesh_format, partitioning, z_column, dem) -> str:
    get_rule(rule)
    if elevation is None:
        elevation = "dem" if dem is not None else "column" if z_column else "geometry"
    for value, known, what in (
        (elevation, ELEVATIONS, "elevation"),
        (invalid, INVALID, "invalid"),
        (mesh_format, MESH_FORMATS, "mesh_format"),
        (partitioning, PARTITIONING, "partitioning"),
    ):
        if value not in known:
            raise ValueError(f"{what} must be one of {', '.join(known)}, not {value!r}")
    if elevation == "dem" and dem is None:
        raise ValueError("elevation 'dem' needs a dem")
    if elevation == "column" and not z_column:
        raise ValueError("elevation 'column' needs a z_column")
    return elevation


def _clear(out_dir: Path) -> None:
    """Make the output folders; a previous run's partition files there are removed."""
    for folder, pattern in (("triangles", "part.*.parquet"), ("meshes", "part.*")):
        (out_dir / folder).mkdir(parents=True, exist_ok=True)
        for stale in (out_dir / folder).glob(pattern):
            stale.unlink()
    for name in ("index.json", "summary.json"):
        (out_dir / name).unlink(missing_ok=True)


def _local_client(workers: int | None) -> Client:
    """A LocalCluster of worker processes (one thread each: the engine is numpy in Python)."""
    # the dashboard (on a free port) needs bokeh
    dashboard = ":0" if importlib.util.find_spec("bokeh") else None
    cluster = LocalCluster(
        n_workers=workers or os.cpu_count() or 1,
        threads_per_worker=1,
        processes=True,
        dashboard_address=dashboard,
    )
    return Client(cluster)


def triangulate_dataset(
    source,
    out_dir,
    *,
    rule: str = "first",
    elevation: str | None = None,
    dem=None,
    dem_band: int = 1,
    dem_method: str = "bilinear",
    z_column: str | None = None,
    id_column: str | None = None,
    invalid: str = "repair",
    planar_tolerance: float = 0.0,
    mesh_format: str = "ply",
    partitioning: str = "hilbert",
    npartitions: int | None = None,
    partition_rows: int = PARTITION_ROWS,
    layer=None,
    client: Client | None = None,
    workers: int | None = None,
    shuffle_method: str | None = "tasks",
    show_progress: bool = False,
) -> dict:
    """Triangulate every polygon of ``source`` on a Dask cluster; write the results under
    ``out_dir`` and return the summary (also written as ``summary.json``).

    - ``source``: a GeoParquet file or folder (partitions: its row groups), a GeoPackage or
      other GDAL vector file (``layer``; row ranges of ``partition_rows``), or a
      (dask-)geopandas GeoDataFrame. ``partitioning="hilbert"`` (default) reorders the rows
      into ``npartitions`` (default: as many as read) spatially coherent partitions with
      dask-geopandas' Hilbert ``spatial_shuffle``; ``"file"`` keeps them as read.
    - Source id (``feature_id`` in the outputs): ``id_column``, else a GeoPackage's fid, a
      GeoDataFrame's index, a GeoParquet row's number (from 0, in file order).
    - ``elevation``: "geometry" (its z; none: 0), "column" (``z_column``, one z per
      feature), "dem" (``dem``: GDAL raster, band ``dem_band``, read by window for each
      partition, sampled as the plugin does; missing cells filled along the ring) or "none";
      by default "dem" with a DEM, "column" with a z column, else "geometry".
    - ``rule``, ``planar_tolerance``: the engine's; ``invalid``: "repair" (GEOS make_valid),
      "fail" or "as_given", as in the plugin; the working plane as the plugin picks it (XY,
      but steep faces in their own plane for the geometry's own z in metres).
    - ``client``: a ``distributed.Client`` (any cluster); None starts a LocalCluster of
      ``workers`` processes (default: one per core) for this call.

    Outputs: ``triangles/part.NNNNN.parquet`` (GeoParquet, one PolygonZ per triangle with the
    source id and attributes, part, BSP order, parent, depth, side, areas, angles),
    ``meshes/part.NNNNN.ply`` (``mesh_format="ply"``, vertices merged) or ``.glb`` ("glb"),
    face values feature_id and depth, ``index.json`` (partition -> files, extent, counts) and
    ``summary.json``: read = triangulated + failed + empty, the failures' ids and reasons.
    """
    elevation = _check(rule, elevation, invalid, mesh_format, partitioning, z_column, dem)
    started = time.perf_counter()
    out_dir = Path(out_dir).absolute()
    _clear(out_dir)
    own_client = client is None
    if own_client:
        client = _local_client(workers)
    try:
        with client.as_current():
            frame, total = _source_frame(source, id_column, layer, partition_rows, client)
            if elevation == "column" and z_column not in frame.columns:
                raise ValueError(f"the source has no column {z_column!r}")
            crs = frame.crs if hasattr(frame, "crs") else None
            dem_info, dem_from = (None, None)
            if elevation == "dem":
                dem_info, dem_from = _dem_settings(dem, dem_band, crs)
            if partitioning == "hilbert" and total > 0:
                frame = _hilbert_shuffle(frame, source, layer, npartitions, shuffle_method)
            settings = Settings(
                out_dir=str(out_dir),
                rule=rule,
                invalid=invalid,
                planar_tolerance=float(planar_tolerance),
                elevation=elevation,
                z_column=z_column,
                dem=dem_info,
                dem_method=dem_method,
                dem_from_crs=dem_from,
                mesh_format=mesh_format,
                plane=_plane(elevation, crs),
                attributes=_attributes(frame.columns, frame.geometry.name),
            )
            prepared = time.perf_counter()
            task = dask.delayed(run_partition, pure=True)
            run = uuid.uuid4().hex  # this run's task names, apart from any other run's
            tasks = [
                task(part, number, settings, dask_key_name=f"bsp-triangulate-{run}-{number}")
                for number, part in enumerate(frame.to_delayed())
            ]
            futures = client.compute(tasks)
            if show_progress:
                progress(futures)
            entries = client.gather(futures)
    finally:
        if own_client:
            cluster = client.cluster
            client.close()
            cluster.close()
    return _finish(out_dir, entries, total, started, prepared)


def _finish(out_dir: Path, entries: list[dict], total: int, started: float, prepared: float):
    """Write index.json and summary.json; the summary."""
    for folder in ("triangles", "meshes"):
        for leftover in (out_dir / folder).glob(".*.tmp"):  # a lost attempt's
            leftover.unlink(missing_ok=True)
    failures = [failure for entry in entries for failure in entry.pop("failures")]
    counts = {
        key: sum(entry[key] for entry in entries)
        for key in ("read", "triangulated", "failed", "empty", "repaired", "triangles")
    }
    if counts["read"] != total:
        raise RuntimeError(f"{counts['read']} rows triangulated of {total} read")
    index = {"partitions": entries}
    (out_dir / "index.json").write_text(json.dumps(index, indent=1), encoding="utf-8")
    finished = time.perf_counter()
    summary = {
        **counts,
        "partitions": len(entries),
        "failures": [{"feature_id": fid, "reason": reason} for fid, reason in failures],
        "seconds": {"total": finished - started, "prepare": prepared - started},
        "worker_seconds": {
            key: sum(entry["seconds"][key] for entry in entries)
            for key in ("read", "triangulate", "write")
        },
    }
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=1), encoding="utf-8")
    return summary
