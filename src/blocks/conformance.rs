//! A conformance runner for block faces, in the manner of JTS's test runner that geo runs: our
//! faces against a reference set (momepy / shapely `polygonize(union_all(lines))`), with a
//! checked-in list of the mismatches we expect, each with the reason it is there.
//!
//! [`compare_faces`] pairs every reference face with the face of ours it overlaps most (candidates
//! from an R-tree on the faces' bounds, intersection-over-union from `geo`'s boolean operations).
//! Faces of a planar subdivision do not overlap, so a pair with IoU above ½ is unique both ways.
//! Every face that is not in a pair with IoU ≥ `min_iou` is a [`Mismatch`]: a reference face with
//! no partner ([`MismatchKind::Missing`]), a face of ours with no partner ([`MismatchKind::Extra`]),
//! or a pair below `min_iou` ([`MismatchKind::LowIou`]).
//!
//! A mismatch is named by a point strictly inside its face (the reference face, or ours for an
//! extra face), rounded to the millimetre: it does not depend on the order of faces, and stays
//! inside the face when a vertex moves a little. [`ExpectedList::check`] fails (returns a non-empty
//! [`Verdict`]) when a listed mismatch is gone, when one that is not listed appears, or when a
//! listed IoU has moved by more than [`IOU_SLACK`].

use crate::geom::predicates::{point_in_polygon, polygon_area, robust_interior_point, Location};
use geo::BooleanOps;
use geo_types::{Coord, Polygon};
use rstar::{primitives::GeomWithData, primitives::Rectangle, RTree, AABB};
use serde::{Deserialize, Serialize};
use std::fmt;

/// How far a listed IoU may move before the list must be updated.
pub const IOU_SLACK: f64 = 0.005;

/// The kind of a mismatch between our faces and the reference.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MismatchKind {
    /// A reference face that no face of ours matches with IoU above ½.
    Missing,
    /// A face of ours that matches no reference face with IoU above ½.
    Extra,
    /// A reference face and our face paired (IoU above ½) but below the required IoU.
    LowIou,
}

impl fmt::Display for MismatchKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Missing => "missing",
            Self::Extra => "extra",
            Self::LowIou => "low_iou",
        })
    }
}

/// A reference face paired with one of ours.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FacePair {
    /// Index in the reference faces.
    pub reference: usize,
    /// Index in our faces.
    pub ours: usize,
    /// Intersection over union.
    pub iou: f64,
}

/// One face that does not conform.
#[derive(Clone, Debug, PartialEq)]
pub struct Mismatch {
    /// What is wrong.
    pub kind: MismatchKind,
    /// A point strictly inside the face that names it (the reference face for `Missing` and
    /// `LowIou`, ours for `Extra`), rounded to 1 mm.
    pub at: [f64; 2],
    /// The best IoU this face has with any face of the other set (0 when none overlaps).
    pub iou: f64,
    /// Area of the face, in the coordinates' units squared.
    pub area: f64,
    /// Index of the reference face involved, if any (the best overlap for `Extra`).
    pub reference: Option<usize>,
    /// Index of our face involved, if any (the best overlap for `Missing`).
    pub ours: Option<usize>,
}

/// The result of [`compare_faces`].
#[derive(Clone, Debug, Default)]
pub struct Comparison {
    /// Number of our faces.
    pub ours: usize,
    /// Number of reference faces.
    pub reference: usize,
    /// Pairs with IoU above ½ (including those below `min_iou`).
    pub pairs: Vec<FacePair>,
    /// Every mismatch, sorted by kind then position.
    pub mismatches: Vec<Mismatch>,
    /// Reference faces whose interior point could not be found (degenerate input).
    pub degenerate: usize,
}

impl Comparison {
    /// Pairs with IoU ≥ `min_iou`.
    pub fn matched(&self, min_iou: f64) -> usize {
        self.pairs.iter().filter(|p| p.iou >= min_iou).count()
    }
    /// The smallest IoU over all pairs (1 when there are none).
    pub fn min_pair_iou(&self) -> f64 {
        self.pairs.iter().map(|p| p.iou).fold(1.0, f64::min)
    }
}

