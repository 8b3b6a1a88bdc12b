//! Directional lightmaps: the first circular moments of the light against
//! closed forms, and the files `bake --directional` writes.

mod common;
use common::*;

use std::f64::consts::{PI, TAU};

use flatbake_core::bake::{Baked, Settings, bake};
use flatbake_core::level::{Cell, Level};
use flatbake_core::quality::Quality;

fn quiet(_: &str) {}

fn directional(mut s: Settings) -> Settings {
    s.directional = true;
    s
}

fn bake_dir(level: &Level, s: &Settings) -> Baked {
    let b = bake(level, &directional(s.clone()), &quiet).unwrap();
    assert!(b.directional.is_some(), "asked for moments");
    b
}

/// Every preset with draft's interpolation off (every pixel exact), then
/// draft as it is with the tolerance its interpolation is held to.
fn presets() -> Vec<(Settings, f64)> {
    let mut v: Vec<(Settings, f64)> = Quality::ALL
        .iter()
        .map(|&q| {
            let mut s = Settings::new(q);
            s.knobs.lattice = None;
            (s, 1e-6)
        })
        .collect();
    v.push((Settings::new(Quality::Draft), 0.025));
    v
}

/// The direction from `p` to `q` as an angle counter-clockwise from `+x`,
/// `+y` up (image rows go down).
fn angle(p: [f64; 2], q: [f64; 2]) -> f64 {
    (-(q[1] - p[1])).atan2(q[0] - p[0])
}

/// The angular interval `[a, b]` (`b - a < pi`) that the convex box with
/// `corners` covers as seen from `p` outside it.
fn extent(p: [f64; 2], corners: &[[f64; 2]]) -> (f64, f64) {
    let cx = corners.iter().map(|c| c[0]).sum::<f64>() / corners.len() as f64;
    let cy = corners.iter().map(|c| c[1]).sum::<f64>() / corners.len() as f64;
    let mid = angle(p, [cx, cy]);
    let rel: Vec<f64> = corners
        .iter()
        .map(|&c| {
            let mut d = angle(p, c) - mid;
            while d > PI {
                d -= TAU;
            }
            while d <= -PI {
                d += TAU;
            }
            d
        })
        .collect();
    let lo = rel.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = rel.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (mid + lo, mid + hi)
}

/// Distance from `p` along direction `theta` (`+y` up) to the box
/// `[x0, x1] x [y0, y1]` (image coordinates), if the ray hits it.
fn ray_box(p: [f64; 2], theta: f64, b: [f64; 4]) -> Option<f64> {
    let (dx, dy) = (theta.cos(), -theta.sin());
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for (o, d, lo, hi) in [(p[0], dx, b[0], b[1]), (p[1], dy, b[2], b[3])] {
        if d.abs() < 1e-300 {
            if o < lo || o > hi {
                return None;
            }
            continue;
        }
        let (a, c) = ((lo - o) / d, (hi - o) / d);
        t0 = t0.max(a.min(c));
        t1 = t1.min(a.max(c));
    }
    (t0 <= t1).then_some(t0)
}

/// A lone emitting block, seen from every floor pixel: with no falloff the
/// mean is `e (b - a) / 2 pi` and the moments `e (sin b - sin a) / 2 pi` and
/// `e (cos a - cos b) / 2 pi` over the angles `[a, b]` it covers; with
/// falloff they are integrals of `e w(r) (1, cos, sin)` over those angles,
/// `r` the distance to the block along each ray (midpoint rule here).
#[test]
fn lone_emitter_moments_are_the_integrals_over_its_angles() {
    let (w, h) = (20usize, 15usize);
    let mut rows = vec![String::from("...................."); h];
    for row in &mut rows[6..8] {
        row.replace_range(8..12, "LLLL");
    }
    let e = 3.0;
    let lvl = ascii(&refs(&rows), &[('L', light(e, 0.0))]);
    let bx = [8.0, 12.0, 6.0, 8.0];
    let corners = [[8.0, 6.0], [12.0, 6.0], [12.0, 8.0], [8.0, 8.0]];
    let mut worst_exact: f64 = 0.0;
    for falloff in [None, Some(6.0)] {
        for (mut settings, tol) in presets() {
            settings.falloff = falloff;
            let q = settings.quality;
            let baked = bake_dir(&lvl, &settings);
            let dir = baked.directional.as_ref().unwrap();
            for y in 0..h {
                for x in 0..w {
                    if lvl.cell(x, y) != Cell::Floor {
                        continue;
                    }
                    let p = [x as f64 + 0.5, y as f64 + 0.5];
                    let (a, b) = extent(p, &corners);
                    let want = match falloff {
                        None => [b - a, b.sin() - a.sin(), a.cos() - b.cos()].map(|v| e * v / TAU),
                        Some(f) => {
                            let n = 20_000;
                            let step = (b - a) / n as f64;
                            let mut m = [0.0; 3];
                            for i in 0..n {
                                let th = a + (i as f64 + 0.5) * step;
                                let r = ray_box(p, th, bx).unwrap_or_else(|| {
                                    // The ray grazes a corner: a zero-width miss.
                                    ray_box(p, th + 1e-12, bx).unwrap_or(0.0)
                                });
                                let wt = f * f / (f * f + r * r);
                                m[0] += wt * step;
                                m[1] += wt * th.cos() * step;
                                m[2] += wt * th.sin() * step;
                            }
                            m.map(|v| e * v / TAU)
                        }
                    };
                    let i = y * w + x;
                    let got = [
                        baked.lightmap.rgb[i][0] as f64,
                        dir.cos[i][0] as f64,
                        dir.sin[i][0] as f64,
                    ];
                    let quad = if falloff.is_some() { 1e-6 } else { 0.0 };
                    for k in 0..3 {
                        let err = (got[k] - want[k]).abs();
                        let scale = want[0].max(1e-3);
                        if tol < 1e-3 {
                            worst_exact = worst_exact.max(err / scale);
                        }
                        assert!(
                            err <= (tol + quad) * scale,
                            "{q} falloff {falloff:?} ({x},{y}) component {k}: {} vs {} (mean {})",
                            got[k],
                            want[k],
                            want[0]
                        );
                    }
                }
            }
        }
    }
    eprintln!("worst error of the exact presets, relative to the mean: {worst_exact:.2e}");
}

