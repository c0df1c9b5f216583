//! Construction of one BlockMap from the source prisms (seed 000 §3.3, seed 002 §4.3.2), on the
//! CPU, deterministic.
//!
//! 1. **Height map and roof attributes** (seed 002 §4.3.2 "HeightMap and Roof/Ground Surface
//!    Attributes"): a top-down orthographic render of the prisms with one sample per texel
//!    centre. For vertical prisms that render is scan conversion of the footprints with the
//!    highest roof winning ([`top_down_owners`]), done directly on the footprints (the oracle's
//!    triangle rasteriser through an orthographic `clip_from_world` gives the same picture up to
//!    centres on an edge, and a test checks it, but costs a projection per triangle). The
//!    winning building gives the texel its height (its exact `height_m`, quantised to the
//!    nearest of 256 levels; a building lower than half a level gets level 1, so that it never
//!    vanishes as "empty") and its roof colour.
//!
//!    **Supersampling** (deviation, [`BuildOptions::fill_samples`], default 4×4 samples per
//!    texel, [`top_down_owners_supersampled`]): the building with most samples fills the texel
//!    when at least half of them hit a building (area-preserving), or, when that building is
//!    narrower than a texel, at least a quarter ([`BuildOptions::fill_share`]). Why: one sample
//!    per texel keeps a share of texels equal to the share of ground the buildings cover, but a
//!    building seen obliquely covers more of the image than its footprint (its walls), and
//!    where buildings are narrower than a texel (the upper levels: 149 m texels at the root of
//!    the 80k generated city) the centre-sampled root map covered 106 pixels of a view where
//!    the meshes cover 258 (coverage error 1.24 %). Measured on that view: centre 1.24 %; 4×4
//!    with a ½ share everywhere 1.36 %; a ¼ share everywhere 0.54 % (but Astana's wide blocks
//!    then grow by up to ¾ texel and reach 1.07 %); the rule above 0.54 % on the 80k root,
//!    Astana max 0.91 % (centre: 0.88 %), Helsinki max 0.29 % with ε max 25.1 m (centre: 0.31 %,
//!    26.4 m). A rule filling a texel when its content, seen from 45°, covers at least half of
//!    the filled texel's projection (`f + w·h/s ≥ ½(1 + h/s)`, `f` the covered share, `w` the
//!    share of sample rows and columns touched) was measured against it with every map checked
//!    (`blockwalk blockmaps … --check 1000`): generated 5k seed 7 max 1.56 % against 1.92 %, but
//!    Bubeneč 0.25 % against 0.12 %, Helsinki 0.31 % against 0.29 %, and twice the buildings
//!    vanished (15,221 thin features against 8,001 on seed 7), so it was not kept.
//!
//!    **Footprint edges inside a texel** (blockwalk's addition, [`BuildOptions::edges`], on by
//!    default; layout in [`super::layout`]): every texel a footprint edge crosses stores the
//!    half-plane that covers the footprints' part of the texel with the least excess area,
//!    chosen among the supporting lines of the edges crossing it (normal quantised, offset then
//!    rounded up with the quantised normal, so it stays conservative); a texel that no such line
//!    cuts (a concave corner, two buildings on opposite sides) stays a whole square. A boundary
//!    texel the sampling above left empty but a footprint overlaps is filled too when a
//!    half-plane cuts it with less excess than the footprint area it adds (owner: the building
//!    with most area in it), so that footprint slivers are no longer lost. One that no line
//!    cuts (a gap between two buildings narrower than a texel) or whose half-plane is more than
//!    twice the footprint area in it (a building much smaller than the texel, at the upper
//!    levels) stays empty: filling those tripled the coverage error of the Astana fly-over
//!    (1.2 → 4.8 %). So every footprint point the whole-texel map covered is still covered,
//!    and more. Why: whole texels put a band of wrong pixels about a quarter texel wide on
//!    every footprint edge (coverage error 1.2–5.6 % at τ = 1 where buildings are a
//!    few pixels across). Measured (README, fly-overs at τ = 1): Helsinki K = 32 1.48 → 0.67 %,
//!    K = 64 0.92 → 0.41 %, Astana 1.23 → 1.15 %, the 80k city 5.75 → 4.21 %.
//! 2. **Exposed texels** (seed 000 §3.1): a texel with at least one 4-neighbour lower than
//!    itself (outside the map counts as empty). An edge texel is exposed on at least the side
//!    its edge's normal faces most, so that its edge wall gets a facade column.
//! 3. **Wall parametrisation** (seed 002 §4.3.2 "Walls Parametrization"): per slice, exposed
//!    texels get offsets 1, 2, … in the order of an unfolding of the boundaries (seed 000 §3.3:
//!    a walk that goes on to an exposed 8-neighbour when it can, so adjacent boundary texels get
//!    adjacent columns). When a slice needs more than 255 columns the slice count doubles, down
//!    to slices of 2 rows; past that, neighbouring texels along the unfolding share columns
//!    (seed 000 §3.3 scales the wall region along u), and the shared ones are counted.
//! 4. **Wall attributes** (seed 000 §3.3, Fig. 4b): per exposed side, the facade of the texel's
//!    building nearest to the side's midpoint gives the outward normal; the sides' normals and
//!    colours are averaged into the column. Deviation: seed 002 samples walls from many views on
//!    the GPU; for LoD1 prisms with one facade colour per height the nearest facade edge gives
//!    the same attributes without rendering.
//! 5. **AO** (optional, [`BuildOptions::ao`]): horizon-based over the height map, see [`super::ao`].

