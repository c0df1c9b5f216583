//! The conclusion of a walk, stated before its tables: what pays on this route, by how much, and
//! whether the difference is larger than the spread of the frames.

use crate::index::Structure;
use crate::walk::{CullMode, FrameRecord, WalkRecord};
use serde::Serialize;

/// One structure and culling mode's frame times along the route.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Timing {
    /// The structure.
    pub structure: Structure,
    /// The culling mode.
    pub mode: CullMode,
    /// Median seconds per frame.
    pub median_s: f64,
    /// Interquartile range of the seconds per frame.
    pub iqr_s: f64,
}

/// What pays on the route.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdict {
    /// The fastest structure and mode (lowest median frame time).
    pub best: Timing,
    /// The plain case it is compared with: the first structure walked with frustum culling
    /// alone, or the runner-up when that is the fastest.
    pub against: Timing,
    /// `1 − best / against`: the share of the frame time saved.
    pub saving: f64,
    /// True when the difference of the medians is smaller than the mean of the two
    /// interquartile ranges: the runs cannot tell the two apart.
    pub within_noise: bool,
    /// The sentence for the reader.
    pub text: String,
}

/// The median and interquartile range of `v` (sorted in place); `None` when empty.
fn median_iqr(v: &mut [f64]) -> Option<(f64, f64)> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let q = |p: f64| {
        let x = p * (v.len() - 1) as f64;
        let (i, f) = (x.floor() as usize, x.fract());
        v[i] + (v[(i + 1).min(v.len() - 1)] - v[i]) * f
    };
    Some((q(0.5), q(0.75) - q(0.25)))
}

/// The frame times of every structure and mode, in order of first appearance.
pub fn timings(frames: &[FrameRecord]) -> Vec<Timing> {
    let mut keys: Vec<(Structure, CullMode)> = Vec::new();
    for r in frames {
        if !keys.contains(&(r.structure, r.mode)) {
            keys.push((r.structure, r.mode));
        }
    }
    keys.into_iter()
        .filter_map(|(structure, mode)| {
            let mut v: Vec<f64> = frames
                .iter()
                .filter(|r| r.structure == structure && r.mode == mode)
                .map(|r| r.frame_s)
                .collect();
            median_iqr(&mut v).map(|(median_s, iqr_s)| Timing {
                structure,
                mode,
                median_s,
                iqr_s,
            })
        })
        .collect()
}

/// The conclusion of `frames`: the fastest structure and mode against the plain case (see
/// [`Verdict`]); `None` with fewer than two structure–mode pairs.
pub fn verdict(frames: &[FrameRecord]) -> Option<Verdict> {
    let t = timings(frames);
    if t.len() < 2 {
        return None;
    }
    let best = *t.iter().min_by(|a, b| a.median_s.total_cmp(&b.median_s))?;
    let plain = t
        .iter()
        .find(|x| x.mode == CullMode::Frustum)
        .copied()
        .unwrap_or(t[0]);
    let against = if plain == best {
        *t.iter()
            .filter(|x| **x != best)
            .min_by(|a, b| a.median_s.total_cmp(&b.median_s))?
    } else {
        plain
    };
    let saving = if against.median_s > 0.0 {
        1.0 - best.median_s / against.median_s
    } else {
        0.0
    };
    let within_noise = against.median_s - best.median_s < 0.5 * (best.iqr_s + against.iqr_s);
    let name = |x: &Timing| format!("{} with {}", x.structure, x.mode);
    let text = format!(
        "{} is fastest on this route: {:.3} ms per frame (median), {:.1} % less than {} ({:.3} ms); {}",
        name(&best),
        best.median_s * 1e3,
        saving * 100.0,
        name(&against),
        against.median_s * 1e3,
        if within_noise {
            format!(
                "within the noise of the frames (interquartile ranges {:.3} and {:.3} ms): the runs cannot tell them apart",
                best.iqr_s * 1e3,
                against.iqr_s * 1e3
            )
        } else {
            format!(
                "larger than the frames' spread (interquartile ranges {:.3} and {:.3} ms)",
                best.iqr_s * 1e3,
                against.iqr_s * 1e3
            )
        }
    );
    Some(Verdict {
        best,
        against,
        saving,
        within_noise,
        text,
    })
}

/// The lines a reader sees first: the verdict, and the far field's when one was given.
pub fn conclusion(record: &WalkRecord) -> Vec<String> {
    let mut out: Vec<String> = verdict(&record.frames)
        .map(|v| v.text)
        .into_iter()
        .collect();
    if let Some(f) = record.far_summary() {
        out.push(match (f.used, f.frame_time_ratio_vs_mesh, &f.reason) {
            (true, Some(r), _) => format!(
                "The far field ({}) is drawn: hybrid frames take {:.2} × the mesh-only frames' time (τ = {} px).",
                f.representation, r, f.tau_px
            ),
            (true, None, _) => format!(
                "The far field ({}) is drawn (τ = {} px).",
                f.representation, f.tau_px
            ),
            (false, _, Some(why)) => {
                format!("The far field ({}) is left out: {why}.", f.representation)
            }
            (false, _, None) => format!("The far field ({}) is left out.", f.representation),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::index::CullStats;

    fn frame(structure: Structure, mode: CullMode, frame_s: f64) -> FrameRecord {
        FrameRecord {
            frame: 0,
            structure,
            mode,
            cull_s: 0.0,
            render_s: None,
            frame_s,
            stats: CullStats::default(),
            blocks: 0,
            buildings: None,
            triangles: 0,
            draws: 0,
            false_culls: None,
        }
    }

    fn walk(a: &[f64], b: &[f64]) -> Vec<FrameRecord> {
        a.iter()
            .map(|&s| frame(Structure::Bqr, CullMode::Frustum, s))
            .chain(
                b.iter()
                    .map(|&s| frame(Structure::Bqr, CullMode::FrustumOcclusion, s)),
            )
            .collect()
    }

    #[test]
    fn a_clear_win_is_named_with_its_saving() {
        let f = walk(&[0.020, 0.021, 0.019, 0.020], &[0.010, 0.011, 0.010, 0.009]);
        let v = verdict(&f).unwrap();
        assert_eq!(v.best.mode, CullMode::FrustumOcclusion);
        assert_eq!(v.against.mode, CullMode::Frustum);
        assert!((v.saving - 0.5).abs() < 0.03, "{v:?}");
        assert!(!v.within_noise);
        assert!(
            v.text.contains("larger than the frames' spread"),
            "{}",
            v.text
        );
    }

    #[test]
    fn a_tie_within_the_spread_says_so() {
        let f = walk(&[0.010, 0.030, 0.020, 0.025], &[0.012, 0.028, 0.019, 0.024]);
        let v = verdict(&f).unwrap();
        assert!(v.within_noise, "{v:?}");
        assert!(v.text.contains("within the noise"), "{}", v.text);
        // The plain case fastest: compared with the runner-up.
        let f = walk(&[0.010, 0.010, 0.010], &[0.020, 0.020, 0.020]);
        let v = verdict(&f).unwrap();
        assert_eq!(v.best.mode, CullMode::Frustum);
        assert_eq!(v.against.mode, CullMode::FrustumOcclusion);
        // One pair only: nothing to compare.
        assert!(verdict(&walk(&[0.01], &[])).is_none());
    }

    #[test]
    fn median_and_iqr_interpolate() {
        let (m, q) = median_iqr(&mut [4.0, 1.0, 3.0, 2.0]).unwrap();
        assert_eq!(m, 2.5);
        assert_eq!(q, 1.5);
        assert!(median_iqr(&mut []).is_none());
    }
}
