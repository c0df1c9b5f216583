"""Benchmark (not a test): blockwalk.blocks against momepy.enclosures, shapely.polygonize and the
`blockwalk blocks` command on Helsinki's block-class streets repeated N × N by translation.

    python python/bench/bench_blocks.py [--n 10] [--repeat 3] [--cli PATH]

Prints one JSON object: the layer sizes, the best of `repeat` wall times of each method in this
process (blockwalk's conversions to and from WKB included), and the CLI's own stage times
(`ms`: block detection; `total_ms`: reading, city building and detection) for the same layers
written to GeoPackages. Like is compared with like: the faces of the street layer alone
(`blockwalk.blocks(streets=...)`, `momepy.enclosures`, `shapely.polygonize`), then the faces with
every building assigned (`blockwalk.blocks(buildings, streets)`; momepy's enclosures with a
spatial join of the buildings' representative points). The load average before and after is
printed too: other work on the machine slows every figure.
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time
import warnings

import geopandas as gpd
import pandas as pd
import shapely

import blockwalk

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "python" / "tests"))
from conftest import cli_binary  # noqa: E402


def grid(gdf, n, dx, dy):
    parts = [gdf.translate(i * dx, j * dy) for i in range(n) for j in range(n)]
    g = pd.concat(parts, ignore_index=True)
    cols = pd.concat([gdf.drop(columns="geometry")] * (n * n), ignore_index=True)
    return gpd.GeoDataFrame(cols, geometry=g.values, crs=gdf.crs)


def best(f, repeat):
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cli", default=None)
    a = ap.parse_args()
    b0 = gpd.read_file(ROOT / "data/helsinki/buildings.shp")
    s0 = gpd.read_file(ROOT / "data/helsinki/streets_blockclass.shp")
    minx, miny, maxx, maxy = s0.total_bounds
    dx, dy = maxx - minx, maxy - miny
    b, s = grid(b0, a.n, dx, dy), grid(s0, a.n, dx, dy)
    res = {"n": a.n, "streets": len(s), "buildings": len(b), "load_before": os.getloadavg()[0]}

    # The faces of the street layer alone: what momepy.enclosures and shapely.polygonize compute.
    t, (faces_bw, _) = best(lambda: blockwalk.blocks(streets=s), a.repeat)
    res["blockwalk_streets_s"] = t
    res["blockwalk_streets_faces"] = len(faces_bw)
    sargs = blockwalk._layer(s)
    t, _ = best(
        lambda: blockwalk._blockwalk.blocks(
            None, sargs, None, snap=0.05, street_width=20.0, outskirts_link=30.0
        ),
        a.repeat,
    )
    res["blockwalk_streets_rust_call_s"] = t

    def poly():
        return shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.union_all(s.geometry.values))))

    t, faces = best(poly, a.repeat)
    res["shapely_polygonize_s"] = t
    res["shapely_faces"] = len(faces)
    try:
        import momepy

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t, enc = best(lambda: momepy.enclosures(s), a.repeat)
            res["momepy_enclosures_s"] = t
            res["momepy_faces"] = len(enc)

            # Enclosures and the enclosure of every building (its representative point's).
            def enclosures_and_buildings():
                enc = momepy.enclosures(s)
                pts = gpd.GeoDataFrame(geometry=b.geometry.representative_point(), crs=b.crs)
                return enc, gpd.sjoin(pts, enc, how="left", predicate="within")

            t, _ = best(enclosures_and_buildings, a.repeat)
            res["momepy_enclosures_sjoin_s"] = t
    except ImportError:
        res["momepy_enclosures_s"] = None

    # With the buildings: faces, every building assigned, outskirts groups (as the CLI).
    t, (blocks, assigned) = best(lambda: blockwalk.blocks(b, s), a.repeat)
    res["blockwalk_s"] = t
    res["blockwalk_faces"] = int((blocks["kind"] == "block").sum())
    args = (blockwalk._layer(b), sargs)
    t, _ = best(
        lambda: blockwalk._blockwalk.blocks(
            args[0], args[1], None, snap=0.05, street_width=20.0, outskirts_link=30.0
        ),
        a.repeat,
    )
    res["blockwalk_rust_call_s"] = t

    exe = a.cli or cli_binary()
    if exe:
        with tempfile.TemporaryDirectory() as d:
            bp, sp = os.path.join(d, "buildings.gpkg"), os.path.join(d, "streets.gpkg")
            b.to_file(bp, driver="GPKG")
            s.to_file(sp, driver="GPKG")
            runs = []
            for _ in range(a.repeat):
                p = subprocess.run([exe, "blocks", bp, "--streets", sp, "--json"], capture_output=True, text=True, check=True)
                runs.append(json.loads(p.stdout))
            fastest = min(runs, key=lambda r: r["ms"])
            res["cli"] = exe
            res["cli_stage_ms"] = fastest["ms"]
            res["cli_total_ms"] = min(r["total_ms"] for r in runs)
            res["cli_faces"] = fastest["blocks"]
    stage = res.get("cli_stage_ms")
    res["ratio_streets_to_cli_stage"] = res["blockwalk_streets_s"] * 1e3 / stage if stage else None
    res["ratio_blockwalk_to_cli_stage"] = res["blockwalk_s"] * 1e3 / stage if stage else None
    if res.get("momepy_enclosures_s"):
        res["speedup_streets_vs_momepy"] = res["momepy_enclosures_s"] / res["blockwalk_streets_s"]
        res["speedup_vs_momepy_sjoin"] = res["momepy_enclosures_sjoin_s"] / res["blockwalk_s"]
    res["load_after"] = os.getloadavg()[0]
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
