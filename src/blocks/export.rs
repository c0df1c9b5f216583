//! Block layout output: GeoJSON in the input's own coordinates, a one-object summary, and a map
//! picture (SVG, or PNG through an RGB raster).

use super::types::{BlockKind, BlockLayout, BlockSource};
use crate::geom::predicates::polygon_area;
use blockwalk_importers::{Crs, MetricTransform};
use geo_types::{Coord, LineString, Polygon};
use plotters::prelude::*;
use serde::Serialize;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// Why an output could not be written. Every variant names the file and keeps the cause.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The output could not be written, renamed or placed (see [`crate::output`]).
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    /// The file could not be written.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The GeoJSON could not be serialised.
    #[error("{file}: serialising the GeoJSON failed: {source}")]
    Json {
        /// The file.
        file: PathBuf,
        /// What `serde_json` said.
        #[source]
        source: serde_json::Error,
    },
    /// plotters failed to draw the map (for SVG this includes writing the file).
    #[error("{file}: drawing the map failed: {source}")]
    Draw {
        /// The file.
        file: PathBuf,
        /// plotters' error (its type depends on the backend).
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The PNG could not be encoded or written.
    #[error("{file}: writing the image failed: {source}")]
    Image {
        /// The file.
        file: PathBuf,
        /// What `image` said.
        #[source]
        source: image::ImageError,
    },
    /// The map format is not known from the file name.
    #[error("{file}: unknown map format (expected .svg or .png)")]
    Format {
        /// The file.
        file: PathBuf,
    },
}

fn to_input(t: &MetricTransform, ls: &LineString<f64>) -> LineString<f64> {
    LineString(
        ls.0.iter()
            .map(|c| {
                let [x, y] = t.from_metric([c.x, c.y]);
                Coord { x, y }
            })
            .collect(),
    )
}

/// A polygon mapped from metric world coordinates back to the input's own coordinates.
pub fn polygon_to_input(t: &MetricTransform, p: &Polygon<f64>) -> Polygon<f64> {
    Polygon::new(
        to_input(t, p.exterior()),
        p.interiors().iter().map(|r| to_input(t, r)).collect(),
    )
}

/// Counts and areas of a layout, as printed by `blockwalk blocks --json`.
#[derive(Clone, Debug, Serialize)]
pub struct LayoutSummary {
    /// Blocks (faces / inferred blocks), not counting outskirts groups.
    pub blocks: usize,
    /// Outskirts groups.
    pub outskirts_groups: usize,
    /// Sum of the block areas in the input's own planar units (e.g. EPSG:3857 units²).
    pub total_area: f64,
    /// Sum of the block areas in square metres on the ground (metric world coordinates).
    pub total_area_m2: f64,
    /// Buildings inside blocks.
    pub buildings_assigned: usize,
    /// Buildings in outskirts groups.
    pub buildings_outskirts: usize,
    /// Edges of the noded street graph.
    pub street_edges: usize,
    /// Dangling street ends.
    pub dangles: usize,
    /// How the blocks were found.
    pub source: BlockSource,
}

/// Summarises a layout; `transform` maps the metric world back to the input's coordinates.
pub fn summary(layout: &BlockLayout, transform: &MetricTransform) -> LayoutSummary {
    let mut s = LayoutSummary {
        blocks: 0,
        outskirts_groups: 0,
        total_area: 0.0,
        total_area_m2: 0.0,
        buildings_assigned: 0,
        buildings_outskirts: 0,
        street_edges: layout.street_edges.len(),
        dangles: layout.dangles,
        source: layout.source,
    };
    for b in &layout.blocks {
        match b.kind {
            BlockKind::Block => {
                s.blocks += 1;
                s.total_area_m2 += polygon_area(&b.polygon);
                s.total_area += polygon_area(&polygon_to_input(transform, &b.polygon));
                s.buildings_assigned += b.buildings.len();
            }
            BlockKind::Outskirts => {
                s.outskirts_groups += 1;
                s.buildings_outskirts += b.buildings.len();
            }
        }
    }
    s
}

