//! A tiled city walked by streaming (`blockwalk::stream`): the packed block meshes equal the
//! whole city's; converged frames equal the whole city's frames (meshes) and the fully
//! resident frames (with BlockMaps); no block the oracle sees is left out, at tile borders
//! included, whatever is resident; the budget holds; the render thread never waits in real
//! time, over a throttled HTTP link with range requests; damaged and missing files are refused
//! by name and the walk goes on with stand-ins.

mod support;
use support::skip;

use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use blockwalk::blockmap::CityMapsOptions;
use blockwalk::blocks::{detect, BlockId, BlockOptions};
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::city::Mesh;
use blockwalk::geom::Camera;
use blockwalk::jobs::pack::{decode_record, TileHierarchy};
use blockwalk::jobs::{merge, plan, run_tile, write_plan, PlanOptions, TileOptions};
use blockwalk::scene::CitySource;
use blockwalk::stream::play::StreamOptions;
use blockwalk::stream::serve::Server;
use blockwalk::stream::{play, LinkSpec, Mode, StreamCity};
use blockwalk::visibility::oracle;
use glam::DVec3;

const SIZE: (u32, u32) = (160, 90);

/// The city (3,000 generated buildings) and its tiles with BlockMaps, made once per run.
struct Fixture {
    _tmp: tempfile::TempDir,
    city: PathBuf,
    jobs: PathBuf,
    tiles: usize,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let city = tmp.path().join("city");
        let c = generate_city(&GenerateParams {
            buildings: 3000,
            seed: 7,
            parcels: false,
            ..Default::default()
        })
        .unwrap();
        write_city(&c, &city).unwrap();
        let jobs = tmp.path().join("jobs");
        let p = plan(
            &city.join("buildings.shp"),
            &city.join("streets.shp"),
            &PlanOptions {
                max_buildings: 500,
                build: Default::default(),
            },
            &mut |_| {},
        )
        .unwrap();
        let plan_path = write_plan(&p, &jobs).unwrap();
        let maps = CityMapsOptions {
            checks: 0,
            tree: blockwalk::blockmap::TreeOptions {
                build: blockwalk::blockmap::BuildOptions {
                    k: 32,
                    ..Default::default()
                },
                ..Default::default()
            },
            ..Default::default()
        };
        for t in 0..p.tiles.len() {
            run_tile(
                &plan_path,
                t,
                &TileOptions {
                    maps: Some(maps),
                    ..TileOptions::default()
                },
            )
            .unwrap();
        }
        merge(&jobs).unwrap();
        Fixture {
            city,
            jobs,
            tiles: p.tiles.len(),
            _tmp: tmp,
        }
    })
}

/// The whole city's block meshes, by block id (one run, no tiles).
fn whole_city_blocks(f: &Fixture) -> HashMap<BlockId, Mesh> {
    let source = CitySource::parse(
        &f.city.join("buildings.shp"),
        Some(f.city.join("streets.shp")),
        None,
        &[],
        0,
    )
    .unwrap();
    let city = source.load(&Default::default(), &mut |_| {}).unwrap().city;
    let layout = detect(&city, &BlockOptions::default()).unwrap();
    blockwalk::scene::block_meshes(&city, &layout)
        .into_iter()
        .collect()
}

fn options(mode: Mode, far: bool) -> StreamOptions {
    let mut o =
        StreamOptions::new(1 << 30, 3, LinkSpec::default(), mode, 2.0, SIZE, 10, None).unwrap();
    o.far = far;
    o
}

