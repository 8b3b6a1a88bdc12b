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

use crate::bake::{self, Settings};
use crate::level::{self, Cell, Level, LoadLimits};
use crate::output::write_atomic;
use crate::palette::Palette;
use crate::quality::{Knobs, Quality};
use crate::report::Timings;

/// Largest relative RMS change allowed between `reference` and its refinement.
pub const REFERENCE_TOLERANCE: f64 = 5e-4;

/// One measured setting of one level.
#[derive(Clone, Debug)]
pub struct Row {
    pub level: String,
    /// A preset name, or `step` for an in-between setting.
    pub quality: String,
    pub knobs: Knobs,
    pub seconds: f64,
    pub timings: Timings,
    pub patches: usize,
    /// Relative RMS error over floor pixels and channels against `reference`.
    pub rel_rmse: f64,
    /// Largest absolute error over floor pixels and channels.
    pub max_err: f64,
}

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
    level: &Level,
    palette: &Palette,
    quality: Quality,
    knobs: Knobs,
) -> Result<(bake::Baked, f64), String> {
    let mut s = Settings::new(quality);
    s.knobs = knobs;
    s.falloff = palette.settings.falloff;
    s.bounces = palette.settings.bounces;
    let t = Instant::now();
    let b = bake::bake(level, &s, &|_| {}).map_err(|e| format!("{}: {e}", level.name))?;
    Ok((b, t.elapsed().as_secs_f64()))
}

/// Sweeps one level; returns its rows and the reference convergence check
/// (relative RMS change when the reference is refined).
pub fn sweep_level(path: &Path, progress: &dyn Fn(&str)) -> Result<(Vec<Row>, f64), String> {
    let palette = Palette::resolve_for_level(path, None).map_err(|e| e.to_string())?;
    let level =
        level::load_level(path, &palette, LoadLimits::default()).map_err(|e| e.to_string())?;
    let ladder = settings_ladder();
    let mut baked = Vec::new();
    for (name, knobs) in &ladder {
        progress(&format!(
            "{}: {name} (patch {}, quad {})",
            level.name, knobs.patch_len, knobs.quad
        ));
        let quality = preset_of(name).unwrap_or(Quality::Reference);
        let (b, secs) = bake_with(&level, &palette, quality, *knobs)?;
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
    let (fine, _) = bake_with(&level, &palette, Quality::Reference, finer)?;
    let (check, _) = compare(&level, reference, &fine.lightmap.rgb);
    Ok((rows, check))
}

fn preset_of(name: &str) -> Option<Quality> {
    Quality::ALL.into_iter().find(|q| q.name() == name)
}

/// Runs a sweep over `levels` and writes the three outputs into `dir`.
pub fn run(
    levels: &[PathBuf],
    dir: &Path,
    progress: &dyn Fn(&str),
) -> Result<Vec<(String, Vec<Row>, f64)>, String> {
    crate::output::ensure_output_dir(dir).map_err(|e| e.to_string())?;
    let mut all = Vec::new();
    let mut failures = Vec::new();
    for path in crate::batch::collect_levels(levels) {
        match sweep_level(&path, progress) {
            Ok((rows, check)) => all.push((rows[0].level.clone(), rows, check)),
            Err(e) => failures.push(e),
        }
    }
    let write = |name: &str, bytes: &[u8]| {
        write_atomic(&dir.join(name), bytes)
            .map_err(|e| format!("cannot write {}: {e}", dir.join(name).display()))
    };
    write("accuracy.csv", csv(&all).as_bytes())?;
    write("accuracy.md", markdown(&all).as_bytes())?;
    write("accuracy.png", &plot(&all)?)?;
    if failures.is_empty() {
        Ok(all)
    } else {
        Err(failures.join("\n"))
    }
}

/// The rows as CSV (`level,quality,seconds,rel_rmse,max_err` first).
pub fn csv(all: &[(String, Vec<Row>, f64)]) -> String {
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
pub fn markdown(all: &[(String, Vec<Row>, f64)]) -> String {
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

/// Error against time, log-log, one line per level, presets labelled.
pub fn plot(all: &[(String, Vec<Row>, f64)]) -> Result<Vec<u8>, String> {
    use plotters::prelude::*;
    static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSansMono.ttf");
    // Registering twice is harmless; the first registration wins.
    let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    let (w, h) = (960u32, 640u32);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let pts: Vec<(f64, f64)> = all
            .iter()
            .flat_map(|(_, rows, _)| rows.iter())
            .filter(|r| r.rel_rmse > 0.0)
            .map(|r| (r.seconds, r.rel_rmse))
            .collect();
        let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
        for &(x, y) in &pts {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        if pts.is_empty() {
            (x0, x1, y0, y1) = (1e-3, 1.0, 1e-4, 1e-1);
        }
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Error against time (each level's reference preset is the yardstick)",
                ("sans-serif", 20),
            )
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d(
                (x0 / 1.5..x1 * 1.5).log_scale(),
                (y0 / 2.0..y1 * 2.0).log_scale(),
            )
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("seconds (whole bake)")
            .y_desc("relative RMS error")
            .y_label_formatter(&|v| format!("{:.1e}", v))
            .x_label_formatter(&|v| format!("{:.2}", v))
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(|e| e.to_string())?;
        for (i, (level, rows, _)) in all.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let line: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.rel_rmse > 0.0)
                .map(|r| (r.seconds, r.rel_rmse))
                .collect();
            chart
                .draw_series(LineSeries::new(line.clone(), color.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(level.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            chart
                .draw_series(line.iter().map(|&p| Circle::new(p, 4, color.filled())))
                .map_err(|e| e.to_string())?;
            for r in rows
                .iter()
                .filter(|r| r.rel_rmse > 0.0 && r.quality != "step")
            {
                chart
                    .draw_series(std::iter::once(Text::new(
                        r.quality.clone(),
                        (r.seconds, r.rel_rmse),
                        ("sans-serif", 13).into_font().color(&BLACK),
                    )))
                    .map_err(|e| e.to_string())?;
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    let img = image::RgbImage::from_raw(w, h, buf).ok_or("plot buffer has the wrong size")?;
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| e.to_string())?;
    Ok(bytes)
}