use super::colors;
use super::layout::{encode_unit, BlockMap};
pub use super::source::{Source, SourceBuilding};
use super::BlockMapError;
use crate::city::BuildingId;
use crate::geom::clip::clip_to_box_into;
use crate::geom::predicates::shoelace;
use glam::{DVec2, DVec3};
use serde::Serialize;

/// The owner of a texel no building covers.
pub const SKY: u32 = u32::MAX;

/// Largest ambient-occlusion radius accepted, metres. Each azimuth is marched in at most
/// [`super::ao::MAX_STEPS`] samples, so past this radius a step (over 12 m) jumps across streets
/// and whole buildings, and the occlusion fades towards nothing instead of growing.
pub const MAX_AO_RADIUS_M: f64 = 200.0;

/// Construction options.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BuildOptions {
    /// Height-map side K (32, 64, 128).
    pub k: u32,
    /// Smallest slice height in rows (≥ 2, seed 002 §4.3.2).
    pub min_slice_rows: u32,
    /// Samples per texel side for the height map: 1 samples the texel centre (seed 002's
    /// top-down render), `n > 1` takes `n × n` samples and fills the texel when at least
    /// [`BuildOptions::fill_share`] of them hit a building.
    pub fill_samples: u32,
    /// Share of a texel's samples that must hit a building to fill it (with `fill_samples > 1`).
    pub fill_share: f64,
    /// Compute ambient occlusion ([`super::ao`]); off leaves the A channels at 255 (open sky).
    pub ao: bool,
    /// How far AO looks for occluders, metres (at least one texel is always looked at).
    pub ao_radius_m: f64,
    /// Store a footprint edge (half-plane) in each texel a footprint edge crosses (see the
    /// module doc); off builds whole-texel columns only.
    pub edges: bool,
    /// With [`BuildOptions::edges`], store a second half-plane where two hold a texel's
    /// footprint part more closely than one (a convex corner, a building narrower than the
    /// texel; `layout` doc).
    pub two_edges: bool,
}

impl BuildOptions {
    /// Checks the options before anything is built.
    ///
    /// # Errors
    /// [`BlockMapError::BadParameter`], naming the option, for a K other than 32, 64 or 128, a
    /// slice minimum outside 2..=K, `fill_samples` outside 1..=8, `fill_share` outside (0, 1],
    /// or (with AO) an AO radius that is not a finite number of metres > 0.
    pub fn validate(&self) -> Result<(), BlockMapError> {
        let bad = |m: String| Err(BlockMapError::BadParameter(m));
        if !super::layout::ALLOWED_K.contains(&self.k) {
            let why = if self.k.is_power_of_two() {
                "out of range"
            } else {
                "not a power of two"
            };
            return bad(format!("k = {}: {why}; expected 32, 64 or 128", self.k));
        }
        if self.min_slice_rows < 2 || self.min_slice_rows > self.k {
            return bad(format!(
                "min_slice_rows = {}: need 2..=K",
                self.min_slice_rows
            ));
        }
        if !(1..=8).contains(&self.fill_samples) {
            return bad(format!(
                "fill_samples = {}: expected 1 to 8",
                self.fill_samples
            ));
        }
        if !(self.fill_share > 0.0 && self.fill_share <= 1.0) {
            return bad(format!(
                "fill_share = {}: expected a share in (0, 1]",
                self.fill_share
            ));
        }
        if !(self.ao_radius_m.is_finite()
            && self.ao_radius_m > 0.0
            && self.ao_radius_m <= MAX_AO_RADIUS_M)
        {
            return bad(format!(
                "ao_radius_m = {}: expected a radius in (0, {MAX_AO_RADIUS_M}] m",
                self.ao_radius_m
            ));
        }
        Ok(())
    }
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            k: 64,
            min_slice_rows: 2,
            fill_samples: 4,
            fill_share: 0.25,
            ao: false,
            ao_radius_m: 30.0,
            edges: true,
            two_edges: true,
        }
    }
}

/// What one construction counted.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct BuildStats {
    /// Buildings given.
    pub buildings: usize,
    /// Texels with a building.
    pub filled_texels: usize,
    /// Exposed texels (a 4-neighbour lower).
    pub exposed_texels: usize,
    /// Exposed texels that share a column with a neighbour along the unfolding (overflow past
    /// the smallest slice).
    pub shared_columns: usize,
    /// Slices.
    pub slices: u32,
    /// Buildings no texel centre falls in (they vanish from the map).
    pub dropped_buildings: Vec<BuildingId>,
    /// The ambient occlusion computed, when asked for.
    pub ao: Option<super::ao::AoStats>,
    /// Texels with a footprint edge (half-plane).
    pub edge_texels: usize,
    /// Of those, texels with a second half-plane.
    pub edge2_texels: usize,
    /// Of those, texels filled only because a footprint overlaps them (the sampling left them
    /// empty).
    pub edge_filled_texels: usize,
    /// For a map built from its children's maps, what the resample counted.
    pub from_children: Option<ResampleStats>,
}

/// How the maps of inner quadtree nodes are built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Parents {
    /// From the source polygons, as every leaf (the default: each map its own measured bound).
    #[default]
    Polygons,
    /// From the children's maps, max-filtered ([`super::children`]).
    Children,
}

