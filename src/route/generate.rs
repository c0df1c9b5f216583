//! Routes for any city: the paper's route (Pina, Serón and Cerezo, §5), a street-level walk, an orbit; and the
//! street graph they walk on.

use super::obstacles::{FootprintCorner, Obstacles, EYE_CLEARANCE_M};
use super::{CameraRoute, KeyFrame, Lens, RouteError};
use crate::city::LocalFrame;
use crate::geom::tolerance::ROUTE_NODE_GRID_M;
use crate::geom::Aabb3;
use crate::geom::Camera;
use geo_types::LineString;
use glam::{DVec2, DVec3};
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};
use std::f64::consts::{FRAC_PI_2, TAU};

/// An undirected street graph in the local frame (x, y metres): vertices of the street lines are
/// nodes (vertices that round to the same point of the
/// [`crate::geom::tolerance::ROUTE_NODE_GRID_M`] grid, 1 cm, are one node; see
/// there why it is finer than the blocks' snap tolerance), consecutive vertices are joined by
/// edges weighted by length.
#[derive(Clone, Debug, Default)]
pub struct StreetGraph {
    /// Node positions, local frame.
    pub nodes: Vec<DVec2>,
    /// Adjacency: `(neighbour, length)` per node.
    pub adjacency: Vec<Vec<(u32, f64)>>,
    /// Connected component of each node.
    component: Vec<u32>,
    /// Node count per component.
    component_size: Vec<u32>,
}

impl StreetGraph {
    /// Builds the graph from street lines in metric world coordinates (e.g.
    /// `BlockLayout::street_edges`), moved into the local frame with `frame`. Non-finite
    /// vertices are skipped.
    pub fn from_world_lines(lines: &[LineString<f64>], frame: &LocalFrame) -> Self {
        let mut g = StreetGraph::default();
        let mut lookup: HashMap<(i64, i64), u32> = HashMap::new();
        for line in lines {
            let mut prev: Option<u32> = None;
            for c in line.coords() {
                if !(c.x.is_finite() && c.y.is_finite()) {
                    prev = None;
                    continue;
                }
                let p = frame.to_local_xy(*c);
                let key = (
                    (p.x / ROUTE_NODE_GRID_M).round() as i64,
                    (p.y / ROUTE_NODE_GRID_M).round() as i64,
                );
                let id = *lookup.entry(key).or_insert_with(|| {
                    g.nodes.push(p);
                    g.adjacency.push(Vec::new());
                    (g.nodes.len() - 1) as u32
                });
                if let Some(a) = prev {
                    if a != id {
                        let w = g.nodes[a as usize].distance(g.nodes[id as usize]);
                        g.adjacency[a as usize].push((id, w));
                        g.adjacency[id as usize].push((a, w));
                    }
                }
                prev = Some(id);
            }
        }
        g.label_components();
        g
    }

    fn label_components(&mut self) {
        let n = self.nodes.len();
        self.component = vec![u32::MAX; n];
        self.component_size.clear();
        let mut stack = Vec::new();
        for s in 0..n {
            if self.component[s] != u32::MAX {
                continue;
            }
            let c = self.component_size.len() as u32;
            let mut size = 0;
            self.component[s] = c;
            stack.push(s as u32);
            while let Some(v) = stack.pop() {
                size += 1;
                for &(w, _) in &self.adjacency[v as usize] {
                    if self.component[w as usize] == u32::MAX {
                        self.component[w as usize] = c;
                        stack.push(w);
                    }
                }
            }
            self.component_size.push(size);
        }
    }

    /// True when the graph has no node.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The node nearest to `p` among the nodes of the largest connected component (so that any
    /// two such nodes are joined by a path); `None` for an empty graph. Ties go to the lower id.
    pub fn nearest_in_main_component(&self, p: DVec2) -> Option<u32> {
        let main = self
            .component_size
            .iter()
            .enumerate()
            .max_by_key(|&(i, s)| (*s, Reverse(i)))?
            .0 as u32;
        let mut best: Option<(f64, u32)> = None;
        for (i, q) in self.nodes.iter().enumerate() {
            if self.component[i] != main {
                continue;
            }
            let d = q.distance_squared(p);
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, i as u32));
            }
        }
        best.map(|(_, i)| i)
    }

    /// Shortest path from `from` to `to` (Dijkstra); the node sequence including both ends, or
    /// `None` when they are not connected.
    pub fn shortest_path(&self, from: u32, to: u32) -> Option<Vec<u32>> {
        let n = self.nodes.len();
        if from as usize >= n || to as usize >= n {
            return None;
        }
        let mut dist = vec![f64::INFINITY; n];
        let mut prev = vec![u32::MAX; n];
        let mut heap = BinaryHeap::new();
        dist[from as usize] = 0.0;
        // Distances are finite and non-negative: their bit patterns order like the values.
        heap.push(Reverse((0u64, from)));
        while let Some(Reverse((dbits, v))) = heap.pop() {
            let d = f64::from_bits(dbits);
            if d > dist[v as usize] {
                continue;
            }
            if v == to {
                break;
            }
            for &(w, len) in &self.adjacency[v as usize] {
                let nd = d + len;
                if nd < dist[w as usize] {
                    dist[w as usize] = nd;
                    prev[w as usize] = v;
                    heap.push(Reverse((nd.to_bits(), w)));
                }
            }
        }
        if !dist[to as usize].is_finite() {
            return None;
        }
        let mut path = vec![to];
        let mut v = to;
        while v != from {
            v = prev[v as usize];
            path.push(v);
        }
        path.reverse();
        Some(path)
    }

    /// The graph a camera at `eye_height` can walk without coming closer than `clearance` to a
    /// building: the nodes at least that far from every building, joined by the edges whose whole
    /// segment is (street lines through a passage, under an arcade or across a courtyard drop
    /// out). Node ids change.
    pub fn walkable(&self, obstacles: &Obstacles, eye_height: f64, clearance: f64) -> StreetGraph {
        if obstacles.is_empty() {
            return self.clone();
        }
        let mut new_id = vec![u32::MAX; self.nodes.len()];
        let mut g = StreetGraph::default();
        for (i, p) in self.nodes.iter().enumerate() {
            if obstacles.is_clear(p.extend(eye_height), clearance) {
                new_id[i] = g.nodes.len() as u32;
                g.nodes.push(*p);
                g.adjacency.push(Vec::new());
            }
        }
        for (i, adj) in self.adjacency.iter().enumerate() {
            let a = new_id[i];
            if a == u32::MAX {
                continue;
            }
            for &(j, w) in adj {
                let b = new_id[j as usize];
                // Each undirected edge once (from its lower old id), then both directions.
                if b == u32::MAX || (j as usize) < i {
                    continue;
                }
                let (pa, pb) = (self.nodes[i], self.nodes[j as usize]);
                if obstacles.segment_distance(pa, pb, eye_height, clearance) >= clearance {
                    g.adjacency[a as usize].push((b, w));
                    g.adjacency[b as usize].push((a, w));
                }
            }
        }
        g.label_components();
        g
    }

    /// Total length of a node path, metres.
    pub fn path_length(&self, path: &[u32]) -> f64 {
        path.windows(2)
            .map(|w| self.nodes[w[0] as usize].distance(self.nodes[w[1] as usize]))
            .sum()
    }
}

