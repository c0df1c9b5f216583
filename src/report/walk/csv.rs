//! The walk's per-frame table as CSV.

use crate::walk::WalkRecord;
use std::fmt::Write as _;

/// The CSV header, one column per [`crate::walk::FrameRecord`] field and the camera.
pub const HEADER: &str = "frame,structure,mode,cull_s,render_s,frame_s,nodes_visited,plane_tests,blocks,buildings,triangles,false_culls,x,y,z,yaw_deg,pitch_deg";

/// Per-frame records as CSV (empty cells for values not measured).
pub fn frames_csv(record: &WalkRecord) -> String {
    let mut s = String::from(HEADER);
    s.push('\n');
    for r in &record.frames {
        let c = &record.cameras[r.frame];
        let _ = writeln!(
            s,
            "{},{},{},{:.9},{},{:.9},{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3}",
            r.frame,
            r.structure,
            r.mode,
            r.cull_s,
            r.render_s.map(|v| format!("{v:.9}")).unwrap_or_default(),
            r.frame_s,
            r.stats.nodes_visited,
            r.stats.plane_tests,
            r.blocks,
            r.buildings.map(|v| v.to_string()).unwrap_or_default(),
            r.triangles,
            r.false_culls.map(|v| v.to_string()).unwrap_or_default(),
            c.position.x,
            c.position.y,
            c.position.z,
            c.yaw.to_degrees(),
            c.pitch.to_degrees(),
        );
    }
    s
}

/// The header of [`far_csv`].
pub const FAR_HEADER: &str = "frame,mode,select_s,render_s,frame_s,mesh_frame_s,mesh_blocks,mesh_triangles,far_nodes,far_blocks,far_pixels,nodes_visited,coverage_error,psnr_db,silhouette_px,silhouette_ratio,beyond_bound,beyond_bound_subpixel,beyond_bound_thin,popping_px,popping_colour_px";

/// The hybrid frames as CSV (empty cells for values not measured).
pub fn far_csv(record: &WalkRecord) -> String {
    let mut s = String::from(FAR_HEADER);
    s.push('\n');
    let opt = |v: Option<f64>| v.map(|v| format!("{v:.9}")).unwrap_or_default();
    let count = |v: Option<u64>| v.map(|v| v.to_string()).unwrap_or_default();
    for r in &record.far {
        let i = r.image.as_ref();
        let _ = writeln!(
            s,
            "{},{},{:.9},{},{:.9},{:.9},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.frame,
            r.mode,
            r.select_s,
            opt(r.render_s),
            r.frame_s,
            r.mesh_frame_s,
            r.mesh_blocks,
            r.mesh_triangles,
            r.far_nodes,
            r.far_blocks,
            r.far_pixels.map(|v| v.to_string()).unwrap_or_default(),
            r.stats.nodes_visited,
            opt(i.map(|i| i.coverage_error)),
            opt(i.map(|i| i.psnr_db)),
            opt(i.map(|i| i.silhouette_px)),
            opt(i.and_then(|i| i.silhouette_ratio_max)),
            count(i.and_then(|i| i.beyond_bound)),
            count(i.and_then(|i| i.beyond_bound_subpixel)),
            count(i.and_then(|i| i.beyond_bound_thin)),
            i.map(|i| i.popping_px.to_string()).unwrap_or_default(),
            i.map(|i| i.popping_colour_px.to_string())
                .unwrap_or_default(),
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_per_record_with_every_column() {
        let r = crate::report::walk::tests::record();
        let csv = frames_csv(&r);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines[0], HEADER);
        assert_eq!(lines.len(), 1 + r.frames.len());
        let cols = HEADER.split(',').count();
        for l in &lines[1..] {
            assert_eq!(l.split(',').count(), cols, "{l}");
        }
        assert!(lines[1].starts_with("0,bqr,frustum,"), "{}", lines[1]);
        assert!(
            lines[2].starts_with("0,bqr,frustum+occlusion,"),
            "{}",
            lines[2]
        );
    }
}
