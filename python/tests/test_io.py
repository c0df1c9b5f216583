"""blockwalk.read, attribute round trips, extrude and tileset."""

import json

import geopandas as gpd
import numpy as np
import pandas as pd
import pytest
import shapely

import blockwalk
from conftest import data


@pytest.mark.parametrize(
    "rel",
    ["helsinki/buildings.shp", "helsinki/buildings.geojson", "bubenec/streets.shp", "bubenec/buildings.geojson"],
)
def test_read_matches_geopandas(rel):
    mine = blockwalk.read(data(rel))
    ref = gpd.read_file(data(rel))
    rep = mine.attrs["blockwalk_report"]
    assert rep["read"] == len(ref)
    assert rep["imported"] + len(rep["refused"]) == rep["read"]
    kept = mine.index.to_numpy()
    assert len(mine) == rep["imported"]
    assert mine.crs is not None and mine.crs.equals(ref.crs) or mine.crs.to_epsg() == ref.crs.to_epsg()
    refg = ref.geometry.values[kept]
    # Same vertices (rings closed, holes kept), whatever the ring orientation.
    for a, b in zip(mine.geometry.values, refg):
        ca, cb = shapely.get_coordinates(a), shapely.get_coordinates(b)
        ca, cb = ca[np.lexsort(ca.T)], cb[np.lexsort(cb.T)]
        assert ca.shape == cb.shape and np.allclose(ca, cb, rtol=0, atol=1e-9)
    for col in ref.columns:
        if col == "geometry":
            continue
        assert col in mine.columns, col
        for x, y in zip(mine[col].to_numpy(), ref[col].to_numpy()[kept]):
            if pd.isna(y) or y is None:
                assert x is None or pd.isna(x), (col, x, y)
            else:
                assert x == y or (isinstance(y, float) and x == pytest.approx(y)), (col, x, y)


def test_read_geopackage_and_osm():
    g = blockwalk.read(data("originals/bubenec.gpkg"), theme="buildings")
    assert len(g) == 144 and g.crs.to_epsg() == 3857
    ref = gpd.read_file(data("originals/bubenec.gpkg"), layer="buildings")
    assert abs(g.area.sum() - ref.area.sum()) < 1e-6 * ref.area.sum()
    s = blockwalk.read(data("originals/Helsinki.osm.pbf"), theme="streets")
    assert len(s) > 0 and s.crs.to_epsg() == 4326
    assert set(s.geom_type) <= {"LineString", "MultiLineString"}
    assert s.attrs["blockwalk_report"]["imported"] == len(s)


def test_read_errors_name_the_file(tmp_path):
    missing = tmp_path / "nope.shp"
    with pytest.raises(blockwalk.ReadError, match="nope.shp"):
        blockwalk.read(missing)
    bad = tmp_path / "bad.geojson"
    bad.write_text('{"type": "FeatureCollection", "features": [')
    with pytest.raises(blockwalk.ReadError, match="bad.geojson.*JSON"):
        blockwalk.read(bad)
    assert issubclass(blockwalk.ReadError, blockwalk.BlockwalkError)


def test_blocks_keep_every_column(helsinki):
    buildings, streets = helsinki
    extra = buildings.copy()
    extra["flag"] = np.arange(len(extra)) % 2 == 0
    extra["nullable"] = pd.array([i if i % 3 else None for i in range(len(extra))], dtype="Int64")
    _, assigned = blockwalk.blocks(extra, streets)
    assert list(assigned.columns) == list(extra.columns) + ["block_id"]
    pd.testing.assert_frame_equal(assigned.drop(columns="block_id"), extra)
    assert str(assigned["block_id"].dtype) == "Int64"


