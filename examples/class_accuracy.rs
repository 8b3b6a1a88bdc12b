//! `draft` and `normal` against `high` at full size, on every level class
//! of the speed targets (`synth::hard_classes`, up to `--max-pixels`): the
//! relative RMS over the floor, the largest difference, and the pixels
//! that come out the most times too bright and too dark (each pixel's
//! light and `high`'s plus 2 % of the floor's mean light, so that the
//! darkest pixels do not rule the ratio). A Markdown table for
//! docs/performance.md.
//!
//! The accuracy sweep (`flatbake sweep`) runs at 192 px against
//! `reference`; a preset's outliers can hide at that size: a pixel of
//! wall noise ten times too bright at `draft` did, for eight passes
//! (docs/performance.md, forty-second pass). `high` is the yardstick
//! here because `reference` at full size takes too long.
//!
//! ```text
//! cargo run --release --example class_accuracy -- [--max-pixels N] [--only TEXT]...
//! ```

use std::time::Instant;

use anyhow::anyhow;
use flatbake_core::accuracy::compare;
use flatbake_core::bake::{Baked, Settings, bake};
use flatbake_core::level::{Cell, Level};
use flatbake_core::quality::Quality;

fn main() -> anyhow::Result<()> {
    let mut max_pixels = 1_100_000usize;
    let mut only: Vec<String> = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--max-pixels" => {
                max_pixels = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .ok_or_else(|| anyhow!("--max-pixels needs a number"))?;
            }
            "--only" => only.push(args.next().ok_or_else(|| anyhow!("--only needs a text"))?),
            _ => {
                return Err(anyhow!(
                    "usage: class_accuracy [--max-pixels N] [--only TEXT]..."
                ));
            }
        }
    }
    println!(
        "| class | preset | s | `high` s | relative RMS | largest difference | brightest: light / `high` | darkest: `high` / light |"
    );
    println!("|---|---|---:|---:|---:|---:|---|---|");
    for class in flatbake_synth::hard_classes() {
        let painted = &class.level;
        if painted.width * painted.height > max_pixels
            || !(only.is_empty() || only.iter().any(|o| class.label.contains(o.as_str())))
        {
            continue;
        }
        let (level, palette) = painted.level().map_err(|e| anyhow!("{e}"))?;
        let run = |q: Quality| -> anyhow::Result<(Baked, f64)> {
            let mut s = Settings::new(q);
            s.falloff = palette.settings.falloff;
            s.bounces = palette.settings.bounces;
            let t = Instant::now();
            let b = bake(&level, &s, &|_| {}).map_err(|e| anyhow!("{e}"))?;
            Ok((b, t.elapsed().as_secs_f64()))
        };
        let (high, th) = run(Quality::High)?;
        for q in [Quality::Draft, Quality::Normal] {
            let (b, t) = run(q)?;
            let (rms, max) = compare(&level, &b.lightmap.rgb, &high.lightmap.rgb);
            let (bright, dark) = match outliers(&level, &b, &high) {
                Some(((x, at_x), (y, at_y))) => {
                    (format!("{x:.1}x at {at_x}"), format!("{y:.1}x at {at_y}"))
                }
                None => ("(no light)".into(), "(no light)".into()),
            };
            println!(
                "| {} | {} | {t:.2} | {th:.2} | {:.3} % | {max:.4} | {bright} | {dark} |",
                class.label,
                q.name(),
                100.0 * rms,
            );
        }
    }
    Ok(())
}

/// The floor pixels of `b` the most times brighter and darker than
/// `high`'s (each pixel's light summed over its channels, both plus 2 %
/// of `high`'s mean over the floor), with where they are; `None` where
/// `high`'s floor has no light.
fn outliers(level: &Level, b: &Baked, high: &Baked) -> Option<((f64, String), (f64, String))> {
    let floor: Vec<usize> = (0..level.cells.len())
        .filter(|&i| level.cells[i] == Cell::Floor)
        .collect();
    let sum = |v: &[f32; 3]| v.iter().map(|&c| f64::from(c)).sum::<f64>();
    let mean = floor
        .iter()
        .map(|&i| sum(&high.lightmap.rgb[i]))
        .sum::<f64>()
        / floor.len().max(1) as f64;
    if mean <= 0.0 {
        return None;
    }
    let guard = 0.02 * mean;
    let at = |i: usize| format!("({}, {})", i % level.width, i / level.width);
    let (mut bright, mut dark) = ((0.0, String::new()), (0.0, String::new()));
    for &i in &floor {
        let (x, r) = (
            sum(&b.lightmap.rgb[i]) + guard,
            sum(&high.lightmap.rgb[i]) + guard,
        );
        if x / r > bright.0 {
            bright = (x / r, at(i));
        }
        if r / x > dark.0 {
            dark = (r / x, at(i));
        }
    }
    Some((bright, dark))
}
