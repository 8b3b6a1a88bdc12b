//! The sweep's plot: error against time, drawn with plotters.

use flatbake_core::accuracy::LevelRows;

/// Error against time, log-log, one line per level, presets labelled.
pub fn plot(all: &[LevelRows]) -> Result<Vec<u8>, String> {
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
        let (xlo, xhi) = (x0 / 1.5, x1 * 1.5);
        // Plotters labels 1, 2, ..., 9, 10 within a decade, which overlap
        // where the decade is narrow; the labels are chosen here instead.
        let ticks = log_ticks(xlo, xhi, f64::from(w - X_AXIS_MARGIN));
        let light: Vec<f64> = light_points(xlo, xhi);
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Error against time (each level's reference preset is the yardstick)",
                ("sans-serif", 20),
            )
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d(
                (xlo..xhi)
                    .log_scale()
                    .with_key_points(ticks.clone())
                    .with_light_points(light),
                (y0 / 2.0..y1 * 2.0).log_scale(),
            )
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("seconds (whole bake)")
            .y_desc("relative RMS error")
            .y_label_formatter(&|v| format!("{:.1e}", v))
            .x_label_formatter(&|v| tick_label(*v))
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

/// Pixels of the plot's width that are not the x axis (margins and the y
/// labels), for spacing the x labels.
const X_AXIS_MARGIN: u32 = 2 * 16 + 70;
/// Width of one label character in pixels (DejaVu Sans Mono at 14 px).
const LABEL_CHAR_PX: f64 = 8.5;
/// Least free space between two neighbouring x labels, in pixels.
const LABEL_GAP_PX: f64 = 12.0;

/// A tick value as its label: as few digits as it needs (`0.005`, `0.2`,
/// `3`, `20`), so that neighbouring ticks never read the same.
fn tick_label(v: f64) -> String {
    // Three significant digits, trailing zeros dropped (ticks have at most two).
    let decimals = (2 - v.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// The x tick values of a log axis from `lo` to `hi` that is `width_px`
/// wide: the densest of 1-1.5-2-2.5-3..9, 1..9, 1-2-5, 1-3, 1 per decade, then every 2nd,
/// 4th, ... decade, whose labels all fit side by side without touching.
fn log_ticks(lo: f64, hi: f64, width_px: f64) -> Vec<f64> {
    if !(lo > 0.0 && hi > lo && width_px > 0.0) {
        return Vec::new();
    }
    let span = (hi / lo).log10();
    let px = |v: f64| width_px * (v / lo).log10() / span;
    let fits = |ticks: &[f64]| {
        ticks.windows(2).all(|p| {
            let half = |v: f64| tick_label(v).chars().count() as f64 * LABEL_CHAR_PX / 2.0;
            px(p[1]) - px(p[0]) >= half(p[0]) + half(p[1]) + LABEL_GAP_PX
        })
    };
    let (d0, d1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let with = |mantissas: &[f64], every: i32| -> Vec<f64> {
        (d0..=d1)
            .filter(|d| d.rem_euclid(every) == 0)
            .flat_map(|d| mantissas.iter().map(move |m| m * 10f64.powi(d)))
            .filter(|&v| v >= lo && v <= hi)
            .collect()
    };
    let finest = [1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0];
    let all: Vec<f64> = (1..=9).map(f64::from).collect();
    for mantissas in [&finest[..], &all[..], &[1.0, 2.0, 5.0], &[1.0, 3.0], &[1.0]] {
        let t = with(mantissas, 1);
        if fits(&t) {
            return t;
        }
    }
    let mut every = 2;
    loop {
        let t = with(&[1.0], every);
        if fits(&t) || t.len() <= 1 {
            return t;
        }
        every *= 2;
    }
}

/// The faint grid lines: every 1..9 of each decade in range.
fn light_points(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo > 0.0 && hi > lo) {
        return Vec::new();
    }
    let (d0, d1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    (d0..=d1)
        .flat_map(|d| (1..=9).map(move |m| f64::from(m) * 10f64.powi(d)))
        .filter(|&v| v >= lo && v <= hi)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whatever the range, neighbouring x labels leave room between them,
    /// read differently, and there are at least two when the range spans
    /// a 1-2-5 step.
    #[test]
    fn x_labels_never_overlap_and_never_repeat() {
        let width = 858.0;
        for (lo, hi) in [
            (0.003, 0.4),
            (0.05, 2.0),
            (0.3, 24.0),
            (1.4, 24.0),
            (0.004, 30.0),
            (1e-4, 1e4),
            (0.11, 0.19),
            (0.8, 9.0),
        ] {
            let ticks = log_ticks(lo, hi, width);
            let span = (hi / lo).log10();
            let labels: Vec<String> = ticks.iter().map(|&v| tick_label(v)).collect();
            for (i, p) in ticks.windows(2).enumerate() {
                let gap = width * (p[1] / p[0]).log10() / span;
                let need = (labels[i].len() + labels[i + 1].len()) as f64 * LABEL_CHAR_PX / 2.0;
                assert!(gap >= need, "{lo}..{hi}: {labels:?} overlap");
                assert_ne!(labels[i], labels[i + 1], "{lo}..{hi}: {labels:?}");
            }
            if hi / lo >= 2.5 {
                assert!(ticks.len() >= 2, "{lo}..{hi}: {labels:?}");
            }
        }
    }

    #[test]
    fn labels_use_the_digits_they_need() {
        assert_eq!(tick_label(0.005), "0.005");
        assert_eq!(tick_label(0.2), "0.2");
        assert_eq!(tick_label(0.01), "0.01");
        assert_eq!(tick_label(3.0), "3");
        assert_eq!(tick_label(20.0), "20");
        assert_eq!(tick_label(1.5), "1.5");
        assert_eq!(tick_label(0.25), "0.25");
        assert_eq!(tick_label(3.0 * 10f64.powi(-1)), "0.3");
    }
}