/// Cameras over the city: an orbit around it at 120 m, and low views along and across every
/// tile border (eye at 1.7 m and 25 m on the border's midpoint).
fn cameras(city: &StreamCity) -> Vec<Camera> {
    let b = city.city_box();
    let c = b.center();
    let r = (b.max - b.min).truncate().length() * 0.6;
    let mut cams: Vec<Camera> = (0..8)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 8.0;
            Camera::looking_at(
                DVec3::new(c.x + r * a.cos(), c.y + r * a.sin(), 120.0),
                DVec3::new(c.x, c.y, 0.0),
            )
        })
        .collect();
    let o = city.frame.origin;
    for t in &city.index.tiles {
        let [x0, y0, x1, y1] = t.bounds;
        let (x0, y0, x1, y1) = (x0 - o.x, y0 - o.y, x1 - o.x, y1 - o.y);
        for (p, along) in [
            (DVec3::new(x1, (y0 + y1) / 2.0, 0.0), DVec3::Y),
            (DVec3::new((x0 + x1) / 2.0, y1, 0.0), DVec3::X),
        ] {
            for h in [1.7, 25.0] {
                let eye = p + DVec3::Z * h;
                for d in [along, -along, along.cross(DVec3::Z), -along.cross(DVec3::Z)] {
                    cams.push(Camera::looking_at(
                        eye,
                        eye + d * 100.0 - DVec3::Z * h * 0.5,
                    ));
                }
            }
        }
    }
    cams
}

#[test]
fn packed_block_meshes_equal_the_whole_city_blocks_bit_for_bit() {
    let f = fixture();
    let whole = whole_city_blocks(f);
    let mut checked = 0;
    for t in 0..f.tiles {
        let hp = f.jobs.join(format!("tiles/tile_{t:05}.hier.json"));
        let Ok(text) = std::fs::read(&hp) else {
            continue; // a tile without buildings has no hierarchy
        };
        let h = TileHierarchy::parse(&text, &hp).unwrap();
        let pack = std::fs::read(f.jobs.join(h.pack.as_ref().unwrap())).unwrap();
        for b in &h.blocks {
            let want = &whole[&BlockId(b.id)];
            let Some(r) = &b.mesh else {
                assert!(want.indices.is_empty(), "block {} lost its mesh", b.id);
                continue;
            };
            let got = decode_record(
                &pack[r.offset as usize..(r.offset + r.bytes) as usize],
                h.compression.as_deref(),
                r.inflated,
            )
            .unwrap();
            let bits = |m: &Mesh| -> Vec<u32> {
                m.positions
                    .iter()
                    .chain(&m.normals)
                    .flat_map(|v| v.to_array().map(f32::to_bits))
                    .collect()
            };
            assert_eq!(bits(&got), bits(want), "block {}", b.id);
            assert_eq!(got.indices, want.indices, "block {}", b.id);
            assert_eq!(got.appearance, want.appearance, "block {}", b.id);
            assert_eq!(got.styles, want.styles, "block {}", b.id);
            checked += 1;
        }
    }
    assert_eq!(
        checked,
        whole.values().filter(|m| !m.indices.is_empty()).count()
    );
}

#[test]
fn converged_streamed_frames_equal_the_whole_city_frames() {
    let f = fixture();
    let city = StreamCity::open(&f.jobs.to_string_lossy()).unwrap();
    assert!(city.startup.refused.is_empty());
    assert_eq!(city.startup.buildings, 3000);
    let whole = whole_city_blocks(f);
    let list: Vec<(BlockId, &Mesh)> = whole.iter().map(|(b, m)| (*b, m)).collect();
    let cams = cameras(&city);
    let mut o = options(Mode::Deterministic, false);
    o.keep_every = Some(1);
    let run = play(&city, &cams, &o, &mut |_, _| {}).unwrap();
    assert_eq!(run.kept.len(), cams.len());
    let mut drawn_something = 0;
    for ((i, img), cam) in run.kept.iter().zip(&cams) {
        assert!(run.frames[*i].converged(), "frame {i}");
        let (want, depth) =
            oracle::shade_with_ground_depth(&list, &Mesh::default(), cam, SIZE.0, SIZE.1);
        assert!(img == &want, "frame {i} differs from the whole city's");
        drawn_something += usize::from(depth.iter().any(|&d| d < 1.0) && run.frames[*i].meshes > 0);
    }
    assert!(
        drawn_something >= cams.len() / 2,
        "{drawn_something} frames show buildings"
    );
    assert!(
        run.summary.wait_max_s > 0.0,
        "deterministic frames wait for loads"
    );
}

