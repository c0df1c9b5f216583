"""blockwalk for Python: urban blocks, extruded cities and 3D Tiles from GeoPandas data.

The work is done by blockwalk's Rust library (the compiled module ``blockwalk._blockwalk``), with
the GIL released: other Python threads keep running meanwhile.

Inputs
------
Every function that takes features (``buildings``, ``streets``, ``parcels``) accepts

* a ``geopandas.GeoDataFrame`` or ``GeoSeries`` (its CRS is used; attributes are the columns),
* any object with ``__geo_interface__`` (a FeatureCollection, a Feature or a geometry; its CRS is
  taken from a ``crs`` attribute when there is one, else from the ``crs`` argument),
* a ``(wkb, crs)`` pair: a sequence of WKB ``bytes`` (``None`` for a missing geometry) and a CRS.

Geometry travels to Rust as WKB (``shapely.to_wkb``, vectorised); a CRS as ``EPSG:n`` when pyproj
knows the code, else as WKT. Attribute values are kept as None, bool, int, float and str (NaN and
pandas' missing values become null; other objects, such as timestamps, their ``str()``).

Features are numbered by row position: the reports name a feature as ``buildings:ROW``
(``streets:ROW``, ``parcels:ROW``).
"""

from __future__ import annotations

import json
import os
from typing import Any, Optional, Sequence, Tuple, Union

import geopandas as gpd
import numpy as np
import pandas as pd
import shapely

from . import _blockwalk
from ._blockwalk import BlocksError, BlockwalkError, ExportError, InputError, ReadError

__all__ = [
    "read",
    "blocks",
    "extrude",
    "tileset",
    "BlockwalkError",
    "ReadError",
    "InputError",
    "BlocksError",
    "ExportError",
    "DEFAULT_SNAP",
    "DEFAULT_STREET_WIDTH",
    "DEFAULT_OUTSKIRTS_LINK",
]

#: Snap tolerance of the street graph, metres (the CLI's ``--snap`` default).
DEFAULT_SNAP = 0.05
#: Street width threshold for blocks from footprints, metres (``--street-width``).
DEFAULT_STREET_WIDTH = 20.0
#: Outskirts buildings closer than this are one group, metres (``--outskirts-link``).
DEFAULT_OUTSKIRTS_LINK = 30.0

Features = Union[gpd.GeoDataFrame, gpd.GeoSeries, Any, Tuple[Sequence[Optional[bytes]], Any]]


def _crs_text(crs: Any) -> Optional[str]:
    """A CRS as text the library parses: ``EPSG:n`` when known, else WKT; None when absent."""
    if crs is None:
        return None
    if isinstance(crs, str):
        return crs
    try:
        from pyproj import CRS

        c = CRS.from_user_input(crs)
    except Exception:  # noqa: BLE001 - an object pyproj does not know: its text
        return str(crs)
    epsg = c.to_epsg()
    return f"EPSG:{epsg}" if epsg is not None else c.to_wkt()


def _columns(df: pd.DataFrame) -> dict:
    """Attribute columns by name (the Series themselves: the library converts those it reads)."""
    geom = getattr(df, "_geometry_column_name", None)
    return {str(name): df[name] for name in df.columns if name != geom}


def _layer(obj: Features, crs: Any = None) -> Tuple[Any, dict, Optional[str]]:
    """(wkb, columns, crs) of one layer, whatever it was given as."""
    if isinstance(obj, gpd.GeoDataFrame):
        geoms = obj.geometry.values
        wkb = shapely.to_wkb(np.asarray(geoms), output_dimension=2)
        return wkb, _columns(obj), _crs_text(obj.crs if crs is None else crs)
    if isinstance(obj, gpd.GeoSeries):
        wkb = shapely.to_wkb(np.asarray(obj.values), output_dimension=2)
        return wkb, {}, _crs_text(obj.crs if crs is None else crs)
    if isinstance(obj, tuple) and len(obj) == 2:
        wkb, c = obj
        return list(wkb), {}, _crs_text(c if crs is None else crs)
    if hasattr(obj, "__geo_interface__"):
        gi = obj.__geo_interface__
        feats = (
            gi.get("features", [])
            if gi.get("type") == "FeatureCollection"
            else [gi if gi.get("type") == "Feature" else {"geometry": gi, "properties": {}}]
        )
        df = gpd.GeoDataFrame.from_features(feats)
        own = getattr(obj, "crs", None)
        return _layer(df, crs if crs is not None else own)
    raise TypeError(
        f"expected a GeoDataFrame, a GeoSeries, an object with __geo_interface__ or a (wkb, crs) pair, "
        f"got {type(obj).__name__}"
    )


