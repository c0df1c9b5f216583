//! Parents built from their children's maps (the option; Di Benedetto, §4.3.1
//! builds internal nodes "from the 4 children", BLOCKMAPS.md A.3 and A.4-7) instead of from the
//! source polygons ([`Parents::Children`], `blockwalk blockmaps --parents children`).
//!
//! # The resample
//! Sibling grids are not aligned with the parent's: every node's box is the square around its
//! own footprints. So a parent texel is a **conservative max filter** over the child texels whose
//! solid overlaps it with positive area:
//! - **Child solids exactly.** A child texel with a footprint edge contributes the part of its
//!   square inside its half-plane (what the caster and the error measure draw), a texel without
//!   one its whole square. Parts are clipped to the parent texel; an overlap below 10⁻⁹ of the
//!   parent texel's area counts as touching, not overlapping. Parts outside the parent's square
//!   are left out: the parent square holds every footprint of the node, so they hold only a
//!   child's excess beyond its footprints.
//! - **Height** = the largest height over the overlapping parts, quantised **up** in the parent's
//!   256 levels (BLOCKMAPS.md A.4-4: round up for a map that must contain its input), so the
//!   parent's solid holds the union of the children's solids.
//! - **Footprint edge** of the parent texel: among the axis directions and the child edges' own
//!   (already quantised) normals, the half-plane of least area that holds every vertex of the
//!   clipped parts, offset rounded up as the polygon builder does ([`super::build`] step 1). So
//!   the parent's edges trim the max filter's dilation: a child texel over a corner of a parent
//!   texel fills only that corner's side of the parent texel.
//! - **Roof attributes** (colour, roof normal) from the part that gave the maximum (ties: the
//!   first child in slot order, then row-major texel order).
//! - **Walls**: exposed texels, slices and unfolded column offsets recomputed from the resampled
//!   heights exactly as the polygon builder does (steps 2–3); each column's colours and normal
//!   are read from the wall column of the child texel that gave the maximum (or, when that child
//!   texel has no column, the tallest overlapping child texel that has one), resampled in height
//!   from the child's `[0, zmax_c]` to the parent's `[0, zmax_p]` rows. Difference from the
//!   polygon builder: the attributes are averaged per texel, not per exposed side, and a texel
//!   with no walled child texel at all takes its roof colour and the mean of its exposed sides'
//!   directions as normal.
//! - **Children without a map** (kids of a mapped node drawn as meshes, Cignoni et al., §4's
//!   competitive stop) are built **from the polygons first**, at the same K, and resampled like
//!   the others; they are not kept.
//!
//! # The declared ε
//! With `U` the union of the children's solids and `S` the source's (surfaces with the ground),
//! the triangle inequality for the Hausdorff distance gives
//! `d_H(∂S, ∂P) ≤ d_H(∂S, ∂U) + d_H(∂U, ∂P) ≤ max_c ε_c + r`, with `r = d_H(∂U, ∂P)` the
//! resampling term, **computed from the maps alone** ([`resample_distances`]):
//! - `∂P → ∂U` is at most the parent's voxel diagonal `√(2s² + Δz²)`: a parent column holds a
//!   child part of its height (up to one level), within one texel diagonal of any of its points.
//! - `∂U → ∂P` has no such bound: where a gap narrower than a parent texel between two children's
//!   buildings is filled, the children's ground there lies up to the buildings' height below the
//!   parent's roof. So both are sampled (texel tops, corners, exposed sides, empty ground) with
//!   the exact point-to-map distance of [`super::error::MapColumns::distance`].
//!
//! The parent declares `ε = max(½ voxel diagonal, max_c ε_c + r)` ([`ResampleStats`]); each map
//! is then measured against the source polygons with the measuring twin
//! ([`super::error::measure`]), and the declared value is raised to the measured one should it
//! be lower (counted in [`ResampleStats::measured_over_derived`], so never hidden). `d_H(∂S, ∂U)
//! ≤ max_c ε_c` is the one step taken on trust: a child's surface point may lie inside a
//! sibling's solid; the measurement is what checks it. Leaves are built from the polygons, so
//! ε stays non-increasing downward and boxes nest as with [`Parents::Polygons`].

