//! The plan-view predicates read rings in place: `point_in_ring`, `ring_signed_area` and
//! `orient2d` allocate nothing, whichever point type the ring is made of.
//!
//! Checked with a counting global allocator (this test binary only; the library itself forbids
//! unsafe code). The count is per thread, so the test harness's own allocations on other threads
//! do not disturb it.

use blockwalk::geom::predicates::{orient2d, point_in_ring, ring_signed_area, Location};
use geo_types::Coord;
use glam::DVec2;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: every call is forwarded unchanged to the system allocator; the thread-local counter is
// const-initialised and has no destructor, so touching it never allocates or re-enters.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> u64 {
    ALLOCATIONS.with(|c| c.get())
}

#[test]
fn point_in_ring_and_area_allocate_nothing() {
    let n = 64;
    let ring: Vec<DVec2> = (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            let r = if i % 2 == 0 { 10.0 } else { 6.0 };
            DVec2::new(5.0e5 + r * a.cos(), 5.4e6 + r * a.sin())
        })
        .collect();
    let coords: Vec<Coord<f64>> = ring.iter().map(|p| Coord { x: p.x, y: p.y }).collect();
    let probes: Vec<DVec2> = (0..200)
        .map(|k| DVec2::new(5.0e5 - 12.0 + 0.12 * k as f64, 5.4e6 + 0.05 * k as f64))
        .collect();

    // Make sure the counter works at all (a vacuous test would pass anyway).
    let before = allocations();
    let v = std::hint::black_box(vec![1u8; 16]);
    assert!(
        allocations() > before,
        "the counting allocator is not in use"
    );
    drop(v);

    let before = allocations();
    let (mut inside, mut outside) = (0, 0);
    for &p in &probes {
        let a = point_in_ring(p, &ring);
        let b = point_in_ring(Coord { x: p.x, y: p.y }, &coords);
        assert_eq!(a, b);
        match a {
            Location::Inside => inside += 1,
            Location::Outside => outside += 1,
            Location::OnBoundary => {}
        }
        std::hint::black_box(orient2d(ring[0], ring[1], p));
    }
    let area = ring_signed_area(&ring) + ring_signed_area(&coords);
    assert_eq!(allocations(), before, "a predicate allocated");
    assert!(inside > 0 && outside > 0, "{inside} {outside}");
    assert!(area > 0.0);
}
