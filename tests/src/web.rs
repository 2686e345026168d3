//! The 3D Tiles tools the export tests run: the official validator
//! (CesiumGS' 3d-tiles-validator, which `scripts/setup.sh` installs in
//! `target/3d-tiles-validator`) and the web viewer in headless Chromium
//! (`viewer/web/shot.mjs` with playwright-core from `target/web`).

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

fn target() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target")
}

/// `Some(())` when `what` is there; else the skip recorded, or a failure
/// when `require` is set in the environment.
fn need(test: &str, have: bool, require: &str, what: &str) -> Option<()> {
    if have {
        return Some(());
    }
    if std::env::var_os(require).is_some() {
        panic!("{test}: {what} is not installed although {require} is set");
    }
    crate::record_skip(
        test,
        &format!("{what} not installed (scripts/setup.sh installs it)"),
    );
    None
}

/// The validator's entry script, if installed.
pub fn validator(test: &str) -> Option<PathBuf> {
    let main = target().join("3d-tiles-validator/build/main.js");
    need(
        test,
        main.is_file(),
        "HLOD_REQUIRE_3DTILES",
        "the 3D Tiles validator",
    )?;
    Some(main)
}

/// The validator's report on `tileset` (`numErrors`, `numWarnings`,
/// `issues`). It exits 0 whatever it finds, so the report is what counts.
pub fn validate(main: &Path, tileset: &Path) -> Value {
    let dir = tempfile::tempdir().expect("a temp dir");
    let report = dir.path().join("report.json");
    let out = Command::new("node")
        .arg(main)
        .arg("-t")
        .arg(tileset)
        .arg("-r")
        .arg(&report)
        .output()
        .expect("node runs");
    let text = std::fs::read(&report).unwrap_or_else(|e| {
        panic!(
            "no validator report ({e}): {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    });
    serde_json::from_slice(&text).expect("the report is JSON")
}

/// The first few issues of a report, one line each, for a failure message.
pub fn issues(report: &Value) -> String {
    let mut lines = Vec::new();
    let mut stack: Vec<&Value> = vec![report];
    while let Some(v) = stack.pop() {
        for key in ["issues", "causes"] {
            for i in v[key].as_array().into_iter().flatten() {
                if i["severity"] != "INFO" {
                    lines.push(format!("{} {} {}", i["type"], i["path"], i["message"]));
                }
                stack.push(i);
            }
        }
    }
    lines.truncate(12);
    lines.join("\n")
}

/// The browser driver (`node shot.mjs`), if Chromium and playwright-core
/// are installed.
pub fn browser(test: &str) -> Option<PathBuf> {
    let chromium = std::env::var_os("CHROMIUM")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/usr/bin/chromium"));
    let modules = target().join("web/node_modules/playwright-core");
    need(
        test,
        chromium.exists() && modules.is_dir(),
        "HLOD_REQUIRE_BROWSER",
        "Chromium with playwright-core",
    )?;
    // The scripts import playwright-core from beside them.
    for name in ["shot.mjs", "browser.mjs"] {
        std::fs::copy(
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../viewer/web")
                .join(name),
            target().join("web").join(name),
        )
        .unwrap_or_else(|e| panic!("{name} copied: {e}"));
    }
    Some(target().join("web/shot.mjs"))
}

/// Opens `url` at `width` x `height`, waits until the view is complete,
/// saves a screenshot to `png` and picks at `picks`: what the page saw
/// (`idleMs`, `stats`, `pick`, `errors`).
pub fn shoot(
    script: &Path,
    url: &str,
    size: (u32, u32),
    png: &Path,
    picks: &[(u32, u32)],
) -> Value {
    let mut cmd = Command::new("node");
    cmd.arg(script)
        .arg(url)
        .arg("--size")
        .arg(format!("{}x{}", size.0, size.1))
        .arg("--out")
        .arg(png);
    if !picks.is_empty() {
        let p: Vec<String> = picks.iter().map(|(x, y)| format!("{x},{y}")).collect();
        cmd.arg("--pick").arg(p.join(";"));
    }
    let out = cmd.output().expect("node runs");
    assert!(
        out.status.success(),
        "shot.mjs failed: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text.lines().last().unwrap_or_default();
    serde_json::from_str(line).unwrap_or_else(|e| panic!("shot.mjs printed {text:?}: {e}"))
}