/// At every texel density a texel's mean and moments are the averages of
/// the lone emitter's closed-form integrals over the texel's quadrature
/// points on the floor (the midpoints of its `s x s` grid, or below one
/// texel per pixel the centres of its floor pixels); texels without floor
/// have no moments. A closed room's moments vanish at every density too.
#[test]
fn moments_at_every_density_are_texel_averages_of_the_integrals() {
    use flatbake_core::bake::texels::{Density, TexelOptions, Walls, bake_texels};
    let (w, h) = (20usize, 15usize);
    let mut rows = vec![String::from("...................."); h];
    for row in &mut rows[6..8] {
        row.replace_range(8..11, "LLL");
    }
    let e = 3.0;
    let lvl = ascii(&refs(&rows), &[('L', light(e, 0.0))]);
    let corners = [[8.0, 6.0], [11.0, 6.0], [11.0, 8.0], [8.0, 8.0]];
    let mut settings = directional(Settings::new(Quality::Normal));
    settings.knobs.lattice = None;
    let mut worst: f64 = 0.0;
    for (density, samples) in [
        (Density::Up(2), None),
        (Density::Up(4), Some(1)),
        (Density::Up(1), Some(3)),
        (Density::Down(2), None),
        (Density::Down(3), Some(2)),
    ] {
        let t = TexelOptions {
            density,
            samples,
            walls: Walls::Lit,
        };
        let tb = bake_texels(&lvl, &settings, &t, &quiet, &|_| {}).unwrap();
        let dir = tb
            .baked
            .directional
            .as_ref()
            .expect("moments at every density");
        let (tw, th) = (tb.level.width, tb.level.height);
        assert_eq!((dir.width, dir.height), (tw, th));
        assert_eq!(dir.cos.len(), tw * th);
        // Quadrature pixels per painted pixel and per texel side.
        let k = t.scale();
        let block = match density {
            Density::Up(_) => t.samples() as usize,
            Density::Down(m) => m as usize * t.samples() as usize,
        };
        let mut floor_texels = 0;
        for ty in 0..th {
            for tx in 0..tw {
                let mut want = [0.0; 3];
                let mut n = 0;
                for qy in ty * block..((ty + 1) * block).min(h * k) {
                    for qx in tx * block..((tx + 1) * block).min(w * k) {
                        let p = [(qx as f64 + 0.5) / k as f64, (qy as f64 + 0.5) / k as f64];
                        if lvl.cell(qx / k, qy / k) != Cell::Floor {
                            continue;
                        }
                        let (a, b) = extent(p, &corners);
                        let m = [b - a, b.sin() - a.sin(), a.cos() - b.cos()];
                        for c in 0..3 {
                            want[c] += e * m[c] / TAU;
                        }
                        n += 1;
                    }
                }
                let i = ty * tw + tx;
                let got = [
                    tb.baked.lightmap.rgb[i][0] as f64,
                    dir.cos[i][0] as f64,
                    dir.sin[i][0] as f64,
                ];
                if n == 0 {
                    assert_eq!(
                        [got[1], got[2]],
                        [0.0, 0.0],
                        "{density:?} texel ({tx},{ty})"
                    );
                    continue;
                }
                floor_texels += 1;
                let want = want.map(|v| v / n as f64);
                for c in 0..3 {
                    let err = (got[c] - want[c]).abs() / want[0];
                    worst = worst.max(err);
                    assert!(
                        err < 1e-5,
                        "{density:?} samples {samples:?} texel ({tx},{ty}) component {c}: {} vs {} (mean {})",
                        got[c],
                        want[c],
                        want[0]
                    );
                }
            }
        }
        assert!(
            floor_texels * 2 > tw * th,
            "{density:?}: {floor_texels} floor texels"
        );
        // A closed room at the same layout: no first moment anywhere.
        let room_lvl = ascii(&refs(&room(13, 9)), &[('#', light(0.7, 0.5))]);
        let tb = bake_texels(&room_lvl, &settings, &t, &quiet, &|_| {}).unwrap();
        let dir = tb.baked.directional.as_ref().unwrap();
        for v in dir.cos.iter().chain(&dir.sin) {
            assert!(
                v[0].abs() < 1e-6 * 1.4,
                "{density:?}: closed room moment {}",
                v[0]
            );
        }
    }
    eprintln!("worst texel error relative to the mean: {worst:.2e}");
}

