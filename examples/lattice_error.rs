//! What the interpolated gather costs and saves: bakes every level at
//! `draft` and `normal` as the presets set them and with their lattice
//! off, times each bake (in process, one run), and compares each with
//! `high` (relative RMS over floor pixels): a Markdown table for
//! docs/performance.md.
//!
//! ```text
//! cargo run --release --example lattice_error -- LEVELS...
//! ```

use std::path::PathBuf;
use std::time::Instant;

use flatbake_core::accuracy::compare;
use flatbake_core::bake::{Baked, Settings, bake};
use flatbake_core::level::palette::Palette;
use flatbake_core::level::{LoadLimits, load_level};
use flatbake_core::quality::Quality;

fn main() -> anyhow::Result<()> {
    let paths: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    println!(
        "| level | preset | lattice s | lattice error | interpolated | exact s | exact error | exact / lattice time |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|");
    for path in flatbake_core::batch::collect_levels(&paths) {
        let palette =
            Palette::resolve_for_level(&path, None).map_err(|e| anyhow::anyhow!("{e}"))?;
        let level = load_level(&path, &palette, LoadLimits::default())
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let run = |q: Quality, lattice: bool| -> anyhow::Result<(Baked, f64)> {
            let mut s = Settings::new(q);
            s.falloff = palette.settings.falloff;
            s.bounces = palette.settings.bounces;
            if !lattice {
                s.knobs.lattice = None;
            }
            let t = Instant::now();
            let b = bake(&level, &s, &|_| {}).map_err(|e| anyhow::anyhow!("{e}"))?;
            Ok((b, t.elapsed().as_secs_f64()))
        };
        let (high, _) = run(Quality::High, false)?;
        for q in [Quality::Draft, Quality::Normal] {
            let (a, ta) = run(q, true)?;
            let (b, tb) = run(q, false)?;
            let ea = compare(&level, &a.lightmap.rgb, &high.lightmap.rgb).0;
            let eb = compare(&level, &b.lightmap.rgb, &high.lightmap.rgb).0;
            let interp = a
                .report
                .skipped
                .iter()
                .find(|s| s.reason.contains("interpolated"))
                .and_then(|s| s.reason.split(' ').next()?.parse::<f64>().ok())
                .unwrap_or(0.0);
            println!(
                "| {} | {} | {ta:.2} | {:.3}% | {:.0}% | {tb:.2} | {:.3}% | {:.2} |",
                level.name,
                q.name(),
                100.0 * ea,
                100.0 * interp / a.report.counts.floor_pixels.max(1) as f64,
                100.0 * eb,
                tb / ta
            );
        }
    }
    Ok(())
}
