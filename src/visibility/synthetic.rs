//! A synthetic city for tests and benches (see [`SyntheticCity`]).

use crate::blocks::{Block, BlockId, BlockKind, BlockLayout, BlockSource};
use crate::city::{Building, BuildingId, City, CityReport, HeightSource, LocalFrame, Mesh};
use geo_types::{coord, LineString, Polygon};
use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A synthetic city for tests and benches: a grid of rectangular blocks separated by streets,
/// each lined with touching box buildings of random heights, an L-shaped building at one corner,
/// some gaps between buildings, and some raised buildings (`min_height_m > 0`, passages). Every
/// footprint is a union of axis-aligned boxes, so [`SyntheticCity::meshes`] holds the exact
/// geometry. World coordinates are offset by `origin` to exercise the local frame.
#[derive(Clone, Debug)]
pub struct SyntheticCity {
    /// The city (metric world coordinates).
    pub city: City,
    /// Its blocks and street edges.
    pub layout: BlockLayout,
    /// One mesh per block (local frame).
    pub meshes: Vec<(BlockId, Mesh)>,
}

impl SyntheticCity {
    /// A `cols × rows` grid of blocks from `seed`.
    pub fn generate(cols: usize, rows: usize, seed: u64, origin: DVec2) -> Self {
        Self::generate_shifted(cols, rows, seed, origin, DVec2::ZERO)
    }

