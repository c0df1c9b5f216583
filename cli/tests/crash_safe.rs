//! Outputs survive a crash, a full disk and an unwritable folder: the binary is killed with
//! SIGKILL in the middle of a large `.glb` export and of `jobs run`; it writes into a full file
//! system (a small tmpfs), a read-only one and `/dev/full`; it writes a tileset over another
//! city's. Each time the final names hold either the previous file or the complete new one, the
//! error names the path and the exit status is non-zero.
//!
//! The tmpfs tests mount file systems and so need root or `sudo -n` (need `mounts`: they skip
//! loudly without it, and fail where `BLOCKWALK_REQUIRE` asks for mounts, as `.ci/run` does).

#[path = "../../tests/support/mod.rs"]
mod support;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};
use support::data::data;
use support::skip::{or_skip, Need};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_blockwalk"))
}

fn run(cmd: &mut Command) -> Output {
    cmd.output().expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A `.glb` whose header length is its file length.
fn complete_glb(p: &Path) -> bool {
    let b = std::fs::read(p).unwrap();
    b.len() >= 12
        && &b[0..4] == b"glTF"
        && u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize == b.len()
}

/// A large city: 60 × 60 blocks, an 80 MB `.glb` written over about 4 s in a debug build.
const BIG: &str = "synthetic:60x60";

#[test]
fn a_killed_glb_export_leaves_the_previous_file_and_a_rerun_completes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.glb");
    std::fs::write(&out, b"the previous model").unwrap();
    let mut child = bin()
        .args(["import", BIG, "-o"])
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Kill it once the temporary file holds a few megabytes: mid-write.
    let t0 = Instant::now();
    let mut killed_at = None;
    while t0.elapsed() < Duration::from_secs(120) {
        let part = names(dir.path()).into_iter().find(|n| n.ends_with(".part"));
        if let Some(p) = part {
            let len = std::fs::metadata(dir.path().join(&p)).map_or(0, |m| m.len());
            if len > 4 << 20 {
                child.kill().unwrap();
                killed_at = Some(len);
                break;
            }
        }
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let status = child.wait().unwrap();
    let len = killed_at.expect("the export was caught mid-write (a temporary of over 4 MiB)");
    assert!(!status.success(), "killed at {len} bytes");
    assert_eq!(
        std::fs::read(&out).unwrap(),
        b"the previous model",
        "the final name holds the previous file"
    );
    // The rerun writes the whole model; the killed run's hidden temporary is all that is left
    // of it.
    let o = run(bin().args(["import", BIG, "-o"]).arg(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(complete_glb(&out));
    let left: Vec<String> = names(dir.path())
        .into_iter()
        .filter(|n| n != "city.glb")
        .collect();
    assert!(
        left.len() == 1 && left[0].starts_with(".city.glb.") && left[0].ends_with(".part"),
        "{left:?}"
    );
}

#[test]
fn dev_full_is_an_error_naming_it_and_devices_are_never_removed() {
    for flag in ["-o", "--cityjson", "--geojson"] {
        let mut cmd = bin();
        cmd.args(["import", BIG, flag, "/dev/full"]);
        if flag != "-o" {
            cmd.args(["-o", "/dev/null"]);
        }
        let o = run(&mut cmd);
        assert!(!o.status.success(), "{flag}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains("/dev/full"), "{flag}: {e}");
        assert!(e.to_lowercase().contains("no space"), "{flag}: {e}");
        use std::os::unix::fs::FileTypeExt;
        let m = std::fs::symlink_metadata("/dev/full").unwrap();
        assert!(
            m.file_type().is_char_device(),
            "/dev/full is still the device"
        );
        let m = std::fs::symlink_metadata("/dev/null").unwrap();
        assert!(
            m.file_type().is_char_device(),
            "/dev/null is still the device"
        );
    }
}

/// A tmpfs mounted for one test, unmounted when dropped.
struct Mount {
    dir: tempfile::TempDir,
}

impl Mount {
    fn tmpfs(test: &str, size: &str) -> Option<Mount> {
        let dir = tempfile::tempdir().unwrap();
        // Owned by the user running the tests, so that a non-root run (through `sudo -n`) can
        // write into it.
        let (uid, gid) = ids();
        let o = privileged("mount")
            .args([
                "-t",
                "tmpfs",
                "-o",
                &format!("size={size},uid={uid},gid={gid}"),
                "tmpfs",
            ])
            .arg(dir.path())
            .output();
        let found = match o {
            Ok(o) if o.status.success() => Ok(()),
            Ok(o) => Err(format!(
                "mounting a tmpfs failed (root, or sudo -n, is needed): {}",
                stderr(&o).trim()
            )),
            Err(e) => Err(format!("cannot run mount: {e}")),
        };
        or_skip(Need::Mounts, test, found)?;
        Some(Mount { dir })
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }

    fn remount_read_only(&self) {
        let o = run(privileged("mount")
            .args(["-o", "remount,ro"])
            .arg(self.path()));
        assert!(o.status.success(), "{}", stderr(&o));
    }

    /// Fills the file system but for about `free` bytes.
    fn fill_but(&self, free: u64) {
        let filler = self.path().join("filler");
        let f = std::fs::File::create(&filler).unwrap();
        let chunk = vec![0u8; 64 << 10];
        let mut w = std::io::BufWriter::new(f);
        use std::io::Write;
        while w.write_all(&chunk).is_ok() {}
        drop(w);
        let len = std::fs::metadata(&filler).unwrap().len();
        std::fs::OpenOptions::new()
            .write(true)
            .open(&filler)
            .unwrap()
            .set_len(len.saturating_sub(free))
            .unwrap();
    }
}

impl Drop for Mount {
    fn drop(&mut self) {
        let _ = privileged("umount").arg(self.dir.path()).output();
    }
}

/// The real user and group ids, read from `/proc/self/status` (no `unsafe` call to `getuid`).
fn ids() -> (String, String) {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |key: &str| {
        s.lines()
            .find(|l| l.starts_with(key))
            .and_then(|l| l.split_whitespace().nth(1))
            .unwrap_or("0")
            .to_string()
    };
    (field("Uid:"), field("Gid:"))
}

/// `program` as root: itself when the tests run as root, else through `sudo -n`.
fn privileged(program: &str) -> Command {
    if ids().0 == "0" {
        Command::new(program)
    } else {
        let mut c = Command::new("sudo");
        c.args(["-n", program]);
        c
    }
}

/// Every output kind into a full file system: each fails naming its path and saying the disk is
/// full, exits non-zero, leaves the previous file as it was and no partial file behind.
#[test]
fn a_full_disk_fails_naming_the_path_and_leaves_no_partial_file() {
    let Some(m) = Mount::tmpfs("a_full_disk_fails_naming_the_path", "8m") else {
        return;
    };
    let root = m.path().to_path_buf();
    let previous = root.join("city.glb");
    std::fs::write(&previous, b"previous").unwrap();
    let gen_src = tempfile::tempdir().unwrap();
    let o = run(bin()
        .args(["generate", "--buildings", "3000", "--seed", "3", "-o"])
        .arg(gen_src.path().join("g")));
    assert!(o.status.success(), "{}", stderr(&o));
    m.fill_but(48 << 10);
    let cases: Vec<(&str, Vec<String>, PathBuf)> = vec![
        (
            "glb",
            vec!["import".into(), BIG.into(), "-o".into(), s(&previous)],
            previous.clone(),
        ),
        (
            "cityjson",
            vec![
                "import".into(),
                BIG.into(),
                "-o".into(),
                "/dev/null".into(),
                "--cityjson".into(),
                s(&root.join("c.city.json")),
            ],
            root.join("c.city.json"),
        ),
        (
            "geojson",
            vec![
                "import".into(),
                BIG.into(),
                "-o".into(),
                "/dev/null".into(),
                "--geojson".into(),
                s(&root.join("c.geojson")),
            ],
            root.join("c.geojson"),
        ),
        (
            "tileset",
            vec![
                "tileset".into(),
                s(&data("bubenec/buildings.shp")),
                "--streets".into(),
                s(&data("bubenec/streets.shp")),
                "-o".into(),
                s(&root.join("tiles")),
            ],
            root.join("tiles"),
        ),
        (
            "generate",
            vec![
                "generate".into(),
                "--buildings".into(),
                "3000".into(),
                "-o".into(),
                s(&root.join("gen")),
            ],
            root.join("gen"),
        ),
        (
            "jobs plan",
            vec![
                "jobs".into(),
                "plan".into(),
                s(&gen_src.path().join("g")),
                "--max-buildings".into(),
                "500".into(),
                "-o".into(),
                s(&root.join("plan")),
            ],
            root.join("plan/plan.json"),
        ),
    ];
    let before: Vec<String> = names(&root);
    for (what, args, target) in &cases {
        let o = run(bin().args(args));
        let e = stderr(&o);
        assert!(!o.status.success(), "{what}: succeeded on a full disk");
        assert!(
            e.contains(&s(target)) || e.contains(&s(target.parent().unwrap())),
            "{what}: the error names the path: {e}"
        );
        assert!(
            e.contains("disk is full") || e.to_lowercase().contains("no space"),
            "{what}: {e}"
        );
        assert!(!e.contains("panicked"), "{what}: {e}");
        if target == &previous {
            assert_eq!(std::fs::read(&previous).unwrap(), b"previous", "{what}");
        } else {
            assert!(!target.exists(), "{what}: {} exists", target.display());
        }
        // Nothing partial, no temporary: the folder holds what it held (a `jobs plan` folder
        // may be created, empty).
        let mut now = names(&root);
        now.retain(|n| !(n == "plan" && names(&root.join("plan")).is_empty()));
        assert_eq!(now, before, "{what}: left behind");
    }
}

/// A read-only file system: the error says so and names the path; the old file stays.
#[test]
fn a_read_only_folder_fails_naming_the_path_and_keeps_the_old_file() {
    let Some(m) = Mount::tmpfs("a_read_only_folder_fails_naming_the_path", "4m") else {
        return;
    };
    let out = m.path().join("city.glb");
    std::fs::write(&out, b"previous").unwrap();
    m.remount_read_only();
    let o = run(bin()
        .args(["import"])
        .arg(data("bubenec/buildings.shp"))
        .arg("-o")
        .arg(&out));
    let e = stderr(&o);
    assert!(!o.status.success());
    assert!(e.contains(&s(&out)), "{e}");
    assert!(e.contains("read-only"), "{e}");
    assert_eq!(std::fs::read(&out).unwrap(), b"previous");
    assert_eq!(names(m.path()), vec!["city.glb"]);
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// Content URIs in a tileset.json.
fn uris(v: &serde_json::Value, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(o) => {
            if let Some(serde_json::Value::String(u)) = o.get("uri") {
                out.push(u.clone());
            }
            o.values().for_each(|x| uris(x, out));
        }
        serde_json::Value::Array(a) => a.iter().for_each(|x| uris(x, out)),
        _ => {}
    }
}

#[test]
fn a_tileset_over_another_citys_holds_only_the_new_city() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tiles");
    let tileset = |fp: &str, st: &str| {
        run(bin()
            .arg("tileset")
            .arg(data(fp))
            .arg("--streets")
            .arg(data(st))
            .arg("-o")
            .arg(&out))
    };
    let o = tileset("bubenec/buildings.shp", "bubenec/streets.shp");
    assert!(o.status.success(), "{}", stderr(&o));
    let first = names(&out.join("tiles"));
    let o = tileset("helsinki/buildings.shp", "helsinki/streets_blockclass.shp");
    assert!(o.status.success(), "{}", stderr(&o));
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("tileset.json")).unwrap()).unwrap();
    let mut referenced = Vec::new();
    uris(&doc, &mut referenced);
    referenced.sort();
    let on_disk: Vec<String> = names(&out.join("tiles"))
        .into_iter()
        .map(|n| format!("tiles/{n}"))
        .collect();
    assert_eq!(
        referenced, on_disk,
        "every tile on disk is the new tileset's, and only those"
    );
    assert_ne!(first, names(&out.join("tiles")), "the cities' tiles differ");
    assert_eq!(
        names(dir.path()),
        vec!["tiles"],
        "no staging or old folder left"
    );
    // A folder holding anything else is refused before any work, and kept.
    std::fs::write(out.join("notes.txt"), b"mine").unwrap();
    let o = tileset("bubenec/buildings.shp", "bubenec/streets.shp");
    let e = stderr(&o);
    assert!(!o.status.success());
    assert!(e.contains("notes.txt"), "{e}");
    assert_eq!(std::fs::read(out.join("notes.txt")).unwrap(), b"mine");
}

/// A generated city (`buildings`, `seed`) in `dir/city` and its `jobs plan` (at most `max`
/// buildings per tile) in `dir/plan`.
fn generated_plan(dir: &Path, buildings: u32, seed: u32, max: u32) -> (PathBuf, PathBuf) {
    let city = dir.join("city");
    let o = run(bin()
        .args(["generate", "--buildings", &buildings.to_string()])
        .args(["--seed", &seed.to_string(), "-o"])
        .arg(&city));
    assert!(o.status.success(), "{}", stderr(&o));
    let plan_dir = dir.join("plan");
    let o = run(bin()
        .args(["jobs", "plan"])
        .arg(&city)
        .args(["--max-buildings", &max.to_string(), "-o"])
        .arg(&plan_dir));
    assert!(o.status.success(), "{}", stderr(&o));
    (city, plan_dir)
}

/// `jobs run` killed at several moments: a tile whose manifest exists is complete (merge takes
/// it), one without is unfinished (merge says so, and names the command); the rerun and the
/// merge then succeed, whatever moment it was killed at.
#[test]
fn a_killed_jobs_run_is_unfinished_or_complete_and_reruns() {
    let dir = tempfile::tempdir().unwrap();
    let (_, plan_dir) = generated_plan(dir.path(), 4000, 5, 1500);
    let plan = plan_dir.join("plan.json");
    let tiles = serde_json::from_slice::<serde_json::Value>(&std::fs::read(&plan).unwrap())
        .unwrap()["tiles"]
        .as_array()
        .unwrap()
        .len();
    assert!(tiles >= 2, "{tiles} tiles");
    let run_tile = |t: usize| {
        bin()
            .args(["jobs", "run"])
            .arg(&plan)
            .args(["--tile", &t.to_string(), "--blockmaps", "32"])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    for t in 1..tiles {
        let o = run_tile(t).wait_with_output().unwrap();
        assert!(o.status.success(), "tile {t}: {}", stderr(&o));
    }
    let (mut unfinished, mut complete) = (0, 0);
    for delay_ms in [30, 150, 400, 800, 1500, 3000] {
        let mut child = run_tile(0);
        std::thread::sleep(Duration::from_millis(delay_ms));
        let _ = child.kill();
        let _ = child.wait();
        let manifest = plan_dir.join("tiles/tile_00000.json");
        let o = run(bin().args(["jobs", "merge"]).arg(&plan_dir));
        let e = stderr(&o);
        if manifest.exists() {
            complete += 1;
            assert!(
                o.status.success(),
                "killed at {delay_ms} ms, manifest there: {e}"
            );
        } else {
            unfinished += 1;
            assert!(!o.status.success());
            assert!(
                e.contains("has not finished"),
                "killed at {delay_ms} ms: {e}"
            );
        }
        let o = run_tile(0).wait_with_output().unwrap();
        assert!(
            o.status.success(),
            "rerun after {delay_ms} ms: {}",
            stderr(&o)
        );
        let o = run(bin().args(["jobs", "merge"]).arg(&plan_dir));
        assert!(o.status.success(), "merge after the rerun: {}", stderr(&o));
        // The rerun cleared the killed run's temporaries.
        let hidden: Vec<String> = names(&plan_dir.join("tiles"))
            .into_iter()
            .filter(|n| n.starts_with(".tile_00000"))
            .collect();
        assert!(hidden.is_empty(), "{hidden:?}");
    }
    eprintln!("jobs run killed 6 times: {unfinished} unfinished, {complete} complete");
    assert!(unfinished > 0, "no kill caught the tile unfinished");
}

#[test]
fn an_edited_plan_or_a_changed_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (city, plan_dir) = generated_plan(dir.path(), 600, 2, 50_000);
    let plan = plan_dir.join("plan.json");
    let tile0 = || run(bin().args(["jobs", "run"]).arg(&plan).args(["--tile", "0"]));
    // An edited frame origin: the plan no longer hashes to its id.
    let text = std::fs::read_to_string(&plan).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["frame_origin"][0] = serde_json::json!("1.5");
    let edited = serde_json::to_string(&v).unwrap();
    assert_ne!(edited, text);
    std::fs::write(&plan, &edited).unwrap();
    let o = tile0();
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("changed after it was written"),
        "{}",
        stderr(&o)
    );
    std::fs::write(&plan, &text).unwrap();
    assert!(tile0().status.success());
    // A replaced .dbf (heights) and a replaced .prj: both stamped, both refused.
    for ext in ["dbf", "prj"] {
        let f = city.join(format!("buildings.{ext}"));
        let old = std::fs::read(&f).unwrap();
        let mut new = old.clone();
        let last = new.len() - 2;
        new[last] ^= 1;
        std::fs::write(&f, &new).unwrap();
        let o = tile0();
        assert!(!o.status.success(), "{ext}");
        assert!(
            stderr(&o).contains(&format!("buildings.{ext}")),
            "{ext}: {}",
            stderr(&o)
        );
        std::fs::write(&f, &old).unwrap();
    }
    assert!(tile0().status.success());
}
