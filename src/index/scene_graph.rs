//! The VAMSplit R-tree over *buildings* with scene-graph semantics: the setting of Pina, Serón and Cerezo, §5.1,
//! where the comparison structure is an R-tree over the scene's geometry loaded into a scene
//! graph (OpenGL Performer) whose leaves are drawn whole.
//!
//! The items are single buildings (or any boxes); they are grouped top-down by White & Jain's
//! VAMSplit into *pages* of at most [`SceneGraphParams::leaf_capacity`] items, and the pages into
//! inner nodes of at most [`SceneGraphParams::node_capacity`] children. Culling is Performer's
//! (Pina, Serón and Cerezo, §5.1): a node outside the frustum is dropped with its subtree, a node inside it is
//! accepted with its subtree without further tests, a partly inside node is descended, and a
//! *leaf* (a page) whose box meets the frustum is accepted whole: its items are not tested one by
//! one, because in a scene graph the leaf is one piece of geometry. The output ids are *page*
//! ids (`BlockId(p)` for page `p`, see [`SceneGraphTree::page_items`]), the unit the renderer
//! draws.
//!
//! Deviation from Pina, Serón and Cerezo: the paper does not give the tree's fan-out; the default (8 items a
//! page, 8 children a node) is the block VAMSplit tree's.

use super::bqr::box_distance_2;
use super::vamsplit::{child_capacity, vam_split};
use super::{validate_bounds, BlockBounds, CityIndex, CullQuery, CullStats, IndexError, Structure};
use crate::blocks::BlockId;
use crate::geom::{Aabb3, Containment, PlaneMask, ALL_PLANES};

const NAME: Structure = Structure::SceneGraph;

/// Build parameters of a [`SceneGraphTree`].
#[derive(Clone, Debug, PartialEq)]
pub struct SceneGraphParams {
    /// Most items of a page (a leaf drawn whole), ≥ 1.
    pub leaf_capacity: usize,
    /// Most children of an inner node, ≥ 2.
    pub node_capacity: usize,
}

impl Default for SceneGraphParams {
    fn default() -> Self {
        Self {
            leaf_capacity: 8,
            node_capacity: 8,
        }
    }
}

#[derive(Clone, Debug)]
struct Node {
    aabb: Aabb3,
    /// Inner: range in `child_list`.
    child_start: u32,
    child_end: u32,
    /// Pages of the subtree (contiguous); a leaf is exactly one page.
    page_start: u32,
    page_end: u32,
    leaf: bool,
}

/// One leaf: a box around its items and the triangles drawing it costs.
#[derive(Clone, Debug)]
struct Page {
    aabb: Aabb3,
    triangles: u64,
    item_start: u32,
    item_end: u32,
}

/// A VAMSplit R-tree whose leaves (pages of items) are drawn whole (see the module docs).
#[derive(Clone, Debug)]
pub struct SceneGraphTree {
    nodes: Vec<Node>,
    child_list: Vec<u32>,
    pages: Vec<Page>,
    /// Item ids, page by page.
    items: Vec<BlockId>,
    /// Item boxes, in the order of `items`.
    item_boxes: Vec<Aabb3>,
    params: SceneGraphParams,
}

struct Builder<'a> {
    input: &'a [BlockBounds],
    leaf_cap: usize,
    node_cap: usize,
    nodes: Vec<Node>,
    child_list: Vec<u32>,
    pages: Vec<Page>,
    order: Vec<u32>,
}

impl Builder<'_> {
    fn build(&mut self, items: &mut [u32]) -> u32 {
        let idx = self.nodes.len() as u32;
        let page_start = self.pages.len() as u32;
        self.nodes.push(Node {
            aabb: Aabb3::EMPTY,
            child_start: 0,
            child_end: 0,
            page_start,
            page_end: page_start,
            leaf: true,
        });
        if items.len() <= self.leaf_cap {
            let item_start = self.order.len() as u32;
            self.order.extend_from_slice(items);
            let (aabb, triangles) = items.iter().fold((Aabb3::EMPTY, 0u64), |(a, t), &i| {
                let b = &self.input[i as usize];
                (a.union(b.aabb), t + u64::from(b.triangles))
            });
            self.pages.push(Page {
                aabb,
                triangles,
                item_start,
                item_end: self.order.len() as u32,
            });
            let n = &mut self.nodes[idx as usize];
            n.aabb = aabb;
            n.page_end = self.pages.len() as u32;
            return idx;
        }
        let cap = child_capacity(self.leaf_cap, self.node_cap, items.len());
        let mut groups = Vec::new();
        vam_split(self.input, items, cap, 0, &mut groups);
        let mut children = Vec::with_capacity(groups.len());
        for (a, b) in groups {
            children.push(self.build(&mut items[a..b]));
        }
        let aabb = children
            .iter()
            .fold(Aabb3::EMPTY, |a, &c| a.union(self.nodes[c as usize].aabb));
        let child_start = self.child_list.len() as u32;
        self.child_list.extend_from_slice(&children);
        let page_end = self.pages.len() as u32;
        let n = &mut self.nodes[idx as usize];
        n.aabb = aabb;
        n.leaf = false;
        n.child_start = child_start;
        n.child_end = child_start + children.len() as u32;
        n.page_end = page_end;
        idx
    }
}

