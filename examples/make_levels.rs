//! Regenerates the sample levels in `levels/` (or the folder given):
//!
//! ```text
//! cargo run --release --example make_levels [-- OUT_DIR] [--preview DIR]
//! ```
//!
//! Every level is painted by `flatbake_synth` and written as `NAME.png`
//! plus `NAME.palette.toml`. With `--preview DIR` each level is also baked at
//! draft quality into DIR, to check exposure after changing a generator.

use std::path::PathBuf;

use flatbake_synth::{self as synth, Painted};

/// The sample set: small enough that the whole folder bakes at several
/// qualities in a few minutes on two cores, varied enough to show every
/// effect the README talks about.
/// `level` with `[bake] exposure = x` in its palette: the sample levels whose
/// bright lamps would clip more than a tenth of the floor at exposure 1 (and
/// so warn on a newcomer's first bake) are shipped darker.
fn exposed(mut level: Painted, x: f64) -> Painted {
    assert!(
        !level.palette_toml.contains("[bake]"),
        "{}: one [bake] table",
        level.name
    );
    level.palette_toml += &format!("\n[bake]\nexposure = {x}\n");
    level
}

fn samples() -> Vec<Painted> {
    vec![
        exposed(synth::cornell(96), 0.8),
        exposed(synth::colour_bleed(128), 0.7),
        exposed(synth::dungeon(192, 160, 7), 0.8),
        exposed(synth::maze(128, 128, 3, 11), 0.8),
        synth::pillars(160, 70, 5),
        synth::falloff_hall(256, 64),
        synth::big_level(512, 2014),
    ]
}

fn main() -> anyhow::Result<()> {
    let mut out = PathBuf::from("levels");
    let mut preview: Option<PathBuf> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--preview" => {
                preview = Some(
                    args.next()
                        .ok_or_else(|| anyhow::anyhow!("--preview needs a folder"))?
                        .into(),
                )
            }
            "-h" | "--help" => {
                println!("usage: make_levels [OUT_DIR] [--preview DIR]");
                return Ok(());
            }
            _ => out = PathBuf::from(a),
        }
    }
    for level in samples() {
        level.save(&out)?;
        println!(
            "{:>14}  {}x{}  -> {}",
            level.name,
            level.width,
            level.height,
            out.display()
        );
        if let Some(dir) = &preview {
            preview_bake(&level, dir)?;
        }
    }
    Ok(())
}

/// Bakes `level` at draft quality and writes its lightmap and lit view.
fn preview_bake(level: &Painted, dir: &std::path::Path) -> anyhow::Result<()> {
    use flatbake_core::bake::{Settings, bake};
    use flatbake_core::level::Level;
    use flatbake_core::level::palette::Palette;
    use flatbake_core::output::{OutputOptions, encode_images, write_files};
    use flatbake_core::quality::Quality;

    std::fs::create_dir_all(dir)?;
    let path = dir.join(format!("{}.palette.toml", level.name));
    let palette = Palette::parse(&level.palette_toml, &path)?;
    let lv = Level::from_rgba(
        &level.name,
        level.width,
        level.height,
        &level.rgba,
        &palette,
    );
    let mut settings = Settings::new(Quality::Draft);
    settings.falloff = palette.settings.falloff;
    let t = std::time::Instant::now();
    let baked = bake(&lv, &settings, &|_| {})?;
    let images = encode_images(&lv, &baked.lightmap, &OutputOptions::default())?;
    let written = write_files(dir, &lv.name, &images)?;
    contact_sheet(
        level,
        &written,
        &dir.join(format!("{}.sheet.png", level.name)),
    )?;
    let floor: Vec<f32> = lv
        .cells
        .iter()
        .zip(&baked.lightmap.rgb)
        .filter(|(c, _)| **c == flatbake_core::level::Cell::Floor)
        .map(|(_, v)| (v[0] + v[1] + v[2]) / 3.0)
        .collect();
    let mut sorted = floor.clone();
    sorted.sort_by(f32::total_cmp);
    let q = |f: f64| {
        sorted
            .get(((sorted.len() as f64 - 1.0) * f) as usize)
            .copied()
            .unwrap_or(0.0)
    };
    println!(
        "{:>14}  baked in {:.2}s; floor light p10 {:.3} median {:.3} p90 {:.3} max {:.3}; warnings {:?}",
        level.name,
        t.elapsed().as_secs_f64(),
        q(0.1),
        q(0.5),
        q(0.9),
        q(1.0),
        baked.report.warnings
    );
    Ok(())
}

/// The painted level beside its baked images, scaled up (nearest neighbour)
/// to about 1200 px wide so small levels can be judged by eye.
fn contact_sheet(level: &Painted, baked: &[PathBuf], path: &std::path::Path) -> anyhow::Result<()> {
    let mut tiles = vec![level.to_image()];
    for p in baked {
        tiles.push(image::open(p)?.to_rgba8());
    }
    let (w, h) = (level.width as u32, level.height as u32);
    // Wide levels stack top to bottom, the others side by side.
    let vertical = w > 2 * h;
    let n = tiles.len() as u32;
    let gap = 4;
    let scale = if vertical {
        1200 / (w + gap)
    } else {
        1200 / ((w + gap) * n)
    }
    .clamp(1, 8);
    let (sw, sh) = if vertical {
        (w * scale, (h * scale + gap) * n)
    } else {
        ((w * scale + gap) * n, h * scale)
    };
    let mut sheet = image::RgbaImage::from_pixel(sw, sh, image::Rgba([40, 40, 40, 255]));
    for (i, t) in tiles.iter().enumerate() {
        let big = image::imageops::resize(
            t,
            w * scale,
            h * scale,
            image::imageops::FilterType::Nearest,
        );
        let i = i as u32;
        let (x, y) = if vertical {
            (0, i * (h * scale + gap))
        } else {
            (i * (w * scale + gap), 0)
        };
        image::imageops::overlay(&mut sheet, &big, x as i64, y as i64);
    }
    sheet.save(path)?;
    Ok(())
}
