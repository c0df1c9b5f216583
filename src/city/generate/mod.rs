//! Deterministic procedural cities, written as Shapefiles, for benchmarks at scales the bundled
//! real data does not reach (Pina, Serón and Cerezo, §6 measures cities of tens of thousands of buildings).
//!
//! The layout: a street grid whose block sizes (60–150 m) and street widths (12–25 m) vary at
//! random; each block is cut into parcels along its four sides (a perimeter block, the common
//! European form), leaving the block's inside as a shared yard; each parcel holds one building
//! set back from the street: a rectangle, an L, a U, or a rectangle with a courtyard. Storeys
//! follow a log-normal law (median 4) and about 1 % of buildings are towers of 15–60 storeys.
//! The same parameters and seed give byte-identical files (but for the date of writing in the
//! `.dbf` headers).
//!
//! Coordinates are UTM zone 33N metres (EPSG:32633) around x ≈ 500 000, y ≈ 5 400 000 by
//! default, so the f64 → local-frame path is exercised as with real data; another projected CRS
//! in metres ([`GenerateParams::epsg`]) and a centre ([`GenerateParams::centre`]) put the city
//! elsewhere (on an elevation model's ground, say).

//!
//! The generator's tuning numbers (parcel depths, wing layouts, detail probabilities, …) are
//! named and documented in [`tuning`]. The code is split by responsibility:
//! - `layout`: the street grid and each block's parcels;
//! - `footprint`: one building's footprint inside its parcel;
//! - `heights`: storeys and heights;
//! - `write`: the Shapefiles ([`write_city`]).

mod footprint;
mod heights;
mod layout;
pub mod tuning;
mod write;

use std::path::PathBuf;

use geo_types::{LineString, Polygon};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use footprint::{building_shape, poly, rect};
pub use write::{write_city, WrittenCity, UTM33N_PRJ};

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
    /// South-west corner of the city in the CRS's metres.
    pub origin: (f64, f64),
    /// The city's CRS: an EPSG code of a projected CRS in metres (default 32633, UTM 33N).
    pub epsg: u32,
    /// Where the centre of the city's box goes (CRS metres); `None`: the city grows from
    /// `origin`.
    pub centre: Option<(f64, f64)>,
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
            epsg: 32633,
            centre: None,
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
    /// The CRS (EPSG code) its coordinates are in.
    pub epsg: u32,
}

/// Why generation failed.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// The output folder could not be placed or swapped in (see [`crate::output`]).
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    /// A range parameter is not a finite range `lo..hi` with `0 < lo < hi`.
    #[error("invalid parameter {name} = ({lo}, {hi}): need finite 0 < lo < hi (metres)")]
    BadRange {
        /// The parameter (a field of [`GenerateParams`]).
        name: &'static str,
        /// Its lower end.
        lo: f64,
        /// Its upper end.
        hi: f64,
    },
    /// The storey height is not a finite positive number.
    #[error("invalid parameter storey_m = {value}: need a finite height > 0 (metres)")]
    BadStoreyHeight {
        /// The value given.
        value: f64,
    },
    /// No buildings asked for.
    #[error("invalid parameter buildings = 0: a generated city needs at least 1 building")]
    NoBuildings,
    /// The CRS is unknown or not a projected CRS in metres.
    #[error("invalid parameter epsg = {epsg}: {why}")]
    BadCrs {
        /// The code given.
        epsg: u32,
        /// What is wrong.
        why: String,
    },
    /// The centre is not finite.
    #[error("invalid parameter centre = ({x}, {y}): need finite coordinates")]
    BadCentre {
        /// Easting.
        x: f64,
        /// Northing.
        y: f64,
    },
    /// Blocks are too small for two rows of parcels.
    #[error("invalid parameter block_m: blocks must be at least {min_m} m on a side, got {lo} m")]
    BlocksTooSmall {
        /// The smallest block side asked for.
        lo: f64,
        /// The least allowed ([`tuning::MIN_BLOCK_SIDE_M`]).
        min_m: f64,
    },
    /// A directory or file could not be created or written.
    #[error("{file}: {source}")]
    Io {
        /// The file or directory.
        file: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The Shapefile writer failed.
    #[error("{file}: writing the Shapefile failed: {source}")]
    Shapefile {
        /// The `.shp` file.
        file: PathBuf,
        /// The writer's error.
        #[source]
        source: shapefile::Error,
    },
}

