//! Prints the performance tables of `docs/performance.md`:
//!
//! ```text
//! cargo build --release --bins --examples && target/release/examples/perf_table [--quick] [--max SIZE]
//! ```
//!
//! * Level size: `synth::bench_obstacles(size, 60, 12, 7)` (60 obstacles, a
//!   dozen lights, falloff size / 12) at 128 to 2048 px, each baked by the
//!   real `flatbake bake` binary (whole process, `normal` quality) under
//!   `/usr/bin/time` for wall time and peak memory; stage times come from the
//!   report JSON.
//! * Edge count: the 512 px level with 15 to 240 obstacles.
//! * Patch count: the 512 px level at `draft`, `normal` and `high`.
//! * Naive against fast: `synth::bench_scattered(size, 40, 3, 7)` baked in
//!   this process with both gathers on the same patches and the same solve;
//!   the gather stage times are compared, and so are the lightmaps (the fast
//!   gather is exact for the given radiosity; the naive one samples points
//!   on each patch, 8 and 64 of them). All are compared with the `reference`
//!   bake, so each ratio is stated with both errors.
//!
//! `--quick` stops the size table at 512 and skips the 128 px naive runs.
//! Timings are wall time on whatever machine runs this; the load average is
//! printed with the tables because the numbers depend on it.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use flatbake_core::bake::{GatherMethod, Settings, bake};
use flatbake_core::level::{Cell, Level};
use flatbake_core::quality::Quality;
use flatbake_synth::{self as synth, Painted};

struct Run {
    wall: f64,
    /// User + system CPU seconds of the process (less sensitive to load).
    cpu: Option<f64>,
    peak_mb: Option<f64>,
    report: serde_json::Value,
}

fn flatbake_bin() -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe()?;
    let dir = exe
        .parent()
        .and_then(Path::parent)
        .ok_or_else(|| anyhow::anyhow!("cannot locate the target folder"))?;
    let bin = dir.join("flatbake");
    if !bin.exists() {
        anyhow::bail!(
            "{} not found: run `cargo build --release --bins --examples` first",
            bin.display()
        );
    }
    Ok(bin)
}

/// Bakes `level` (saved into `dir`) with the flatbake binary, whole process.
fn bake_process(dir: &Path, level: &Painted, quality: &str) -> anyhow::Result<Run> {
    level.save(dir)?;
    let png = dir.join(format!("{}.png", level.name));
    let out = dir.join("out");
    let bin = flatbake_bin()?;
    let timed = Path::new("/usr/bin/time").exists();
    let mut cmd = if timed {
        let mut c = Command::new("/usr/bin/time");
        c.arg("-f").arg("PERF_TABLE %e %M %U %S").arg(&bin);
        c
    } else {
        Command::new(&bin)
    };
    cmd.args(["bake", "--quiet", "-q", quality, "-o"])
        .arg(&out)
        .arg(&png);
    let t = Instant::now();
    let res = cmd.output()?;
    let mut wall = t.elapsed().as_secs_f64();
    if !res.status.success() {
        anyhow::bail!(
            "flatbake failed on {}: {}",
            png.display(),
            String::from_utf8_lossy(&res.stderr)
        );
    }
    let mut peak_mb = None;
    let mut cpu = None;
    for line in String::from_utf8_lossy(&res.stderr).lines() {
        if let Some(rest) = line.strip_prefix("PERF_TABLE ") {
            let mut it = rest.split_whitespace();
            if let Some(w) = it.next().and_then(|v| v.parse::<f64>().ok()) {
                wall = w;
            }
            peak_mb = it
                .next()
                .and_then(|v| v.parse::<f64>().ok())
                .map(|kb| kb / 1024.0);
            let user = it.next().and_then(|v| v.parse::<f64>().ok());
            let sys = it.next().and_then(|v| v.parse::<f64>().ok());
            cpu = user.zip(sys).map(|(u, s)| u + s);
        }
    }
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(
        out.join(format!("{}.report.json", level.name)),
    )?)?;
    Ok(Run {
        wall,
        cpu,
        peak_mb,
        report,
    })
}

fn stage(r: &Run, name: &str) -> f64 {
    r.report["timings"][name].as_f64().unwrap_or(0.0)
}

fn count(r: &Run, name: &str) -> u64 {
    r.report["counts"][name].as_u64().unwrap_or(0)
}

