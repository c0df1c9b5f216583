//! The GeoTIFF elevation reader (`read_dem`) against truths it did not compute:
//!
//! - the five real grids of `../shared/data/dem` (beside the repository; `$BLOCKWALK_SHARED`
//!   names another `shared/`), checked against their READMEs and Nepal's `stats.json`, and, for
//!   the three uncompressed ones, sample by sample against a decoder written here from the TIFF
//!   specification (the georeferencing of all five is also recomputed here from the raw tags).
//!   Without the data the tests skip loudly; the `dem` need (which `.ci/run` requires) makes the
//!   absence a failure;
//! - small GeoTIFFs written here byte by byte (strips and tiles, every sample type, both byte
//!   orders) or with the `tiff` crate's encoder (LZW, Deflate, PackBits, the horizontal
//!   predictor), whose values and georeferencing are known by construction;
//! - broken files (no georeferencing, rotated, several bands, truncated at every length, random
//!   bytes, random mutations of a valid file): an error naming the file, never a panic.

use blockwalk_importers::{read_dem, Crs, DemError, DemGrid, PixelIs};
use proptest::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

#[allow(dead_code)]
#[path = "../../tests/support/skip.rs"]
mod skip;

/// The repository's root (where `skip` logs).
fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

// ---------------------------------------------------------------------------------------------
// The real grids.

/// `../shared/data/dem` beside the repository, else `$BLOCKWALK_SHARED/data/dem`.
fn dem_dir() -> Result<PathBuf, String> {
    dem_dir_in(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared"),
        std::env::var_os("BLOCKWALK_SHARED").map(PathBuf::from),
    )
}

/// `beside/data/dem` when it holds the DEMs' README, else `named/data/dem`, else why neither.
fn dem_dir_in(beside: &Path, named: Option<PathBuf>) -> Result<PathBuf, String> {
    let beside = beside.join("data/dem");
    if beside.join("README.md").is_file() {
        return Ok(beside);
    }
    match named {
        Some(s) => {
            let d = s.join("data/dem");
            if d.join("README.md").is_file() {
                Ok(d)
            } else {
                Err(format!(
                    "the shared DEMs are in neither {} nor $BLOCKWALK_SHARED/data/dem ({})",
                    beside.display(),
                    d.display()
                ))
            }
        }
        None => Err(format!(
            "the shared DEMs ({}) are absent and BLOCKWALK_SHARED is not set",
            beside.display()
        )),
    }
}

#[test]
fn the_shared_folder_beside_the_repository_else_the_variable() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    std::fs::create_dir_all(b.join("data/dem")).unwrap();
    std::fs::write(b.join("data/dem/README.md"), "").unwrap();
    assert_eq!(dem_dir_in(&a, Some(b.clone())), Ok(b.join("data/dem")));
    assert!(dem_dir_in(&a, None)
        .unwrap_err()
        .contains("BLOCKWALK_SHARED is not set"));
    assert!(dem_dir_in(&a, Some(a.clone())).is_err());
    assert_eq!(dem_dir_in(&b, Some(a)), Ok(b.join("data/dem")));
}

/// The real file `rel` under the DEM folder, or `None` after a loud skip. The repository's skip
/// helper (`tests/support/skip.rs`, included by path: this crate needs nothing of `blockwalk`)
/// knows the shared elevation grids as the `dem` need, which `.ci/run` requires:
/// `BLOCKWALK_REQUIRE=dem` turns the skip into a failure.
fn real(test: &str, rel: &str) -> Option<PathBuf> {
    skip::or_skip(skip::Need::Dem, test, dem_dir()).map(|d| d.join(rel))
}

/// A minimal TIFF reader written from the specification, independent of the `tiff` crate: the
/// first directory's tags, and the samples of an uncompressed single-band file.
struct RawTiff {
    data: Vec<u8>,
    le: bool,
    /// tag → (type, count, offset of the value in `data`).
    tags: BTreeMap<u16, (u16, usize, usize)>,
}

impl RawTiff {
    fn open(path: &Path) -> RawTiff {
        let data = std::fs::read(path).unwrap();
        let le = &data[..2] == b"II";
        let mut raw = RawTiff {
            data,
            le,
            tags: BTreeMap::new(),
        };
        assert_eq!(raw.u16_at(2), 42, "classic TIFF");
        let ifd = raw.u32_at(4) as usize;
        for i in 0..raw.u16_at(ifd) as usize {
            let e = ifd + 2 + 12 * i;
            let (tag, ty, count) = (raw.u16_at(e), raw.u16_at(e + 2), raw.u32_at(e + 4) as usize);
            let size = match ty {
                1 | 2 | 6 | 7 => 1,
                3 | 8 => 2,
                4 | 9 | 11 => 4,
                _ => 8,
            };
            let at = if size * count <= 4 {
                e + 8
            } else {
                raw.u32_at(e + 8) as usize
            };
            raw.tags.insert(tag, (ty, count, at));
        }
        raw
    }

    fn bytes<const N: usize>(&self, at: usize) -> [u8; N] {
        let mut b: [u8; N] = self.data[at..at + N].try_into().unwrap();
        if !self.le {
            b.reverse();
        }
        b
    }
    fn u16_at(&self, at: usize) -> u16 {
        u16::from_le_bytes(self.bytes(at))
    }
    fn u32_at(&self, at: usize) -> u32 {
        u32::from_le_bytes(self.bytes(at))
    }

    /// An integer tag's values (SHORT or LONG).
    fn ints(&self, tag: u16) -> Option<Vec<usize>> {
        let &(ty, n, at) = self.tags.get(&tag)?;
        Some(
            (0..n)
                .map(|i| match ty {
                    3 => self.u16_at(at + 2 * i) as usize,
                    4 => self.u32_at(at + 4 * i) as usize,
                    _ => panic!("tag {tag} has type {ty}"),
                })
                .collect(),
        )
    }

    fn doubles(&self, tag: u16) -> Option<Vec<f64>> {
        let &(ty, n, at) = self.tags.get(&tag)?;
        assert_eq!(ty, 12, "tag {tag} is DOUBLE");
        Some(
            (0..n)
                .map(|i| f64::from_le_bytes(self.bytes(at + 8 * i)))
                .collect(),
        )
    }

    fn ascii(&self, tag: u16) -> Option<String> {
        let &(_, n, at) = self.tags.get(&tag)?;
        let s = String::from_utf8_lossy(&self.data[at..at + n]).into_owned();
        Some(s.trim_end_matches('\0').to_string())
    }

    /// A GeoKey stored in the directory itself.
    fn geokey(&self, key: usize) -> Option<usize> {
        let dir = self.ints(34735)?;
        dir[4..]
            .chunks(4)
            .find(|e| e[0] == key && e[1] == 0)
            .map(|e| e[3])
    }

