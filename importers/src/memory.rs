//! A layer from features held in memory as Well-Known Binary: the geometry column of a data frame
//! (GeoPandas' `to_wkb`) with its attribute columns, handed over by a caller that read the data
//! itself. The features are checked as the file readers check theirs, and the [`ImportReport`]
//! accounts for every one.

use crate::wkb::{check_finite, decode_wkb};
use crate::{Attributes, Crs, Feature, ImportReport, Layer};
use rayon::prelude::*;
use std::path::PathBuf;

/// One feature as handed over: its id, its geometry as WKB (`None`: a missing geometry) and its
/// attributes.
#[derive(Clone, Debug)]
pub struct WkbFeature<'a> {
    /// The feature's id in the report and in the buildings' source ids (a row position).
    pub fid: u64,
    /// The geometry as WKB (either byte order, 2D or with Z/M, which are dropped).
    pub wkb: Option<&'a [u8]>,
    /// The attributes by column name.
    pub attributes: Attributes,
}

/// A layer named `name` (its `source` is what error messages and reports call it, e.g. `"the
/// GeoDataFrame buildings"`) in `crs` from `features`. A feature whose geometry is missing, cannot
/// be decoded, is empty, or has a NaN or infinite coordinate is refused with the reason (its
/// vertex named); the others are kept in order.
pub fn layer_from_wkb<'a>(
    name: &str,
    source: impl Into<PathBuf>,
    crs: Crs,
    features: impl IntoIterator<Item = WkbFeature<'a>>,
) -> Layer {
    let mut report = ImportReport::default();
    let mut out = Vec::new();
    // Decoded in parallel, accounted for in order.
    let features: Vec<WkbFeature<'a>> = features.into_iter().collect();
    let decoded: Vec<(WkbFeature<'a>, Result<_, String>)> = features
        .into_par_iter()
        .map(|f| {
            let geometry = match f.wkb {
                None => Err("missing geometry".to_string()),
                Some(bytes) => match decode_wkb(bytes) {
                    Ok(None) => Err("empty geometry".to_string()),
                    Ok(Some(g)) => check_finite(&g).map(|_| g),
                    Err(e) => Err(format!("geometry cannot be decoded as WKB: {e}")),
                },
            };
            (f, geometry)
        })
        .collect();
    for (f, geometry) in decoded {
        report.read += 1;
        match geometry {
            Ok(geometry) => out.push(Feature {
                fid: f.fid,
                geometry,
                attributes: f.attributes,
            }),
            Err(reason) => report.refuse(f.fid, reason),
        }
    }
    report.imported = out.len();
    report.group_refusals();
    Layer {
        name: name.to_string(),
        source: source.into(),
        crs,
        features: out,
        report,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wkb::encode_wkb;
    use crate::AttrValue;
    use geo_types::{polygon, Geometry};

    #[test]
    fn every_feature_is_kept_or_refused_with_its_reason() {
        let good = encode_wkb(&Geometry::Polygon(polygon![
            (x: 0.0, y: 0.0), (x: 1.0, y: 0.0), (x: 1.0, y: 1.0), (x: 0.0, y: 0.0)
        ]));
        let nan = encode_wkb(&Geometry::Polygon(polygon![
            (x: 0.0, y: 0.0), (x: f64::NAN, y: 0.0), (x: 1.0, y: 1.0), (x: 0.0, y: 0.0)
        ]));
        let truncated = &good[..good.len() - 3];
        let attrs: Attributes = [("h".to_string(), AttrValue::Float(12.5))].into();
        let inputs: [Option<&[u8]>; 4] = [Some(&good), Some(&nan), Some(truncated), None];
        let layer = layer_from_wkb(
            "buildings",
            "the frame",
            Crs::Unknown,
            inputs.iter().enumerate().map(|(i, w)| WkbFeature {
                fid: i as u64,
                wkb: *w,
                attributes: attrs.clone(),
            }),
        );
        assert_eq!(layer.features.len(), 1);
        assert_eq!(layer.features[0].attributes, attrs);
        assert_eq!(layer.report.read, 4);
        assert_eq!(layer.report.imported, 1);
        let reasons: Vec<(u64, &str)> = layer
            .report
            .refused
            .iter()
            .map(|r| (r.fid, r.reason.as_str()))
            .collect();
        assert_eq!(
            reasons[0],
            (1, "non-finite coordinate (NaN or infinity) at vertex 1")
        );
        assert_eq!(reasons[1].0, 2);
        assert!(reasons[1].1.contains("truncated"), "{}", reasons[1].1);
        assert_eq!(reasons[2], (3, "missing geometry"));
    }
}