#[test]
fn deterministic_walks_repeat_and_converged_frames_equal_fully_resident_ones() {
    let f = fixture();
    let city = StreamCity::open(&f.jobs.to_string_lossy()).unwrap();
    assert!(city.startup.maps > 0, "tiles with BlockMaps");
    let cams = cameras(&city);
    let mut o = options(Mode::Deterministic, true);
    o.keep_every = Some(1);
    o.check = true;
    let a = play(&city, &cams, &o, &mut |_, _| {}).unwrap();
    let b = play(&city, &cams, &o, &mut |_, _| {}).unwrap();
    assert!(a.kept == b.kept, "the same images twice");
    assert_eq!(a.summary.frames_with_standins, 0);
    assert_eq!(a.summary.converged_but_different, Some(0));
    let maps: usize = a.frames.iter().map(|f| f.maps).sum();
    assert!(maps > 0, "the far field was drawn");
    assert!(a.frames.iter().all(|f| f.differing_pixels == Some(0)));
}

/// Every block the supersampled oracle sees in the whole city is drawn (as a mesh, inside a
/// map, or as a box), and none twice.
fn check_covers(city: &StreamCity, cams: &[Camera], run: &blockwalk::stream::StreamRun) -> usize {
    let whole = whole_city_blocks(fixture());
    let list: Vec<(BlockId, &Mesh)> = whole.iter().map(|(b, m)| (*b, m)).collect();
    let mut seen = 0;
    for (f, cam) in run.frames.iter().zip(cams) {
        let drawn: BTreeSet<BlockId> = f.blocks.iter().copied().collect();
        assert_eq!(
            drawn.len(),
            f.blocks.len(),
            "frame {}: a block drawn twice",
            f.frame
        );
        let visible = oracle::visible_blocks_supersampled(&list, cam, SIZE.0, SIZE.1, 4);
        seen += visible.len();
        let missed: Vec<_> = visible.difference(&drawn).collect();
        assert!(
            missed.is_empty(),
            "frame {}: blocks seen, not drawn: {missed:?}",
            f.frame
        );
    }
    let _ = city;
    seen
}

#[test]
fn no_block_the_oracle_sees_is_left_out_at_tile_borders() {
    let f = fixture();
    let city = StreamCity::open(&f.jobs.to_string_lossy()).unwrap();
    let cams = cameras(&city);
    // Fully loaded, and cold with a slow link (stand-ins everywhere).
    let mut o = options(Mode::Deterministic, true);
    o.record_blocks = true;
    let run = play(&city, &cams, &o, &mut |_, _| {}).unwrap();
    let seen = check_covers(&city, &cams, &run);
    assert!(seen > 100, "{seen} visible blocks in all");
    let mut o = options(Mode::Realtime, true);
    o.record_blocks = true;
    o.link = LinkSpec::new(Some(2e6), 0.01).unwrap();
    o.budget_bytes = 2 << 20;
    let run = play(&city, &cams, &o, &mut |_, _| {}).unwrap();
    assert!(
        run.summary.frames_with_standins > 0,
        "a slow link leaves stand-ins"
    );
    let boxes: usize = run.frames.iter().map(|f| f.standin_boxes).sum();
    assert!(boxes > 0, "boxes stood in");
    check_covers(&city, &cams, &run);
}

