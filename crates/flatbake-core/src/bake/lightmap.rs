//! The last stage: the lightmap of the level, linear light per pixel — the
//! gathered light on floor pixels, the mean radiosity of their exposed
//! sides on solid pixels (emitters glow), 0 on void — and, for layers and
//! caches, the per-emitter [`Responses`] it is the sum of.

use std::borrow::Cow;

use rayon::prelude::*;

use super::radiosity::{Solved, TRACED_EMISSION};
use super::responses::Responses;
use super::{Ctx, Gathered, Log, Plan, Scene};
use crate::geometry::Geometry;
use crate::level::{Cell, Level};
use crate::transport::Patches;

/// Linear light per pixel, ready to encode.
#[derive(Clone, Debug)]
pub struct Lightmap {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Row-major linear RGB: I(p) on floor pixels, the mean radiosity of the
    /// exposed edges on solid pixels, zero on void pixels.
    pub rgb: Vec<[f32; 3]>,
}

/// The lightmap, the per-emitter responses if planned, and the radiosity
/// per channel per patch.
pub struct Assembled {
    /// The lightmap.
    pub lightmap: Lightmap,
    /// The per-emitter light, when the plan traced it.
    pub responses: Option<Responses>,
    /// Radiosity per channel (R, G, B) per patch; 0 for dark channels.
    pub radiosity: [Vec<f64>; 3],
}

/// Puts the gathered light and the solid pixels' radiosity together.
pub fn assemble(
    ctx: &Ctx,
    scene: &Scene,
    plan: &Plan,
    solved: &Solved,
    gathered: &Gathered,
) -> Assembled {
    let level = ctx.level;
    let (geometry, patches) = (&scene.geometry, &scene.patches);
    let np = patches.len();
    let kk = gathered.components;
    let mut rgb = vec![[0f32; 3]; level.width * level.height];
    for (i, p) in gathered.reached.iter().enumerate() {
        let px = &mut rgb[p[1] as usize * level.width + p[0] as usize];
        for c in 0..3 {
            if let Some(k) = plan.channels.class_of[c] {
                px[c] = light_f32(gathered.values[i * kk + k] * plan.channels.scale[c]);
            }
        }
    }
    let responses = responses(ctx, scene, plan, solved, gathered);
    // Solid pixels: mean radiosity of their exposed sides.
    let radiosity: [Vec<f64>; 3] = std::array::from_fn(|c| {
        plan.channels.class_of[c].map_or_else(
            || vec![0.0; np],
            |k| scaled(&solved.class_b[k], plan.channels.scale[c]).into_owned(),
        )
    });
    solid_pixels(level, geometry, patches, &radiosity, &mut rgb);
    // With responses, the lightmap is their sum at the palette's emission, so
    // that layers (and a relight with unchanged emission) add up to it
    // exactly. It differs from the direct result only where the positivity
    // limiter on patch slopes (`SlopeRows::slopes`) acts differently on one
    // emitter's light than on the sum, a small fraction of a percent.
    if let Some(r) = &responses {
        let e: Vec<[f64; 3]> = r
            .emitters
            .iter()
            .map(|&m| level.materials[m].emission)
            .collect();
        rgb = r.combine(&e);
    }
    Assembled {
        lightmap: Lightmap {
            width: level.width,
            height: level.height,
            rgb,
        },
        responses,
        radiosity,
    }
}

/// `b` times `k` (`b` itself where `k` is 1).
pub(super) fn scaled(b: &[f64], k: f64) -> Cow<'_, [f64]> {
    if k == 1.0 {
        Cow::Borrowed(b)
    } else {
        Cow::Owned(b.iter().map(|v| v * k).collect())
    }
}

