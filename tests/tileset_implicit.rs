//! The implicit and one-file (`.3tz`) forms of the Helsinki tileset against the explicit one.
//!
//! - Our own reader of the implicit form (subtree headers, availability bitstreams in Morton
//!   order, the tile property table) expands it into tiles that are the explicit tree's: the same
//!   BqR keys, kinds, boxes, geometric errors, parents and content bytes; each child at its
//!   quadrant's (level, x, y), a node's own blocks in a free slot.
//! - The `.3tz` read by hand: the index is the last entry, stored, sorted by hash; every other
//!   entry is found by the MD5 of its path and its offset points at its local header; the entries
//!   are exactly the folder's files, byte for byte.
//! - A `.3tz` is replaced only when the new one is complete; a failed run leaves it and nothing
//!   else behind.
//! - 3d-tiles-tools (npm `3d-tiles-tools`) converts each `.3tz` back into exactly the folder's
//!   files and traverses the implicit form into exactly the explicit tree's tiles (skipped loudly
//!   without node, unless the validators are required: `BLOCKWALK_REQUIRE=validators`).

mod support;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use blockwalk::city::extrude::extrude_city;
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use blockwalk::tiles::{build_tileset, TilesError, TilesetOptions, TilesetSummary};
use md5::{Digest, Md5};
use serde_json::Value;