/// Drops points closer than `min_gap` to the last kept one; the last point always ends the list.
fn thin(points: Vec<DVec2>, min_gap: f64) -> Vec<DVec2> {
    let Some(&end) = points.last() else {
        return points;
    };
    let mut out: Vec<DVec2> = Vec::with_capacity(points.len());
    for p in points {
        if out.last().is_none_or(|q| q.distance(p) >= min_gap) {
            out.push(p);
        }
    }
    if out.last() != Some(&end) {
        if out.len() > 1 {
            out.pop();
        }
        out.push(end);
    }
    out.dedup_by(|a, b| a.distance(*b) < 1e-9);
    out
}

/// Key frames walking along `points` at eye height `eye`, looking along the way (each key looks
/// toward the next point), starting at `t0` with `speed` m/s. Returns the keys and the end time.
fn walk_keys(points: &[DVec2], eye: f64, speed: f64, t0: f64) -> (Vec<KeyFrame>, f64) {
    let mut keys = Vec::with_capacity(points.len());
    let mut t = t0;
    let mut yaw = 0.0;
    for (i, p) in points.iter().enumerate() {
        if i > 0 {
            t += points[i - 1].distance(*p) / speed;
        }
        if let Some(next) = points.get(i + 1) {
            let d = *next - *p;
            yaw = d.y.atan2(d.x);
        }
        keys.push(KeyFrame::new(t, p.extend(eye), yaw, 0.0));
    }
    (keys, t)
}

/// Turns every key whose view (its heading, its pitch) has no building within 500 m to the
/// nearest heading, by 45° steps, that has one ([`heading_with_city_in_view`]): a walk looks
/// along its way unless the way leads out of the city.
fn face_the_city(keys: &mut [KeyFrame], lens: Lens, obstacles: &Obstacles) {
    for k in keys.iter_mut() {
        let (yaw, pitch) = super::yaw_pitch_from_orientation(k.orientation);
        let turned = heading_with_city_in_view(k.position, yaw, pitch, lens, obstacles);
        if turned != yaw {
            k.orientation = super::orientation_from_yaw_pitch(turned, pitch);
        }
    }
}

/// Builds the route from `keys`, then samples every segment (a step of a quarter of
/// `clearance`) and, where the spline's curve comes closer than `clearance` to a building (it
/// cuts a street corner), makes both ends of that segment corners, which turns the segment into
/// the straight chord between its keys (clear when its keys were chosen clear). Repeats until
/// nothing changes (at most a few rounds: corners only spread to neighbouring segments).
fn keep_clear(
    name: &str,
    mut keys: Vec<KeyFrame>,
    lens: Lens,
    obstacles: &Obstacles,
    clearance: f64,
) -> Result<CameraRoute, RouteError> {
    loop {
        let route = CameraRoute::new(name, keys.clone(), lens)?;
        if obstacles.is_empty() {
            return Ok(route);
        }
        let mut changed = false;
        for i in 0..keys.len() - 1 {
            if keys[i].corner && keys[i + 1].corner {
                continue;
            }
            let (t0, t1) = (keys[i].time, keys[i + 1].time);
            let len = keys[i].position.distance(keys[i + 1].position);
            let n = (len / (0.25 * clearance)).ceil().clamp(1.0, 20_000.0) as usize;
            let blocked = (0..=n).any(|k| {
                let p = route
                    .camera_at(t0 + (t1 - t0) * k as f64 / n as f64)
                    .position;
                !obstacles.is_clear(p, clearance)
            });
            if blocked {
                keys[i].corner = true;
                keys[i + 1].corner = true;
                changed = true;
            }
        }
        if !changed {
            return Ok(route);
        }
    }
}