    /// Sample (col, row) → position, from the pixel scale, the first tie point and the raster
    /// type, as the GeoTIFF specification defines them.
    fn sample_position(&self, col: f64, row: f64) -> [f64; 2] {
        let s = self.doubles(33550).unwrap();
        let t = self.doubles(33922).unwrap();
        let half = if self.geokey(1025) == Some(2) {
            0.0
        } else {
            0.5
        };
        [
            t[3] + (col + half - t[0]) * s[0],
            t[4] - (row + half - t[1]) * s[1],
        ]
    }

    /// Every sample of an uncompressed single-band int16 or float32 file, strips or tiles.
    fn samples(&self) -> Vec<f64> {
        assert_eq!(self.ints(259).unwrap_or(vec![1]), [1], "uncompressed");
        let (w, h) = (self.ints(256).unwrap()[0], self.ints(257).unwrap()[0]);
        let (bits, format) = (self.ints(258).unwrap()[0], self.ints(339).unwrap()[0]);
        let sample = |at: usize| match (bits, format) {
            (16, 2) => i16::from_le_bytes(self.bytes(at)) as f64,
            (32, 3) => f32::from_le_bytes(self.bytes(at)) as f64,
            other => panic!("sample type {other:?}"),
        };
        let size = bits / 8;
        let mut out = vec![f64::NAN; w * h];
        if let Some(offsets) = self.ints(324) {
            let (tw, th) = (self.ints(322).unwrap()[0], self.ints(323).unwrap()[0]);
            let across = w.div_ceil(tw);
            for (t, &off) in offsets.iter().enumerate() {
                let (x0, y0) = ((t % across) * tw, (t / across) * th);
                for r in 0..th {
                    for c in 0..tw {
                        if x0 + c < w && y0 + r < h {
                            out[(y0 + r) * w + x0 + c] = sample(off + (r * tw + c) * size);
                        }
                    }
                }
            }
        } else {
            let rps = self.ints(278).map_or(h, |v| v[0]);
            for (s, &off) in self.ints(273).unwrap().iter().enumerate() {
                for r in 0..rps.min(h - s * rps) {
                    for c in 0..w {
                        out[(s * rps + r) * w + c] = sample(off + (r * w + c) * size);
                    }
                }
            }
        }
        out
    }
}

/// What a README states about one grid.
struct Stated {
    rel: &'static str,
    width: usize,
    height: usize,
    sample_type: &'static str,
    epsg: u32,
    /// Pixel-edge bounds `[west, south, east, north]` as GDAL reports them, and how finely the
    /// README rounds them.
    edges: [f64; 4],
    edge_tol: f64,
    /// Elevation range, and how finely the README rounds it.
    range: (f64, f64),
    range_tol: f64,
    nodata: Option<f64>,
}

/// Checks `g` against what its README states, and its georeferencing against the raw tags.
fn check_stated(g: &DemGrid, s: &Stated, raw: &RawTiff) {
    let name = s.rel;
    assert_eq!((g.width, g.height), (s.width, s.height), "{name}: size");
    assert_eq!(g.values.len(), s.width * s.height, "{name}");
    assert_eq!(g.sample_type, s.sample_type, "{name}: sample type");
    let epsg = match &g.crs {
        Crs::Projected { epsg, .. } | Crs::Geographic { epsg } => *epsg,
        other => panic!("{name}: CRS {other:?}"),
    };
    assert_eq!(epsg, Some(s.epsg), "{name}: CRS");
    let expected_layout = if raw.tags.contains_key(&322) {
        "tiles"
    } else {
        "strips"
    };
    assert_eq!(g.layout, expected_layout, "{name}: layout");

    // The pixel-edge bounds: the sample bounds widened by half a pixel on each side.
    let [x0, y0, x1, y1] = g.bounds();
    let (hx, hy) = (g.transform[1].abs() / 2.0, g.transform[5].abs() / 2.0);
    let edges = [x0 - hx, y0 - hy, x1 + hx, y1 + hy];
    for (k, (got, want)) in edges.iter().zip(s.edges).enumerate() {
        assert!(
            (got - want).abs() <= s.edge_tol,
            "{name}: edge {k} is {got}, README {want} (± {})",
            s.edge_tol
        );
    }
    // The corner samples against the tags read independently.
    for (c, r) in [(0, 0), (s.width - 1, s.height - 1), (s.width - 1, 0)] {
        let want = raw.sample_position(c as f64, r as f64);
        let got = g.position(c as f64, r as f64);
        let tol = 1e-9 * want[0].abs().max(want[1].abs()).max(1.0);
        assert!(
            (got[0] - want[0]).abs() <= tol && (got[1] - want[1]).abs() <= tol,
            "{name}: sample ({c}, {r}) at {got:?}, the tags say {want:?}"
        );
        let [fc, fr] = g.fractional_index(got[0], got[1]).unwrap();
        assert!((fc - c as f64).abs() < 1e-6 && (fr - r as f64).abs() < 1e-6);
    }
    let (min, max) = g.stats();
    assert!(
        (min - s.range.0).abs() <= s.range_tol && (max - s.range.1).abs() <= s.range_tol,
        "{name}: range {min}..{max}, README {:?} (± {})",
        s.range,
        s.range_tol
    );
    match (g.nodata, s.nodata) {
        (Some(got), Some(want)) => assert!(
            (got - want).abs() <= 1e-4 * want.abs(),
            "{name}: nodata {got}, README {want}"
        ),
        (got, want) => assert_eq!(got, want, "{name}: nodata"),
    }
    assert_eq!(
        g.nodata_count,
        g.values.iter().filter(|v| v.is_nan()).count(),
        "{name}"
    );
}

/// Every sample of an uncompressed file against the independent decoder: equal, or `NaN` where
/// the raw sample is the nodata value (compared in the sample type, as GDAL does).
fn check_samples(g: &DemGrid, raw: &RawTiff) {
    let nodata = raw.ascii(42113).map(|s| s.trim().parse::<f64>().unwrap());
    let float = raw.ints(339).unwrap()[0] == 3;
    let mut nodata_seen = 0;
    for (i, (&got, &want)) in g.values.iter().zip(&raw.samples()).enumerate() {
        let is_nodata = nodata.is_some_and(|nd| {
            if float {
                want as f32 == nd as f32
            } else {
                want == nd
            }
        });
        if is_nodata {
            nodata_seen += 1;
            assert!(got.is_nan(), "sample {i}: {got}, raw {want} is nodata");
        } else {
            assert_eq!(got, want, "sample {i}");
        }
    }
    assert_eq!(g.nodata_count, nodata_seen);
}