/// Two equal lights facing each other across a symmetric room: at the
/// pixel midway between them (and on the room's horizontal axis) the first
/// moment vanishes, and everywhere the moments mirror. Walls reflect, so
/// the bounce (reflected pieces, slopes) is in it too.
#[test]
fn midway_between_two_equal_lights_the_first_moment_vanishes() {
    // 21 px wide: the floor spans x 1..20, centred on pixel 10's centre.
    let mut rows = room(21, 9);
    for row in &mut rows[3..6] {
        row.replace_range(0..1, "L");
        row.replace_range(20..21, "L");
    }
    let e = 2.0;
    let lvl = ascii(&refs(&rows), &[('#', wall(0.6)), ('L', light(e, 0.3))]);
    for (settings, ptol) in presets() {
        let q = settings.quality;
        // Merged distant reflected light errs by at most reach_bound x the
        // brightest emission per pixel (docs/transport.md#floor-gather), and
        // the 8x8 tiles that decide it are not mirror-symmetric.
        let merged = 2.0 * settings.knobs.reach_bound * e;
        let tol = |m: f64| ptol * m + merged + 1e-7;
        let baked = bake_dir(&lvl, &settings);
        let dir = baked.directional.as_ref().unwrap();
        let at = |x: usize, y: usize| y * 21 + x;
        let mean = baked.lightmap.rgb[at(10, 4)][0] as f64;
        assert!(mean > 0.0);
        let (c, s) = (dir.cos[at(10, 4)][0] as f64, dir.sin[at(10, 4)][0] as f64);
        assert!(
            c.abs() < tol(mean) && s.abs() < tol(mean),
            "{q}: moments ({c}, {s}) of mean {mean}"
        );
        for y in 1..8 {
            for x in 1..20 {
                let (i, j) = (at(x, y), at(20 - x, y));
                let m = baked.lightmap.rgb[i][0] as f64;
                let tol = tol(m);
                assert!(
                    (dir.cos[i][0] as f64 + dir.cos[j][0] as f64).abs() < tol,
                    "{q} ({x},{y}): cos {} vs mirror {}",
                    dir.cos[i][0],
                    dir.cos[j][0]
                );
                assert!(
                    (dir.sin[i][0] as f64 - dir.sin[j][0] as f64).abs() < tol,
                    "{q} ({x},{y}): sin {} vs mirror {}",
                    dir.sin[i][0],
                    dir.sin[j][0]
                );
            }
        }
        // Off the axis the light comes from the nearer light: the moments
        // are not trivially zero.
        assert!(dir.cos[at(3, 4)][0] < -0.05 * baked.lightmap.rgb[at(3, 4)][0]);
    }
}

/// In a closed room whose walls all emit `e` and reflect `r`, radiance is
/// `e / (1 - r)` from every direction: the moments vanish everywhere.
#[test]
fn closed_room_moments_vanish() {
    for (settings, _) in presets() {
        let q = settings.quality;
        for r in [0.0, 0.5, 0.9] {
            let rows = room(13, 9);
            let lvl = ascii(&refs(&rows), &[('#', light(0.7, r))]);
            let baked = bake_dir(&lvl, &settings);
            let dir = baked.directional.as_ref().unwrap();
            let want = 0.7 / (1.0 - r);
            let mut worst: f64 = 0.0;
            for (i, c) in lvl.cells.iter().enumerate() {
                if *c == Cell::Floor {
                    for v in [dir.cos[i][0], dir.sin[i][0]] {
                        worst = worst.max(v.abs() as f64 / want);
                    }
                }
            }
            assert!(worst < 1e-6, "{q} r={r}: moment {worst:e} of the radiance");
        }
    }
}

/// A level with walls, a pillar, bounce and falloff: with `directional` the
/// lightmap is bit for bit the plain one at every preset (draft's lattice
/// included), and moments are never longer than the mean.
#[test]
fn mean_is_the_plain_lightmap() {
    let rows = [
        "####################",
        "#..................#",
        "#....##............L",
        "#....##......#.....L",
        "#............#.....#",
        "L............#.....#",
        "#..................#",
        "####################",
    ];
    let lvl = ascii(&rows, &[('#', wall(0.7)), ('L', light(1.5, 0.2))]);
    for falloff in [None, Some(12.0)] {
        for q in Quality::ALL {
            let mut s = Settings::new(q);
            s.falloff = falloff;
            let plain = bake(&lvl, &s, &quiet).unwrap();
            assert!(plain.directional.is_none());
            let dir = bake_dir(&lvl, &s);
            assert_eq!(
                plain.lightmap.rgb, dir.lightmap.rgb,
                "{q} {falloff:?}: the mean differs from the plain lightmap"
            );
            let m = dir.directional.as_ref().unwrap();
            for (i, c) in lvl.cells.iter().enumerate() {
                let mean = dir.lightmap.rgb[i][0];
                let len = m.cos[i][0].hypot(m.sin[i][0]);
                if *c == Cell::Floor {
                    assert!(
                        len <= mean * (1.0 + 1e-5) + 1e-9,
                        "{q}: |m| {len} > mean {mean}"
                    );
                } else {
                    assert_eq!(len, 0.0);
                }
            }
        }
    }
}