#[test]
fn a_small_budget_is_never_exceeded() {
    let f = fixture();
    let city = StreamCity::open(&f.jobs.to_string_lossy()).unwrap();
    let cams = cameras(&city);
    let mut o = options(Mode::Deterministic, true);
    o.budget_bytes = 3 << 20;
    let run = play(&city, &cams, &o, &mut |_, _| {}).unwrap();
    assert!(run.summary.evictions > 0, "evictions under a small budget");
    for fr in &run.frames {
        assert!(fr.resident_bytes <= o.budget_bytes, "frame {}", fr.frame);
    }
}

#[test]
fn real_time_over_throttled_http_never_waits_and_converges() {
    let f = fixture();
    let server = Server::start(&f.jobs, "127.0.0.1:0", 16).unwrap();
    let url = format!("{}index.json", server.url());
    let city = StreamCity::open(&url).unwrap();
    assert!(city.startup.source.starts_with("HTTP"));
    // One view held for 3 s at 20 frames per second over 20 Mb/s with 10 ms per request.
    let cam = cameras(&city)[8]; // at street level on a tile border: meshes near
    let cams = vec![cam; 60];
    let mut o = options(Mode::Realtime, true);
    o.link = LinkSpec::new(Some(20e6), 0.01).unwrap();
    o.fps = Some(20.0);
    o.keep_every = Some(1);
    let run = play(&city, &cams, &o, &mut |_, _| {}).unwrap();
    assert!(
        run.frames.iter().all(|f| f.wait_s == 0.0),
        "the render thread never waits"
    );
    assert!(
        !run.frames[0].converged(),
        "the first frame has nothing resident"
    );
    let (first, _) = run.summary.first_converged.expect("converges within 3 s");
    assert!(run.frames[first..].iter().all(|f| f.converged()));
    // Converged frames equal the deterministic walk over the folder.
    let local = StreamCity::open(&f.jobs.to_string_lossy()).unwrap();
    let det = play(&local, &cams[..1], &options_kept(), &mut |_, _| {}).unwrap();
    assert!(run.kept.last().unwrap().1 == det.kept[0].1);
    use std::sync::atomic::Ordering;
    assert!(
        server.counts().ranges.load(Ordering::Relaxed) > 0,
        "block meshes came as ranges"
    );
}

fn options_kept() -> StreamOptions {
    let mut o = options(Mode::Deterministic, true);
    o.keep_every = Some(1);
    o
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let p = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &p);
        } else {
            std::fs::copy(e.path(), &p).unwrap();
        }
    }
}

