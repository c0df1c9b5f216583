//! `blockwalk jobs` on batch engines: the examples of `examples/jobs` cut Helsinki into tiles of
//! at most 100 buildings (13 tiles) and run them
//!
//! - on Slurm: a single-node cluster started on the loopback by `tests/batch/slurm_cluster.sh`
//!   (munged, slurmctld, slurmd), where `examples/jobs/slurm.sh` submits the plan job, the array
//!   of tiles and the merge job that depends on it (need `slurm`);
//! - on Kubernetes: the manifests of `examples/jobs/k8s` checked, and their pods run here as the
//!   Job controller and the kubelet start them (`tests/batch/k8s_indexed_job.py`, need `pyyaml`);
//! - on Dagster: the partitioned assets of `examples/jobs/dagster` materialised in-process
//!   (`tests/batch/dagster_tiles.py`, need `dagster`).
//!
//! Each result is compared with the single-process run of the same plan: the plan copied to
//! another folder, its tiles run one after another by `blockwalk jobs run`, then `jobs merge`.
//! The two folders must hold the same files, every one equal byte for byte, but for the tiles'
//! manifests and `index.json`, which must be equal as JSON once the fields that measure the job
//! itself are removed ([`MEASURED`], [`MEASURED_TILE`]).
//!
//! The Python tests use `$BLOCKWALK_PYTHON`, else `python3`.

#[path = "../../tests/support/mod.rs"]
mod support;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Instant;

use serde_json::Value;
use support::data::data;
use support::skip::{or_skip, Need};

const BIN: &str = env!("CARGO_BIN_EXE_blockwalk");
/// Buildings per tile: Helsinki's 496 buildings in 13 tiles.
const MAX_BUILDINGS: usize = 100;
/// Fields of `index.json` that measure the jobs (their times and memory), not the city.
const MEASURED: [&str; 2] = ["job_seconds", "max_peak_rss_bytes"];
/// Fields of a tile's manifest, and of a tile in `index.json`, that measure its job.
const MEASURED_TILE: [&str; 2] = ["seconds", "peak_rss_bytes"];

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn ok(what: &str, o: &Output) {
    assert!(
        o.status.success(),
        "{what}: {}\n--- stdout\n{}\n--- stderr\n{}",
        o.status,
        text(&o.stdout),
        text(&o.stderr)
    );
}

fn json_file(path: &Path) -> Value {
    let s = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&s).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The Python of the batch tests, if it can import `module`.
fn python_with(module: &str) -> Result<String, String> {
    let py = std::env::var("BLOCKWALK_PYTHON").unwrap_or_else(|_| "python3".into());
    match Command::new(&py)
        .args(["-c", &format!("import {module}")])
        .output()
    {
        Ok(o) if o.status.success() => Ok(py),
        Ok(o) => Err(format!(
            "{py} cannot import {module} ({}); set BLOCKWALK_PYTHON to a Python that can",
            text(&o.stderr).lines().last().unwrap_or("")
        )),
        Err(e) => Err(format!("cannot run {py}: {e}")),
    }
}

/// Every file under `dir`, by path relative to it.
fn files(dir: &Path) -> BTreeMap<String, PathBuf> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<String, PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
                out.insert(rel, p);
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// `v` without `fields`, each of which must be there (a list of what differs that names a field
/// no longer written would hide nothing, and say so).
fn without(mut v: Value, fields: &[&str], what: &str) -> Value {
    let o = v
        .as_object_mut()
        .unwrap_or_else(|| panic!("{what}: not an object"));
    for f in fields {
        assert!(o.remove(*f).is_some(), "{what} has no field {f}");
    }
    v
}

/// The single-process run of the plan in `plan_dir`: the plan copied into `dir`, every tile run
/// one after another, then merged.
fn single_process_run(plan_dir: &Path, dir: &Path) -> usize {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::copy(plan_dir.join("plan.json"), dir.join("plan.json")).unwrap();
    let tiles = json_file(&dir.join("plan.json"))["tiles"]
        .as_array()
        .unwrap()
        .len();
    for i in 0..tiles {
        let o = Command::new(BIN)
            .args(["jobs", "run"])
            .arg(dir.join("plan.json"))
            .args(["--tile", &i.to_string()])
            .output()
            .unwrap();
        ok(&format!("jobs run --tile {i}"), &o);
    }
    ok(
        "jobs merge",
        &Command::new(BIN)
            .args(["jobs", "merge"])
            .arg(dir)
            .output()
            .unwrap(),
    );
    tiles
}

