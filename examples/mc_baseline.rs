//! What a user would write instead of flatbake: a Monte Carlo ray caster on
//! the pixel grid, with flatbake's physics (docs/transport.md), and how long
//! it takes to be as accurate.
//!
//! ```text
//! cargo build --release --examples && target/release/examples/mc_baseline [--size N] [--seed S] [--target ERR] [--max-rays N] [--level PATH] [--validate-only]
//! ```
//!
//! The caster: every floor pixel centre sends `n` rays stratified in angle
//! (one jittered ray per `2 pi / n`), for
//! `I(p) = 1/(2 pi) * integral of B(first hit) w(r) d psi`. Rays march with
//! an exact grid DDA to the first solid pixel; the side crossed is the edge
//! hit, its pixel's material gives emission and reflectance per channel. At
//! a wall the path goes on in a cosine-distributed direction (flatland
//! Lambert, pdf `cos(theta) / 2` on `(-pi/2, pi/2)`), so one continuation
//! estimates `B = eps + rho * w(r) * B(next hit)`; the first bounce's
//! directions are stratified too (Latin hypercube against the first ray's
//! strata). Paths end at the bounce count of the palette's `bounces` when
//! it has one, else by Russian roulette (unbiased: the infinite series that
//! flatbake solves). Light off the image is lost; void passes light. Falloff
//! is `w(r) = A / (A + r^2)`, `A = falloff^2`, at every segment. Pixels run in
//! parallel with rayon; each pixel's random stream is seeded by its index,
//! so the image does not depend on the thread count.
//!
//! First the caster is checked against closed forms and against flatbake: a
//! closed room of emitting, reflecting walls (`I = e / (1 - r)`) and a lone
//! emitting block (`I = e phi / (2 pi)`). Then the driver, on the one-pixel
//! maze (`synth::maze(size, size, 1, seed)`, or `--level`), bakes flatbake's
//! `reference` in process, times the caster at doubling ray counts until its
//! relative RMS error (as `flatbake_core::accuracy::compare` computes it)
//! is at most `--target` (default 1 %), times flatbake at `draft`, `normal`
//! and `high`, and prints both error-against-time tables and the time ratio
//! at equal error.

use std::f64::consts::TAU;
use std::path::PathBuf;
use std::time::Instant;

use flatbake_core::accuracy::compare;
use flatbake_core::bake::{Settings, bake};
use flatbake_core::level::palette::Palette;
use flatbake_core::level::{Cell, Level, LoadLimits, load_level};
use flatbake_core::quality::Quality;
use flatbake_synth::{self as synth, Canvas, Floor, Painted, PaletteBuilder, Rect, Rng, VOID};
use rayon::prelude::*;

/// The level as the caster sees it.
struct Scene {
    w: i32,
    h: i32,
    /// Material index per pixel, `-1` for free pixels (floor and void).
    solid: Vec<i32>,
    floor: Vec<bool>,
    eps: Vec<[f64; 3]>,
    rho: Vec<[f64; 3]>,
    /// `falloff^2`, or `None` for no falloff.
    a: Option<f64>,
    /// Truncate after this many bounces (flatbake's `bounces`).
    bounces: Option<u32>,
}

impl Scene {
    fn new(level: &Level, falloff: Option<f64>, bounces: Option<u32>) -> Scene {
        Scene {
            w: level.width as i32,
            h: level.height as i32,
            solid: level
                .cells
                .iter()
                .map(|c| match c {
                    Cell::Solid(m) => *m as i32,
                    _ => -1,
                })
                .collect(),
            floor: level.cells.iter().map(|c| *c == Cell::Floor).collect(),
            eps: level.materials.iter().map(|m| m.emission).collect(),
            rho: level.materials.iter().map(|m| m.reflectance).collect(),
            // As flatbake: falloffs above 1e100 px act as 1e100.
            a: falloff.map(|f| f.min(1e100).powi(2)),
            bounces,
        }
    }

    fn weight(&self, r: f64) -> f64 {
        match self.a {
            Some(a) => a / (a + r * r),
            None => 1.0,
        }
    }
}

