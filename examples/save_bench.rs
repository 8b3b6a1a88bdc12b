//! Writes the benchmark levels of docs/performance.md as PNG + palette, for baking or
//! profiling them by hand:
//!
//! ```text
//! cargo run --release --example save_bench -- OUT_DIR [SIZE...]
//! ```
//!
//! `bench_obstacles_SIZE` (60 obstacles, 12 lights, falloff SIZE / 12) for
//! each SIZE (default 512), and `bench_scattered_64`.

use std::path::PathBuf;

use flatbake_synth as synth;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(
        args.next()
            .ok_or_else(|| anyhow::anyhow!("usage: save_bench OUT_DIR [SIZE...]"))?,
    );
    let mut sizes: Vec<usize> = args
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
