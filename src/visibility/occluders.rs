//! Occluders of a city: facade top edges, per block, with collinear runs merged along block
//! fronts (Willmott et al., §3.2.5).

use super::shadow::Occluder;
use crate::blocks::{BlockId, BlockLayout};
use crate::city::extrude::try_extrude_building;
use crate::city::City;
use crate::geom::predicates::ring_signed_area;
use crate::geom::Aabb3;
use glam::{DVec2, DVec3};

/// How occluders are extracted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OccluderOptions {
    /// Facade runs are merged when the gap between them along their common line is at most this
    /// many metres. A gap is an opening one could see through, so any value above 0 is an
    /// approximation; the default only closes rounding-sized gaps between touching buildings.
    pub merge_gap: f64,
    /// Edges are collinear when their directions differ by at most this angle (radians) and
    /// their lines are at most `collinear_offset` metres apart.
    pub collinear_angle: f64,
    /// See `collinear_angle`, metres.
    pub collinear_offset: f64,
    /// Edges shorter than this (metres) are not kept on their own (they may still join a run).
    pub min_length: f64,
}

impl Default for OccluderOptions {
    fn default() -> Self {
        Self {
            merge_gap: 1e-3,
            collinear_angle: 1e-4,
            collinear_offset: 1e-3,
            min_length: 1.0,
        }
    }
}

/// The occluders of one block and its bounds.
#[derive(Clone, Debug)]
pub struct BlockOccluders {
    /// The block.
    pub block: BlockId,
    /// Box around the block's buildings, local frame (footprints × [0, max height]).
    pub aabb: Aabb3,
    /// Facade edges and merged facade runs.
    pub occluders: Vec<Occluder>,
}

/// Facade top edges of every building of every block, local frame (heights are world z: the
/// building's base plus its height).
///
/// Only exterior rings are used. A roof edge at height `h` occludes only if the wall below it is
/// solid down to the ground (on terrain: down to the building's base, under which the ground
/// rises at least as high along the whole footprint, since the base is the lowest ground under
/// it), so buildings with `min_height_m > 0` (passages, overhangs, bridges)
/// give no occluders; they are still culled like any other geometry. Edges of the same block whose
/// lines coincide and that point the same way (a block front of touching buildings) are merged
/// into one run at the smallest of their heights, which is still a solid wall; the original edges
/// are kept too, at their own heights.
///
/// A building whose extrusion fails ([`try_extrude_building`]) is drawn as nothing, so it gives
/// no occluder (it still counts in its block's box, which only makes the box larger). The
/// extrusions are tried here, in parallel; [`extract_drawn`] takes the answer instead.
pub fn extract(city: &City, layout: &BlockLayout, opts: &OccluderOptions) -> Vec<BlockOccluders> {
    use rayon::prelude::*;
    let drawn: Vec<bool> = city
        .buildings
        .par_iter()
        .map(|b| try_extrude_building(b, &city.frame).is_ok())
        .collect();
    extract_drawn(city, layout, opts, &drawn)
}

/// As [`extract`], with `drawn[i]` saying whether building `i` has a mesh (a building past the
/// end of `drawn` counts as not drawn).
pub fn extract_drawn(
    city: &City,
    layout: &BlockLayout,
    opts: &OccluderOptions,
    drawn: &[bool],
) -> Vec<BlockOccluders> {
    layout
        .blocks
        .iter()
        .map(|block| {
            let mut aabb = Aabb3::EMPTY;
            let mut edges = Vec::new();
            for bid in &block.buildings {
                let Some(b) = city.buildings.get(bid.0 as usize) else {
                    continue;
                };
                if !(b.height_m.is_finite()) {
                    continue;
                }
                for c in b.footprint.exterior().coords() {
                    let p = city.frame.to_local_xy(*c);
                    aabb = aabb
                        .including(DVec3::new(p.x, p.y, b.base_m))
                        .including(DVec3::new(p.x, p.y, b.top_z().max(b.base_m)));
                }
                if b.min_height_m > 0.0
                    || b.height_m <= 0.0
                    || !drawn.get(bid.0 as usize).copied().unwrap_or(false)
                {
                    continue;
                }
                let ring: Vec<DVec2> = b
                    .footprint
                    .exterior()
                    .coords()
                    .map(|c| city.frame.to_local_xy(*c))
                    .collect();
                let ccw = ring_signed_area(&ring) >= 0.0;
                for w in ring.windows(2) {
                    let (a, b2) = if ccw { (w[0], w[1]) } else { (w[1], w[0]) };
                    if a != b2 {
                        edges.push(Occluder {
                            a,
                            b: b2,
                            height: b.top_z(),
                        });
                    }
                }
            }
            let mut occluders = merge_runs(&edges, opts);
            occluders.extend(edges.iter().filter(|e| e.length() >= opts.min_length));
            BlockOccluders {
                block: block.id,
                aabb,
                occluders,
            }
        })
        .collect()
}