/// The per-emitter images of the responses the plan traced, at unit
/// emission: the gathered light on floor pixels, the radiosity of their
/// exposed sides on solid pixels.
fn responses(
    ctx: &Ctx,
    scene: &Scene,
    plan: &Plan,
    solved: &Solved,
    gathered: &Gathered,
) -> Option<Responses> {
    let level = ctx.level;
    let (geometry, patches) = (&scene.geometry, &scene.patches);
    let np = patches.len();
    let kk = gathered.components;
    let k_main = solved.class_b.len();
    plan.responses.as_ref().map(|rp| {
        let n = level.width * level.height;
        let zeros = vec![0.0; np];
        let images = solved
            .responses
            .iter()
            .enumerate()
            .map(|(j, r)| {
                let mut img = vec![[0f32; 3]; n];
                for (i, p) in gathered.reached.iter().enumerate() {
                    img[p[1] as usize * level.width + p[0] as usize][0] =
                        gathered.values[i * kk + k_main + j] as f32;
                }
                let one = [r.b.clone(), zeros.clone(), zeros.clone()];
                solid_pixels(level, geometry, patches, &one, &mut img);
                img.iter()
                    .map(|v| (v[0] as f64 / TRACED_EMISSION) as f32)
                    .collect()
            })
            .collect();
        // The moments of each response, per unit emission, when asked for.
        let moments =
            if gathered.directional && gathered.moments.len() == gathered.reached.len() * 2 * kk {
                (0..solved.responses.len())
                    .map(|j| {
                        let mut img = vec![[0f32; 2]; n];
                        for (i, p) in gathered.reached.iter().enumerate() {
                            let m = &gathered.moments[i * 2 * kk..(i + 1) * 2 * kk];
                            img[p[1] as usize * level.width + p[0] as usize] = [
                                (m[k_main + j] / TRACED_EMISSION) as f32,
                                (m[kk + k_main + j] / TRACED_EMISSION) as f32,
                            ];
                        }
                        img
                    })
                    .collect()
            } else {
                Vec::new()
            };
        Responses {
            width: level.width,
            height: level.height,
            emitters: rp.emitters.clone(),
            rho_class_of: rp.rho_class_of,
            rho_classes: rp.rho_reps.len(),
            images,
            traced_emission: TRACED_EMISSION,
            moments,
        }
    })
}

/// Never hands out NaN or negative light: clamps it to 0, with a warning
/// where it is more than `allowed` below 0 (it would be a bug upstream).
/// `allowed` is what the gather's approximations may take from a pixel
/// ([`super::light::approximation_bound`]).
pub fn clamp(lightmap: &mut Lightmap, allowed: f64, log: &mut Log) {
    // The fast gather sums closed-form moments of each visible piece, terms
    // of the size of the brightest light that nearly cancel for a far or
    // faint piece (a tiny falloff): a pixel that receives almost nothing can
    // come out a rounding error below 0 (seen down to -6e-11 of the
    // brightest pixel). And a merged run of distant patches is a parabola
    // within the preset's bound of their light, which may dip below 0 over
    // a nearly dark pixel (seen down to -5.6e-7 of the brightest emission
    // with a bound of 1e-5). Both are set to 0 without a word; anything
    // further below 0, or not finite, is a fault worth reporting.
    // (On the workers: each pass is a few ms on one core at 512 px.)
    let brightest = lightmap
        .rgb
        .par_iter()
        .flatten()
        .filter(|v| v.is_finite())
        .copied()
        .reduce(|| 0f32, f32::max);
    let silent = (ROUNDING_BELOW_ZERO * brightest).max(allowed as f32);
    let bad = |v: &f32| !v.is_finite() || *v < -silent;
    if lightmap.rgb.par_iter().any(|p| p.iter().any(bad)) {
        log.warn("non-finite or negative light was clamped to 0 (please report this level)");
    }
    lightmap.rgb.par_iter_mut().flatten().for_each(|v| {
        if !v.is_finite() || *v < 0.0 {
            *v = 0.0;
        }
    });
}

/// How far below 0, relative to the brightest pixel, a pixel's light may
/// round before it counts as a fault (f32 itself resolves 6e-8 of a value).
pub const ROUNDING_BELOW_ZERO: f32 = 1e-9;

/// Light as stored in the lightmap: values beyond the f32 range saturate at
/// the largest f32 instead of becoming infinite (which the final check would
/// clamp to black); NaN stays NaN so that the check still catches it.
fn light_f32(v: f64) -> f32 {
    if v > f32::MAX as f64 {
        f32::MAX
    } else {
        v as f32
    }
}

