//! Writes the benchmark levels of docs/performance.md as PNG + palette, for baking or
//! profiling them by hand:
//!
//! ```text
//! cargo run --release --example save_bench -- OUT_DIR [SIZE...]
//! cargo run --release --example save_bench -- OUT_DIR --classes
//! cargo run --release --example save_bench -- OUT_DIR --classes-small SIZE
//! ```
//!
//! `bench_obstacles_SIZE` (60 obstacles, 12 lights, falloff SIZE / 12) for
//! each SIZE (default 512), and `bench_scattered_64`.
//!
//! `--classes` writes instead every level class of the speed targets
//! (docs/performance.md) at the size it was first timed at
//! (`flatbake_synth::hard_classes`, the 8192 px benchmark included), and
//! `--classes-small SIZE` the same scenes about SIZE px across
//! (`small_classes`), for `flatbake sweep OUT_DIR`. Both print each level's
//! size, traced edges, free regions and light pixels.

use std::path::PathBuf;

use flatbake_core::geometry::trace;
use flatbake_synth::{self as synth, Class};

fn usage() -> anyhow::Error {
    anyhow::anyhow!(
        "usage: save_bench OUT_DIR [SIZE...] | OUT_DIR --classes | OUT_DIR --classes-small SIZE"
    )
}

/// Saves each class and prints what it holds.
fn save_classes(out: &std::path::Path, classes: &[Class]) -> anyhow::Result<()> {
    println!("| level | class | size | edges | free regions | light px |");
    println!("|---|---|---|---|---|---|");
    for c in classes {
        let p = &c.level;
        p.save(out)?;
        let (level, _) = p.level()?;
        let g = trace(&level);
        let light_px = level
            .cells
            .iter()
            .filter(|cell| match cell {
                flatbake_core::level::Cell::Solid(m) => level.materials[*m as usize].emits(),
                _ => false,
            })
            .count();
        println!(
            "| {} | {} | {}x{} | {} | {} | {} |",
            p.name,
            c.label,
            p.width,
            p.height,
            g.edges.len(),
            g.component_count,
            light_px
        );
    }
    println!("\n-> {}", out.display());
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().ok_or_else(usage)?);
    let rest: Vec<String> = args.collect();
    match rest.first().map(String::as_str) {
        Some("--classes") => return save_classes(&out, &synth::hard_classes()),
        Some("--classes-small") => {
            let size = rest.get(1).and_then(|v| v.parse().ok()).ok_or_else(usage)?;
            return save_classes(&out, &synth::small_classes(size));
        }
        _ => {}
    }
    let mut sizes: Vec<usize> = rest
        .iter()
        .map(|a| a.parse().map_err(|_| anyhow::anyhow!("not a size: {a}")))
        .collect::<anyhow::Result<_>>()?;
    if sizes.is_empty() {
        sizes.push(512);
    }
    for s in sizes {
        let level = synth::bench_obstacles(s, 60, 12, 7);
        level.save(&out)?;
        println!("{} -> {}", level.name, out.display());
    }
    let level = synth::bench_scattered(64, 40, 3, 7);
    level.save(&out)?;
    println!("{} -> {}", level.name, out.display());
    Ok(())
}