#[test]
fn grenoble_copernicus_int16_pixel_is_point() {
    let Some(path) = real(
        "grenoble_copernicus_int16_pixel_is_point",
        "grenoble-copernicus-demcompare/Copernicus_DSM_10_N45_00_E005_00_DEM.tif",
    ) else {
        return;
    };
    let g = read_dem(&path).unwrap();
    let raw = RawTiff::open(&path);
    check_stated(
        &g,
        &Stated {
            rel: "grenoble",
            width: 500,
            height: 500,
            sample_type: "int16",
            epsg: 4326,
            edges: [4.9999, 44.9999, 6.0001, 46.0001],
            edge_tol: 0.5e-4,
            range: (136.0, 2854.0),
            range_tol: 0.0,
            nodata: Some(-32767.0),
        },
        &raw,
    );
    // The file says pixel-is-point: its tie point is sample (0, 0) itself.
    assert_eq!(g.pixel_is, PixelIs::Point);
    let tie = raw.doubles(33922).unwrap();
    assert_eq!(g.position(0.0, 0.0), [tie[3], tie[4]]);
    check_samples(&g, &raw);
}

#[test]
fn turkey_srtm_int16_strips() {
    let Some(path) = real(
        "turkey_srtm_int16_strips",
        "turkey-srtm-demcompare/srtm_ref.tif",
    ) else {
        return;
    };
    let g = read_dem(&path).unwrap();
    let raw = RawTiff::open(&path);
    check_stated(
        &g,
        &Stated {
            rel: "turkey",
            width: 1000,
            height: 1000,
            sample_type: "int16",
            epsg: 4326,
            edges: [40.0, 39.1667, 40.8333, 40.0],
            edge_tol: 0.5e-4,
            range: (1111.0, 3270.0),
            range_tol: 0.0,
            nodata: Some(-32768.0),
        },
        &raw,
    );
    assert_eq!(g.pixel_is, PixelIs::Area);
    // Pixel-is-area: sample (0, 0) is half a pixel (3″ / 2) in from the tie point's corner.
    let d = 1.0 / 2400.0;
    let [x, y] = g.position(0.0, 0.0);
    assert!((x - (40.0 + d)).abs() < 1e-12 && (y - (40.0 - d)).abs() < 1e-12);
    check_samples(&g, &raw);
}

#[test]
fn jacksboro_deflate_int16() {
    let Some(path) = real(
        "jacksboro_deflate_int16",
        "jacksboro-matplotlib/jacksboro_3as_4326.tif",
    ) else {
        return;
    };
    let g = read_dem(&path).unwrap();
    let raw = RawTiff::open(&path);
    // The README gives the cell edges of the source: x −84.41375..−84.07792, y (north first)
    // 36.73292..36.44625.
    check_stated(
        &g,
        &Stated {
            rel: "jacksboro",
            width: 403,
            height: 344,
            sample_type: "int16",
            epsg: 4326,
            edges: [-84.41375, 36.44625, -84.07792, 36.73292],
            edge_tol: 0.5e-5,
            range: (236.0, 1076.0),
            range_tol: 0.0,
            nodata: None,
        },
        &raw,
    );
    assert_eq!(raw.ints(259).unwrap(), [8], "Deflate");
    // No nodata tag and integer samples: nothing can be nodata.
    assert_eq!(g.nodata_count, 0);
    // README: row 0 is the north row.
    assert!(g.transform[5] < 0.0);
}

#[test]
fn minnesota_lidar_float32_tiles() {
    let Some(path) = real(
        "minnesota_lidar_float32_tiles",
        "minnesota-lidar-1m/lidar_dem_1m_26915.tif",
    ) else {
        return;
    };
    let g = read_dem(&path).unwrap();
    let raw = RawTiff::open(&path);
    check_stated(
        &g,
        &Stated {
            rel: "minnesota",
            width: 400,
            height: 400,
            sample_type: "float32",
            epsg: 26915,
            edges: [429_252.31, 5_150_485.42, 429_652.31, 5_150_885.42],
            edge_tol: 0.005,
            range: (379.7, 410.8),
            range_tol: 0.05,
            nodata: Some(-3.4028e38),
        },
        &raw,
    );
    assert_eq!(g.transform[1], 1.0, "1 m");
    // The file also names its geographic datum (NAD83, 4269): the projected key wins.
    assert_eq!(raw.geokey(2048), Some(4269));
    check_samples(&g, &raw);
}

#[test]
fn nepal_float32_deflate_floating_point_predictor() {
    let Some(path) = real(
        "nepal_float32_deflate_floating_point_predictor",
        "nepal-langtang-mapbox-terrain/nepal_30m_32645.tif",
    ) else {
        return;
    };
    let stats: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(path.with_file_name("nepal_30m_32645.stats.json")).unwrap(),
    )
    .unwrap();
    let num = |k: &str| {
        stats[k]
            .as_f64()
            .unwrap_or_else(|| panic!("stats.json: {k}"))
    };
    let bounds: Vec<f64> = stats["bounds"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();

    let t = std::time::Instant::now();
    let g = read_dem(&path).unwrap();
    eprintln!(
        "read {} ({} × {}, {}) in {:.1} ms",
        path.display(),
        g.width,
        g.height,
        g.layout,
        t.elapsed().as_secs_f64() * 1e3
    );
    let raw = RawTiff::open(&path);
    assert_eq!(raw.ints(259).unwrap(), [8], "Deflate");
    assert_eq!(raw.ints(317).unwrap(), [3], "floating-point predictor");
    check_stated(
        &g,
        &Stated {
            rel: "nepal",
            width: num("width") as usize,
            height: num("height") as usize,
            sample_type: "float32",
            epsg: num("epsg") as u32,
            edges: bounds.try_into().unwrap(),
            edge_tol: 1e-6,
            // stats.json rounds to 2 decimals.
            range: (num("min"), num("max")),
            range_tol: 0.005,
            nodata: Some(-9999.0),
        },
        &raw,
    );
    assert_eq!(g.transform[1], num("res_m"));
    assert_eq!(g.nodata_count, num("nodata_cells") as usize);
    let valid: Vec<f64> = g.values.iter().copied().filter(|v| !v.is_nan()).collect();
    let mean = valid.iter().sum::<f64>() / valid.len() as f64;
    assert!(
        (mean - num("mean")).abs() <= 0.005,
        "mean {mean}, stats.json {}",
        num("mean")
    );
    // README: sample (0, 0) is the centre of the north-west 30 m cell.
    assert_eq!(g.position(0.0, 0.0), [328_290.0 + 15.0, 3_123_600.0 - 15.0]);
}

// ---------------------------------------------------------------------------------------------
// GeoTIFFs written here.