/// Light is linear in emission, and so are its moments: twice the emission
/// gives twice the moments (the bounce included).
#[test]
fn moments_are_linear_in_emission() {
    let rows = [
        "##########",
        "#........#",
        "#..##....L",
        "#........#",
        "##########",
    ];
    let bake_at = |e: f64| {
        let lvl = ascii(&rows, &[('#', wall(0.5)), ('L', light(e, 0.2))]);
        let mut s = Settings::new(Quality::Normal);
        s.exhaustive = true;
        bake_dir(&lvl, &s)
    };
    let (one, two) = (bake_at(1.0), bake_at(2.0));
    let (a, b) = (one.directional.unwrap(), two.directional.unwrap());
    for i in 0..a.cos.len() {
        for (x, y) in [(a.cos[i][1], b.cos[i][1]), (a.sin[i][1], b.sin[i][1])] {
            assert!(
                (2.0 * x as f64 - y as f64).abs() <= 1e-6 * (y.abs() as f64 + 1e-6),
                "pixel {i}: {x} x 2 vs {y}"
            );
        }
    }
}

/// `--kernel paper` and `--gather naive` have no moments: refused, not zero.
#[test]
fn directional_needs_the_flatland_kernel_and_the_fast_gather() {
    let lvl = ascii(&refs(&room(8, 6)), &[('#', light(1.0, 0.5))]);
    let mut s = directional(Settings::new(Quality::Draft));
    s.kernel = flatbake_core::gather::Kernel::Paper;
    let err = bake(&lvl, &s, &quiet).err().expect("refused");
    assert!(err.to_string().contains("flatland kernel"), "{err}");
    let mut s = directional(Settings::new(Quality::Draft));
    s.gather = flatbake_core::bake::GatherMethod::Naive;
    assert!(bake(&lvl, &s, &quiet).is_err());
}

/// `bake --directional` writes the EXR with the mean and the moments, the
/// direction preview and, beside a normal map, the lit preview; without the
/// flag none of them, and the flag re-bakes an up-to-date level.
#[test]
fn bake_directional_writes_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let (levels, out) = (dir.path().join("levels"), dir.path().join("out"));
    std::fs::create_dir_all(&levels).unwrap();
    write_room(&levels, "room", true);
    let o = flatbake(&["bake", s(&levels), "--out", s(&out), "--quality", "draft"]);
    assert_exit(&o, 0);
    assert!(!out.join("room.directional.exr").exists());
    // A flat normal map: the lit preview is the lit image, to rounding.
    let flat = image::RgbImage::from_pixel(24, 16, image::Rgb([128, 128, 255]));
    flat.save(levels.join("room.normals.png")).unwrap();
    let o = flatbake(&[
        "bake",
        s(&levels),
        "--out",
        s(&out),
        "--quality",
        "draft",
        "--directional",
    ]);
    assert_exit(&o, 0);
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("1 baked")
            || !String::from_utf8_lossy(&o.stdout).contains("up to date"),
        "the flag re-bakes: {}",
        String::from_utf8_lossy(&o.stdout)
    );
    assert!(
        !out.join("room.normals.lightmap.png").exists(),
        "the normal map is no level"
    );
    let exr = std::fs::read(out.join("room.directional.exr")).unwrap();
    for name in ["cos.R", "cos.G", "cos.B", "sin.R", "sin.G", "sin.B"] {
        let needle = format!("{name}\0");
        assert!(
            exr.windows(needle.len()).any(|w| w == needle.as_bytes()),
            "channel {name} in the EXR"
        );
    }
    // Its R, G, B are the mean: what `image` reads of it is the lightmap.
    let mean = image::open(out.join("room.directional.exr"))
        .unwrap()
        .into_rgb32f();
    let lit = image::open(out.join("room.lit.png")).unwrap().into_rgba8();
    let lit_n = image::open(out.join("room.lit-normals.png"))
        .unwrap()
        .into_rgba8();
    let preview = image::open(out.join("room.direction.png"))
        .unwrap()
        .into_rgb8();
    assert_eq!(preview.dimensions(), (24, 16));
    assert!(mean.pixels().any(|p| p.0[0] > 0.0));
    for (a, b) in lit.pixels().zip(lit_n.pixels()) {
        for k in 0..4 {
            assert!((a.0[k] as i32 - b.0[k] as i32).abs() <= 1, "{a:?} vs {b:?}");
        }
    }
    // Without the flag again: the stamp spells the option only when on.
    let stamp = std::fs::read_to_string(out.join("room.stamp.json")).unwrap();
    assert!(stamp.contains("room.directional.exr"), "{stamp}");
    // A normal map of the wrong size is an error naming it.
    image::RgbImage::from_pixel(5, 5, image::Rgb([128, 128, 255]))
        .save(levels.join("room.normals.png"))
        .unwrap();
    let o = flatbake(&[
        "bake",
        s(&levels),
        "--out",
        s(&out),
        "--quality",
        "draft",
        "--directional",
    ]);
    assert_exit(&o, 1);
    assert_says(&o, &["room.normals.png", "5x5"]);
}