/// Merged runs of collinear, same-direction edges (only runs of two or more edges).
///
/// What holds for a run: it lies on the line of one of its edges `e0`; every edge merged into
/// The smallest side of a terrain occluder cell, metres ([`terrain_occluders`]).
pub const TERRAIN_OCCLUDER_CELL_M: f64 = 25.0;

/// The block id terrain occluders carry ([`terrain_occluders`]): no block of a layout has it.
pub const TERRAIN_OCCLUDER_BLOCK: BlockId = BlockId(u32::MAX);

/// Terrain occluders (Willmott et al., §3.2, with the terrain's min-filtered level as the
/// occluder): the cells of the finest level of `tree` whose side is at least `cell_m`, each a
/// column from below up to the lowest full-resolution sample under it
/// ([`crate::terrain::TerrainTree::occluder_cells`]), as four walls at that height; one group per
/// tile of that level, in `frame`'s local coordinates. The terrain as drawn at full resolution
/// (the oracle's) never goes below these walls' tops over their cells, and is solid below, so
/// their shadows are conservative. Collinear walls along a row of cells are merged into runs
/// at the lowest of their heights, as facade runs are ([`merge_runs`]).
pub fn terrain_occluders(
    tree: &crate::terrain::TerrainTree,
    frame: &crate::city::LocalFrame,
    cell_m: f64,
    opts: &OccluderOptions,
) -> Vec<BlockOccluders> {
    let spacing = tree.terrain().spacing();
    let cell = spacing.x.min(spacing.y).max(f64::MIN_POSITIVE);
    // The finest level whose cells are at least `cell_m` (the root's when none is that coarse).
    let level = (0..=tree.depth())
        .rev()
        .find(|&l| {
            tree.node_ids()
                .find(|&n| tree.level(n) == l)
                .is_some_and(|n| tree.stride(n) as f64 * cell >= cell_m)
        })
        .unwrap_or(0);
    tree.node_ids()
        .filter(|&n| tree.level(n) == level)
        .filter_map(|n| {
            let mut edges = Vec::new();
            let mut aabb = Aabb3::EMPTY;
            for (b, z) in tree.occluder_cells(n) {
                let lo = frame.to_local_f64(DVec3::new(b[0], b[1], z));
                let hi = frame.to_local_f64(DVec3::new(b[2], b[3], z));
                aabb = aabb.including(lo).including(hi);
                // Counter-clockwise: the outward side is on the right of each edge.
                let ring = [
                    DVec2::new(lo.x, lo.y),
                    DVec2::new(hi.x, lo.y),
                    DVec2::new(hi.x, hi.y),
                    DVec2::new(lo.x, hi.y),
                    DVec2::new(lo.x, lo.y),
                ];
                for w in ring.windows(2) {
                    edges.push(Occluder {
                        a: w[0],
                        b: w[1],
                        height: lo.z,
                    });
                }
            }
            if edges.is_empty() {
                return None;
            }
            let ext = tree.extent(n);
            aabb = aabb.including(frame.to_local_f64(ext.min));
            let mut occluders = merge_runs(&edges, opts);
            occluders.extend(edges.iter().filter(|e| e.length() >= opts.min_length));
            Some(BlockOccluders {
                block: TERRAIN_OCCLUDER_BLOCK,
                aabb,
                occluders,
            })
        })
        .collect()
}

