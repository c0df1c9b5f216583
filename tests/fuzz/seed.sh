#!/usr/bin/env bash
# Builds the fuzz corpora tests/fuzz/corpus/TARGET from the bundled data (data/, examples/) and
# the small hand-made seeds in tests/fuzz/seeds/TARGET. Safe to run again: files are named by
# what they came from and overwritten. Needs python3 (for packing the Shapefile parts, shrinking
# the GeoPackage and encoding the geometry seeds).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
corpus="$here/corpus"
for t in shapefile geojson gpkg osm_pbf wkb prj route plan repair faces extrude tile; do
    mkdir -p "$corpus/$t"
    if [ -d "$here/seeds/$t" ]; then cp "$here/seeds/$t"/* "$corpus/$t/"; fi
done
cp "$root"/examples/routes/* "$corpus/route/"
for f in "$root"/data/*/*.prj; do cp "$f" "$corpus/prj/$(basename "$(dirname "$f")")_$(basename "$f")"; done
for f in "$root"/data/bubenec/streets.geojson "$root"/data/bubenec/buildings.geojson \
         "$root"/data/bubenec_utm33n/streets.geojson "$root"/data/helsinki/building_parts.geojson; do
    cp "$f" "$corpus/geojson/$(basename "$(dirname "$f")")_$(basename "$f")"
done
cp "$root/data/originals/Helsinki.osm.pbf" "$corpus/osm_pbf/helsinki.osm.pbf"
python3 - "$root" "$corpus" <<'PY'
import os, shutil, sqlite3, struct, sys, tempfile
root, corpus = sys.argv[1], sys.argv[2]

def join_parts(parts):
    # The format of blockwalk_importers::fuzzing::split_parts: a u32 LE length before every
    # part but the last.
    out = b""
    for i, p in enumerate(parts):
        if i + 1 < len(parts):
            out += struct.pack("<I", len(p))
        out += p
    return out

# Shapefiles: .shp, .shx, .dbf, .prj of the small layers.
for layer in ["bubenec/buildings", "bubenec/streets", "bubenec_utm33n/buildings",
              "bubenec_utm33n/streets", "helsinki/building_parts"]:
    parts = []
    for ext in ["shp", "shx", "dbf", "prj"]:
        p = os.path.join(root, "data", layer + "." + ext)
        parts.append(open(p, "rb").read() if os.path.exists(p) else b"")
    name = layer.replace("/", "_")
    open(os.path.join(corpus, "shapefile", name), "wb").write(join_parts(parts))
    # The same layer without its .prj and without its .shx.
    open(os.path.join(corpus, "shapefile", name + "_noprj"), "wb").write(join_parts(parts[:3] + [b""]))
    open(os.path.join(corpus, "shapefile", name + "_noshx"), "wb").write(join_parts([parts[0], b"", parts[2], parts[3]]))

# GeoPackage: the bundled one cut to a few features per table, vacuumed; WKB blobs from it.
src = os.path.join(root, "data", "originals", "bubenec.gpkg")
tmp = tempfile.mkdtemp()
small = os.path.join(tmp, "small.gpkg")
shutil.copy(src, small)
c = sqlite3.connect(small)
tables = [t for (t,) in c.execute("select table_name from gpkg_contents where data_type='features'")]
blobs = []
for t in tables:
    col = c.execute("select column_name from gpkg_geometry_columns where table_name=?", (t,)).fetchone()[0]
    blobs += [b for (b,) in c.execute(f'select "{col}" from "{t}" limit 3')]
    c.execute(f'delete from "{t}" where rowid not in (select rowid from "{t}" limit 6)')
for (t,) in c.execute("select name from sqlite_master where type='table'").fetchall():
    if t.startswith("gpkg_2d_gridded") or t == "dtm" or t.startswith("rtree_"):
        try:
            c.execute(f'delete from "{t}"')
        except sqlite3.DatabaseError:
            pass
c.commit()
c.execute("vacuum")
c.close()
shutil.copy(small, os.path.join(corpus, "gpkg", "bubenec_small.gpkg"))
for i, b in enumerate(blobs):
    open(os.path.join(corpus, "wkb", f"bubenec_{i}"), "wb").write(bytes(b))
    # The plain WKB after the GeoPackage header (8 bytes + envelope).
    flags = b[3]
    env = {0: 0, 1: 32, 2: 48, 3: 48, 4: 64}.get((flags >> 1) & 7, 0)
    open(os.path.join(corpus, "wkb", f"bubenec_{i}_plain"), "wb").write(bytes(b[8 + env:]))
shutil.rmtree(tmp)

# Geometry seeds in the encoding of blockwalk::fuzzing::Decoder (i16 LE eighths of a metre).
def pts(ring):
    return bytes([len(ring)]) + b"".join(struct.pack("<hh", int(x * 8), int(y * 8)) for x, y in ring)

def polygon(ext, holes=()):
    return bytes([len(holes) << 1]) + pts(ext) + b"".join(pts(h) for h in holes)

square = [(0, 0), (20, 0), (20, 10), (0, 10)]
shapes = {
    "square": polygon(square),
    "square_closed_cw": polygon(list(reversed(square)) + [square[-1]]),
    "courtyard": polygon([(0, 0), (30, 0), (30, 30), (0, 30)], [[(10, 10), (20, 10), (20, 20), (10, 20)]]),
    "bowtie": polygon([(0, 0), (10, 10), (10, 0), (0, 10)]),
    "spike": polygon([(0, 0), (10, 0), (10, 5), (15, 5), (10, 5), (10, 10), (0, 10)]),
    "hole_touching": polygon(square, [[(0, 0), (5, 2), (5, 5)]]),
    "l_shape_70": polygon([(i * 0.5, 0) for i in range(66)] + [(33, 10), (10, 10), (10, 20), (0, 20)]),
}
for name, b in shapes.items():
    for t in ["repair", "extrude"]:
        extra = bytes([12, 0]) if t == "extrude" else b""
        open(os.path.join(corpus, t, name), "wb").write(b + extra)

def line(ps):
    return bytes([len(ps) - 1]) + b"".join(struct.pack("<hh", int(x * 8), int(y * 8)) for x, y in ps)

grid = b"".join(line([(0, y), (60, y)]) for y in (0, 20, 40)) + b"".join(line([(x, -5), (x, 45)]) for x in (0, 30, 60))
open(os.path.join(corpus, "faces", "grid"), "wb").write(bytes([1]) + grid)
island = line([(0, 0), (50, 0), (50, 50), (0, 50), (0, 0)]) + line([(20, 20), (30, 20), (30, 30), (20, 30), (20, 20)]) + line([(0, 25), (10, 25)])
open(os.path.join(corpus, "faces", "island_dangle"), "wb").write(bytes([1]) + island)
near = line([(0, 0), (40, 0)]) + line([(20, 0.01), (20, 30)]) + line([(0, 0.02), (40, 0.02)])
for tol in range(4):
    open(os.path.join(corpus, "faces", f"near_miss_{tol}"), "wb").write(bytes([tol]) + near)
PY
for t in "$corpus"/*/; do printf '%-10s %4d files %8d bytes\n' "$(basename "$t")" "$(ls "$t" | wc -l)" "$(cat "$t"/* | wc -c)"; done
