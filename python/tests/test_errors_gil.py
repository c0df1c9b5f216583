"""Errors as exceptions that name the feature and the problem; the GIL released during work."""

import threading
import time

import numpy as np
import pytest
import shapely
import geopandas as gpd

import blockwalk
from blockwalk import _blockwalk


# shapely warns while building the NaN ring the test feeds in on purpose.
@pytest.mark.filterwarnings("ignore:invalid value encountered in linearrings:RuntimeWarning")
def test_bad_geometry_is_named_by_row(bubenec):
    buildings, streets = bubenec
    b = buildings.copy()
    geoms = list(b.geometry.values)
    geoms[3] = shapely.Polygon([(0, 0), (np.nan, 0), (1, 1)])
    geoms[5] = shapely.Point(0, 0)
    geoms[7] = None
    b = b.set_geometry(gpd.GeoSeries(geoms, index=b.index, crs=b.crs))
    blocks, assigned = blockwalk.blocks(b, streets)
    refused = {r["id"]: r["reason"] for r in assigned.attrs["blockwalk_report"]["buildings_refused"]}
    assert set(refused) == {"buildings:3", "buildings:5", "buildings:7"}
    assert "non-finite coordinate" in refused["buildings:3"]
    assert "Point" in refused["buildings:5"]
    assert "missing geometry" in refused["buildings:7"]
    assert assigned["block_id"].isna().sum() == 3
    assert assigned["block_id"].notna().sum() == len(b) - 3


def test_no_usable_footprint_is_an_error_naming_rows():
    bad = gpd.GeoDataFrame(geometry=[shapely.Point(0, 0), None], crs="EPSG:3857")
    with pytest.raises(blockwalk.InputError) as e:
        blockwalk.blocks(bad)
    msg = str(e.value)
    assert "GeoDataFrame buildings" in msg and "no usable building footprint" in msg
    assert "buildings:0" in msg and "buildings:1" in msg
    assert isinstance(e.value, blockwalk.BlockwalkError)


def test_bad_inputs_and_crs():
    with pytest.raises(TypeError):
        blockwalk.blocks(42)
    g = gpd.GeoDataFrame(geometry=[shapely.box(0, 0, 10, 10)])
    with pytest.raises(blockwalk.InputError, match="CRS"):
        blockwalk.blocks(g, crs="EPSG:999999")
    with pytest.raises(blockwalk.InputError, match="source"):
        blockwalk.blocks(g, source="roads")
    # A layer without CRS is taken as metres in a local frame, and works.
    blocks, assigned = blockwalk.blocks(g)
    assert assigned["block_id"].notna().all()


def grid(buildings, streets, n):
    """`n × n` copies of the layers, translated by the layers' extent."""
    minx, miny, maxx, maxy = streets.total_bounds
    dx, dy = maxx - minx, maxy - miny
    bs, ss = [], []
    for i in range(n):
        for j in range(n):
            bs.append(buildings.translate(i * dx, j * dy))
            ss.append(streets.translate(i * dx, j * dy))
    import pandas as pd

    return (
        gpd.GeoDataFrame(geometry=pd.concat(bs, ignore_index=True), crs=buildings.crs),
        gpd.GeoDataFrame(geometry=pd.concat(ss, ignore_index=True), crs=streets.crs),
    )


def test_the_gil_is_released_while_blocks_run(helsinki):
    b, s = grid(*helsinki, 6)
    args = blockwalk._layer(b), blockwalk._layer(s)
    count = 0
    stop = False

    def counter():
        nonlocal count
        while not stop:
            count += 1

    t = threading.Thread(target=counter)
    t.start()
    try:
        # The counter's speed alone (the main thread asleep, the GIL free).
        c0 = count
        time.sleep(0.2)
        rate = (count - c0) / 0.2
        before = count
        t0 = time.perf_counter()
        # Calls one after the other for at least 0.3 s: long enough to tell a released GIL from
        # switch intervals, however fast one call is.
        while time.perf_counter() - t0 < 0.3:
            r = _blockwalk.blocks(args[0], args[1], None, snap=0.05, street_width=20.0, outskirts_link=30.0)
        dt = time.perf_counter() - t0
        during = count - before
    finally:
        stop = True
        t.join()
    assert sum(k == "block" for k in r["kind"]) >= 70 * 36
    # A call holding the GIL would let the counter run only in the switch intervals around it
    # (5 ms each, a few % of the call); released, it runs through the call, at its own speed
    # less what the library's worker threads take of the cores.
    assert dt >= 0.3, dt
    assert during > 0.1 * rate * dt, (during, rate, dt)