/// At another texel density the normal map is painted pixel for pixel (or
/// texel for texel of the lightmap): the lit preview is at the lightmap's
/// size, a flat map leaves it the lit image, and a map of neither size is
/// an error naming both. A relight with `--level` reads it the same way.
#[test]
fn normal_maps_follow_the_texel_density() {
    let dir = tempfile::tempdir().unwrap();
    let levels = dir.path().join("levels");
    std::fs::create_dir_all(&levels).unwrap();
    write_room(&levels, "room", true);
    let flat = |w: u32, h: u32| image::RgbImage::from_pixel(w, h, image::Rgb([128, 128, 255]));
    for (density, (w, h), (tw, th)) in [
        ("2", (24u32, 16u32), (48u32, 32u32)),
        ("2", (48, 32), (48, 32)),
        ("1/2", (24, 16), (12, 8)),
        ("1/4", (6, 4), (6, 4)),
    ] {
        flat(w, h).save(levels.join("room.normals.png")).unwrap();
        let out = dir
            .path()
            .join(format!("out-{}-{w}", density.replace('/', "_")));
        let o = flatbake(&[
            "bake",
            s(&levels.join("room.png")),
            "--out",
            s(&out),
            "--quality",
            "draft",
            "--directional",
            "--cache",
            "--texels-per-pixel",
            density,
        ]);
        assert_exit(&o, 0);
        let lit = image::open(out.join("room.lit.png")).unwrap().into_rgba8();
        let lit_n = image::open(out.join("room.lit-normals.png"))
            .unwrap()
            .into_rgba8();
        assert_eq!(lit_n.dimensions(), (tw, th), "at {density} from {w}x{h}");
        assert_eq!(lit.dimensions(), (tw, th));
        for (a, b) in lit.pixels().zip(lit_n.pixels()) {
            for k in 0..4 {
                assert!((a.0[k] as i32 - b.0[k] as i32).abs() <= 1, "{a:?} vs {b:?}");
            }
        }
        // The relight reads the map at the cache's density.
        let relit = out.join("relit");
        let o = flatbake(&[
            "relight",
            s(&out.join("room.flatbake")),
            "--level",
            s(&levels.join("room.png")),
            "-o",
            s(&relit),
        ]);
        assert_exit(&o, 0);
        assert_eq!(
            std::fs::read(relit.join("room.lit-normals.png")).unwrap(),
            std::fs::read(out.join("room.lit-normals.png")).unwrap(),
            "at {density}"
        );
    }
    flat(30, 20).save(levels.join("room.normals.png")).unwrap();
    let o = flatbake(&[
        "bake",
        s(&levels.join("room.png")),
        "--out",
        s(&dir.path().join("bad")),
        "--quality",
        "draft",
        "--directional",
        "--texels-per-pixel",
        "2",
    ]);
    assert_exit(&o, 1);
    assert_says(&o, &["room.normals.png", "30x20", "24x16", "48x32"]);
}

/// The radiosity a ray from `p` in direction `theta` (`+y` up) meets first:
/// the patch mean of the edge face it hits (found by walking the pixel grid).
fn first_hit(baked: &Baked, lvl: &Level, p: [f64; 2], theta: f64) -> f64 {
    use flatbake_core::geometry::Normal;
    let (dx, dy) = (theta.cos(), -theta.sin());
    let (mut cx, mut cy) = (p[0].floor() as i64, p[1].floor() as i64);
    let step_x = if dx > 0.0 { 1 } else { -1 };
    let step_y = if dy > 0.0 { 1 } else { -1 };
    let next = |c: i64, s: i64| if s > 0 { c as f64 + 1.0 } else { c as f64 };
    loop {
        let tx = if dx.abs() < 1e-300 {
            f64::INFINITY
        } else {
            (next(cx, step_x) - p[0]) / dx
        };
        let ty = if dy.abs() < 1e-300 {
            f64::INFINITY
        } else {
            (next(cy, step_y) - p[1]) / dy
        };
        let (normal, t) = if tx < ty {
            cx += step_x;
            (
                if step_x > 0 {
                    Normal::Left
                } else {
                    Normal::Right
                },
                tx,
            )
        } else {
            cy += step_y;
            (if step_y > 0 { Normal::Up } else { Normal::Down }, ty)
        };
        if lvl.cell(cx as usize, cy as usize) == Cell::Floor {
            continue;
        }
        let hit = [p[0] + t * dx, p[1] + t * dy];
        let (line, s) = if normal.is_vertical_edge() {
            (hit[0], hit[1])
        } else {
            (hit[1], hit[0])
        };
        for (ei, e) in baked.geometry.edges.iter().enumerate() {
            let (lo, hi) = e.extent();
            if e.normal == normal && e.line() == line.round() && s >= lo && s <= hi {
                let range = baked.patches.of_edge(ei);
                let k = (((s - lo) / baked.patches.step[ei]) as usize).min(range.len() - 1);
                return baked.radiosity[0][range.start + k];
            }
        }
        panic!("no edge at {hit:?} facing {normal:?}");
    }
}

