//! GPU rendering against independent truths: the block-ID pass of a few boxes compared, pixel
//! by pixel, with exact ray casting of the same boxes on the CPU.
//!
//! Needs an adapter (a GPU or a software rasteriser such as Mesa's lavapipe). Without one the
//! tests skip loudly, unless the GPU is required (`BLOCKWALK_REQUIRE=gpu`), when they fail.
#![cfg(feature = "render")]

mod support;

use blockwalk::blocks::BlockId;
use blockwalk::city::Mesh;
use blockwalk::geom::{Aabb3, Camera};
use blockwalk::render::{MeshRenderer, RenderError, RenderOptions, Shading};
use glam::{DVec3, DVec4, Vec3};

use support::gpu::gpu_or_skip;

/// A closed box mesh with outward normals (4 vertices per face, CCW from outside).
fn box_mesh(b: &Aabb3) -> Mesh {
    let (lo, hi) = (b.min.as_vec3(), b.max.as_vec3());
    let c = |x: bool, y: bool, z: bool| {
        Vec3::new(
            if x { hi.x } else { lo.x },
            if y { hi.y } else { lo.y },
            if z { hi.z } else { lo.z },
        )
    };
    let faces: [([Vec3; 4], Vec3); 6] = [
        (
            [
                c(false, false, false),
                c(false, true, false),
                c(true, true, false),
                c(true, false, false),
            ],
            -Vec3::Z,
        ),
        (
            [
                c(false, false, true),
                c(true, false, true),
                c(true, true, true),
                c(false, true, true),
            ],
            Vec3::Z,
        ),
        (
            [
                c(false, false, false),
                c(true, false, false),
                c(true, false, true),
                c(false, false, true),
            ],
            -Vec3::Y,
        ),
        (
            [
                c(false, true, false),
                c(false, true, true),
                c(true, true, true),
                c(true, true, false),
            ],
            Vec3::Y,
        ),
        (
            [
                c(false, false, false),
                c(false, false, true),
                c(false, true, true),
                c(false, true, false),
            ],
            -Vec3::X,
        ),
        (
            [
                c(true, false, false),
                c(true, true, false),
                c(true, true, true),
                c(true, false, true),
            ],
            Vec3::X,
        ),
    ];
    let mut m = Mesh::default();
    for (quad, n) in faces {
        let base = m.positions.len() as u32;
        m.positions.extend_from_slice(&quad);
        m.normals.extend_from_slice(&[n; 4]);
        m.indices
            .extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
    }
    m
}

/// What the ray through a pixel centre meets first.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Ray {
    /// The surface of this box, entered from outside within the camera's near..far depth.
    Hit(BlockId),
    /// Nothing.
    Sky,
    /// The ray starts (at the near plane) inside a box: what a rasteriser shows depends on its
    /// back-face rule, so the pixel proves nothing and is counted apart.
    Inside,
}

