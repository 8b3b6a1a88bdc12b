//! What each skip saves: bakes every level twice, as flatbake does by
//! default and with `Settings::exhaustive` (nothing skipped), and prints a
//! Markdown table of times, solves and the skips taken, for the README.
//!
//! ```text
//! cargo run --release --example skip_savings -- levels [--quality normal] [--runs 3]
//! ```
//! Also bakes grey and no-bounce variants of each level (all emitters made
//! white; all reflectances 0), where the channel and bounce skips show.

use std::path::PathBuf;
use std::time::Instant;

use flatbake_core::bake::{Baked, Settings, bake};
use flatbake_core::level::palette::Palette;
use flatbake_core::level::{Level, LoadLimits, load_level};
use flatbake_core::quality::Quality;

fn main() -> anyhow::Result<()> {
    let mut paths = Vec::new();
    let mut quality = Quality::Normal;
    let mut runs = 3usize;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--quality" => {
                let q = args.next().unwrap_or_default();
                quality = Quality::ALL
                    .into_iter()
                    .find(|x| x.name() == q)
                    .ok_or_else(|| anyhow::anyhow!("unknown quality {q}"))?;
            }
            "--runs" => runs = args.next().and_then(|s| s.parse().ok()).unwrap_or(3).max(1),
            _ => paths.push(PathBuf::from(a)),
        }
    }
    println!(
        "| level | variant | default: solves | default: s | exhaustive: solves | exhaustive: s | saved | max diff | skipped |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---|");
    for path in flatbake_core::batch::collect_levels(&paths) {
        let palette =
            Palette::resolve_for_level(&path, None).map_err(|e| anyhow::anyhow!("{e}"))?;
        let level = load_level(&path, &palette, LoadLimits::default())
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let mut grey = level.clone();
        for m in &mut grey.materials {
            let e = m.emission.iter().sum::<f64>() / 3.0;
            let r = m.reflectance.iter().sum::<f64>() / 3.0;
            m.emission = [e; 3];
            m.reflectance = [r; 3];
        }
        let mut matte = level.clone();
        for m in &mut matte.materials {
            m.reflectance = [0.0; 3];
        }
        for (variant, lvl) in [
            ("as painted", &level),
            ("grey", &grey),
            ("no reflection", &matte),
        ] {
            let time = |exhaustive: bool| -> anyhow::Result<(f64, Baked)> {
                let mut s = Settings::new(quality);
                s.falloff = palette.settings.falloff;
                s.exhaustive = exhaustive;
                let mut best = f64::INFINITY;
                let mut last = None;
                for _ in 0..runs {
                    let t = Instant::now();
                    let b = bake(lvl, &s, &|_| {}).map_err(|e| anyhow::anyhow!("{e}"))?;
                    best = best.min(t.elapsed().as_secs_f64());
                    last = Some(b);
                }
                Ok((best, last.expect("at least one run")))
            };
            let (td, d) = time(false)?;
            let (tx, x) = time(true)?;
            println!(
                "| {} | {variant} | {} | {td:.3} | {} | {tx:.3} | {:.0}% | {:.1e} | {} |",
                level_name(&level),
                d.report.solves,
                x.report.solves,
                100.0 * (1.0 - td / tx),
                max_diff(&d, &x),
                d.report
                    .skipped
                    .iter()
                    .map(|s| s.effect.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
    Ok(())
}

fn level_name(l: &Level) -> &str {
    &l.name
}

fn max_diff(a: &Baked, b: &Baked) -> f64 {
    a.lightmap
        .rgb
        .iter()
        .zip(&b.lightmap.rgb)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs() as f64))
        .fold(0.0, f64::max)
}
