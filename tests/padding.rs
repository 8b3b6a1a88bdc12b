//! Padded lightmaps (`OutputOptions::padding`): bilinear filtering next to
//! a wall stays within the floor's light, the coverage channel marks the
//! floor exactly, and the padding reaches as far as asked and no further.

mod common;
use common::*;

use flatbake_core::bake::{Settings, bake};
use flatbake_core::level::{Cell, Level};
use flatbake_core::output::{
    Encoded, OutputKind, OutputOptions, encode_images, padded_hdr_pixels, rgbm_decode,
};
use flatbake_core::quality::Quality;

fn quiet(_: &str) {}

/// A lit room in a margin of void: an emitter in the top wall, a pillar
/// that casts a shadow, and a one-pixel partition with a gap.
fn level() -> Level {
    let (w, h, m) = (30usize, 20usize, 4usize);
    let rows: Vec<String> = (0..h)
        .map(|y| {
            (0..w)
                .map(|x| {
                    let inside = x >= m && y >= m && x < w - m && y < h - m;
                    let ring = inside && (x == m || y == m || x == w - m - 1 || y == h - m - 1);
                    if !inside {
                        ' '
                    } else if ring && y == m && (8..12).contains(&x) {
                        'L'
                    } else if ring
                        || ((11..13).contains(&x) && (9..11).contains(&y))
                        || (x == 19 && y < 12)
                    {
                        '#'
                    } else {
                        '.'
                    }
                })
                .collect()
        })
        .collect();
    ascii(&refs(&rows), &[('#', wall(0.5)), ('L', light(4.0, 0.5))])
}

fn floor_mask(lvl: &Level) -> Vec<bool> {
    lvl.cells.iter().map(|c| *c == Cell::Floor).collect()
}

/// Bilinear sample of `v` at continuous texel coordinates (texel centres at
/// integers), clamped to the edge.
fn bilinear(v: &[[f32; 3]], w: usize, h: usize, x: f64, y: f64) -> [f64; 3] {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let at = |xi: f64, yi: f64| {
        let xi = xi.clamp(0.0, (w - 1) as f64) as usize;
        let yi = yi.clamp(0.0, (h - 1) as f64) as usize;
        v[yi * w + xi].map(f64::from)
    };
    let (a, b, c, d) = (
        at(x0, y0),
        at(x0 + 1.0, y0),
        at(x0, y0 + 1.0),
        at(x0 + 1.0, y0 + 1.0),
    );
    [0, 1, 2].map(|k| {
        (1.0 - fy) * ((1.0 - fx) * a[k] + fx * b[k]) + fy * ((1.0 - fx) * c[k] + fx * d[k])
    })
}

/// Samples between every floor texel and each non-floor 8-neighbour (a
/// quarter, half and three quarters of the way) that leave the range of
/// the floor values within 2 texels of that floor texel.
fn bleeding_samples(v: &[[f32; 3]], lvl: &Level) -> usize {
    let (w, h) = (lvl.width, lvl.height);
    let floor = floor_mask(lvl);
    let mut bad = 0;
    for y in 0..h {
        for x in 0..w {
            if !floor[y * w + x] {
                continue;
            }
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for yy in y.saturating_sub(2)..(y + 3).min(h) {
                for xx in x.saturating_sub(2)..(x + 3).min(w) {
                    if floor[yy * w + xx] {
                        for k in 0..3 {
                            lo[k] = lo[k].min(v[yy * w + xx][k] as f64);
                            hi[k] = hi[k].max(v[yy * w + xx][k] as f64);
                        }
                    }
                }
            }
            for (dx, dy) in [
                (-1i64, -1i64),
                (0, -1),
                (1, -1),
                (-1, 0),
                (1, 0),
                (-1, 1),
                (0, 1),
                (1, 1),
            ] {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                    continue;
                }
                if floor[ny as usize * w + nx as usize] {
                    continue;
                }
                for t in [0.25, 0.5, 0.75] {
                    let s = bilinear(v, w, h, x as f64 + t * dx as f64, y as f64 + t * dy as f64);
                    for k in 0..3 {
                        let tol = 1e-6 * hi[k].abs().max(1e-30);
                        if s[k] < lo[k] - tol || s[k] > hi[k] + tol {
                            bad += 1;
                        }
                    }
                }
            }
        }
    }
    bad
}

fn baked() -> (Level, flatbake_core::output::Lightmap) {
    let lvl = level();
    let baked = bake(&lvl, &Settings::new(Quality::Draft), &quiet).expect("bake");
    (lvl, baked.lightmap)
}