/// The first box surface met by the ray through the centre of pixel (x, y), by the slab test,
/// within the camera's near..far depth. A box is entered at the largest of its slab entries;
/// when that lies before the near plane while the exit lies after it, the ray starts inside.
fn ray_cast(cam: &Camera, boxes: &[(BlockId, Aabb3)], w: u32, h: u32, x: u32, y: u32) -> Ray {
    let inv = cam.clip_from_world().inverse();
    let ndc_x = (x as f64 + 0.5) / w as f64 * 2.0 - 1.0;
    let ndc_y = 1.0 - (y as f64 + 0.5) / h as f64 * 2.0;
    let un = |z: f64| {
        let p = inv * DVec4::new(ndc_x, ndc_y, z, 1.0);
        p.truncate() / p.w
    };
    let (a, b) = (un(0.0), un(1.0));
    let d = b - a;
    let mut best: Option<(f64, BlockId)> = None;
    let mut inside = false;
    for (id, bx) in boxes {
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        for k in 0..3 {
            let (o, dk, lo, hi) = (a[k], d[k], bx.min[k], bx.max[k]);
            if dk.abs() < 1e-15 {
                if o < lo || o > hi {
                    t0 = f64::INFINITY;
                }
                continue;
            }
            let (mut ta, mut tb) = ((lo - o) / dk, (hi - o) / dk);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
        if t0 > t1 || t1 < 0.0 || t0 > 1.0 {
            continue;
        }
        if t0 < 0.0 {
            inside = true;
        } else if best.is_none_or(|(bt, _)| t0 < bt) {
            best = Some((t0, *id));
        }
    }
    match (inside, best) {
        (true, _) => Ray::Inside,
        (false, Some((_, id))) => Ray::Hit(id),
        (false, None) => Ray::Sky,
    }
}

/// Pixels where the id image and the ray casts disagree, pixels the boxes cover, and pixels
/// counted apart because the ray starts inside a box.
fn compare(
    ids: &[Option<BlockId>],
    cam: &Camera,
    boxes: &[(BlockId, Aabb3)],
    w: u32,
    h: u32,
) -> (usize, usize, usize) {
    let (mut differ, mut covered, mut inside) = (0, 0, 0);
    for y in 0..h {
        for x in 0..w {
            let truth = match ray_cast(cam, boxes, w, h, x, y) {
                Ray::Inside => {
                    inside += 1;
                    continue;
                }
                Ray::Hit(id) => Some(id),
                Ray::Sky => None,
            };
            covered += truth.is_some() as usize;
            differ += (ids[(y * w + x) as usize] != truth) as usize;
        }
    }
    (differ, covered, inside)
}

#[test]
fn ray_cast_counts_eyes_inside_a_box_apart_and_sees_moved_boxes() {
    let boxes = scene();
    let (w, h) = (64u32, 36u32);
    // An eye inside box 0: every pixel starts inside.
    let cam = Camera::looking_at(DVec3::new(27.0, 0.0, 5.0), DVec3::new(60.0, 0.0, 5.0));
    let inside = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| ray_cast(&cam, &boxes, w, h, x, y) == Ray::Inside)
        .count();
    assert_eq!(inside, (w * h) as usize);
    // From outside, nothing starts inside, and the comparison notices a box moved by 2 m.
    let cam = Camera::looking_at(DVec3::new(0.0, 0.0, 1.7), DVec3::new(40.0, 0.0, 8.0));
    let ids: Vec<Option<BlockId>> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| match ray_cast(&cam, &boxes, w, h, x, y) {
            Ray::Hit(id) => Some(id),
            _ => None,
        })
        .collect();
    assert_eq!(compare(&ids, &cam, &boxes, w, h).0, 0);
    assert_eq!(compare(&ids, &cam, &boxes, w, h).2, 0);
    let mut moved = boxes.clone();
    moved[0].1.max.y += 2.0;
    moved[0].1.min.y += 2.0;
    let (differ, _, _) = compare(&ids, &cam, &moved, w, h);
    assert!(differ as f64 > 0.005 * (w * h) as f64, "{differ}");
}

fn scene() -> Vec<(BlockId, Aabb3)> {
    vec![
        (
            BlockId(0),
            Aabb3::new(DVec3::new(20.0, -10.0, 0.0), DVec3::new(35.0, 10.0, 18.0)),
        ),
        (
            BlockId(7),
            Aabb3::new(DVec3::new(45.0, 0.0, 0.0), DVec3::new(60.0, 25.0, 30.0)),
        ),
        (
            BlockId(300),
            Aabb3::new(DVec3::new(30.0, -30.0, 0.0), DVec3::new(40.0, -18.0, 9.0)),
        ),
    ]
}

