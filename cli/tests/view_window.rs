//! `blockwalk view` in a real window: an X server (Xvfb through `xvfb-run`), a wgpu surface on
//! lavapipe, the route played for a few frames and the last one saved. With `--far blockmaps` the
//! window draws the hybrid frame (near meshes, far BlockMaps ray-cast into the same targets), as
//! `blockwalk walk --far blockmaps` does.
//!
//! Without `xvfb-run` or a Vulkan driver the tests skip loudly, unless the display and the GPU
//! are required (`BLOCKWALK_REQUIRE=display,gpu`, as `.ci/run` sets), in which case they fail.
#![cfg(feature = "window")]

#[path = "../../tests/support/mod.rs"]
mod support;

use std::path::{Path, PathBuf};
use std::process::Command;

use support::skip::{or_skip, Need};

fn xvfb_run() -> Option<PathBuf> {
    std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join("xvfb-run"))
            .find(|p| p.is_file())
    })
}

fn out_dir() -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("view-window");
    std::fs::create_dir_all(&d).expect("create the test folder");
    d
}

/// Runs `blockwalk view` on Helsinki under Xvfb with `extra` arguments, saving the last of three
/// orbit frames to `shot`; returns its JSON summary, or `None` (skip) without a display server or
/// a GPU.
fn view(test: &str, extra: &[&str], shot: &Path) -> Option<serde_json::Value> {
    view_city(test, &support::data::data("helsinki"), extra, shot)
}

/// [`view`] of `city` (a city folder, or a tiled city's folder).
fn view_city(test: &str, city: &Path, extra: &[&str], shot: &Path) -> Option<serde_json::Value> {
    let xvfb = or_skip(
        Need::Display,
        test,
        xvfb_run().ok_or_else(|| "xvfb-run is not installed (apt-get install xvfb xauth)".into()),
    )?;
    let out = Command::new(xvfb)
        .args(["-a", "-s", "-screen 0 1280x720x24"])
        .arg(env!("CARGO_BIN_EXE_blockwalk"))
        .arg("view")
        .arg(city)
        .args(["--route", "orbit", "--frames", "3", "--size", "320x180"])
        .arg("--screenshot")
        .arg(shot)
        .arg("--json")
        .args(extra)
        .env("NODEVICE_SELECT", "1")
        .env("WGPU_BACKEND", "vulkan")
        .output()
        .expect("run xvfb-run blockwalk view");
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        let no_gpu = stderr.contains("adapter") || stderr.contains("surface");
        assert!(
            no_gpu,
            "blockwalk view {extra:?} failed: {}\n{stderr}",
            out.status
        );
        return or_skip(Need::Gpu, test, Err(format!("no GPU surface: {stderr}")));
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout.lines().last().unwrap_or_default();
    Some(serde_json::from_str(line).unwrap_or_else(|e| panic!("summary {line:?}: {e}")))
}

fn load(p: &Path) -> image::RgbaImage {
    image::open(p)
        .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
        .to_rgba8()
}

#[test]
fn the_window_draws_the_far_field_where_the_walk_would() {
    let test = "the_window_draws_the_far_field_where_the_walk_would";
    let dir = out_dir();
    let (mesh_png, far_png) = (dir.join("meshes.png"), dir.join("blockmaps.png"));
    let Some(mesh) = view(test, &["--far", "none"], &mesh_png) else {
        return;
    };
    let Some(far) = view(
        test,
        &["--far", "blockmaps", "--tau", "4", "--k", "64"],
        &far_png,
    ) else {
        return;
    };
    assert_eq!(mesh["frames"], 3);
    assert_eq!(far["frames"], 3);
    assert_eq!(mesh["far_nodes"], 0, "meshes only: {mesh}");
    assert_eq!(far["far"], "blockmaps");
    let nodes = far["far_nodes"].as_u64().expect("far_nodes");
    let pixels = far["far_pixels"].as_u64().expect("far_pixels");
    assert!(
        nodes > 0 && pixels > 0,
        "the orbit at τ = 4 px must draw maps: {far}"
    );
    // The maps replace meshes: fewer triangles than the mesh-only frame of the same camera.
    let (tm, tf) = (
        mesh["triangles"].as_u64().expect("triangles"),
        far["triangles"].as_u64().expect("triangles"),
    );
    assert!(tf < tm, "hybrid {tf} triangles, meshes only {tm}");
    let (a, b) = (load(&mesh_png), load(&far_png));
    assert_eq!(a.dimensions(), (320, 180));
    assert_eq!(b.dimensions(), (320, 180));
    // The same city from the same camera: the maps stand where the meshes stood, so only a
    // small share of the pixels change, and at most as many as the maps won plus their
    // silhouettes' neighbours (a map drawn in the wrong place changes far more).
    let changed = a
        .pixels()
        .zip(b.pixels())
        .filter(|(p, q)| p.0.iter().zip(q.0.iter()).any(|(x, y)| x.abs_diff(*y) > 24))
        .count();
    let total = (320 * 180) as usize;
    eprintln!("{changed} pixels changed, maps won {pixels}, {nodes} maps, {tf} of {tm} triangles");
    assert!(
        changed * 10 < total,
        "{changed} of {total} pixels differ between the mesh-only and the hybrid window frames"
    );
    assert!(
        changed as u64 <= 2 * pixels,
        "{changed} pixels differ but the maps won only {pixels}"
    );
}

