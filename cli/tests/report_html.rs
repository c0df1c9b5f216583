//! The walk report a person reads: a short rendered walk over Helsinki through the CLI, with the
//! BlockMap far field and its image comparison, whose
//! `report.html` is opened from a `file://` URL in headless Chromium (Debian `chromium`) by
//! `tests/tools/report_screenshot.mjs` (puppeteer-core), with every request outside the page
//! refused. The page must load without console errors, page errors or failed requests, every
//! image must decode, the route map and one caption per kept frame must be there, and a
//! screenshot is saved as `target/report-html/report.png` (or under `BLOCKWALK_SCREENSHOT_DIR`).
//!
//! Needs `node`, `chromium` and `npm ci --prefix tests/tools` (what `.ci/run` does). Without them
//! the test skips loudly, unless the validators are required (`BLOCKWALK_REQUIRE=validators`).

use serde_json::{json, Value};
use std::process::Command;

#[path = "../../tests/support/mod.rs"]
mod support;

#[test]
fn the_helsinki_walk_report_opens_alone_in_chromium() {
    let test = "the_helsinki_walk_report_opens_alone_in_chromium";
    let Some((node, chromium)) = support::node::or_skip(
        test,
        support::node::node_with(&["puppeteer-core"])
            .and_then(|n| Ok((n, support::node::chromium()?))),
    ) else {
        return;
    };
    let data = support::data::data("helsinki");
    let out = tempfile::tempdir().unwrap();
    let walk = out.path().join("walk");
    let args: Vec<String> = [
        "walk",
        data.join("buildings.shp").to_str().unwrap(),
        "--streets",
        data.join("streets_blockclass.shp").to_str().unwrap(),
        "--frames",
        "6",
        "--structures",
        "bqr,flat",
        "--render",
        "--image-every",
        "2",
        "--size",
        "192x108",
        "--out",
        walk.to_str().unwrap(),
        "--far",
        "blockmaps",
        "--keep-far",
        "--reference",
        "--tau",
        "8",
        "--json",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let o = Command::new(env!("CARGO_BIN_EXE_blockwalk"))
        .args(&args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "walk failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let j: Value = serde_json::from_slice(&o.stdout).unwrap();
    // The command line in report.json is the one that ran.
    let command: Vec<String> = serde_json::from_value(j["command"].clone()).unwrap();
    assert_eq!(&command[1..], &args[..]);
    assert!(j["machine"]["cores"].as_u64().unwrap() >= 1);
    let kept = j["kept_frames"].as_array().unwrap();
    assert_eq!(kept.len(), 3, "frames 0, 2, 4");

    let html = walk.join("report.html");
    let page = std::fs::read_to_string(&html).unwrap();
    // Under each kept frame, its far-field figures, the same as in report.json.
    for k in kept {
        let f = k["frame"].as_u64().unwrap();
        let caption = page
            .split(&format!("<b>frame {f}</b>"))
            .nth(1)
            .and_then(|c| c.split("</figcaption>").next())
            .unwrap_or_else(|| panic!("no caption for frame {f}"));
        let far = &k["far"];
        assert!(far["far_nodes"].is_u64(), "frame {f}: {k}");
        assert!(
            caption.contains(&format!("far field: {} nodes", far["far_nodes"])),
            "frame {f}: {caption}"
        );
        if let Some(psnr) = far["psnr_db"].as_f64() {
            assert!(caption.contains(&format!("PSNR {psnr:.1} dB")), "{caption}");
        }
    }
    assert!(page.contains(&format!("({} hardware threads)", j["machine"]["cores"])));
    let shot = support::node::screenshot_dir("report-html").join("report.png");
    let spec = out.path().join("spec.json");
    std::fs::write(
        &spec,
        serde_json::to_string(&json!({
            "chromium": chromium,
            "html": html,
            "screenshot": shot,
            "width": 1280,
        }))
        .unwrap(),
    )
    .unwrap();
    let r = support::node::run_json(&node, "report_screenshot.mjs", &spec);
    eprintln!("{test}: {r}");
    let errors: Vec<&Value> = r["console"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| m["type"] == "error" || m["type"] == "warn")
        .collect();
    assert!(errors.is_empty(), "console: {errors:?}");
    assert_eq!(r["page_errors"], json!([]));
    assert_eq!(r["failed_requests"], json!([]));
    // The page was the only file requested: everything else is embedded.
    let reqs = r["requests"].as_array().unwrap();
    assert!(reqs[0].as_str().unwrap().starts_with("file://"));
    for q in &reqs[1..] {
        assert!(q.as_str().unwrap().starts_with("data:"), "{q}");
    }
    let imgs = r["images"].as_array().unwrap();
    // Three thumbnails, the far field's frame-time plot, and two Fig.-4 plots per culling mode
    // of the walk's Table 1 (frustum and frustum+occlusion, each with and without the
    // per-building test).
    let mut modes: Vec<String> = j["summary"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["mode"].as_str().unwrap().to_string())
        .collect();
    modes.sort();
    modes.dedup();
    assert_eq!(modes.len(), 4, "{modes:?}");
    assert_eq!(imgs.len(), 3 + 1 + 2 * modes.len(), "{imgs:?}");
    for m in &modes {
        assert!(
            imgs.iter()
                .any(|i| i["alt"] == format!("time per frame, {m}")),
            "no frame-time plot of {m}"
        );
    }
    assert!(imgs
        .iter()
        .any(|i| i["alt"] == "mesh-only against hybrid frame time"));
    for i in imgs {
        assert!(i["data_url"].as_bool().unwrap(), "{i}");
        assert!(i["complete"].as_bool().unwrap(), "{i}");
        assert!(i["natural_width"].as_u64().unwrap() > 0, "not decoded: {i}");
    }
    let svgs = r["svgs"].as_array().unwrap();
    assert_eq!(svgs.len(), 1, "the route map");
    assert!(svgs[0]["width"].as_f64().unwrap() > 100.0);
    assert!(
        svgs[0]["paths"].as_u64().unwrap() >= 3,
        "blocks, buildings, route"
    );
    assert_eq!(
        r["captions"],
        json!(["frame 0", "frame 2", "frame 4"]),
        "one caption per kept frame"
    );
    let png = image::open(&shot).unwrap();
    assert_eq!(png.width(), 1280);
    assert!(png.height() > 900, "the whole page");
    eprintln!("{test}: screenshot {}", shot.display());
}