impl std::str::FromStr for Parents {
    type Err = BlockMapError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "polygons" => Ok(Self::Polygons),
            "children" => Ok(Self::Children),
            _ => Err(BlockMapError::BadParameter(format!(
                "parents '{s}': expected 'polygons' or 'children'"
            ))),
        }
    }
}

/// What building a parent from its children counted ([`super::children`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ResampleStats {
    /// Children's maps resampled (kept maps and the ones built for kids without a map).
    pub children: usize,
    /// Of those, kids without a map, built from the polygons first.
    pub from_polygons: usize,
    /// Largest declared ε of the children, metres.
    pub child_eps_max_m: f64,
    /// Sampled directed distance from the parent's surface to the children's union, metres.
    pub to_children_m: f64,
    /// Sampled directed distance from the children's union surface to the parent's, metres.
    pub from_children_m: f64,
    /// `max(½ voxel diagonal, child_eps_max_m + max(to, from))`, metres.
    pub derived_eps_m: f64,
    /// The error measured against the polygons exceeded the derived ε (then declared instead).
    pub measured_over_derived: bool,
}

/// Builds the BlockMap of `buildings` (indices into `source.buildings`) over the square that
/// holds their footprints (side = the longer side of their box).
///
/// # Errors
/// [`BlockMapError::BadParameter`] for a K outside 32/64/128, a bad slice minimum, or no building.
pub fn build_map(
    source: &Source,
    buildings: &[u32],
    opts: &BuildOptions,
) -> Result<(BlockMap, Vec<u32>, BuildStats), BlockMapError> {
    opts.validate()?;
    let bs: Vec<&SourceBuilding> = buildings
        .iter()
        .filter_map(|&i| source.buildings.get(i as usize).and_then(|b| b.as_ref()))
        .collect();
    if bs.is_empty() {
        return Err(BlockMapError::BadParameter("no building to map".into()));
    }
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    // Heights span the lowest ground under the node's buildings (0 without terrain) to the
    // highest roof; the terrain itself is drawn beside the maps, not in them.
    let (mut zmin, mut zmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for b in &bs {
        lo = lo.min(b.min);
        hi = hi.max(b.max);
        zmin = zmin.min(b.ground).min(b.z0);
        zmax = zmax.max(b.z1);
    }
    let ext = hi - lo;
    // A square base (seed 002 §4.2.1) centred on the footprints' box.
    let side = ext.x.max(ext.y).max(1e-3) * (1.0 + 1e-9);
    let min = (lo + hi) * 0.5 - DVec2::splat(side * 0.5);
    let zmax = if zmax > zmin { zmax } else { zmin + 1.0 };
    let mut map = BlockMap::empty(opts.k, min.extend(zmin), side, zmax)?;
    let k = opts.k as usize;

    // 1. Top-down orthographic sampling at the texel centres: the highest roof over a centre
    //    wins (the depth test of a top-down render).
    let owner = top_down_owners_supersampled(
        &bs,
        min,
        map.texel_m(),
        k,
        opts.fill_samples as usize,
        opts.fill_share,
    );
    let mut stats = BuildStats {
        buildings: bs.len(),
        ..BuildStats::default()
    };
    let index_of = |id: u32| source.buildings[id as usize].as_ref();
    let mut owner = owner;
    let (edge_bytes, edge2_bytes) = if opts.edges {
        let e = footprint_edges(&bs, min, map.texel_m(), k, &mut owner, opts.two_edges);
        stats.edge_filled_texels = e.filled;
        (e.bytes, e.bytes2)
    } else {
        (vec![None; k * k], vec![None; k * k])
    };
    for j in 0..k {
        for i in 0..k {
            let id = owner[j * k + i];
            if id == SKY {
                continue;
            }
            let Some(b) = index_of(id) else { continue };
            stats.filled_texels += 1;
            let code = (((b.z1 - zmin) / (zmax - zmin) * 255.0)
                .round()
                .clamp(1.0, 255.0)) as u8;
            let t = map.texel_mut(i as u32, j as u32);
            t[0] = code;
            let c = colors::to_bytes(colors::roof_rgb(&b.style));
            *map.texel_mut((k + i) as u32, j as u32) = [c[0], c[1], c[2], 255];
        }
    }
    for (t, e) in edge_bytes.iter().enumerate() {
        if e.is_some() && owner[t] != SKY {
            map.set_edge_bytes((t % k) as u32, (t / k) as u32, *e);
            stats.edge_texels += 1;
            if edge2_bytes[t].is_some() {
                map.set_edge2_bytes((t % k) as u32, (t / k) as u32, edge2_bytes[t]);
                stats.edge2_texels += 1;
            }
        }
    }
    let mut seen: Vec<u32> = owner.iter().copied().filter(|&o| o != SKY).collect();
    seen.sort_unstable();
    seen.dedup();
    for b in &bs {
        if seen.binary_search(&b.id.0).is_err() {
            stats.dropped_buildings.push(b.id);
        }
    }

    // 2. Exposed texels and their lower sides.
    let exposed = exposed_sides(&map);
    stats.exposed_texels = exposed.iter().filter(|&&b| b != 0).count();

    // 3. Slices and offsets.
    let orders = wall_slices(&exposed, k, opts);
    let slices = orders.len() as u32;
    map.meta.slices = slices;
    stats.slices = slices;
    let rows = opts.k / slices;
    let colour_rows = rows - 1;
    for (s, order) in orders.iter().enumerate() {
        let n = order.len();
        if n > 255 {
            stats.shared_columns += n - 255;
        }
        let mut sums = ColumnSums::new(n, colour_rows as usize);
        for (idx, &t) in order.iter().enumerate() {
            let (i, j) = (t % k, t / k);
            let c = wall_column(idx, n);
            map.texel_mut(i as u32, j as u32)[1] = c;
            let id = owner[t];
            let Some(b) = index_of(id) else { continue };
            let slot = c as usize - 1;
            let s_m = map.texel_m();
            let centre = min + DVec2::new((i as f64 + 0.5) * s_m, (j as f64 + 0.5) * s_m);
            for (sidx, (di, dj)) in SIDES.iter().enumerate() {
                if exposed[t] & (1 << sidx) == 0 {
                    continue;
                }
                let dir = DVec2::new(*di as f64, *dj as f64);
                let mid = centre + dir * (0.5 * s_m);
                let (n, u) = nearest_facade(b, mid).unwrap_or((dir, 0.0));
                sums.nsum[slot] += n.extend(0.0);
                // The side's colour: the facade around the nearest point, averaged over the
                // texel's width (two u samples) and each row's height (two z samples).
                for r in 0..colour_rows as usize {
                    let acc = sums.colour_mut(slot, r);
                    for du in [-0.25f32, 0.25] {
                        for dz in [0.25f64, 0.75] {
                            let z = (zmin + (r as f64 + dz) / colour_rows as f64 * (zmax - zmin))
                                .min(b.z1);
                            let fc = colors::facade_rgb(&b.style, u + du * s_m as f32, z as f32);
                            for ch in 0..3 {
                                acc[ch] += fc[ch] as f64;
                            }
                        }
                    }
                }
                // Colours are summed over 4 samples per side, normals once per side.
                sums.cnt[slot] += 4;
            }
        }
        sums.write(&mut map, s as u32 * rows, rows, |mean| {
            colors::to_bytes(mean.map(|v| v as f32))
        });
    }
    // 5. Ambient occlusion (seed 002 §4.2.1), when asked for.
    if opts.ao {
        stats.ao = Some(super::ao::compute(&mut map, &exposed, opts.ao_radius_m));
    }
    let kept: Vec<u32> = bs.iter().map(|b| b.id.0).collect();
    Ok((map, kept, stats))
}

/// The four sides of a texel: bit `s` of an exposed mask is side `SIDES[s]` (Δi, Δj).
pub(crate) const SIDES: [(i64, i64); 4] = [(-1, 0), (1, 0), (0, -1), (0, 1)];

/// Step 2 of a map's construction, from its heights and footprint edges: per texel (row-major),
/// bit `s` set when side [`SIDES`]`[s]` faces a lower column, or is the side a footprint edge of
/// the texel faces most (an edge wall shows that side's column).
pub(crate) fn exposed_sides(map: &BlockMap) -> Vec<u8> {
    let k = map.k() as usize;
    let h = |i: i64, j: i64| -> u8 {
        if i < 0 || j < 0 || i >= k as i64 || j >= k as i64 {
            0
        } else {
            map.height_code(i as u32, j as u32)
        }
    };
    let mut exposed = vec![0u8; k * k];
    for j in 0..k as i64 {
        for i in 0..k as i64 {
            let c = h(i, j);
            if c == 0 {
                continue;
            }
            let mut bits = 0u8;
            for (s, (di, dj)) in SIDES.iter().enumerate() {
                if h(i + di, j + dj) < c {
                    bits |= 1 << s;
                }
            }
            for e in map.edges(i as u32, j as u32).into_iter().flatten() {
                let best = SIDES
                    .iter()
                    .enumerate()
                    .map(|(s, (di, dj))| (s, e.n[0] * *di as f32 + e.n[1] * *dj as f32))
                    .fold(
                        (0usize, f32::NEG_INFINITY),
                        |a, b| if b.1 > a.1 { b } else { a },
                    );
                bits |= 1 << best.0;
            }
            exposed[(j as usize) * k + i as usize] = bits;
        }
    }
    exposed
}

/// Step 3: the fewest slices (powers of two, each at least `opts.min_slice_rows` rows) whose
/// unfolded exposed texels fit 255 wall columns, or the thinnest allowed; per slice, its texels
/// in unfolding order. The slice count is the vector's length.
pub(crate) fn wall_slices(exposed: &[u8], k: usize, opts: &BuildOptions) -> Vec<Vec<usize>> {
    let mut slices = 1u32;
    loop {
        let rows = opts.k / slices;
        let orders: Vec<Vec<usize>> = (0..slices)
            .map(|s| unfold(exposed, k, (s * rows) as usize, ((s + 1) * rows) as usize))
            .collect();
        let worst = orders.iter().map(Vec::len).max().unwrap_or(0);
        if worst <= 255 || rows / 2 < opts.min_slice_rows {
            return orders;
        }
        slices *= 2;
    }
}

/// The wall column (1..=255) of the `idx`-th of a slice's `n` exposed texels; on overflow,
/// neighbours along the unfolding share a column (seed 000 §3.3).
pub(crate) fn wall_column(idx: usize, n: usize) -> u8 {
    if n <= 255 {
        (idx + 1) as u8
    } else {
        (idx * 255 / n + 1) as u8
    }
}

/// Step 4's sums for one slice's wall columns: per column, the normal sum, the colour sums per
/// colour row and the sample count.
pub(crate) struct ColumnSums {
    pub(crate) nsum: Vec<DVec3>,
    csum: Vec<[f64; 3]>,
    pub(crate) cnt: Vec<u32>,
    colour_rows: usize,
}

impl ColumnSums {
    /// Sums for a slice of `n` exposed texels (at most 255 columns).
    pub(crate) fn new(n: usize, colour_rows: usize) -> Self {
        let ncol = n.min(255);
        Self {
            nsum: vec![DVec3::ZERO; ncol],
            csum: vec![[0.0; 3]; ncol * colour_rows],
            cnt: vec![0; ncol],
            colour_rows,
        }
    }

    /// The colour sum of column `slot` (0-based), colour row `r`.
    pub(crate) fn colour_mut(&mut self, slot: usize, r: usize) -> &mut [f64; 3] {
        &mut self.csum[slot * self.colour_rows + r]
    }

    /// Writes every column with samples into the slice starting at image row `row0` of
    /// `rows` rows: the mean colours (`to_rgb` turns a mean sum into bytes) and, in the last
    /// row, the normalised normal sum.
    pub(crate) fn write(
        &self,
        map: &mut BlockMap,
        row0: u32,
        rows: u32,
        to_rgb: impl Fn([f64; 3]) -> [u8; 3],
    ) {
        let k = map.k();
        for (slot, &cnt) in self.cnt.iter().enumerate() {
            if cnt == 0 {
                continue;
            }
            let u = 2 * k + slot as u32;
            for r in 0..self.colour_rows {
                let c = to_rgb(self.csum[slot * self.colour_rows + r].map(|v| v / cnt as f64));
                *map.texel_mut(u, row0 + r as u32) = [c[0], c[1], c[2], 255];
            }
            let n = self.nsum[slot].normalize_or(DVec3::X).as_vec3();
            *map.texel_mut(u, row0 + rows - 1) =
                [encode_unit(n.x), encode_unit(n.y), encode_unit(n.z), 255];
        }
    }
}

/// The footprint edges of a map: per texel, the edge bytes ([`BlockMap::set_edge_bytes`]).
struct Edges {
    bytes: Vec<Option<[u8; 3]>>,
    /// The second half-plane of a texel, when two hold its footprint part more closely.
    bytes2: Vec<Option<[u8; 3]>>,
    filled: usize,
}

/// Area of the part of the unit square centred on 0 where `n·q ≤ o`.
pub fn kept_area(n: DVec2, o: f64) -> f64 {
    kept_area_of(&[(n, o)])
}

/// Area of the part of the unit square centred on 0 inside every half-plane `n·q ≤ o` of
/// `planes` (Sutherland–Hodgman on the convex square).
pub fn kept_area_of(planes: &[(DVec2, f64)]) -> f64 {
    let mut poly = vec![
        DVec2::new(-0.5, -0.5),
        DVec2::new(0.5, -0.5),
        DVec2::new(0.5, 0.5),
        DVec2::new(-0.5, 0.5),
    ];
    for &(n, o) in planes {
        let mut out = Vec::with_capacity(poly.len() + 1);
        for q in 0..poly.len() {
            let (a, b) = (poly[q], poly[(q + 1) % poly.len()]);
            let (ga, gb) = (n.dot(a) - o, n.dot(b) - o);
            if ga <= 0.0 {
                out.push(a);
            }
            if (ga <= 0.0) != (gb <= 0.0) {
                out.push(a + (b - a) * (ga / (ga - gb)));
            }
        }
        poly = out;
        if poly.is_empty() {
            return 0.0;
        }
    }
    shoelace(&poly).abs()
}

/// Finds, for every texel a footprint edge crosses, the half-plane of least area (within the
/// texel) that holds every footprint point of the texel, among the supporting lines of the
/// crossing edges (normals quantised as the layout stores them, offsets rounded up with the
/// quantised normal). Fills (in `owner`) a crossed texel the sampling left empty when footprints
/// cover part of it and a half-plane cuts it with less excess than that part's area, with the
/// building covering most of it.
fn footprint_edges(
    bs: &[&SourceBuilding],
    min: DVec2,
    s: f64,
    k: usize,
    owner: &mut [u32],
    two_edges: bool,
) -> Edges {
    use super::layout::{decode_offset, decode_unit, encode_offset_up};
    // Per texel, the (building, ring, edge) crossing it.
    let mut cross: Vec<Vec<(u32, u32, u32)>> = vec![Vec::new(); k * k];
    let (mut clip, mut tmp) = (Vec::new(), Vec::new());
    for (p, b) in bs.iter().enumerate() {
        for (r, ring) in b.rings.iter().enumerate() {
            let n = ring.len();
            for e in 0..n {
                let (a, c) = (ring[e], ring[(e + 1) % n]);
                let lo = (a.min(c) - min) / s;
                let hi = (a.max(c) - min) / s;
                let i0 = (lo.x.floor().max(0.0) as usize).min(k - 1);
                let j0 = (lo.y.floor().max(0.0) as usize).min(k - 1);
                let i1 = (hi.x.floor().max(0.0) as usize).min(k - 1);
                let j1 = (hi.y.floor().max(0.0) as usize).min(k - 1);
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        let blo = min + DVec2::new(i as f64, j as f64) * s;
                        let bhi = blo + DVec2::splat(s);
                        // An end inside the closed box survives every clip; otherwise clip.
                        let holds = |q: DVec2| q.cmpge(blo).all() && q.cmple(bhi).all();
                        let touches = holds(a) || holds(c) || {
                            clip_to_box_into(&[a, c], blo, bhi, &mut clip, &mut tmp);
                            !clip.is_empty()
                        };
                        if touches {
                            cross[j * k + i].push((p as u32, r as u32, e as u32));
                        }
                    }
                }
            }
        }
    }
    // Buildings over each texel centre (a building over the centre that no edge of it crosses
    // holds the whole texel).
    let mut centre: Vec<Vec<u32>> = vec![Vec::new(); k * k];
    {
        let pos: std::collections::HashMap<u32, u32> = bs
            .iter()
            .enumerate()
            .map(|(p, b)| (b.id.0, p as u32))
            .collect();
        scan(bs, min, s, k, &mut |t, b| centre[t].push(pos[&b.id.0]));
    }
    // Orientation of each ring (+1 counter-clockwise).
    let orient: Vec<Vec<f64>> = bs
        .iter()
        .map(|b| {
            b.rings
                .iter()
                .enumerate()
                .map(|(r, ring)| {
                    let ccw = shoelace(ring) >= 0.0;
                    // Outward of the solid: right of a CCW exterior, left of a CCW hole.
                    match (r == 0, ccw) {
                        (true, true) | (false, false) => 1.0,
                        _ => -1.0,
                    }
                })
                .collect()
        })
        .collect();
    let mut bytes = vec![None; k * k];
    let mut bytes2 = vec![None; k * k];
    let mut filled = 0usize;
    let mut pts: Vec<DVec2> = Vec::new();
    let mut ext: Vec<DVec2> = Vec::new();
    let mut crossing: Vec<u32> = Vec::new();
    for t in 0..k * k {
        if cross[t].is_empty() {
            continue;
        }
        crossing.clear();
        crossing.extend(cross[t].iter().map(|c| c.0));
        crossing.sort_unstable();
        crossing.dedup();
        if centre[t].iter().any(|b| crossing.binary_search(b).is_err()) {
            continue; // a building holds the whole texel
        }
        let (i, j) = (t % k, t / k);
        let lo = min + DVec2::new(i as f64, j as f64) * s;
        let hi = lo + DVec2::splat(s);
        let mid = lo + DVec2::splat(0.5 * s);
        pts.clear();
        let mut best_area: (f64, f64, u32) = (0.0, 0.0, SKY);
        let mut total = 0.0;
        for &p in &crossing {
            let b = bs[p as usize];
            clip_to_box_into(&b.rings[0], lo, hi, &mut ext, &mut tmp);
            let mut area = shoelace(&ext).abs();
            for hole in &b.rings[1..] {
                clip_to_box_into(hole, lo, hi, &mut clip, &mut tmp);
                area -= shoelace(&clip).abs();
            }
            let area = area.max(0.0) / (s * s);
            total += area;
            pts.extend(ext.iter().map(|v| (*v - mid) / s));
            if area > best_area.0 || (area == best_area.0 && b.z1 > best_area.1) {
                best_area = (area, b.z1, b.id.0);
            }
        }
        if total <= 1e-9 {
            continue; // the footprints only touch the texel
        }
        // The supporting lines of the crossing edges (quantised normal, offset rounded up so
        // that each holds every footprint point of the texel).
        let mut lines: Vec<(DVec2, f64, [u8; 3])> = Vec::new();
        for &(p, r, e) in &cross[t] {
            let ring = &bs[p as usize].rings[r as usize];
            let (a, c) = (ring[e as usize], ring[(e as usize + 1) % ring.len()]);
            let d = (c - a).normalize_or_zero() * orient[p as usize][r as usize];
            if d == DVec2::ZERO {
                continue;
            }
            let (bx, by) = (encode_unit(d.y as f32), encode_unit(-d.x as f32));
            let nq = DVec2::new(decode_unit(bx) as f64, decode_unit(by) as f64);
            if nq == DVec2::ZERO {
                continue;
            }
            let need = pts
                .iter()
                .map(|q| nq.dot(*q))
                .fold(f64::NEG_INFINITY, f64::max);
            // A millionth of a texel for the f32 walk's rounding.
            let Some(bo) = encode_offset_up(need + 1e-6) else {
                continue;
            };
            if lines.iter().any(|l| l.2 == [bx, by, bo]) {
                continue;
            }
            lines.push((nq, decode_offset(bo) as f64, [bx, by, bo]));
        }
        // The best line, then the best pair when two lines keep less (by more than a
        // hundredth of the texel): a convex corner, or two sides of a thin building.
        let mut best: Option<(f64, [u8; 3])> = None;
        for l in &lines {
            let area = kept_area(l.0, l.1);
            if area < 1.0 - 1e-6 && best.is_none_or(|(ba, _)| area < ba) {
                best = Some((area, l.2));
            }
        }
        let mut best2: Option<(f64, [u8; 3], [u8; 3])> = None;
        if two_edges {
            for a in 0..lines.len() {
                for b in a + 1..lines.len() {
                    let area = kept_area_of(&[(lines[a].0, lines[a].1), (lines[b].0, lines[b].1)]);
                    if best2.is_none_or(|(ba, _, _)| area < ba) {
                        best2 = Some((area, lines[a].2, lines[b].2));
                    }
                }
            }
        }
        let pair = match (best, best2) {
            (Some((a1, _)), Some((a2, _, _))) if a2 < a1 - 0.01 => best2,
            (None, Some((a2, _, _))) if a2 < 1.0 - 0.01 => best2,
            _ => None,
        };
        if owner[t] == SKY {
            // An empty texel gets a column only when that lowers its area error: the column's
            // excess (kept − covered) must be below the footprint area it would add (covered).
            // A whole square between two buildings, or a half-plane around a building much
            // smaller than the texel (upper levels: 100 m texels), adds more than it fixes.
            let covered = total.min(1.0);
            let kept = pair.map_or(best.map(|b| b.0), |p| Some(p.0));
            if kept.is_none_or(|kept| kept >= 2.0 * covered) {
                continue;
            }
            owner[t] = best_area.2;
            filled += 1;
        }
        match pair {
            Some((_, e1, e2)) => {
                bytes[t] = Some(e1);
                bytes2[t] = Some(e2);
            }
            None => bytes[t] = best.map(|b| b.1),
        }
    }
    Edges {
        bytes,
        bytes2,
        filled,
    }
}