/// Parameters of the paper's route (Pina, Serón and Cerezo, §5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaperRouteParams {
    /// Eye height above the ground while walking, metres.
    pub eye_height: f64,
    /// How far outside the city's box the walk starts, as a fraction of the box's larger side.
    pub start_margin: f64,
    /// Height reached by the rise above the highest roof, metres.
    pub clearance: f64,
    /// Share of the route's time spent walking in.
    pub walk_share: f64,
    /// Share of the route's time spent rising (the rest is the diagonal descent).
    pub rise_share: f64,
    /// Route duration, seconds (sampling chooses the frame count).
    pub duration: f64,
    /// Pitch at the end of the descent, radians (negative: looking down a little). The descent
    /// starts straight down and turns to this pitch on the way, so that the last frames look at
    /// the city, not at the ground at the camera's feet.
    pub landing_pitch: f64,
    /// Least distance from the eye to any building anywhere on the route, metres.
    pub clearance_m: f64,
}

impl Default for PaperRouteParams {
    /// The proportions of Pina, Serón and Cerezo, Fig. 4: the rise spans frames 48–140 of about 200, so about a
    /// quarter of the time walks in, 45 % rises, the rest descends.
    fn default() -> Self {
        Self {
            eye_height: 1.7,
            start_margin: 0.05,
            clearance: 60.0,
            walk_share: 0.25,
            rise_share: 0.45,
            duration: 60.0,
            landing_pitch: -10f64.to_radians(),
            clearance_m: EYE_CLEARANCE_M,
        }
    }
}

/// The paper's route (Pina, Serón and Cerezo, §5) for a city whose geometry lies in `bounds` (local frame):
/// it starts outside the city at street level (south of the box, `start_margin` out), walks to
/// the centre (along the street network when `streets` has nodes: the shortest path, over the
/// streets a camera can walk clear of `obstacles`, from the street node nearest the start to the
/// node nearest the centre; else straight, stopping before the first building in the way), rises
/// vertically above the roofs while turning to look straight down, then flies diagonally down to
/// the ground, straight down at first and turning to `landing_pitch`, to the clear street node
/// (or point) nearest to a quarter of the box's diagonal north-east of the centre whose descent
/// passes no building.
///
/// The eye keeps `params.clearance_m` from every building of `obstacles` on every frame (the
/// walk's curve is straightened where it would cut a corner, see [`StreetGraph::walkable`]), and
/// the landing heading is the descent's, or the nearest turn of it by 45° steps that has a
/// building in view.
///
/// Deviation: the paper gives no numbers for the heights or the landing point; the defaults in
/// [`PaperRouteParams`] are ours.
pub fn paper_route(
    bounds: &Aabb3,
    streets: Option<&StreetGraph>,
    obstacles: &Obstacles,
    params: &PaperRouteParams,
    lens: Lens,
) -> Result<CameraRoute, RouteError> {
    let bad = |problem: &str| RouteError::Bad {
        route: "paper".into(),
        problem: problem.into(),
    };
    if bounds.is_empty() || !bounds.min.is_finite() || !bounds.max.is_finite() {
        return Err(bad("the city has no geometry to route through"));
    }
    let ok = params.walk_share > 0.0
        && params.rise_share > 0.0
        && params.walk_share + params.rise_share < 1.0
        && params.duration > 0.0
        && params.eye_height > 0.0
        && params.clearance_m >= 0.0
        && params.clearance_m.is_finite();
    if !ok {
        return Err(bad(
            "route shares must be positive and sum below 1; duration and eye height positive; clearance finite and not negative",
        ));
    }
    let eye = params.eye_height;
    let gap = params.clearance_m;
    let clear = |p: DVec2| obstacles.is_clear(p.extend(eye), gap);
    let ext = bounds.extent();
    let side = ext.x.max(ext.y).max(1.0);
    let centre = bounds.center().truncate();
    let anchor = DVec2::new(centre.x, bounds.min.y - params.start_margin * side);

    let graph = streets
        .filter(|g| !g.is_empty())
        .map(|g| g.walkable(obstacles, eye, gap));
    let mut walk: Vec<DVec2> = Vec::new();
    if let Some(g) = &graph {
        let s = g.nearest_in_main_component(anchor);
        let e = g.nearest_in_main_component(centre);
        if let (Some(s), Some(e)) = (s, e) {
            if let Some(path) = g.shortest_path(s, e) {
                let first = g.nodes[s as usize];
                // The way in from outside, unless a building stands in it.
                if clear(anchor) && obstacles.segment_distance(anchor, first, eye, gap) >= gap {
                    walk.push(anchor);
                }
                walk.extend(path.iter().map(|&i| g.nodes[i as usize]));
            }
        }
    }
    if walk.len() < 2 {
        walk = straight_walk(anchor, centre, &clear);
    }
    let walk = thin(walk, 1.0);
    let walk = if walk.len() < 2 {
        // Nowhere to walk (the start is shut in): step one metre back out.
        vec![anchor - DVec2::Y, anchor]
    } else {
        walk
    };

    let walk_len: f64 = walk.windows(2).map(|w| w[0].distance(w[1])).sum();
    let t_walk = params.duration * params.walk_share;
    let speed = walk_len.max(1e-3) / t_walk;
    let (mut keys, t_end) = walk_keys(&walk, eye, speed, 0.0);
    face_the_city(&mut keys, lens, obstacles);
    let top_z = bounds.max.z.max(obstacles.max_height()).max(0.0) + params.clearance.max(gap);
    let last = *keys.last().expect("a walk has keys");
    let (yaw, _) = super::yaw_pitch_from_orientation(last.orientation);
    let here = last.position.truncate();
    // Keep the heading of the walk while turning to look down; the end of the walk is a corner.
    keys.last_mut().expect("a walk has keys").corner = true;
    let t_rise = t_end + params.duration * params.rise_share;
    keys.push(KeyFrame::new(t_rise, here.extend(top_z), yaw, -FRAC_PI_2).corner());
    let diag = DVec2::new(ext.x, ext.y).length().max(1.0);
    let target = here + DVec2::new(1.0, 1.0).normalize() * (0.25 * diag);
    let top = here.extend(top_z);
    let descent_clear = |p: DVec2| clear(p) && obstacles.segment_is_clear(top, p.extend(eye), gap);
    let land = landing_point(target, graph.as_ref(), &descent_clear).unwrap_or(here);
    let fly = land - here;
    let fly_yaw = if fly.length() > 1e-6 {
        fly.y.atan2(fly.x)
    } else {
        yaw
    };
    let land_yaw = heading_with_city_in_view(
        land.extend(eye),
        fly_yaw,
        params.landing_pitch,
        lens,
        obstacles,
    );
    // Straight down at the top, turning to the landing pitch on the way down (Pina, Serón and Cerezo, Fig. 4
    // flies down "facing the floor"; the last frames look at the city, not at the ground).
    keys.push(KeyFrame::new(
        params.duration,
        land.extend(eye),
        land_yaw,
        params.landing_pitch,
    ));
    keep_clear("paper", keys, lens, obstacles, gap)
}