/// The block of every footprint feature that gave at least one building, by the feature's id
/// ([`crate::city::build::source_fid`] of its buildings' source ids): for a feature that gave
/// several buildings (a MultiPolygon, a polygon split by repair) whose parts lie in different
/// blocks, the block of its largest part by ground area (the first such part on a tie). Features
/// that were refused have no entry (the city's report lists them).
pub fn feature_blocks(
    city: &crate::city::City,
    layout: &BlockLayout,
) -> std::collections::BTreeMap<u64, super::types::BlockId> {
    let mut block_of = vec![None; city.buildings.len()];
    for b in &layout.blocks {
        for i in &b.buildings {
            if let Some(slot) = block_of.get_mut(i.0 as usize) {
                *slot = Some(b.id);
            }
        }
    }
    let mut best: std::collections::BTreeMap<u64, (f64, super::types::BlockId)> =
        std::collections::BTreeMap::new();
    for (b, block) in city.buildings.iter().zip(block_of) {
        let (Some(fid), Some(block)) = (crate::city::build::source_fid(&b.source_id), block) else {
            continue;
        };
        let area = polygon_area(&b.footprint).abs();
        best.entry(fid)
            .and_modify(|e| {
                if area > e.0 {
                    *e = (area, block);
                }
            })
            .or_insert((area, block));
    }
    best.into_iter().map(|(f, (_, b))| (f, b)).collect()
}

fn ring_json(ls: &LineString<f64>) -> Value {
    Value::Array(ls.0.iter().map(|c| json!([c.x, c.y])).collect())
}

/// The layout as a GeoJSON FeatureCollection in the input's own coordinates. Properties: `id`,
/// `kind` (`block` / `outskirts`), `area_m2` (ground area of the metric polygon), `area` (planar
/// area in the input's units), `n_buildings`, `buildings` (indices into the city's buildings).
/// A legacy `crs` member names the input's EPSG code when it is known.
pub fn to_geojson(layout: &BlockLayout, transform: &MetricTransform) -> Value {
    let features: Vec<Value> = layout
        .blocks
        .iter()
        .map(|b| {
            let p = polygon_to_input(transform, &b.polygon);
            let mut rings = vec![ring_json(p.exterior())];
            rings.extend(p.interiors().iter().map(ring_json));
            json!({
                "type": "Feature",
                "id": b.id.0,
                "properties": {
                    "id": b.id.0,
                    "kind": b.kind,
                    "area_m2": polygon_area(&b.polygon),
                    "area": polygon_area(&p),
                    "n_buildings": b.buildings.len(),
                    "buildings": b.buildings.iter().map(|i| i.0).collect::<Vec<_>>(),
                },
                "geometry": { "type": "Polygon", "coordinates": rings },
            })
        })
        .collect();
    let mut fc = json!({ "type": "FeatureCollection", "features": features });
    let epsg = match &transform.crs {
        Crs::Projected { epsg: Some(e), .. } | Crs::Geographic { epsg: Some(e) } => Some(*e),
        Crs::WebMercator => Some(3857),
        _ => None,
    };
    if let Some(e) = epsg {
        fc["crs"] =
            json!({"type": "name", "properties": {"name": format!("urn:ogc:def:crs:EPSG::{e}")}});
    }
    fc
}

/// Writes [`to_geojson`] to a file.
///
/// # Errors
/// [`ExportError::Json`] or [`ExportError::Io`] naming the file.
pub fn write_geojson(
    path: &Path,
    layout: &BlockLayout,
    transform: &MetricTransform,
) -> Result<(), ExportError> {
    let text = serde_json::to_string(&to_geojson(layout, transform)).map_err(|source| {
        ExportError::Json {
            file: path.to_path_buf(),
            source,
        }
    })?;
    crate::output::write_bytes(path, text)
        .map(drop)
        .map_err(crate::output::OutputError::into_io)
        .map_err(|source| ExportError::Io {
            file: path.to_path_buf(),
            source,
        })
}