type Env = GeomWithData<Rectangle<[f64; 2]>, usize>;

fn bounds(p: &Polygon<f64>) -> ([f64; 2], [f64; 2]) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for c in &p.exterior().0 {
        lo = [lo[0].min(c.x), lo[1].min(c.y)];
        hi = [hi[0].max(c.x), hi[1].max(c.y)];
    }
    (lo, hi)
}

/// Intersection over union of two polygons, given their areas.
pub fn iou(a: &Polygon<f64>, area_a: f64, b: &Polygon<f64>, area_b: f64) -> f64 {
    let i: f64 = a.intersection(b).0.iter().map(polygon_area).sum();
    let u = area_a + area_b - i;
    if u > 0.0 {
        (i / u).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

fn key(p: &Polygon<f64>) -> Option<[f64; 2]> {
    robust_interior_point(p).map(|c| [(c.x * 1e3).round() / 1e3, (c.y * 1e3).round() / 1e3])
}

/// For each face of `from`, the face of `to` with the highest IoU (and that IoU), if any
/// overlaps. Candidates overlap in bounds, and are skipped when even a perfect overlap could not
/// beat the best IoU so far (IoU ≤ smaller area / larger area).
fn best_overlaps(
    from: &[Polygon<f64>],
    from_area: &[f64],
    to: &[Polygon<f64>],
    to_area: &[f64],
) -> Vec<Option<(usize, f64)>> {
    let tree = RTree::bulk_load(
        to.iter()
            .enumerate()
            .map(|(i, p)| {
                let (lo, hi) = bounds(p);
                Env::new(Rectangle::from_corners(lo, hi), i)
            })
            .collect(),
    );
    from.iter()
        .zip(from_area)
        .map(|(p, &a)| {
            let (lo, hi) = bounds(p);
            let mut cands: Vec<usize> = tree
                .locate_in_envelope_intersecting(&AABB::from_corners(lo, hi))
                .map(|c| c.data)
                .collect();
            // Most promising first: the closest in area.
            let ratio = |j: usize| a.min(to_area[j]) / a.max(to_area[j]);
            cands.sort_by(|&x, &y| ratio(y).total_cmp(&ratio(x)).then(x.cmp(&y)));
            let mut best: Option<(usize, f64)> = None;
            for j in cands {
                let bound = ratio(j);
                if best.is_some_and(|(_, b)| b >= bound) {
                    break;
                }
                let v = iou(p, a, &to[j], to_area[j]);
                if v > 0.0 && best.is_none_or(|(_, b)| v > b) {
                    best = Some((j, v));
                }
            }
            best
        })
        .collect()
}

/// Compares our faces with the reference faces (see the module docs). Faces are polygons in the
/// same coordinates; `min_iou` is the IoU a pair needs to conform (e.g. 0.99).
pub fn compare_faces(
    ours: &[Polygon<f64>],
    reference: &[Polygon<f64>],
    min_iou: f64,
) -> Comparison {
    let ours_area: Vec<f64> = ours.iter().map(polygon_area).collect();
    let ref_area: Vec<f64> = reference.iter().map(polygon_area).collect();
    let from_ref = best_overlaps(reference, &ref_area, ours, &ours_area);
    let mut mismatches = Vec::new();
    let mut degenerate = 0;
    let mut pairs = Vec::new();
    let mut paired = vec![false; ours.len()];
    for (r, best) in from_ref.iter().enumerate() {
        let (kind, o, v) = match *best {
            Some((o, v)) if v > 0.5 => {
                paired[o] = true;
                pairs.push(FacePair {
                    reference: r,
                    ours: o,
                    iou: v,
                });
                if v >= min_iou {
                    continue;
                }
                (MismatchKind::LowIou, Some(o), v)
            }
            Some((o, v)) => (MismatchKind::Missing, Some(o), v),
            None => (MismatchKind::Missing, None, 0.0),
        };
        match key(&reference[r]) {
            Some(at) => mismatches.push(Mismatch {
                kind,
                at,
                iou: v,
                area: ref_area[r],
                reference: Some(r),
                ours: o,
            }),
            None => degenerate += 1,
        }
    }
    let unpaired: Vec<usize> = (0..ours.len()).filter(|&o| !paired[o]).collect();
    let sub: Vec<Polygon<f64>> = unpaired.iter().map(|&o| ours[o].clone()).collect();
    let sub_area: Vec<f64> = unpaired.iter().map(|&o| ours_area[o]).collect();
    for (k, best) in best_overlaps(&sub, &sub_area, reference, &ref_area)
        .into_iter()
        .enumerate()
    {
        let o = unpaired[k];
        let (r, v) = best.map_or((None, 0.0), |(r, v)| (Some(r), v));
        // A degenerate face of ours (no interior) has no point to name it by; it still counts.
        mismatches.push(Mismatch {
            kind: MismatchKind::Extra,
            at: key(&ours[o]).unwrap_or([f64::NAN; 2]),
            iou: v,
            area: ours_area[o],
            reference: r,
            ours: Some(o),
        });
    }
    let mut cmp = Comparison {
        ours: ours.len(),
        reference: reference.len(),
        pairs,
        mismatches,
        degenerate,
    };
    cmp.mismatches.sort_by(|a, b| {
        (a.kind as u8)
            .cmp(&(b.kind as u8))
            .then(a.at[0].total_cmp(&b.at[0]))
            .then(a.at[1].total_cmp(&b.at[1]))
    });
    cmp
}

/// One expected mismatch, as written in a conformance list.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExpectedMismatch {
    /// The kind of mismatch.
    pub kind: MismatchKind,
    /// A point inside the face (see [`Mismatch::at`]).
    pub at: [f64; 2],
    /// The measured IoU, required for `low_iou` (checked to within [`IOU_SLACK`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iou: Option<f64>,
    /// Why this face differs, found by looking at the geometry (never empty).
    pub reason: String,
}

/// A checked-in list of expected mismatches (TOML: `min_iou = 0.99` and `[[mismatch]]` tables).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExpectedList {
    /// The IoU a pair needs to conform.
    pub min_iou: f64,
    /// The mismatches we expect.
    #[serde(default)]
    pub mismatch: Vec<ExpectedMismatch>,
}