fn header() {
    println!(
        "| level | px | edges | patches | geometry s | F s | solve s | gather s | bake s | process s | CPU s | s / Mpx | peak MB |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
}

fn row(label: &str, size: usize, r: &Run) {
    let mpx = (size * size) as f64 / 1e6;
    println!(
        "| {label} | {size}x{size} | {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {} | {:.2} | {} |",
        count(r, "edges"),
        count(r, "patches"),
        stage(r, "geometry"),
        stage(r, "form_factors"),
        stage(r, "solve"),
        stage(r, "gather"),
        stage(r, "total"),
        r.wall,
        r.cpu.map_or("n/a".into(), |c| format!("{c:.2}")),
        r.wall / mpx,
        r.peak_mb.map_or("n/a".into(), |m| format!("{m:.0}")),
    );
}

fn load_level(p: &Painted) -> anyhow::Result<(Level, Option<f64>)> {
    let (lv, palette) = p.level()?;
    Ok((lv, palette.settings.falloff))
}

/// Floor-pixel light of a `normal` bake, and the gather stage time.
fn bake_floor(lv: &Level, gather: GatherMethod, samples: usize) -> anyhow::Result<(Vec<f32>, f64)> {
    bake_floor_at(lv, Quality::Normal, gather, samples)
}

fn bake_floor_at(
    lv: &Level,
    quality: Quality,
    gather: GatherMethod,
    samples: usize,
) -> anyhow::Result<(Vec<f32>, f64)> {
    let mut s = Settings::new(quality);
    s.gather = gather;
    s.naive_samples = samples;
    let b = bake(lv, &s, &|_| {})?;
    let v = lv
        .cells
        .iter()
        .zip(&b.lightmap.rgb)
        .filter(|(c, _)| **c == Cell::Floor)
        .flat_map(|(_, v)| *v)
        .collect();
    Ok((v, b.report.timings.gather))
}

/// RMS and largest difference of `a` against `reference`, relative to the
/// reference's RMS.
fn rel_err(a: &[f32], reference: &[f32]) -> (f64, f64) {
    let n = reference.len().max(1) as f64;
    let rms_ref = (reference.iter().map(|v| (*v as f64).powi(2)).sum::<f64>() / n).sqrt();
    let rms = (a
        .iter()
        .zip(reference)
        .map(|(x, y)| (*x as f64 - *y as f64).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let max = a
        .iter()
        .zip(reference)
        .map(|(x, y)| (*x as f64 - *y as f64).abs())
        .fold(0.0, f64::max);
    (rms / rms_ref, max / rms_ref)
}

fn main() -> anyhow::Result<()> {
    let mut quick = false;
    let mut max = 2048;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--quick" => quick = true,
            "--max" => {
                max = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .ok_or_else(|| anyhow::anyhow!("--max needs a size"))?
            }
            _ => {
                println!("usage: perf_table [--quick] [--max SIZE]");
                return Ok(());
            }
        }
    }
    if quick {
        max = max.min(512);
    }
    let dir = tempfile::tempdir()?;
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "flatbake perf_table: {} logical cores, load average at start: {}",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );

    println!("\n### Level size (60 obstacles, 12 lights, falloff size/12, normal)\n");
    header();
    let mut by_size = Vec::new();
    for size in [128usize, 256, 512, 1024, 2048] {
        if size > max {
            break;
        }
        let r = bake_process(
            dir.path(),
            &synth::bench_obstacles(size, 60, 12, 7),
            "normal",
        )?;
        row("obstacles", size, &r);
        by_size.push((size, r));
    }
    println!("\nScaling per 4x pixels (process time, gather time):");
    for w in by_size.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        println!(
            "- {} -> {}: process x{:.2}, CPU x{:.2}, gather x{:.2}, F x{:.2}",
            a.0,
            b.0,
            b.1.wall / a.1.wall,
            b.1.cpu.unwrap_or(f64::NAN) / a.1.cpu.unwrap_or(f64::NAN),
            stage(&b.1, "gather") / stage(&a.1, "gather"),
            stage(&b.1, "form_factors") / stage(&a.1, "form_factors").max(1e-9),
        );
    }

    println!("\n### Edge count (512 px, 12 lights, normal)\n");
    header();
    let mut by_edges = Vec::new();
    for obstacles in [15usize, 30, 60, 120, 240] {
        let r = bake_process(
            dir.path(),
            &synth::bench_obstacles(512, obstacles, 12, 7),
            "normal",
        )?;
        row(&format!("{obstacles} obstacles"), 512, &r);
        by_edges.push(r);
    }
    let (first, last) = (&by_edges[0], &by_edges[by_edges.len() - 1]);
    println!(
        "\nEdges x{:.1}: gather x{:.2}, process x{:.2}, CPU x{:.2}",
        count(last, "edges") as f64 / count(first, "edges") as f64,
        stage(last, "gather") / stage(first, "gather"),
        last.wall / first.wall,
        last.cpu.unwrap_or(f64::NAN) / first.cpu.unwrap_or(f64::NAN)
    );

    println!("\n### Patch count (512 px, 60 obstacles)\n");
    header();
    for q in ["draft", "normal", "high"] {
        let r = bake_process(dir.path(), &synth::bench_obstacles(512, 60, 12, 7), q)?;
        row(q, 512, &r);
    }

    println!(
        "\n### Naive against fast gather (40 one-pixel walls, 3 lights, no falloff, normal)\n"
    );
    println!(
        "Errors: RMS difference relative to the `reference` bake's RMS (patch 0.5 px, quadrature 8). The naive gather runs at 8 and at 64 sample points per patch; ratios are naive gather time over fast gather time, measured in this run.\n"
    );
    println!(
        "| level | fast gather s | fast err | naive (8) s | naive (8) err | naive (8) / fast | naive (64) s | naive (64) err | naive (64) / fast |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for size in [32usize, 64, 128] {
        if quick && size > 64 {
            break;
        }
        let (lv, _) = load_level(&synth::bench_scattered(size, 40, 3, 7))?;
        let (reference, _) = bake_floor_at(&lv, Quality::Reference, GatherMethod::Fast, 8)?;
        // Warm-up, then the best of three for the fast gather (it is short).
        let _ = bake_floor(&lv, GatherMethod::Fast, 8)?;
        let mut fast_t = f64::INFINITY;
        let mut fast = Vec::new();
        for _ in 0..3 {
            let (v, t) = bake_floor(&lv, GatherMethod::Fast, 8)?;
            fast_t = fast_t.min(t);
            fast = v;
        }
        let err = |v: &[f32]| 100.0 * rel_err(v, &reference).0;
        let (naive8, t8) = bake_floor(&lv, GatherMethod::Naive, 8)?;
        let (naive64, t64) = bake_floor(&lv, GatherMethod::Naive, 64)?;
        println!(
            "| scattered {size}x{size} | {fast_t:.4} | {:.3}% | {t8:.3} | {:.3}% | {:.0} | {t64:.2} | {:.3}% | {:.0} |",
            err(&fast),
            err(&naive8),
            t8 / fast_t,
            err(&naive64),
            t64 / fast_t,
        );
    }
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "\nload average at end: {}",
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    Ok(())
}