/// The straight walk from `from` to `to`, stopping at the last metre step before the first point
/// that is not `clear` (the whole line when nothing is in the way).
fn straight_walk(from: DVec2, to: DVec2, clear: &dyn Fn(DVec2) -> bool) -> Vec<DVec2> {
    let n = from.distance(to).ceil().max(1.0) as usize;
    let mut end = from;
    for i in 0..=n {
        let p = from.lerp(to, i as f64 / n as f64);
        if !clear(p) {
            break;
        }
        end = p;
    }
    vec![from, end]
}

/// The landing point nearest `target` for which `ok` holds: among the walkable street nodes when
/// there is a graph, else among points on rings around `target` (5 m apart, 16 per ring, out to
/// 1 km). `None` when none qualifies.
fn landing_point(
    target: DVec2,
    graph: Option<&StreetGraph>,
    ok: &dyn Fn(DVec2) -> bool,
) -> Option<DVec2> {
    let mut candidates: Vec<DVec2> = match graph {
        Some(g) if !g.is_empty() => g.nodes.clone(),
        _ => {
            let mut c = vec![target];
            for ring in 1..=200 {
                let r = 5.0 * ring as f64;
                c.extend((0..16).map(|k| {
                    let a = TAU * k as f64 / 16.0;
                    target + DVec2::new(a.cos(), a.sin()) * r
                }));
            }
            c
        }
    };
    candidates.sort_by(|a, b| {
        a.distance_squared(target)
            .total_cmp(&b.distance_squared(target))
    });
    candidates.into_iter().take(2000).find(|p| ok(*p))
}

/// `yaw`, or the nearest turn of it by 45° steps, whose view from `eye` at `pitch` has a
/// building in it (within 500 m); `yaw` itself when none has or there are no buildings.
fn heading_with_city_in_view(
    eye: DVec3,
    yaw: f64,
    pitch: f64,
    lens: Lens,
    obstacles: &Obstacles,
) -> f64 {
    if obstacles.is_empty() {
        return yaw;
    }
    let step = std::f64::consts::FRAC_PI_4;
    [0.0, 1.0, -1.0, 2.0, -2.0, 3.0, -3.0, 4.0]
        .into_iter()
        .map(|k| yaw + k * step)
        .find(|&y| {
            let mut c = Camera::new(eye, y, pitch);
            c.fov_y = lens.fov_y;
            c.aspect = lens.aspect;
            c.near = lens.near;
            c.far = lens.far.min(500.0);
            obstacles.any_in_view(&c.frustum(), eye.truncate(), 500.0)
        })
        .unwrap_or(yaw)
}

/// A walk at eye height along the shortest street path between the street nodes nearest to
/// `from` and `to` (local frame), at `speed` m/s, looking along the way (or, where the way
/// leads out of the city, turned by 45° steps toward a building), over the streets a
/// camera can walk [`EYE_CLEARANCE_M`] clear of `obstacles` ([`StreetGraph::walkable`]; the
/// curve is straightened where it would cut a corner).
pub fn street_walk(
    graph: &StreetGraph,
    obstacles: &Obstacles,
    from: DVec2,
    to: DVec2,
    eye_height: f64,
    speed: f64,
    lens: Lens,
) -> Result<CameraRoute, RouteError> {
    let bad = |problem: String| RouteError::Bad {
        route: "street".into(),
        problem,
    };
    if !(speed > 0.0 && speed.is_finite()) {
        return Err(bad(format!("speed must be positive, got {speed}")));
    }
    let graph = &graph.walkable(obstacles, eye_height, EYE_CLEARANCE_M);
    let s = graph
        .nearest_in_main_component(from)
        .ok_or_else(|| bad("no street node is clear of the buildings".into()))?;
    let e = graph
        .nearest_in_main_component(to)
        .ok_or_else(|| bad("no street node is clear of the buildings".into()))?;
    let path = graph
        .shortest_path(s, e)
        .ok_or_else(|| bad("no street path between the two points".into()))?;
    let pts = thin(path.iter().map(|&i| graph.nodes[i as usize]).collect(), 1.0);
    if pts.len() < 2 {
        return Err(bad(format!(
            "the two points snap to the same street node at ({:.1}, {:.1})",
            graph.nodes[s as usize].x, graph.nodes[s as usize].y
        )));
    }
    let (mut keys, _) = walk_keys(&pts, eye_height, speed, 0.0);
    face_the_city(&mut keys, lens, obstacles);
    keep_clear("street", keys, lens, obstacles, EYE_CLEARANCE_M)
}

