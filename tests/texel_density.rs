//! Texel density (`TexelOptions`, `--texels-per-pixel`) and wall faces
//! (`--walls`) against closed forms: a closed room reads e/(1-r) at every
//! texel at every density, a lone emitter's texels are the exact area
//! average of its subtended angle within the quadrature bound of
//! docs/transport.md, a texel split by a shadow lies between its two sides,
//! the solve does not change with the density, and relight, layers and
//! padding work on texels.

mod common;
use common::*;

use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

use flatbake_core::bake::texels::{Density, TexelOptions, Walls, bake_texels};
use flatbake_core::bake::{Settings, bake};
use flatbake_core::level::{Cell, Level};
use flatbake_core::quality::Quality;

fn quiet(_: &str) {}

const DENSITIES: [Density; 6] = [
    Density::Down(4),
    Density::Down(2),
    Density::Up(1),
    Density::Up(2),
    Density::Up(4),
    Density::Up(8),
];

fn texels(density: Density, samples: Option<u32>, walls: Walls) -> TexelOptions {
    TexelOptions {
        density,
        samples,
        walls,
    }
}

fn at(level: &Level, settings: &Settings, t: &TexelOptions) -> flatbake_core::bake::TexelBake {
    bake_texels(level, settings, t, &quiet, &|_| {}).unwrap()
}

#[test]
fn density_parses_whole_numbers_and_their_inverses() {
    for (s, d) in [
        ("1", Density::Up(1)),
        ("2", Density::Up(2)),
        ("8", Density::Up(8)),
        ("16", Density::Up(16)),
        ("1/4", Density::Down(4)),
        ("0.25", Density::Down(4)),
        ("0.5", Density::Down(2)),
        ("1/2", Density::Down(2)),
        ("2/1", Density::Up(2)),
        (" 4 ", Density::Up(4)),
        ("0.0625", Density::Down(16)),
    ] {
        assert_eq!(Density::parse(s), Ok(d), "{s}");
    }
    for s in [
        "0", "-1", "0.3", "1.5", "32", "1/32", "abc", "1/0", "", "nan", "inf",
    ] {
        let e = Density::parse(s).unwrap_err().to_string();
        assert!(
            e.contains("from 1 to 16") && e.contains(&format!("not {s}")),
            "{s}: {e}"
        );
    }
}

/// A closed room whose walls emit e and reflect r reads e/(1-r) on every
/// floor texel and (lit walls) on every texel of a wall face pixel, at every
/// density; the radiosity of its patches is the same at every density.
#[test]
fn closed_room_is_e_over_one_minus_r_at_every_texel_and_density() {
    let (e, r) = (0.7, 0.5);
    let want = e / (1.0 - r);
    let rows = room(13, 9);
    let lvl = ascii(&refs(&rows), &[('#', light(e, r))]);
    let settings = Settings::new(Quality::Normal);
    for d in DENSITIES {
        let t = at(&lvl, &settings, &texels(d, None, Walls::Lit));
        let (tl, map) = (&t.level, &t.baked.lightmap);
        assert_eq!((map.width, map.height), (tl.width, tl.height));
        let n = d.value();
        assert_eq!(map.width, (13.0 * n).ceil() as usize, "{d:?}");
        for b in &t.baked.radiosity[0] {
            assert!((b / want - 1.0).abs() < 1e-6, "{d:?}: patch {b}");
        }
        let mut floors = 0;
        for (i, c) in tl.cells.iter().enumerate() {
            let v = map.rgb[i][0] as f64;
            let (x, y) = (i % tl.width, i / tl.width);
            match c {
                Cell::Floor => {
                    floors += 1;
                    assert!((v / want - 1.0).abs() < 1e-5, "{d:?} ({x},{y}): {v}");
                }
                Cell::Solid(_) => {
                    // Every texel of a ring pixel with a face on the room
                    // carries its light; the four corner pixels face nothing.
                    let face = match d {
                        Density::Up(n) => {
                            let (px, py) = (x / n as usize, y / n as usize);
                            let edge_x = px == 0 || px == 12;
                            let edge_y = py == 0 || py == 8;
                            !(edge_x && edge_y)
                        }
                        // Wall-only texels of the coarse grid hold a corner
                        // or a side pixel: some hold a face.
                        Density::Down(_) => v > 0.0,
                    };
                    if face {
                        assert!((v / want - 1.0).abs() < 1e-5, "{d:?} wall ({x},{y}): {v}");
                    } else {
                        assert_eq!(v, 0.0, "{d:?} corner ({x},{y})");
                    }
                }
                Cell::Void => assert_eq!(v, 0.0),
            }
        }
        assert!(floors > 0, "{d:?}");
    }
}