#[test]
fn id_pass_matches_ray_casting() {
    let Some(gpu) = gpu_or_skip("id_pass_matches_ray_casting") else {
        return;
    };
    let boxes = scene();
    let meshes: Vec<(BlockId, Mesh)> = boxes.iter().map(|(id, b)| (*id, box_mesh(b))).collect();
    let refs: Vec<(BlockId, &Mesh)> = meshes.iter().map(|(id, m)| (*id, m)).collect();
    let (w, h) = (320u32, 180u32);
    let r = MeshRenderer::with_options(
        &gpu,
        &refs,
        RenderOptions {
            width: w,
            height: h,
        },
    )
    .unwrap();
    let cams = [
        Camera::looking_at(DVec3::new(0.0, 0.0, 1.7), DVec3::new(40.0, 0.0, 8.0)),
        Camera::looking_at(DVec3::new(-10.0, -60.0, 50.0), DVec3::new(40.0, 0.0, 0.0)),
        // Straight down from above.
        Camera::new(
            DVec3::new(40.0, 0.0, 120.0),
            0.3,
            -std::f64::consts::FRAC_PI_2,
        ),
    ];
    let all: Vec<BlockId> = boxes.iter().map(|b| b.0).collect();
    for cam in cams {
        let frame = r.draw_shaded(&gpu, &cam, &all, Shading::Ids).unwrap();
        let ids = frame.block_ids();
        let (differ, covered, inside) = compare(&ids, &cam, &boxes, w, h);
        // No pixel of these views starts inside a box: every pixel is a real comparison.
        assert_eq!(inside, 0, "pixels starting inside a box are counted apart");
        let share = differ as f64 / (w * h) as f64;
        // Tolerance: rasterisation and ray casting may disagree only on pixels whose centre is
        // within rounding of an edge: at most 0.5 % of the image (observed on lavapipe: well
        // below).
        assert!(covered > 500, "the boxes are in view: {covered} px");
        assert!(
            share <= 0.005,
            "{differ} of {} pixels differ ({:.3} %)",
            w * h,
            share * 100.0
        );
    }
}

#[test]
fn only_listed_blocks_are_drawn_and_lit_frames_have_sky_and_ground() {
    let Some(gpu) = gpu_or_skip("only_listed_blocks_are_drawn") else {
        return;
    };
    let boxes = scene();
    let meshes: Vec<(BlockId, Mesh)> = boxes.iter().map(|(id, b)| (*id, box_mesh(b))).collect();
    let refs: Vec<(BlockId, &Mesh)> = meshes.iter().map(|(id, m)| (*id, m)).collect();
    let (w, h) = (160u32, 90u32);
    let r = MeshRenderer::with_options(
        &gpu,
        &refs,
        RenderOptions {
            width: w,
            height: h,
        },
    )
    .unwrap();
    let cam = Camera::looking_at(DVec3::new(-10.0, -60.0, 50.0), DVec3::new(40.0, 0.0, 0.0));
    let only7 = r
        .draw_shaded(&gpu, &cam, &[BlockId(7), BlockId(999)], Shading::Ids)
        .unwrap();
    let ids = only7.block_ids();
    assert!(ids.contains(&Some(BlockId(7))));
    assert!(ids.iter().all(|i| i.is_none() || *i == Some(BlockId(7))));
    assert_eq!(only7.timings.blocks, 1);
    assert_eq!(only7.timings.triangles, 12);
    let none = r.draw_shaded(&gpu, &cam, &[], Shading::Ids).unwrap();
    assert!(none.block_ids().iter().all(Option::is_none));

    // Lit: the top row sees sky (camera pitched down ~30°, 60° fov: the horizon is in view),
    // the bottom row sees ground, and some pixels are building colours.
    let lit = r
        .draw(
            &gpu,
            &Camera { pitch: -0.2, ..cam },
            &[BlockId(0), BlockId(7), BlockId(300)],
        )
        .unwrap();
    let px = |x: u32, y: u32| {
        let i = ((y * w + x) * 4) as usize;
        [lit.rgba[i], lit.rgba[i + 1], lit.rgba[i + 2]]
    };
    let sky = px(w / 2, 0);
    assert!(sky[2] > sky[0] && sky[2] > 200, "sky {sky:?}");
    let ground = px(w / 2, h - 1);
    assert!(ground != sky, "ground {ground:?}");
    assert!(lit.timings.wall_s > 0.0);
    if gpu.timestamps {
        assert!(lit.timings.gpu_s.is_some_and(|t| t >= 0.0));
    }
}

