//! What pays on a route: occlusion culling, and the per-building test inside the surviving
//! blocks, decided from the reference structure's frames.

use super::{BuildingsDecision, CullMode, FrameRecord, OcclusionDecision};
use crate::index::Structure;

/// Per block culling mode walked with and without the per-building test: whether the test paid
/// for the reference structure (drawn frames: mean frame time; nothing drawn: triangles).
pub(super) fn buildings_decisions(
    frames: &[FrameRecord],
    reference: Structure,
) -> Vec<BuildingsDecision> {
    let per = |m: CullMode| -> Option<(f64, f64, f64, bool, f64)> {
        let v: Vec<&FrameRecord> = frames
            .iter()
            .filter(|r| r.structure == reference && r.mode == m)
            .collect();
        (!v.is_empty()).then(|| {
            let n = v.len() as f64;
            (
                v.iter().map(|r| r.frame_s).sum::<f64>() / n,
                v.iter().map(|r| r.cull_s).sum::<f64>() / n,
                v.iter().map(|r| r.triangles as f64).sum::<f64>() / n,
                v.iter().all(|r| r.render_s.is_some()),
                v.iter().map(|r| r.draws as f64).sum::<f64>() / n,
            )
        })
    };
    let mut out = Vec::new();
    for base in [CullMode::Frustum, CullMode::FrustumOcclusion] {
        let (Some((bs, bc, bt, bd, bn)), Some((ws, wc, wt, wd, wn))) =
            (per(base), per(base.with_buildings()))
        else {
            continue;
        };
        let drawn = bd && wd;
        let pays = if drawn { ws < bs } else { wt < bt };
        let saved = if bt > 0.0 { 1.0 - wt / bt } else { 0.0 };
        let note = format!(
            "per-building test after {base} ({reference}): {:.0} → {:.0} triangles per frame ({:.1} % fewer) in {:.1} → {:.1} draw calls, cull {:.3} → {:.3} ms{}: {}",
            bt,
            wt,
            saved * 100.0,
            bn,
            wn,
            bc * 1e3,
            wc * 1e3,
            if drawn {
                format!(", frame {:.3} → {:.3} ms", bs * 1e3, ws * 1e3)
            } else {
                String::new()
            },
            match (pays, drawn) {
                (true, true) => "it pays (faster frames): keep it",
                (false, true) => "it does not pay here (no faster frames): leave it out",
                (true, false) => "it removes triangles (nothing drawn to time)",
                (false, false) => "it removes nothing: leave it out",
            }
        );
        out.push(BuildingsDecision {
            mode: base,
            blocks_s: bs,
            buildings_s: ws,
            blocks_cull_s: bc,
            buildings_cull_s: wc,
            blocks_triangles: bt,
            buildings_triangles: wt,
            blocks_draws: bn,
            buildings_draws: wn,
            drawn,
            pays,
            note,
        });
    }
    out
}

/// Whether occlusion culling saved time on the route: the reference structure's mean frame time
/// with and without it, and the blocks it dropped (none when only one mode was walked).
pub(super) fn occlusion_decision(
    frames: &[FrameRecord],
    reference: Structure,
) -> Option<OcclusionDecision> {
    let per = |m: CullMode| -> Option<(f64, f64)> {
        let v: Vec<&FrameRecord> = frames
            .iter()
            .filter(|r| r.structure == reference && r.mode == m)
            .collect();
        (!v.is_empty()).then(|| {
            let n = v.len() as f64;
            (
                v.iter().map(|r| r.frame_s).sum::<f64>() / n,
                v.iter().map(|r| r.blocks as f64).sum::<f64>() / n,
            )
        })
    };
    let (fs, fb) = per(CullMode::Frustum)?;
    let (os, ob) = per(CullMode::FrustumOcclusion)?;
    let dropped = fb - ob;
    let saves = os < fs && dropped > 0.0;
    let note = if dropped <= 0.0 {
        format!(
            "occlusion culling drops no block on this route ({:.3} ms per frame with it, {:.3} ms without; the difference is noise): leave it out (--occlusion off)",
            os * 1e3,
            fs * 1e3
        )
    } else if saves {
        format!(
            "occlusion culling pays on this route: {:.3} ms vs {:.3} ms per frame, {dropped:.1} blocks dropped per frame",
            os * 1e3,
            fs * 1e3
        )
    } else {
        format!(
            "occlusion culling saves nothing on this route: {:.3} ms per frame with it vs {:.3} ms without, though it drops {dropped:.1} blocks per frame: leave it out (--occlusion off)",
            os * 1e3,
            fs * 1e3
        )
    };
    Some(OcclusionDecision {
        frustum_s: fs,
        occlusion_s: os,
        blocks_dropped: dropped,
        saves,
        note,
    })
}