def _report(text: str) -> dict:
    return json.loads(text)


def read(
    path: Union[str, os.PathLike],
    *,
    theme: str = "any",
    table: Optional[str] = None,
    crs: Any = None,
    columns: Optional[Sequence[str]] = None,
) -> gpd.GeoDataFrame:
    """Reads a layer file as blockwalk's importers read it.

    Formats: Shapefile (``.shp`` with ``.shx``/``.dbf``/``.prj``), GeoJSON, GeoPackage
    (``file.gpkg`` or ``file.gpkg:table``), OSM PBF (``.osm.pbf``: buildings, or streets with
    ``theme="streets"``).

    Args:
        path: the file.
        theme: which features of a multi-theme source: ``"any"``, ``"buildings"``, ``"streets"``,
            ``"parcels"`` (OSM PBF, GeoPackage tables named like them).
        table: a GeoPackage table by name (same as ``path:table``).
        crs: a CRS stated for the file, replacing the one it gives (EPSG code, PROJ string,
            WKT or a pyproj CRS).
        columns: keep only these attribute columns.

    Returns:
        A GeoDataFrame in the file's CRS with the attributes as columns (None, bool, int, float
        and str values), indexed by the feature ids (``fid``: record number, row id, OSM id).
        ``gdf.attrs["blockwalk_report"]`` holds the import report: ``read``, ``imported``,
        ``refused`` (``fid`` and ``reason`` of each refused feature), ``refused_by_reason``,
        ``notes``.

    Raises:
        ReadError: the file is missing, unreadable, not in its format, or its CRS is unusable
            (the message names the file and the problem).
        InputError: the stated CRS or the theme cannot be used.
    """
    t = f"table:{table}" if table is not None else theme
    r = _blockwalk.read(os.fspath(path), t, _crs_text(crs), list(columns) if columns is not None else None)
    geometry = shapely.from_wkb(np.asarray(r["wkb"], dtype=object))
    df = pd.DataFrame(r["columns"], index=pd.Index(r["fid"], name="fid"))
    gdf = gpd.GeoDataFrame(df, geometry=geometry, crs=r["crs"])
    gdf.attrs["blockwalk_report"] = _report(r["report"])
    gdf.attrs["blockwalk_source"] = r["source"]
    return gdf