impl GenerateParams {
    /// Checks the ranges and the storey height.
    ///
    /// # Errors
    /// [`GenerateError::NoBuildings`], [`GenerateError::BadRange`],
    /// [`GenerateError::BadStoreyHeight`] or [`GenerateError::BlocksTooSmall`].
    pub fn validate(&self) -> Result<(), GenerateError> {
        if self.buildings == 0 {
            return Err(GenerateError::NoBuildings);
        }
        for (name, (lo, hi)) in [
            ("block_m", self.block_m),
            ("street_m", self.street_m),
            ("frontage_m", self.frontage_m),
        ] {
            if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo < hi) {
                return Err(GenerateError::BadRange { name, lo, hi });
            }
        }
        if !(self.storey_m.is_finite() && self.storey_m > 0.0) {
            return Err(GenerateError::BadStoreyHeight {
                value: self.storey_m,
            });
        }
        match blockwalk_importers::Crs::from_epsg(self.epsg) {
            Ok(c) if c.is_metric_projected() => {}
            Ok(c) => {
                return Err(GenerateError::BadCrs {
                    epsg: self.epsg,
                    why: format!("{} is not a projected CRS in metres", c.describe()),
                })
            }
            Err(e) => {
                return Err(GenerateError::BadCrs {
                    epsg: self.epsg,
                    why: e.to_string(),
                })
            }
        }
        if blockwalk_importers::crs::epsg_wkt(self.epsg).is_none() {
            return Err(GenerateError::BadCrs {
                epsg: self.epsg,
                why: "no WKT for the .prj files".into(),
            });
        }
        if let Some((x, y)) = self.centre {
            if !(x.is_finite() && y.is_finite()) {
                return Err(GenerateError::BadCentre { x, y });
            }
        }
        if self.block_m.0 < tuning::MIN_BLOCK_SIDE_M {
            return Err(GenerateError::BlocksTooSmall {
                lo: self.block_m.0,
                min_m: tuning::MIN_BLOCK_SIDE_M,
            });
        }
        Ok(())
    }
}

