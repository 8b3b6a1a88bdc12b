//! The README's picture of texel density: one region of a sample level,
//! lit, at one texel per pixel and at four, side by side, each shown at the
//! same size with every texel a square (nearest-neighbour), so the blocky
//! light and shadow edges of density 1 and the smooth ones of density 4 can
//! be compared.
//!
//! ```text
//! cargo run --release --example density_pictures -- [LEVEL.png X Y W H OUT.png]
//! ```
//!
//! Defaults: `levels/pillars.png`, the region at (8, 8) of 48 x 36 painted
//! pixels, written to `assets/texel_density.png`.

use std::path::Path;

use flatbake_core::bake::texels::{Density, TexelOptions, Walls, bake_texels};
use flatbake_core::output::{OutputOptions, lit_image};
use flatbake_core::{LoadLimits, Palette, Quality, Settings, load_level};
use image::imageops::{self, FilterType};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (path, x, y, w, h, out) = match args.as_slice() {
        [] => (
            "levels/pillars.png".to_string(),
            8,
            8,
            48,
            36,
            "assets/texel_density.png".to_string(),
        ),
        [p, x, y, w, h, o] => (
            p.clone(),
            x.parse()?,
            y.parse()?,
            w.parse()?,
            h.parse()?,
            o.clone(),
        ),
        _ => anyhow::bail!("usage: density_pictures [LEVEL.png X Y W H OUT.png]"),
    };
    let path = Path::new(&path);
    let palette = Palette::resolve_for_level(path, None)?;
    let level = load_level(path, &palette, LoadLimits::default())?;
    let mut settings = Settings::new(Quality::Normal);
    settings.falloff = palette.settings.falloff;
    let exposure = palette.settings.exposure.unwrap_or(1.0);
    // Shown at 8 screen pixels per painted pixel.
    let screen = 8u32;
    let mut tiles = Vec::new();
    for n in [1u32, 4] {
        let t = bake_texels(
            &level,
            &settings,
            &TexelOptions {
                density: Density::Up(n),
                samples: None,
                walls: Walls::Lit,
            },
            &|_| {},
            &|_| {},
        )?;
        let opts = OutputOptions {
            exposure,
            ..OutputOptions::default()
        };
        let img = lit_image(&t.level, &t.baked.lightmap, &opts)?.to_rgba8();
        let crop = imageops::crop_imm(&img, x * n, y * n, w * n, h * n).to_image();
        tiles.push(imageops::resize(
            &crop,
            w * screen,
            h * screen,
            FilterType::Nearest,
        ));
    }
    let gap = 8;
    let mut m = image::RgbaImage::from_pixel(
        2 * w * screen + gap,
        h * screen,
        image::Rgba([255, 255, 255, 255]),
    );
    imageops::overlay(&mut m, &tiles[0], 0, 0);
    imageops::overlay(&mut m, &tiles[1], (w * screen + gap) as i64, 0);
    m.save(&out)?;
    println!("wrote {out} ({}x{})", m.width(), m.height());
    Ok(())
}