def blocks(
    buildings: Optional[Features] = None,
    streets: Optional[Features] = None,
    *,
    parcels: Optional[Features] = None,
    source: Optional[str] = None,
    snap: float = DEFAULT_SNAP,
    grade_separated_bridges: bool = False,
    street_width: float = DEFAULT_STREET_WIDTH,
    outskirts_link: float = DEFAULT_OUTSKIRTS_LINK,
    exclude_tags: Sequence[str] = (),
    crs: Any = None,
) -> Tuple[gpd.GeoDataFrame, gpd.GeoDataFrame]:
    """Urban blocks of the buildings, and the block of every building.

    The same blocks and assignment as ``blockwalk blocks`` on the same data: the layers become a
    city (``city::build``: CRS to ground metres, footprint repair) and ``blocks::detect`` finds
    the faces of the street graph (else unions of parcels, else blocks inferred from the gaps
    between footprints) and puts every building in exactly one block or outskirts group.

    Without buildings (``blocks(streets=lines)``) the result is the faces of the street layer
    alone, what ``momepy.enclosures(lines)`` and ``shapely.polygonize`` compute: no assignment,
    no outskirts groups.

    Args:
        buildings: footprints (see the module's Inputs), or None for the faces of ``streets``.
        streets: street centre lines, in any CRS (reprojected into the buildings').
        parcels: cadastral parcels.
        source: ``"streets"``, ``"parcels"`` or ``"footprints"`` instead of the first of them
            that is given (``--source``).
        snap: snap tolerance, metres (``--snap``; 0.001 to 5).
        grade_separated_bridges: streets with a ``bridge`` or ``tunnel`` attribute do not bound
            blocks (``--grade-separated-bridges``).
        street_width: blocks from footprints: buildings closer than this are one block, metres.
        outskirts_link: outskirts buildings closer than this are one group, metres.
        exclude_tags: street features to leave out, ``"k=v"`` (``--exclude-tag``).
        crs: the CRS of inputs that do not carry one.

    Returns:
        ``(blocks, buildings)``; ``buildings`` is None when none were given. ``blocks``: a
        GeoDataFrame in the buildings' CRS (the streets' without buildings), one row per
        block then per outskirts group, columns ``block_id``, ``kind`` (``"block"`` or
        ``"outskirts"``), ``source``, ``area`` (in the CRS's units²), ``area_m2`` (ground
        square metres), ``n_buildings`` (buildings after repair: a row with several parts counts
        each), ``rows`` (the row positions of the buildings it holds). ``buildings``: a copy of the input with a ``block_id``
        column (nullable integer): the block of each row; a row whose footprint has several
        parts in different blocks gets the block of its largest part; a row refused as a
        footprint (listed in the report) has none. Both carry the city's report in
        ``attrs["blockwalk_report"]`` and the counts of ``blockwalk blocks --json`` in
        ``attrs["blockwalk_summary"]``.

    Raises:
        InputError: no usable footprint (the reasons and the rows are named), a CRS that cannot
            be set up, a bad option, neither buildings nor streets, or parcels or another source
            than streets without buildings.
        BlocksError: a forced source without its layer, an option out of range.
    """
    b = _layer(buildings, crs) if buildings is not None else None
    s = _layer(streets, crs) if streets is not None else None
    p = _layer(parcels, crs) if parcels is not None else None
    r = _blockwalk.blocks(
        b,
        s,
        p,
        snap=float(snap),
        source=source,
        grade_separated_bridges=bool(grade_separated_bridges),
        street_width=float(street_width),
        outskirts_link=float(outskirts_link),
        exclude_tags=list(exclude_tags),
    )
    report = _report(r["report"])
    summary = _report(r["summary"])
    given, layer = (buildings, b) if buildings is not None else (streets, s)
    out_crs = given.crs if isinstance(given, (gpd.GeoDataFrame, gpd.GeoSeries)) else layer[2]
    if crs is not None and out_crs is None:
        out_crs = layer[2]
    n = len(r["id"])
    building_fid = r["building_fid"]
    rows = (
        [sorted({building_fid[i] for i in bs if building_fid[i] is not None}) for bs in r["buildings"]]
        if b is not None
        else [[] for _ in range(n)]
    )
    blocks_gdf = gpd.GeoDataFrame(
        {
            "block_id": np.asarray(r["id"], dtype=np.int64),
            "kind": r["kind"],
            "source": [r["source"]] * n,
            "area": np.asarray(r["area"], dtype=float),
            "area_m2": np.asarray(r["area_m2"], dtype=float),
            "n_buildings": np.asarray(r["n_buildings"], dtype=np.int64),
            "rows": rows,
        },
        geometry=shapely.from_wkb(np.asarray(r["wkb"], dtype=object)),
        crs=out_crs,
    )
    if b is None:
        blocks_gdf.attrs["blockwalk_report"] = report
        blocks_gdf.attrs["blockwalk_summary"] = summary
        return blocks_gdf, None
    values = np.zeros(len(b[0]), dtype=np.int64)
    missing = np.ones(len(b[0]), dtype=bool)
    if r["feature_fid"]:
        fid = np.asarray(r["feature_fid"], dtype=np.int64)
        values[fid] = np.asarray(r["feature_block"], dtype=np.int64)
        missing[fid] = False
    block_id = pd.arrays.IntegerArray(values, missing)
    if isinstance(buildings, gpd.GeoDataFrame):
        assigned = buildings.copy()
    elif isinstance(buildings, gpd.GeoSeries):
        assigned = gpd.GeoDataFrame(geometry=buildings.copy())
    else:
        assigned = gpd.GeoDataFrame(geometry=shapely.from_wkb(np.asarray(b[0], dtype=object)), crs=out_crs)
    assigned["block_id"] = block_id
    for g in (blocks_gdf, assigned):
        g.attrs["blockwalk_report"] = report
        g.attrs["blockwalk_summary"] = summary
    # The city's buildings (a footprint row gives one per part) and the row each came from, as
    # `blockwalk blocks` numbers them in its GeoJSON's `buildings` lists.
    blocks_gdf.attrs["blockwalk_building_rows"] = list(building_fid)
    blocks_gdf.attrs["blockwalk_block_buildings"] = r["buildings"]
    return blocks_gdf, assigned


