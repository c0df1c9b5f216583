//! Deterministic procedural cities, written as Shapefiles, for benchmarks at scales the bundled
//! real data does not reach (seed 003 §6 measures cities of tens of thousands of buildings).
//!
//! The layout: a street grid whose block sizes (60–150 m) and street widths (12–25 m) vary at
//! random; each block is cut into parcels along its four sides (a perimeter block, the common
//! European form), leaving the block's inside as a shared yard; each parcel holds one building
//! set back from the street: a rectangle, an L, a U, or a rectangle with a courtyard. Storeys
//! follow a log-normal law (median 4) and about 1 % of buildings are towers of 15–60 storeys.
//! The same parameters and seed give byte-identical files.
//!
//! Coordinates are UTM zone 33N metres (EPSG:32633) around x ≈ 500 000, y ≈ 5 400 000, so the
//! f64 → local-frame path is exercised as with real data.

use std::path::{Path, PathBuf};

use geo_types::{Coord, LineString, Polygon};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Parameters of a generated city.
#[derive(Clone, Debug, PartialEq)]
pub struct GenerateParams {
    /// Number of buildings (exactly this many are written).
    pub buildings: usize,
    /// Random seed.
    pub seed: u64,
    /// Block side range, metres.
    pub block_m: (f64, f64),
    /// Street width range (between block edges), metres.
    pub street_m: (f64, f64),
    /// Parcel frontage range, metres.
    pub frontage_m: (f64, f64),
    /// Storey height, metres.
    pub storey_m: f64,
    /// Write `parcels.shp` too.
    pub parcels: bool,
    /// South-west corner of the city in EPSG:32633 metres.
    pub origin: (f64, f64),
}

impl Default for GenerateParams {
    fn default() -> Self {
        GenerateParams {
            buildings: 1000,
            seed: 1,
            block_m: (60.0, 150.0),
            street_m: (12.0, 25.0),
            frontage_m: (12.0, 30.0),
            storey_m: 3.2,
            parcels: true,
            origin: (500_000.0, 5_400_000.0),
        }
    }
}

/// A generated building.
#[derive(Clone, Debug, PartialEq)]
pub struct GenBuilding {
    /// Footprint (exterior CCW, holes CW), metres.
    pub footprint: Polygon<f64>,
    /// Height, metres.
    pub height_m: f64,
    /// Storeys.
    pub levels: u32,
}

/// A generated street segment (between two consecutive intersections of the grid).
#[derive(Clone, Debug, PartialEq)]
pub struct GenStreet {
    /// Centre line.
    pub line: LineString<f64>,
    /// Width between block edges, metres.
    pub width_m: f64,
}

/// A generated city in memory.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GeneratedCity {
    /// Buildings.
    pub buildings: Vec<GenBuilding>,
    /// Street segments.
    pub streets: Vec<GenStreet>,
    /// Parcels.
    pub parcels: Vec<Polygon<f64>>,
    /// Number of blocks used.
    pub blocks: usize,
}

/// Why generation failed.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// Bad parameters.
    #[error("invalid parameters: {0}")]
    Params(String),
    /// A file could not be written.
    #[error("{file}: {message}")]
    Write {
        /// The file.
        file: PathBuf,
        /// What went wrong.
        message: String,
    },
}

/// The EPSG:32633 definition written to the `.prj` files (ESRI WKT).
pub const UTM33N_PRJ: &str = "PROJCS[\"WGS_1984_UTM_Zone_33N\",GEOGCS[\"GCS_WGS_1984\",DATUM[\"D_WGS_1984\",SPHEROID[\"WGS_1984\",6378137.0,298.257223563]],PRIMEM[\"Greenwich\",0.0],UNIT[\"Degree\",0.0174532925199433]],PROJECTION[\"Transverse_Mercator\"],PARAMETER[\"False_Easting\",500000.0],PARAMETER[\"False_Northing\",0.0],PARAMETER[\"Central_Meridian\",15.0],PARAMETER[\"Scale_Factor\",0.9996],PARAMETER[\"Latitude_Of_Origin\",0.0],UNIT[\"Meter\",1.0]]";

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<Coord<f64>> {
    vec![
        Coord { x: x0, y: y0 },
        Coord { x: x1, y: y0 },
        Coord { x: x1, y: y1 },
        Coord { x: x0, y: y1 },
        Coord { x: x0, y: y0 },
    ]
}

