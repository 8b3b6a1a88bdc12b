//! What `--directional` costs: bakes `levels/big_level.png` and two hard
//! synthetic classes (`noise 0.3` and `checkerboard, 4 rooms`, 512 px) with
//! the `flatbake` binary beside this example, plain and with
//! `--directional`, interleaved (plain, directional, plain, ...), and prints
//! the median wall time of each and of its gather stage (from the report),
//! with their ratio and the load average.
//!
//! `cargo build --release --bins --examples && target/release/examples/directional_cost [RUNS] [QUALITY]`
//! (default 3 runs, `normal`).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use flatbake_synth as synth;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let runs: usize = args.next().map_or(Ok(3), |a| a.parse())?;
    let quality = args.next().unwrap_or_else(|| "normal".into());
    let bin = std::env::current_exe()?
        .parent()
        .and_then(Path::parent)
        .map(|p| p.join("flatbake"))
        .ok_or_else(|| anyhow::anyhow!("no flatbake binary beside the example"))?;
    let dir = tempfile::tempdir()?;
    let mut levels: Vec<(String, PathBuf)> =
        vec![("big_level".into(), "levels/big_level.png".into())];
    // The classes as `synth::hard_classes` makes them.
    for (label, level) in [
        ("noise 0.3", synth::noise(512, 0.3, 12, 1)),
        ("checkerboard, 4 rooms", synth::checkerboard(512, 4, 1)),
    ] {
        let sub = dir.path().join(&level.name);
        level.save(&sub)?;
        levels.push((label.into(), sub.join(format!("{}.png", level.name))));
    }
    let load = || std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "quality {quality}, {runs} interleaved runs each, load at start {}",
        load().trim()
    );
    println!(
        "| level | plain s | directional s | ratio | plain gather s | directional gather s | ratio |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for (label, path) in &levels {
        let mut t = [Vec::new(), Vec::new()];
        let mut g = [Vec::new(), Vec::new()];
        for _ in 0..runs {
            for (k, extra) in [None, Some("--directional")].into_iter().enumerate() {
                let out = dir.path().join(format!("out{k}"));
                let mut cmd = Command::new(&bin);
                cmd.args(["bake", "--quiet", "--force", "-q", &quality, "-o"])
                    .arg(&out)
                    .arg(path);
                cmd.args(extra);
                let start = Instant::now();
                let status = cmd.status()?;
                t[k].push(start.elapsed().as_secs_f64());
                anyhow::ensure!(status.success(), "{label}: bake failed");
                let name = path.file_stem().unwrap().to_string_lossy();
                let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(
                    out.join(format!("{name}.report.json")),
                )?)?;
                g[k].push(report["timings"]["gather"].as_f64().unwrap_or(f64::NAN));
            }
        }
        let med = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (t0, t1, g0, g1) = (
            med(&mut t[0]),
            med(&mut t[1]),
            med(&mut g[0]),
            med(&mut g[1]),
        );
        println!(
            "| {label} | {t0:.2} | {t1:.2} | {:.3} | {g0:.2} | {g1:.2} | {:.3} |",
            t1 / t0,
            g1 / g0
        );
    }
    println!("load at end {}", load().trim());
    Ok(())
}