impl SceneGraphTree {
    /// Builds the tree over `items` (one [`BlockBounds`] per building: its box, centre and
    /// triangles; the ids are carried through to [`Self::page_items`]).
    ///
    /// # Errors
    /// [`IndexError::BadParam`] for `leaf_capacity < 1` or `node_capacity < 2`,
    /// [`IndexError::BadBlock`] for a non-finite or empty item box.
    pub fn build(items: &[BlockBounds], params: &SceneGraphParams) -> Result<Self, IndexError> {
        if params.leaf_capacity < 1 {
            return Err(IndexError::BadParam {
                structure: NAME,
                name: "leaf_capacity",
                value: params.leaf_capacity.to_string(),
                reason: "must be at least 1",
            });
        }
        if params.node_capacity < 2 {
            return Err(IndexError::BadParam {
                structure: NAME,
                name: "node_capacity",
                value: params.node_capacity.to_string(),
                reason: "must be at least 2",
            });
        }
        validate_bounds(NAME, items)?;
        let mut b = Builder {
            input: items,
            leaf_cap: params.leaf_capacity,
            node_cap: params.node_capacity,
            nodes: Vec::new(),
            child_list: Vec::new(),
            pages: Vec::new(),
            order: Vec::with_capacity(items.len()),
        };
        if !items.is_empty() {
            let mut all: Vec<u32> = (0..items.len() as u32).collect();
            b.build(&mut all);
        }
        Ok(Self {
            items: b.order.iter().map(|&i| items[i as usize].id).collect(),
            item_boxes: b.order.iter().map(|&i| items[i as usize].aabb).collect(),
            nodes: b.nodes,
            child_list: b.child_list,
            pages: b.pages,
            params: params.clone(),
        })
    }

    /// Number of pages (leaves).
    pub fn page_count(&self) -> usize {
        self.pages.len()
    }

    /// The item ids of page `p` (empty for an unknown page).
    pub fn page_items(&self, p: usize) -> &[BlockId] {
        self.pages
            .get(p)
            .map(|pg| &self.items[pg.item_start as usize..pg.item_end as usize])
            .unwrap_or(&[])
    }

    /// The box of page `p`: the union of its items' boxes.
    pub fn page_box(&self, p: usize) -> Option<Aabb3> {
        self.pages.get(p).map(|pg| pg.aabb)
    }

    /// Triangles of page `p` (the sum over its items).
    pub fn page_triangles(&self, p: usize) -> u64 {
        self.pages.get(p).map_or(0, |pg| pg.triangles)
    }

    /// The build parameters.
    pub fn params(&self) -> &SceneGraphParams {
        &self.params
    }

