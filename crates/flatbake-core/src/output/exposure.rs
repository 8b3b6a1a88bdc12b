//! How bright the PNG lightmaps come out: the share of the floor clipped at
//! full scale for an exposure, and the exposure `--exposure auto` chooses.
//!
//! Clipping is counted on floor pixels only (emitters glow far above full
//! scale by design): a floor pixel is clipped when some channel of its PNG
//! lightmap value is at the largest code (255 in 8 bits). The automatic
//! exposure puts the 99th percentile of the floor's brightness (the
//! brightest channel of each floor pixel) at [`AUTO_TARGET`] of full scale
//! in the encoded image, so at most about 1 % of the floor can clip.

use super::Depth;
use super::image::{srgb8, srgb16};
use crate::bake::Lightmap;
use crate::bake::checks::{BLACK, CLIPPED};
use crate::bake::report::Problem;
use crate::level::{Cell, Level};

/// How the exposure of the PNG lightmaps is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exposure {
    /// This factor (finite, > 0).
    Fixed(f64),
    /// From the level's own light: see [`auto_exposure`].
    Auto,
}

/// Where the automatic exposure puts the 99th percentile of the floor's
/// brightness, as a fraction of the encoded full scale (the sRGB code,
/// not linear light).
pub const AUTO_TARGET: f64 = 0.9;

/// The percentile of the floor's brightness that the automatic exposure
/// places at [`AUTO_TARGET`].
pub const AUTO_PERCENTILE: f64 = 0.99;

/// A floor clipped over more than this fraction of its pixels is a problem
/// ([`clipping_problem`]).
pub const CLIPPED_PROBLEM: f64 = 0.10;

/// The brightest channel of each floor pixel, in linear light.
fn floor_brightness(level: &Level, map: &Lightmap) -> Vec<f32> {
    level
        .cells
        .iter()
        .zip(&map.rgb)
        .filter(|(c, _)| **c == Cell::Floor)
        .map(|(_, p)| {
            p.iter()
                .map(|&v| if v.is_finite() && v > 0.0 { v } else { 0.0 })
                .fold(0.0, f32::max)
        })
        .collect()
}

/// The smallest linear value that encodes to the largest code at `depth`.
fn full_scale(depth: Depth) -> f64 {
    let top = |x: f64| match depth {
        Depth::Eight => srgb8(x) == u8::MAX,
        Depth::Sixteen => srgb16(x) == u16::MAX,
    };
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if top(mid) { hi = mid } else { lo = mid }
    }
    hi
}

/// The fraction of floor pixels whose PNG lightmap value at `exposure` is
/// at full scale in some channel (0 for a level without floor).
pub fn clipped_fraction(level: &Level, map: &Lightmap, exposure: f64, depth: Depth) -> f64 {
    let b = floor_brightness(level, map);
    if b.is_empty() {
        return 0.0;
    }
    let limit = full_scale(depth);
    let clipped = b.iter().filter(|&&v| v as f64 * exposure >= limit).count();
    clipped as f64 / b.len() as f64
}

/// The exposure that puts the 99th percentile of the floor's brightness at
/// [`AUTO_TARGET`] of full scale, rounded down to three significant digits;
/// 1 when the floor is black or missing.
pub fn auto_exposure(level: &Level, map: &Lightmap) -> f64 {
    let mut b = floor_brightness(level, map);
    if b.is_empty() {
        return 1.0;
    }
    let k = ((b.len() - 1) as f64 * AUTO_PERCENTILE).round() as usize;
    let (_, p, _) = b.select_nth_unstable_by(k, f32::total_cmp);
    let p = *p as f64;
    if !(p > 0.0 && p.is_finite()) {
        return 1.0;
    }
    // The linear value whose sRGB code is AUTO_TARGET of full scale.
    let target = srgb_to_linear_f(AUTO_TARGET);
    round_down_3(target / p)
}

/// The sRGB curve's inverse for an encoded value in `0..=1`.
fn srgb_to_linear_f(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// `x` rounded down to three significant digits (positive, finite `x`).
fn round_down_3(x: f64) -> f64 {
    let scale = 10f64.powi(2 - x.log10().floor() as i32);
    let r = (x * scale).floor() / scale;
    if r > 0.0 && r.is_finite() { r } else { x }
}

/// The problem of a mostly clipped floor, with the exposure that would fix
/// it; `None` when at most [`CLIPPED_PROBLEM`] of the floor is clipped.
pub fn clipping_problem(clipped: f64, exposure: f64, auto: Option<f64>) -> Option<Problem> {
    if clipped <= CLIPPED_PROBLEM {
        return None;
    }
    let fix = match auto {
        Some(a) => format!(" (it would choose {a} here)"),
        None => String::new(),
    };
    Some(Problem {
        kind: CLIPPED.into(),
        message: format!(
            "{:.1}% of the floor is clipped at full brightness (255) in the lightmap PNG at \
             exposure {exposure}: detail there is lost. Lower the exposure or the lamps' \
             emission, or bake with --exposure auto{fix}",
            100.0 * clipped
        ),
    })
}

/// The problem of a floor that has light but shows none at `exposure`
/// (every floor pixel encodes to 0); `None` otherwise.
pub fn too_dark_problem(level: &Level, map: &Lightmap, exposure: f64) -> Option<Problem> {
    let b = floor_brightness(level, map);
    let brightest = b.iter().copied().fold(0.0, f32::max) as f64;
    if brightest <= 0.0 || srgb8(brightest * exposure) > 0 {
        return None;
    }
    Some(Problem {
        kind: BLACK.into(),
        message: format!(
            "the lightmap PNG is black at exposure {exposure}: the brightest floor pixel is \
             {brightest:.3e}, too faint to show. Raise the exposure or the lamps' emission, or \
             bake with --exposure auto (it would choose {})",
            auto_exposure(level, map)
        ),
    })
}