/// What [`ExpectedList::check`] found wrong; empty when the comparison conforms to the list.
#[derive(Clone, Debug, Default)]
pub struct Verdict {
    /// Mismatches that the list does not name.
    pub unexpected: Vec<Mismatch>,
    /// Listed mismatches that no longer happen (the face now matches, or changed kind).
    pub gone: Vec<ExpectedMismatch>,
    /// Listed `low_iou` mismatches whose IoU moved by more than [`IOU_SLACK`]: (listed, now).
    pub moved: Vec<(ExpectedMismatch, f64)>,
    /// Listed entries without a reason, or `low_iou` without an IoU.
    pub malformed: Vec<ExpectedMismatch>,
}

impl Verdict {
    /// True when nothing is wrong.
    pub fn is_empty(&self) -> bool {
        self.unexpected.is_empty()
            && self.gone.is_empty()
            && self.moved.is_empty()
            && self.malformed.is_empty()
    }
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for m in &self.unexpected {
            writeln!(
                f,
                "unexpected {} at [{:.3}, {:.3}] (IoU {:.4}, area {:.1}); to list it:",
                m.kind, m.at[0], m.at[1], m.iou, m.area
            )?;
            writeln!(f, "{}", entry_toml(m))?;
        }
        for e in &self.gone {
            writeln!(
                f,
                "listed {} at [{:.3}, {:.3}] no longer happens ({})",
                e.kind, e.at[0], e.at[1], e.reason
            )?;
        }
        for (e, now) in &self.moved {
            writeln!(
                f,
                "listed low_iou at [{:.3}, {:.3}]: IoU {:.4} listed, {now:.4} now",
                e.at[0],
                e.at[1],
                e.iou.unwrap_or(f64::NAN)
            )?;
        }
        for e in &self.malformed {
            writeln!(
                f,
                "listed {} at [{:.3}, {:.3}] needs a reason (and an iou for low_iou)",
                e.kind, e.at[0], e.at[1]
            )?;
        }
        Ok(())
    }
}

