//! Compact tile contents (`ContentEncoding::Compact`: `KHR_mesh_quantization`,
//! `EXT_meshopt_compression`) against plain ones of the same city: Helsinki with its streets, a
//! generated city, Astana (when its data is there) and Helsinki on a terrain (its terrain tiles). Every content is decoded by the
//! tests' own reader (`support::glb`: the GLB container and JSON parsed here, the compressed
//! streams through meshoptimizer's decoder) and compared with the plain content of the same
//! tile: the same tiles and `tileset.json`, the same triangles (each a tuple of its vertices'
//! plain attributes, matched independently of the vertex and triangle order), positions within
//! the stated error (and under 1 mm), normals within the octahedral error, colours, feature ids
//! and property tables exactly. Terrain vertices that two leaves share decode to the same point
//! in both. The Khronos glTF-Validator checks the compact contents too (0 errors), skipped
//! loudly without node unless the validators are required (`BLOCKWALK_REQUIRE=validators`).

mod support;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use blockwalk::city::extrude::extrude_city;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::city::City;
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use blockwalk::tiles::{build_tileset, ContentEncoding, TilesetOptions, TilesetSummary};
use support::glb::Glb;

/// The largest angle between a compact normal and its plain one, degrees: 8-bit octahedral
/// coordinates (steps of 1/127 on the octahedron) decoded to 8-bit components.
const NORMAL_TOLERANCE_DEG: f64 = 2.0;

struct Out {
    dir: tempfile::TempDir,
    summary: TilesetSummary,
}

fn load(input: &Path, streets: Option<PathBuf>) -> Scene {
    let source = CitySource::parse(input, streets, None, &[], 0).expect("source");
    Scene::load(
        &source,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
        &mut |_| {},
    )
    .expect("scene")
}

fn export(scene: &Scene, city: &City, opts: &TilesetOptions<'_>) -> Out {
    let meshes = extrude_city(city);
    let dir = tempfile::tempdir().unwrap();
    let (_, summary) = build_tileset(
        city,
        &scene.layout,
        &scene.bounds,
        &meshes,
        dir.path(),
        opts,
        &|_, _| {},
    )
    .expect("tileset");
    Out { dir, summary }
}

/// Every file of a tileset folder, relative, sorted.
fn files(dir: &Path) -> Vec<PathBuf> {
    fn walk(d: &Path, root: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, root, out);
            } else {
                out.push(p.strip_prefix(root).unwrap().to_path_buf());
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    out
}

/// A point of a content: its f32 position's bits, colour and feature id.
type Key = ([u32; 3], [u8; 4], u32);

/// What one content's comparison measured.
#[derive(Default)]
struct Measured {
    position_m: f64,
    normal_deg: f64,
    stated_m: f64,
    triangles: usize,
}

