//! A test terrain: a smooth height function over a city's extent (with a margin), sampled on a
//! regular grid with a small hole of missing heights, and the city's buildings stood on it.

use blockwalk::city::export::TerrainTin;
use blockwalk::city::City;
use glam::DVec2;

/// The terrain's height at a world point: a few metres of hills around 30 m, relative to `o`.
pub fn height(o: DVec2, x: f64, y: f64) -> f64 {
    30.0 + 8.0 * ((x - o.x) / 90.0).sin() + 5.0 * ((y - o.y) / 130.0).cos()
}

/// The grid over `city` (its footprints' box grown by two cells), `spacing` metres, with the
/// nodes within 2.5 cells of a point a third of the way across missing (NaN); the grid origin
/// and the node counts.
pub fn grid(city: &City, spacing: f64) -> (DVec2, usize, usize, Vec<f64>) {
    grid_with(city, spacing, height)
}

/// [`grid`] with heights from `f(origin, x, y)`.
pub fn grid_with(
    city: &City,
    spacing: f64,
    f: impl Fn(DVec2, f64, f64) -> f64,
) -> (DVec2, usize, usize, Vec<f64>) {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for b in &city.buildings {
        for c in &b.footprint.exterior().0 {
            lo = lo.min(DVec2::new(c.x, c.y));
            hi = hi.max(DVec2::new(c.x, c.y));
        }
    }
    let o = ((lo / spacing).floor() - 2.0) * spacing;
    let n = ((hi - o) / spacing).ceil() + 3.0;
    let (nx, ny) = (n.x as usize, n.y as usize);
    let hole = o + DVec2::new(nx as f64, ny as f64) * spacing / 3.0;
    let mut h = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let p = o + DVec2::new(i as f64, j as f64) * spacing;
            h.push(if p.distance(hole) < 2.5 * spacing {
                f64::NAN
            } else {
                f(o, p.x, p.y)
            });
        }
    }
    (o, nx, ny, h)
}

/// The TIN of [`grid`] and the city with every building's base on the terrain's height at its
/// footprint's first corner.
pub fn terrain_city(city: &City, spacing: f64) -> (City, TerrainTin) {
    terrain_city_with(city, spacing, height)
}

/// [`terrain_city`] with heights from `f(origin, x, y)`.
pub fn terrain_city_with(
    city: &City,
    spacing: f64,
    f: impl Fn(DVec2, f64, f64) -> f64 + Copy,
) -> (City, TerrainTin) {
    let (o, nx, ny, h) = grid_with(city, spacing, f);
    let tin = TerrainTin::from_grid(o, spacing, nx, ny, &h).unwrap();
    let mut city = city.clone();
    for b in &mut city.buildings {
        let c = b.footprint.exterior().0[0];
        b.base_m = f(o, c.x, c.y);
    }
    (city, tin)
}