#[test]
fn a_bad_tau_is_refused_before_a_window_opens() {
    let out = Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .arg("view")
        .arg(support::data::data("helsinki"))
        .args(["--far", "blockmaps", "--tau", "0"])
        .output()
        .expect("run blockwalk view");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("tau 0"), "{err}");
}

#[test]
fn without_a_display_the_viewer_says_so_in_one_line() {
    let out = Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .args(["view", "synthetic:3x3", "--frames", "1"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("run blockwalk view");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    // The key help may come first; the error is one line, said once.
    let lines: Vec<&str> = err.lines().filter(|l| l.contains("error")).collect();
    assert_eq!(lines.len(), 1, "one error line: {err}");
    assert_eq!(err.matches("display").count(), 1, "said once: {err}");
    assert!(lines[0].contains("no display found"), "{err}");
    assert!(
        lines[0].contains("DISPLAY") && lines[0].contains("walk --render"),
        "{err}"
    );
    assert!(!err.contains(".cargo") && !err.contains("winit"), "{err}");
}

fn run_ok(args: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .args(args)
        .output()
        .expect("run blockwalk");
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn the_window_streams_a_tiled_city_and_shows_the_walks_frame() {
    let test = "the_window_streams_a_tiled_city_and_shows_the_walks_frame";
    let dir = out_dir().join("tiled");
    let _ = std::fs::remove_dir_all(&dir);
    let jobs = dir.join("jobs");
    let h = support::data::data("helsinki");
    let (fp, st) = (h.join("buildings.shp"), h.join("streets_blockclass.shp"));
    let j = jobs.to_str().unwrap();
    let cmds = run_ok(&[
        "jobs",
        "plan",
        fp.to_str().unwrap(),
        "--streets",
        st.to_str().unwrap(),
        "-o",
        j,
        "--max-buildings",
        "150",
    ]);
    let plan = jobs.join("plan.json");
    let n = cmds.lines().filter(|l| l.contains("jobs run")).count();
    for t in 0..n {
        run_ok(&[
            "jobs",
            "run",
            plan.to_str().unwrap(),
            "--tile",
            &t.to_string(),
            "--blockmaps",
            "32",
        ]);
    }
    run_ok(&["jobs", "merge", j]);
    let shot = dir.join("window.png");
    let args = ["--far", "blockmaps", "--tau", "2", "--deterministic"];
    let Some(v) = view_city(test, &jobs, &args, &shot) else {
        return;
    };
    assert_eq!(v["frames"], 3);
    assert_eq!(v["streamed"]["buildings"], 496, "{v}");
    // The walk's deterministic frames of the same three cameras.
    let walk = dir.join("walk");
    run_ok(&[
        "walk",
        j,
        "--route",
        "orbit",
        "--frames",
        "3",
        "--size",
        "320x180",
        "--render",
        "--image-every",
        "1",
        "--out",
        walk.to_str().unwrap(),
        "--far",
        "blockmaps",
        "--tau",
        "2",
        "--deterministic",
    ]);
    let strip = load(&walk.join("strip.png"));
    let last = image::imageops::crop_imm(&strip, 2 * (320 + 4), 0, 320, 180).to_image();
    let window = load(&shot);
    assert!(window == last, "the window shows the walk's frame");
}