/// Compares a compact content with the plain one of the same tile (see the file's doc);
/// `shared` collects, per plain terrain vertex, where the compact contents put it.
fn compare(
    plain: &Glb,
    compact: &Glb,
    shared: Option<&mut HashMap<[u32; 3], [f64; 3]>>,
) -> Measured {
    let name = &compact.name;
    assert!(!plain.compressed && compact.compressed, "{name}");
    let required: Vec<&str> = compact.doc["extensionsRequired"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_str().unwrap())
        .collect();
    assert!(
        required.contains(&"EXT_meshopt_compression")
            && required.contains(&"KHR_mesh_quantization")
    );
    // The same extras, and the error stated.
    let mut extras = compact.extras().clone();
    let stated = extras["position_error_m"]
        .as_f64()
        .expect("position_error_m");
    let encoding = extras["position_encoding"]
        .as_str()
        .expect("position_encoding")
        .to_string();
    extras.as_object_mut().unwrap().remove("position_error_m");
    extras.as_object_mut().unwrap().remove("position_encoding");
    assert_eq!(&extras, plain.extras(), "{name}: extras");
    assert!(stated < 1e-3, "{name}: stated error {stated} m");
    // Property tables and feature id sets.
    assert_eq!(
        plain.properties(),
        compact.properties(),
        "{name}: property table"
    );
    assert_eq!(
        plain.primitive()["extensions"],
        compact.primitive()["extensions"],
        "{name}: EXT_mesh_features"
    );
    assert_eq!(
        plain.doc["extensions"]["EXT_structural_metadata"]["schema"],
        compact.doc["extensions"]["EXT_structural_metadata"]["schema"]
    );

    let attrs = |g: &Glb| {
        let p = g.positions();
        let n = g.normals();
        let c = g.colors().unwrap_or_else(|| vec![[0; 4]; p.len()]);
        let f = g.feature_ids().unwrap_or_else(|| vec![u32::MAX; p.len()]);
        assert!(
            n.len() == p.len() && c.len() == p.len() && f.len() == p.len(),
            "{}",
            g.name
        );
        (p, n, c, f)
    };
    let (pp, pn, pc, pf) = attrs(plain);
    let (cp, cn, cc, cf) = attrs(compact);

    // Plain vertices by 1 cm cell.
    let cell = |p: [f64; 3]| p.map(|x| (x / 0.01).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, p) in pp.iter().enumerate() {
        grid.entry(cell(*p)).or_default().push(i);
    }
    let dist = |a: [f64; 3], b: [f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let angle = |a: [f64; 3], b: [f64; 3]| {
        (a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    };
    // A point of the content: plain vertices of the same colour and feature within 1 mm of each
    // other (a prism corner's vertices, one per face, or a footprint's near-duplicate corners)
    // are one point, each standing for the first of its kind. Normals do not take part: a
    // corner of two nearly parallel walls has two normals closer than the octahedral error, so a
    // compact normal may lie nearer the other wall's; the triangles below tell them apart.
    let exact = |i: usize| -> Key { (pp[i].map(|x| (x as f32).to_bits()), pc[i], pf[i]) };
    let mut kinds: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    let mut first = vec![0usize; pp.len()];
    for i in 0..pp.len() {
        let c = cell(pp[i]);
        let mut found = None;
        'near: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    for &r in kinds
                        .get(&[c[0] + dx, c[1] + dy, c[2] + dz])
                        .into_iter()
                        .flatten()
                    {
                        if pc[r] == pc[i] && pf[r] == pf[i] && dist(pp[r], pp[i]) < 1e-3 {
                            found = Some(r);
                            break 'near;
                        }
                    }
                }
            }
        }
        first[i] = found.unwrap_or_else(|| {
            kinds.entry(c).or_default().push(i);
            i
        });
    }
    let key = |i: usize| exact(first[i]);
    let mut m = Measured {
        stated_m: stated,
        ..Measured::default()
    };
    // Each compact vertex: the point of the nearest plain vertex of the same colour and feature
    // within 1 mm.
    let matched: Vec<Key> = (0..cp.len())
        .map(|i| {
            let c = cell(cp[i]);
            let mut best: Option<(f64, usize)> = None;
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(v) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                            continue;
                        };
                        for &j in v {
                            let d = dist(cp[i], pp[j]);
                            if d < 1e-3
                                && pc[j] == cc[i]
                                && pf[j] == cf[i]
                                && best.is_none_or(|(bd, _)| d < bd)
                            {
                                best = Some((d, j));
                            }
                        }
                    }
                }
            }
            let (d, j) = best.unwrap_or_else(|| {
                panic!(
                    "{name}: compact vertex {i} at {:?} has no plain vertex within 1 mm",
                    cp[i]
                )
            });
            m.position_m = m.position_m.max(d);
            key(j)
        })
        .collect();
    if let Some(s) = shared {
        for (i, k) in matched.iter().enumerate() {
            let was = *s.entry(k.0).or_insert(cp[i]);
            assert_eq!(
                was, cp[i],
                "{name}: a shared terrain vertex decodes differently in two tiles"
            );
        }
    }
    // Triangles by their points, rotated to start at the smallest (winding kept); a triangle
    // with two equal points has two such rotations, and both are tried below.
    let rotations = |t: [usize; 3], key: &dyn Fn(usize) -> Key| -> ([Key; 3], Vec<[usize; 3]>) {
        let all: Vec<[usize; 3]> = (0..3)
            .map(|k| [t[k], t[(k + 1) % 3], t[(k + 2) % 3]])
            .collect();
        let least = all.iter().map(|r| r.map(key)).min().unwrap();
        let at_least = all.into_iter().filter(|r| r.map(key) == least).collect();
        (least, at_least)
    };
    let (pi, ci) = (plain.indices(), compact.indices());
    assert_eq!(pi.len(), ci.len(), "{name}: index count");
    let mut plain_tris: HashMap<[Key; 3], Vec<Option<[usize; 3]>>> = HashMap::new();
    for t in pi.chunks(3) {
        let (k, r) = rotations([0, 1, 2].map(|v| t[v] as usize), &key);
        plain_tris.entry(k).or_default().push(Some(r[0]));
    }
    // Each compact triangle takes the plain triangle of the same points, not yet taken, whose
    // normals are nearest its own (the largest of the three angles); every angle must be within
    // the octahedral tolerance.
    for t in ci.chunks(3) {
        let (k, rots) = rotations([0, 1, 2].map(|v| t[v] as usize), &|i| matched[i]);
        let Some(candidates) = plain_tris.get_mut(&k) else {
            panic!("{name}: the triangles differ: a compact triangle at {:?} is not in the plain content", t.iter().map(|&v| cp[v as usize]).collect::<Vec<_>>());
        };
        let mut best: Option<(f64, usize)> = None;
        for (n, c) in candidates.iter().enumerate() {
            let Some(pv) = c else { continue };
            for r in &rots {
                let worst = (0..3)
                    .map(|v| angle(cn[r[v]], pn[pv[v]]))
                    .fold(0.0f64, f64::max);
                if best.is_none_or(|(b, _)| worst < b) {
                    best = Some((worst, n));
                }
            }
        }
        let (worst, n) = best.unwrap_or_else(|| {
            panic!(
                "{name}: the triangles differ: more compact than plain triangles at {:?}",
                t.iter().map(|&v| cp[v as usize]).collect::<Vec<_>>()
            )
        });
        candidates[n] = None;
        m.normal_deg = m.normal_deg.max(worst);
    }
    // Every plain triangle is taken once: the same triangles.
    assert!(
        plain_tris.values().flatten().all(Option::is_none),
        "{name}: the triangles differ"
    );
    m.triangles = pi.len() / 3;
    assert!(
        m.position_m < 1e-3,
        "{name}: position error {} m",
        m.position_m
    );
    assert!(
        m.position_m <= stated + 1e-12,
        "{name} ({encoding}): measured {} m over the stated {stated} m",
        m.position_m
    );
    assert!(
        m.normal_deg < NORMAL_TOLERANCE_DEG,
        "{name}: normal off by {}°",
        m.normal_deg
    );
    m
}