/// A room with a lamp of emission 2 in its top wall, walls of reflectance
/// `r` and the lamp's own reflectance `lamp_r`, and two pillars.
fn lamp_room(r: f64, lamp_r: f64) -> Level {
    let rows = [
        "################",
        "#......LL......#",
        "#..............#",
        "#...##.........#",
        "#...##....#....#",
        "#.........#....#",
        "#..............#",
        "################",
    ];
    ascii(&rows, &[('#', wall(r)), ('L', light(2.0, lamp_r))])
}

/// The solve is the same scene at every density: the upscaled level has
/// the same patches (every length scaled with it), so radiosity per patch,
/// and the power balance, agree to rounding — with walls, shadows, a
/// bounce and falloff.
#[test]
fn radiosity_does_not_change_with_the_density() {
    let lvl = lamp_room(0.6, 0.3);
    for falloff in [None, Some(6.0)] {
        let mut settings = Settings::new(Quality::Normal);
        settings.falloff = falloff;
        let plain = bake(&lvl, &settings, &quiet).unwrap();
        for d in [Density::Up(2), Density::Up(4), Density::Down(2)] {
            for samples in [None, Some(3)] {
                let t = at(&lvl, &settings, &texels(d, samples, Walls::Lit));
                let b = &t.baked.radiosity;
                assert_eq!(b[0].len(), plain.radiosity[0].len(), "{d:?}");
                let top = plain.radiosity[0].iter().fold(0.0f64, |a, &v| a.max(v));
                for (x, y) in b[0].iter().zip(&plain.radiosity[0]) {
                    assert!((x - y).abs() <= 1e-9 * top, "{d:?} {falloff:?}: {x} vs {y}");
                }
                let (e0, e1) = (&plain.report.energy, &t.baked.report.energy);
                assert!((e0.emitted - e1.emitted).abs() < 1e-9 * e0.emitted);
                assert!((e0.absorbed - e1.absorbed).abs() < 1e-9 * e0.emitted);
                assert_eq!(t.baked.report.falloff, falloff);
            }
        }
    }
}

/// Direction angle from `p` to `q`.
fn dir(p: [f64; 2], q: [f64; 2]) -> f64 {
    (q[1] - p[1]).atan2(q[0] - p[0])
}

/// The angular interval `[lo, hi]` a convex box subtends from `p` (no wrap
/// in the scenes below: every box lies above `p`, or to its upper left).
fn interval(p: [f64; 2], corners: &[[f64; 2]; 4]) -> (f64, f64) {
    let a = corners.map(|c| dir(p, c));
    (
        a.iter().copied().fold(f64::INFINITY, f64::min),
        a.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    )
}