/// A fixed, colour-blind-friendly palette for blocks.
const PALETTE: [(u8, u8, u8); 8] = [
    (230, 159, 0),
    (86, 180, 233),
    (0, 158, 115),
    (240, 228, 66),
    (0, 114, 178),
    (213, 94, 0),
    (204, 121, 167),
    (153, 204, 102),
];

/// Draws the map: blocks coloured (outskirts groups grey outlines), street edges in dark grey,
/// buildings in near-black. `buildings` are the footprints in metric world coordinates.
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    size: (u32, u32),
    layout: &BlockLayout,
    buildings: &[Polygon<f64>],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    let mut grow = |c: &Coord<f64>| {
        lo = [lo[0].min(c.x), lo[1].min(c.y)];
        hi = [hi[0].max(c.x), hi[1].max(c.y)];
    };
    layout
        .blocks
        .iter()
        .flat_map(|b| &b.polygon.exterior().0)
        .for_each(&mut grow);
    buildings
        .iter()
        .flat_map(|b| &b.exterior().0)
        .for_each(&mut grow);
    layout
        .street_edges
        .iter()
        .flat_map(|l| &l.0)
        .for_each(&mut grow);
    if lo[0] > hi[0] {
        return Ok(());
    }
    let margin = 10.0;
    let scale = ((size.0 as f64 - 2.0 * margin) / (hi[0] - lo[0]).max(1e-9))
        .min((size.1 as f64 - 2.0 * margin) / (hi[1] - lo[1]).max(1e-9));
    let px = |c: &Coord<f64>| -> (i32, i32) {
        (
            (margin + (c.x - lo[0]) * scale).round() as i32,
            (size.1 as f64 - margin - (c.y - lo[1]) * scale).round() as i32,
        )
    };
    let ring = |ls: &LineString<f64>| ls.0.iter().map(px).collect::<Vec<_>>();
    for b in &layout.blocks {
        match b.kind {
            BlockKind::Block => {
                let (r, g, bl) = PALETTE[b.id.0 as usize % PALETTE.len()];
                root.draw(&plotters::element::Polygon::new(
                    ring(b.polygon.exterior()),
                    RGBColor(r, g, bl).mix(0.45).filled(),
                ))?;
                for h in b.polygon.interiors() {
                    root.draw(&plotters::element::Polygon::new(ring(h), WHITE.filled()))?;
                }
            }
            BlockKind::Outskirts => {
                root.draw(&PathElement::new(
                    ring(b.polygon.exterior()),
                    RGBColor(150, 150, 150).stroke_width(1),
                ))?;
            }
        }
    }
    for l in &layout.street_edges {
        root.draw(&PathElement::new(
            ring(l),
            RGBColor(60, 60, 60).stroke_width(2),
        ))?;
    }
    for b in buildings {
        root.draw(&plotters::element::Polygon::new(
            ring(b.exterior()),
            RGBColor(30, 30, 30).filled(),
        ))?;
    }
    root.present()
}