#[test]
fn damaged_and_missing_files_are_refused_by_name_and_the_walk_goes_on() {
    let f = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("jobs");
    copy_dir(&f.jobs, &dir);
    let city = StreamCity::open(&dir.to_string_lossy()).unwrap();
    // Damage: one map's bytes flipped, another map deleted, one tile's pack truncated, and
    // another tile's hierarchy edited.
    // Root maps (a tile's coarsest), which a coarse walk asks for.
    let maps: Vec<&blockwalk::stream::Content> = city
        .contents
        .iter()
        .filter(|c| {
            matches!(c.kind, blockwalk::stream::ContentKind::Map(n, _) if city.nodes[n].parent.is_none())
        })
        .collect();
    assert!(maps.len() >= 3);
    let flipped = maps[0].file.clone();
    let deleted = maps[maps.len() / 2].file.clone();
    let mut bytes = std::fs::read(dir.join(&flipped)).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x55;
    std::fs::write(dir.join(&flipped), &bytes).unwrap();
    std::fs::remove_file(dir.join(&deleted)).unwrap();
    let pack_tile = maps[maps.len() / 2].tile;
    let pack = city
        .contents
        .iter()
        .find(|c| c.tile != pack_tile && c.range.is_some())
        .unwrap();
    let truncated = pack.file.clone();
    let len = std::fs::metadata(dir.join(&truncated)).unwrap().len();
    let fh = std::fs::OpenOptions::new()
        .write(true)
        .open(dir.join(&truncated))
        .unwrap();
    fh.set_len(len / 2).unwrap();
    drop(fh);
    let other = city
        .index
        .tiles
        .iter()
        .find(|t| t.buildings > 0 && t.id != pack.tile && t.id != pack_tile && t.id != maps[0].tile)
        .unwrap();
    let hier = other
        .files
        .iter()
        .find(|f| f.path.ends_with(".hier.json"))
        .unwrap();
    let text = std::fs::read_to_string(dir.join(&hier.path)).unwrap();
    std::fs::write(
        dir.join(&hier.path),
        text.replacen("\"outskirts\":false", "\"outskirts\":true", 1),
    )
    .unwrap();

    let city = StreamCity::open(&dir.to_string_lossy()).unwrap();
    assert_eq!(city.startup.refused.len(), 1);
    assert_eq!(city.startup.refused[0].tile, other.id);
    assert!(
        city.startup.refused[0].why.contains(&hier.path),
        "{}",
        city.startup.refused[0].why
    );
    // Everything is wanted: a view of the whole city from above at τ small, then every camera.
    let b = city.city_box();
    let mut cams = vec![Camera::looking_at(
        DVec3::new(b.center().x, b.min.y - 50.0, 300.0),
        b.center(),
    )];
    cams.extend(cameras(&city));
    let mut o = options(Mode::Deterministic, true);
    o.record_blocks = true;
    o.tau_px = 0.05;
    let run = play(&city, &cams, &o, &mut |_, _| {}).unwrap();
    let mut o2 = options(Mode::Deterministic, true);
    o2.tau_px = 1000.0;
    let coarse = play(&city, &cams, &o2, &mut |_, _| {}).unwrap();
    let text: Vec<String> = run
        .summary
        .refusals
        .iter()
        .chain(&coarse.summary.refusals)
        .map(|r| r.error.to_string())
        .collect();
    let named =
        |file: &str, what: &str| text.iter().any(|t| t.contains(file) && t.starts_with(what));
    assert!(named(&deleted, "missing"), "{text:?}");
    assert!(named(&truncated, "failed"), "{text:?}");
    assert!(named(&flipped, "refused"), "{text:?}");
    assert!(
        run.summary.frames_with_standins > 0,
        "stand-ins for what was refused"
    );
    // The refused tile's blocks are not drawn; every other block the oracle sees is.
    let gone: BTreeSet<BlockId> = other.blocks.iter().map(|&b| BlockId(b)).collect();
    let whole = whole_city_blocks(f);
    let list: Vec<(BlockId, &Mesh)> = whole
        .iter()
        .filter(|(b, _)| !gone.contains(b))
        .map(|(b, m)| (*b, m))
        .collect();
    for (fr, cam) in run.frames.iter().zip(&cams) {
        let drawn: BTreeSet<BlockId> = fr.blocks.iter().copied().collect();
        let visible = oracle::visible_blocks_supersampled(&list, cam, SIZE.0, SIZE.1, 4);
        assert!(visible.is_subset(&drawn), "frame {}", fr.frame);
    }
}