fn corners(x0: f64, y0: f64, x1: f64, y1: f64) -> [[f64; 2]; 4] {
    [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
}

/// Smallest distance from `v` to the axis-aligned square of side `h` at
/// `(x, y)`.
fn dist_to_square(v: [f64; 2], x: f64, y: f64, h: f64) -> f64 {
    let dx = (x - v[0]).max(v[0] - (x + h)).max(0.0);
    let dy = (y - v[1]).max(v[1] - (y + h)).max(0.0);
    dx.hypot(dy)
}

/// Mean distance from the centre of a unit square to its points:
/// (sqrt 2 + ln(1 + sqrt 2)) / 6.
const MEAN_DISTANCE: f64 = 0.382_597_858_232_106;

/// The area average over texel square `(x, y, h)` of `light`, by a fine
/// midpoint grid of `n x n` (its own error is bounded by the callers).
fn fine_average(light: &dyn Fn([f64; 2]) -> f64, x: f64, y: f64, h: f64, n: usize) -> f64 {
    let mut sum = 0.0;
    for j in 0..n {
        for i in 0..n {
            let p = [
                x + (i as f64 + 0.5) * h / n as f64,
                y + (j as f64 + 0.5) * h / n as f64,
            ];
            sum += light(p);
        }
    }
    sum / (n * n) as f64
}

/// Checks every floor texel of `t` against the exact area average of
/// `light` within the documented midpoint bound `0.383 (h / s) L`, with
/// `L = e/(2 pi) * 2 * sum_v 1/dist(v, texel)` over the scene's corners `v`
/// (every end of a visible stretch is the direction to one of them, and
/// each end moves at 1/r). Returns the largest error over the bound, and
/// the texels checked.
fn check_area_average(
    t: &flatbake_core::bake::TexelBake,
    texel: f64,
    samples: u32,
    e: f64,
    vertices: &[[f64; 2]],
    light: &dyn Fn([f64; 2]) -> f64,
) -> (f64, usize) {
    let (tl, map) = (&t.level, &t.baked.lightmap);
    let (mut worst, mut n) = (0.0f64, 0);
    for ty in 0..tl.height {
        for tx in 0..tl.width {
            let i = ty * tl.width + tx;
            if tl.cells[i] != Cell::Floor {
                continue;
            }
            let (x, y) = (tx as f64 * texel, ty as f64 * texel);
            let lip = e / TAU
                * 2.0
                * vertices
                    .iter()
                    .map(|&v| 1.0 / dist_to_square(v, x, y, texel).max(1e-3))
                    .sum::<f64>();
            let fine_n = 48;
            let exact = fine_average(light, x, y, texel, fine_n);
            let fine_err = MEAN_DISTANCE * texel / fine_n as f64 * lip;
            let bound = MEAN_DISTANCE * texel / samples as f64 * lip + fine_err + 1e-5 * exact;
            let got = map.rgb[i][0] as f64;
            worst = worst.max((got - exact).abs() / bound);
            n += 1;
        }
    }
    (worst, n)
}

/// A lone emitting block: each texel's value is its subtended angle
/// e θ / 2π averaged over the texel's area, within the quadrature bound, at
/// every density and sample count.
#[test]
fn lone_emitter_texels_are_the_area_average_within_the_bound() {
    let mut rows = vec![String::from("...................."); 14];
    for row in &mut rows[1..3] {
        row.replace_range(8..12, "LLLL");
    }
    let e = 3.0;
    let lvl = ascii(&refs(&rows), &[('L', light(e, 0.0))]);
    let block = corners(8.0, 1.0, 12.0, 3.0);
    // Floor texels below the block (y >= 3): the block lies above them.
    let light = |p: [f64; 2]| {
        if p[1] < 3.0 {
            return f64::NAN;
        }
        let (lo, hi) = interval(p, &block);
        e * (hi - lo) / TAU
    };
    let settings = Settings::new(Quality::Normal);
    for (d, samples) in [
        (Density::Down(2), None),
        (Density::Up(1), None),
        (Density::Up(1), Some(4)),
        (Density::Up(2), None),
        (Density::Up(4), None),
    ] {
        let t = at(&lvl, &settings, &texels(d, samples, Walls::Lit));
        let s = texels(d, samples, Walls::Lit).samples();
        let texel = 1.0 / d.value();
        // Only texels wholly below the block's bottom (y >= 3), whose
        // light the closed form above describes.
        let mut below = t.level.clone();
        for ty in 0..below.height {
            if (ty as f64) * texel < 3.0 {
                for tx in 0..below.width {
                    below.cells[ty * below.width + tx] = Cell::Void;
                }
            }
        }
        let t = flatbake_core::bake::TexelBake {
            level: below,
            baked: t.baked,
            scale: t.scale,
        };
        let (worst, n) = check_area_average(&t, texel, s, e, &block, &light);
        assert!(n >= 40, "{d:?}: {n} texels");
        assert!(worst <= 1.0, "{d:?} s={s}: error {worst:.3} of the bound");
    }
}

/// A small light far above a bar casts a shadow whose penumbra is much
/// narrower than a texel: a texel split by it reads the area average (not
/// the lit or the dark side, which one midpoint sample would give), so it
/// lies strictly between its lit and its shadowed neighbour.
#[test]
fn a_texel_split_by_a_shadow_lies_between_the_two_sides() {
    let (w, h) = (40usize, 30usize);
    let rows: Vec<String> = (0..h)
        .map(|y| {
            (0..w)
                .map(|x| {
                    if (2..3).contains(&x) && (2..3).contains(&y) {
                        'L'
                    } else if (20..38).contains(&x) && y == 20 {
                        '#'
                    } else {
                        '.'
                    }
                })
                .collect()
        })
        .collect();
    let e = 50.0;
    let lvl = ascii(&refs(&rows), &[('L', light(e, 0.0)), ('#', wall(0.0))]);
    let lamp = corners(2.0, 2.0, 3.0, 3.0);
    let bar = corners(20.0, 20.0, 38.0, 21.0);
    // Below the bar's bottom (y >= 21): the lamp above-left, the bar between.
    let light = |p: [f64; 2]| {
        let (a0, a1) = interval(p, &lamp);
        let (b0, b1) = interval(p, &bar);
        let hidden = (a1.min(b1) - a0.max(b0)).max(0.0);
        e * (a1 - a0 - hidden) / TAU
    };
    let settings = Settings::new(Quality::Normal);
    let mut verts = lamp.to_vec();
    verts.extend(bar);
    for (d, samples) in [(Density::Up(1), Some(4)), (Density::Up(2), None)] {
        let t = at(&lvl, &settings, &texels(d, samples, Walls::Lit));
        let s = texels(d, samples, Walls::Lit).samples();
        let texel = 1.0 / d.value();
        let (tl, map) = (&t.level, &t.baked.lightmap);
        let mut split = 0;
        for ty in 0..tl.height {
            let y = ty as f64 * texel;
            if !(22.0..27.0).contains(&y) {
                continue;
            }
            for tx in 1..tl.width - 1 {
                let x = tx as f64 * texel;
                if !(20.0..30.0).contains(&x) {
                    continue;
                }
                let centre = light([x + 0.5 * texel, y + 0.5 * texel]);
                let exact = fine_average(&light, x, y, texel, 64);
                let (lit, dark) = (
                    light([x + 0.5 * texel - texel, y + 0.5 * texel]),
                    light([x + 1.5 * texel, y + 0.5 * texel]),
                );
                // A texel the shadow line crosses: its average is well
                // away from its centre's value and from either side.
                if (exact - centre).abs() > 0.2 * lit && exact > dark + 0.1 * lit {
                    split += 1;
                    let got = map.rgb[ty * tl.width + tx][0] as f64;
                    let lip = e / TAU
                        * 2.0
                        * verts
                            .iter()
                            .map(|&v| 1.0 / dist_to_square(v, x, y, texel))
                            .sum::<f64>();
                    let bound = MEAN_DISTANCE * texel / s as f64 * lip + 1e-4 * lit;
                    assert!(
                        (got - exact).abs() <= bound,
                        "{d:?} ({tx},{ty}): {got} vs area average {exact} (bound {bound})"
                    );
                    let left = map.rgb[ty * tl.width + tx - 1][0] as f64;
                    let right = map.rgb[ty * tl.width + tx + 1][0] as f64;
                    assert!(
                        got > right.min(left) + 0.05 * lit && got < right.max(left) - 0.05 * lit,
                        "{d:?} ({tx},{ty}): {got} not between {left} and {right}"
                    );
                }
            }
        }
        assert!(split >= 3, "{d:?}: only {split} texels split by the shadow");
    }
}

/// `--walls`: lit walls carry their radiosity B on exposed faces, glow
/// writes the emission on emitter faces only, dark writes 0; the floor is
/// the same in all three, at every density.
#[test]
fn walls_dark_glow_lit_write_what_they_say() {
    let rows = [
        "##########",
        "#........#",
        "L...##...#",
        "L...##...#",
        "#........#",
        "##########",
    ];
    let (e, r) = (2.0, 0.5);
    let lvl = ascii(&rows, &[('#', wall(r)), ('L', light(e, 0.2))]);
    let settings = Settings::new(Quality::Normal);
    let plain = bake(&lvl, &settings, &quiet).unwrap();
    for d in [Density::Down(2), Density::Up(1), Density::Up(2)] {
        let lit = at(&lvl, &settings, &texels(d, None, Walls::Lit));
        let glow = at(&lvl, &settings, &texels(d, None, Walls::Glow));
        let dark = at(&lvl, &settings, &texels(d, None, Walls::Dark));
        let tl = &lit.level;
        let mut lit_walls = 0;
        for (i, c) in tl.cells.iter().enumerate() {
            let [l, g, k] = [&lit, &glow, &dark].map(|t| t.baked.lightmap.rgb[i][0]);
            match c {
                Cell::Floor => {
                    assert_eq!(l, g, "{d:?} floor {i}");
                    assert_eq!(l, k, "{d:?} floor {i}");
                }
                Cell::Solid(m) => {
                    assert_eq!(k, 0.0, "{d:?} dark wall {i}");
                    if *m == 1 {
                        // An emitter's face glows with its emission; lit, it
                        // carries its B >= e.
                        assert!(g == 0.0 || (g as f64 - e).abs() < 1e-6, "{d:?} {g}");
                        assert!(g == 0.0 || l as f64 >= e - 1e-6, "{d:?} {l}");
                    } else {
                        assert_eq!(g, 0.0, "{d:?} glowing wall {i}");
                        if l > 0.0 {
                            lit_walls += 1;
                        }
                    }
                }
                Cell::Void => {}
            }
        }
        // (At density 1/2 nearly every texel of this small room holds floor.)
        let least = if d == Density::Down(2) { 1 } else { 10 };
        assert!(lit_walls >= least, "{d:?}: {lit_walls} lit wall texels");
    }
    // At density 2, the texels of a wall pixel with one face average to
    // the plain bake's value of that pixel (the face's mean B): each texel
    // carries the face's light at its own stretch of the face.
    let lit2 = at(&lvl, &settings, &texels(Density::Up(2), None, Walls::Lit));
    let mut checked = 0;
    for y in 0..lvl.height {
        for x in 0..lvl.width {
            if !lvl.cells[y * lvl.width + x].is_solid() {
                continue;
            }
            let free = |dx: i32, dy: i32| {
                let (qx, qy) = (x as i32 + dx, y as i32 + dy);
                qx >= 0
                    && qy >= 0
                    && (qx as usize) < lvl.width
                    && (qy as usize) < lvl.height
                    && lvl.cells[qy as usize * lvl.width + qx as usize].is_free()
            };
            let faces = [(-1, 0), (1, 0), (0, -1), (0, 1)]
                .iter()
                .filter(|d| free(d.0, d.1))
                .count();
            if faces != 1 {
                continue;
            }
            let w2 = lit2.level.width;
            let mean: f64 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                .iter()
                .map(|(dx, dy)| lit2.baked.lightmap.rgb[(2 * y + dy) * w2 + 2 * x + dx][0] as f64)
                .sum::<f64>()
                / 4.0;
            let want = plain.lightmap.rgb[y * lvl.width + x][0] as f64;
            assert!(
                (mean - want).abs() <= 1e-5 * want.max(1e-3),
                "wall pixel ({x},{y}): texels {mean} vs {want}"
            );
            checked += 1;
        }
    }
    assert!(checked > 10, "{checked}");
    // At density 1 the lit walls are the plain bake's solid pixels.
    let lit1 = at(
        &lvl,
        &settings,
        &texels(Density::Up(1), Some(1), Walls::Lit),
    );
    assert_eq!(lit1.baked.lightmap.rgb, plain.lightmap.rgb);
    let glow1 = at(&lvl, &settings, &texels(Density::Up(1), None, Walls::Glow));
    for (i, c) in lvl.cells.iter().enumerate() {
        let want = match c {
            Cell::Solid(1) => e as f32,
            Cell::Solid(_) => 0.0,
            _ => plain.lightmap.rgb[i][0],
        };
        assert_eq!(glow1.baked.lightmap.rgb[i][0], want, "pixel {i}");
    }
}

/// With responses (layers, cache), the lightmap is their sum at every
/// density, so a relight with unchanged emission gives it back.
#[test]
fn responses_add_up_to_the_lightmap_at_every_density() {
    let rows = [
        "##########",
        "#........#",
        "L...##...M",
        "#...##...#",
        "##########",
    ];
    let lvl = ascii(
        &rows,
        &[
            ('#', wall(0.5)),
            ('L', light(2.0, 0.2)),
            ('M', light(1.0, 0.2)),
        ],
    );
    let mut settings = Settings::new(Quality::Normal);
    settings.responses = true;
    for d in [Density::Down(2), Density::Up(2), Density::Up(4)] {
        for walls in [Walls::Lit, Walls::Glow] {
            let t = at(&lvl, &settings, &texels(d, None, walls));
            let r = t.baked.responses.as_ref().unwrap();
            assert_eq!((r.width, r.height), (t.level.width, t.level.height));
            let e: Vec<[f64; 3]> = r
                .emitters
                .iter()
                .map(|&m| lvl.materials[m].emission)
                .collect();
            assert_eq!(r.combine(&e), t.baked.lightmap.rgb, "{d:?} {walls:?}");
            // The light is linear in emission: double it, double the map.
            let e2: Vec<[f64; 3]> = e.iter().map(|v| v.map(|x| 2.0 * x)).collect();
            for (a, b) in r.combine(&e2).iter().zip(&t.baked.lightmap.rgb) {
                assert!((a[0] - 2.0 * b[0]).abs() <= 1e-5 * b[0].max(1e-3));
            }
        }
    }
}

/// The stamp spells the options only when they are not the defaults.
#[test]
fn fingerprint_spells_texel_options_only_when_set() {
    let mut opts = flatbake_core::BatchOptions::default();
    let base = opts.fingerprint();
    assert!(!base.contains("texel") && !base.contains("walls"));
    opts.texels.samples = Some(1);
    assert_eq!(opts.fingerprint(), base);
    opts.texels.density = Density::Up(4);
    opts.texels.samples = Some(2);
    assert!(opts.fingerprint().ends_with(" texels-per-pixel 4"));
    opts.texels.samples = Some(3);
    assert!(opts.fingerprint().contains(" texel-samples 3"));
    opts.texels = TexelOptions {
        walls: Walls::Dark,
        ..TexelOptions::default()
    };
    assert!(opts.fingerprint().ends_with(" walls dark"));
}

/// Writes the room with a pillar to `dir` as `room.png` and bakes it into
/// `dir/out` with `args`: the level, the output folder and the run.
fn bake_room(dir: &Path, args: &[&str]) -> (PathBuf, PathBuf, std::process::Output) {
    write_room(dir, "room", true);
    let level = dir.join("room.png");
    let out = dir.join("out");
    let mut all = vec!["bake", s(&level), "-o", s(&out)];
    all.extend_from_slice(args);
    let o = flatbake(&all);
    (level, out, o)
}

/// The binary: a density-4 bake with padding, layers and a cache writes
/// texel-sized images; relighting the cache with unchanged emission gives
/// the same lightmap bytes; the density is refused with its range.
#[test]
fn cli_density_bake_relight_and_padding() {
    let dir = tempfile::tempdir().unwrap();
    let (level, out, o) = bake_room(
        dir.path(),
        &[
            "--texels-per-pixel",
            "4",
            "--padding",
            "4",
            "--cache",
            "--layers",
            "--quiet",
        ],
    );
    assert_exit(&o, EXIT_OK);
    let painted = image::open(&level).unwrap();
    let map = image::open(out.join("room.lightmap.png")).unwrap();
    assert_eq!(map.width(), 4 * painted.width());
    assert_eq!(map.height(), 4 * painted.height());
    let relit = dir.path().join("relit");
    let o = flatbake(&[
        "relight",
        s(&out.join("room.flatbake")),
        "-o",
        s(&relit),
        "--padding",
        "4",
        "--quiet",
    ]);
    assert_exit(&o, EXIT_OK);
    assert_eq!(
        std::fs::read(out.join("room.lightmap.png")).unwrap(),
        std::fs::read(relit.join("room.lightmap.png")).unwrap()
    );
    // A second bake with the same options is up to date; another density is not.
    let again = |d: &str| {
        flatbake(&[
            "bake",
            s(&level),
            "-o",
            s(&out),
            "--texels-per-pixel",
            d,
            "--padding",
            "4",
            "--cache",
            "--layers",
        ])
    };
    assert_says(&again("4"), &["up to date"]);
    let o = again("1/2");
    assert_exit(&o, EXIT_OK);
    let map = image::open(out.join("room.lightmap.png")).unwrap();
    assert_eq!(map.width(), painted.width().div_ceil(2));
    let o = flatbake(&[
        "bake",
        s(&level),
        "-o",
        s(&out),
        "--texels-per-pixel",
        "3/4",
    ]);
    assert_exit(&o, EXIT_USAGE);
    assert_says(&o, &["texels per pixel", "1/16", "not 3/4"]);
}

/// The report tells the painted size, the texel grid and the quadrature
/// points apart, in its JSON fields and in the verbose console line.
#[test]
fn the_report_counts_pixels_texels_and_points_apart() {
    let lvl = lamp_room(0.5, 0.2);
    let settings = Settings::new(Quality::Draft);
    let (w, h) = (lvl.width, lvl.height);
    let floor = lvl.cells.iter().filter(|&&c| c == Cell::Floor).count();
    for (d, samples) in [
        (Density::Up(1), None),
        (Density::Up(2), None),
        (Density::Up(2), Some(3)),
        (Density::Down(2), None),
        (Density::Down(3), Some(2)),
    ] {
        let t = at(&lvl, &settings, &texels(d, samples, Walls::Lit));
        let r = &t.baked.report;
        let s = texels(d, samples, Walls::Lit).samples() as usize;
        let (tw, th) = d.texels(w, h);
        assert_eq!(r.painted_size, [w, h], "{d:?}");
        assert_eq!(r.size, [tw, th], "{d:?}");
        assert_eq!(r.texels_per_pixel, d.value(), "{d:?}");
        let side = match d {
            Density::Up(_) => s,
            Density::Down(m) => m as usize * s,
        };
        assert_eq!(r.points_per_texel as usize, side * side, "{d:?}");
        let floor_texels = t.level.cells.iter().filter(|&&c| c == Cell::Floor).count();
        assert_eq!(r.counts.floor_texels, floor_texels, "{d:?}");
        // The floor points: every painted floor pixel upscaled by k.
        let k = match d {
            Density::Up(n) => n as usize * s,
            Density::Down(_) => s,
        };
        assert_eq!(r.counts.floor_pixels, floor * k * k, "{d:?}");
        let words = r.size_words();
        if d == Density::Up(1) && s == 1 {
            assert_eq!(words, format!("{w} x {h} pixels"));
        } else {
            assert_eq!(
                words,
                format!(
                    "{w} x {h} pixels, {tw} x {th} texels, {} points per texel",
                    side * side
                )
            );
        }
    }
    // The binary says it, and writes the fields.
    let dir = tempfile::tempdir().unwrap();
    let (level, out, o) = bake_room(dir.path(), &["--texels-per-pixel", "2", "--verbose"]);
    assert_exit(&o, EXIT_OK);
    let painted = image::open(&level).unwrap();
    let (pw, ph) = (painted.width(), painted.height());
    let said = format!(
        "size: {pw} x {ph} pixels, {} x {} texels, 4 points per texel",
        2 * pw,
        2 * ph
    );
    let all = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(all.contains(&said), "{said:?} not in:\n{all}");
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("room.report.json")).unwrap()).unwrap();
    assert_eq!(r["painted_size"], serde_json::json!([pw, ph]));
    assert_eq!(r["size"], serde_json::json!([2 * pw, 2 * ph]));
    assert_eq!(r["texels_per_pixel"].as_f64(), Some(2.0));
    assert_eq!(r["points_per_texel"].as_u64(), Some(4));
}