def _heights(height: Union[str, float, int, None]) -> dict:
    if height is None:
        return {}
    if isinstance(height, str):
        return {"height_field": height}
    return {"height_m": float(height)}


def extrude(
    buildings: Features,
    *,
    path: Union[str, os.PathLike],
    height: Union[str, float, None] = None,
    storey_m: Optional[float] = None,
    crs: Any = None,
) -> dict:
    """Extrudes the footprints to prisms and writes them.

    Args:
        buildings: footprints (see the module's Inputs).
        path: ``.glb`` (binary glTF 2.0), ``.jsonl`` (CityJSONSeq), anything else CityJSON 2.0
            (e.g. ``city.city.json``). Written to a temporary name and renamed when complete.
        height: a column holding heights in metres, or one height in metres for every building.
            ``None``: blockwalk's default fields (``height``, then storeys from ``levels`` ×
            ``storey_m``, else 9 m).
        storey_m: metres per storey for heights from levels (default 3).
        crs: the CRS of inputs that do not carry one.

    Returns:
        A dict: ``format``, ``stats`` (what was written), ``report`` (the city's report), and
        ``extrude_errors`` (buildings that gave no mesh, glTF only). CityJSON keeps every
        column as the city objects' attributes.

    Raises:
        InputError: no usable footprint, a bad height or CRS. ExportError: the file cannot be
        written (the message names it).
    """
    r = _blockwalk.extrude(_layer(buildings, crs), os.fspath(path), storey_m=storey_m, **_heights(height))
    return {
        "format": r["format"],
        "stats": _report(r["stats"]),
        "report": _report(r["report"]),
        "extrude_errors": list(r["extrude_errors"]),
    }


def tileset(
    buildings: Features,
    streets: Optional[Features] = None,
    *,
    out: Union[str, os.PathLike],
    k: int = 64,
    levels: Optional[int] = None,
    height: Union[str, float, None] = None,
    crs: Any = None,
    implicit: bool = False,
    plain: bool = False,
) -> dict:
    """Writes the city as a 3D Tiles 1.1 tileset in the folder ``out`` (``tileset.json`` and
    ``tiles/``), or as one ``.3tz`` archive when ``out`` ends in ``.3tz``: BlockMap height
    fields as inner tiles, building meshes at the leaves, as ``blockwalk tileset``. Contents
    are compact (``KHR_mesh_quantization`` and ``EXT_meshopt_compression``) unless ``plain``.

    Args:
        buildings: footprints; streets: centre lines (the blocks; without them blocks come from
            the footprints).
        out: the output folder (replaced whole when complete).
        k: height-map side of the inner tiles' BlockMaps: 32, 64 or 128.
        levels: inner tiles for the first ``levels`` levels of the quadtree; ``None``: a map
            where it costs fewer bytes than the meshes.
        height: as in :func:`extrude`.
        crs: the CRS of inputs that do not carry one.
        implicit: write a 3D Tiles 1.1 implicit quadtree (subtree files) instead of an
            explicit ``tileset.json`` tree.
        plain: plain glTF contents (f32, uncompressed) for viewers without
            ``EXT_meshopt_compression``.

    Returns:
        A dict: ``summary`` (tiles, depth, bytes, ``tileset_json``, …) and ``report``.

    Raises:
        InputError, BlocksError, ExportError.
    """
    r = _blockwalk.tileset(
        _layer(buildings, crs),
        _layer(streets, crs) if streets is not None else None,
        os.fspath(out),
        k=int(k),
        levels=None if levels is None else int(levels),
        implicit=bool(implicit),
        plain=bool(plain),
        **_heights(height),
    )
    return {"summary": _report(r["summary"]), "report": _report(r["report"])}