/// Where a ray first meets a solid pixel.
struct Hit {
    /// Distance along the (unit) direction.
    t: f64,
    /// The solid pixel.
    x: i32,
    y: i32,
    /// Outward normal of the side hit, into the free pixel the ray came from.
    n: (i32, i32),
    material: usize,
}

/// Exact grid DDA from `(ox, oy)` in free pixel `(px, py)` along the unit
/// direction `(dx, dy)`; `None` when the ray leaves the image.
fn trace(
    s: &Scene,
    (ox, oy): (f64, f64),
    (px, py): (i32, i32),
    (dx, dy): (f64, f64),
) -> Option<Hit> {
    let (mut x, mut y) = (px, py);
    let (sx, sy) = (if dx > 0.0 { 1 } else { -1 }, if dy > 0.0 { 1 } else { -1 });
    let (tdx, tdy) = (1.0 / dx.abs(), 1.0 / dy.abs());
    // Ray parameter of the first pixel boundary crossed along one axis.
    let first = |cell: i32, o: f64, d: f64| {
        if d > 0.0 {
            (cell as f64 + 1.0 - o) / d
        } else if d < 0.0 {
            (cell as f64 - o) / d
        } else {
            f64::INFINITY
        }
    };
    let (mut tmx, mut tmy) = (first(x, ox, dx), first(y, oy, dy));
    loop {
        let (t, n) = if tmx < tmy {
            x += sx;
            let t = tmx;
            tmx += tdx;
            (t, (-sx, 0))
        } else {
            y += sy;
            let t = tmy;
            tmy += tdy;
            (t, (0, -sy))
        };
        if x < 0 || y < 0 || x >= s.w || y >= s.h {
            return None;
        }
        let m = s.solid[(y * s.w + x) as usize];
        if m >= 0 {
            return Some(Hit {
                t,
                x,
                y,
                n,
                material: m as usize,
            });
        }
    }
}

/// Light arriving along one ray from `o` (in free pixel `p`) in direction
/// `d`: the first hit's radiosity times the falloff, estimated by one path.
/// `u1` is the (stratified) sample for the first bounce's direction.
fn radiance(
    s: &Scene,
    o: (f64, f64),
    p: (i32, i32),
    d: (f64, f64),
    u1: f64,
    rng: &mut Rng,
) -> [f64; 3] {
    let mut out = [0.0; 3];
    let mut thr = [1.0f64; 3];
    let (mut o, mut p, mut d) = (o, p, d);
    let mut depth = 0u32;
    loop {
        let Some(hit) = trace(s, o, p, d) else {
            return out;
        };
        let w = s.weight(hit.t);
        let (eps, rho) = (s.eps[hit.material], s.rho[hit.material]);
        for k in 0..3 {
            thr[k] *= w;
            out[k] += thr[k] * eps[k];
            thr[k] *= rho[k];
        }
        if s.bounces.is_some_and(|b| depth >= b) {
            return out;
        }
        let m = thr[0].max(thr[1]).max(thr[2]);
        if m <= 0.0 {
            return out;
        }
        if s.bounces.is_none() && depth >= 2 {
            // Russian roulette, survival in proportion to the throughput.
            let q = m.min(1.0);
            if rng.unit() >= q {
                return out;
            }
            for t in &mut thr {
                *t /= q;
            }
        }
        // The path goes on from the hit point, in the free pixel in front of
        // the side hit, in a cosine-distributed direction about its normal.
        o = (o.0 + hit.t * d.0, o.1 + hit.t * d.1);
        p = (hit.x + hit.n.0, hit.y + hit.n.1);
        let u = if depth == 0 { u1 } else { rng.unit() };
        let theta = (2.0 * u - 1.0).clamp(-1.0, 1.0).asin();
        let (n, tan) = (
            (hit.n.0 as f64, hit.n.1 as f64),
            (-(hit.n.1 as f64), hit.n.0 as f64),
        );
        let (c, sn) = (theta.cos(), theta.sin());
        d = (n.0 * c + tan.0 * sn, n.1 * c + tan.1 * sn);
        depth += 1;
    }
}