/// A tag value for the writer.
#[derive(Clone, Debug)]
enum V {
    Short(Vec<u16>),
    Long(Vec<u32>),
    Double(Vec<f64>),
    Ascii(String),
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum St {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl St {
    const ALL: [St; 8] = [
        St::I8,
        St::U8,
        St::I16,
        St::U16,
        St::I32,
        St::U32,
        St::F32,
        St::F64,
    ];
    /// (BitsPerSample, SampleFormat, name)
    fn tags(self) -> (u16, u16, &'static str) {
        match self {
            St::I8 => (8, 2, "int8"),
            St::U8 => (8, 1, "uint8"),
            St::I16 => (16, 2, "int16"),
            St::U16 => (16, 1, "uint16"),
            St::I32 => (32, 2, "int32"),
            St::U32 => (32, 1, "uint32"),
            St::F32 => (32, 3, "float32"),
            St::F64 => (64, 3, "float64"),
        }
    }
    fn put(self, v: f64, be: bool, out: &mut Vec<u8>) {
        macro_rules! put {
            ($x:expr) => {{
                let x = $x;
                out.extend(if be { x.to_be_bytes() } else { x.to_le_bytes() })
            }};
        }
        match self {
            St::I8 => put!(v as i8),
            St::U8 => put!(v as u8),
            St::I16 => put!(v as i16),
            St::U16 => put!(v as u16),
            St::I32 => put!(v as i32),
            St::U32 => put!(v as u32),
            St::F32 => put!(v as f32),
            St::F64 => put!(v),
        }
    }
}

/// An uncompressed TIFF written byte by byte.
#[derive(Clone, Debug)]
struct Synth {
    width: u32,
    height: u32,
    bands: u16,
    st: St,
    /// Row-major, `bands` per pixel.
    samples: Vec<f64>,
    /// Tiles of this size, else strips of `rows_per_strip`.
    tiles: Option<(u32, u32)>,
    rows_per_strip: u32,
    big_endian: bool,
    /// Tags added to (or, with `None`, removed from) the basic ones.
    tags: BTreeMap<u16, Option<V>>,
}

/// A GeoKey directory of SHORT keys.
fn geokeys(keys: &[(u16, u16)]) -> V {
    let mut d = vec![1, 1, 0, keys.len() as u16];
    for &(k, v) in keys {
        d.extend([k, 0, 1, v]);
    }
    V::Short(d)
}

impl Synth {
    /// `width × height` samples `f(col, row)`, georeferenced pixel-is-area in EPSG:32633 with
    /// 10 m pixels and the north-west corner at (1000, 2000).
    fn new(width: u32, height: u32, st: St, f: impl Fn(u32, u32) -> f64) -> Synth {
        let samples = (0..height)
            .flat_map(|r| (0..width).map(move |c| (c, r)))
            .map(|(c, r)| f(c, r))
            .collect();
        let mut s = Synth {
            width,
            height,
            bands: 1,
            st,
            samples,
            tiles: None,
            rows_per_strip: 2,
            big_endian: false,
            tags: BTreeMap::new(),
        };
        s.tag(33550, V::Double(vec![10.0, 10.0, 0.0]));
        s.tag(33922, V::Double(vec![0.0, 0.0, 0.0, 1000.0, 2000.0, 0.0]));
        s.tag(34735, geokeys(&[(1024, 1), (1025, 1), (3072, 32633)]));
        s
    }

    fn tag(&mut self, tag: u16, v: V) -> &mut Self {
        self.tags.insert(tag, Some(v));
        self
    }

    fn untag(&mut self, tag: u16) -> &mut Self {
        self.tags.insert(tag, None);
        self
    }

    /// The file: header, directory (with its out-of-line values), then the pixel data, as
    /// GDAL lays them out.
    fn bytes(&self) -> Vec<u8> {
        self.bytes_and_data_start().0
    }

    /// [`Synth::bytes`] and where the pixel data starts.
    fn bytes_and_data_start(&self) -> (Vec<u8>, usize) {
        let be = self.big_endian;
        let (w, h, b) = (
            self.width as usize,
            self.height as usize,
            self.bands as usize,
        );
        let sample = |c: usize, r: usize, k: usize| {
            if c < w && r < h {
                self.samples[(r * w + c) * b + k]
            } else {
                0.0 // a tile's padding
            }
        };
        // The chunks, at offsets relative to the start of the data.
        let mut data = Vec::new();
        let (mut offsets, mut counts) = (Vec::new(), Vec::new());
        let mut chunk = |x0: usize, y0: usize, cw: usize, ch: usize| {
            let start = data.len();
            for r in y0..y0 + ch {
                for c in x0..x0 + cw {
                    for k in 0..b {
                        self.st.put(sample(c, r, k), be, &mut data);
                    }
                }
            }
            offsets.push(start as u32);
            counts.push((data.len() - start) as u32);
        };
        let mut tags: BTreeMap<u16, V> = BTreeMap::new();
        let offsets_tag = match self.tiles {
            Some((tw, th)) => {
                let (tw, th) = (tw as usize, th as usize);
                for ty in 0..h.div_ceil(th) {
                    for tx in 0..w.div_ceil(tw) {
                        chunk(tx * tw, ty * th, tw, th);
                    }
                }
                tags.insert(322, V::Long(vec![tw as u32]));
                tags.insert(323, V::Long(vec![th as u32]));
                tags.insert(325, V::Long(counts));
                324
            }
            None => {
                let rps = self.rows_per_strip as usize;
                for s in 0..h.div_ceil(rps) {
                    chunk(0, s * rps, w, rps.min(h - s * rps));
                }
                tags.insert(278, V::Long(vec![rps as u32]));
                tags.insert(279, V::Long(counts));
                273
            }
        };
        let (bits, format, _) = self.st.tags();
        tags.insert(256, V::Long(vec![self.width]));
        tags.insert(257, V::Long(vec![self.height]));
        tags.insert(258, V::Short(vec![bits; b]));
        tags.insert(259, V::Short(vec![1]));
        tags.insert(262, V::Short(vec![1]));
        tags.insert(277, V::Short(vec![self.bands]));
        tags.insert(284, V::Short(vec![1]));
        tags.insert(339, V::Short(vec![format; b]));
        for (k, v) in &self.tags {
            match v {
                Some(v) => tags.insert(*k, v.clone()),
                None => tags.remove(k),
            };
        }
        let header: &[u8] = if be { b"MM\0*" } else { b"II*\0" };
        // The directory's length does not depend on the offsets' values: write it once to
        // learn where the data starts, then for real.
        let mut out = header.to_vec();
        out.extend([0; 4]);
        tags.insert(offsets_tag, V::Long(offsets.clone()));
        write_ifd(&mut out, &tags, be);
        let data_start = out.len();
        let moved = offsets.iter().map(|o| o + data_start as u32).collect();
        tags.insert(offsets_tag, V::Long(moved));
        out.truncate(8);
        write_ifd(&mut out, &tags, be);
        assert_eq!(out.len(), data_start);
        out.extend(data);
        (out, data_start)
    }

    fn write(&self, dir: &Path, name: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, self.bytes()).unwrap();
        p
    }
}

/// Appends the directory of `tags` (and the values that do not fit in an entry) and points the
/// header at it.
fn write_ifd(out: &mut Vec<u8>, tags: &BTreeMap<u16, V>, be: bool) {
    fn put<const N: usize>(out: &mut Vec<u8>, le: [u8; N], be: bool) {
        let mut b = le;
        if be {
            b.reverse();
        }
        out.extend(b);
    }
    if out.len() % 2 == 1 {
        out.push(0);
    }
    let ifd = out.len();
    let mut extra: Vec<u8> = Vec::new();
    let extra_at = ifd + 2 + 12 * tags.len() + 4;
    put(out, (tags.len() as u16).to_le_bytes(), be);
    for (&tag, v) in tags {
        let mut bytes = Vec::new();
        let (ty, count) = match v {
            V::Short(x) => {
                x.iter().for_each(|x| put(&mut bytes, x.to_le_bytes(), be));
                (3u16, x.len())
            }
            V::Long(x) => {
                x.iter().for_each(|x| put(&mut bytes, x.to_le_bytes(), be));
                (4, x.len())
            }
            V::Double(x) => {
                x.iter().for_each(|x| put(&mut bytes, x.to_le_bytes(), be));
                (12, x.len())
            }
            V::Ascii(s) => {
                bytes.extend(s.as_bytes());
                bytes.push(0);
                (2, bytes.len())
            }
        };
        put(out, tag.to_le_bytes(), be);
        put(out, ty.to_le_bytes(), be);
        put(out, (count as u32).to_le_bytes(), be);
        if bytes.len() <= 4 {
            bytes.resize(4, 0);
            out.extend(&bytes);
        } else {
            put(out, ((extra_at + extra.len()) as u32).to_le_bytes(), be);
            extra.extend(&bytes);
            if extra.len() % 2 == 1 {
                extra.push(0);
            }
        }
    }
    put(out, 0u32.to_le_bytes(), be); // no next directory
    out.extend(extra);
    let mut at = Vec::new();
    put(&mut at, (ifd as u32).to_le_bytes(), be);
    out[4..8].copy_from_slice(&at);
}

/// The `Format` problem of a read that must fail, after checking that it names the file.
fn problem(path: &Path) -> String {
    match read_dem(path) {
        Ok(g) => panic!("{} was read ({} × {})", path.display(), g.width, g.height),
        Err(e @ DemError::Format { .. }) => {
            let text = e.to_string();
            assert!(
                text.starts_with(&path.display().to_string()),
                "the error does not name the file: {text}"
            );
            let DemError::Format { problem, .. } = e else {
                unreachable!()
            };
            problem
        }
        Err(e) => panic!("{}: not a format error: {e}", path.display()),
    }
}

#[test]
fn pixel_is_area_puts_samples_half_a_pixel_in_from_the_tie_point() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = Synth::new(5, 4, St::I16, |c, r| (100 * r + c) as f64);
    let area = read_dem(&s.write(dir.path(), "area.tif")).unwrap();
    s.tag(34735, geokeys(&[(1024, 1), (1025, 2), (3072, 32633)]));
    let point = read_dem(&s.write(dir.path(), "point.tif")).unwrap();