fn poly(ext: Vec<Coord<f64>>, holes: Vec<Vec<Coord<f64>>>) -> Polygon<f64> {
    Polygon::new(
        LineString::from(ext),
        holes.into_iter().map(LineString::from).collect(),
    )
}

/// A building inside the axis-aligned box `[x0,x1]×[y0,y1]`; `front` is the side facing the
/// street (0 south, 1 east, 2 north, 3 west), where an L or U stays closed.
fn building_shape(rng: &mut ChaCha8Rng, b: [f64; 4], front: u8) -> Polygon<f64> {
    let [x0, y0, x1, y1] = b;
    let (w, h) = (x1 - x0, y1 - y0);
    let r: f64 = rng.random();
    // Work in a frame where the front is south, then rotate the result back into the box.
    let (fw, fd) = if front % 2 == 0 { (w, h) } else { (h, w) };
    let local: (Vec<(f64, f64)>, Option<Vec<(f64, f64)>>) = if r < 0.1 && fw >= 22.0 && fd >= 22.0 {
        // Rectangle with a courtyard.
        let t = rng.random_range(6.0..9.0f64).min(fw / 3.0).min(fd / 3.0);
        (
            vec![(0.0, 0.0), (fw, 0.0), (fw, fd), (0.0, fd)],
            Some(vec![(t, t), (t, fd - t), (fw - t, fd - t), (fw - t, t)]),
        )
    } else if r < 0.3 && fw >= 14.0 && fd >= 14.0 {
        // L: the front wing full width, a wing back along one side.
        let t = rng.random_range(0.4..0.6) * fd;
        let s = rng.random_range(0.35..0.55) * fw;
        if rng.random::<bool>() {
            (
                vec![(0.0, 0.0), (fw, 0.0), (fw, t), (s, t), (s, fd), (0.0, fd)],
                None,
            )
        } else {
            (
                vec![
                    (0.0, 0.0),
                    (fw, 0.0),
                    (fw, fd),
                    (fw - s, fd),
                    (fw - s, t),
                    (0.0, t),
                ],
                None,
            )
        }
    } else if r < 0.4 && fw >= 20.0 && fd >= 14.0 {
        // U: front wing and two side wings.
        let t = rng.random_range(0.35..0.5) * fd;
        let s = rng.random_range(0.2..0.3) * fw;
        (
            vec![
                (0.0, 0.0),
                (fw, 0.0),
                (fw, fd),
                (fw - s, fd),
                (fw - s, t),
                (s, t),
                (s, fd),
                (0.0, fd),
            ],
            None,
        )
    } else {
        (vec![(0.0, 0.0), (fw, 0.0), (fw, fd), (0.0, fd)], None)
    };
    // Rotations that keep counter-clockwise order: front south → front `front`.
    let map = |(u, v): (f64, f64)| -> Coord<f64> {
        match front {
            0 => Coord {
                x: x0 + u,
                y: y0 + v,
            },
            1 => Coord {
                x: x1 - v,
                y: y0 + u,
            },
            2 => Coord {
                x: x1 - u,
                y: y1 - v,
            },
            _ => Coord {
                x: x0 + v,
                y: y1 - u,
            },
        }
    };
    let close = |v: Vec<(f64, f64)>| -> Vec<Coord<f64>> {
        let mut r: Vec<Coord<f64>> = v.into_iter().map(map).collect();
        r.push(r[0]);
        r
    };
    poly(close(local.0), local.1.map(close).into_iter().collect())
}

fn storeys(rng: &mut ChaCha8Rng) -> u32 {
    if rng.random::<f64>() < 0.01 {
        return rng.random_range(15..=60);
    }
    // Log-normal, median 4 storeys, sigma 0.45 (Box–Muller).
    let u1: f64 = rng.random_range(f64::EPSILON..1.0);
    let u2: f64 = rng.random();
    let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
    ((4.0f64.ln() + 0.45 * z).exp().round() as u32).clamp(1, 14)
}

