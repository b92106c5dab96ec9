//! `fem2d report` end to end: the page has every section and picture, the pictures exist, and
//! the page renders in headless Chromium (a screenshot that is not blank, and every image
//! decoded, counted by the page's own script).
//!
//! The browser part needs Chromium (`/usr/bin/chromium`, Debian's `chromium` package, which
//! `.ci/run` installs). Without it the test says so and checks only the files, unless
//! `FEM2D_REQUIRE_BROWSER=1` (set by `.ci/run`), which makes a missing browser a failure.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use crate::common::{arg, fem2d, read, scratch};
use fem_render::Image;

/// The report, built once for the tests of this file.
fn report() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = scratch("report");
        let out = fem2d(&["report", "--out", arg(&dir)]);
        assert!(
            out.status.success(),
            "fem2d report failed:\n{}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        dir
    })
}

fn images_in(html: &str) -> usize {
    html.matches("<img ").count()
}

#[test]
fn report_has_every_section_and_picture() {
    let dir = report();
    let html = read(&dir.join("index.html"));
    for needle in [
        "Table 1: case A",
        "Figure 1",
        "Figure 2",
        "Figure 3",
        "Figure 4",
        "Figure 5",
        "Case A: tip deflection",
        "Case C: tip deflection",
        "stability map",
        "Animations",
        "Frame budget: 90 Hz, 5 ms per frame",
        "neo-hookean at 90 Hz within 5 ms per frame, ranked by the soft tissue's von Mises stress in the sustained phase",
        "Frame budget windows, case-d",
        "neo-hookean, case-a in 2D against case-a-3d in 3D at 90 Hz within 5 ms per frame",
        "cannot run: linear-implicit has no 3D path yet",
        "Cost of a frame against mesh size, 2D and 3D",
        "Run metadata",
        "Wall time",
        "cores available",
        "paper (s)",
    ] {
        assert!(html.contains(needle), "index.html lacks \"{needle}\"");
    }
    // Self-contained: every image is a data URI, nothing is fetched.
    assert!(!html.contains("src=\"http"), "the page fetches something");
    assert_eq!(
        html.matches("src=\"data:image/").count(),
        images_in(&html),
        "an image is not embedded"
    );
    // 6 figures (case A in 2D and in 3D) + 2 curve charts + the stability map + 6 frame-budget
    // charts (case A's three energies, case D's and its windows, case A in 3D) + the cost
    // against mesh size + 4 animations.
    assert_eq!(images_in(&html), 20);
    for file in [
        "figure-1-mesh-pipeline.png",
        "figure-2-case-a.png",
        "figure-2-case-a-3d.png",
        "figure-3-case-b.png",
        "figure-4-case-c.png",
        "figure-5-case-d.png",
        "curves-case-a.png",
        "curves-case-a.svg",
        "curves-case-c.svg",
        "stability-case-b.png",
        "stability-case-b.svg",
        "animation-case-a.gif",
        "animation-case-d.gif",
        "budget-case-a-stvk.png",
        "budget-case-d-neo-hookean.png",
        "budget-case-a-3d-neo-hookean.png",
        "budget-scaling.png",
    ] {
        let path = dir.join("figures").join(file);
        let size = std::fs::metadata(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .len();
        assert!(size > 1000, "{file} is only {size} bytes");
    }
}

fn chromium() -> Option<PathBuf> {
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .flat_map(|name| {
            std::env::var_os("PATH")
                .map(|p| {
                    std::env::split_paths(&p)
                        .map(|d| d.join(name))
                        .collect::<Vec<_>>()
                })
                .unwrap_or_default()
        })
        .find(|p| p.is_file())
}

/// Chromium's flags for a sandbox without network or GPU.
fn browser(exe: &Path, profile: &Path) -> Command {
    let mut c = Command::new(exe);
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--hide-scrollbars",
        "--virtual-time-budget=10000",
    ])
    .arg(format!("--user-data-dir={}", profile.display()));
    c
}

#[test]
fn report_renders_in_headless_chromium() {
    let Some(exe) = chromium() else {
        assert!(
            std::env::var("FEM2D_REQUIRE_BROWSER").as_deref() != Ok("1"),
            "FEM2D_REQUIRE_BROWSER=1 but no chromium on PATH (apt-get install chromium)"
        );
        eprintln!(
            "report_renders_in_headless_chromium: no chromium on PATH; browser check skipped"
        );
        return;
    };
    let dir = report();
    let index = std::path::absolute(dir.join("index.html")).unwrap();
    let url = format!("file://{}", index.display());
    let html = read(&index);

    // The DOM after the load event: the page's script has counted the decoded images.
    let profile = scratch("report-chromium-dom");
    let out = browser(&exe, &profile)
        .arg("--dump-dom")
        .arg(&url)
        .output()
        .expect("chromium runs");
    let dom = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "chromium --dump-dom failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let n = images_in(&html);
    assert!(
        dom.contains(&format!("data-images-loaded=\"{n}/{n}\"")),
        "not every image loaded: {}",
        dom.lines()
            .find(|l| l.contains("<body"))
            .unwrap_or("(no body tag in the DOM)")
    );

    // A screenshot of the top of the page: not blank, with the colours of the pictures.
    let profile = scratch("report-chromium-shot");
    let shot = profile.join("shot.png");
    let out = browser(&exe, &profile)
        .arg(format!("--screenshot={}", shot.display()))
        .arg("--window-size=1280,2400")
        .arg(&url)
        .output()
        .expect("chromium runs");
    assert!(
        out.status.success(),
        "chromium --screenshot failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = Image::from_png(&std::fs::read(&shot).unwrap()).unwrap();
    assert_eq!((img.width(), img.height()), (1280, 2400));
    let px = img.as_rgba().chunks_exact(4);
    let total = px.len();
    let non_white = px
        .clone()
        .filter(|c| c[0] < 240 || c[1] < 240 || c[2] < 240)
        .count();
    let colourful = px
        .filter(|c| {
            let (mx, mn) = (c[0].max(c[1]).max(c[2]), c[0].min(c[1]).min(c[2]));
            mx - mn > 60
        })
        .count();
    assert!(
        non_white * 20 > total,
        "the page looks blank: {non_white} of {total} pixels not white"
    );
    assert!(
        colourful > 5000,
        "no picture visible in the screenshot ({colourful} colourful pixels)"
    );
}