/// Parameters of [`corner_walk`].
#[derive(Clone, Debug, PartialEq)]
pub struct CornerWalkParams {
    /// Eye height above the ground, metres.
    pub eye_height: f64,
    /// Distances from the facades at which the corners are rounded, metres, used in turn (one
    /// per corner passed).
    pub offsets: Vec<f64>,
    /// How far along each facade the walk runs beside it before and after the corner, metres
    /// (shortened to 80 % of a shorter wall).
    pub approach_m: f64,
    /// A street node passes the convex building corners within this distance, metres.
    pub reach_m: f64,
    /// Least turn of the outline at a corner worth rounding, radians.
    pub min_turn: f64,
    /// Least distance from the eye to any building anywhere on the route, metres.
    pub clearance_m: f64,
    /// Walking speed between corners, metres per second.
    pub speed: f64,
    /// Walking speed beside and around a corner, metres per second (slower, so that evenly
    /// timed frames crowd where the occluders' shadows are hardest).
    pub corner_speed: f64,
    /// Near plane, metres: below the least offset, so the walls beside the eye stay closed.
    pub near: f64,
    /// Largest angle between two points of a corner's arc, radians.
    pub arc_step: f64,
}

impl Default for CornerWalkParams {
    fn default() -> Self {
        Self {
            eye_height: 1.7,
            offsets: vec![0.3, 0.5, 0.7, 1.0],
            approach_m: 4.0,
            reach_m: 30.0,
            min_turn: 30f64.to_radians(),
            clearance_m: 0.25,
            speed: 1.4,
            corner_speed: 0.35,
            near: 0.1,
            arc_step: 15f64.to_radians(),
        }
    }
}

impl CornerWalkParams {
    fn check(&self) -> Result<(), String> {
        let pos = |v: f64| v > 0.0 && v.is_finite();
        if !(pos(self.eye_height)
            && pos(self.approach_m)
            && pos(self.reach_m)
            && pos(self.speed)
            && pos(self.corner_speed)
            && pos(self.near)
            && pos(self.arc_step))
        {
            return Err(
                "eye height, approach, reach, speeds, near plane and arc step must be positive and finite"
                    .into(),
            );
        }
        if !(self.clearance_m.is_finite() && self.clearance_m >= 0.0) {
            return Err(format!(
                "clearance {} m: must be finite and not negative",
                self.clearance_m
            ));
        }
        if !(self.min_turn.is_finite() && (0.0..std::f64::consts::PI).contains(&self.min_turn)) {
            return Err(format!(
                "least turn {} rad: must be in [0, π)",
                self.min_turn
            ));
        }
        if self.offsets.is_empty()
            || self
                .offsets
                .iter()
                .any(|&o| !(o.is_finite() && o > self.clearance_m && o > self.near))
        {
            return Err(format!(
                "offsets {:?} m: give at least one, each finite and beyond the clearance ({} m) and the near plane ({} m)",
                self.offsets, self.clearance_m, self.near
            ));
        }
        Ok(())
    }
}

/// The points of one corner visit: beside the arriving wall `approach` metres before the
/// corner at `offset` from it, around the corner on the arc of radius `offset`, and beside the
/// leaving wall `approach` metres after it.
fn corner_visit(c: &FootprintCorner, offset: f64, approach: f64, arc_step: f64) -> Vec<DVec2> {
    let before = approach.min(0.8 * c.incoming_len);
    let after = approach.min(0.8 * c.outgoing_len);
    let n_in = c.incoming_normal();
    let mut pts = vec![c.at - c.incoming * before + n_in * offset];
    let steps = (c.turn / arc_step).ceil().max(1.0) as usize;
    for k in 0..=steps {
        let a = c.turn * k as f64 / steps as f64;
        pts.push(c.at + DVec2::from_angle(a).rotate(n_in) * offset);
    }
    pts.push(c.at + c.outgoing * after + c.outgoing_normal() * offset);
    pts
}

