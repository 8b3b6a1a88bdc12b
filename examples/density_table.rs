//! Times `flatbake bake` at texel densities 1/4 to 4 (`--texels-per-pixel`)
//! on a 128 px wall-noise level (`small_classes(128)`, "noise 0.1", one of
//! the hard classes of docs/performance.md) and the 512 px sample level, with the same
//! binary in one run, and prints the README's table:
//!
//! ```text
//! cargo build --release --bins --examples && target/release/examples/density_table [--bin PATH] [--rounds N]
//! ```
//!
//! Each round bakes every level at every density once, in order, so that
//! the load of the machine falls on all densities alike; the table gives
//! the round with the least CPU time (user + system of the bake process,
//! less sensitive to the load than wall time). The load average is printed
//! before and after.
//! Density `N >= 2` averages 2 x 2 quadrature points per texel by default,
//! so its baked level has `(2N)^2` points per painted pixel: the table gives
//! seconds per million texels and per million quadrature points.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

const DENSITIES: [(&str, f64, usize); 5] = [
    // (flag, texels per pixel, quadrature points per painted pixel side)
    ("1/4", 0.25, 1),
    ("1/2", 0.5, 1),
    ("1", 1.0, 1),
    ("2", 2.0, 4),
    ("4", 4.0, 8),
];

/// CPU seconds (user + system) of this process's waited-for children, from
/// `/proc/self/stat` (clock ticks of 1/100 s): less sensitive to the load
/// than wall time.
fn children_cpu() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // Fields after the command name in parentheses; cutime and cstime are
    // fields 16 and 17 of the whole line.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = rest
        .split_whitespace()
        .map(|x| x.parse().unwrap_or(0.0))
        .collect();
    if f.len() > 14 {
        (f[13] + f[14]) / 100.0
    } else {
        f64::NAN
    }
}

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".into())
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut bin = std::env::current_exe()?
        .parent()
        .and_then(Path::parent)
        .map(|d| d.join("flatbake"))
        .unwrap_or_else(|| PathBuf::from("flatbake"));
    let mut rounds = 1;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--bin" => bin = PathBuf::from(it.next().ok_or_else(|| anyhow::anyhow!("--bin PATH"))?),
            "--rounds" => {
                rounds = it
                    .next()
                    .ok_or_else(|| anyhow::anyhow!("--rounds N"))?
                    .parse()?
            }
            other => anyhow::bail!("unknown argument {other}"),
        }
    }
    let tmp = tempfile::tempdir()?;
    let class = flatbake_synth::small_classes(128)
        .into_iter()
        .find(|c| c.label == "noise 0.1")
        .ok_or_else(|| anyhow::anyhow!("no noise class"))?;
    class.level.save(tmp.path())?;
    let synth_png = tmp.path().join(format!("{}.png", class.level.name));
    // The small hard class first: its table is complete early.
    let levels = [
        (class.level.name.as_str(), synth_png),
        ("big_level", PathBuf::from("levels/big_level.png")),
    ];
    let before = load();
    // best[level][density] = (CPU s, wall s, gather s, texels, points)
    let mut best =
        vec![vec![(f64::INFINITY, 0.0, 0.0, 0usize, 0usize); DENSITIES.len()]; levels.len()];
    for _ in 0..rounds {
        for (li, (name, png)) in levels.iter().enumerate() {
            for (di, (flag, _, _)) in DENSITIES.iter().enumerate() {
                let out = tmp.path().join(format!("out-{li}-{di}"));
                let t = Instant::now();
                let cpu0 = children_cpu();
                let st = Command::new(&bin)
                    .args([
                        "bake",
                        "--force",
                        "--quiet",
                        "--texels-per-pixel",
                        flag,
                        "-o",
                    ])
                    .arg(&out)
                    .arg(png)
                    .status()?;
                let wall = t.elapsed().as_secs_f64();
                let cpu = children_cpu() - cpu0;
                anyhow::ensure!(st.success(), "{name} at {flag}: {st}");
                let stem = png.file_stem().unwrap().to_string_lossy();
                let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(
                    out.join(format!("{stem}.report.json")),
                )?)?;
                let size = &report["size"];
                let texels =
                    size[0].as_u64().unwrap_or(0) as usize * size[1].as_u64().unwrap_or(0) as usize;
                let points = report["counts"]["floor_pixels"].as_u64().unwrap_or(0) as usize;
                let gather = report["timings"]["gather"].as_f64().unwrap_or(0.0);
                if cpu < best[li][di].0 {
                    best[li][di] = (cpu, wall, gather, texels, points);
                }
                eprintln!("{name} {flag}: {cpu:.2} CPU s, {wall:.2} s");
            }
        }
    }
    let after = load();
    println!("load average before {before}, after {after}; {rounds} round(s), fastest shown\n");
    println!(
        "| level | texels per pixel | texels | floor points | CPU s | wall s | gather s | CPU s / M points | CPU / density 1 | points / density 1 |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (li, (name, _)) in levels.iter().enumerate() {
        let (one, one_points) = (best[li][2].0, best[li][2].4);
        for (di, (flag, _, _)) in DENSITIES.iter().enumerate() {
            let (cpu, wall, gather, texels, points) = best[li][di];
            println!(
                "| {name} | {flag} | {texels} | {points} | {cpu:.2} | {wall:.2} | {gather:.2} | {:.2} | {:.2} | {:.2} |",
                cpu / points.max(1) as f64 * 1e6,
                cpu / one,
                points as f64 / one_points.max(1) as f64
            );
        }
    }
    Ok(())
}