/// A mismatch as a `[[mismatch]]` TOML table, with a reason still to be written.
pub fn entry_toml(m: &Mismatch) -> String {
    let iou = if m.kind == MismatchKind::LowIou {
        format!("iou = {:.4}\n", m.iou)
    } else {
        String::new()
    };
    format!(
        "[[mismatch]]\nkind = \"{}\"\nat = [{:.3}, {:.3}]\n{iou}reason = \"TODO\"",
        m.kind, m.at[0], m.at[1]
    )
}

/// Errors reading a conformance list.
#[derive(Debug, thiserror::Error)]
pub enum ListError {
    /// The file could not be read.
    #[error("{file}: {source}")]
    Io {
        /// The list's path.
        file: String,
        /// The error.
        source: std::io::Error,
    },
    /// The file is not a valid list.
    #[error("{file}: {source}")]
    Parse {
        /// The list's path.
        file: String,
        /// The error.
        source: toml::de::Error,
    },
}

impl ExpectedList {
    /// Parses a list from TOML text; `file` names it in errors.
    ///
    /// # Errors
    /// [`ListError::Parse`] for text that is not a list (unknown fields are refused).
    pub fn from_toml(text: &str, file: &str) -> Result<Self, ListError> {
        toml::from_str(text).map_err(|source| ListError::Parse {
            file: file.to_string(),
            source,
        })
    }

