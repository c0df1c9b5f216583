//! `blockwalk walk` over a tiled city: `jobs plan` / `run --blockmaps` / `merge`, then the walk
//! streamed from the folder (its summary and `--json`, the report files) and over HTTP; and the
//! refusals (relief impostors, a bad budget, a folder that is no tiled city).

fn blockwalk(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .args(args)
        .output()
        .expect("run blockwalk")
}

fn ok(o: &std::process::Output) -> String {
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn a_tiled_city_is_walked_by_streaming_from_a_folder_and_over_http() {
    let tmp = tempfile::tempdir().unwrap();
    let city = tmp.path().join("city");
    let jobs = tmp.path().join("jobs");
    let (c, j) = (city.to_str().unwrap(), jobs.to_str().unwrap());
    ok(&blockwalk(&[
        "generate",
        "--buildings",
        "600",
        "--seed",
        "3",
        "--no-parcels",
        "-o",
        c,
    ]));
    let cmds = ok(&blockwalk(&[
        "jobs",
        "plan",
        c,
        "-o",
        j,
        "--max-buildings",
        "200",
    ]));
    let plan = jobs.join("plan.json");
    let tiles = cmds.lines().filter(|l| l.contains("jobs run")).count();
    assert!(tiles >= 2, "{cmds}");
    for t in 0..tiles {
        ok(&blockwalk(&[
            "jobs",
            "run",
            plan.to_str().unwrap(),
            "--tile",
            &t.to_string(),
            "--blockmaps",
            "32",
        ]));
    }
    ok(&blockwalk(&["jobs", "merge", j]));

    let out = tmp.path().join("walk");
    let o = out.to_str().unwrap();
    let text = ok(&blockwalk(&[
        "walk",
        j,
        "--far",
        "blockmaps",
        "--route",
        "orbit",
        "--frames",
        "12",
        "--size",
        "96x54",
        "--deterministic",
        "--check",
        "--render",
        "--image-every",
        "4",
        "--out",
        o,
    ]));
    assert!(text.contains("600 buildings"), "{text}");
    assert!(text.contains("first frame at"), "{text}");
    assert!(text.contains("converged frames that differ: 0"), "{text}");
    for f in ["frames.csv", "stream.json", "strip.png"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    assert_eq!(csv.lines().count(), 13, "a header and 12 frames");

    // The same walk as JSON over HTTP, from `blockwalk serve` on a free port.
    let mut server = Killed(
        std::process::Command::new(env!("CARGO_BIN_EXE_blockwalk"))
            .args(["serve", j, "--addr", "127.0.0.1:0"])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("run blockwalk serve"),
    );
    let mut line = String::new();
    std::io::BufRead::read_line(
        &mut std::io::BufReader::new(server.0.stdout.take().unwrap()),
        &mut line,
    )
    .unwrap();
    let url = line
        .split_whitespace()
        .find(|w| w.starts_with("http://"))
        .unwrap_or_else(|| panic!("no URL in {line:?}"))
        .to_string();
    assert!(url.ends_with("index.json"), "{line}");
    let o = blockwalk(&[
        "walk",
        &url,
        "--far",
        "blockmaps",
        "--route",
        "orbit",
        "--frames",
        "12",
        "--size",
        "96x54",
        "--bandwidth",
        "50Mbps",
        "--latency-ms",
        "5",
        "--json",
        "--out",
        tmp.path().join("walk_http").to_str().unwrap(),
    ]);
    let j: serde_json::Value = serde_json::from_str(&ok(&o)).unwrap();
    assert!(j["source"].as_str().unwrap().starts_with("HTTP"), "{j}");
    assert_eq!(j["summary"]["frames"], 12);
    assert_eq!(j["summary"]["wait_total_s"], 0.0, "real time never waits");
    assert_eq!(j["startup"]["buildings"], 600);
    drop(server);

    // Refusals, each naming the problem.
    let bad = blockwalk(&["walk", j_str(&jobs), "--far", "relief", "--frames", "2"]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("relief"));
    let bad = blockwalk(&["walk", j_str(&jobs), "--budget", "lots", "--frames", "2"]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("768MiB"));
    // A plan's folder not merged yet.
    let unmerged = tmp.path().join("unmerged");
    ok(&blockwalk(&[
        "jobs",
        "plan",
        c,
        "-o",
        unmerged.to_str().unwrap(),
    ]));
    let bad = blockwalk(&["walk", unmerged.to_str().unwrap(), "--frames", "2"]);
    assert!(!bad.status.success());
    let e = String::from_utf8_lossy(&bad.stderr);
    assert!(e.contains("index.json") && e.contains("jobs merge"), "{e}");
    let not = tmp.path().join("not_tiled");
    std::fs::create_dir_all(&not).unwrap();
    std::fs::write(not.join("index.json"), "{\"format\": \"something else\"}").unwrap();
    let bad = blockwalk(&["walk", not.to_str().unwrap(), "--frames", "2"]);
    assert!(!bad.status.success());
    let e = String::from_utf8_lossy(&bad.stderr);
    assert!(e.contains("index.json") && e.contains("jobs merge"), "{e}");
}

/// A child process killed when dropped, so that a failing test leaves no server behind.
struct Killed(std::process::Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn j_str(p: &std::path::Path) -> &str {
    p.to_str().unwrap()
}
