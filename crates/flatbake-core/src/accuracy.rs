//! The price of accuracy: `flatbake sweep` bakes levels at every quality
//! preset and at steps of the main knob in between, times each stage, and
//! measures the error against the `reference` preset.
//!
//! It writes `accuracy.csv` (one row per level and setting), `accuracy.md`
//! (the same as tables) and `accuracy.png` (error against time, log-log, one
//! line per level). It also checks that `reference` is converged: halving its
//! patch length and doubling its quadrature changes the result by less than
//! [`REFERENCE_TOLERANCE`].

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::bake::report::Timings;
use crate::bake::{self, Settings};
use crate::error::{Error, Result};
use crate::level::palette::Palette;
use crate::level::{self, Cell, Level, LoadLimits};
use crate::output::write_file_atomic;
use crate::quality::{Knobs, Quality};

/// Largest relative RMS change allowed between `reference` and its refinement.
pub const REFERENCE_TOLERANCE: f64 = 5e-4;

/// One measured setting of one level.
#[derive(Clone, Debug)]
pub struct Row {
    /// The level's name.
    pub level: String,
    /// A preset name, or `step` for an in-between setting.
    pub quality: String,
    /// The discretisation baked with.
    pub knobs: Knobs,
    /// Seconds of the whole bake.
    pub seconds: f64,
    /// Seconds per stage.
    pub timings: Timings,
    /// Patches of the bake.
    pub patches: usize,
    /// Relative RMS error over floor pixels and channels against `reference`.
    pub rel_rmse: f64,
    /// Largest absolute error over floor pixels and channels.
    pub max_err: f64,
}

/// One level's sweep: its name, a row per setting, and the reference check.
pub type LevelRows = (String, Vec<Row>, f64);

/// The settings a sweep bakes, from cheapest to `reference` (last).
pub fn settings_ladder() -> Vec<(String, Knobs)> {
    let k = |q: Quality| q.knobs();
    let step = |patch_len: f64, quad: usize, base: Quality| Knobs {
        patch_len,
        quad,
        ..base.knobs()
    };
    vec![
        ("draft".into(), k(Quality::Draft)),
        ("step".into(), step(6.0, 2, Quality::Draft)),
        ("normal".into(), k(Quality::Normal)),
        ("step".into(), step(3.0, 3, Quality::Normal)),
        ("high".into(), k(Quality::High)),
        ("step".into(), step(1.0, 4, Quality::High)),
        ("reference".into(), k(Quality::Reference)),
    ]
}

/// Relative RMS and max absolute difference of `a` against `reference`,
/// over floor pixels and all channels.
pub fn compare(level: &Level, a: &[[f32; 3]], reference: &[[f32; 3]]) -> (f64, f64) {
    let (mut num, mut den, mut max) = (0.0, 0.0, 0.0f64);
    for (i, c) in level.cells.iter().enumerate() {
        if *c != Cell::Floor {
            continue;
        }
        for k in 0..3 {
            let (x, r) = (a[i][k] as f64, reference[i][k] as f64);
            num += (x - r) * (x - r);
            den += r * r;
            max = max.max((x - r).abs());
        }
    }
    if den == 0.0 {
        (if num == 0.0 { 0.0 } else { f64::INFINITY }, max)
    } else {
        ((num / den).sqrt(), max)
    }
}

fn bake_with(
    path: &Path,
    level: &Level,
    palette: &Palette,
    quality: Quality,
    knobs: Knobs,
) -> Result<(bake::Baked, f64)> {
    let mut s = Settings::new(quality);
    s.knobs = knobs;
    s.falloff = palette.settings.falloff;
    s.bounces = palette.settings.bounces;
    let t = Instant::now();
    let b = bake::bake(level, &s, &|_| {}).map_err(|source| Error::Bake {
        path: path.to_path_buf(),
        source,
    })?;
    Ok((b, t.elapsed().as_secs_f64()))
}

/// Sweeps one level; returns its rows and the reference convergence check
/// (relative RMS change when the reference is refined).
pub fn sweep_level(path: &Path, progress: &dyn Fn(&str)) -> Result<(Vec<Row>, f64)> {
    let palette = Palette::resolve_for_level(path, None)?;
    let level = level::load_level(path, &palette, LoadLimits::default())?;
    let ladder = settings_ladder();
    let mut baked = Vec::new();
    for (name, knobs) in &ladder {
        progress(&format!(
            "{}: {name} (patch {}, quad {})",
            level.name, knobs.patch_len, knobs.quad
        ));
        let quality = preset_of(name).unwrap_or(Quality::Reference);
        let (b, secs) = bake_with(path, &level, &palette, quality, *knobs)?;
        baked.push((name.clone(), *knobs, b, secs));
    }
    let reference = &baked
        .last()
        .expect("the ladder ends with reference")
        .2
        .lightmap
        .rgb;
    let rows = baked
        .iter()
        .map(|(name, knobs, b, secs)| {
            let (rel_rmse, max_err) = compare(&level, &b.lightmap.rgb, reference);
            Row {
                level: level.name.clone(),
                quality: name.clone(),
                knobs: *knobs,
                seconds: *secs,
                timings: b.report.timings.clone(),
                patches: b.report.counts.patches,
                rel_rmse,
                max_err,
            }
        })
        .collect();
    progress(&format!("{}: refined reference", level.name));
    let r = Quality::Reference.knobs();
    let finer = Knobs {
        patch_len: r.patch_len / 2.0,
        quad: (2 * r.quad).min(8),
        ..r
    };
    let (fine, _) = bake_with(path, &level, &palette, Quality::Reference, finer)?;
    let (check, _) = compare(&level, reference, &fine.lightmap.rgb);
    Ok((rows, check))
}

