//! Frames: the layers' CRS to the metric world, the local origin for f32, and how far the model
//! reaches from it.
//!
//! - The metric world is the footprints' frame ([`blockwalk_importers::Crs::try_metric_transform`]);
//!   street and parcel layers in another CRS are reprojected into it
//!   ([`blockwalk_importers::MetricTransform::for_layer`]), datum shifts included. A layer without
//!   a CRS next to one with a CRS is taken to be in it, with a note.
//! - The local origin is the median of the footprints' bounding-box centres (x and y apart), so
//!   one stray feature far away (a building at (0, 0), 3,300 km off) cannot move it; features
//!   whose centre lies beyond [`OUTLIER_FACTOR`] × the median distance (and at least
//!   [`OUTLIER_MIN_DISTANCE_M`]) are named in the report.
//! - f32 keeps 24 bits: at a distance `d` from the origin, vertices are `2^(⌊log2 d⌋ − 23)` m apart.
//!   [`MAX_F32_OFFSET_M`] (16,384 m) is where that spacing passes 1 mm; a model that reaches further
//!   is reported with its farthest buildings and the spacing there.

use blockwalk_importers::{Crs, Layer, MetricTransform};
use geo_types::Polygon;
use glam::DVec3;
use serde::Serialize;

use super::geometry::{lines_of, polygons_of};
use super::BuildError;
use crate::city::model::{Building, LocalFrame};
use crate::geom::Rect;

/// A feature whose centre is this many times the median centre distance from the origin is an
/// outlier (when also beyond [`OUTLIER_MIN_DISTANCE_M`]).
pub const OUTLIER_FACTOR: f64 = 10.0;
/// Outliers are at least this far from the origin, metres (a compact town is never flagged).
pub const OUTLIER_MIN_DISTANCE_M: f64 = 2_000.0;
/// The largest offset from the origin at which f32 vertices are at most 1 mm apart: f32 spacing
/// is 2^-10 m ≈ 0.98 mm in [8,192, 16,384) m and 1.95 mm above.
pub const MAX_F32_OFFSET_M: f64 = 16_384.0;
/// How many outliers or far buildings the report names.
const NAMED: usize = 10;

/// Where the local origin is and what f32 keeps of the model relative to it.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameReport {
    /// How the origin was chosen.
    pub origin_rule: String,
    /// Buildings far from all the others (source id and distance from the origin, m); they do
    /// not move the origin.
    pub outliers: Vec<(String, f64)>,
    /// The largest |x| or |y| of a building vertex relative to the origin, metres.
    pub max_offset_m: f64,
    /// The spacing of f32 values at that offset, metres (what a `.glb` vertex can resolve there).
    pub f32_spacing_m: f64,
    /// True when the spacing is at most 1 mm everywhere ([`MAX_F32_OFFSET_M`]).
    pub f32_ok: bool,
    /// The farthest buildings when `f32_ok` is false (source id, offset in m).
    pub farthest: Vec<(String, f64)>,
}

/// Spacing of f32 values near `d` (d ≥ 0), metres.
pub fn f32_spacing(d: f64) -> f64 {
    let d = d.abs() as f32;
    if d == 0.0 {
        return f32::MIN_POSITIVE as f64;
    }
    (d.next_up() - d) as f64
}

/// `[xmin, ymin, xmax, ymax]` of the finite corners of `p`'s outer ring; `None` when it has none.
pub fn finite_bbox(p: &Polygon<f64>) -> Option<[f64; 4]> {
    p.exterior()
        .0
        .iter()
        .filter(|c| c.x.is_finite() && c.y.is_finite())
        .fold(None, |b, c| Some(Rect::grow(b, Rect::point([c.x, c.y]))))
        .map(Rect::to_array)
}

fn bbox_centre(p: &Polygon<f64>) -> Option<[f64; 2]> {
    finite_bbox(p).map(|b| Rect::from(b).centre())
}

fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// The median (x and y apart) of the given centres.
pub fn median_centre(centres: &[[f64; 2]]) -> Option<[f64; 2]> {
    let mut xs: Vec<f64> = centres.iter().map(|c| c[0]).collect();
    let mut ys: Vec<f64> = centres.iter().map(|c| c[1]).collect();
    Some([median(&mut xs)?, median(&mut ys)?])
}

/// The median of the footprint features' bounding-box centres, in the layer's own coordinates
/// (the centre of the local projection for Web Mercator and lon/lat data).
pub fn layer_centre(layer: &Layer) -> Option<[f64; 2]> {
    let centres: Vec<[f64; 2]> = layer
        .features
        .iter()
        .filter_map(|f| polygons_of(&f.geometry))
        .flat_map(|ps| ps.into_iter().filter_map(|p| bbox_centre(&p)))
        .collect();
    median_centre(&centres)
}

/// The median of the line features' bounding-box centres, in the layer's own coordinates: the
/// centre of a street layer's metric transform when there are no footprints.
pub fn line_layer_centre(layer: &Layer) -> Option<[f64; 2]> {
    let centres: Vec<[f64; 2]> = layer
        .features
        .iter()
        .filter_map(|f| lines_of(&f.geometry))
        .flat_map(|ls| {
            ls.into_iter().filter_map(|l| {
                l.0.iter()
                    .filter(|c| c.x.is_finite() && c.y.is_finite())
                    .fold(None, |b, c| Some(Rect::grow(b, Rect::point([c.x, c.y]))))
                    .map(|r| r.centre())
            })
        })
        .collect();
    median_centre(&centres)
}