/// Reflected light too: around a corner from a light, a pixel that sees lit
/// walls (and a little of the light) gets the moments of the first-hit
/// radiosity found by casting rays, to the discretisation error of the
/// `reference` preset's half-pixel patches (the ray cast takes each patch's
/// mean, the bake its slope too).
#[test]
fn moments_of_reflected_light_match_a_ray_cast() {
    let rows = [
        "################",
        "#..............#",
        "#..............#",
        "#######........#",
        "      #........#",
        "      #........#",
        "      #........#",
        "      ###LLL####",
    ];
    let lvl = ascii(&rows, &[('#', wall(0.8)), ('L', light(2.0, 0.0))]);
    let mut s = Settings::new(Quality::Reference);
    s.knobs.lattice = None;
    let baked = bake_dir(&lvl, &s);
    let dir = baked.directional.as_ref().unwrap();
    let mut checked = 0;
    for (x, y) in [(2usize, 1usize), (3, 2), (5, 1), (8, 2), (14, 1), (9, 5)] {
        let p = [x as f64 + 0.5, y as f64 + 0.5];
        let n = 100_000;
        let mut m = [0.0; 3];
        for i in 0..n {
            let th = (i as f64 + 0.5) * TAU / n as f64;
            let b = first_hit(&baked, &lvl, p, th);
            m[0] += b / n as f64;
            m[1] += b * th.cos() / n as f64;
            m[2] += b * th.sin() / n as f64;
        }
        let i = y * lvl.width + x;
        let got = [
            baked.lightmap.rgb[i][0] as f64,
            dir.cos[i][0] as f64,
            dir.sin[i][0] as f64,
        ];
        for k in 0..3 {
            assert!(
                (got[k] - m[k]).abs() < 3e-3 * m[0],
                "({x},{y}) component {k}: bake {} vs ray cast {} (mean {})",
                got[k],
                m[k],
                m[0]
            );
        }
        eprintln!(
            "({x},{y}): mean {:.5} vs {:.5}, cos {:.5} vs {:.5}, sin {:.5} vs {:.5}",
            got[0], m[0], got[1], m[1], got[2], m[2]
        );
        checked += 1;
    }
    assert_eq!(checked, 6);
}

/// The channels of an EXR that flatbake wrote (single part, scan lines, no
/// compression, 32-bit float): name -> row-major values.
fn read_exr_channels(bytes: &[u8]) -> std::collections::BTreeMap<String, Vec<f32>> {
    let i32_at = |o: usize| i32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let cstr = |o: usize| {
        let end = o + bytes[o..].iter().position(|&b| b == 0).unwrap();
        (String::from_utf8(bytes[o..end].to_vec()).unwrap(), end + 1)
    };
    let (mut o, mut names, mut window) = (8, Vec::new(), [0i32; 4]);
    loop {
        let (name, next) = cstr(o);
        if name.is_empty() {
            o = next;
            break;
        }
        let (_, next) = cstr(next);
        let size = i32_at(next) as usize;
        let value = next + 4;
        if name == "channels" {
            let mut c = value;
            while bytes[c] != 0 {
                let (n, after) = cstr(c);
                assert_eq!(i32_at(after), 2, "FLOAT channels");
                names.push(n);
                c = after + 16;
            }
        }
        if name == "dataWindow" {
            window = [0, 1, 2, 3].map(|k| i32_at(value + 4 * k));
        }
        o = value + size;
    }
    let (w, h) = ((window[2] + 1) as usize, (window[3] + 1) as usize);
    o += 8 * h; // offset table
    let mut out: std::collections::BTreeMap<String, Vec<f32>> = names
        .iter()
        .map(|n| (n.clone(), vec![0.0; w * h]))
        .collect();
    for y in 0..h {
        assert_eq!(i32_at(o), y as i32);
        o += 8;
        for n in &names {
            let v = out.get_mut(n).unwrap();
            for x in 0..w {
                v[y * w + x] = f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
                o += 4;
            }
        }
    }
    out
}

/// A room with two light groups, baked with layers and a cache: the
/// layers' moments add up to the level's, the cache relights to the same
/// bytes with the same emission, and to twice the moments with twice the
/// emission of every light; at every texel density.
#[test]
fn layers_relight_and_caches_carry_the_moments() {
    for density in ["1", "2", "1/2"] {
        layers_relight_and_caches_carry_the_moments_at(density);
    }
}