/// Exports `city` plain and compact and compares every content (see the file's doc).
fn plain_against_compact(
    name: &str,
    scene: &Scene,
    city: &City,
    opts: &TilesetOptions<'_>,
) -> (u64, u64, Vec<String>) {
    let plain = export(
        scene,
        city,
        &TilesetOptions {
            content: ContentEncoding::Plain,
            ..*opts
        },
    );
    let compact = export(
        scene,
        city,
        &TilesetOptions {
            content: ContentEncoding::Compact,
            ..*opts
        },
    );
    assert_eq!(compact.summary.content, ContentEncoding::Compact);
    assert_eq!(plain.summary.position_error_m, 0.0);
    let (pd, cd) = (plain.dir.path(), compact.dir.path());
    let list = files(pd);
    assert_eq!(list, files(cd), "{name}: the same files");
    let (mut worst, mut normal, mut stated, mut contents, mut tris) =
        (0.0f64, 0.0f64, 0.0f64, 0, 0);
    let mut encodings: HashMap<String, usize> = HashMap::new();
    let mut shared = HashMap::new();
    let mut bytes = [0u64; 2];
    for f in &list {
        let (a, b) = (
            std::fs::read(pd.join(f)).unwrap(),
            std::fs::read(cd.join(f)).unwrap(),
        );
        bytes[0] += a.len() as u64;
        bytes[1] += b.len() as u64;
        if f.extension().is_some_and(|e| e == "json") {
            // The same tile tree, boxes and errors: contents do not change the tileset.
            assert!(a == b, "{name}: {} differs", f.display());
            continue;
        }
        let p = Glb::from_bytes(&format!("plain {}", f.display()), &a);
        let c = Glb::from_bytes(&format!("{name}: compact {}", f.display()), &b);
        let terrain = f.starts_with("terrain");
        let m = compare(&p, &c, terrain.then_some(&mut shared));
        *encodings
            .entry(
                c.extras()["position_encoding"]
                    .as_str()
                    .unwrap()
                    .to_string(),
            )
            .or_default() += 1;
        worst = worst.max(m.position_m);
        normal = normal.max(m.normal_deg);
        stated = stated.max(m.stated_m);
        contents += 1;
        tris += m.triangles;
    }
    assert!(contents > 5, "{name}: {contents} contents");
    // The summary states the largest error of all contents.
    assert_eq!(compact.summary.position_error_m, stated, "{name}");
    assert_eq!(
        bytes[0], plain.summary.bytes,
        "{name}: summary bytes (plain)"
    );
    assert_eq!(
        bytes[1], compact.summary.bytes,
        "{name}: summary bytes (compact)"
    );
    let mut enc: Vec<_> = encodings.into_iter().collect();
    enc.sort();
    println!(
        "{name}: {contents} contents, {tris} triangles: plain {} bytes, compact {} bytes ({:.1} %); \
         positions within {:.3} mm (stated {:.3} mm), normals within {:.2}°; encodings {enc:?}",
        bytes[0],
        bytes[1],
        100.0 * bytes[1] as f64 / bytes[0] as f64,
        worst * 1e3,
        stated * 1e3,
        normal
    );
    (
        bytes[0],
        bytes[1],
        enc.into_iter().map(|(e, _)| e).collect(),
    )
}

