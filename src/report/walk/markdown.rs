//! Table 1 of Pina, Serón and Cerezo as Markdown.

use crate::walk::SummaryRow;
use std::fmt::Write as _;

/// The summary as a Markdown table (Pina, Serón and Cerezo, Table 1, plus culling and triangle columns).
pub fn summary_markdown(summary: &[SummaryRow]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| structure | culling | seconds/frame | ratio BqR/structure | cull s/frame | render s/frame | triangles/frame | blocks/frame | buildings/frame | nodes/frame | false culls |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in summary {
        let _ = writeln!(
            s,
            "| {} | {} | {:.6} | {:.3} | {:.6} | {} | {:.0} | {:.1} | {} | {:.1} | {} |",
            r.structure,
            r.mode,
            r.seconds_per_frame,
            r.ratio,
            r.cull_s,
            r.render_s.map(|v| format!("{v:.6}")).unwrap_or("–".into()),
            r.triangles,
            r.blocks,
            r.buildings.map(|v| format!("{v:.1}")).unwrap_or("–".into()),
            r.nodes_visited,
            r.false_culls.map(|v| v.to_string()).unwrap_or("–".into()),
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_row_per_summary_entry() {
        let r = crate::report::walk::tests::record();
        let md = summary_markdown(&r.summary);
        let lines: Vec<&str> = md.lines().collect();
        assert_eq!(lines.len(), 2 + r.summary.len());
        assert!(
            lines[2].starts_with("| bqr | frustum | 0.002010 | 1.000 |"),
            "{}",
            lines[2]
        );
        assert!(lines.iter().all(|l| l.starts_with('|') && l.ends_with('|')));
    }
}