    // The tie point (1000, 2000) is pixel (0, 0)'s north-west corner in the area file, sample
    // (0, 0) itself in the point file; pixels are 10 m, rows go south.
    assert_eq!(area.pixel_is, PixelIs::Area);
    assert_eq!(area.transform, [1005.0, 10.0, 0.0, 1995.0, 0.0, -10.0]);
    assert_eq!(area.position(0.0, 0.0), [1005.0, 1995.0]);
    assert_eq!(area.position(4.0, 3.0), [1045.0, 1965.0]);
    assert_eq!(area.bounds(), [1005.0, 1965.0, 1045.0, 1995.0]);
    assert_eq!(point.pixel_is, PixelIs::Point);
    assert_eq!(point.transform, [1000.0, 10.0, 0.0, 2000.0, 0.0, -10.0]);
    assert_eq!(point.position(0.0, 0.0), [1000.0, 2000.0]);
    // Exactly half a pixel apart, east and south.
    let (a, p) = (area.position(2.0, 1.0), point.position(2.0, 1.0));
    assert_eq!([a[0] - p[0], a[1] - p[1]], [5.0, -5.0]);
    // A pixel-is-area grid's outer corner is at index (-0.5, -0.5).
    assert_eq!(area.position(-0.5, -0.5), [1000.0, 2000.0]);
    assert_eq!(area.fractional_index(1000.0, 2000.0), Some([-0.5, -0.5]));

    assert_eq!(area.values, point.values);
    assert_eq!(area.value(3, 2), 203.0);
    assert_eq!(area.stats(), (0.0, 304.0));
    assert_eq!(area.layout, "strips");
    assert_eq!(area.sample_type, "int16");
    assert_eq!(area.nodata, None);
    assert_eq!(area.nodata_count, 0);
    assert!(matches!(
        area.crs,
        Crs::Projected {
            epsg: Some(32633),
            ..
        }
    ));
}

#[test]
fn a_tie_point_off_the_first_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = Synth::new(4, 3, St::F32, |c, r| (c + r) as f64);
    // Raster position (2, 1) is at (500, 800); pixels are 2 × 4.
    s.tag(33550, V::Double(vec![2.0, 4.0, 0.0]));
    s.tag(33922, V::Double(vec![2.0, 1.0, 0.0, 500.0, 800.0, 0.0]));
    let g = read_dem(&s.write(dir.path(), "tie.tif")).unwrap();
    // Sample (0, 0)'s centre is at raster (0.5, 0.5): 1.5 pixels west, 0.5 pixel north.
    assert_eq!(g.position(0.0, 0.0), [500.0 - 3.0, 800.0 + 2.0]);
}

#[test]
fn tiles_with_partial_edge_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let f = |c: u32, r: u32| c as f64 * 100.0 + r as f64 * 0.25 - 50.0;
    let mut s = Synth::new(37, 20, St::F32, f);
    s.tiles = Some((16, 16));
    let g = read_dem(&s.write(dir.path(), "tiles.tif")).unwrap();
    assert_eq!(g.layout, "tiles");
    assert_eq!((g.width, g.height), (37, 20));
    for r in 0..20 {
        for c in 0..37 {
            assert_eq!(g.value(c, r), f(c as u32, r as u32), "({c}, {r})");
        }
    }
    // The same grid in strips of 3 rows, and in one strip, reads the same.
    let mut s = Synth::new(37, 20, St::F32, f);
    s.rows_per_strip = 3;
    assert_eq!(
        read_dem(&s.write(dir.path(), "s3.tif")).unwrap().values,
        g.values
    );
    s.rows_per_strip = 20;
    assert_eq!(
        read_dem(&s.write(dir.path(), "s1.tif")).unwrap().values,
        g.values
    );
}