fn helsinki() -> (Scene, Vec<blockwalk::city::Mesh>) {
    let source = CitySource::parse(
        Path::new("data/helsinki/buildings.shp"),
        Some("data/helsinki/streets_blockclass.shp".into()),
        None,
        &[],
        0,
    )
    .unwrap();
    let scene = Scene::load(
        &source,
        &SceneOptions {
            structures: Vec::new(),
            ..SceneOptions::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let meshes = extrude_city(&scene.city);
    (scene, meshes)
}

fn write(
    scene: &Scene,
    meshes: &[blockwalk::city::Mesh],
    out: &Path,
    implicit: bool,
    subtree_levels: u32,
    archive: bool,
) -> Result<TilesetSummary, TilesError> {
    build_tileset(
        &scene.city,
        &scene.layout,
        &scene.bounds,
        meshes,
        out,
        &TilesetOptions {
            implicit,
            subtree_levels,
            archive,
            ..TilesetOptions::default()
        },
        &|_, _| {},
    )
    .map(|(_, s)| s)
}

/// One tile as both readers give it.
#[derive(Clone, Debug, PartialEq)]
struct T {
    kind: String,
    bbox: Vec<f64>,
    geometric_error: f64,
    parent: Option<u64>,
    content: Option<Vec<u8>>,
}

/// The explicit tree, by node key.
fn read_explicit(dir: &Path) -> BTreeMap<u64, T> {
    let doc: Value =
        serde_json::from_slice(&std::fs::read(dir.join("tileset.json")).unwrap()).unwrap();
    let mut out = BTreeMap::new();
    let mut stack = vec![(&doc["root"], None)];
    while let Some((t, parent)) = stack.pop() {
        let key = t["extras"]["node_key"].as_u64().unwrap();
        let content = t["content"]["uri"]
            .as_str()
            .map(|u| std::fs::read(dir.join(u)).unwrap());
        let bbox = t["boundingVolume"]["box"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let prev = out.insert(
            key,
            T {
                kind: t["extras"]["kind"].as_str().unwrap().to_string(),
                bbox,
                geometric_error: t["geometricError"].as_f64().unwrap(),
                parent,
                content,
            },
        );
        assert!(prev.is_none(), "key {key} twice");
        for c in t["children"].as_array().into_iter().flatten() {
            stack.push((c, Some(key)));
        }
    }
    out
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}
fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap())
}

/// An availability: every bit of `n` from a constant or a bitstream (bit i at byte i / 8, bit
/// i % 8).
fn bits(av: &Value, views: &[&[u8]], n: usize) -> Vec<bool> {
    if let Some(c) = av.get("constant") {
        return vec![c.as_u64().unwrap() == 1; n];
    }
    let v = views[av["bitstream"].as_u64().unwrap() as usize];
    assert!(v.len() >= n.div_ceil(8));
    let out: Vec<bool> = (0..n).map(|i| v[i / 8] >> (i % 8) & 1 == 1).collect();
    if let Some(count) = av.get("availableCount") {
        assert_eq!(
            out.iter().filter(|b| **b).count() as u64,
            count.as_u64().unwrap()
        );
    }
    out
}

/// (x, y) of a Morton index: x from the even bits, y from the odd.
fn demorton(m: u64) -> (u32, u32) {
    let (mut x, mut y) = (0u32, 0u32);
    for i in 0..32 {
        x |= ((m >> (2 * i)) & 1) as u32 * (1 << i);
        y |= ((m >> (2 * i + 1)) & 1) as u32 * (1 << i);
    }
    (x, y)
}

/// (level, x, y) by node key.
type Coords = BTreeMap<u64, (u32, u32, u32)>;

/// The implicit tree expanded from its subtree files, by node key, and each key's (level, x, y).
fn read_implicit(dir: &Path) -> (BTreeMap<u64, T>, Coords) {
    let doc: Value =
        serde_json::from_slice(&std::fs::read(dir.join("tileset.json")).unwrap()).unwrap();
    let root = &doc["root"];
    let it = &root["implicitTiling"];
    assert_eq!(it["subdivisionScheme"], "QUADTREE");
    assert_eq!(root["content"]["uri"], "tiles/{level}/{x}/{y}.glb");
    assert_eq!(it["subtrees"]["uri"], "subtrees/{level}/{x}/{y}.subtree");
    assert_eq!(root["refine"], "REPLACE");
    let s = it["subtreeLevels"].as_u64().unwrap() as u32;
    let available = it["availableLevels"].as_u64().unwrap() as u32;
    // The schema names the semantics the tile properties carry.
    let props = &doc["schema"]["classes"]["tile"]["properties"];
    assert_eq!(props["bounding_box"]["semantic"], "TILE_BOUNDING_BOX");
    assert_eq!(props["geometric_error"]["semantic"], "TILE_GEOMETRIC_ERROR");

    let mut by_coord: BTreeMap<(u32, u32, u32), (u64, T)> = BTreeMap::new();
    let mut queue = vec![(0u32, 0u32, 0u32)];
    while let Some((l0, x0, y0)) = queue.pop() {
        let b = std::fs::read(dir.join(format!("subtrees/{l0}/{x0}/{y0}.subtree"))).unwrap();
        assert_eq!(&b[..4], b"subt");
        assert_eq!(u32_at(&b, 4), 1);
        let (jl, bl) = (u64_at(&b, 8) as usize, u64_at(&b, 16) as usize);
        assert_eq!(jl % 8, 0);
        assert_eq!(bl % 8, 0);
        assert_eq!(b.len(), 24 + jl + bl);
        let j: Value = serde_json::from_slice(&b[24..24 + jl]).unwrap();
        let buf = &b[24 + jl..];
        assert_eq!(j["buffers"][0]["byteLength"].as_u64().unwrap() as usize, bl);
        let views: Vec<&[u8]> = j["bufferViews"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| {
                let o = v["byteOffset"].as_u64().unwrap() as usize;
                assert_eq!(o % 8, 0);
                &buf[o..o + v["byteLength"].as_u64().unwrap() as usize]
            })
            .collect();
        let n_tiles = ((1usize << (2 * s)) - 1) / 3;
        let tile_av = bits(&j["tileAvailability"], &views, n_tiles);
        let content_av = bits(&j["contentAvailability"][0], &views, n_tiles);
        let child_av = bits(&j["childSubtreeAvailability"], &views, 1 << (2 * s));
        let table = &j["propertyTables"][j["tileMetadata"].as_u64().unwrap() as usize];
        assert_eq!(table["class"], "tile");
        let col =
            |name: &str| views[table["properties"][name]["values"].as_u64().unwrap() as usize];
        let (boxes, errors, keys, kinds) = (
            col("bounding_box"),
            col("geometric_error"),
            col("node_key"),
            col("kind"),
        );
        let mut row = 0usize;
        for l in 0..s {
            let first = ((1usize << (2 * l)) - 1) / 3;
            for m in 0..(1usize << (2 * l)) {
                let i = first + m;
                if !tile_av[i] {
                    assert!(!content_av[i], "content without a tile");
                    continue;
                }
                let (dx, dy) = demorton(m as u64);
                let c = (l0 + l, (x0 << l) + dx, (y0 << l) + dy);
                let key = u64_at(keys, 8 * row);
                let t = T {
                    kind: ["blockmap", "buildings"][kinds[row] as usize].to_string(),
                    bbox: (0..12)
                        .map(|k| {
                            f64::from_le_bytes(
                                boxes[96 * row + 8 * k..96 * row + 8 * k + 8]
                                    .try_into()
                                    .unwrap(),
                            )
                        })
                        .collect(),
                    geometric_error: f64::from_le_bytes(
                        errors[8 * row..8 * row + 8].try_into().unwrap(),
                    ),
                    parent: None,
                    content: content_av[i].then(|| {
                        std::fs::read(dir.join(format!("tiles/{}/{}/{}.glb", c.0, c.1, c.2)))
                            .unwrap()
                    }),
                };
                row += 1;
                assert!(by_coord.insert(c, (key, t)).is_none());
            }
        }
        assert_eq!(row as u64, table["count"].as_u64().unwrap());
        for (m, _) in child_av.iter().enumerate().filter(|(_, b)| **b) {
            let (dx, dy) = demorton(m as u64);
            queue.push((l0 + s, (x0 << s) + dx, (y0 << s) + dy));
        }
    }
    assert_eq!(
        by_coord.keys().map(|c| c.0).max().unwrap() + 1,
        available,
        "availableLevels"
    );
    // Parents: the tile at (l − 1, x / 2, y / 2), which must exist.
    let mut tiles = BTreeMap::new();
    let mut coords = BTreeMap::new();
    for (c, (key, t)) in &by_coord {
        let mut t = t.clone();
        if c.0 > 0 {
            let p = (c.0 - 1, c.1 / 2, c.2 / 2);
            t.parent = Some(
                by_coord
                    .get(&p)
                    .unwrap_or_else(|| panic!("{c:?}: no parent"))
                    .0,
            );
        }
        assert!(tiles.insert(*key, t).is_none(), "key {key} twice");
        coords.insert(*key, *c);
    }
    (tiles, coords)
}

#[test]
fn the_implicit_tree_read_from_its_subtrees_is_the_explicit_tree() {
    let (scene, meshes) = helsinki();
    let work = tempfile::tempdir().unwrap();
    let ex = work.path().join("explicit");
    write(&scene, &meshes, &ex, false, 3, false).unwrap();
    let explicit = read_explicit(&ex);
    assert!(explicit.len() > 20);
    // Several subtree depths: one subtree for the whole tree, child subtrees at every level.
    for s in [1, 2, 3, 10] {
        let im = work.path().join(format!("implicit_{s}"));
        let summary = write(&scene, &meshes, &im, true, s, false).unwrap();
        let (implicit, coords) = read_implicit(&im);
        assert_eq!(implicit.len(), explicit.len(), "subtree levels {s}");
        for (key, t) in &explicit {
            assert_eq!(
                implicit.get(key),
                Some(t),
                "subtree levels {s}: node {key:#x}"
            );
        }
        // Each child in its quadrant's slot; a node's own blocks (4k + 4) in a free one.
        for (key, t) in &explicit {
            let Some(p) = t.parent else { continue };
            let (c, pc) = (coords[key], coords[&p]);
            assert_eq!(c.0, pc.0 + 1);
            assert_eq!((c.1 / 2, c.2 / 2), (pc.1, pc.2));
            if *key != 4 * p + 4 {
                let depth = |k: u64| (63 - k.leading_zeros()) / 2;
                let q = (key >> (2 * (depth(*key) - depth(p) - 1))) & 3;
                assert_eq!(((c.1 & 1) as u64, (c.2 & 1) as u64), (q & 1, q >> 1));
            }
        }
        let n_files = walk(&im).len();
        let subtrees = walk(&im)
            .iter()
            .filter(|f| f.starts_with("subtrees/"))
            .count();
        assert_eq!(subtrees, summary.subtrees);
        assert_eq!(
            n_files,
            1 + subtrees + explicit.values().filter(|t| t.content.is_some()).count()
        );
    }
}

#[test]
fn an_implicit_tileset_folder_replaces_and_is_replaced_by_a_tileset() {
    let (scene, meshes) = helsinki();
    let work = tempfile::tempdir().unwrap();
    let dir = work.path().join("tiles");
    write(&scene, &meshes, &dir, false, 3, false).unwrap();
    write(&scene, &meshes, &dir, true, 3, false).unwrap();
    assert!(dir.join("subtrees/0/0/0.subtree").is_file());
    assert!(!walk(&dir).iter().any(|f| f.starts_with("tiles/leaf_")));
    write(&scene, &meshes, &dir, true, 3, false).unwrap();
    write(&scene, &meshes, &dir, false, 3, false).unwrap();
    assert!(!dir.join("subtrees").exists());
}

/// Relative paths of every file under `dir`, sorted.
fn walk(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap();
                out.push(rel.to_str().unwrap().replace('\\', "/"));
            }
        }
    }
    out.sort();
    out
}