/// it points the same way within `collinear_angle` and has both ends within `collinear_offset`
/// of that line, measured at the ends themselves (not through the lines' distances from the
/// local origin, which let two facades 0.1–0.5 m apart far from the origin pass as one line);
/// consecutive edges along the run overlap or leave a gap of at most `merge_gap`; the run's
/// height is the lowest of its edges'. So the walls below the run are solid up to its height
/// within `collinear_offset` of it, apart from gaps of at most `merge_gap`; the culler adds
/// `collinear_offset` to the plan slack of every shadow ([`super::Slack`]) and treats gaps of
/// `merge_gap` (1 mm by default) as closed.
pub fn merge_runs(edges: &[Occluder], opts: &OccluderOptions) -> Vec<Occluder> {
    // Key each edge by its direction angle and its line's signed offset, then sweep; the
    // offset only orders the sweep, membership is decided at the walls.
    let mut keyed: Vec<(f64, f64, usize)> = edges
        .iter()
        .enumerate()
        .filter(|(_, e)| e.length() > 0.0)
        .map(|(i, e)| {
            let d = (e.b - e.a).normalize();
            let n = DVec2::new(-d.y, d.x);
            (d.y.atan2(d.x), n.dot(e.a), i)
        })
        .collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut out = Vec::new();
    let mut used = vec![false; keyed.len()];
    for s in 0..keyed.len() {
        if used[s] {
            continue;
        }
        // Group: all edges parallel and on the same line as `s` (angle sweep stays local).
        let (ang, _, ei) = keyed[s];
        let mut group = vec![ei];
        used[s] = true;
        let (la, ld) = (edges[ei].a, (edges[ei].b - edges[ei].a).normalize());
        let off_line = |p: DVec2| ld.perp_dot(p - la).abs();
        for t in s + 1..keyed.len() {
            if keyed[t].0 - ang > opts.collinear_angle {
                break;
            }
            let e = edges[keyed[t].2];
            if !used[t]
                && off_line(e.a) <= opts.collinear_offset
                && off_line(e.b) <= opts.collinear_offset
            {
                used[t] = true;
                group.push(keyed[t].2);
            }
        }
        if group.len() < 2 {
            continue;
        }
        let e0 = edges[ei];
        let d = (e0.b - e0.a).normalize();
        let mut iv: Vec<(f64, f64, f64)> = group
            .iter()
            .map(|&k| {
                let e = edges[k];
                (d.dot(e.a - e0.a), d.dot(e.b - e0.a), e.height)
            })
            .collect();
        iv.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut k = 0;
        while k < iv.len() {
            let (start, mut end, mut h) = iv[k];
            let mut parts = 1;
            let mut m = k + 1;
            while m < iv.len() && iv[m].0 <= end + opts.merge_gap {
                end = end.max(iv[m].1);
                h = h.min(iv[m].2);
                parts += 1;
                m += 1;
            }
            if parts >= 2 && end - start >= opts.min_length {
                out.push(Occluder {
                    a: e0.a + d * start,
                    b: e0.a + d * end,
                    height: h,
                });
            }
            k = m;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collinear_touching_edges_merge_at_the_lower_height() {
        let e = |x0: f64, x1: f64, h: f64| Occluder {
            a: DVec2::new(x0, 0.0),
            b: DVec2::new(x1, 0.0),
            height: h,
        };
        let edges = [
            e(0.0, 10.0, 20.0),
            e(10.0, 25.0, 12.0),
            e(30.0, 40.0, 30.0),
            e(40.0, 30.0, 9.0),
        ];
        let runs = merge_runs(&edges, &OccluderOptions::default());
        assert_eq!(runs.len(), 1, "{runs:?}");
        assert_eq!(runs[0].a, DVec2::new(0.0, 0.0));
        assert_eq!(runs[0].b, DVec2::new(25.0, 0.0));
        assert_eq!(runs[0].height, 12.0);
        // With a 5 m gap allowed, the third edge joins (the fourth points the other way).
        let runs = merge_runs(
            &edges,
            &OccluderOptions {
                merge_gap: 5.0,
                ..Default::default()
            },
        );
        assert_eq!(runs.len(), 1);
        assert_eq!(runs[0].b, DVec2::new(40.0, 0.0));
    }

    #[test]
    fn nearly_collinear_walls_far_from_the_origin_do_not_merge() {
        // Two facades 5 km from the local origin, their lines 0.3 m apart at the walls but
        // turned by 6e-5 rad so that their distances from the origin agree within 1 mm: the
        // lines cross near the origin, not at the walls.
        let ang = 6e-5f64;
        let dir = DVec2::new(ang.cos(), ang.sin());
        let n = DVec2::new(-dir.y, dir.x);
        let e1 = Occluder {
            a: DVec2::new(5000.0, 0.0),
            b: DVec2::new(5010.0, 0.0),
            height: 10.0,
        };
        let a2 = DVec2::new(5010.0, 0.3);
        let e2 = Occluder {
            a: a2,
            b: a2 + dir * 10.0,
            height: 10.0,
        };
        // The origin-offset key would call them one line (|0.3 − 5010·6e-5| = 0.0006 m).
        let off2 = n.dot(e2.a);
        assert!(off2.abs() <= 1e-3, "{off2}");
        assert!(merge_runs(&[e1, e2], &OccluderOptions::default()).is_empty());
        // The same facades in line at the walls merge.
        let e3 = Occluder {
            a: DVec2::new(5010.0, 0.0),
            b: DVec2::new(5020.0, 0.0),
            height: 8.0,
        };
        let runs = merge_runs(&[e1, e3], &OccluderOptions::default());
        assert_eq!(runs.len(), 1);
        assert_eq!(runs[0].height, 8.0);
    }

    #[test]
    fn a_building_whose_extrusion_fails_casts_no_shadow() {
        use crate::blocks::{Block, BlockKind, BlockSource};
        use crate::city::{Building, BuildingId, CityReport, HeightSource, LocalFrame};
        use geo_types::{coord, LineString, Polygon};
        // A square and a bow tie (its ring crosses itself: the extrusion refuses it).
        let ring = |pts: &[(f64, f64)]| {
            Polygon::new(
                LineString(pts.iter().map(|&(x, y)| coord! { x: x, y: y }).collect()),
                vec![],
            )
        };
        let square = ring(&[
            (0.0, 0.0),
            (10.0, 0.0),
            (10.0, 10.0),
            (0.0, 10.0),
            (0.0, 0.0),
        ]);
        let bowtie = ring(&[
            (20.0, 0.0),
            (30.0, 10.0),
            (30.0, 0.0),
            (20.0, 10.0),
            (20.0, 0.0),
        ]);
        let building = |i: u32, footprint| Building {
            id: BuildingId(i),
            source_id: format!("t:{i}"),
            footprint,
            height_m: 12.0,
            min_height_m: 0.0,
            base_m: 0.0,
            height_source: HeightSource::Height,
            attributes: Default::default(),
        };
        let city = City {
            name: "t".into(),
            transform: blockwalk_importers::Crs::Unknown.metric_transform([0.0, 0.0]),
            frame: LocalFrame {
                origin: DVec3::ZERO,
            },
            buildings: vec![building(0, square.clone()), building(1, bowtie.clone())],
            streets: vec![],
            parcels: vec![],
            report: CityReport::default(),
            terrain: None,
        };
        assert!(try_extrude_building(&city.buildings[0], &city.frame).is_ok());
        assert!(try_extrude_building(&city.buildings[1], &city.frame).is_err());
        let layout = BlockLayout {
            blocks: vec![
                Block {
                    id: BlockId(0),
                    kind: BlockKind::Block,
                    polygon: square,
                    buildings: vec![BuildingId(0)],
                },
                Block {
                    id: BlockId(1),
                    kind: BlockKind::Block,
                    polygon: bowtie,
                    buildings: vec![BuildingId(1)],
                },
            ],
            source: BlockSource::Streets,
            street_edges: vec![],
            dangles: 0,
        };
        let occ = extract(&city, &layout, &OccluderOptions::default());
        assert_eq!(occ[0].occluders.len(), 4, "{:?}", occ[0].occluders);
        assert!(occ[1].occluders.is_empty(), "{:?}", occ[1].occluders);
        // Its box still counts (larger boxes are only hidden less often).
        assert!(!occ[1].aabb.is_empty());
    }

    #[test]
    fn parallel_edges_on_other_lines_do_not_merge() {
        let edges = [
            Occluder {
                a: DVec2::new(0.0, 0.0),
                b: DVec2::new(10.0, 0.0),
                height: 5.0,
            },
            Occluder {
                a: DVec2::new(10.0, 0.5),
                b: DVec2::new(20.0, 0.5),
                height: 5.0,
            },
        ];
        assert!(merge_runs(&edges, &OccluderOptions::default()).is_empty());
    }
}