/// The building whose roof is highest over each texel centre of the `k × k` grid with lower
/// corner `min` and texel side `s` (row-major, row 0 south), or [`SKY`]: a top-down orthographic
/// render of the prisms with one sample per texel centre, done as scan conversion of the
/// footprints (for vertical prisms the two are the same picture). A centre is inside a footprint
/// by the even-odd rule with half-open crossings (the test of `error::in_polygon`), so a centre
/// on an edge shared by two footprints belongs to exactly one; equal roofs keep the building
/// given first.
pub fn top_down_owners(bs: &[&SourceBuilding], min: DVec2, s: f64, k: usize) -> Vec<u32> {
    let mut owner = vec![SKY; k * k];
    let mut top = vec![f64::NEG_INFINITY; k * k];
    scan(bs, min, s, k, &mut |t, b| {
        if b.z1 > top[t] {
            top[t] = b.z1;
            owner[t] = b.id.0;
        }
    });
    owner
}

/// Supersampled variant of [`top_down_owners`]: `sub × sub` samples per texel, each won by the
/// highest roof over it; the building that won most of them (ties: the higher roof, then the
/// building given first) fills the texel when at least half of its samples are covered, or, for
/// a building narrower than a texel (the smaller side of its box), at least `min_share`.
pub fn top_down_owners_supersampled(
    bs: &[&SourceBuilding],
    min: DVec2,
    s: f64,
    k: usize,
    sub: usize,
    min_share: f64,
) -> Vec<u32> {
    if sub <= 1 {
        return top_down_owners(bs, min, s, k);
    }
    let fine = top_down_owners(bs, min, s / sub as f64, k * sub);
    let mut order: Vec<(u32, usize)> = bs.iter().enumerate().map(|(p, b)| (b.id.0, p)).collect();
    order.sort_unstable();
    let z1 = |id: u32| match order.binary_search_by_key(&id, |o| o.0) {
        Ok(q) => (order[q].1, bs[order[q].1].z1),
        Err(_) => (usize::MAX, f64::NEG_INFINITY),
    };
    let need = ((min_share * (sub * sub) as f64).ceil() as usize).max(1);
    let half = (sub * sub).div_ceil(2);
    let mut owner = vec![SKY; k * k];
    let mut counts: Vec<(u32, usize)> = Vec::with_capacity(sub * sub);
    for j in 0..k {
        for i in 0..k {
            counts.clear();
            for b in 0..sub {
                for a in 0..sub {
                    let id = fine[(j * sub + b) * k * sub + i * sub + a];
                    if id == SKY {
                        continue;
                    }
                    match counts.iter_mut().find(|c| c.0 == id) {
                        Some(c) => c.1 += 1,
                        None => counts.push((id, 1)),
                    }
                }
            }
            let covered: usize = counts.iter().map(|c| c.1).sum();
            let best = counts.iter().copied().max_by(|x, y| {
                let ((px, zx), (py, zy)) = (z1(x.0), z1(y.0));
                x.1.cmp(&y.1).then(zx.total_cmp(&zy)).then(py.cmp(&px))
            });
            if let Some((id, _)) = best {
                // A building at least a texel wide keeps the area-preserving half share; a
                // thinner one (whose walls, seen obliquely, cover more than its footprint)
                // fills the texel from `min_share`.
                let (pos, _) = z1(id);
                let thin = pos < bs.len() && (bs[pos].max - bs[pos].min).min_element() < s;
                let need = if thin { need } else { need.max(half) };
                if covered >= need {
                    owner[j * k + i] = id;
                }
            }
        }
    }
    owner
}