/// The `.3tz` checked by hand against the folder `dir` it must hold.
fn check_archive(path: &Path, dir: &Path) {
    let bytes = std::fs::read(path).unwrap();
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes.clone())).unwrap();
    let names: Vec<String> = zip.file_names().map(|n| n.unwrap().into_owned()).collect();
    // The index is the last central directory record, and stored.
    let last = (0..zip.len())
        .max_by_key(|&i| zip.by_index_raw(i).unwrap().central_header_start())
        .unwrap();
    let idx = zip.by_index_raw(last).unwrap();
    assert_eq!(idx.name().unwrap(), "@3dtilesIndex1@");
    assert_eq!(idx.compression(), zip::CompressionMethod::Stored);
    drop(idx);
    let mut index = Vec::new();
    std::io::Read::read_to_end(&mut zip.by_name("@3dtilesIndex1@").unwrap(), &mut index).unwrap();
    let files = walk(dir);
    let mut entries: Vec<&String> = names.iter().filter(|n| *n != "@3dtilesIndex1@").collect();
    entries.sort();
    assert_eq!(
        entries,
        files.iter().collect::<Vec<_>>(),
        "entries = the folder's files"
    );
    assert_eq!(index.len(), 24 * entries.len());
    let rows: Vec<([u8; 16], u64)> = index
        .chunks(24)
        .map(|r| (r[..16].try_into().unwrap(), u64_at(r, 16)))
        .collect();
    let order = |h: &[u8; 16]| (u64_at(h, 0), u64_at(h, 8));
    assert!(
        rows.windows(2).all(|w| order(&w[0].0) < order(&w[1].0)),
        "index sorted by hash"
    );
    let opened = blockwalk::tiles::archive::Archive::open(path).unwrap();
    for name in &entries {
        let h: [u8; 16] = Md5::digest(name.as_bytes()).into();
        let i = rows
            .binary_search_by_key(&order(&h), |r| order(&r.0))
            .unwrap_or_else(|_| panic!("{name} not in the index"));
        let off = rows[i].1 as usize;
        // A local file header naming the entry.
        assert_eq!(u32_at(&bytes, off), 0x0403_4b50, "{name}");
        let name_len = u16::from_le_bytes(bytes[off + 26..off + 28].try_into().unwrap()) as usize;
        assert_eq!(&bytes[off + 30..off + 30 + name_len], name.as_bytes());
        assert_eq!(
            zip.by_name(name).unwrap().header_start(),
            off as u64,
            "{name}"
        );
        // The bytes, through the central directory and through the index, are the file's.
        let mut got = Vec::new();
        std::io::Read::read_to_end(&mut zip.by_name(name).unwrap(), &mut got).unwrap();
        let want = std::fs::read(dir.join(name.as_str())).unwrap();
        assert!(got == want, "{name}: bytes differ");
        assert!(
            opened.read(name).unwrap().unwrap() == want,
            "{name}: index read differs"
        );
    }
    assert_eq!(opened.read("tiles/none.glb").unwrap(), None);
}