/// The footprints' metric transform, centred on [`layer_centre`].
///
/// # Errors
/// [`BuildError::Crs`] when the CRS cannot be set up.
pub fn footprint_transform(footprints: &Layer) -> Result<MetricTransform, BuildError> {
    let centre = layer_centre(footprints).unwrap_or([0.0, 0.0]);
    footprints
        .crs
        .try_metric_transform(centre)
        .map_err(|source| BuildError::Crs {
            layer: footprints.source.display().to_string(),
            source,
        })
}

/// The transform of a street or parcel layer into the footprints' frame, with a note on what was
/// done.
///
/// # Errors
/// [`BuildError::Crs`] when the layer's CRS cannot be set up.
pub fn layer_transform(
    frame: &MetricTransform,
    layer: &Layer,
    notes: &mut Vec<String>,
) -> Result<MetricTransform, BuildError> {
    let name = &layer.name;
    match (&frame.crs, &layer.crs) {
        (a, b) if a == b => Ok(frame.clone()),
        (_, Crs::Unknown) => {
            notes.push(format!(
                "{name}: no CRS given; taken to be the footprints' ({})",
                frame.crs.describe()
            ));
            Ok(frame.clone())
        }
        (Crs::Unknown, other) => {
            notes.push(format!(
                "{name}: {} cannot be related to the footprints, which have no CRS; its \
                 coordinates are used as they are",
                other.describe()
            ));
            Ok(Crs::Unknown.metric_transform([0.0, 0.0]))
        }
        (_, other) => {
            let t = frame.for_layer(other).map_err(|source| BuildError::Crs {
                layer: layer.source.display().to_string(),
                source,
            })?;
            notes.push(format!("{name}: {}", t.describe()));
            Ok(t)
        }
    }
}

/// The local origin of the buildings (median of their bounding-box centres, z = 0) and the
/// report of outliers and f32 precision.
pub fn robust_origin(buildings: &[Building]) -> (LocalFrame, FrameReport) {
    let centres: Vec<[f64; 2]> = buildings
        .iter()
        .filter_map(|b| bbox_centre(&b.footprint))
        .collect();
    let [ox, oy] = median_centre(&centres).unwrap_or([0.0, 0.0]);
    let frame = LocalFrame {
        origin: DVec3::new(ox, oy, 0.0),
    };
    let mut dist: Vec<f64> = centres
        .iter()
        .map(|c| (c[0] - ox).hypot(c[1] - oy))
        .collect();
    let typical = median(&mut dist.clone()).unwrap_or(0.0);
    let limit = (OUTLIER_FACTOR * typical).max(OUTLIER_MIN_DISTANCE_M);
    let mut outliers: Vec<(String, f64)> = buildings
        .iter()
        .zip(dist.iter_mut())
        .filter(|(_, d)| **d > limit)
        .map(|(b, d)| (b.source_id.clone(), *d))
        .collect();
    outliers.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut offsets: Vec<(String, f64)> = buildings
        .iter()
        .map(|b| {
            let m = b
                .footprint
                .exterior()
                .0
                .iter()
                .map(|c| (c.x - ox).abs().max((c.y - oy).abs()))
                .fold(0.0, f64::max);
            (b.source_id.clone(), m)
        })
        .collect();
    let max_offset_m = offsets.iter().map(|o| o.1).fold(0.0, f64::max);
    let f32_ok = max_offset_m < MAX_F32_OFFSET_M;
    let farthest = if f32_ok {
        Vec::new()
    } else {
        offsets.sort_by(|a, b| b.1.total_cmp(&a.1));
        offsets.truncate(NAMED);
        offsets
    };
    let report = FrameReport {
        origin_rule: format!(
            "median of {} building centres; outliers beyond {:.0} m",
            centres.len(),
            limit
        ),
        outliers,
        max_offset_m,
        f32_spacing_m: f32_spacing(max_offset_m),
        f32_ok,
        farthest,
    };
    (frame, report)
}

/// Notes for the report: outliers and f32 precision, in words.
pub fn frame_notes(r: &FrameReport) -> Vec<String> {
    let mut notes = Vec::new();
    if !r.outliers.is_empty() {
        let names: Vec<String> = r
            .outliers
            .iter()
            .map(|(id, d)| format!("{id} ({:.1} km)", d / 1000.0))
            .collect();
        notes.push(format!(
            "warning: {} building(s) lie far from all the others and did not move the local \
             origin: {}",
            r.outliers.len(),
            names.join(", ")
        ));
    }
    if !r.f32_ok {
        let names: Vec<String> = r
            .farthest
            .iter()
            .map(|(id, d)| format!("{id} ({:.1} km)", d / 1000.0))
            .collect();
        notes.push(format!(
            "warning: the model reaches {:.1} km from its origin, where f32 vertices (.glb, GPU) \
             are {:.1} mm apart, coarser than 1 mm (limit {:.0} m); farthest: {}",
            r.max_offset_m / 1000.0,
            r.f32_spacing_m * 1000.0,
            MAX_F32_OFFSET_M,
            names.join(", ")
        ));
    }
    notes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_spacing_matches_the_format() {
        assert_eq!(f32_spacing(1.0), f32::EPSILON as f64);
        assert_eq!(f32_spacing(10_000.0), 2f64.powi(-10));
        assert_eq!(f32_spacing(3.3e6), 0.25);
        assert!(f32_spacing(MAX_F32_OFFSET_M - 1.0) < 1e-3);
        assert!(f32_spacing(MAX_F32_OFFSET_M) > 1e-3);
    }

    #[test]
    fn median_ignores_one_far_point() {
        let mut c: Vec<[f64; 2]> = (0..9).map(|i| [1000.0 + i as f64, 2000.0]).collect();
        c.push([-3.3e6, 0.0]);
        assert_eq!(median_centre(&c), Some([1003.5, 2000.0]));
    }
}