/// The caster's lightmap: `rays` stratified rays per floor pixel (0 on solid
/// and void pixels, which the comparison skips).
fn render(s: &Scene, rays: usize, seed: u64) -> Vec<[f32; 3]> {
    let n = rays.max(1);
    let w = s.w as usize;
    let mut out = vec![[0.0f32; 3]; s.solid.len()];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let mut perm: Vec<usize> = (0..n).collect();
        for (x, px) in row.iter_mut().enumerate() {
            let i = y * w + x;
            if !s.floor[i] {
                continue;
            }
            let mut rng = Rng::new(seed ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
            // Latin hypercube: the first bounce's strata, shuffled against
            // the first ray's.
            for j in (1..n).rev() {
                perm.swap(j, rng.below(j as u64 + 1) as usize);
            }
            let o = (x as f64 + 0.5, y as f64 + 0.5);
            let mut sum = [0.0f64; 3];
            for (k, &pk) in perm.iter().enumerate() {
                let a = TAU * (k as f64 + rng.unit()) / n as f64;
                let u1 = (pk as f64 + rng.unit()) / n as f64;
                let l = radiance(s, o, (x as i32, y as i32), (a.cos(), a.sin()), u1, &mut rng);
                for c in 0..3 {
                    sum[c] += l[c];
                }
            }
            *px = sum.map(|v| (v / n as f64) as f32);
        }
    });
    out
}

/// flatbake's lightmap at `quality` and its bake time (in process).
fn flatbake(
    level: &Level,
    palette: &Palette,
    quality: Quality,
) -> anyhow::Result<(Vec<[f32; 3]>, f64)> {
    let mut st = Settings::new(quality);
    st.falloff = palette.settings.falloff;
    st.bounces = palette.settings.bounces;
    let t = Instant::now();
    let b = bake(level, &st, &|_| {})?;
    Ok((b.lightmap.rgb, t.elapsed().as_secs_f64()))
}

/// Relative RMS error in percent, as `flatbake sweep` computes it.
fn err(level: &Level, a: &[[f32; 3]], reference: &[[f32; 3]]) -> f64 {
    100.0 * compare(level, a, reference).0
}