#[test]
fn a_3tz_holds_the_folder_and_an_index_that_finds_every_entry() {
    let (scene, meshes) = helsinki();
    let work = tempfile::tempdir().unwrap();
    for implicit in [false, true] {
        let dir = work.path().join(format!("dir_{implicit}"));
        let file = work.path().join(format!("city_{implicit}.3tz"));
        write(&scene, &meshes, &dir, implicit, 3, false).unwrap();
        let s = write(&scene, &meshes, &file, implicit, 3, true).unwrap();
        assert!(s.archive);
        assert_eq!(s.bytes, std::fs::metadata(&file).unwrap().len());
        assert_eq!(s.tileset_json, file);
        check_archive(&file, &dir);
        // Deterministic: the same city, the same archive.
        let again = work.path().join("again.3tz");
        write(&scene, &meshes, &again, implicit, 3, true).unwrap();
        assert!(std::fs::read(&again).unwrap() == std::fs::read(&file).unwrap());
    }
}

#[test]
fn a_3tz_is_replaced_only_when_complete() {
    let (scene, meshes) = helsinki();
    let work = tempfile::tempdir().unwrap();
    let file = work.path().join("city.3tz");
    std::fs::write(&file, b"previous").unwrap();
    // Fails after the contents were written (no subtree of 0 levels): the previous file stays,
    // and no staging folder or partial file is left beside it.
    let e = write(&scene, &meshes, &file, true, 0, true).unwrap_err();
    assert!(e.to_string().contains("subtree levels"), "{e}");
    assert_eq!(std::fs::read(&file).unwrap(), b"previous");
    assert_eq!(walk(work.path()), vec!["city.3tz".to_string()]);
    // A folder at the path is refused before any work.
    let d = work.path().join("dir.3tz");
    std::fs::create_dir(&d).unwrap();
    let e = write(&scene, &meshes, &d, false, 3, true).unwrap_err();
    assert!(e.to_string().contains("folder"), "{e}");
    // Success replaces it whole.
    write(&scene, &meshes, &file, false, 3, true).unwrap();
    assert!(
        blockwalk::tiles::archive::Archive::open(&file)
            .unwrap()
            .len()
            > 10
    );
    let mut left: Vec<String> = std::fs::read_dir(work.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["city.3tz", "dir.3tz"]);
}