/// Astana (32,056 buildings) in tiles draws, once converged, the same frames as Astana whole.
#[test]
fn astana_in_tiles_draws_the_same_frames_as_astana_whole() {
    let Some(dir) = skip::or_skip(
        skip::Need::Astana,
        "astana_in_tiles_draws_the_same_frames_as_astana_whole",
        support::data::astana_dir(),
    ) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let jobs = tmp.path().join("jobs");
    let (fp, st) = (
        dir.join("buildings.shp"),
        dir.join("streets_blockclass.shp"),
    );
    let p = plan(
        &fp,
        &st,
        &PlanOptions {
            max_buildings: 4000,
            build: Default::default(),
        },
        &mut |_| {},
    )
    .unwrap();
    let plan_path = write_plan(&p, &jobs).unwrap();
    for t in 0..p.tiles.len() {
        run_tile(&plan_path, t, &TileOptions::default()).unwrap();
    }
    merge(&jobs).unwrap();
    let city = StreamCity::open(&jobs.to_string_lossy()).unwrap();
    assert_eq!(city.startup.buildings, 32_056);

    let source = CitySource::parse(&fp, Some(st), None, &[], 0).unwrap();
    let whole = source.load(&Default::default(), &mut |_| {}).unwrap().city;
    let layout = detect(&whole, &BlockOptions::default()).unwrap();
    let meshes = blockwalk::scene::block_meshes(&whole, &layout);
    let list: Vec<(BlockId, &Mesh)> = meshes.iter().map(|(b, m)| (*b, m)).collect();
    let cams: Vec<Camera> = cameras(&city).into_iter().take(24).collect();
    let mut o = options(Mode::Deterministic, false);
    o.keep_every = Some(1);
    let run = play(&city, &cams, &o, &mut |_, _| {}).unwrap();
    let mut with_buildings = 0;
    for ((i, img), cam) in run.kept.iter().zip(&cams) {
        assert!(run.frames[*i].converged());
        let (want, _) =
            oracle::shade_with_ground_depth(&list, &Mesh::default(), cam, SIZE.0, SIZE.1);
        assert!(img == &want, "frame {i} differs from Astana whole");
        with_buildings += usize::from(run.frames[*i].meshes > 0);
    }
    assert!(
        with_buildings >= 12,
        "{with_buildings} frames with buildings"
    );
}

/// A street layer in another CRS than the city's lands in the city's frame: Bubeneč in tiles
/// (EPSG:3857) walked along its streets given in EPSG:3857 and in UTM 33N gives the same walk.
#[test]
fn a_street_layer_in_another_crs_is_read_into_the_citys_frame() {
    let data = support::repo().join("data");
    let tmp = tempfile::tempdir().unwrap();
    let jobs = tmp.path().join("jobs");
    let p = plan(
        &data.join("bubenec/buildings.shp"),
        &data.join("bubenec/streets.shp"),
        &PlanOptions {
            max_buildings: 40,
            build: Default::default(),
        },
        &mut |_| {},
    )
    .unwrap();
    let plan_path = write_plan(&p, &jobs).unwrap();
    for t in 0..p.tiles.len() {
        run_tile(&plan_path, t, &TileOptions::default()).unwrap();
    }
    let (index, _) = merge(&jobs).unwrap();
    assert!(
        matches!(index.crs, Some(blockwalk::importers::Crs::WebMercator)),
        "{:?}",
        index.crs
    );
    let city = StreamCity::open(&jobs.to_string_lossy()).unwrap();
    let route = |streets: &str| {
        let (r, _, notes) = blockwalk::stream::job::route_for(
            &city,
            &blockwalk::route::RouteChoice::Street,
            Some(&data.join(streets)),
            16.0 / 9.0,
        )
        .unwrap();
        assert!(!notes.is_empty(), "the street layer's reading is reported");
        r
    };
    let (a, b) = (
        route("bubenec/streets.shp"),
        route("bubenec_utm33n/streets.shp"),
    );
    assert_eq!(a.keys().len(), b.keys().len());
    let worst = a
        .keys()
        .iter()
        .zip(b.keys())
        .map(|(p, q)| (p.position - q.position).length())
        .fold(0.0, f64::max);
    assert!(worst < 0.05, "the two walks are {worst} m apart");
    // A walk over streets that do not meet the city is refused, not placed elsewhere.
    let far = blockwalk::stream::job::route_for(
        &city,
        &blockwalk::route::RouteChoice::Street,
        Some(&data.join("helsinki/streets_blockclass.shp")),
        16.0 / 9.0,
    );
    let e = far
        .expect_err("Helsinki's streets under Prague")
        .to_string();
    assert!(
        e.contains("streets_blockclass.shp") && e.contains("city's blocks"),
        "{e}"
    );
}