#[test]
fn every_sample_type_in_both_byte_orders() {
    let dir = tempfile::tempdir().unwrap();
    for st in St::ALL {
        let (_, _, name) = st.tags();
        let (lo, hi): (f64, f64) = match st {
            St::I8 => (-128.0, 127.0),
            St::U8 => (0.0, 255.0),
            St::I16 => (-32768.0, 32767.0),
            St::U16 => (0.0, 65535.0),
            St::I32 => (-2_147_483_648.0, 2_147_483_647.0),
            St::U32 => (0.0, 4_294_967_295.0),
            St::F32 => (-1.5e30, 3.25e30),
            St::F64 => (-1.0e300, 2.5e300),
        };
        // Both ends of the type's range, and small values between.
        let f = move |c: u32, r: u32| match (c, r) {
            (0, 0) => lo,
            (1, 0) => hi,
            _ => (c + 3 * r) as f64,
        };
        for be in [false, true] {
            for tiles in [None, Some((16, 16))] {
                let mut s = Synth::new(5, 3, st, f);
                s.big_endian = be;
                s.tiles = tiles;
                let path = s.write(dir.path(), &format!("{name}-{be}.tif"));
                let g = read_dem(&path).unwrap_or_else(|e| panic!("{name} be={be}: {e}"));
                assert_eq!(g.sample_type, name);
                let want: Vec<f64> = (0..3)
                    .flat_map(|r| (0..5).map(move |c| f(c, r)))
                    .map(|v| if st == St::F32 { v as f32 as f64 } else { v })
                    .collect();
                assert_eq!(g.values, want, "{name} big-endian {be} tiles {tiles:?}");
                assert_eq!(g.transform, [1005.0, 10.0, 0.0, 1995.0, 0.0, -10.0]);
            }
        }
    }
}

#[test]
fn nodata_in_the_sample_type_and_non_finite_values() {
    let dir = tempfile::tempdir().unwrap();
    // int16 with −9999 at three places.
    let mut s = Synth::new(4, 3, St::I16, |c, r| if c == r { -9999.0 } else { 7.0 });
    s.tag(42113, V::Ascii("-9999".into()));
    let g = read_dem(&s.write(dir.path(), "i16.tif")).unwrap();
    assert_eq!(g.nodata, Some(-9999.0));
    assert_eq!(g.nodata_count, 3);
    assert!(g.value(1, 1).is_nan() && g.value(2, 1) == 7.0);
    assert_eq!(g.stats(), (7.0, 7.0));

    // A fractional nodata cannot be an int16 sample: nothing matches (not even 1 or 2).
    s.tag(42113, V::Ascii("1.5".into()));
    let g = read_dem(&s.write(dir.path(), "frac.tif")).unwrap();
    assert_eq!((g.nodata, g.nodata_count), (Some(1.5), 0));

    // float32: GDAL writes −FLT_MAX-ish nodata as 17 decimals; the samples hold its float32
    // rounding. NaN and ±∞ are nodata too.
    let nd = -3.402_823e38_f64;
    let mut s = Synth::new(3, 2, St::F32, move |c, r| match (c, r) {
        (0, 0) => nd,
        (1, 0) => f64::NAN,
        (2, 0) => f64::INFINITY,
        (0, 1) => f64::NEG_INFINITY,
        _ => 12.5,
    });
    s.tag(42113, V::Ascii("-3.4028229999999999e+038".into()));
    let g = read_dem(&s.write(dir.path(), "f32.tif")).unwrap();
    assert_eq!(g.nodata_count, 4);
    assert_eq!(g.values.iter().filter(|v| **v == 12.5).count(), 2);
    // Without the tag, only the non-finite ones are nodata.
    s.untag(42113);
    let g = read_dem(&s.write(dir.path(), "f32-none.tif")).unwrap();
    assert_eq!((g.nodata, g.nodata_count), (None, 3));
    assert_eq!(g.value(0, 0), nd as f32 as f64);

    // A nodata that is not a number is refused.
    s.tag(42113, V::Ascii("none".into()));
    let p = problem(&s.write(dir.path(), "bad.tif"));
    assert!(p.contains("GDAL_NODATA"), "{p}");
}

#[test]
fn crs_from_the_geokeys() {
    let dir = tempfile::tempdir().unwrap();
    let read = |keys: Option<&[(u16, u16)]>, name: &str| {
        let mut s = Synth::new(2, 2, St::U8, |c, _| c as f64);
        match keys {
            Some(k) => s.tag(34735, geokeys(k)),
            None => s.untag(34735),
        };
        let path = s.write(dir.path(), name);
        (read_dem(&path), path)
    };
    let crs = |keys, name| read(keys, name).0.unwrap().crs;

    assert_eq!(
        crs(Some(&[(1024, 2), (2048, 4326)]), "4326.tif"),
        Crs::Geographic { epsg: Some(4326) }
    );
    assert!(matches!(
        crs(Some(&[(3072, 32645)]), "32645.tif"),
        Crs::Projected {
            epsg: Some(32645),
            ..
        }
    ));
    // The projected key is preferred; the geographic one then names the datum only.
    assert!(matches!(
        crs(Some(&[(2048, 4269), (3072, 26915)]), "both.tif"),
        Crs::Projected {
            epsg: Some(26915),
            ..
        }
    ));
    // A projected model whose projection is user-defined: its geographic key is its datum,
    // not the grid's CRS.
    assert_eq!(
        crs(
            Some(&[(1024, 1), (2048, 4326), (3072, 32767)]),
            "user-proj.tif"
        ),
        Crs::Unknown
    );
    assert_eq!(
        crs(Some(&[(1024, 1), (2048, 4326)]), "proj-no-code.tif"),
        Crs::Unknown
    );
    // No keys at all, or no CRS key: read, with no CRS, pixel-is-area.
    let (g, _) = read(None, "nokeys.tif");
    let g = g.unwrap();
    assert_eq!((g.crs, g.pixel_is), (Crs::Unknown, PixelIs::Area));
    assert_eq!(crs(Some(&[(1025, 1)]), "nocode.tif"), Crs::Unknown);

    // A code the registry does not know is an error naming it.
    let (r, path) = read(Some(&[(3072, 9999)]), "9999.tif");
    assert!(r.is_err());
    let p = problem(&path);
    assert!(
        p.contains("9999") && p.contains("ProjectedCSTypeGeoKey"),
        "{p}"
    );
    // So is a raster type that is neither area nor point.
    let (_, path) = read(Some(&[(1025, 3)]), "raster3.tif");
    assert!(problem(&path).contains("GTRasterTypeGeoKey"));
}