/// Signature of a tile as 3d-tiles-tools reports it: its box, error and contents' MD5s.
fn tools_sig(t: &Value) -> String {
    format!(
        "{} {} {}",
        t["box"],
        t["geometric_error"],
        t["contents"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c["md5"].as_str().unwrap_or("?").to_string())
            .collect::<Vec<_>>()
            .join(",")
    )
}

/// (tile, parent) signatures of a 3d-tiles-tools traversal; the implicit root as tileset.json
/// writes it (a template content) dropped, its child then the root.
fn tools_tree(report: &Value) -> BTreeSet<(String, Option<String>)> {
    let tiles = report["tiles"].as_array().unwrap();
    let by_path: BTreeMap<&str, &Value> = tiles
        .iter()
        .map(|t| (t["path"].as_str().unwrap(), t))
        .collect();
    let template = |t: &Value| {
        t["contents"]
            .as_array()
            .unwrap()
            .iter()
            .any(|c| c["template"] == true)
    };
    tiles
        .iter()
        .filter(|t| !template(t))
        .map(|t| {
            let parent = t["parent"]
                .as_str()
                .map(|p| by_path[p])
                .filter(|p| !template(p))
                .map(tools_sig);
            (tools_sig(t), parent)
        })
        .collect()
}

#[test]
fn tiles_tools_read_every_form_as_the_same_tree() {
    let Some(node) = support::node::or_skip(
        "tiles_tools_read_every_form_as_the_same_tree",
        support::node::node_with(&["3d-tiles-tools"]),
    ) else {
        return;
    };
    let (scene, meshes) = helsinki();
    let work = tempfile::tempdir().unwrap();
    let forms: Vec<(&str, bool, bool, PathBuf)> = vec![
        ("explicit", false, false, work.path().join("explicit")),
        ("implicit", true, false, work.path().join("implicit")),
        (
            "explicit.3tz",
            false,
            true,
            work.path().join("explicit.3tz"),
        ),
        ("implicit.3tz", true, true, work.path().join("implicit.3tz")),
    ];
    let mut trees = BTreeMap::new();
    for (name, implicit, archive, path) in &forms {
        write(&scene, &meshes, path, *implicit, 3, *archive).unwrap();
        let report = support::node::run_json(&node, "tiles_tools_traverse.mjs", path);
        let tiles = report["tiles"].as_array().unwrap();
        println!(
            "3d-tiles-tools: {name}: {} entries, {} tiles traversed",
            report["entries"],
            tiles.len()
        );
        // Every content read (a template only at the implicit root).
        for t in tiles {
            for c in t["contents"].as_array().unwrap() {
                assert!(c["md5"].is_string() || c["template"] == true, "{name}: {c}");
            }
        }
        trees.insert(*name, tools_tree(&report));
    }
    let explicit = &trees["explicit"];
    assert!(explicit.len() > 20);
    for (name, t) in &trees {
        assert_eq!(t, explicit, "{name}: not the explicit tree");
    }
    // `convert` unpacks each archive into exactly the folder's files.
    let cli = support::node::tools().join("node_modules/3d-tiles-tools/build/src/cli/main.js");
    for (folder, archive) in [(&forms[0].3, &forms[2].3), (&forms[1].3, &forms[3].3)] {
        let out = work.path().join(format!(
            "converted_{}",
            archive.file_stem().unwrap().to_string_lossy()
        ));
        let r = std::process::Command::new(&node)
            .arg(&cli)
            .args(["convert", "-i"])
            .arg(archive)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            r.status.success(),
            "convert {}: {}",
            archive.display(),
            String::from_utf8_lossy(&r.stderr)
        );
        let (a, b) = (walk(&out), walk(folder));
        assert_eq!(a, b, "{}: converted file list", archive.display());
        for f in &a {
            assert!(
                std::fs::read(out.join(f)).unwrap() == std::fs::read(folder.join(f)).unwrap(),
                "{}: {f} differs",
                archive.display()
            );
        }
    }
}
