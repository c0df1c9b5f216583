//! The command line on a closed standard output (`blockwalk … | head -c 10`): no panic, a quiet
//! exit with status 0; and numeric arguments that must be refused with a
//! usage error, not a panic.

#[path = "../../tests/support/mod.rs"]
mod support;
use std::io::Read;
use std::process::{Command, Output, Stdio};
use support::data::data;

fn blockwalk() -> Command {
    Command::new(env!("CARGO_BIN_EXE_blockwalk"))
}

/// Runs `cmd` with its standard output closed before it writes anything, so that its first
/// write fails with a broken pipe. Returns the status and standard error.
fn with_stdout_closed(mut cmd: Command) -> (std::process::ExitStatus, String) {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn blockwalk");
    drop(child.stdout.take());
    let mut err = String::new();
    child
        .stderr
        .take()
        .expect("piped")
        .read_to_string(&mut err)
        .expect("read stderr");
    (child.wait().expect("wait"), err)
}

/// Runs `cmd`, reads `n` bytes of its standard output and closes it.
fn reading_only(mut cmd: Command, n: usize) -> (std::process::ExitStatus, Vec<u8>, String) {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn blockwalk");
    let mut out = child.stdout.take().expect("piped");
    let mut head = vec![0u8; n];
    out.read_exact(&mut head)
        .expect("the command prints something");
    drop(out);
    let mut err = String::new();
    child
        .stderr
        .take()
        .expect("piped")
        .read_to_string(&mut err)
        .expect("read stderr");
    (child.wait().expect("wait"), head, err)
}

fn assert_quiet_success(status: std::process::ExitStatus, err: &str, what: &str) {
    assert!(!err.contains("panicked"), "{what}: {err}");
    assert!(!err.contains("Broken pipe"), "{what}: {err}");
    assert_eq!(status.code(), Some(0), "{what}: {status:?}, stderr: {err}");
}

#[test]
fn import_json_into_a_closed_pipe_exits_quietly() {
    let mut cmd = blockwalk();
    cmd.arg("import")
        .arg(data("bubenec/buildings.shp"))
        .arg("--json");
    let (status, err) = with_stdout_closed(cmd);
    assert_quiet_success(status, &err, "import --json");
}

#[test]
fn import_summary_into_a_closed_pipe_exits_quietly() {
    let mut cmd = blockwalk();
    cmd.arg("import").arg(data("helsinki/buildings.shp"));
    let (status, err) = with_stdout_closed(cmd);
    assert_quiet_success(status, &err, "import");
}

#[test]
fn generate_into_a_closed_pipe_exits_quietly_after_writing_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let mut cmd = blockwalk();
    cmd.args(["generate", "--buildings", "40", "--output"])
        .arg(dir.path());
    let (status, err) = with_stdout_closed(cmd);
    assert_quiet_success(status, &err, "generate");
    // The work was done before the summary was printed.
    assert!(
        std::fs::read_dir(dir.path()).unwrap().count() > 0,
        "no files written"
    );
}

/// `import --json | head -c 10` as a shell runs it. The JSON of this small city may fit in the
/// pipe's buffer before the reader closes it, in which case no write fails; the tests above, whose
/// pipe is closed before the first write, are the ones that always meet the broken pipe.
#[test]
fn head_c_10_on_import_json() {
    let mut cmd = blockwalk();
    cmd.arg("import")
        .arg(data("bubenec/buildings.shp"))
        .arg("--json");
    let (status, head, err) = reading_only(cmd, 10);
    assert_eq!(head[0], b'{');
    assert_quiet_success(status, &err, "import --json | head -c 10");
}

#[test]
fn other_errors_still_fail_with_a_message() {
    // A closed pipe is not an excuse for a real error: a missing input still fails.
    let mut cmd = blockwalk();
    cmd.arg("import").arg(data("no such file.shp"));
    let (status, err) = with_stdout_closed(cmd);
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(
        err.contains("error:") && err.contains("no such file"),
        "{err}"
    );
}

fn run(args: &[&str]) -> Output {
    blockwalk().args(args).output().expect("run blockwalk")
}

#[test]
fn nan_fractions_and_unbounded_counts_are_usage_errors() {
    let input = data("bubenec/buildings.shp");
    let input = input.to_str().unwrap();
    for (args, needle) in [
        (
            vec!["occlusion-bench", input, "--street-fraction", "NaN"],
            "--street-fraction",
        ),
        (vec!["cull-bench", input, "--views", "0"], "--views"),
        (
            vec!["cull-bench", input, "--views", "100000000000"],
            "--views",
        ),
        (
            vec!["occlusion-bench", input, "--views", "100000000000"],
            "--views",
        ),
    ] {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn commands_over_blocks_refuse_the_scene_graph_of_pages() {
    let input = data("bubenec/buildings.shp");
    let input = input.to_str().unwrap();
    for (args, needle) in [
        (
            vec!["cull-bench", input, "--structures", "bqr,scenegraph"],
            "--structures scenegraph",
        ),
        (
            vec!["occlusion-bench", input, "--index", "scenegraph"],
            "--index scenegraph",
        ),
        (
            vec!["view", input, "--structure", "scenegraph"],
            "--structure scenegraph",
        ),
    ] {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        // Without the `window` feature `view` refuses for that reason instead.
        let windowless = args[0] == "view" && err.contains("--features window");
        assert!(windowless || err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn an_error_that_shows_its_cause_shows_it_once() {
    let input = data("bubenec/buildings.shp");
    let o = run(&[
        "walk",
        input.to_str().unwrap(),
        "--route",
        "no/such/route.json",
        "--frames",
        "2",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("route.json"), "{err}");
    assert_eq!(err.matches("(os error 2)").count(), 1, "{err}");
}