fn layers_relight_and_caches_carry_the_moments_at(density: &str) {
    let dir = tempfile::tempdir().unwrap();
    let levels = dir.path().join("levels");
    std::fs::create_dir_all(&levels).unwrap();
    let (w, h) = (24u32, 16u32);
    let img = image::RgbaImage::from_fn(w, h, |x, y| {
        let px = |c: [u8; 3]| image::Rgba([c[0], c[1], c[2], 255]);
        if y == 0 && (3..8).contains(&x) {
            px([255, 250, 220])
        } else if x == w - 1 && (8..13).contains(&y) {
            px([160, 200, 255])
        } else if x == 0 || y == 0 || x == w - 1 || y == h - 1 || (x == 12 && y > 6) {
            px([90, 90, 90])
        } else {
            px([180, 170, 150])
        }
    });
    img.save(levels.join("duo.png")).unwrap();
    std::fs::write(
        levels.join("duo.palette.toml"),
        "[[wall]]\ncolor = \"#5a5a5a\"\nreflectance = 0.6\n\n\
         [[emitter]]\ncolor = \"#fffadc\"\nemission = [2.0, 1.8, 1.5]\n\n\
         [[emitter]]\ncolor = \"#a0c8ff\"\nemission = [0.5, 1.0, 2.0]\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    let o = flatbake(&[
        "bake",
        s(&levels.join("duo.png")),
        "-o",
        s(&out),
        "--directional",
        "--layers",
        "--cache",
        "--quiet",
        "--texels-per-pixel",
        density,
    ]);
    assert_exit(&o, 0);
    let read = |p: std::path::PathBuf| {
        read_exr_channels(&std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())))
    };
    let full = read(out.join("duo.directional.exr"));
    // The mean channels are the lightmap EXR's on the floor; on walls the
    // lightmap carries the wall faces (`--walls lit`), the directional
    // file 0.
    let plain = image::open(out.join("duo.lightmap.exr"))
        .unwrap()
        .into_rgb32f();
    assert_eq!(plain.len() as usize, 3 * full["R"].len(), "at {density}");
    let mut same = 0;
    for (i, p) in plain.pixels().enumerate() {
        if full["R"][i] == p.0[0] {
            same += 1;
        } else {
            assert_eq!(full["R"][i], 0.0, "at {density}, texel {i}");
        }
    }
    assert!(same * 2 > full["R"].len(), "at {density}: {same} equal");
    let layers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.to_string_lossy().ends_with(".directional.exr")
                && p.to_string_lossy().contains(".layer-")
        })
        .collect();
    assert_eq!(layers.len(), 2, "{layers:?}");
    // The manifest names each group's directional file.
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("duo.layers.json")).unwrap()).unwrap();
    let mut listed: Vec<std::path::PathBuf> = manifest["groups"]
        .as_array()
        .unwrap()
        .iter()
        .map(|g| out.join(g["directional_exr"].as_str().expect("directional_exr")))
        .collect();
    let mut found = layers.clone();
    listed.sort();
    found.sort();
    assert_eq!(listed, found);
    let parts: Vec<_> = layers.into_iter().map(read).collect();
    let brightest = full["R"].iter().copied().fold(0f32, f32::max);
    let mut moving = 0;
    for ch in [
        "cos.R", "cos.G", "cos.B", "sin.R", "sin.G", "sin.B", "R", "B",
    ] {
        for i in 0..full[ch].len() {
            let sum: f32 = parts.iter().map(|p| p[ch][i]).sum();
            assert!(
                (sum - full[ch][i]).abs() <= 1e-5 * brightest,
                "{ch} pixel {i}: layers sum to {sum}, the level has {}",
                full[ch][i]
            );
            moving += (full[ch][i] != 0.0) as usize;
        }
    }
    assert!(moving > 100);
    // The same emission again: the same bytes.
    let cache = out.join("duo.flatbake");
    let same = dir.path().join("same");
    let o = flatbake(&["relight", s(&cache), "-o", s(&same)]);
    assert_exit(&o, 0);
    assert_eq!(
        std::fs::read(same.join("duo.directional.exr")).unwrap(),
        std::fs::read(out.join("duo.directional.exr")).unwrap()
    );
    // Twice the emission of both lights: twice the moments.
    let twice = dir.path().join("twice");
    let o = flatbake(&[
        "relight",
        s(&cache),
        "--emission",
        "#fffadc=4,3.6,3",
        "--emission",
        "#a0c8ff=1,2,4",
        "-o",
        s(&twice),
    ]);
    assert_exit(&o, 0);
    let doubled = read(twice.join("duo.directional.exr"));
    for ch in ["cos.R", "cos.G", "cos.B", "sin.R", "sin.G", "sin.B"] {
        for i in 0..full[ch].len() {
            let (a, b) = (full[ch][i], doubled[ch][i]);
            assert!(
                (2.0 * a - b).abs() <= 1e-6 * brightest,
                "{ch} pixel {i}: 2 x {a} vs {b}"
            );
        }
    }
}