use super::build::{
    exposed_sides, kept_area, wall_column, wall_slices, BuildOptions, BuildStats, ColumnSums, SIDES,
};
pub use super::build::{Parents, ResampleStats};
use super::error::MapColumns;
use super::layout::{decode_offset, decode_unit, encode_offset_up, BlockMap};
use super::source::Source;
use super::BlockMapError;
use crate::geom::clip::clip_to_box;
use crate::geom::predicates::shoelace;
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// The convex part of a texel's square that its column covers (world xy, counter-clockwise):
/// the whole square, or with a footprint edge the part where `n·q ≤ o` (the rule of
/// `error::cell_parts` and the caster).
fn kept_part(m: &BlockMap, i: u32, j: u32) -> Vec<DVec2> {
    let s = m.texel_m();
    let lo = DVec2::new(m.meta.min[0] + i as f64 * s, m.meta.min[1] + j as f64 * s);
    let sq = [
        lo,
        lo + DVec2::new(s, 0.0),
        lo + DVec2::new(s, s),
        lo + DVec2::new(0.0, s),
    ];
    let Some(e) = m.edge(i, j) else {
        return sq.to_vec();
    };
    let n = DVec2::new(e.n[0] as f64, e.n[1] as f64);
    let c = lo + DVec2::splat(0.5 * s);
    let g = |p: DVec2| n.dot((p - c) / s) - e.o as f64;
    let mut out = Vec::with_capacity(5);
    for q in 0..4 {
        let (a, b) = (sq[q], sq[(q + 1) % 4]);
        let (ga, gb) = (g(a), g(b));
        if ga <= 0.0 {
            out.push(a);
        }
        if (ga <= 0.0) != (gb <= 0.0) {
            out.push(a + (b - a) * (ga / (ga - gb)));
        }
    }
    out
}

/// Height of `m`'s column over `xy` (0 over empty ground and outside the map).
pub fn column_height(m: &BlockMap, xy: DVec2) -> f64 {
    let s = m.texel_m();
    let (i, j) = (
        ((xy.x - m.meta.min[0]) / s).floor() as i64,
        ((xy.y - m.meta.min[1]) / s).floor() as i64,
    );
    let Some(h) = m.texel_height_m(i, j) else {
        return 0.0;
    };
    match m.edge(i as u32, j as u32) {
        None => h,
        Some(e) => {
            let c = DVec2::new(
                m.meta.min[0] + (i as f64 + 0.5) * s,
                m.meta.min[1] + (j as f64 + 0.5) * s,
            );
            let q = (xy - c) / s;
            if e.n[0] as f64 * q.x + e.n[1] as f64 * q.y <= e.o as f64 {
                h
            } else {
                0.0
            }
        }
    }
}

/// Where a parent texel's maximum came from: child slot and child texel.
#[derive(Clone, Copy, Debug)]
struct Src {
    h: f64,
    child: usize,
    i: u32,
    j: u32,
}

