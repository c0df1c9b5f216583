//! The route map: the city in plan view (blocks and building footprints) with the camera path
//! and numbered markers at the kept frames, as inline SVG (no file, no font to load).

use super::context::Plan;
use glam::DVec2;
use std::fmt::Write as _;

/// Width of the map, pixels (the height follows the city's shape, 240 to 900 px).
pub const MAP_WIDTH: f64 = 900.0;

/// The map as an `<svg>` element: footprints in dark grey over light blocks, the path of
/// `cameras` (local frame x, y) in red from a green start, and a numbered marker at each frame
/// of `markers` (frame numbers, indices into `cameras`). `None` when the plan is empty.
pub fn route_map_svg(plan: &Plan, cameras: &[DVec2], markers: &[usize]) -> Option<String> {
    if plan.blocks.is_empty() && plan.footprints.is_empty() {
        return None;
    }
    let pts = plan
        .blocks
        .iter()
        .chain(&plan.footprints)
        .flatten()
        .chain(cameras)
        .filter(|p| p.is_finite());
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for p in pts {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if !(lo.x <= hi.x && lo.y <= hi.y) {
        return None;
    }
    let span = (hi - lo).max(DVec2::splat(1.0));
    let margin = 16.0;
    let scale = (MAP_WIDTH - 2.0 * margin) / span.x;
    let height = (span.y * scale + 2.0 * margin).clamp(240.0, 900.0);
    // Tall cities: shrink to fit the height.
    let scale = scale.min((height - 2.0 * margin) / span.y);
    let px = |p: DVec2| {
        (
            margin + (p.x - lo.x) * scale,
            height - margin - (p.y - lo.y) * scale,
        )
    };
    let path = |rings: &[Vec<DVec2>]| {
        let mut d = String::new();
        for r in rings.iter().filter(|r| r.len() >= 3) {
            for (i, p) in r.iter().enumerate() {
                let (x, y) = px(*p);
                let _ = write!(d, "{}{x:.1} {y:.1}", if i == 0 { "M" } else { "L" });
            }
            d.push('Z');
        }
        d
    };
    let mut s = String::new();
    let _ = write!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" class=\"map\" width=\"{w:.0}\" height=\"{height:.0}\" \
         viewBox=\"0 0 {w:.0} {height:.0}\" role=\"img\" aria-label=\"map of the city with the route\">\
         <rect width=\"100%\" height=\"100%\" fill=\"#fff\"/>\
         <path d=\"{}\" fill=\"#dfe8f1\" stroke=\"#9ab\" stroke-width=\"0.6\"/>\
         <path d=\"{}\" fill=\"#555\" stroke=\"none\"/>",
        path(&plan.blocks),
        path(&plan.footprints),
        w = MAP_WIDTH,
    );
    if !cameras.is_empty() {
        let mut d = String::new();
        for (i, c) in cameras.iter().enumerate() {
            let (x, y) = px(*c);
            let _ = write!(d, "{}{x:.1} {y:.1}", if i == 0 { "M" } else { "L" });
        }
        let _ = write!(
            s,
            "<path class=\"route\" d=\"{d}\" fill=\"none\" stroke=\"#d62728\" stroke-width=\"2.5\" stroke-linejoin=\"round\"/>"
        );
        let (x, y) = px(cameras[0]);
        let _ = write!(
            s,
            "<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"6\" fill=\"#2ca02c\"><title>start</title></circle>"
        );
    }
    for &f in markers {
        let Some(c) = cameras.get(f) else { continue };
        let (x, y) = px(*c);
        let _ = write!(
            s,
            "<g class=\"marker\"><circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"9\" fill=\"#fff\" stroke=\"#d62728\" stroke-width=\"2\"/>\
             <text x=\"{x:.1}\" y=\"{ty:.1}\" font-family=\"sans-serif\" font-size=\"10\" text-anchor=\"middle\">{f}</text></g>",
            ty = y + 3.5
        );
    }
    s.push_str("</svg>");
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_blocks_route_and_markers_inside_the_picture() {
        let sq = |x: f64, y: f64, d: f64| {
            vec![
                DVec2::new(x, y),
                DVec2::new(x + d, y),
                DVec2::new(x + d, y + d),
                DVec2::new(x, y + d),
            ]
        };
        let plan = Plan {
            blocks: vec![sq(0.0, 0.0, 100.0)],
            footprints: vec![sq(10.0, 10.0, 20.0), sq(60.0, 60.0, 20.0)],
        };
        let cams: Vec<DVec2> = (0..5).map(|i| DVec2::new(i as f64 * 25.0, 50.0)).collect();
        let s = route_map_svg(&plan, &cams, &[0, 4, 99]).unwrap();
        assert!(s.starts_with("<svg") && s.ends_with("</svg>"));
        assert_eq!(
            s.matches("class=\"marker\"").count(),
            2,
            "frame 99 has no camera"
        );
        assert!(s.contains(">4</text>"));
        assert_eq!(s.matches("class=\"route\"").count(), 1);
        // Every point of the route lies inside the picture.
        let route = s.split("class=\"route\" d=\"").nth(1).unwrap();
        let route = &route[..route.find('"').unwrap()];
        let nums: Vec<f64> = route
            .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
            .filter_map(|t| t.parse().ok())
            .collect();
        assert_eq!(nums.len(), 10);
        assert!(nums.iter().all(|&v| (0.0..=MAP_WIDTH).contains(&v)));
        assert!(route_map_svg(&Plan::default(), &cams, &[0]).is_none());
    }
}