/// Gauss-Legendre nodes and weights of order `n` on `[-1, 1]` (Newton's
/// method on the Legendre polynomial), for the quadrature below.
fn legendre_rule(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    (p0, p1) = (p1, p2);
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-15 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// Reflected light that is strongly curved along a long wall (a parabola
/// in one channel, the peak of a small bright light close to the wall in
/// the other), given as the patches hold it (a mean and a slope each), and
/// gathered with merging on: far from the wall the patch tree stands in
/// for runs of patches with its parabolas, whose quadratic terms carry the
/// curvature. The mean and both moments must match a fine Gauss-Legendre
/// quadrature of the patches' own piecewise-linear radiosity over the
/// wall's face, computed here from the patches alone (no tree, no closed
/// form), to within the merging bound: a node stands in for its patches
/// only where `dev * w(r) <= tolerance` at its nearest point, so the pieces
/// err by at most `tolerance` times the angle they cover over `2 pi`, in
/// the mean and, since `|cos|, |sin| <= 1`, in each moment. Without the
/// parabolas' quadratic terms the merged pieces are off by about `c2 l^2 /
/// 12` (`l` their length): many times that bound.
#[test]
fn curved_reflected_light_matches_a_quadrature_of_the_patches() {
    use flatbake_core::gather::{GatherOptions, Kernel, Radiosity, gather_with_moments};
    use flatbake_core::geometry::{Normal, trace};
    use flatbake_core::transport::Patches;
    use flatbake_core::transport::kernel::{Falloff, Reach};

    // A wall 60 px long; the pixels below it see its lower face whole.
    let (w, h) = (64usize, 40usize);
    let mut rows = vec![".".repeat(w); h];
    for row in &mut rows[1..3] {
        row.replace_range(2..62, &"#".repeat(60));
    }
    let lvl = ascii(&refs(&rows), &[('#', wall(0.5))]);
    let g = trace(&lvl);
    let faces: Vec<usize> = (0..g.edges.len())
        .filter(|&e| g.edges[e].normal == Normal::Down)
        .collect();
    assert_eq!(faces.len(), 1, "one lower face");
    let face = faces[0];
    let edge = &g.edges[face];
    assert_eq!((edge.line(), edge.extent()), (3.0, (2.0, 62.0)));
    let patches = Patches::new(&g, 0.5);
    // B(s) and B'(s) along the face, per channel.
    let profile = |c: usize, s: f64| -> (f64, f64) {
        if c == 0 {
            let u = (s - 20.0) / 30.0;
            (0.2 + 2.0 * u * u, 4.0 * u / 30.0)
        } else {
            let u = (s - 40.0) / 3.0;
            let q = 1.0 + u * u;
            (0.1 + 3.0 / q, -6.0 * u / (3.0 * q * q))
        }
    };
    let n = patches.len();
    let mut b = vec![vec![0.0; n]; 2];
    let mut slope = vec![vec![0.0; n]; 2];
    for p in patches.of_edge(face) {
        let (s0, s1) = patches.bounds(&g.edges, p);
        for c in 0..2 {
            (b[c][p], slope[c][p]) = profile(c, 0.5 * (s0 + s1));
        }
    }
    let e = vec![vec![0.0; g.edges.len()]; 2];
    let rad = Radiosity::new(&patches, &b, &slope, &e);
    let reach = Reach::unlimited(g.edges.len());
    let pixels: Vec<[i32; 2]> = (3..h as i32)
        .flat_map(|y| (2..62).map(move |x| [x, y]))
        .collect();
    let rule = legendre_rule(16);
    let mut failed = Vec::new();
    for (fall, tolerance) in [(None, 2e-3), (Some(6.0), 1e-4), (Some(20.0), 1e-4)] {
        let falloff = fall.map(Falloff::new);
        let options = GatherOptions {
            falloff,
            kernel: Kernel::Flatland,
            reach: &reach,
            tolerance,
            decide: 0..2,
            progress: None,
            lattice: None,
            anchors: None,
            sweep_every: false,
            coarse: false,
            far: None,
            directional: true,
        };
        let got = gather_with_moments(&g, &patches, &rad, &pixels, &options);
        let (mut worst, mut ratio, mut at): (f64, f64, String) = (0.0, 0.0, String::new());
        for (i, px) in pixels.iter().enumerate() {
            let p = [px[0] as f64 + 0.5, px[1] as f64 + 0.5];
            let d = p[1] - edge.line();
            // integral of B w (1, cos, sin) d theta / 2 pi, with d theta =
            // d ds / r^2 along the face.
            let mut want = [[0.0; 3]; 2];
            for q in patches.of_edge(face) {
                let (s0, s1) = patches.bounds(&g.edges, q);
                let (m, half) = (0.5 * (s0 + s1), 0.5 * (s1 - s0));
                for &(x, wt) in &rule {
                    let s = m + half * x;
                    let dx = s - p[0];
                    let r2 = dx * dx + d * d;
                    let wr = fall.map_or(1.0, |f: f64| f * f / (f * f + r2));
                    let th = angle(p, [s, edge.line()]);
                    let k = wt * half * wr * d / r2 / TAU;
                    for c in 0..2 {
                        let bq = b[c][q] + slope[c][q] * (s - m);
                        want[c][0] += bq * k;
                        want[c][1] += bq * th.cos() * k;
                        want[c][2] += bq * th.sin() * k;
                    }
                }
            }
            // The angle the face covers from p.
            let span = angle(p, [2.0, edge.line()]) - angle(p, [62.0, edge.line()]);
            let bound = tolerance * span / TAU;
            for (c, want) in want.iter().enumerate() {
                let have = [
                    got.values[i * 2 + c],
                    got.moments[i * 4 + c],
                    got.moments[i * 4 + 2 + c],
                ];
                for k in 0..3 {
                    let err = (have[k] - want[k]).abs();
                    let allowed = bound + 1e-11 * want[0];
                    worst = worst.max(err);
                    if err / allowed > ratio {
                        ratio = err / allowed;
                        at = format!(
                            "pixel {px:?} channel {c} component {k}: gathered {} vs quadrature {} \
                             (error {err:.3e}, bound {allowed:.3e})",
                            have[k], want[k]
                        );
                    }
                }
            }
        }
        eprintln!(
            "falloff {fall:?} tolerance {tolerance:e}: {} pieces for {} patch pieces; \
             worst error {worst:.3e}, {ratio:.3} of its bound at {at}",
            got.counts.pieces, got.counts.patch_pieces
        );
        // Far pixels gather far fewer pieces than patches.
        if got.counts.pieces * 2 >= got.counts.patch_pieces {
            failed.push(format!(
                "falloff {fall:?}: too little merged, {:?}",
                got.counts
            ));
        }
        if ratio > 1.0 {
            failed.push(format!("falloff {fall:?}: {at}"));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}