/// A street-level walk that hugs building corners, the hardest case for occluder shadows: along
/// the shortest street paths between consecutive `waypoints` (local frame) over the streets a
/// camera can walk [`EYE_CLEARANCE_M`] clear of `obstacles`, and at every street node where
/// three or more streets meet (a block corner) it leaves the street to round the nearest convex
/// building corner within `reach_m`: beside the arriving facade, around the corner at one of
/// `offsets` from both walls, and beside the leaving facade, looking along the way, then back
/// to the street. A corner is rounded only when the whole visit and the straight legs to and
/// from it keep `clearance_m` from every building (a corner touching a neighbour is passed by);
/// each corner once. The eye never comes nearer than `clearance_m` to any building on any
/// frame (the curve is straightened where it would come nearer).
///
/// # Errors
/// [`RouteError::Bad`] for bad parameters, fewer than two waypoints, no walkable street path,
/// or when no corner can be rounded.
pub fn corner_walk(
    graph: &StreetGraph,
    obstacles: &Obstacles,
    waypoints: &[DVec2],
    params: &CornerWalkParams,
    mut lens: Lens,
) -> Result<CameraRoute, RouteError> {
    let bad = |problem: String| RouteError::Bad {
        route: "corners".into(),
        problem,
    };
    params.check().map_err(&bad)?;
    if waypoints.len() < 2 {
        return Err(bad(format!("needs two waypoints, got {}", waypoints.len())));
    }
    let eye = params.eye_height;
    let gap = params.clearance_m;
    let graph = &graph.walkable(obstacles, eye, EYE_CLEARANCE_M);
    let mut path: Vec<u32> = Vec::new();
    for w in waypoints.windows(2) {
        let s = graph
            .nearest_in_main_component(w[0])
            .ok_or_else(|| bad("no street node is clear of the buildings".into()))?;
        let e = graph
            .nearest_in_main_component(w[1])
            .ok_or_else(|| bad("no street node is clear of the buildings".into()))?;
        let p = graph
            .shortest_path(s, e)
            .ok_or_else(|| bad("no street path between two waypoints".into()))?;
        for v in p {
            if path.last() != Some(&v) {
                path.push(v);
            }
        }
    }
    if path.len() < 2 {
        return Err(bad("the waypoints snap to the same street node".into()));
    }
    let seg_clear = |a: DVec2, b: DVec2| obstacles.segment_distance(a, b, eye, gap) >= gap;
    // Points and whether the way to each point runs beside a corner (slow).
    let mut pts: Vec<(DVec2, bool)> = Vec::new();
    let mut visited: Vec<DVec2> = Vec::new();
    let mut rounded = 0usize;
    for (i, &v) in path.iter().enumerate() {
        let node = graph.nodes[v as usize];
        pts.push((node, false));
        if graph.adjacency[v as usize].len() < 3 {
            continue;
        }
        let next = path.get(i + 1).map(|&w| graph.nodes[w as usize]);
        let offset = params.offsets[rounded % params.offsets.len()];
        let corners = obstacles.convex_corners_near(node, params.reach_m, params.min_turn);
        for c in corners.iter().take(8) {
            if visited.iter().any(|q| q.distance(c.at) < 1e-6) {
                continue;
            }
            let visit = corner_visit(c, offset, params.approach_m, params.arc_step);
            let ok = seg_clear(node, visit[0]) && visit.windows(2).all(|w| seg_clear(w[0], w[1]));
            if !ok {
                continue;
            }
            let end = visit[visit.len() - 1];
            // Straight on to the next node, else back by this one.
            let back = match next {
                Some(n) if seg_clear(end, n) => false,
                Some(_) => {
                    if !seg_clear(end, node) {
                        continue;
                    }
                    true
                }
                None => false,
            };
            pts.push((visit[0], false));
            pts.extend(visit[1..].iter().map(|&p| (p, true)));
            if back {
                pts.push((node, false));
            }
            visited.push(c.at);
            rounded += 1;
            break;
        }
    }
    if rounded == 0 {
        return Err(bad(format!(
            "no building corner within {} m of the street path can be rounded {} m clear of every building",
            params.reach_m, gap
        )));
    }
    pts.dedup_by(|a, b| a.0.distance(b.0) < 1e-6);
    let mut keys = Vec::with_capacity(pts.len());
    let mut t = 0.0;
    for (i, &(p, slow)) in pts.iter().enumerate() {
        if i > 0 {
            let speed = if slow {
                params.corner_speed
            } else {
                params.speed
            };
            t += pts[i - 1].0.distance(p) / speed;
        }
        let ahead = pts
            .get(i + 1)
            .map(|q| q.0 - p)
            .unwrap_or_else(|| p - pts[i.saturating_sub(1)].0);
        keys.push(KeyFrame::new(t, p.extend(eye), ahead.y.atan2(ahead.x), 0.0));
    }
    lens.near = params.near;
    keep_clear("corners", keys, lens, obstacles, gap)
}

/// Share of the buildings' footprint area that the orbit's spread covers: the radius the
/// orbit scales is the distance from the buildings' centre within which this share of the area
/// lies (the 90th percentile), so that a few outlying buildings far away neither move the centre
/// nor widen the circle.
pub const ORBIT_SPREAD_QUANTILE: f64 = 0.9;

/// Rounds of trimming in [`buildings_centre_and_spread`]: each recentres on the buildings within
/// the last spread.
const ORBIT_CENTRE_ROUNDS: usize = 4;

/// The area-weighted `q`-quantile of `values` (`(value, weight)`; weights not positive count as
/// none, all of them none as equal): the least value with at least `q` of the weight at or
/// below it. `None` for no values.
fn weighted_quantile(mut values: Vec<(f64, f64)>, q: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(|a, b| a.0.total_cmp(&b.0));
    let weighted: f64 = values.iter().map(|v| v.1.max(0.0)).sum();
    let equal = !(weighted > 0.0 && weighted.is_finite());
    let weight = |w: f64| if equal { 1.0 } else { w.max(0.0) };
    let total = if equal { values.len() as f64 } else { weighted };
    let need = q.clamp(0.0, 1.0) * total;
    let mut acc = 0.0;
    for &(v, w) in &values {
        acc += weight(w);
        if acc >= need * (1.0 - 1e-12) {
            return Some(v);
        }
    }
    values.last().map(|v| v.0)
}