#[test]
fn vertical_units_in_feet_become_metres() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = Synth::new(2, 1, St::F64, |c, _| 1000.0 * (c + 1) as f64);
    s.tag(34735, geokeys(&[(1024, 1), (3072, 32633), (4099, 9002)]));
    let g = read_dem(&s.write(dir.path(), "ft.tif")).unwrap();
    assert_eq!(g.values, [304.8, 609.6]);
    s.tag(34735, geokeys(&[(1024, 1), (3072, 32633), (4099, 9003)]));
    let g = read_dem(&s.write(dir.path(), "usft.tif")).unwrap();
    assert!((g.values[0] - 304.800_609_6).abs() < 1e-6);
    s.tag(34735, geokeys(&[(4099, 9036)]));
    assert!(problem(&s.write(dir.path(), "km.tif")).contains("9036"));
}

#[test]
fn model_transformation_north_up_is_read_and_rotated_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = Synth::new(3, 2, St::I16, |c, r| (c + r) as f64);
    s.untag(33550).untag(33922);
    #[rustfmt::skip]
    let m = vec![
        2.0, 0.0, 0.0, 500.0,
        0.0, -3.0, 0.0, 900.0,
        0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 1.0,
    ];
    s.tag(34264, V::Double(m.clone()));
    let g = read_dem(&s.write(dir.path(), "matrix.tif")).unwrap();
    assert_eq!(g.transform, [501.0, 2.0, 0.0, 898.5, 0.0, -3.0]);

    let mut rotated = m.clone();
    rotated[1] = 0.5; // x changes along a column: rotated or sheared
    s.tag(34264, V::Double(rotated));
    let p = problem(&s.write(dir.path(), "rotated.tif"));
    assert!(p.contains("rotated grids are not supported"), "{p}");
    let mut rotated = m;
    rotated[4] = -0.1;
    s.tag(34264, V::Double(rotated));
    assert!(problem(&s.write(dir.path(), "rotated2.tif")).contains("rotated"));
}

