//! The plan's tiles: the blocks cut along the block quadtree.

use super::*;
use crate::geom::Rect;

/// Cuts the blocks into tiles along the block quadtree: a node becomes a tile when its blocks
/// hold at most `max_buildings` buildings, when it holds one block, or at [`MAX_DEPTH`].
/// Tiles come in depth-first order, quadrants 0..3 (south-west, south-east, north-west,
/// north-east).
pub fn cut_tiles(blocks: &[PlanBlock], max_buildings: usize) -> Vec<PlanTile> {
    if blocks.is_empty() {
        return Vec::new();
    }
    let centre = |b: &PlanBlock| {
        let r = b.rings.first();
        let mut bb: Option<Rect> = None;
        for c in r.into_iter().flatten() {
            bb = Some(Rect::grow(bb, Rect::point([c[0].0, c[1].0])));
        }
        bb.unwrap_or(Rect::from(b.bounds)).centre()
    };
    let centres: Vec<[f64; 2]> = blocks.iter().map(centre).collect();
    let mut region: Option<Rect> = None;
    for (b, c) in blocks.iter().zip(&centres) {
        region = Some(Rect::grow(region, b.bounds.into()));
        region = Some(Rect::grow(region, Rect::point(*c)));
    }
    let mut items: Vec<u32> = (0..blocks.len() as u32).collect();
    let mut tiles = Vec::new();
    let ctx = Cut {
        blocks,
        centres: &centres,
        max_buildings,
    };
    ctx.node(
        &mut items,
        region.map_or([0.0; 4], Rect::to_array),
        1,
        0,
        &mut tiles,
    );
    tiles
}

struct Cut<'a> {
    blocks: &'a [PlanBlock],
    centres: &'a [[f64; 2]],
    max_buildings: usize,
}

impl Cut<'_> {
    fn node(&self, items: &mut [u32], q: [f64; 4], key: u64, depth: u32, out: &mut Vec<PlanTile>) {
        let buildings: usize = items
            .iter()
            .map(|&i| self.blocks[i as usize].buildings)
            .sum();
        if buildings <= self.max_buildings || items.len() <= 1 || depth >= MAX_DEPTH {
            let mut ids: Vec<u32> = items.to_vec();
            ids.sort_unstable();
            let mut bounds: Option<Rect> = None;
            let mut read: Option<Rect> = None;
            for &i in &ids {
                let b = &self.blocks[i as usize];
                bounds = Some(Rect::grow(bounds, b.bounds.into()));
                if let Some(bb) = b.building_bounds {
                    read = Some(Rect::grow(read, bb.into()));
                }
            }
            out.push(PlanTile {
                id: out.len(),
                key,
                blocks: ids,
                buildings,
                bounds: bounds.map_or([0.0; 4], Rect::to_array),
                read_bounds: read.map(Rect::to_array),
            });
            return;
        }
        let mid = Rect::from(q).centre();
        let quadrant = |i: &u32| {
            let c = self.centres[*i as usize];
            usize::from(c[0] >= mid[0]) + 2 * usize::from(c[1] >= mid[1])
        };
        items.sort_by_key(|i| (quadrant(i), *i));
        let mut rest: &mut [u32] = items;
        for k in 0..4 {
            let n = rest.iter().take_while(|i| quadrant(i) == k).count();
            let (head, tail) = rest.split_at_mut(n);
            rest = tail;
            if head.is_empty() {
                continue;
            }
            let cq = [
                if k & 1 == 1 { mid[0] } else { q[0] },
                if k & 2 == 2 { mid[1] } else { q[1] },
                if k & 1 == 1 { q[2] } else { mid[0] },
                if k & 2 == 2 { q[3] } else { mid[1] },
            ];
            self.node(head, cq, (key << 2) | k as u64, depth + 1, out);
        }
    }
}