    /// As [`SyntheticCity::generate`], with the buildings `shift` metres from the local frame's
    /// origin (world coordinates unchanged, the frame's origin moved by `-shift`), so that the
    /// f32 meshes carry the rounding of coordinates that large (e.g. 5 km: ulp 0.5 mm).
    pub fn generate_shifted(
        cols: usize,
        rows: usize,
        seed: u64,
        origin: DVec2,
        shift: DVec2,
    ) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let frame = LocalFrame {
            origin: (origin - shift).extend(0.0),
        };
        let mut buildings: Vec<Building> = Vec::new();
        let mut blocks: Vec<Block> = Vec::new();
        let mut meshes: Vec<(BlockId, Mesh)> = Vec::new();
        let street = 16.0;
        let xs: Vec<f64> = std::iter::once(0.0)
            .chain((0..cols).scan(0.0, |x, _| {
                *x += rng.random_range(50.0..110.0) + street;
                Some(*x)
            }))
            .collect();
        let ys: Vec<f64> = std::iter::once(0.0)
            .chain((0..rows).scan(0.0, |y, _| {
                *y += rng.random_range(50.0..110.0) + street;
                Some(*y)
            }))
            .collect();
        let mut street_edges = Vec::new();
        let (w, h) = (*xs.last().unwrap_or(&0.0), *ys.last().unwrap_or(&0.0));
        let wl = |x: f64, y: f64| coord! { x: x + origin.x, y: y + origin.y };
        for &x in &xs {
            street_edges.push(LineString(vec![
                wl(x - street / 2.0, -street / 2.0),
                wl(x - street / 2.0, h - street / 2.0),
            ]));
        }
        for &y in &ys {
            street_edges.push(LineString(vec![
                wl(-street / 2.0, y - street / 2.0),
                wl(w - street / 2.0, y - street / 2.0),
            ]));
        }
        for j in 0..rows {
            for i in 0..cols {
                let (x0, x1) = (xs[i], xs[i + 1] - street);
                let (y0, y1) = (ys[j], ys[j + 1] - street);
                let id = BlockId(blocks.len() as u32);
                let mut mesh = Mesh::default();
                let mut ids = Vec::new();
                let depth = rng
                    .random_range(9.0..15.0f64)
                    .min((x1 - x0) / 3.0)
                    .min((y1 - y0) / 3.0);
                // Boxes as (min, max, min_height, height); each entry one building made of boxes.
                let mut parts: Vec<Vec<(DVec2, DVec2)>> = Vec::new();
                // L at the south-west corner.
                let (la, lb) = (
                    rng.random_range(15.0..30.0f64).min(x1 - x0 - depth),
                    rng.random_range(15.0..30.0f64).min(y1 - y0 - depth),
                );
                parts.push(vec![
                    (DVec2::new(x0, y0), DVec2::new(x0 + la, y0 + depth)),
                    (DVec2::new(x0, y0 + depth), DVec2::new(x0 + depth, y0 + lb)),
                ]);
                let row = |a: f64,
                           b: f64,
                           horizontal: bool,
                           fixed0: f64,
                           fixed1: f64,
                           rng: &mut ChaCha8Rng,
                           parts: &mut Vec<Vec<(DVec2, DVec2)>>| {
                    let mut s = a;
                    while s < b - 4.0 {
                        let mut e = (s + rng.random_range(8.0..25.0)).min(b);
                        if b - e < 6.0 {
                            e = b;
                        }
                        let r = if horizontal {
                            (DVec2::new(s, fixed0), DVec2::new(e, fixed1))
                        } else {
                            (DVec2::new(fixed0, s), DVec2::new(fixed1, e))
                        };
                        parts.push(vec![r]);
                        s = e + if rng.random_bool(0.1) { 2.0 } else { 0.0 };
                    }
                };
                row(x0 + la, x1, true, y0, y0 + depth, &mut rng, &mut parts); // south
                row(x0, x1, true, y1 - depth, y1, &mut rng, &mut parts); // north
                row(
                    y0 + depth,
                    y1 - depth,
                    false,
                    x1 - depth,
                    x1,
                    &mut rng,
                    &mut parts,
                ); // east
                row(
                    y0 + lb,
                    y1 - depth,
                    false,
                    x0,
                    x0 + depth,
                    &mut rng,
                    &mut parts,
                ); // west
                for boxes in parts {
                    let height = rng.random_range(6.0..40.0f64).round();
                    let min_height = if boxes.len() == 1 && rng.random_bool(0.05) {
                        4.0
                    } else {
                        0.0
                    };
                    let ring: Vec<DVec2> = if boxes.len() == 1 {
                        let (a, b) = boxes[0];
                        vec![a, DVec2::new(b.x, a.y), b, DVec2::new(a.x, b.y), a]
                    } else {
                        let (a, b) = boxes[0];
                        let (_, d) = boxes[1];
                        vec![
                            a,
                            DVec2::new(b.x, a.y),
                            DVec2::new(b.x, b.y),
                            DVec2::new(d.x, b.y),
                            d,
                            DVec2::new(a.x, d.y),
                            a,
                        ]
                    };
                    let bid = BuildingId(buildings.len() as u32);
                    ids.push(bid);
                    buildings.push(Building {
                        id: bid,
                        source_id: format!("synthetic:{}", bid.0),
                        footprint: Polygon::new(
                            LineString(ring.iter().map(|p| wl(p.x, p.y)).collect()),
                            vec![],
                        ),
                        height_m: height,
                        min_height_m: min_height,
                        base_m: 0.0,
                        height_source: HeightSource::Height,
                        attributes: Default::default(),
                    });
                    for (a, b) in boxes {
                        let m = super::oracle::box_mesh(
                            LocalFrame::round_to_f32((a + shift).extend(min_height)),
                            LocalFrame::round_to_f32((b + shift).extend(height)),
                        );
                        let base = mesh.positions.len() as u32;
                        mesh.positions.extend_from_slice(&m.positions);
                        mesh.normals.extend_from_slice(&m.normals);
                        mesh.indices.extend(m.indices.iter().map(|k| k + base));
                    }
                }
                blocks.push(Block {
                    id,
                    kind: BlockKind::Block,
                    polygon: Polygon::new(
                        LineString(vec![
                            wl(x0, y0),
                            wl(x1, y0),
                            wl(x1, y1),
                            wl(x0, y1),
                            wl(x0, y0),
                        ]),
                        vec![],
                    ),
                    buildings: ids,
                });
                meshes.push((id, mesh));
            }
        }
        let city = City {
            name: format!("synthetic {cols}x{rows} seed {seed}"),
            transform: blockwalk_importers::Crs::Unknown.metric_transform([origin.x, origin.y]),
            frame,
            buildings,
            streets: Vec::new(),
            parcels: Vec::new(),
            report: CityReport::default(),
            terrain: None,
        };
        Self {
            city,
            layout: BlockLayout {
                blocks,
                source: BlockSource::Streets,
                street_edges,
                dangles: 0,
            },
            meshes,
        }
    }

    /// The meshes as the oracle takes them.
    pub fn mesh_refs(&self) -> Vec<(BlockId, &Mesh)> {
        self.meshes.iter().map(|(id, m)| (*id, m)).collect()
    }
}