/// The engine's folder equals the single-process run's: the same files, each equal byte for
/// byte but for the manifests and the index, equal but for the measured fields. Returns the
/// files compared.
fn assert_same_result(engine: &str, got: &Path, want: &Path) -> usize {
    let (g, w) = (files(got), files(want));
    assert_eq!(
        g.keys().collect::<Vec<_>>(),
        w.keys().collect::<Vec<_>>(),
        "{engine}: the files of {} are not the single-process run's ({})",
        got.display(),
        want.display()
    );
    let index = json_file(&w["index.json"]);
    let tiles = index["tiles"].as_array().unwrap().len();
    assert!(
        tiles >= 4,
        "{engine}: {tiles} tiles; the test needs at least 4"
    );
    let manifest = |rel: &str| {
        rel.strip_prefix("tiles/tile_")
            .and_then(|r| r.strip_suffix(".json"))
            .is_some_and(|n| !n.contains('.'))
    };
    let mut manifests = 0;
    for (rel, wp) in &w {
        let gp = &g[rel];
        if rel == "index.json" {
            let norm = |p: &Path| {
                let mut v = without(json_file(p), &MEASURED, rel);
                for t in v["tiles"].as_array_mut().unwrap() {
                    *t = without(t.take(), &MEASURED_TILE, "a tile of index.json");
                }
                v
            };
            assert_eq!(
                norm(gp),
                norm(wp),
                "{engine}: index.json differs beyond the measured fields"
            );
        } else if manifest(rel) {
            manifests += 1;
            assert_eq!(
                without(json_file(gp), &MEASURED_TILE, rel),
                without(json_file(wp), &MEASURED_TILE, rel),
                "{engine}: {rel} differs beyond the measured fields"
            );
        } else {
            let (a, b) = (std::fs::read(gp).unwrap(), std::fs::read(wp).unwrap());
            assert!(
                a == b,
                "{engine}: {rel} differs ({} and {} bytes)",
                a.len(),
                b.len()
            );
        }
    }
    assert_eq!(
        manifests, tiles,
        "{engine}: a manifest per tile, {tiles} tiles"
    );
    assert!(
        w.keys().any(|k| k.ends_with(".glb")),
        "{engine}: no .glb compared"
    );
    w.len()
}