#[test]
fn compact_helsinki_decodes_to_the_plain_contents() {
    let scene = load(
        Path::new("data/helsinki/buildings.shp"),
        Some("data/helsinki/streets_blockclass.shp".into()),
    );
    let (plain, compact, _) =
        plain_against_compact("helsinki", &scene, &scene.city, &TilesetOptions::default());
    // The point of the encoding: at most half the bytes.
    assert!(
        2 * compact <= plain,
        "{compact} bytes compact, {plain} plain"
    );
}

#[test]
fn compact_generated_city_decodes_to_the_plain_contents() {
    let dir = tempfile::tempdir().unwrap();
    let g = generate_city(&GenerateParams {
        buildings: 3000,
        seed: 11,
        ..Default::default()
    })
    .unwrap();
    write_city(&g, dir.path()).unwrap();
    let scene = load(dir.path(), None);
    let (plain, compact, _) = plain_against_compact(
        "generated 3k",
        &scene,
        &scene.city,
        &TilesetOptions::default(),
    );
    assert!(
        2 * compact <= plain,
        "{compact} bytes compact, {plain} plain"
    );
}

/// Astana (32,056 buildings, real data the encoding was not tuned on): every content decodes to
/// the plain one, in at most half the bytes. Skipped loudly without the Astana data unless it is
/// required (`BLOCKWALK_REQUIRE=astana`).
#[test]
fn compact_astana_decodes_to_the_plain_contents() {
    let Some(dir) = support::skip::or_skip(
        support::skip::Need::Astana,
        "compact_astana_decodes_to_the_plain_contents",
        support::data::astana_dir(),
    ) else {
        return;
    };
    let scene = load(
        &dir.join("buildings.shp"),
        Some(dir.join("streets_blockclass.shp")),
    );
    let (plain, compact, _) =
        plain_against_compact("astana", &scene, &scene.city, &TilesetOptions::default());
    assert!(
        2 * compact <= plain,
        "{compact} bytes compact, {plain} plain"
    );
}

/// Terrain tiles too, and the vertices two terrain leaves share land on the same point in both.
#[test]
fn compact_terrain_decodes_to_the_plain_contents_without_cracks() {
    let scene = load(Path::new("data/helsinki/buildings.shp"), None);
    let (city, tin) = support::terrain::terrain_city(&scene.city, 20.0);
    let (_, _, encodings) = plain_against_compact(
        "helsinki on terrain",
        &scene,
        &city,
        &TilesetOptions {
            terrain: Some(&tin),
            terrain_leaf_triangles: 1000,
            ..TilesetOptions::default()
        },
    );
    // Both quantised forms were read back: small tiles on the u16 grid, wider ones through the
    // exponential filter.
    assert!(encodings.iter().any(|e| e == "u16"), "{encodings:?}");
    assert!(
        encodings.iter().any(|e| e.starts_with("exp")),
        "{encodings:?}"
    );
}

#[test]
fn compact_contents_are_valid_gltf() {
    let Some(node) = support::node::or_skip(
        "compact_contents_are_valid_gltf",
        support::node::node_with(&["gltf-validator"]),
    ) else {
        return;
    };
    let scene = load(
        Path::new("data/helsinki/buildings.shp"),
        Some("data/helsinki/streets_blockclass.shp".into()),
    );
    let (city, tin) = support::terrain::terrain_city(&scene.city, 20.0);
    let out = export(
        &scene,
        &city,
        &TilesetOptions {
            terrain: Some(&tin),
            terrain_leaf_triangles: 4000,
            ..TilesetOptions::default()
        },
    );
    let mut totals = [0u64; 4];
    let mut codes: HashMap<String, u64> = HashMap::new();
    let mut n = 0;
    for f in files(out.dir.path()) {
        if f.extension().is_none_or(|e| e != "glb") {
            continue;
        }
        let r = support::node::run_json(&node, "validate_gltf.js", &out.dir.path().join(&f));
        let i = &r["issues"];
        let c =
            ["numErrors", "numWarnings", "numInfos", "numHints"].map(|k| i[k].as_u64().unwrap());
        assert_eq!(c[0], 0, "{}: {:#}", f.display(), i["messages"]);
        for m in i["messages"].as_array().unwrap() {
            *codes
                .entry(m["code"].as_str().unwrap().to_string())
                .or_default() += 1;
        }
        for k in 0..4 {
            totals[k] += c[k];
        }
        n += 1;
    }
    let mut codes: Vec<_> = codes.into_iter().collect();
    codes.sort();
    println!(
        "{n} compact .glb validated: {} errors, {} warnings, {} infos, {} hints: {codes:?}",
        totals[0], totals[1], totals[2], totals[3]
    );
    assert!(n > 5);
}