#[test]
fn bilinear_next_to_a_wall_stays_within_the_floor_range() {
    let (lvl, map) = baked();
    let padded = padded_hdr_pixels(&lvl, &map, 8).expect("pad");
    assert_eq!(bleeding_samples(&padded, &lvl), 0);
    // The check can fail: without padding the walls hold their radiosity
    // (emitters glow), and that bleeds; so does black.
    let unpadded = padded_hdr_pixels(&lvl, &map, 0).expect("unpadded");
    assert!(bleeding_samples(&unpadded, &lvl) > 0);
    let black: Vec<[f32; 3]> = map
        .rgb
        .iter()
        .zip(&lvl.cells)
        .map(|(v, c)| if *c == Cell::Floor { *v } else { [0.0; 3] })
        .collect();
    assert!(bleeding_samples(&black, &lvl) > 0);
}

#[test]
#[allow(clippy::needless_range_loop)]
fn padding_reaches_its_width_and_no_further() {
    let (lvl, map) = baked();
    let (w, h) = (lvl.width, lvl.height);
    let floor = floor_mask(&lvl);
    for n in [1u32, 2, 3] {
        let p = padded_hdr_pixels(&lvl, &map, n).expect("pad");
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if floor[i] {
                    assert_eq!(p[i], map.rgb[i], "floor texel ({x},{y}) changed");
                    continue;
                }
                // Chebyshev distance to the floor and the floor range within it.
                let mut d = usize::MAX;
                for (j, _) in floor.iter().enumerate().filter(|(_, f)| **f) {
                    let (fx, fy) = (j % w, j / w);
                    d = d.min(fx.abs_diff(x).max(fy.abs_diff(y)));
                }
                if d > n as usize {
                    // Beyond the width: the unpadded value (wall or void).
                    let want = if lvl.cells[i] == Cell::Void {
                        [0.0; 3]
                    } else {
                        map.rgb[i]
                    };
                    assert_eq!(p[i], want, "({x},{y}) is {d} from the floor");
                    continue;
                }
                for k in 0..3 {
                    let near = floor
                        .iter()
                        .enumerate()
                        .filter(|(j, f)| **f && (j % w).abs_diff(x).max((j / w).abs_diff(y)) <= d);
                    let (lo, hi) = near
                        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, u), (j, _)| {
                            (l.min(map.rgb[j][k]), u.max(map.rgb[j][k]))
                        });
                    let tol = 1e-6 * hi.abs();
                    assert!(
                        p[i][k] >= lo - tol && p[i][k] <= hi + tol,
                        "({x},{y}) padded {} outside [{lo}, {hi}]",
                        p[i][k]
                    );
                }
            }
        }
    }
}

fn file(files: &[Encoded], kind: OutputKind) -> &[u8] {
    &files.iter().find(|f| f.kind == kind).expect("output").bytes
}

#[test]
fn coverage_marks_the_floor_exactly_in_png_and_exr() {
    let (lvl, map) = baked();
    let floor = floor_mask(&lvl);
    let opts = OutputOptions {
        hdr: true,
        rgbm: true,
        padding: 8,
        ..OutputOptions::default()
    };
    let files = encode_images(&lvl, &map, &opts).expect("encode");
    let padded = padded_hdr_pixels(&lvl, &map, 8).expect("pad");

    let png = image::load_from_memory(file(&files, OutputKind::Lightmap))
        .expect("png")
        .into_rgba8();
    for (p, f) in png.pixels().zip(&floor) {
        assert_eq!(p.0[3], if *f { 255 } else { 0 });
    }
    let exr = image::load_from_memory_with_format(
        file(&files, OutputKind::Hdr),
        image::ImageFormat::OpenExr,
    )
    .expect("exr")
    .into_rgba32f();
    for ((p, f), want) in exr.pixels().zip(&floor).zip(&padded) {
        assert_eq!(p.0[3], if *f { 1.0 } else { 0.0 });
        assert_eq!([p.0[0], p.0[1], p.0[2]], *want);
    }
    let rgbm = image::load_from_memory(file(&files, OutputKind::Rgbm))
        .expect("rgbm")
        .into_rgba8();
    for (p, want) in rgbm.pixels().zip(&padded) {
        let got = rgbm_decode(p.0);
        for k in 0..3 {
            // One 8-bit step of the pixel's multiplier.
            let step = p.0[3] as f32 / 255.0 * 6.0 / 255.0;
            assert!((got[k] - want[k].min(6.0)).abs() <= step * 0.5 + 1e-6);
        }
    }
    // The lit image is not padded.
    let plain = encode_images(&lvl, &map, &OutputOptions::default()).expect("encode");
    assert_eq!(file(&files, OutputKind::Lit), file(&plain, OutputKind::Lit));
    assert_ne!(
        file(&files, OutputKind::Lightmap),
        file(&plain, OutputKind::Lightmap)
    );
}