/// Cuts `[a, b]` into pieces of length in `range` (the last piece absorbs the remainder).
fn cuts(rng: &mut ChaCha8Rng, a: f64, b: f64, range: (f64, f64)) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut x = a;
    while b - x > range.1 {
        let w = rng.random_range(range.0..range.1);
        if b - (x + w) < range.0 {
            break;
        }
        out.push((x, x + w));
        x += w;
    }
    if b - x > 1.0 {
        out.push((x, b));
    }
    out
}

/// Generates a city in memory.
///
/// # Errors
/// [`GenerateError::Params`] for empty or inverted ranges.
pub fn generate_city(p: &GenerateParams) -> Result<GeneratedCity, GenerateError> {
    let ok = |r: (f64, f64)| r.0.is_finite() && r.1.is_finite() && 0.0 < r.0 && r.0 < r.1;
    if !ok(p.block_m) || !ok(p.street_m) || !ok(p.frontage_m) || !(p.storey_m > 0.0) {
        return Err(GenerateError::Params(format!("{p:?}")));
    }
    if p.block_m.0 < 40.0 {
        return Err(GenerateError::Params(
            "blocks must be at least 40 m on a side".into(),
        ));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
    // About 14 buildings per block on average: a square grid of k × k blocks, and more rows if
    // needed.
    let k = ((p.buildings as f64 / 14.0).sqrt().ceil() as usize).max(1);
    let mut xs = Vec::with_capacity(k); // (block x0, x1)
    let mut street_x = Vec::with_capacity(k + 1); // (centre, width)
    let mut x = p.origin.0;
    for _ in 0..k {
        let sw = rng.random_range(p.street_m.0..p.street_m.1);
        street_x.push((x + sw / 2.0, sw));
        x += sw;
        let bw = rng.random_range(p.block_m.0..p.block_m.1);
        xs.push((x, x + bw));
        x += bw;
    }
    let sw = rng.random_range(p.street_m.0..p.street_m.1);
    street_x.push((x + sw / 2.0, sw));

    let mut city = GeneratedCity::default();
    let mut street_y: Vec<(f64, f64)> = Vec::new();
    let mut y = p.origin.1;
    while city.buildings.len() < p.buildings {
        let sh = rng.random_range(p.street_m.0..p.street_m.1);
        street_y.push((y + sh / 2.0, sh));
        y += sh;
        let bh = rng.random_range(p.block_m.0..p.block_m.1);
        let (by0, by1) = (y, y + bh);
        y += bh;
        for &(bx0, bx1) in &xs {
            if city.buildings.len() >= p.buildings {
                break;
            }
            city.blocks += 1;
            let depth = rng
                .random_range(18.0..32.0f64)
                .min((bx1 - bx0) / 2.5)
                .min(bh / 2.5);
            // Parcels: south and north strips full width, east and west strips between them.
            let mut parcels: Vec<([f64; 4], u8)> = Vec::new();
            for (a, b) in cuts(&mut rng, bx0, bx1, p.frontage_m) {
                parcels.push(([a, by0, b, by0 + depth], 0));
            }
            for (a, b) in cuts(&mut rng, by0 + depth, by1 - depth, p.frontage_m) {
                parcels.push(([bx1 - depth, a, bx1, b], 1));
            }
            for (a, b) in cuts(&mut rng, bx0, bx1, p.frontage_m).into_iter().rev() {
                parcels.push(([a, by1 - depth, b, by1], 2));
            }
            for (a, b) in cuts(&mut rng, by0 + depth, by1 - depth, p.frontage_m)
                .into_iter()
                .rev()
            {
                parcels.push(([bx0, a, bx0 + depth, b], 3));
            }
            for (pb, front) in parcels {
                if city.buildings.len() >= p.buildings {
                    break;
                }
                let [x0, y0, x1, y1] = pb;
                if p.parcels {
                    city.parcels.push(poly(rect(x0, y0, x1, y1), vec![]));
                }
                // Side gaps 0.5–2 m, street setback 0–4 m, back yard ≥ 2 m.
                let g = rng.random_range(0.5..2.0);
                let setback = rng.random_range(0.0..4.0);
                let back = rng.random_range(2.0..6.0);
                let inner = match front {
                    0 => [x0 + g, y0 + setback, x1 - g, y1 - back],
                    1 => [x0 + back, y0 + g, x1 - setback, y1 - g],
                    2 => [x0 + g, y0 + back, x1 - g, y1 - setback],
                    _ => [x0 + setback, y0 + g, x1 - back, y1 - g],
                };
                if inner[2] - inner[0] < 4.0 || inner[3] - inner[1] < 4.0 {
                    continue;
                }
                let footprint = building_shape(&mut rng, inner, front);
                let levels = storeys(&mut rng);
                let height_m = ((levels as f64 * p.storey_m + rng.random_range(0.0..2.0)) * 100.0)
                    .round()
                    / 100.0;
                city.buildings.push(GenBuilding {
                    footprint,
                    height_m,
                    levels,
                });
            }
        }
    }
    let sh = rng.random_range(p.street_m.0..p.street_m.1);
    street_y.push((y + sh / 2.0, sh));
    // Street segments between consecutive intersections (a noded grid). Vertical streets span
    // the rows generated; horizontal ones the columns.
    let line = |a: (f64, f64), b: (f64, f64)| {
        LineString::from(vec![Coord { x: a.0, y: a.1 }, Coord { x: b.0, y: b.1 }])
    };
    for &(sx, w) in &street_x {
        for r in 0..street_y.len() - 1 {
            city.streets.push(GenStreet {
                line: line((sx, street_y[r].0), (sx, street_y[r + 1].0)),
                width_m: w,
            });
        }
    }
    for &(sy, w) in &street_y {
        for c in 0..street_x.len() - 1 {
            city.streets.push(GenStreet {
                line: line((street_x[c].0, sy), (street_x[c + 1].0, sy)),
                width_m: w,
            });
        }
    }
    Ok(city)
}

/// What [`write_city`] wrote.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct WrittenCity {
    /// Files written.
    pub files: Vec<PathBuf>,
    /// Buildings.
    pub buildings: usize,
    /// Street segments.
    pub streets: usize,
    /// Parcels.
    pub parcels: usize,
    /// Blocks.
    pub blocks: usize,
}

