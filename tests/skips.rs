//! The skip mechanism itself: a skip reaches the real standard error and the skip log even though
//! the harness captures the test's output, a required need turns it into a failure, the switch
//! refuses names it does not know, `tests/run` counts the log by reason, and `.ci/run` requires
//! every need and runs the README's test command.

mod support;

use std::path::Path;
use std::process::Command;
use support::skip::{or_skip, parse_list, Need};

/// Run only by [`a_skip_is_loud_and_logged`], in a child process of this binary.
#[test]
#[ignore = "a probe that `a_skip_is_loud_and_logged` runs in a child process"]
fn skip_probe() {
    let found: Result<(), String> = Err("the probe finds nothing".into());
    assert!(or_skip(Need::Astana, "skip_probe", found).is_none());
}

/// Runs [`skip_probe`] in a child with only `env` set among the switches; its status, stdout and
/// stderr, and the log it wrote.
fn probe(dir: &Path, env: &[(&str, &str)]) -> (bool, String, String, String) {
    let log = dir.join("skips.log");
    let _ = std::fs::remove_file(&log);
    let mut cmd = Command::new(std::env::current_exe().unwrap());
    cmd.args(["--ignored", "--exact", "skip_probe"])
        .env("BLOCKWALK_SKIP_LOG", &log)
        .env_remove("BLOCKWALK_REQUIRE");
    for need in Need::ALL {
        cmd.env_remove(need.var());
    }
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.output().unwrap();
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    (
        out.status.success(),
        text(&out.stdout),
        text(&out.stderr),
        std::fs::read_to_string(&log).unwrap_or_default(),
    )
}

#[test]
fn a_skip_is_loud_and_logged() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("skips");
    std::fs::create_dir_all(&dir).unwrap();

    // Not required: the test passes, the line is on the real stderr despite the capture, logged.
    let (ok, stdout, stderr, log) = probe(&dir, &[]);
    assert!(ok, "{stdout}{stderr}");
    assert!(stdout.contains("1 passed"), "{stdout}");
    assert!(
        stderr.contains("SKIPPED [astana] skip_probe: the probe finds nothing"),
        "the skip line did not reach the real stderr: {stderr:?}"
    );
    assert_eq!(log, "astana\tskip_probe\tthe probe finds nothing\n");

    // Required by the list, by `all`, or by its own variable: a failure, nothing logged.
    for env in [
        [("BLOCKWALK_REQUIRE", "gpu,astana")],
        [("BLOCKWALK_REQUIRE", "all")],
        [("BLOCKWALK_REQUIRE_ASTANA", "1")],
    ] {
        let (ok, stdout, _, log) = probe(&dir, &env);
        assert!(!ok, "{env:?}: a required need skipped: {stdout}");
        assert!(stdout.contains("astana is required"), "{env:?}: {stdout}");
        assert!(log.is_empty(), "{env:?}: {log}");
    }
    // Required for another need only: still a skip.
    let (ok, _, _, log) = probe(&dir, &[("BLOCKWALK_REQUIRE", "gpu")]);
    assert!(ok && log.starts_with("astana\t"), "{log}");

    // A switch that means nothing is refused, not ignored.
    for env in [
        [("BLOCKWALK_REQUIRE", "gpu,astanna")],
        [("BLOCKWALK_REQUIRE_ASTANA", "yes")],
    ] {
        let (ok, stdout, _, _) = probe(&dir, &env);
        assert!(!ok, "{env:?} was accepted: {stdout}");
    }
}

#[test]
fn the_switch_names_every_need() {
    assert_eq!(
        parse_list("gpu, astana").unwrap(),
        [Need::Gpu, Need::Astana]
    );
    assert_eq!(parse_list("all").unwrap(), Need::ALL);
    assert_eq!(parse_list("").unwrap(), []);
    let e = parse_list("gpu,gpus").unwrap_err();
    assert!(e.contains("`gpus`") && e.contains("validators"), "{e}");
}

#[test]
fn the_run_ends_with_the_skips_by_reason() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("skips-summary");
    std::fs::create_dir_all(&dir).unwrap();
    let summary = |log: &str| {
        let path = dir.join("log");
        std::fs::write(&path, log).unwrap();
        let out = Command::new("bash")
            .arg(support::repo().join("tests/run"))
            .arg("--summary-of")
            .arg(&path)
            .output()
            .unwrap();
        assert!(out.status.success());
        String::from_utf8(out.stdout).unwrap()
    };
    let s = summary("gpu\ta\tno adapter\nastana\tb\tabsent\ngpu\tc\tno adapter\n");
    assert!(
        s.contains("skipped: 3 tests (astana 1, gpu 2); BLOCKWALK_REQUIRE=astana,gpu"),
        "{s}"
    );
    assert!(s.contains("  [gpu] c: no adapter"), "{s}");
    assert!(summary("").contains("skipped: 0 tests"));
}

/// The README's test command: the second line of its first code block, before the comment.
fn readme_test_command() -> String {
    let readme = std::fs::read_to_string(support::repo().join("README.md")).unwrap();
    let block = readme.split("```sh\n").nth(1).expect("a sh block");
    let line = block.lines().nth(1).expect("two commands");
    line.split('#').next().unwrap().trim().to_string()
}

#[test]
fn ci_requires_every_need_and_runs_the_readme_tests() {
    let ci = std::fs::read_to_string(support::repo().join(".ci/run")).unwrap();
    let list = ci
        .lines()
        .find_map(|l| l.trim().strip_prefix("export BLOCKWALK_REQUIRE="))
        .expect(".ci/run exports BLOCKWALK_REQUIRE");
    let needs = parse_list(list.split_whitespace().next().unwrap_or("")).unwrap();
    for need in Need::ALL {
        assert!(needs.contains(&need), ".ci/run does not require {need}");
    }
    let test = readme_test_command();
    assert_eq!(test, "bash tests/run");
    assert!(
        ci.lines().any(|l| l.trim() == test),
        ".ci/run does not run the README's test command `{test}`"
    );
}