/// A closed-form answer per floor pixel, as a lightmap.
fn exact(level: &Level, f: impl Fn(usize, usize) -> f64) -> Vec<[f32; 3]> {
    (0..level.cells.len())
        .map(|i| {
            if level.cells[i] == Cell::Floor {
                let v = f(i % level.width, i / level.width) as f32;
                [v; 3]
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

fn mean_floor(level: &Level, a: &[[f32; 3]]) -> f64 {
    let v: Vec<f64> = level
        .cells
        .iter()
        .zip(a)
        .filter(|(c, _)| **c == Cell::Floor)
        .map(|(_, p)| p[0] as f64)
        .collect();
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// A closed room, 40 x 30 px, whose 1 px walls all emit `e = 1` and reflect
/// `r = 0.5`: every floor pixel reads `e / (1 - r) = 2`.
fn closed_room() -> Painted {
    let mut pal = PaletteBuilder::new("Closed room: every wall emits 1 and reflects 0.5.");
    let wall = pal.emitter("glowing walls", 0xfff0d0, 1.0, Some(0.5.into()));
    let mut c = Canvas::new(40, 30, VOID, 1);
    c.floor(Rect::new(0, 0, 40, 30), Floor::Plain { base: 0xa8a498 });
    c.outline_rect(Rect::new(0, 0, 40, 30), 1, wall);
    Painted::new("closed_room", c, &pal)
}

/// A lone 4 x 4 emitting block (`e = 1`, no reflection) on a 64 x 64 floor
/// with nothing else: a pixel that sees it under the angle `phi` reads
/// `phi / (2 pi)`.
fn lone_emitter() -> Painted {
    let mut pal = PaletteBuilder::new("Lone emitter: a 4 x 4 block, emission 1.");
    let light = pal.emitter("block", 0xfff0d0, 1.0, None);
    let mut c = Canvas::new(64, 64, VOID, 1);
    c.floor(Rect::new(0, 0, 64, 64), Floor::Plain { base: 0xa8a498 });
    c.fill_rect(Rect::new(30, 30, 4, 4), light);
    Painted::new("lone_emitter", c, &pal)
}

/// The angle under which the square `[x0, x1] x [y0, y1]` is seen from `p`
/// outside it.
fn square_angle(p: (f64, f64), (x0, y0, x1, y1): (f64, f64, f64, f64)) -> f64 {
    let c = ((x0 + x1) / 2.0 - p.0, (y0 + y1) / 2.0 - p.1);
    let rel = |q: (f64, f64)| {
        let v = (q.0 - p.0, q.1 - p.1);
        (c.0 * v.1 - c.1 * v.0).atan2(c.0 * v.0 + c.1 * v.1)
    };
    let a = [rel((x0, y0)), rel((x1, y0)), rel((x0, y1)), rel((x1, y1))];
    a.iter().copied().fold(f64::MIN, f64::max) - a.iter().copied().fold(f64::MAX, f64::min)
}

/// A closed-form answer for floor pixel `(x, y)`.
type Exact = dyn Fn(usize, usize) -> f64;

fn validate(rays: usize) -> anyhow::Result<()> {
    println!("### Agreement in the limit ({rays} rays per pixel)\n");
    println!(
        "| scene | closed form | MC mean | MC err vs closed form | flatbake normal err | flatbake reference err | MC err vs flatbake reference |"
    );
    println!("|---|---|---|---|---|---|---|");
    let cases: [(Painted, Box<Exact>, String); 2] = [
        (
            closed_room(),
            Box::new(|_, _| 2.0),
            "e / (1 - r) = 2".into(),
        ),
        (
            lone_emitter(),
            Box::new(|x, y| {
                square_angle((x as f64 + 0.5, y as f64 + 0.5), (30.0, 30.0, 34.0, 34.0)) / TAU
            }),
            "e phi / (2 pi)".into(),
        ),
    ];
    for (p, f, form) in cases {
        let (level, palette) = p.level()?;
        let truth = exact(&level, f);
        let scene = Scene::new(&level, palette.settings.falloff, palette.settings.bounces);
        let mc = render(&scene, rays, 7);
        let (normal, _) = flatbake(&level, &palette, Quality::Normal)?;
        let (reference, _) = flatbake(&level, &palette, Quality::Reference)?;
        println!(
            "| {} | {form} | {:.5} (exact {:.5}) | {:.3}% | {:.4}% | {:.4}% | {:.3}% |",
            p.name,
            mean_floor(&level, &mc),
            mean_floor(&level, &truth),
            err(&level, &mc, &truth),
            err(&level, &normal, &truth),
            err(&level, &reference, &truth),
            err(&level, &mc, &reference),
        );
    }
    Ok(())
}

struct Args {
    size: usize,
    seed: u64,
    target: f64,
    max_rays: usize,
    level: Option<PathBuf>,
    validate_only: bool,
    validate_rays: usize,
}

fn parse() -> anyhow::Result<Args> {
    let mut a = Args {
        size: 128,
        seed: 11,
        target: 1.0,
        max_rays: 1 << 16,
        level: None,
        validate_only: false,
        validate_rays: 4096,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut val = || {
            it.next()
                .ok_or_else(|| anyhow::anyhow!("{flag} needs a value"))
        };
        match flag.as_str() {
            "--size" => a.size = val()?.parse()?,
            "--seed" => a.seed = val()?.parse()?,
            "--target" => a.target = val()?.parse()?,
            "--max-rays" => a.max_rays = val()?.parse()?,
            "--validate-rays" => a.validate_rays = val()?.parse()?,
            "--level" => a.level = Some(val()?.into()),
            "--validate-only" => a.validate_only = true,
            _ => anyhow::bail!(
                "usage: mc_baseline [--size N] [--seed S] [--target PERCENT] [--max-rays N] [--validate-rays N] [--level PATH] [--validate-only]"
            ),
        }
    }
    Ok(a)
}

fn main() -> anyhow::Result<()> {
    let args = parse()?;
    let load = || std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "mc_baseline: {} threads, load average at start {}\n",
        rayon::current_num_threads(),
        load()
            .split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    validate(args.validate_rays)?;
    if args.validate_only {
        return Ok(());
    }

    let (level, palette) = match &args.level {
        Some(path) => {
            let palette = Palette::resolve_for_level(path, None)?;
            (load_level(path, &palette, LoadLimits::default())?, palette)
        }
        None => synth::maze(args.size, args.size, 1, args.seed).level()?,
    };
    let floor = level.cells.iter().filter(|c| **c == Cell::Floor).count();
    println!(
        "\n### {} ({}x{}, {floor} floor pixels, falloff {:?}, bounces {:?}): error against flatbake `reference`\n",
        level.name, level.width, level.height, palette.settings.falloff, palette.settings.bounces
    );
    let t = Instant::now();
    let (reference, ref_s) = flatbake(&level, &palette, Quality::Reference)?;
    println!(
        "reference baked in {ref_s:.2} s ({:.2} s with the level's tracing)\n",
        t.elapsed().as_secs_f64()
    );

    println!("flatbake (in process, bake only):\n");
    println!("| preset | s | rel RMS err |");
    println!("|---|---|---|");
    let mut fb_at_target = None;
    for q in [Quality::Draft, Quality::Normal, Quality::High] {
        // Best of two: the first bake of a preset pays for warm-up.
        let (img, t1) = flatbake(&level, &palette, q)?;
        let (_, t2) = flatbake(&level, &palette, q)?;
        let (secs, e) = (t1.min(t2), err(&level, &img, &reference));
        println!("| {} | {secs:.3} | {e:.3}% |", q.name());
        if e <= args.target && fb_at_target.is_none() {
            fb_at_target = Some((q.name(), secs, e));
        }
    }

    let scene = Scene::new(&level, palette.settings.falloff, palette.settings.bounces);
    println!(
        "\nMonte Carlo (stratified rays per floor pixel, Russian roulette unless the palette sets bounces):\n"
    );
    println!("| rays / px | s | rel RMS err | err x sqrt(s) |");
    println!("|---|---|---|---|");
    let mut mc_at_target = None;
    let mut last = None;
    let mut rays = 16;
    while rays <= args.max_rays {
        let t = Instant::now();
        let img = render(&scene, rays, args.seed);
        let secs = t.elapsed().as_secs_f64();
        let e = err(&level, &img, &reference);
        println!("| {rays} | {secs:.3} | {e:.3}% | {:.3} |", e * secs.sqrt());
        last = Some((rays, secs, e));
        if e <= args.target {
            mc_at_target = Some((rays, secs, e));
            break;
        }
        rays *= 2;
    }

    println!("\n### Equal error ({}% relative RMS)\n", args.target);
    match fb_at_target {
        Some((q, s, e)) => println!("- flatbake: `{q}`, {s:.3} s ({e:.3}%)"),
        None => println!(
            "- flatbake: no preset up to `high` reaches {}%",
            args.target
        ),
    }
    match mc_at_target {
        Some((r, s, e)) => println!("- Monte Carlo: {r} rays / px, {s:.3} s ({e:.3}%)"),
        None => println!("- Monte Carlo: not reached by {} rays / px", args.max_rays),
    }
    // Monte Carlo error falls as 1 / sqrt(time): the time at exactly the
    // target, from the last measured point.
    if let Some((_, s, e)) = last {
        let t_exact = s * (e / args.target).powi(2);
        println!(
            "- Monte Carlo time at exactly {}% (error ~ 1 / sqrt(time) from the last row): {t_exact:.3} s",
            args.target
        );
        if let Some((_, fs, _)) = fb_at_target {
            if let Some((_, ms, _)) = mc_at_target {
                println!(
                    "- ratio Monte Carlo / flatbake at equal error: {:.1}x measured, {:.1}x at exactly {}%",
                    ms / fs,
                    t_exact / fs,
                    args.target
                );
            } else {
                println!(
                    "- ratio Monte Carlo / flatbake at equal error: at least {:.1}x (extrapolated {:.1}x)",
                    s / fs,
                    t_exact / fs
                );
            }
        }
    }
    println!(
        "\nload average at end {}",
        load()
            .split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    Ok(())
}