/// Generates a city in memory: a grid of about [`tuning::BUILDINGS_PER_BLOCK`] buildings per
/// block, square in blocks, with more rows of blocks until `p.buildings` buildings stand.
///
/// # Errors
/// What [`GenerateParams::validate`] finds.
pub fn generate_city(p: &GenerateParams) -> Result<GeneratedCity, GenerateError> {
    p.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
    let k = ((p.buildings as f64 / tuning::BUILDINGS_PER_BLOCK)
        .sqrt()
        .ceil() as usize)
        .max(1);
    let (xs, street_x) = layout::columns(&mut rng, p, k);

    let mut city = GeneratedCity::default();
    let mut street_y: Vec<layout::StreetLine> = Vec::new();
    let mut y = p.origin.1;
    while city.buildings.len() < p.buildings {
        let sh = rng.random_range(p.street_m.0..p.street_m.1);
        street_y.push((y + sh / 2.0, sh));
        y += sh;
        let bh = rng.random_range(p.block_m.0..p.block_m.1);
        let by0 = y;
        y += bh;
        for &bx in &xs {
            if city.buildings.len() >= p.buildings {
                break;
            }
            city.blocks += 1;
            for parcel in layout::block_parcels(&mut rng, bx, by0, bh, p.frontage_m) {
                if city.buildings.len() >= p.buildings {
                    break;
                }
                if p.parcels {
                    let [x0, y0, x1, y1] = parcel.bounds;
                    city.parcels.push(poly(rect(x0, y0, x1, y1), vec![]));
                }
                let Some(inner) = layout::buildable(&mut rng, &parcel) else {
                    continue;
                };
                let footprint = building_shape(&mut rng, inner, parcel.front, parcel.corner);
                let levels = heights::storeys(&mut rng);
                let height_m = heights::height_m(&mut rng, levels, p.storey_m);
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
    city.streets = layout::street_segments(&street_x, &street_y);
    city.epsg = p.epsg;
    if let Some(c) = p.centre {
        city.centre_at(c);
    }
    Ok(city)
}

/// Where [`place_on_dem`] puts a generated city.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DemPlace {
    /// The elevation model's CRS (a projected CRS in metres).
    pub epsg: u32,
    /// The centre of its grid, CRS metres.
    pub centre: (f64, f64),
}

/// Why a city cannot be put on an elevation model.
#[derive(Debug, thiserror::Error)]
pub enum DemPlaceError {
    /// The file could not be read.
    #[error(transparent)]
    Read(#[from] blockwalk_importers::dem::DemError),
    /// Its CRS is not a projected one in metres with an EPSG code.
    #[error("{file}: the generator needs a DEM in a projected CRS in metres with an EPSG code, this one is {crs}")]
    Crs {
        /// The file.
        file: String,
        /// Its CRS.
        crs: String,
    },
}

/// The CRS and centre that put a generated city on the elevation model `dem` (a GeoTIFF):
/// the model's own CRS, and the centre of its grid.
///
/// # Errors
/// [`DemPlaceError`] when the file cannot be read or its CRS is not a projected one in metres
/// with an EPSG code.
pub fn place_on_dem(dem: &std::path::Path) -> Result<DemPlace, DemPlaceError> {
    let grid = blockwalk_importers::dem::read_dem(dem)?;
    let epsg = match &grid.crs {
        blockwalk_importers::Crs::Projected { epsg: Some(e), .. }
            if grid.crs.is_metric_projected() =>
        {
            e
        }
        other => {
            return Err(DemPlaceError::Crs {
                file: dem.display().to_string(),
                crs: other.describe(),
            })
        }
    };
    // The grid's centre sample position (the transform maps sample indices to positions).
    let (c, r) = (
        (grid.width as f64 - 1.0) / 2.0,
        (grid.height as f64 - 1.0) / 2.0,
    );
    let t = grid.transform;
    Ok(DemPlace {
        epsg: *epsg,
        centre: (t[0] + t[1] * c + t[2] * r, t[3] + t[4] * c + t[5] * r),
    })
}

impl GeneratedCity {
    /// The centre of the box around its buildings, streets and parcels.
    pub fn box_centre(&self) -> (f64, f64) {
        use geo::BoundingRect;
        let rects = self
            .buildings
            .iter()
            .filter_map(|b| b.footprint.bounding_rect())
            .chain(self.streets.iter().filter_map(|s| s.line.bounding_rect()))
            .chain(self.parcels.iter().filter_map(|p| p.bounding_rect()));
        let (mut lo, mut hi) = (
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for r in rects {
            lo = (lo.0.min(r.min().x), lo.1.min(r.min().y));
            hi = (hi.0.max(r.max().x), hi.1.max(r.max().y));
        }
        ((lo.0 + hi.0) / 2.0, (lo.1 + hi.1) / 2.0)
    }

    /// Moves everything so that the box centre ([`Self::box_centre`]) is at `c`, rounded to
    /// whole metres of offset (the layout keeps its centimetre grid).
    pub fn centre_at(&mut self, c: (f64, f64)) {
        use geo::Translate;
        let now = self.box_centre();
        let (dx, dy) = ((c.0 - now.0).round(), (c.1 - now.1).round());
        for b in &mut self.buildings {
            b.footprint.translate_mut(dx, dy);
        }
        for s in &mut self.streets {
            s.line.translate_mut(dx, dy);
        }
        for p in &mut self.parcels {
            p.translate_mut(dx, dy);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_buildings_is_refused() {
        let p = GenerateParams {
            buildings: 0,
            ..GenerateParams::default()
        };
        let Err(e) = generate_city(&p) else {
            panic!("0 buildings must be refused")
        };
        assert!(matches!(e, GenerateError::NoBuildings), "{e:?}");
        assert!(e.to_string().contains("at least 1"), "{e}");
    }
    use crate::geom::predicates::polygon_area;
    use crate::geom::repair::check_polygon;

    /// Triangles of a footprint's extruded prism (see `city::extrude`): two per ring edge for
    /// the walls, and `V + 2H − 2` for each of the roof and the floor.
    fn prism_triangles(p: &Polygon<f64>) -> usize {
        let v: usize = std::iter::once(p.exterior())
            .chain(p.interiors())
            .map(|r| r.0.len() - 1)
            .sum();
        2 * v + 2 * (v + 2 * p.interiors().len() - 2)
    }

    /// Footprints are detailed (about 50 prism triangles per building, so 80,000 buildings
    /// give about 4 M triangles) with detail growing with size, and valid as generated.
    #[test]
    fn footprints_are_detailed_valid_and_graded() {
        let p = GenerateParams {
            buildings: 4000,
            seed: 11,
            ..Default::default()
        };
        let city = generate_city(&p).unwrap();
        assert_eq!(city.buildings.len(), 4000);
        let (mut tris, mut boxes) = (0usize, 0usize);
        let (mut small, mut big) = ((0usize, 0usize), (0usize, 0usize));
        let mut max_v = 0;
        for (i, b) in city.buildings.iter().enumerate() {
            if let Err(e) = check_polygon(&b.footprint) {
                panic!("building {i}: {e}");
            }
            let t = prism_triangles(&b.footprint);
            tris += t;
            let a = polygon_area(&b.footprint);
            if a < 150.0 {
                small = (small.0 + t, small.1 + 1);
            } else if a > 450.0 {
                big = (big.0 + t, big.1 + 1);
            }
            if t == 12 {
                boxes += 1;
            }
            max_v = max_v.max(b.footprint.exterior().0.len() - 1);
        }
        let avg = tris as f64 / city.buildings.len() as f64;
        let small_avg = small.0 as f64 / small.1.max(1) as f64;
        let big_avg = big.0 as f64 / big.1.max(1) as f64;
        println!(
            "avg {avg:.1} triangles/building; small {small_avg:.1} ({}), big {big_avg:.1} ({}); \
             {boxes} boxes; max exterior vertices {max_v}",
            small.1, big.1
        );
        // Plain boxes give 12 triangles, the former L/U/courtyard mix about 14.
        assert!((42.0..=58.0).contains(&avg), "{avg}");
        // A realistic spread: small houses simple, large blocks detailed, some plain boxes.
        assert!(small.1 > 0 && big.1 > 0);
        assert!(big_avg > 2.0 * small_avg, "{small_avg} vs {big_avg}");
        assert!(boxes > 0 && boxes < city.buildings.len() / 3, "{boxes}");
    }

    /// FNV-1a (64 bit): a hash fixed by its definition, unlike `std`'s `DefaultHasher`.
    struct Fnv(u64);

    impl Fnv {
        fn new() -> Self {
            Fnv(0xcbf2_9ce4_8422_2325)
        }
        fn bytes(&mut self, b: &[u8]) {
            for &x in b {
                self.0 = (self.0 ^ x as u64).wrapping_mul(0x0100_0000_01b3);
            }
        }
        fn u64(&mut self, v: u64) {
            self.bytes(&v.to_le_bytes());
        }
        fn f64(&mut self, v: f64) {
            self.u64(v.to_bits());
        }
        fn line(&mut self, l: &LineString<f64>) {
            self.u64(l.0.len() as u64);
            for c in &l.0 {
                self.f64(c.x);
                self.f64(c.y);
            }
        }
        fn polygon(&mut self, p: &Polygon<f64>) {
            self.line(p.exterior());
            self.u64(p.interiors().len() as u64);
            for r in p.interiors() {
                self.line(r);
            }
        }
    }

    /// Every coordinate, height, level, width and count of a generated city, bit for bit.
    fn city_hash(c: &GeneratedCity) -> u64 {
        let mut h = Fnv::new();
        h.u64(c.blocks as u64);
        h.u64(c.buildings.len() as u64);
        for b in &c.buildings {
            h.polygon(&b.footprint);
            h.f64(b.height_m);
            h.u64(b.levels as u64);
        }
        h.u64(c.streets.len() as u64);
        for s in &c.streets {
            h.line(&s.line);
            h.f64(s.width_m);
        }
        h.u64(c.parcels.len() as u64);
        for p in &c.parcels {
            h.polygon(p);
        }
        h.0
    }

    /// The generator's output is pinned: these figures were computed on the generator before its
    /// tuning numbers were named, and any change to the numbers, the order of the random draws or
    /// the arithmetic changes them. The written Shapefiles are pinned too.
    #[test]
    fn pinned_output_for_fixed_seeds() {
        let small = GenerateParams {
            buildings: 400,
            seed: 2024,
            ..Default::default()
        };
        let odd = GenerateParams {
            buildings: 150,
            seed: 5,
            block_m: (45.0, 200.0),
            street_m: (8.0, 30.0),
            frontage_m: (7.0, 45.0),
            storey_m: 2.9,
            parcels: false,
            origin: (480_123.25, 5_390_001.5),
            epsg: 32633,
            centre: None,
        };
        let mut got = Vec::new();
        for p in [&small, &odd] {
            let c = generate_city(p).unwrap();
            let vertices: usize = c
                .buildings
                .iter()
                .map(|b| {
                    std::iter::once(b.footprint.exterior())
                        .chain(b.footprint.interiors())
                        .map(|r| r.0.len())
                        .sum::<usize>()
                })
                .sum();
            let dir = tempfile::tempdir().unwrap();
            let written = write_city(&c, dir.path()).unwrap();
            let mut files = Fnv::new();
            for f in &written.files {
                let mut bytes = std::fs::read(f).unwrap();
                if f.extension().is_some_and(|e| e == "dbf") {
                    // The dBase header's bytes 1–3 hold the date the file was written.
                    bytes[1..4].fill(0);
                }
                files.bytes(&bytes);
            }
            got.push((
                c.buildings.len(),
                c.streets.len(),
                c.parcels.len(),
                c.blocks,
                vertices,
                city_hash(&c),
                files.0,
            ));
        }
        // (buildings, streets, parcels, blocks, footprint vertices, city hash, file hash)
        assert_eq!(
            got,
            vec![
                (
                    400,
                    71,
                    400,
                    26,
                    5580,
                    17_988_929_856_730_493_869,
                    3_768_489_381_686_716_777
                ),
                (
                    150,
                    22,
                    0,
                    7,
                    2425,
                    15_684_274_352_938_293_588,
                    16_253_339_084_810_151_546
                ),
            ]
        );
    }

    #[test]
    fn bad_parameters_are_refused_by_name() {
        let base = GenerateParams::default();
        let e = generate_city(&GenerateParams {
            street_m: (25.0, 12.0),
            ..base.clone()
        })
        .unwrap_err();
        assert!(
            matches!(e, GenerateError::BadRange { name: "street_m", lo, hi } if lo == 25.0 && hi == 12.0),
            "{e:?}"
        );
        assert!(e.to_string().contains("street_m"), "{e}");
        let e = generate_city(&GenerateParams {
            frontage_m: (f64::NAN, 30.0),
            ..base.clone()
        })
        .unwrap_err();
        assert!(
            matches!(
                e,
                GenerateError::BadRange {
                    name: "frontage_m",
                    ..
                }
            ),
            "{e:?}"
        );
        let e = generate_city(&GenerateParams {
            storey_m: f64::INFINITY,
            ..base.clone()
        })
        .unwrap_err();
        assert!(matches!(e, GenerateError::BadStoreyHeight { .. }), "{e:?}");
        let e = generate_city(&GenerateParams {
            block_m: (30.0, 150.0),
            ..base
        })
        .unwrap_err();
        assert!(
            matches!(e, GenerateError::BlocksTooSmall { lo, min_m } if lo == 30.0 && min_m == tuning::MIN_BLOCK_SIDE_M),
            "{e:?}"
        );
    }

    #[test]
    fn write_errors_keep_the_file_and_the_cause() {
        let dir = tempfile::tempdir().unwrap();
        let blocker = dir.path().join("not_a_dir");
        std::fs::write(&blocker, b"x").unwrap();
        let city = generate_city(&GenerateParams {
            buildings: 3,
            ..Default::default()
        })
        .unwrap();
        let e = write_city(&city, &blocker).unwrap_err();
        assert!(
            matches!(&e, GenerateError::Output(crate::output::OutputError::WrongKind { path, .. }) if path == &blocker),
            "{e:?}"
        );
        assert!(e.to_string().contains("not_a_dir"), "{e}");
        assert_eq!(std::fs::read(&blocker).unwrap(), b"x", "the file is kept");
        // A folder of other files is refused, and kept whole.
        let other = dir.path().join("mine");
        std::fs::create_dir(&other).unwrap();
        std::fs::write(other.join("notes.txt"), b"keep").unwrap();
        let e = write_city(&city, &other).unwrap_err();
        assert!(e.to_string().contains("notes.txt"), "{e}");
        assert_eq!(std::fs::read(other.join("notes.txt")).unwrap(), b"keep");
        // A previous city is replaced whole.
        let out = dir.path().join("city");
        let w = write_city(&city, &out).unwrap();
        assert!(
            w.files.iter().all(|f| f.starts_with(&out) && f.exists()),
            "{:?}",
            w.files
        );
        write_city(&city, &out).unwrap();
    }

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