#[test]
fn bad_meshes_are_refused() {
    let Some(gpu) = gpu_or_skip("bad_meshes_are_refused") else {
        return;
    };
    let mut m = box_mesh(&scene()[0].1);
    m.indices.push(999);
    m.indices.push(0);
    m.indices.push(1);
    let e = MeshRenderer::new(&gpu, &[(BlockId(3), &m)]).unwrap_err();
    assert!(
        matches!(
            e,
            RenderError::IndexOutOfRange {
                block: BlockId(3),
                index: 999,
                vertices: 24
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("block 3"), "{e}");

    let mut m = box_mesh(&scene()[0].1);
    m.normals.pop();
    let e = MeshRenderer::new(&gpu, &[(BlockId(2), &m)]).unwrap_err();
    assert!(
        matches!(
            e,
            RenderError::BadMesh {
                block: BlockId(2),
                positions: 24,
                normals: 23,
                ..
            }
        ),
        "{e:?}"
    );

    let m = box_mesh(&scene()[0].1);
    let e = MeshRenderer::new(&gpu, &[(BlockId(0x00FF_FFFF), &m)]).unwrap_err();
    assert!(
        matches!(
            e,
            RenderError::BlockIdTooLarge {
                id: 0x00FF_FFFF,
                limit: 0x00FF_FFFE
            }
        ),
        "{e:?}"
    );

    for (width, height) in [(0, 10), (10, 0)] {
        let e = MeshRenderer::with_options(&gpu, &[], RenderOptions { width, height }).unwrap_err();
        assert!(
            matches!(e, RenderError::EmptyImage { width: w, height: h } if (w, h) == (width, height)),
            "{e:?}"
        );
    }
    let limit = gpu.device.limits().max_texture_dimension_2d;
    let e = MeshRenderer::with_options(
        &gpu,
        &[],
        RenderOptions {
            width: limit + 1,
            height: 8,
        },
    )
    .unwrap_err();
    assert!(
        matches!(e, RenderError::ImageTooLarge { limit: l, .. } if l == limit),
        "{e:?}"
    );
}

/// A frame whose pixels do not match its size, and an image file that cannot be written, are
/// errors that keep their cause (no GPU needed).
#[test]
fn frame_write_errors_keep_their_cause() {
    use blockwalk::render::{Frame, FrameTimings};
    use std::error::Error;
    let dir = tempfile::tempdir().unwrap();
    let bad = Frame {
        width: 4,
        height: 4,
        rgba: vec![0; 10],
        timings: FrameTimings::default(),
    };
    let e = bad.save_png(&dir.path().join("f.png")).unwrap_err();
    assert!(
        matches!(
            e,
            RenderError::FrameSize {
                width: 4,
                height: 4,
                bytes: 10
            }
        ),
        "{e:?}"
    );
    let good = Frame {
        width: 2,
        height: 2,
        rgba: vec![255; 16],
        timings: FrameTimings::default(),
    };
    let missing = dir.path().join("no such dir").join("f.png");
    let e = good.save_png(&missing).unwrap_err();
    match &e {
        RenderError::Image { file, source } => {
            assert_eq!(file, &missing);
            assert!(
                matches!(source, image::ImageError::IoError(_)),
                "{source:?}"
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(e.source().is_some());
    assert!(e.to_string().contains("no such dir"), "{e}");
    good.save_png(&dir.path().join("ok.png")).unwrap();
}

#[test]
fn meshes_with_bad_appearance_are_refused() {
    use blockwalk::city::VertexAppearance;
    let Some(gpu) = gpu_or_skip("meshes_with_bad_appearance_are_refused") else {
        return;
    };
    // One appearance entry short.
    let mut m = box_mesh(&scene()[0].1);
    m.styles.push(Default::default());
    m.appearance = vec![VertexAppearance::default(); m.positions.len() - 1];
    let e = MeshRenderer::new(&gpu, &[(BlockId(4), &m)]).unwrap_err();
    assert!(
        matches!(
            e,
            RenderError::BadAppearance {
                block: BlockId(4),
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string().contains("block 4") && e.to_string().contains("appearance"),
        "{e}"
    );
    // A style index past the mesh's styles.
    m.appearance.push(VertexAppearance { u_m: 0.0, style: 1 });
    let e = MeshRenderer::new(&gpu, &[(BlockId(5), &m)]).unwrap_err();
    assert!(
        e.to_string().contains("block 5") && e.to_string().contains("style 1"),
        "{e}"
    );
    // A bad ground mesh is named as such.
    let ground = Mesh {
        indices: vec![0, 1, 2],
        ..Default::default()
    };
    let e = MeshRenderer::with_ground(&gpu, &[], &ground, RenderOptions::default()).unwrap_err();
    assert!(e.to_string().contains("ground"), "{e}");
}
