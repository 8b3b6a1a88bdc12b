//! Reference images: every sample level in `levels/` (images, the Tiled
//! map, the levels of the LDtk project) is baked through the
//! real command line (`--quality normal --depth 16`) and its lightmap is
//! compared with `tests/reference/NAME.lightmap.png`, channel by channel,
//! with an explicit tolerance.
//!
//! After an intended change of results, regenerate the references with
//!
//! ```sh
//! FLATBAKE_BLESS=1 cargo test --release --test reference_images
//! ```
//!
//! and look at the new images before committing them. On a mismatch a diff
//! image (the absolute difference, amplified 16x) is written to
//! `target/reference-diff/NAME.diff.png`.
//!
//! Blessing records the flatbake version in `tests/reference/VERSION`,
//! and refuses to change an existing reference's pixels under the version
//! that blessed it: batch stamps and relight caches are keyed by the
//! version, so lightmaps that change without it would be reported up to
//! date with the old light. Bump the workspace version first.

use std::path::{Path, PathBuf};
use std::process::Command;

use image::{ImageBuffer, Rgba};

type Img16 = ImageBuffer<Rgba<u16>, Vec<u16>>;

/// Largest allowed per-channel difference, as a fraction of full scale of
/// the sRGB-encoded 16-bit lightmap (about one 8-bit step).
const TOLERANCE: f64 = 1.0 / 256.0;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn load16(p: &Path) -> Img16 {
    image::open(p)
        .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
        .to_rgba16()
}

#[test]
fn sample_levels_match_their_reference_lightmaps() {
    let out = tempfile::tempdir().expect("temp dir");
    let status = Command::new(env!("CARGO_BIN_EXE_flatbake"))
        .args([
            "bake",
            "--quiet",
            "--quality",
            "normal",
            "--depth",
            "16",
            "-o",
        ])
        .arg(out.path())
        .arg(root().join("levels"))
        .status()
        .expect("flatbake runs");
    assert!(
        status.success(),
        "baking the sample levels failed: {status}"
    );

    let bless = std::env::var_os("FLATBAKE_BLESS").is_some();
    let refs = root().join("tests/reference");
    let diffs = root().join("target/reference-diff");
    // Every level the folder holds: images, Tiled maps, each level of an
    // LDtk project.
    let mut levels: Vec<String> = flatbake_core::batch::collect_levels(&[root().join("levels")])
        .iter()
        .map(|p| flatbake_core::output::names::level_name(p))
        .collect();
    levels.sort();
    assert!(levels.len() >= 11, "the sample set has at least 11 levels");
    for editor in ["tiled_hall", "topdown.World_Level_0"] {
        assert!(levels.iter().any(|l| l == editor), "{editor} is a sample");
    }

    if bless {
        let version = env!("CARGO_PKG_VERSION");
        let record = refs.join("VERSION");
        let blessed_at = std::fs::read_to_string(&record).unwrap_or_default();
        let changed: Vec<&String> = levels
            .iter()
            .filter(|name| {
                let want = refs.join(format!("{name}.lightmap.png"));
                want.exists()
                    && load16(&want) != load16(&out.path().join(format!("{name}.lightmap.png")))
            })
            .collect();
        assert!(
            changed.is_empty() || blessed_at.trim() != version,
            "the lightmaps of {changed:?} changed under version {version}, which blessed them: \
             bump the workspace version (batch stamps and relight caches are keyed by it) and bless again"
        );
        std::fs::create_dir_all(&refs).expect("create tests/reference");
        std::fs::write(&record, format!("{version}\n")).expect("record the version");
    }
    let mut failures = Vec::new();
    for name in &levels {
        let got_path = out.path().join(format!("{name}.lightmap.png"));
        let want_path = refs.join(format!("{name}.lightmap.png"));
        if bless {
            std::fs::copy(&got_path, &want_path).expect("copy reference");
            continue;
        }
        assert!(
            want_path.exists(),
            "{} is missing: run FLATBAKE_BLESS=1 cargo test --release --test reference_images",
            want_path.display()
        );
        let (got, want) = (load16(&got_path), load16(&want_path));
        assert_eq!(got.dimensions(), want.dimensions(), "{name}: size changed");
        let mut worst = 0.0f64;
        let mut bad = 0usize;
        let mut diff = Img16::new(got.width(), got.height());
        for ((a, b), d) in got.pixels().zip(want.pixels()).zip(diff.pixels_mut()) {
            let mut px = [0u16, 0, 0, 65535];
            for c in 0..4 {
                let e = (a[c] as f64 - b[c] as f64).abs() / 65535.0;
                worst = worst.max(e);
                if e > TOLERANCE {
                    bad += 1;
                }
                if c < 3 {
                    px[c] = (e * 16.0 * 65535.0).min(65535.0) as u16;
                }
            }
            *d = Rgba(px);
        }
        if bad > 0 {
            std::fs::create_dir_all(&diffs).expect("create diff folder");
            let p = diffs.join(format!("{name}.diff.png"));
            diff.save(&p).expect("write diff image");
            failures.push(format!(
                "{name}: {bad} channel values differ by more than {TOLERANCE:.4} (worst {worst:.4}); diff image {}",
                p.display()
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