fn preset_of(name: &str) -> Option<Quality> {
    Quality::ALL.into_iter().find(|q| q.name() == name)
}

/// Sweeps every level of `levels` (files or folders); returns the levels
/// swept and the errors of those that could not be.
pub fn run(levels: &[PathBuf], progress: &dyn Fn(&str)) -> (Vec<LevelRows>, Vec<Error>) {
    let mut all = Vec::new();
    let mut failures = Vec::new();
    for path in crate::batch::collect_levels(levels) {
        match sweep_level(&path, progress) {
            Ok((rows, check)) => all.push((rows[0].level.clone(), rows, check)),
            Err(e) => failures.push(e),
        }
    }
    (all, failures)
}

/// Writes `accuracy.csv` and `accuracy.md` into `dir` (created if missing).
pub fn write_tables(dir: &Path, all: &[LevelRows]) -> Result<()> {
    crate::output::ensure_output_dir(dir)?;
    for (name, text) in [("accuracy.csv", csv(all)), ("accuracy.md", markdown(all))] {
        write_file_atomic(&dir.join(name), text.as_bytes())?;
    }
    Ok(())
}

/// The rows as CSV (`level,quality,seconds,rel_rmse,max_err` first).
pub fn csv(all: &[LevelRows]) -> String {
    let mut s = String::from(
        "level,quality,seconds,rel_rmse,max_err,patch_len,quad,patches,geometry_s,form_factors_s,solve_s,gather_s\n",
    );
    for (_, rows, _) in all {
        for r in rows {
            let _ = writeln!(
                s,
                "{},{},{:.4},{:.4e},{:.4e},{},{},{},{:.4},{:.4},{:.4},{:.4}",
                r.level,
                r.quality,
                r.seconds,
                r.rel_rmse,
                r.max_err,
                r.knobs.patch_len,
                r.knobs.quad,
                r.patches,
                r.timings.geometry,
                r.timings.form_factors,
                r.timings.solve,
                r.timings.gather
            );
        }
    }
    s
}

/// The rows as Markdown tables, one per level.
pub fn markdown(all: &[LevelRows]) -> String {
    let mut s = String::from(
        "# The price of accuracy\n\nError against the `reference` preset over floor pixels (all channels); time is the whole bake of the level on this machine.\n\n",
    );
    // One summary row per level: error and time of each preset.
    let _ = writeln!(
        s,
        "| level | draft | normal | high | reference | reference check |\n|---|---:|---:|---:|---:|---:|"
    );
    for (level, rows, check) in all {
        let cell = |q: Quality| {
            rows.iter()
                .find(|r| r.quality == q.name())
                .map_or_else(String::new, |r| {
                    if q == Quality::Reference {
                        format!("{:.2} s", r.seconds)
                    } else {
                        format!("{:.3}% in {:.2} s", 100.0 * r.rel_rmse, r.seconds)
                    }
                })
        };
        let _ = writeln!(
            s,
            "| {level} | {} | {} | {} | {} | {:.4}% |",
            cell(Quality::Draft),
            cell(Quality::Normal),
            cell(Quality::High),
            cell(Quality::Reference),
            100.0 * check
        );
    }
    let _ = writeln!(
        s,
        "\nCells: relative RMS error against `reference` and the whole bake time. Reference check: the change when `reference` is refined (halved patch length, doubled quadrature).\n"
    );
    for (level, rows, check) in all {
        let _ = writeln!(s, "## {level}\n");
        let _ = writeln!(
            s,
            "| quality | patch | quad | patches | seconds | rel. RMS error | max error |"
        );
        let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|");
        for r in rows {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {:.3} | {:.3}% | {:.2e} |",
                r.quality,
                r.knobs.patch_len,
                r.knobs.quad,
                r.patches,
                r.seconds,
                100.0 * r.rel_rmse,
                r.max_err
            );
        }
        let _ = writeln!(
            s,
            "\nReference check: halving the patch length and doubling the quadrature changes `reference` by {:.4}% (limit {:.2}%).\n",
            100.0 * check,
            100.0 * REFERENCE_TOLERANCE
        );
    }
    s
}