/// Fills solid pixels with the mean radiosity of their exposed sides.
fn solid_pixels(
    level: &Level,
    g: &Geometry,
    patches: &Patches,
    b: &[Vec<f64>; 3],
    rgb: &mut [[f32; 3]],
) {
    let w = level.width;
    // Sums only for the solid pixels with an exposed side (a slot each, in
    // the order they are met), not for every pixel of the level.
    let mut slot = vec![u32::MAX; level.width * level.height];
    let mut sum: Vec<[f64; 3]> = Vec::new();
    let mut count: Vec<u32> = Vec::new();
    for (ei, e) in g.edges.iter().enumerate() {
        let (lo, hi) = e.extent();
        let range = patches.of_edge(ei);
        let step = patches.step[ei];
        for u in lo as i32..hi as i32 {
            let px = e.solid_pixel_at(u);
            let at = &mut slot[px[1] as usize * w + px[0] as usize];
            if *at == u32::MAX {
                *at = sum.len() as u32;
                sum.push([0.0; 3]);
                count.push(0);
            }
            let i = *at as usize;
            if range.is_empty() {
                // A side facing a region no light reaches: radiosity 0.
                count[i] += 1;
                continue;
            }
            // Length-weighted mean of the patches covering [u, u + 1].
            let (a, bnd) = (u as f64, u as f64 + 1.0);
            let k0 = (((a - lo) / step).floor() as usize).min(range.len() - 1);
            let mut v = [0f64; 3];
            let mut k = k0;
            while k < range.len() {
                let (s0, s1) = (lo + k as f64 * step, lo + (k + 1) as f64 * step);
                let ov = s1.min(bnd) - s0.max(a);
                if ov > 0.0 {
                    for c in 0..3 {
                        v[c] += ov * b[c][range.start + k];
                    }
                }
                if s1 >= bnd {
                    break;
                }
                k += 1;
            }
            for c in 0..3 {
                sum[i][c] += v[c];
            }
            count[i] += 1;
        }
    }
    for (i, cell) in level.cells.iter().enumerate() {
        let j = slot[i] as usize;
        if matches!(cell, Cell::Solid(_)) && slot[i] != u32::MAX && count[j] > 0 {
            rgb[i] = [0, 1, 2].map(|c| light_f32(sum[j][c] / count[j] as f64));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clamped(values: &[f32], allowed: f64) -> (Vec<f32>, bool) {
        let mut map = Lightmap {
            width: values.len(),
            height: 1,
            rgb: values.iter().map(|&v| [v, 1.0, 0.5]).collect(),
        };
        let mut log = Log::default();
        clamp(&mut map, allowed, &mut log);
        let warned = log.warnings.iter().any(|w| w.contains("clamped"));
        (map.rgb.iter().map(|p| p[0]).collect(), warned)
    }

    /// Rounding below 0 and light within the approximations' bound below 0
    /// are set to 0 silently; light further below 0, or not finite, is set
    /// to 0 with a warning; light at or above 0 is untouched.
    #[test]
    fn clamps_to_zero_and_warns_only_past_the_bounds() {
        // Brightest 10: rounding is 1e-8 below 0.
        assert_eq!(
            clamped(&[10.0, 0.25, -5e-9], 0.0),
            (vec![10.0, 0.25, 0.0], false)
        );
        assert_eq!(clamped(&[10.0, -1e-6], 0.0), (vec![10.0, 0.0], true));
        assert_eq!(clamped(&[10.0, -1e-6], 1e-4), (vec![10.0, 0.0], false));
        assert_eq!(clamped(&[10.0, -1e-3], 1e-4), (vec![10.0, 0.0], true));
        assert_eq!(clamped(&[10.0, f32::NAN], 1e-4), (vec![10.0, 0.0], true));
        assert_eq!(
            clamped(&[10.0, f32::INFINITY], 1.0),
            (vec![10.0, 0.0], true)
        );
    }
}