/// The buildings' centre and spread in plan (local frame): the centroid of their footprints
/// weighted by footprint area, recentred a few times on the buildings within the spread (which
/// moves it onto the densest part when outliers lie far away), and the area-weighted
/// [`ORBIT_SPREAD_QUANTILE`] distance of the footprint centroids from it. `None` without
/// buildings.
fn buildings_centre_and_spread(obstacles: &Obstacles) -> Option<(DVec2, f64)> {
    let pts = obstacles.plan_centroids();
    if pts.is_empty() {
        return None;
    }
    let mean = |keep: &dyn Fn(DVec2) -> bool| -> Option<DVec2> {
        let (mut sum, mut total, mut plain, mut n) = (DVec2::ZERO, 0.0, DVec2::ZERO, 0usize);
        for &(c, a) in pts.iter().filter(|(c, _)| keep(*c)) {
            sum += c * a;
            total += a;
            plain += c;
            n += 1;
        }
        if total > 0.0 {
            Some(sum / total)
        } else if n > 0 {
            Some(plain / n as f64)
        } else {
            None
        }
    };
    let spread = |centre: DVec2| {
        weighted_quantile(
            pts.iter().map(|&(c, a)| (c.distance(centre), a)).collect(),
            ORBIT_SPREAD_QUANTILE,
        )
        .unwrap_or(0.0)
    };
    let mut centre = mean(&|_| true)?;
    for _ in 0..ORBIT_CENTRE_ROUNDS {
        let r = spread(centre);
        match mean(&|c| c.distance(centre) <= r) {
            Some(c) => centre = c,
            None => break,
        }
    }
    Some((centre, spread(centre)))
}