    /// Reads a list from a TOML file.
    ///
    /// # Errors
    /// [`ListError`] when the file cannot be read or parsed.
    pub fn read(path: &std::path::Path) -> Result<Self, ListError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ListError::Io {
            file: file.clone(),
            source,
        })?;
        Self::from_toml(&text, &file)
    }

    /// Checks a comparison (made with this list's `min_iou`) against the list. `ours` and
    /// `reference` are the faces given to [`compare_faces`]: a listed point names a mismatch when
    /// it lies inside (or on the boundary of) that mismatch's face, or within 1 cm of its point.
    pub fn check(
        &self,
        cmp: &Comparison,
        ours: &[Polygon<f64>],
        reference: &[Polygon<f64>],
    ) -> Verdict {
        let mut v = Verdict::default();
        let mut taken = vec![false; cmp.mismatches.len()];
        for e in &self.mismatch {
            if e.reason.trim().is_empty()
                || e.reason.trim() == "TODO"
                || (e.kind == MismatchKind::LowIou) != e.iou.is_some()
            {
                v.malformed.push(e.clone());
            }
            let p = Coord {
                x: e.at[0],
                y: e.at[1],
            };
            let found = cmp.mismatches.iter().enumerate().find(|(k, m)| {
                if taken[*k] || m.kind != e.kind {
                    return false;
                }
                let face = match m.kind {
                    MismatchKind::Extra => m.ours.map(|o| &ours[o]),
                    _ => m.reference.map(|r| &reference[r]),
                };
                (m.at[0] - p.x).hypot(m.at[1] - p.y) <= 0.01
                    || face.is_some_and(|f| point_in_polygon(p, f) != Location::Outside)
            });
            match found {
                Some((k, m)) => {
                    taken[k] = true;
                    if let Some(listed) = e.iou {
                        if (listed - m.iou).abs() > IOU_SLACK {
                            v.moved.push((e.clone(), m.iou));
                        }
                    }
                }
                None => v.gone.push(e.clone()),
            }
        }
        v.unexpected = cmp
            .mismatches
            .iter()
            .zip(&taken)
            .filter(|(_, &t)| !t)
            .map(|(m, _)| m.clone())
            .collect();
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo_types::polygon;

    fn square(x: f64, y: f64, s: f64) -> Polygon<f64> {
        polygon![(x: x, y: y), (x: x + s, y: y), (x: x + s, y: y + s), (x: x, y: y + s)]
    }

    #[test]
    fn kinds_of_mismatch() {
        // Reference: four unit-10 squares. Ours: the first two, the third shifted by 2 (IoU 8/12),
        // the fourth missing, and an extra square elsewhere.
        let reference = vec![
            square(0., 0., 10.),
            square(10., 0., 10.),
            square(20., 0., 10.),
            square(30., 0., 10.),
        ];
        let ours = vec![
            square(10., 0., 10.),
            square(0., 0., 10.),
            polygon![(x: 22., y: 0.), (x: 32., y: 0.), (x: 32., y: 10.), (x: 22., y: 10.)],
            square(100., 0., 10.),
        ];
        let c = compare_faces(&ours, &reference, 0.99);
        assert_eq!((c.ours, c.reference), (4, 4));
        assert_eq!(c.matched(0.99), 2);
        let kinds: Vec<MismatchKind> = c.mismatches.iter().map(|m| m.kind).collect();
        assert_eq!(
            kinds,
            vec![
                MismatchKind::Missing,
                MismatchKind::Extra,
                MismatchKind::LowIou
            ]
        );
        let low = &c.mismatches[2];
        assert!((low.iou - 8.0 / 12.0).abs() < 1e-12);
        assert_eq!((low.reference, low.ours), (Some(2), Some(2)));
        // The missing square overlaps our shifted one by 2/18.
        let missing = &c.mismatches[0];
        assert_eq!(missing.reference, Some(3));
        assert!((missing.iou - 2.0 / 18.0).abs() < 1e-12);
        assert_eq!(c.mismatches[1].ours, Some(3));

        let list = ExpectedList::from_toml(
            r#"
min_iou = 0.99
[[mismatch]]
kind = "missing"
at = [31.0, 1.0]
reason = "test"
[[mismatch]]
kind = "extra"
at = [105.0, 5.0]
reason = "test"
[[mismatch]]
kind = "low_iou"
at = [25.0, 5.0]
iou = 0.6667
reason = "test"
"#,
            "t.toml",
        )
        .unwrap();
        let v = list.check(&c, &ours, &reference);
        assert!(v.is_empty(), "{v}");

        // A listed mismatch that no longer happens, an unlisted one, a moved IoU, a missing reason.
        let mut l2 = list.clone();
        l2.mismatch[1].at = [55.0, 5.0];
        l2.mismatch[2].iou = Some(0.7);
        l2.mismatch[0].reason = String::new();
        let v = l2.check(&c, &ours, &reference);
        assert_eq!(v.gone.len(), 1);
        assert_eq!(v.unexpected.len(), 1);
        assert_eq!(v.unexpected[0].kind, MismatchKind::Extra);
        assert_eq!(v.moved.len(), 1);
        assert_eq!(v.malformed.len(), 1);
        assert!(v.to_string().contains("kind = \"extra\""));
    }

    #[test]
    fn unknown_fields_are_refused() {
        let e = ExpectedList::from_toml("min_iou = 0.99\nfoo = 1\n", "x.toml").unwrap_err();
        assert!(matches!(e, ListError::Parse { .. }));
        assert!(e.to_string().starts_with("x.toml:"));
    }

    #[test]
    fn identical_sets_conform() {
        let a: Vec<Polygon<f64>> = (0..20).map(|i| square(i as f64 * 10.0, 0., 10.)).collect();
        let c = compare_faces(&a, &a, 0.999);
        assert!(c.mismatches.is_empty());
        assert_eq!(c.matched(0.999), 20);
        assert_eq!(c.min_pair_iou(), 1.0);
    }
}