/// Builds a map over the square with lower corner `min` (z = 0) and side `side`, heights over
/// `[0, zmax]`, from `children`'s maps by the conservative max filter of the module doc.
/// `opts.k` is the parent's K; `opts.edges`, `opts.min_slice_rows`, `opts.ao` and
/// `opts.ao_radius_m` apply as in [`super::build::build_map`] (the sampling options do not: nothing is
/// sampled). The stats count texels, exposed texels, columns and edges; dropped buildings are
/// the caller's (a building no child holds).
///
/// # Errors
/// [`BlockMapError::BadParameter`] for a K outside 32/64/128, a bad slice minimum or box, or a
/// child whose top is above `zmax`.
pub fn build_from_children(
    children: &[&BlockMap],
    min: DVec2,
    side: f64,
    zmax: f64,
    opts: &BuildOptions,
) -> Result<(BlockMap, BuildStats), BlockMapError> {
    if opts.min_slice_rows < 2 || opts.min_slice_rows > opts.k {
        return Err(BlockMapError::BadParameter(format!(
            "min_slice_rows = {}: need 2..=K",
            opts.min_slice_rows
        )));
    }
    let mut map = BlockMap::empty(opts.k, min.extend(0.0), side, zmax)?;
    for (c, m) in children.iter().enumerate() {
        if m.meta.zmax > zmax * (1.0 + 1e-12) || m.meta.zmin != 0.0 {
            return Err(BlockMapError::BadParameter(format!(
                "child {c} spans z {}..{} m, outside the parent's 0..{zmax} m",
                m.meta.zmin, m.meta.zmax
            )));
        }
    }
    let k = opts.k as usize;
    let s = map.texel_m();
    let mut best: Vec<Option<Src>> = vec![None; k * k];
    // The tallest overlapping child texel that has a wall column (for the walls).
    let mut walled: Vec<Option<Src>> = vec![None; k * k];
    let mut verts: Vec<Vec<DVec2>> = vec![Vec::new(); k * k];
    let mut normals: Vec<Vec<[u8; 2]>> = vec![Vec::new(); k * k];
    let pmax = min + DVec2::splat(side);
    for (c, m) in children.iter().enumerate() {
        let kc = m.k();
        for j in 0..kc {
            for i in 0..kc {
                let code = m.height_code(i, j);
                if code == 0 {
                    continue;
                }
                let h = m.code_height_m(code);
                let part = clip_to_box(&kept_part(m, i, j), min, pmax);
                if part.len() < 3 {
                    continue;
                }
                let (mut lo, mut hi) =
                    (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
                for p in &part {
                    lo = lo.min(*p);
                    hi = hi.max(*p);
                }
                let i0 = (((lo.x - min.x) / s).floor().max(0.0) as usize).min(k - 1);
                let j0 = (((lo.y - min.y) / s).floor().max(0.0) as usize).min(k - 1);
                let i1 = (((hi.x - min.x) / s).floor().max(0.0) as usize).min(k - 1);
                let j1 = (((hi.y - min.y) / s).floor().max(0.0) as usize).min(k - 1);
                let edge = m.edge(i, j).map(|_| {
                    let t = m.texel(m.edge_u(i), j);
                    [t[0], t[1]]
                });
                let wall = m.wall_offset(i, j) != 0;
                for pj in j0..=j1 {
                    for pi in i0..=i1 {
                        let tlo = min + DVec2::new(pi as f64, pj as f64) * s;
                        let cut = clip_to_box(&part, tlo, tlo + DVec2::splat(s));
                        // Touching is not overlapping.
                        if cut.len() < 3 || shoelace(&cut).abs() <= 1e-9 * s * s {
                            continue;
                        }
                        let t = pj * k + pi;
                        let from = Src { h, child: c, i, j };
                        if best[t].is_none_or(|b| h > b.h) {
                            best[t] = Some(from);
                        }
                        if wall && walled[t].is_none_or(|b| h > b.h) {
                            walled[t] = Some(from);
                        }
                        let centre = tlo + DVec2::splat(0.5 * s);
                        verts[t].extend(cut.iter().map(|v| (*v - centre) / s));
                        if let Some(e) = edge {
                            if !normals[t].contains(&e) {
                                normals[t].push(e);
                            }
                        }
                    }
                }
            }
        }
    }
    let mut stats = BuildStats::default();
    // 1. Heights (rounded up), roof attributes and edges.
    const AXES: [[u8; 2]; 4] = [[255, 128], [1, 128], [128, 255], [128, 1]];
    for t in 0..k * k {
        let Some(b) = best[t] else { continue };
        let (i, j) = ((t % k) as u32, (t / k) as u32);
        let mut code = ((b.h / zmax * 255.0).ceil().clamp(1.0, 255.0)) as u8;
        while code < 255 && map.code_height_m(code) < b.h {
            code += 1;
        }
        let m = children[b.child];
        let src = m.texel(b.i, b.j);
        *map.texel_mut(i, j) = [code, 0, src[2], src[3]];
        let roof = m.texel(m.k() + b.i, b.j);
        *map.texel_mut(opts.k + i, j) = [roof[0], roof[1], roof[2], 255];
        stats.filled_texels += 1;
        if !opts.edges {
            continue;
        }
        let mut pick: Option<(f64, [u8; 3])> = None;
        for nb in AXES.iter().chain(normals[t].iter()) {
            let nq = DVec2::new(decode_unit(nb[0]) as f64, decode_unit(nb[1]) as f64);
            if nq == DVec2::ZERO {
                continue;
            }
            let need = verts[t]
                .iter()
                .map(|q| nq.dot(*q))
                .fold(f64::NEG_INFINITY, f64::max);
            // A millionth of a texel for the f32 walk's rounding, as the polygon builder.
            let Some(bo) = encode_offset_up(need + 1e-6) else {
                continue;
            };
            let a = kept_area(nq, decode_offset(bo) as f64);
            if a < 1.0 - 1e-6 && pick.is_none_or(|(pa, _)| a < pa) {
                pick = Some((a, [nb[0], nb[1], bo]));
            }
        }
        if let Some((_, e)) = pick {
            map.set_edge_bytes(i, j, Some(e));
            stats.edge_texels += 1;
        }
    }
    // 2. Exposed texels and their lower sides, and 3. slices and offsets: the polygon
    // builder's steps.
    let exposed = exposed_sides(&map);
    stats.exposed_texels = exposed.iter().filter(|&&b| b != 0).count();
    let orders = wall_slices(&exposed, k, opts);
    let slices = orders.len() as u32;
    map.meta.slices = slices;
    stats.slices = slices;
    let rows = opts.k / slices;
    let colour_rows = (rows - 1) as usize;
    // 4. Wall attributes from the children's columns.
    for (sl, order) in orders.iter().enumerate() {
        let n = order.len();
        if n > 255 {
            stats.shared_columns += n - 255;
        }
        let mut sums = ColumnSums::new(n, colour_rows);
        for (idx, &t) in order.iter().enumerate() {
            let (i, j) = ((t % k) as u32, (t / k) as u32);
            let col = wall_column(idx, n);
            map.texel_mut(i, j)[1] = col;
            let slot = col as usize - 1;
            let from = walled[t].or(best[t]);
            let Some(f) = from else { continue };
            let m = children[f.child];
            let off = m.wall_offset(f.i, f.j);
            if off == 0 {
                // No child column: the roof colour and the exposed sides' mean direction.
                let roof = map.texel(opts.k + i, j);
                let mut dir = DVec3::ZERO;
                for (sd, (di, dj)) in SIDES.iter().enumerate() {
                    if exposed[t] & (1 << sd) != 0 {
                        dir += DVec3::new(*di as f64, *dj as f64, 0.0);
                    }
                }
                sums.nsum[slot] += dir.normalize_or(DVec3::X);
                for r in 0..colour_rows {
                    let acc = sums.colour_mut(slot, r);
                    for ch in 0..3 {
                        acc[ch] += roof[ch] as f64;
                    }
                }
                sums.cnt[slot] += 1;
                continue;
            }
            let u = m.wall_u(off);
            let nt = m.texel(u, m.wall_normal_row(f.j));
            sums.nsum[slot] += DVec3::new(
                decode_unit(nt[0]) as f64,
                decode_unit(nt[1]) as f64,
                decode_unit(nt[2]) as f64,
            );
            for r in 0..colour_rows {
                let acc = sums.colour_mut(slot, r);
                for dz in [0.25f64, 0.75] {
                    let z = (r as f64 + dz) / colour_rows as f64 * zmax;
                    let z01 = (z / m.meta.zmax).clamp(0.0, 1.0) as f32;
                    let ct = m.texel(u, m.wall_color_row(f.j, z01));
                    for ch in 0..3 {
                        acc[ch] += 0.5 * ct[ch] as f64;
                    }
                }
            }
            sums.cnt[slot] += 1;
        }
        sums.write(&mut map, sl as u32 * rows, rows, |mean| {
            mean.map(|v| v.round().clamp(0.0, 255.0) as u8)
        });
    }
    if opts.ao {
        stats.ao = Some(super::ao::compute(&mut map, &exposed, opts.ao_radius_m));
    }
    Ok((map, stats))
}

/// Points on a map's surface (ground included) for the map-to-map distances: each non-empty
/// texel's kept part (centroid and corners at its top) and its sides that face a lower column
/// (midpoint every two texels of height from the lower column to the top, and the ends at the
/// bottom), each empty texel's centre on the ground. Only points inside `[lo, hi]` (xy).
fn surface_samples(m: &BlockMap, lo: DVec2, hi: DVec2) -> Vec<DVec3> {
    let k = m.k();
    let s = m.texel_m();
    let mut out = Vec::new();
    let inside = |p: DVec2| p.x >= lo.x && p.y >= lo.y && p.x <= hi.x && p.y <= hi.y;
    let mut push = |p: DVec3| {
        if inside(p.truncate()) {
            out.push(p);
        }
    };
    for j in 0..k {
        for i in 0..k {
            let Some(h) = m.texel_height_m(i as i64, j as i64) else {
                let c = DVec2::new(
                    m.meta.min[0] + (i as f64 + 0.5) * s,
                    m.meta.min[1] + (j as f64 + 0.5) * s,
                );
                push(c.extend(0.0));
                continue;
            };
            let part = kept_part(m, i, j);
            let centroid = part.iter().copied().sum::<DVec2>() / part.len() as f64;
            push(centroid.extend(h));
            for q in 0..part.len() {
                let (a, b) = (part[q], part[(q + 1) % part.len()]);
                push(a.extend(h));
                let mid = (a + b) * 0.5;
                // Just across the side (outward of a counter-clockwise polygon is its right).
                let out_dir = DVec2::new(b.y - a.y, a.x - b.x).normalize_or_zero() * (1e-6 * s);
                let hn = column_height(m, mid + out_dir);
                if hn >= h {
                    continue;
                }
                let steps = ((h - hn) / (2.0 * s)).ceil().max(1.0) as usize;
                for z in 0..=steps {
                    push(mid.extend(hn + (h - hn) * z as f64 / steps as f64));
                }
                push(a.extend(hn));
                push(b.extend(hn));
            }
        }
    }
    out
}

/// The sampled directed distances between a parent's surface and the union of its children's
/// surfaces (both with the ground), metres: `(parent → children, children → parent)`, over the
/// parent's square. Exact point-to-surface distances at the points of every texel's top,
/// corners and exposed sides and every empty texel's ground (child points that lie inside a
/// sibling's solid are not on the union's surface and are skipped).
pub fn resample_distances(parent: &BlockMap, children: &[&BlockMap]) -> (f64, f64) {
    let lo = DVec2::new(parent.meta.min[0], parent.meta.min[1]);
    let hi = lo + DVec2::splat(parent.meta.side);
    let union_top = |xy: DVec2| {
        children
            .iter()
            .map(|c| column_height(c, xy))
            .fold(0.0, f64::max)
    };
    // Parent → union: the parent holds the union, so its surface points are on or outside it
    // and the distance to the union is the least distance to any child's solid (≤ z: below the
    // ground everything is solid).
    let parent_cols = MapColumns::new(parent);
    let child_cols: Vec<MapColumns> = children.iter().map(|c| MapColumns::new(c)).collect();
    let to = max_pruned(
        surface_samples(parent, lo, hi)
            .into_iter()
            .map(|p| (p, (union_top(p.truncate()) - p.z).abs()))
            .collect(),
        &|p| {
            let mut d = p.z.max(0.0);
            for (c, cols) in children.iter().zip(&child_cols) {
                let cl = DVec2::new(c.meta.min[0], c.meta.min[1]);
                let ch = cl + DVec2::splat(c.meta.side);
                let gap = (cl - p.truncate()).max(p.truncate() - ch).max(DVec2::ZERO);
                if gap.length() < d {
                    d = d.min(cols.distance(p, f64::NEG_INFINITY));
                }
            }
            d
        },
    );
    let mut samples = Vec::new();
    for (ci, c) in children.iter().enumerate() {
        samples.extend(
            surface_samples(c, lo, hi)
                .into_iter()
                .filter(|p| {
                    children
                        .iter()
                        .enumerate()
                        .all(|(o, other)| o == ci || column_height(other, p.truncate()) <= p.z)
                })
                .map(|p| (p, (column_height(parent, p.truncate()) - p.z).abs())),
        );
    }
    let from = max_pruned(samples, &|p| parent_cols.distance(p, f64::NEG_INFINITY));
    (to, from)
}

/// `max` over `points` of `min(bound, exact(point))`, where each point's `bound` is an upper
/// bound of its distance (the vertical distance to the other surface's top over the same xy,
/// a point of that surface): points are taken by decreasing bound, and the exact distance is
/// computed only while a bound exceeds the running maximum (the result is the same as with
/// every point computed).
fn max_pruned(mut points: Vec<(DVec3, f64)>, exact: &(dyn Fn(DVec3) -> f64 + Sync)) -> f64 {
    points.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut best: f64 = 0.0;
    for chunk in points.chunks(256) {
        if chunk[0].1 <= best {
            break;
        }
        let m = chunk
            .par_iter()
            .filter(|q| q.1 > best)
            .map(|q| exact(q.0).min(q.1))
            .reduce(|| 0.0, f64::max);
        best = best.max(m);
    }
    best
}

/// The sampled directed distance from `a`'s surface to `b`'s (both with the ground), metres,
/// over `a`'s square: the largest exact point-to-surface distance
/// ([`super::error::MapColumns::distance`]) from the points of every texel's top, corners and
/// exposed sides and every empty texel's ground.
pub fn directed_distance(a: &BlockMap, b: &BlockMap) -> f64 {
    let lo = DVec2::new(a.meta.min[0], a.meta.min[1]);
    let hi = lo + DVec2::splat(a.meta.side);
    let cols = MapColumns::new(b);
    max_pruned(
        surface_samples(a, lo, hi)
            .into_iter()
            .map(|p| (p, (column_height(b, p.truncate()) - p.z).abs()))
            .collect(),
        &|p| cols.distance(p, f64::NEG_INFINITY),
    )
}

/// The square [`super::build::build_map`] puts around `buildings` (indices into `source.buildings`): lower
/// corner, side and top, or `None` without a building.
pub fn node_square(source: &Source, buildings: &[u32]) -> Option<(DVec2, f64, f64)> {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    let mut zmax: f64 = 0.0;
    let mut any = false;
    for b in buildings
        .iter()
        .filter_map(|&i| source.buildings.get(i as usize).and_then(|b| b.as_ref()))
    {
        lo = lo.min(b.min);
        hi = hi.max(b.max);
        zmax = zmax.max(b.z1);
        any = true;
    }
    if !any {
        return None;
    }
    let ext = hi - lo;
    let side = ext.x.max(ext.y).max(1e-3) * (1.0 + 1e-9);
    let min = (lo + hi) * 0.5 - DVec2::splat(side * 0.5);
    Some((min, side, if zmax > 0.0 { zmax } else { 1.0 }))
}