/// An orbit around the buildings: one turn in `duration` seconds, counter-clockwise, starting
/// south, at `height` metres above the highest roof (of `bounds` and of `obstacles`), looking
/// down at the centre of the buildings on the ground.
///
/// With buildings, the centre is their footprint centroid weighted by footprint area, trimmed
/// to the densest part ([`ORBIT_SPREAD_QUANTILE`]: the buildings within the distance holding 90 %
/// of the area), and the radius is `radius_factor` × that distance (at least 1 m): a sparse city
/// with outliers kilometres away is framed by its buildings, not by its box, and every frame
/// looks at them. Without buildings, the centre of `bounds` and `radius_factor` × the box's
/// larger half-side. The pitch aims at the centre on the ground, and the lens's far plane is
/// raised, where needed, to reach past the far side of the spread.
pub fn orbit_route(
    bounds: &Aabb3,
    obstacles: &Obstacles,
    radius_factor: f64,
    height: f64,
    duration: f64,
    mut lens: Lens,
) -> Result<CameraRoute, RouteError> {
    let positive = |v: f64| v > 0.0; // false for NaN
    let framed =
        buildings_centre_and_spread(obstacles).filter(|(c, s)| c.is_finite() && s.is_finite());
    if (bounds.is_empty() && framed.is_none()) || !positive(duration) || !positive(radius_factor) {
        return Err(RouteError::Bad {
            route: "orbit".into(),
            problem: "needs a non-empty city, positive radius and duration".into(),
        });
    }
    let (c, spread) = match framed {
        Some((c, s)) => (c, s.max(1.0)),
        None => {
            let ext = bounds.extent();
            (bounds.center().truncate(), 0.5 * ext.x.max(ext.y).max(1.0))
        }
    };
    let r = radius_factor * spread;
    // Above every roof (of the box and of any building outside it), so the eye is always clear.
    let top = if bounds.is_empty() { 0.0 } else { bounds.max.z };
    let z = top.max(obstacles.max_height()).max(0.0) + height.max(EYE_CLEARANCE_M);
    let target = DVec3::new(c.x, c.y, 0.0);
    let reach = (r + spread).hypot(z) * 1.05;
    if reach.is_finite() && reach > lens.far {
        lens.far = reach;
    }
    let n = 24;
    let keys = (0..=n)
        .map(|i| {
            let a = -FRAC_PI_2 + TAU * i as f64 / n as f64;
            let eye = DVec3::new(c.x + r * a.cos(), c.y + r * a.sin(), z);
            let cam = crate::geom::Camera::looking_at(eye, target);
            KeyFrame::new(duration * i as f64 / n as f64, eye, cam.yaw, cam.pitch)
        })
        .collect();
    CameraRoute::new("orbit", keys, lens)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame0() -> LocalFrame {
        LocalFrame {
            origin: DVec3::new(1000.0, 2000.0, 0.0),
        }
    }

    /// A 3×3 grid of streets, 100 m apart, in world coordinates.
    fn grid_lines() -> Vec<LineString<f64>> {
        let mut lines = Vec::new();
        for i in 0..3 {
            let v = 1000.0 + 100.0 * i as f64;
            lines.push(LineString::from(vec![
                (v, 2000.0),
                (v, 2100.0),
                (v, 2200.0),
            ]));
            let h = 2000.0 + 100.0 * i as f64;
            lines.push(LineString::from(vec![
                (1000.0, h),
                (1100.0, h),
                (1200.0, h),
            ]));
        }
        lines
    }

    #[test]
    fn dijkstra_matches_manhattan_distance_on_a_grid() {
        let g = StreetGraph::from_world_lines(&grid_lines(), &frame0());
        assert_eq!(g.nodes.len(), 9);
        let a = g.nearest_in_main_component(DVec2::new(0.0, 0.0)).unwrap();
        let b = g
            .nearest_in_main_component(DVec2::new(200.0, 200.0))
            .unwrap();
        let p = g.shortest_path(a, b).unwrap();
        assert!((g.path_length(&p) - 400.0).abs() < 1e-9);
        assert_eq!(p.len(), 5);
    }

    /// Box buildings `margin` metres inside each block of [`grid_lines`], in world coordinates.
    fn grid_buildings(margin: f64) -> Vec<crate::city::Building> {
        use crate::city::model::{BuildingId, HeightSource};
        use geo_types::polygon;
        let mut out = Vec::new();
        for i in 0..2 {
            for j in 0..2 {
                let (x0, y0) = (1000.0 + 100.0 * i as f64, 2000.0 + 100.0 * j as f64);
                let (x1, y1) = (x0 + 100.0 - margin, y0 + 100.0 - margin);
                let (x0, y0) = (x0 + margin, y0 + margin);
                out.push(crate::city::Building {
                    id: BuildingId(out.len() as u32),
                    source_id: format!("t:{}", out.len()),
                    footprint: polygon![(x: x0, y: y0), (x: x1, y: y0), (x: x1, y: y1), (x: x0, y: y1)],
                    height_m: 15.0,
                    min_height_m: 0.0,
                    base_m: 0.0,
                    height_source: HeightSource::Height,
                    attributes: Default::default(),
                });
            }
        }
        out
    }

    #[test]
    fn the_corner_walk_rounds_corners_close_and_never_enters_a_building() {
        let frame = frame0();
        let g = StreetGraph::from_world_lines(&grid_lines(), &frame);
        let buildings = grid_buildings(6.0);
        let obstacles = Obstacles::from_buildings(&buildings, &frame);
        let params = CornerWalkParams::default();
        let waypoints = [
            DVec2::new(0.0, 0.0),
            DVec2::new(200.0, 200.0),
            DVec2::new(200.0, 0.0),
            DVec2::new(0.0, 200.0),
        ];
        let route = corner_walk(&g, &obstacles, &waypoints, &params, Lens::default()).unwrap();
        assert_eq!(route.lens.near, params.near);
        // The building corners in the local frame (each block's box, 6 m in).
        let corners: Vec<DVec2> = buildings
            .iter()
            .flat_map(|b| {
                b.footprint
                    .exterior()
                    .coords()
                    .take(4)
                    .copied()
                    .collect::<Vec<_>>()
            })
            .map(|c| frame.to_local_xy(c))
            .collect();
        let inside = |p: DVec2| {
            buildings.iter().any(|b| {
                let r = b.footprint.exterior();
                let (lo, hi) = (frame.to_local_xy(r.0[0]), frame.to_local_xy(r.0[2]));
                p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y
            })
        };
        let cams = route.sample(40_000);
        let mut passed = vec![f64::INFINITY; corners.len()];
        for c in &cams {
            let p = c.position;
            assert!((p.z - params.eye_height).abs() < 1e-9, "{p}");
            assert!(!inside(p.truncate()), "eye inside a building at {p}");
            let d = obstacles.distance(p, 2.0);
            assert!(
                d >= params.clearance_m - 1e-6,
                "eye {d} m from a wall at {p}"
            );
            for (k, q) in corners.iter().enumerate() {
                passed[k] = passed[k].min(q.distance(p.truncate()));
            }
        }
        // The walk crosses the inner intersections: several corners are rounded within the
        // largest offset (1 m), none nearer than the clearance.
        let close = passed.iter().filter(|&&d| d <= 1.0 + 1e-3).count();
        assert!(
            close >= 4,
            "corners passed within 1 m: {close} ({passed:?})"
        );
        assert!(passed.iter().all(|&d| d >= params.clearance_m - 1e-6));
        // A frame step of 0.1 m keeps the check above dense: the route is short enough.
        let len: f64 = cams
            .windows(2)
            .map(|w| w[0].position.distance(w[1].position))
            .sum();
        assert!(len / 40_000.0 < 0.1, "{len} m");
    }

    #[test]
    fn a_corner_walk_with_no_corner_in_reach_is_refused() {
        let frame = frame0();
        let g = StreetGraph::from_world_lines(&grid_lines(), &frame);
        // Buildings 40 m inside their blocks: every corner is 56 m from the nearest street node.
        let obstacles = Obstacles::from_buildings(&grid_buildings(40.0), &frame);
        let waypoints = [DVec2::new(0.0, 0.0), DVec2::new(200.0, 200.0)];
        let params = CornerWalkParams::default();
        let e = corner_walk(&g, &obstacles, &waypoints, &params, Lens::default()).unwrap_err();
        assert!(e.to_string().contains("no building corner"), "{e}");
        // Within a reach of 60 m they are rounded.
        let far = CornerWalkParams {
            reach_m: 60.0,
            ..Default::default()
        };
        assert!(corner_walk(&g, &obstacles, &waypoints, &far, Lens::default()).is_ok());
        let bad = CornerWalkParams {
            offsets: vec![0.1],
            ..Default::default()
        };
        let e = corner_walk(&g, &obstacles, &waypoints, &bad, Lens::default()).unwrap_err();
        assert!(e.to_string().contains("offsets"), "{e}");
    }

    #[test]
    fn disconnected_nodes_are_not_chosen() {
        let mut lines = grid_lines();
        lines.push(LineString::from(vec![(900.0, 1900.0), (901.0, 1900.0)]));
        let g = StreetGraph::from_world_lines(&lines, &frame0());
        let near_island = g
            .nearest_in_main_component(DVec2::new(-100.0, -100.0))
            .unwrap();
        assert_eq!(g.nodes[near_island as usize], DVec2::new(0.0, 0.0));
    }
}