fn write_err(file: &Path, e: impl std::fmt::Display) -> GenerateError {
    GenerateError::Write {
        file: file.to_path_buf(),
        message: e.to_string(),
    }
}

fn write_prj(shp: &Path, files: &mut Vec<PathBuf>) -> Result<(), GenerateError> {
    let prj = shp.with_extension("prj");
    std::fs::write(&prj, UTM33N_PRJ).map_err(|e| write_err(&prj, e))?;
    let cpg = shp.with_extension("cpg");
    std::fs::write(&cpg, "UTF-8").map_err(|e| write_err(&cpg, e))?;
    files.extend([
        shp.to_path_buf(),
        shp.with_extension("shx"),
        shp.with_extension("dbf"),
        prj,
        cpg,
    ]);
    Ok(())
}

fn field(name: &str) -> shapefile::dbase::FieldName {
    shapefile::dbase::FieldName::try_from(name).expect("field names here are valid")
}

/// Writes a generated city to `dir` as `buildings.shp` (fields `id`, `height`, `levels`),
/// `streets.shp` (`id`, `width`) and, when it has parcels, `parcels.shp` (`id`), each with a
/// `.prj` (EPSG:32633) and a `.cpg`.
///
/// # Errors
/// [`GenerateError::Write`] naming the file.
pub fn write_city(city: &GeneratedCity, dir: &Path) -> Result<WrittenCity, GenerateError> {
    use shapefile::dbase::{FieldValue, Record, TableWriterBuilder};
    std::fs::create_dir_all(dir).map_err(|e| write_err(dir, e))?;
    let mut files = Vec::new();

    let path = dir.join("buildings.shp");
    let table = TableWriterBuilder::new()
        .add_numeric_field(field("id"), 10, 0)
        .add_numeric_field(field("height"), 8, 2)
        .add_numeric_field(field("levels"), 4, 0);
    let mut w = shapefile::Writer::from_path(&path, table).map_err(|e| write_err(&path, e))?;
    for (i, b) in city.buildings.iter().enumerate() {
        let shape = shapefile::Polygon::from(b.footprint.clone());
        let mut r = Record::default();
        r.insert("id".into(), FieldValue::Numeric(Some(i as f64)));
        r.insert("height".into(), FieldValue::Numeric(Some(b.height_m)));
        r.insert("levels".into(), FieldValue::Numeric(Some(b.levels as f64)));
        w.write_shape_and_record(&shape, &r)
            .map_err(|e| write_err(&path, e))?;
    }
    drop(w);
    write_prj(&path, &mut files)?;

    let path = dir.join("streets.shp");
    let table = TableWriterBuilder::new()
        .add_numeric_field(field("id"), 10, 0)
        .add_numeric_field(field("width"), 6, 2);
    let mut w = shapefile::Writer::from_path(&path, table).map_err(|e| write_err(&path, e))?;
    for (i, s) in city.streets.iter().enumerate() {
        let pts: Vec<shapefile::Point> = s
            .line
            .0
            .iter()
            .map(|c| shapefile::Point::new(c.x, c.y))
            .collect();
        let shape = shapefile::Polyline::new(pts);
        let mut r = Record::default();
        r.insert("id".into(), FieldValue::Numeric(Some(i as f64)));
        r.insert(
            "width".into(),
            FieldValue::Numeric(Some((s.width_m * 100.0).round() / 100.0)),
        );
        w.write_shape_and_record(&shape, &r)
            .map_err(|e| write_err(&path, e))?;
    }
    drop(w);
    write_prj(&path, &mut files)?;

    if !city.parcels.is_empty() {
        let path = dir.join("parcels.shp");
        let table = TableWriterBuilder::new().add_numeric_field(field("id"), 10, 0);
        let mut w = shapefile::Writer::from_path(&path, table).map_err(|e| write_err(&path, e))?;
        for (i, p) in city.parcels.iter().enumerate() {
            let shape = shapefile::Polygon::from(p.clone());
            let mut r = Record::default();
            r.insert("id".into(), FieldValue::Numeric(Some(i as f64)));
            w.write_shape_and_record(&shape, &r)
                .map_err(|e| write_err(&path, e))?;
        }
        drop(w);
        write_prj(&path, &mut files)?;
    }
    Ok(WrittenCity {
        files,
        buildings: city.buildings.len(),
        streets: city.streets.len(),
        parcels: city.parcels.len(),
        blocks: city.blocks,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::predicates::polygon_area;
    use crate::geom::repair::check_polygon;

    #[test]
    fn deterministic_exact_count_and_valid() {
        let p = GenerateParams {
            buildings: 700,
            seed: 7,
            ..Default::default()
        };
        let a = generate_city(&p).unwrap();
        let b = generate_city(&p).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.buildings.len(), 700);
        let c = generate_city(&GenerateParams {
            seed: 8,
            ..p.clone()
        })
        .unwrap();
        assert_ne!(a.buildings[0], c.buildings[0]);
        let mut shapes = [0usize; 3];
        for bl in &a.buildings {
            check_polygon(&bl.footprint).unwrap();
            assert!(polygon_area(&bl.footprint) > 10.0);
            assert!(bl.height_m > 0.0 && bl.levels >= 1);
            match (
                bl.footprint.interiors().len(),
                bl.footprint.exterior().0.len(),
            ) {
                (1, _) => shapes[0] += 1,
                (0, 5) => shapes[1] += 1,
                _ => shapes[2] += 1,
            }
        }
        // Every shape kind occurs.
        assert!(shapes.iter().all(|&n| n > 0), "{shapes:?}");
        // Buildings do not overlap their neighbours: total area of the union equals the sum
        // (checked on bounding boxes here: footprints lie in disjoint parcel boxes).
        let boxes: Vec<[f64; 4]> = a
            .buildings
            .iter()
            .map(|b| {
                let e = &b.footprint.exterior().0;
                let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
                for c in e {
                    lo = (lo.0.min(c.x), lo.1.min(c.y));
                    hi = (hi.0.max(c.x), hi.1.max(c.y));
                }
                [lo.0, lo.1, hi.0, hi.1]
            })
            .collect();
        for i in 0..boxes.len().min(200) {
            for j in i + 1..boxes.len() {
                let (p, q) = (boxes[i], boxes[j]);
                let overlap = p[0] < q[2] && q[0] < p[2] && p[1] < q[3] && q[1] < p[3];
                assert!(!overlap, "buildings {i} and {j} overlap");
            }
        }
        let x0 = a.buildings[0].footprint.exterior().0[0].x;
        assert!((4.9e5..5.2e5).contains(&x0));
    }
}