fn on_path(tool: &str) -> bool {
    let path = std::env::var("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(["/usr/sbin".into(), "/sbin".into()])
        .any(|d: PathBuf| d.join(tool).is_file())
}

fn uid() -> String {
    let o = Command::new("id").arg("-u").output().unwrap();
    text(&o.stdout).trim().to_string()
}

/// What the Slurm test needs: the tools and root (or `sudo -n`, then the command to prefix).
fn slurm_tools() -> Result<Vec<String>, String> {
    let missing: Vec<&str> = [
        "munged",
        "slurmctld",
        "slurmd",
        "sbatch",
        "scontrol",
        "sinfo",
        "squeue",
        "scancel",
    ]
    .into_iter()
    .filter(|t| !on_path(t))
    .collect();
    if !missing.is_empty() {
        return Err(format!(
            "{} not found (apt-get install slurm-wlm munge)",
            missing.join(", ")
        ));
    }
    if uid() == "0" {
        return Ok(vec![]);
    }
    match Command::new("sudo").args(["-n", "true"]).output() {
        Ok(o) if o.status.success() => Ok(vec!["sudo".into(), "-n".into()]),
        _ => Err("slurmd runs as root: neither root nor sudo -n".into()),
    }
}

/// A `blockwalk` that fails the tile `tile` (exit 3) and runs everything else: a job that fails.
fn failing_binary(dir: &Path, tile: usize) -> PathBuf {
    let b = dir.join("bin/blockwalk");
    std::fs::create_dir_all(b.parent().unwrap()).unwrap();
    std::fs::write(
        &b,
        format!(
            "#!/bin/sh\ncase \" $* \" in *\" --tile {tile} \"*) echo \"tile {tile} fails here\" >&2; exit 3;; esac\nexec '{BIN}' \"$@\"\n"
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&b, std::fs::Permissions::from_mode(0o755)).unwrap();
    b
}

#[test]
fn slurm_array_of_tiles_equals_the_single_process_run() {
    let test = "slurm_array_of_tiles_equals_the_single_process_run";
    let Some(sudo) = or_skip(Need::Slurm, test, slurm_tools()) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let (out, logs) = (tmp.path().join("out"), tmp.path().join("logs"));
    let (bad_out, bad_logs) = (tmp.path().join("bad"), tmp.path().join("bad-logs"));
    let bad_bin = failing_binary(tmp.path(), 2);
    let repo = support::repo();
    let script = repo.join("examples/jobs/slurm.sh");
    // The plan as a job of its own in the first run, on this node in the second.
    let slurm = |bin: &Path, out: &Path, logs: &Path, plan_job: &str| {
        format!(
            "BLOCKWALK='{}' '{}' --streets '{}' --max-buildings {MAX_BUILDINGS} --parallel 3 \
             --time 10 --mem 512M --poll 0.5 {plan_job} --logs '{}' --wait '{}' '{}' -- --json",
            bin.display(),
            script.display(),
            data("helsinki/streets_blockclass.shp").display(),
            logs.display(),
            data("helsinki/buildings.shp").display(),
            out.display()
        )
    };
    // On one cluster: the run that must succeed; then one whose tile 2 fails, after which tile 2
    // is run again alone (its batch script resubmitted as a one-task array, the binary now one
    // that succeeds), then the merge's script.
    let until_done = "while [ -n \"$(squeue -h -j \"$j\")\" ]; do sleep 0.5; done";
    let body = format!(
        "set -e\n{good}\necho\nrc=0\n{bad} > '{log}' 2>&1 || rc=$?\n\
         echo \"failing run: exit $rc\"\n\
         [ -e '{bad_out}/index.json' ] || echo 'no index after the failure'\n\
         printf '#!/bin/sh\\nexec %s \"$@\"\\n' '{bin}' > '{bad_bin}'\n\
         j=$(sbatch --parsable --array=2 '{bad_logs}/tile.sbatch')\n{until_done}\n\
         j=$(sbatch --parsable '{bad_logs}/merge.sbatch')\n{until_done}\n\
         echo \"tile 2 again: $(cat '{bad_logs}/merge.out')\"\n",
        good = slurm(Path::new(BIN), &out, &logs, "--plan-job"),
        bad = slurm(&bad_bin, &bad_out, &bad_logs, ""),
        log = tmp.path().join("bad.log").display(),
        bad_out = bad_out.display(),
        bad_logs = bad_logs.display(),
        bad_bin = bad_bin.display(),
        bin = BIN,
    );
    std::fs::write(tmp.path().join("body.sh"), &body).unwrap();
    let t0 = Instant::now();
    let mut argv = sudo.clone();
    argv.extend([
        "env".into(),
        format!("PATH={}", std::env::var("PATH").unwrap_or_default()),
        "BLOCKWALK_SLURM_TIMEOUT=400".into(),
        "bash".into(),
        repo.join("tests/batch/slurm_cluster.sh")
            .display()
            .to_string(),
        "bash".into(),
        "-c".into(),
        body,
    ]);
    let mut cmd = Command::new(&argv[0]);
    cmd.args(&argv[1..]);
    let o = cmd.output().unwrap();
    let secs = t0.elapsed().as_secs_f64();
    if !sudo.is_empty() {
        let owner = format!(
            "{}:{}",
            uid(),
            text(&Command::new("id").arg("-g").output().unwrap().stdout).trim()
        );
        let _ = Command::new("sudo")
            .args(["-n", "chown", "-R", &owner])
            .arg(tmp.path())
            .output();
    }
    ok("the Slurm cluster and examples/jobs/slurm.sh", &o);
    let stdout = text(&o.stdout);

    // The run: plan job, array, merge job; each task's log is its own tile's manifest (`--json`
    // passed through), the merge's summary is in the merge log.
    assert!(logs.join("plan.sbatch").is_file(), "no plan job");
    let tile_script = std::fs::read_to_string(logs.join("tile.sbatch")).unwrap();
    for line in [
        "#SBATCH --time=10",
        "#SBATCH --mem=512M",
        "#SBATCH --job-name=blockwalk-tiles",
    ] {
        assert!(
            tile_script.lines().any(|l| l == line),
            "{line}: {tile_script}"
        );
    }
    assert!(
        tile_script.contains("--tile \"$SLURM_ARRAY_TASK_ID\" --json"),
        "{tile_script}"
    );
    let tiles = json_file(&out.join("plan.json"))["tiles"]
        .as_array()
        .unwrap()
        .len();
    for i in 0..tiles {
        let m = json_file(&logs.join(format!("tile_{i}.out")));
        assert_eq!(m["tile"], i, "array task {i} ran tile {}", m["tile"]);
    }
    assert!(
        std::fs::read_to_string(logs.join("merge.out"))
            .unwrap()
            .contains(&format!("{tiles} tiles")),
        "merge.out"
    );
    let reference = tmp.path().join("single");
    single_process_run(&out, &reference);
    let compared = assert_same_result("slurm", &out, &reference);

    // The failing run: tile 2 failed, the merge never ran, the script says which task failed.
    let bad = std::fs::read_to_string(tmp.path().join("bad.log")).unwrap();
    assert!(stdout.contains("failing run: exit 1"), "{stdout}\n{bad}");
    assert!(
        bad.contains("ArrayTaskId=2 JobState=FAILED ExitCode=3:0"),
        "the failed task is not named: {bad}"
    );
    assert!(bad.contains("tile 2 fails here"), "{bad}");
    assert!(stdout.contains("no index after the failure"), "{stdout}");
    // Tile 2 run again alone, then merged: the same result.
    assert!(
        stdout.contains(&format!("tile 2 again: buildings: {tiles} tiles")),
        "{stdout}"
    );
    assert_same_result("slurm, tile 2 run again", &bad_out, &reference);
    eprintln!(
        "slurm: {tiles} tiles as an array job on a single-node cluster, {compared} files equal to the single-process run; a failing task stops the merge, and run again alone gives the same result; {secs:.1} s with the cluster's start and stop"
    );
}

#[test]
fn kubernetes_indexed_job_equals_the_single_process_run() {
    let test = "kubernetes_indexed_job_equals_the_single_process_run";
    let Some(py) = or_skip(Need::Pyyaml, test, python_with("yaml")) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    // The volume: the city where the plan Job's CITY points (/data/city, a city folder).
    let volume = tmp.path().join("volume");
    std::fs::create_dir_all(volume.join("city")).unwrap();
    for (from, to) in [
        ("buildings", "buildings"),
        ("streets_blockclass", "streets"),
    ] {
        for ext in ["shp", "shx", "dbf", "prj", "cpg"] {
            std::fs::copy(
                data(&format!("helsinki/{from}.{ext}")),
                volume.join(format!("city/{to}.{ext}")),
            )
            .unwrap();
        }
    }
    let o = Command::new(&py)
        .arg(support::repo().join("tests/batch/k8s_indexed_job.py"))
        .args(["--blockwalk", BIN, "--volume"])
        .arg(&volume)
        .args(["--parallel", "3", "--env"])
        .arg(format!("MAX_BUILDINGS={MAX_BUILDINGS}"))
        .output()
        .unwrap();
    ok("tests/batch/k8s_indexed_job.py", &o);
    let r: Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    let out = PathBuf::from(r["out"].as_str().unwrap());
    assert_eq!(out, volume.join("out"));
    let reference = tmp.path().join("single");
    let tiles = single_process_run(&out, &reference);
    assert_eq!(r["tiles"], tiles);
    assert_eq!(r["pods"], tiles + 2);
    assert_same_result("kubernetes", &out, &reference);
}

#[test]
fn dagster_tile_partitions_equal_the_single_process_run() {
    let test = "dagster_tile_partitions_equal_the_single_process_run";
    let Some(py) = or_skip(Need::Dagster, test, python_with("dagster")) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = Command::new(&py)
        .arg(support::repo().join("tests/batch/dagster_tiles.py"))
        .args(["--blockwalk", BIN, "--city"])
        .arg(data("helsinki/buildings.shp"))
        .arg("--streets")
        .arg(data("helsinki/streets_blockclass.shp"))
        .arg("--out")
        .arg(&out)
        .args(["--max-buildings", &MAX_BUILDINGS.to_string()])
        .env("DAGSTER_HOME", tmp.path())
        .output()
        .unwrap();
    ok("tests/batch/dagster_tiles.py", &o);
    let r: Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    let reference = tmp.path().join("single");
    let tiles = single_process_run(&out, &reference);
    assert_eq!(r["tiles"], tiles);
    // Two plans, a run per partition, the merge.
    assert_eq!(r["runs"], tiles + 3);
    assert_same_result("dagster", &out, &reference);
}
