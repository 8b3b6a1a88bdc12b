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