    /// Checks the invariants: capacities, every item in exactly one page, boxes holding their
    /// children and items, contiguous page ranges.
    ///
    /// # Panics
    /// When an invariant is broken.
    pub fn check_invariants(&self) {
        let mut seen_pages = vec![false; self.pages.len()];
        let mut stack = Vec::new();
        if !self.nodes.is_empty() {
            stack.push(0usize);
        }
        let mut visited = 0;
        while let Some(i) = stack.pop() {
            visited += 1;
            let n = &self.nodes[i];
            if n.leaf {
                assert_eq!(n.page_end, n.page_start + 1, "leaf {i} is not one page");
                let p = n.page_start as usize;
                assert!(!seen_pages[p], "page {p} twice");
                seen_pages[p] = true;
                let pg = &self.pages[p];
                let count = (pg.item_end - pg.item_start) as usize;
                assert!(
                    (1..=self.params.leaf_capacity).contains(&count),
                    "page {p} holds {count}"
                );
                for k in pg.item_start..pg.item_end {
                    let b = &self.item_boxes[k as usize];
                    assert!(
                        pg.aabb.contains_point(b.min) && pg.aabb.contains_point(b.max),
                        "page {p} box misses item {:?}",
                        self.items[k as usize]
                    );
                }
                assert!(
                    n.aabb.contains_point(pg.aabb.min) && n.aabb.contains_point(pg.aabb.max),
                    "leaf {i} box misses its page"
                );
            } else {
                let kids = &self.child_list[n.child_start as usize..n.child_end as usize];
                assert!(
                    (2..=self.params.node_capacity).contains(&kids.len()),
                    "node {i} has {} children",
                    kids.len()
                );
                let mut next = n.page_start;
                for &c in kids {
                    let cn = &self.nodes[c as usize];
                    assert!(c as usize > i, "children after parent");
                    assert_eq!(cn.page_start, next, "node {i}: page ranges");
                    next = cn.page_end;
                    assert!(
                        n.aabb.contains_point(cn.aabb.min) && n.aabb.contains_point(cn.aabb.max),
                        "node {i} box misses child {c}"
                    );
                    stack.push(c as usize);
                }
                assert_eq!(next, n.page_end, "node {i}: page range");
            }
        }
        assert_eq!(visited, self.nodes.len(), "unreachable nodes");
        assert!(seen_pages.iter().all(|&s| s), "a page is in no leaf");
        let items: usize = self
            .pages
            .iter()
            .map(|p| (p.item_end - p.item_start) as usize)
            .sum();
        assert_eq!(items, self.items.len(), "items in pages");
    }