/// Calls `hit(texel, building)` for every texel centre of the grid inside each footprint.
fn scan<'b>(
    bs: &[&'b SourceBuilding],
    min: DVec2,
    s: f64,
    k: usize,
    hit: &mut dyn FnMut(usize, &'b SourceBuilding),
) {
    let mut xs: Vec<f64> = Vec::new();
    for b in bs {
        // Rows whose centre y lies in the footprint's y range.
        let j0 = (((b.min.y - min.y) / s - 0.5).floor().max(0.0)) as usize;
        let j1 = (((b.max.y - min.y) / s - 0.5).ceil().max(0.0) as usize).min(k - 1);
        for j in j0..=j1 {
            let y = min.y + (j as f64 + 0.5) * s;
            if y < b.min.y || y > b.max.y {
                continue;
            }
            xs.clear();
            for ring in &b.rings {
                let n = ring.len();
                let mut q = n - 1;
                for p in 0..n {
                    let (a, c) = (ring[p], ring[q]);
                    if (a.y > y) != (c.y > y) {
                        xs.push((c.x - a.x) * (y - a.y) / (c.y - a.y) + a.x);
                    }
                    q = p;
                }
            }
            xs.sort_by(f64::total_cmp);
            // A centre x is inside when an odd number of crossings lie right of it
            // (x < crossing): x ∈ [xs[2m], xs[2m + 1]).
            for span in xs.chunks_exact(2) {
                let (x0, x1) = (span[0], span[1]);
                let mut i = (((x0 - min.x) / s - 0.5).floor().max(0.0)) as usize;
                while i < k {
                    let x = min.x + (i as f64 + 0.5) * s;
                    if x >= x1 {
                        break;
                    }
                    if x >= x0 {
                        hit(j * k + i, b);
                    }
                    i += 1;
                }
            }
        }
    }
}

/// Exposed texels of rows `[r0, r1)` in unfolding order: start at the first unvisited exposed
/// texel in row-major order, then keep stepping to an unvisited exposed 4-neighbour, else
/// 8-neighbour (fixed order), so a building's boundary is followed around.
pub(crate) fn unfold(exposed: &[u8], k: usize, r0: usize, r1: usize) -> Vec<usize> {
    let mut visited = vec![false; k * k];
    let mut out = Vec::new();
    const NB: [(i64, i64); 8] = [
        (1, 0),
        (0, 1),
        (-1, 0),
        (0, -1),
        (1, 1),
        (-1, 1),
        (-1, -1),
        (1, -1),
    ];
    for start in r0 * k..r1 * k {
        if exposed[start] == 0 || visited[start] {
            continue;
        }
        let mut cur = start;
        visited[cur] = true;
        out.push(cur);
        loop {
            let (i, j) = ((cur % k) as i64, (cur / k) as i64);
            let next = NB.iter().find_map(|(di, dj)| {
                let (ni, nj) = (i + di, j + dj);
                if ni < 0 || ni >= k as i64 || nj < r0 as i64 || nj >= r1 as i64 {
                    return None;
                }
                let t = nj as usize * k + ni as usize;
                (exposed[t] != 0 && !visited[t]).then_some(t)
            });
            match next {
                Some(t) => {
                    visited[t] = true;
                    out.push(t);
                    cur = t;
                }
                None => break,
            }
        }
    }
    out
}

/// The footprint edge of `b` nearest to `p`: its outward unit normal and the `u` coordinate
/// (metres along the unfolded ring) of the point of the edge nearest to `p`. `None` for a
/// footprint without edges.
pub fn nearest_facade(b: &SourceBuilding, p: DVec2) -> Option<(DVec2, f32)> {
    let mut best: Option<(f64, DVec2, f32)> = None;
    for (ri, ring) in b.rings.iter().enumerate() {
        let n = ring.len();
        for e in 0..n {
            let (a, c) = (ring[e], ring[(e + 1) % n]);
            let d = c - a;
            let l2 = d.length_squared();
            if l2 == 0.0 {
                continue;
            }
            let t = ((p - a).dot(d) / l2).clamp(0.0, 1.0);
            let dist = (a + d * t - p).length_squared();
            // Exterior CCW and holes CW: the solid is on the left, outward is the right normal.
            let out = DVec2::new(d.y, -d.x) / l2.sqrt();
            if best.is_none_or(|(bd, _, _)| dist < bd) {
                let us = &b.ring_u[ri];
                let u = us[e] + (us[e + 1] - us[e]) * t as f32;
                best = Some((dist, out, u));
            }
        }
    }
    best.map(|(_, n, u)| (n, u))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ao_radius_is_bounded() {
        for (r, ok) in [
            (30.0, true),
            (MAX_AO_RADIUS_M, true),
            (200.5, false),
            (1e9, false),
            (0.0, false),
            (f64::NAN, false),
        ] {
            let o = BuildOptions {
                ao: true,
                ao_radius_m: r,
                ..BuildOptions::default()
            };
            assert_eq!(o.validate().is_ok(), ok, "{r}");
            if !ok {
                let e = o.validate().unwrap_err().to_string();
                assert!(e.contains("(0, 200] m"), "{e}");
            }
        }
    }

    #[test]
    fn kept_area_of_two_half_planes() {
        // One half-plane: half the square; two perpendicular ones: a quarter.
        assert!((kept_area(DVec2::X, 0.0) - 0.5).abs() < 1e-12);
        let q = kept_area_of(&[(DVec2::X, 0.0), (DVec2::Y, 0.0)]);
        assert!((q - 0.25).abs() < 1e-12, "{q}");
        // Two parallel sides of a strip 0.2 wide.
        let s = kept_area_of(&[(DVec2::X, 0.1), (DVec2::NEG_X, 0.1)]);
        assert!((s - 0.2).abs() < 1e-12, "{s}");
        // Disjoint half-planes keep nothing; none keeps the square.
        assert_eq!(kept_area_of(&[(DVec2::X, -0.2), (DVec2::NEG_X, -0.2)]), 0.0);
        assert!((kept_area_of(&[]) - 1.0).abs() < 1e-12);
    }
}