/// Writes the map as SVG or PNG, chosen by the file's extension; the long side is `long_side`
/// pixels.
///
/// # Errors
/// [`ExportError`] naming the file.
pub fn write_map(
    path: &Path,
    layout: &BlockLayout,
    buildings: &[Polygon<f64>],
    long_side: u32,
) -> Result<(), ExportError> {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for c in layout
        .blocks
        .iter()
        .flat_map(|b| &b.polygon.exterior().0)
        .chain(buildings.iter().flat_map(|b| &b.exterior().0))
    {
        lo = [lo[0].min(c.x), lo[1].min(c.y)];
        hi = [hi[0].max(c.x), hi[1].max(c.y)];
    }
    let (w, h) = if lo[0] <= hi[0] {
        let (dx, dy) = ((hi[0] - lo[0]).max(1e-9), (hi[1] - lo[1]).max(1e-9));
        if dx >= dy {
            (long_side, ((long_side as f64 * dy / dx) as u32).max(64))
        } else {
            (((long_side as f64 * dx / dy) as u32).max(64), long_side)
        }
    } else {
        (long_side, long_side)
    };
    let fail = |source: Box<dyn std::error::Error + Send + Sync>| ExportError::Draw {
        file: path.to_path_buf(),
        source,
    };
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("svg") => {
            let mut text = String::new();
            {
                let root = SVGBackend::with_string(&mut text, (w, h)).into_drawing_area();
                draw(&root, (w, h), layout, buildings).map_err(|e| fail(e.into()))?;
            }
            crate::output::write_bytes(path, text)
                .map(drop)
                .map_err(ExportError::Output)
        }
        Some("png") => {
            let mut buf = vec![255u8; (w * h * 3) as usize];
            {
                let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
                draw(&root, (w, h), layout, buildings).map_err(|e| fail(e.into()))?;
            }
            let img = image::RgbImage::from_raw(w, h, buf)
                .expect("the buffer was allocated as width × height × 3");
            crate::output::write_png(path, &img)
                .map(drop)
                .map_err(|source| ExportError::Image {
                    file: path.to_path_buf(),
                    source,
                })
        }
        _ => Err(ExportError::Format {
            file: path.to_path_buf(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::importers::{Attributes, Crs, Feature, ImportReport, Layer};
    use geo_types::{line_string, polygon, Geometry, MultiPolygon};

    fn layer(name: &str, geoms: Vec<Geometry<f64>>) -> Layer {
        let n = geoms.len();
        Layer {
            name: name.into(),
            source: name.into(),
            crs: Crs::Unknown,
            features: geoms
                .into_iter()
                .enumerate()
                .map(|(i, geometry)| Feature {
                    fid: i as u64,
                    geometry,
                    attributes: Attributes::new(),
                })
                .collect(),
            report: ImportReport {
                read: n,
                imported: n,
                ..Default::default()
            },
        }
    }

    #[test]
    fn a_feature_in_several_blocks_goes_where_its_largest_part_is() {
        let sq = |x: f64, y: f64, s: f64| polygon![(x: x, y: y), (x: x + s, y: y), (x: x + s, y: y + s), (x: x, y: y + s), (x: x, y: y)];
        // Two street cells side by side: [0, 100] and [100, 200] × [0, 100].
        let streets = layer(
            "streets",
            vec![
                Geometry::LineString(line_string![(x: -10.0, y: 0.0), (x: 210.0, y: 0.0)]),
                Geometry::LineString(line_string![(x: -10.0, y: 100.0), (x: 210.0, y: 100.0)]),
                Geometry::LineString(line_string![(x: 0.0, y: -10.0), (x: 0.0, y: 110.0)]),
                Geometry::LineString(line_string![(x: 100.0, y: -10.0), (x: 100.0, y: 110.0)]),
                Geometry::LineString(line_string![(x: 200.0, y: -10.0), (x: 200.0, y: 110.0)]),
            ],
        );
        let buildings = layer(
            "buildings",
            vec![
                // A small part in the left cell, a large one in the right cell.
                Geometry::MultiPolygon(MultiPolygon(vec![
                    sq(10.0, 10.0, 10.0),
                    sq(120.0, 20.0, 30.0),
                ])),
                Geometry::Polygon(sq(40.0, 40.0, 20.0)),
            ],
        );
        let city =
            crate::city::build::build_city(&buildings, Some(&streets), None, &Default::default())
                .unwrap();
        let layout = crate::blocks::detect(&city, &Default::default()).unwrap();
        let block_at = |x: f64| {
            layout
                .blocks
                .iter()
                .find(|b| {
                    b.kind == BlockKind::Block
                        && crate::geom::predicates::polygon_area(&b.polygon) > 9000.0
                        && b.polygon
                            .exterior()
                            .0
                            .iter()
                            .all(|c| c.x >= x - 1e-6 && c.x <= x + 100.0 + 1e-6)
                })
                .map(|b| b.id)
                .unwrap()
        };
        let m = feature_blocks(&city, &layout);
        assert_eq!(m.len(), 2);
        assert_eq!(m[&0], block_at(100.0));
        assert_eq!(m[&1], block_at(0.0));
        assert_ne!(block_at(0.0), block_at(100.0));
    }
}
