//! The before/after picture of the README's "Directional lightmaps and
//! normal maps": a level painted here, with a procedural normal map of
//! bevelled floor bricks and round studs (`NAME.normals.png`, RGB =
//! n * 0.5 + 0.5, green up), baked with `--directional`; the picture puts
//! the plain lit image (a plain lightmap cannot respond to the normal map)
//! beside `NAME.lit-normals.png`, both scaled up 3x.
//!
//! `cargo run --release --example normal_map_demo -- [OUT_DIR] [PICTURE]`
//! (defaults `target/normal-map-demo` and `assets/directional-before-after.png`).

use std::path::PathBuf;

use flatbake_core::batch::{self, BatchOptions, LevelOutcome, Silent};
use flatbake_core::quality::Quality;
use image::{Rgb, RgbImage, Rgba, RgbaImage};

const W: u32 = 160;
const H: u32 = 96;

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "target/normal-map-demo".into()),
    );
    let picture = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "assets/directional-before-after.png".into()),
    );
    let levels = dir.join("levels");
    let out = dir.join("out");
    std::fs::create_dir_all(&levels).map_err(|e| e.to_string())?;
    level()
        .save(levels.join("bricks.png"))
        .map_err(|e| e.to_string())?;
    normals()
        .save(levels.join("bricks.normals.png"))
        .map_err(|e| e.to_string())?;
    std::fs::write(
        levels.join("bricks.palette.toml"),
        "[[wall]]\ncolor = \"#5a5a5a\"\nreflectance = 0.5\n\n\
         [[emitter]]\ncolor = \"#ffd9a0\"\nemission = [3.0, 2.2, 1.2]\n\n\
         [[emitter]]\ncolor = \"#a0c8ff\"\nemission = [0.9, 1.5, 3.0]\n",
    )
    .map_err(|e| e.to_string())?;
    let opts = BatchOptions {
        out_dir: out.clone(),
        quality: Quality::Normal,
        directional: true,
        force: true,
        ..BatchOptions::default()
    };
    for o in batch::run(&[levels.join("bricks.png")], &opts, &Silent) {
        if let LevelOutcome::Failed { error, .. } = o {
            return Err(error.to_string());
        }
    }
    let read = |n: &str| {
        image::open(out.join(n))
            .map(|i| i.into_rgba8())
            .map_err(|e| format!("{n}: {e}"))
    };
    let (plain, lit) = (read("bricks.lit.png")?, read("bricks.lit-normals.png")?);
    let s = 3;
    let gap = 6;
    let mut pic = RgbaImage::from_pixel(2 * W * s + gap, H * s, Rgba([255, 255, 255, 255]));
    for (i, img) in [plain, lit].iter().enumerate() {
        let x0 = i as u32 * (W * s + gap);
        for y in 0..H * s {
            for x in 0..W * s {
                pic.put_pixel(x0 + x, y, *img.get_pixel(x / s, y / s));
            }
        }
    }
    if let Some(p) = picture.parent() {
        std::fs::create_dir_all(p).map_err(|e| e.to_string())?;
    }
    pic.save(&picture).map_err(|e| e.to_string())?;
    println!("wrote {}", picture.display());
    Ok(())
}

fn is_wall(x: u32, y: u32) -> bool {
    let border = x == 0 || y == 0 || x == W - 1 || y == H - 1;
    // Two pillars and a low wall.
    let pillar = |cx: u32, cy: u32| x.abs_diff(cx) <= 4 && y.abs_diff(cy) <= 4;
    border || pillar(56, 34) || pillar(108, 62) || (x == 80 && (60..H).contains(&y))
}

/// The level: walls, a warm light on the left wall, a cool one at the top
/// right, floor everywhere else.
fn level() -> RgbImage {
    RgbImage::from_fn(W, H, |x, y| {
        if x == 0 && (36..60).contains(&y) {
            Rgb([0xff, 0xd9, 0xa0])
        } else if y == 0 && (118..142).contains(&x) {
            Rgb([0xa0, 0xc8, 0xff])
        } else if is_wall(x, y) {
            Rgb([0x5a, 0x5a, 0x5a])
        } else {
            Rgb([190, 180, 165])
        }
    })
}

/// Floor bricks of 16 x 8 pixels, every other row shifted by half a brick,
/// with 2-pixel bevels at 50 degrees, and round studs (hemispheres of
/// radius 5) in a grid; flat elsewhere.
fn normals() -> RgbImage {
    RgbImage::from_fn(W, H, |x, y| {
        let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
        let mut n = [0.0, 0.0, 1.0];
        // Studs.
        let (cx, cy) = (
            (px / 32.0).floor() * 32.0 + 16.0,
            (py / 32.0).floor() * 32.0 + 16.0,
        );
        let (dx, dy) = (px - cx, py - cy);
        let r2 = dx * dx + dy * dy;
        if r2 < 25.0 {
            // +y up: image rows go down.
            n = [dx / 5.0, -dy / 5.0, (1.0 - r2 / 25.0).sqrt()];
        } else {
            let row = (py / 8.0).floor();
            let shift = if row as i64 % 2 == 0 { 0.0 } else { 8.0 };
            let u = (px + shift).rem_euclid(16.0);
            let v = py.rem_euclid(8.0);
            let tilt = 50f64.to_radians();
            let (s, c) = (tilt.sin(), tilt.cos());
            if u < 2.0 {
                n = [-s, 0.0, c];
            } else if u > 14.0 {
                n = [s, 0.0, c];
            } else if v < 2.0 {
                n = [0.0, s, c];
            } else if v > 6.0 {
                n = [0.0, -s, c];
            }
        }
        if is_wall(x, y) {
            n = [0.0, 0.0, 1.0];
        }
        Rgb(n.map(|c| ((c * 0.5 + 0.5) * 255.0).round().clamp(0.0, 255.0) as u8))
    })
}