#[test]
fn files_that_are_refused_with_a_reason() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = Synth::new(3, 2, St::I16, |c, _| c as f64);
    let refused = |s: &Synth, name: &str, needle: &str| {
        let p = problem(&s.write(d, name));
        assert!(p.contains(needle), "{name}: {p:?} lacks {needle:?}");
    };

    let mut s = base.clone();
    s.untag(33550).untag(33922).untag(34735);
    refused(&s, "plain.tif", "no georeferencing");
    let mut s = base.clone();
    s.untag(33550);
    refused(&s, "tie-only.tif", "ModelPixelScaleTag");
    s.tag(
        33922,
        V::Double(vec![
            0.0, 0.0, 0.0, 1.0, 2.0, 0.0, 5.0, 5.0, 0.0, 3.0, 4.0, 0.0,
        ]),
    );
    refused(&s, "gcps.tif", "ground control points");
    let mut s = base.clone();
    s.tag(33550, V::Double(vec![0.0, 10.0, 0.0]));
    refused(&s, "zero-scale.tif", "zero pixel size");

    let mut s = Synth::new(3, 2, St::U8, |c, _| c as f64);
    s.bands = 3;
    s.samples = (0..18).map(f64::from).collect();
    refused(&s, "rgb.tif", "3 samples per pixel");

    let mut s = base.clone();
    s.tag(258, V::Short(vec![64])).tag(339, V::Short(vec![2]));
    refused(
        &s,
        "int64.tif",
        "unsupported sample type: 64-bit signed integer",
    );
    let mut s = base.clone();
    s.tag(258, V::Short(vec![1])).tag(339, V::Short(vec![1]));
    refused(&s, "bilevel.tif", "unsupported sample type");
    let mut s = base.clone();
    s.tag(339, V::Short(vec![6]));
    refused(&s, "complex.tif", "complex");

    let mut s = base.clone();
    s.tag(259, V::Short(vec![7]));
    refused(&s, "jpeg.tif", "JPEG");

    let mut s = base.clone();
    s.tag(256, V::Long(vec![0]));
    refused(&s, "zero.tif", "zero-size image (0 × 2 pixels)");
    // 60,000² pixels in one strip of 12 bytes: refused before the grid is allocated.
    let mut s = base.clone();
    s.rows_per_strip = 2;
    s.tag(256, V::Long(vec![60_000]))
        .tag(257, V::Long(vec![60_000]))
        .tag(278, V::Long(vec![60_000]));
    refused(&s, "huge.tif", "more than its");
    let mut s = base.clone();
    s.tag(262, V::Short(vec![0]));
    refused(&s, "white.tif", "WhiteIsZero");

    // Not TIFF at all.
    std::fs::write(d.join("png.tif"), b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR").unwrap();
    assert!(problem(&d.join("png.tif")).contains("not a TIFF"));
    std::fs::write(d.join("empty.tif"), b"").unwrap();
    assert!(problem(&d.join("empty.tif")).contains("empty"));
    std::fs::write(d.join("ii.tif"), b"II").unwrap();
    assert!(problem(&d.join("ii.tif")).contains("not a TIFF"));

    // A file that is not there is an I/O error naming it.
    let missing = d.join("missing.tif");
    match read_dem(&missing) {
        Err(e @ DemError::Io { .. }) => {
            assert!(e.to_string().contains("missing.tif"), "{e}")
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn truncated_at_every_length_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    for tiles in [None, Some((16, 16))] {
        let mut s = Synth::new(20, 18, St::I16, |c, r| (c * r) as f64);
        s.tiles = tiles;
        let (bytes, data_start) = s.bytes_and_data_start();
        for len in 0..bytes.len() {
            let path = dir.path().join("cut.tif");
            std::fs::write(&path, &bytes[..len]).unwrap();
            let p = problem(&path);
            // Once the directory is whole, the cut is in the pixels.
            if len >= data_start {
                assert!(p.contains("truncated"), "cut at {len}: {p}");
            }
        }
    }
}

#[test]
fn the_tiff_encoder_s_compressions_and_predictor() {
    use tiff::encoder::compression::DeflateLevel;
    use tiff::encoder::{colortype, Compression, TiffEncoder};
    use tiff::tags::{Predictor, Tag};

    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (33u32, 21u32);
    let ints: Vec<i16> = (0..w * h)
        .map(|i| ((i % w) as i16 - 10) * 37 + (i / w) as i16 * 11)
        .collect();
    let floats: Vec<f32> = (0..w * h).map(|i| (i as f32).sqrt() * 13.5 - 7.0).collect();
    let compressions = [
        ("none", Compression::Uncompressed),
        ("lzw", Compression::Lzw),
        ("deflate", Compression::Deflate(DeflateLevel::Best)),
        ("packbits", Compression::Packbits),
    ];
    for (name, c) in compressions {
        for predictor in [Predictor::None, Predictor::Horizontal] {
            let mut buf = std::io::Cursor::new(Vec::new());
            {
                let mut enc = TiffEncoder::new(&mut buf)
                    .unwrap()
                    .with_compression(c)
                    .with_predictor(predictor);
                let mut img = enc.new_image::<colortype::GrayI16>(w, h).unwrap();
                img.rows_per_strip(4).unwrap();
                let e = img.encoder();
                e.write_tag(Tag::ModelPixelScaleTag, &[30.0f64, 30.0, 0.0][..])
                    .unwrap();
                e.write_tag(
                    Tag::ModelTiepointTag,
                    &[0.0f64, 0.0, 0.0, 328_290.0, 3_123_600.0, 0.0][..],
                )
                .unwrap();
                e.write_tag(
                    Tag::GeoKeyDirectoryTag,
                    &[1u16, 1, 0, 2, 1025, 0, 1, 2, 3072, 0, 1, 32645][..],
                )
                .unwrap();
                e.write_tag(Tag::GdalNodata, "-370").unwrap();
                img.write_data(&ints).unwrap();
            }
            let path = dir.path().join(format!("{name}-{predictor:?}.tif"));
            std::fs::write(&path, buf.into_inner()).unwrap();
            let g = read_dem(&path).unwrap_or_else(|e| panic!("{name} {predictor:?}: {e}"));
            let want: Vec<f64> = ints
                .iter()
                .map(|&v| if v == -370 { f64::NAN } else { v.into() })
                .collect();
            assert_eq!(g.nodata_count, ints.iter().filter(|&&v| v == -370).count());
            assert!(g.nodata_count > 0);
            assert!(
                g.values
                    .iter()
                    .zip(&want)
                    .all(|(a, b)| a == b || (a.is_nan() && b.is_nan())),
                "{name} {predictor:?}"
            );
            assert_eq!(g.pixel_is, PixelIs::Point);
            assert_eq!(g.position(0.0, 0.0), [328_290.0, 3_123_600.0]);
        }

        // float32 (the encoder has no floating-point predictor; the Nepal file has one).
        let mut buf = std::io::Cursor::new(Vec::new());
        {
            let mut enc = TiffEncoder::new(&mut buf).unwrap().with_compression(c);
            let mut img = enc.new_image::<colortype::Gray32Float>(w, h).unwrap();
            let e = img.encoder();
            e.write_tag(
                Tag::ModelTransformationTag,
                &[
                    0.5f64, 0.0, 0.0, 10.0, 0.0, -0.5, 0.0, 20.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                    0.0, 1.0,
                ][..],
            )
            .unwrap();
            img.write_data(&floats).unwrap();
        }
        let path = dir.path().join(format!("{name}-f32.tif"));
        std::fs::write(&path, buf.into_inner()).unwrap();
        let g = read_dem(&path).unwrap_or_else(|e| panic!("{name} f32: {e}"));
        let want: Vec<f64> = floats.iter().map(|&v| v.into()).collect();
        assert_eq!(g.values, want, "{name} f32");
        assert_eq!(g.sample_type, "float32");
        assert_eq!(g.crs, Crs::Unknown);
        assert_eq!(g.position(0.0, 0.0), [10.25, 19.75]);
    }
}

/// A small LCG, so the byte soup is the same on every run.
fn lcg(seed: u64) -> impl FnMut() -> u8 {
    let mut x = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
    move || {
        x = x
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (x >> 33) as u8
    }
}

/// Reads `bytes` as a file; whatever comes back must be consistent: a grid whose counts agree,
/// or an error naming the file.
fn read_bytes(dir: &Path, bytes: &[u8]) {
    let path = dir.join("soup.tif");
    std::fs::write(&path, bytes).unwrap();
    match read_dem(&path) {
        Ok(g) => {
            assert_eq!(g.values.len(), g.width * g.height);
            assert_eq!(
                g.nodata_count,
                g.values.iter().filter(|v| v.is_nan()).count()
            );
        }
        Err(e) => assert!(e.to_string().contains("soup.tif"), "{e}"),
    }
}

#[test]
fn random_bytes_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    for seed in 0..300u64 {
        let mut next = lcg(seed);
        let len = next() as usize * 4;
        let mut bytes: Vec<u8> = (0..len).map(|_| next()).collect();
        // Half of them start like a TIFF, so that the decoder gets past the signature.
        if seed % 2 == 0 && bytes.len() >= 8 {
            bytes[..4].copy_from_slice(if seed % 4 == 0 { b"II*\0" } else { b"MM\0*" });
            bytes[4..8].copy_from_slice(&[8, 0, 0, 0]);
            if seed % 4 != 0 {
                bytes[4..8].reverse();
            }
        }
        read_bytes(dir.path(), &bytes);
    }
}

/// A small valid GeoTIFF of each layout, for the mutations.
fn mutation_bases() -> Vec<Vec<u8>> {
    let mut s = Synth::new(9, 7, St::F32, |c, r| (c * 7 + r) as f64 - 20.0);
    s.tag(42113, V::Ascii("-20".into()));
    let strips = s.bytes();
    s.tiles = Some((16, 16));
    s.big_endian = true;
    let tiles = s.bytes();
    vec![strips, tiles]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Any byte of a valid file changed, or the file cut: a grid or an error, never a panic.
    #[test]
    fn mutations_of_a_valid_file_never_panic(
        base in 0usize..2,
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in prop::option::of(any::<prop::sample::Index>()),
    ) {
        let mut bytes = mutation_bases().swap_remove(base);
        for (at, b) in &edits {
            let i = at.index(bytes.len());
            bytes[i] = *b;
        }
        if let Some(c) = cut {
            bytes.truncate(c.index(bytes.len()));
        }
        let dir = tempfile::tempdir().unwrap();
        read_bytes(dir.path(), &bytes);
    }
}

#[test]
fn the_mutation_bases_are_valid() {
    let dir = tempfile::tempdir().unwrap();
    for (i, b) in mutation_bases().iter().enumerate() {
        let path = dir.path().join(format!("base{i}.tif"));
        std::fs::write(&path, b).unwrap();
        let g = read_dem(&path).unwrap();
        assert_eq!((g.width, g.height, g.nodata_count), (9, 7, 1));
    }
}