/// The level with a second light group: a red lamp in the bottom wall.
fn two_group_level() -> Level {
    let mut lvl = level();
    let mut red = light(3.0, 0.5);
    red.color = [255, 0, 0];
    red.emission = [3.0, 0.5, 0.5];
    lvl.materials.push(red);
    let id = (lvl.materials.len() - 1) as u16;
    let y = lvl.height - 5; // the bottom wall row of the room
    for x in 20..24 {
        assert!(matches!(lvl.cells[y * lvl.width + x], Cell::Solid(_)));
        lvl.cells[y * lvl.width + x] = Cell::Solid(id);
    }
    lvl
}

#[test]
#[allow(clippy::needless_range_loop)]
fn layers_are_padded_like_the_lightmap() {
    use flatbake_core::output::layers::{encode_layers, palette_emission};
    let lvl = two_group_level();
    let mut settings = Settings::new(Quality::Draft);
    settings.responses = true;
    let baked = bake(&lvl, &settings, &quiet).expect("bake");
    let r = baked.responses.as_ref().expect("responses");
    let emission = palette_emission(&lvl, r);
    let floor = floor_mask(&lvl);
    let opts = OutputOptions {
        padding: 8,
        ..OutputOptions::default()
    };
    let files = encode_layers(&lvl, r, &emission, &opts).expect("layers");
    let exrs: Vec<&Encoded> = files
        .iter()
        .filter(|f| matches!(f.kind, OutputKind::LayerExr(_)))
        .collect();
    assert_eq!(exrs.len(), 2);
    let mut sum = vec![[0f64; 3]; lvl.width * lvl.height];
    for f in &exrs {
        let img = image::load_from_memory_with_format(&f.bytes, image::ImageFormat::OpenExr)
            .expect("layer EXR")
            .into_rgba32f();
        let rgb: Vec<[f32; 3]> = img.pixels().map(|p| [p.0[0], p.0[1], p.0[2]]).collect();
        // The same bilinear check as the lightmap's.
        assert_eq!(bleeding_samples(&rgb, &lvl), 0, "{:?}", f.kind);
        for ((p, fl), s) in img.pixels().zip(&floor).zip(&mut sum) {
            assert_eq!(p.0[3], if *fl { 1.0 } else { 0.0 }, "{:?}", f.kind);
            for k in 0..3 {
                s[k] += p.0[k] as f64;
            }
        }
    }
    // The check can fail: the same layers unpadded bleed.
    let plain = encode_layers(&lvl, r, &emission, &OutputOptions::default()).expect("layers");
    let unpadded = plain
        .iter()
        .find(|f| matches!(f.kind, OutputKind::LayerExr(_)))
        .expect("layer");
    let img = image::load_from_memory_with_format(&unpadded.bytes, image::ImageFormat::OpenExr)
        .expect("layer EXR")
        .into_rgb32f();
    let rgb: Vec<[f32; 3]> = img.pixels().map(|p| p.0).collect();
    assert!(bleeding_samples(&rgb, &lvl) > 0);
    // Padding is linear in the light, so the padded layers still add up to
    // the padded lightmap (of the same responses).
    let map = flatbake_core::output::Lightmap {
        width: lvl.width,
        height: lvl.height,
        rgb: r.combine(&emission),
    };
    let padded = padded_hdr_pixels(&lvl, &map, 8).expect("pad");
    for (s, p) in sum.iter().zip(&padded) {
        for k in 0..3 {
            assert!((s[k] - p[k] as f64).abs() <= 1e-5 * (p[k] as f64).max(1e-3));
        }
    }
    // The previews' alpha is the coverage too.
    for f in files
        .iter()
        .filter(|f| matches!(f.kind, OutputKind::LayerPng(_)))
    {
        let png = image::load_from_memory(&f.bytes).expect("png").into_rgba8();
        for (p, fl) in png.pixels().zip(&floor) {
            assert_eq!(p.0[3], if *fl { 255 } else { 0 });
        }
    }
}