def test_cityjson_keeps_attributes_and_types(tmp_path, helsinki):
    buildings, _ = helsinki
    b = buildings.copy()
    b["n"] = np.arange(len(b), dtype=np.int64)
    b["x"] = np.linspace(0.5, 9.5, len(b))
    b["ok"] = np.arange(len(b)) % 2 == 1
    out = tmp_path / "city.city.json"
    r = blockwalk.extrude(b, path=out, height="height")
    assert r["format"] == "cityjson"
    cj = json.loads(out.read_text())
    objs = cj["CityObjects"]
    seen = 0
    for key, o in objs.items():
        row = int(key.split(":")[1].split(".")[0].split("#")[0])
        a = o["attributes"]
        for col in b.columns:
            if col == "geometry":
                continue
            v = b[col].iloc[row]
            got = a.get(col, a.get(f"source:{col}"))
            if v is None or (isinstance(v, float) and np.isnan(v)):
                assert got is None, (key, col)
            elif isinstance(v, (bool, np.bool_)):
                assert got is bool(v), (key, col)
            elif isinstance(v, (int, np.integer)):
                assert type(got) is int and got == v, (key, col)
            elif isinstance(v, (float, np.floating)):
                assert got == pytest.approx(float(v)), (key, col)
            else:
                assert got == v, (key, col)
        # Heights from the column when it holds a usable value.
        h = b["height"].iloc[row]
        if h is not None and not pd.isna(h) and 0 < float(h) <= 1000:
            assert a["height_m"] == pytest.approx(float(h))
            assert a["height_source"] == "height"
        seen += 1
    assert seen >= len(b) - len(r["report"]["buildings_refused"])


def test_extrude_glb_and_constant_height(tmp_path, bubenec):
    buildings, _ = bubenec
    out = tmp_path / "city.glb"
    r = blockwalk.extrude(buildings, path=out, height=12.5)
    assert out.read_bytes()[:4] == b"glTF"
    assert r["format"] == "glb" and r["extrude_errors"] == []
    cj = tmp_path / "c.city.json"
    blockwalk.extrude(buildings, path=cj, height=12.5)
    hs = {o["attributes"]["height_m"] for o in json.loads(cj.read_text())["CityObjects"].values()}
    assert hs == {12.5}
    with pytest.raises(blockwalk.ExportError, match="no_such_dir"):
        blockwalk.extrude(buildings, path=tmp_path / "no_such_dir" / "x.glb", height=3)


def test_tileset(tmp_path, bubenec):
    buildings, streets = bubenec
    out = tmp_path / "tiles"
    r = blockwalk.tileset(buildings, streets, out=out, k=32, levels=2)
    ts = json.loads((out / "tileset.json").read_text())
    assert ts["asset"]["version"] == "1.1"
    s = r["summary"]
    assert s["buildings"] == 144 and s["tiles"] >= 2
    with pytest.raises(blockwalk.InputError):
        blockwalk.tileset(buildings, streets, out=out, k=48)


def test_tileset_forms(tmp_path, bubenec):
    """Compact by default, plain on request, implicit subtrees, and one `.3tz` file; the same
    tiles in every form."""
    buildings, streets = bubenec
    compact = blockwalk.tileset(buildings, streets, out=tmp_path / "c", k=32)["summary"]
    plain = blockwalk.tileset(buildings, streets, out=tmp_path / "p", k=32, plain=True)["summary"]
    assert compact["content"] == "compact" and plain["content"] == "plain"
    assert compact["tiles"] == plain["tiles"] and compact["buildings"] == plain["buildings"] == 144
    assert compact["bytes"] < plain["bytes"]
    assert 0 < compact["position_error_m"] < 1e-3
    glb = next((tmp_path / "c" / "tiles").glob("leaf_*.glb")).read_bytes()
    assert b"EXT_meshopt_compression" in glb
    glb = next((tmp_path / "p" / "tiles").glob("leaf_*.glb")).read_bytes()
    assert b"EXT_meshopt_compression" not in glb
    imp = blockwalk.tileset(buildings, streets, out=tmp_path / "i", k=32, implicit=True)["summary"]
    assert imp["implicit"] and imp["tiles"] == compact["tiles"]
    assert "implicitTiling" in (tmp_path / "i" / "tileset.json").read_text()
    one = blockwalk.tileset(buildings, streets, out=tmp_path / "city.3tz", k=32)["summary"]
    assert one["archive"] and (tmp_path / "city.3tz").is_file()
    import zipfile

    with zipfile.ZipFile(tmp_path / "city.3tz") as z:
        names = z.namelist()
    assert "tileset.json" in names and names[-1] == "@3dtilesIndex1@"
