//! Table 1 of Pina, Serón and Cerezo: averages per structure and culling mode along a route.

use super::{CullMode, FrameRecord};
use crate::index::Structure;
use serde::Serialize;

/// Averages over the route for one structure and mode (Pina, Serón and Cerezo, Table 1).
#[derive(Clone, Debug, Serialize)]
pub struct SummaryRow {
    /// The structure.
    pub structure: Structure,
    /// Culling mode.
    pub mode: CullMode,
    /// Mean seconds per frame.
    pub seconds_per_frame: f64,
    /// Mean culling seconds per frame.
    pub cull_s: f64,
    /// Mean drawing seconds per frame, when drawing.
    pub render_s: Option<f64>,
    /// Reference structure's seconds per frame / this structure's, in the same mode (1 for the
    /// reference; NaN when this structure took no time).
    pub ratio: f64,
    /// Mean triangles drawn per frame.
    pub triangles: f64,
    /// Mean blocks drawn per frame (pages for the scene graph; blocks that survived for the
    /// per-building modes).
    pub blocks: f64,
    /// Mean buildings drawn per frame, in the per-building modes.
    pub buildings: Option<f64>,
    /// Mean nodes visited per frame.
    pub nodes_visited: f64,
    /// Total false culls over the route, when checked.
    pub false_culls: Option<usize>,
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        0.0
    } else {
        s / n as f64
    }
}

/// Table 1 from per-frame records: one row per (structure, mode) in order of first appearance;
/// ratios against `reference` in the same mode (0 when the reference did not run in that mode).
pub fn summarise(rows: &[FrameRecord], reference: Structure) -> Vec<SummaryRow> {
    let mut keys: Vec<(Structure, CullMode)> = Vec::new();
    for r in rows {
        if !keys.contains(&(r.structure, r.mode)) {
            keys.push((r.structure, r.mode));
        }
    }
    let mut out: Vec<SummaryRow> = keys
        .iter()
        .map(|&(s, m)| {
            let sel = || rows.iter().filter(move |r| r.structure == s && r.mode == m);
            let drawn = sel().all(|r| r.render_s.is_some());
            SummaryRow {
                structure: s,
                mode: m,
                seconds_per_frame: mean(sel().map(|r| r.frame_s)),
                cull_s: mean(sel().map(|r| r.cull_s)),
                render_s: drawn.then(|| mean(sel().map(|r| r.render_s.unwrap_or(0.0)))),
                ratio: 0.0,
                triangles: mean(sel().map(|r| r.triangles as f64)),
                blocks: mean(sel().map(|r| r.blocks as f64)),
                buildings: sel()
                    .all(|r| r.buildings.is_some())
                    .then(|| mean(sel().map(|r| r.buildings.unwrap_or(0) as f64))),
                nodes_visited: mean(sel().map(|r| r.stats.nodes_visited as f64)),
                false_culls: sel()
                    .map(|r| r.false_culls)
                    .try_fold(0usize, |a, x| x.map(|x| a + x)),
            }
        })
        .collect();
    let refs: Vec<(CullMode, f64)> = out
        .iter()
        .filter(|r| r.structure == reference)
        .map(|r| (r.mode, r.seconds_per_frame))
        .collect();
    for r in &mut out {
        if let Some((_, t)) = refs.iter().find(|(m, _)| *m == r.mode) {
            r.ratio = if r.seconds_per_frame > 0.0 {
                t / r.seconds_per_frame
            } else {
                f64::NAN
            };
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::index::CullStats;

    fn rec(frame: usize, s: Structure, mode: CullMode, frame_s: f64, tri: u64) -> FrameRecord {
        FrameRecord {
            frame,
            structure: s,
            mode,
            cull_s: frame_s / 2.0,
            render_s: Some(frame_s / 2.0),
            frame_s,
            stats: CullStats {
                nodes_visited: 10,
                ..Default::default()
            },
            blocks: 3,
            triangles: tri,
            draws: 3,
            buildings: None,
            false_culls: Some(frame % 2),
        }
    }

    #[test]
    fn averages_and_ratios_per_structure_and_mode() {
        let f = CullMode::Frustum;
        let o = CullMode::FrustumOcclusion;
        let rows = vec![
            rec(0, Structure::Bqr, f, 0.002, 100),
            rec(0, Structure::Vamsplit, f, 0.004, 100),
            rec(0, Structure::Bqr, o, 0.001, 50),
            rec(1, Structure::Bqr, f, 0.004, 300),
            rec(1, Structure::Vamsplit, f, 0.004, 100),
            rec(1, Structure::Bqr, o, 0.003, 70),
        ];
        let s = summarise(&rows, Structure::Bqr);
        assert_eq!(s.len(), 3);
        let bqr_f = &s[0];
        assert_eq!((bqr_f.structure, bqr_f.mode), (Structure::Bqr, f));
        assert!((bqr_f.seconds_per_frame - 0.003).abs() < 1e-12);
        assert!((bqr_f.triangles - 200.0).abs() < 1e-12);
        assert!((bqr_f.ratio - 1.0).abs() < 1e-12);
        let vam = &s[1];
        assert_eq!(vam.structure, Structure::Vamsplit);
        assert!((vam.ratio - 0.75).abs() < 1e-12, "{}", vam.ratio);
        assert_eq!(vam.false_culls, Some(1));
        let bqr_o = &s[2];
        assert_eq!(bqr_o.mode, o);
        assert!((bqr_o.ratio - 1.0).abs() < 1e-12);
        assert!((bqr_o.render_s.unwrap() - 0.001).abs() < 1e-12);
    }

    #[test]
    fn unchecked_frames_give_no_false_cull_total() {
        let mut r = rec(0, Structure::Flat, CullMode::Frustum, 0.001, 1);
        r.false_culls = None;
        let s = summarise(&[r], Structure::Bqr);
        assert_eq!(s[0].false_culls, None);
        assert_eq!(s[0].ratio, 0.0, "no reference in this mode");
    }
}