    fn accept_range(&self, a: u32, b: u32, out: &mut Vec<BlockId>, stats: &mut CullStats) {
        for p in a..b {
            out.push(BlockId(p));
            stats.blocks_accepted += 1;
            stats.triangles_accepted += self.pages[p as usize].triangles;
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn visit(
        &self,
        i: usize,
        mask: PlaneMask,
        q: &CullQuery<'_>,
        keep: &mut Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
        stats: &mut CullStats,
        scratch: &mut Vec<(f64, u32)>,
    ) {
        let n = &self.nodes[i];
        stats.nodes_visited += 1;
        let mut m = mask;
        let res = if m == 0 {
            Containment::Inside
        } else {
            q.frustum
                .test_aabb_masked(&n.aabb, &mut m, &mut stats.plane_tests)
        };
        if res == Containment::Outside {
            return;
        }
        if let Some(k) = keep.as_mut() {
            if !k(&n.aabb) {
                return;
            }
        }
        // A leaf meeting the frustum is drawn whole; an inner node inside it, with its subtree
        // (Performer's shortcut, only when nothing filters).
        if n.leaf || (res == Containment::Inside && keep.is_none()) {
            self.accept_range(n.page_start, n.page_end, out, stats);
            return;
        }
        let base = scratch.len();
        for &c in &self.child_list[n.child_start as usize..n.child_end as usize] {
            scratch.push((box_distance_2(&self.nodes[c as usize].aabb, q.eye), c));
        }
        scratch[base..].sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let end = scratch.len();
        for j in base..end {
            let c = scratch[j].1;
            self.visit(c as usize, m, q, keep, out, stats, scratch);
        }
        scratch.truncate(base);
    }
}

impl CityIndex for SceneGraphTree {
    fn structure(&self) -> Structure {
        NAME
    }

    /// Pushes the *pages* (`BlockId(page)`) whose leaf meets the frustum (and that
    /// `hidden_filter` keeps); see the module docs.
    fn cull(
        &self,
        query: &CullQuery<'_>,
        hidden_filter: Option<&mut dyn FnMut(&Aabb3) -> bool>,
        out: &mut Vec<BlockId>,
    ) -> CullStats {
        let mut stats = CullStats::default();
        let mut keep = hidden_filter;
        if !self.nodes.is_empty() {
            let mut scratch = Vec::with_capacity(64);
            self.visit(
                0,
                ALL_PLANES,
                query,
                &mut keep,
                out,
                &mut stats,
                &mut scratch,
            );
        }
        stats
    }

    /// Number of items (buildings) indexed.
    fn len(&self) -> usize {
        self.items.len()
    }

    fn node_count(&self) -> usize {
        self.nodes.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Camera;
    use crate::index::synthetic::block_grid;
    use glam::DVec3;

    /// Random cameras over a grid; brute force over the items' boxes.
    fn cameras(n: usize) -> Vec<Camera> {
        let mut s = 0x9E37_79B9_7F4A_7C15u64;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| {
                let pos = DVec3::new(
                    rnd() * 1200.0 - 100.0,
                    rnd() * 1200.0 - 100.0,
                    1.7 + rnd() * 300.0,
                );
                Camera::new(pos, rnd() * std::f64::consts::TAU, -rnd() * 1.2)
            })
            .collect()
    }

    #[test]
    fn never_loses_an_item_and_draws_leaves_whole() {
        let items = block_grid(2_000, 11);
        for params in [
            SceneGraphParams::default(),
            SceneGraphParams {
                leaf_capacity: 3,
                node_capacity: 2,
            },
            SceneGraphParams {
                leaf_capacity: 1,
                node_capacity: 16,
            },
        ] {
            let tree = SceneGraphTree::build(&items, &params).unwrap();
            tree.check_invariants();
            assert_eq!(tree.len(), items.len());
            let mut checked = 0;
            for cam in cameras(60) {
                let f = cam.frustum();
                let mut pages = Vec::new();
                let stats = tree.cull(&CullQuery::with_eye(&f, cam.position), None, &mut pages);
                let drawn: std::collections::HashSet<BlockId> = pages
                    .iter()
                    .flat_map(|p| tree.page_items(p.0 as usize).iter().copied())
                    .collect();
                for it in &items {
                    if f.intersects_aabb(&it.aabb) {
                        checked += 1;
                        assert!(drawn.contains(&it.id), "{params:?}: item {:?} lost", it.id);
                    }
                }
                // Leaves are drawn whole: the triangles accepted are the sum over the
                // accepted pages of all their items' triangles.
                let whole: u64 = pages
                    .iter()
                    .flat_map(|p| tree.page_items(p.0 as usize))
                    .map(|id| u64::from(items[id.0 as usize].triangles))
                    .sum();
                assert_eq!(stats.triangles_accepted, whole);
                assert_eq!(stats.blocks_accepted as usize, pages.len());
                let unique: std::collections::HashSet<_> = pages.iter().collect();
                assert_eq!(unique.len(), pages.len(), "a page twice");
            }
            assert!(checked > 1_000, "too few items in view: {checked}");
        }
    }

    #[test]
    fn a_page_meeting_the_frustum_brings_items_outside_it() {
        // Scene-graph semantics draw more than the items in view: some accepted page holds an
        // item the frustum misses (which the block-level VAMSplit would have dropped).
        let items = block_grid(2_000, 3);
        let tree = SceneGraphTree::build(&items, &SceneGraphParams::default()).unwrap();
        let mut extra = 0;
        for cam in cameras(30) {
            let f = cam.frustum();
            let mut pages = Vec::new();
            tree.cull(&CullQuery::new(&f), None, &mut pages);
            extra += pages
                .iter()
                .flat_map(|p| tree.page_items(p.0 as usize))
                .filter(|id| !f.intersects_aabb(&items[id.0 as usize].aabb))
                .count();
        }
        assert!(extra > 0);
    }

    #[test]
    fn bad_parameters_are_named() {
        let items = block_grid(10, 1);
        let e = SceneGraphTree::build(
            &items,
            &SceneGraphParams {
                leaf_capacity: 0,
                node_capacity: 8,
            },
        )
        .unwrap_err();
        assert!(matches!(
            e,
            IndexError::BadParam {
                name: "leaf_capacity",
                ..
            }
        ));
        let e = SceneGraphTree::build(
            &items,
            &SceneGraphParams {
                leaf_capacity: 4,
                node_capacity: 1,
            },
        )
        .unwrap_err();
        assert!(matches!(
            e,
            IndexError::BadParam {
                name: "node_capacity",
                ..
            }
        ));
    }

    #[test]
    fn hidden_filter_drops_pages() {
        let items = block_grid(500, 2);
        let tree = SceneGraphTree::build(&items, &SceneGraphParams::default()).unwrap();
        let cam = Camera::new(DVec3::new(-50.0, -50.0, 200.0), 0.8, -0.5);
        let f = cam.frustum();
        let mut all = Vec::new();
        tree.cull(&CullQuery::new(&f), None, &mut all);
        let mut none = Vec::new();
        let mut reject = |_: &Aabb3| false;
        tree.cull(&CullQuery::new(&f), Some(&mut reject), &mut none);
        assert!(!all.is_empty());
        assert!(none.is_empty());
    }
}
