//! The directional lightmap ([`Settings::directional`](super::Settings::directional)):
//! per pixel and channel, the first circular moments of the incoming light
//! beside the lightmap's mean (docs/transport.md#directional-lightmaps).

use super::{Gathered, Plan};

/// The first circular moments of the light on every pixel: with the
/// lightmap's mean `I = (1/2 pi) integral of L(theta) d theta`, the cosine
/// moment `(1/2 pi) integral of L(theta) cos(theta) d theta` and the sine
/// moment, per RGB channel, `theta` counter-clockwise from `+x` with `+y`
/// up on screen (image rows go down). Linear light, like the lightmap.
///
/// Floor pixels hold the gathered moments; solid and void pixels 0 (a
/// wall's texel holds its radiosity, which comes from no direction).
#[derive(Clone, Debug, PartialEq)]
pub struct Directional {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Row-major cosine moment per channel.
    pub cos: Vec<[f32; 3]>,
    /// Row-major sine moment per channel.
    pub sin: Vec<[f32; 3]>,
}

impl Directional {
    /// All zero.
    pub fn zero(width: usize, height: usize) -> Directional {
        Directional {
            width,
            height,
            cos: vec![[0.0; 3]; width * height],
            sin: vec![[0.0; 3]; width * height],
        }
    }
}

/// The moments of the plan's channel classes out of `gathered`, if it
/// holds moments.
pub fn assemble(
    width: usize,
    height: usize,
    plan: &Plan,
    gathered: &Gathered,
) -> Option<Directional> {
    if !gathered.directional {
        return None;
    }
    let mut d = Directional::zero(width, height);
    let kk = gathered.components;
    if gathered.moments.len() != gathered.reached.len() * 2 * kk {
        return Some(d);
    }
    for (i, p) in gathered.reached.iter().enumerate() {
        let at = p[1] as usize * width + p[0] as usize;
        let m = &gathered.moments[i * 2 * kk..(i + 1) * 2 * kk];
        for c in 0..3 {
            if let Some(k) = plan.channels.class_of[c] {
                let scale = plan.channels.scale[c];
                d.cos[at][c] = finite(m[k] * scale);
                d.sin[at][c] = finite(m[kk + k] * scale);
            }
        }
    }
    Some(d)
}

/// A moment as stored: non-finite values (never expected) become 0, values
/// beyond the f32 range saturate.
fn finite(v: f64) -> f32 {
    if v.is_finite() {
        v.clamp(-(f32::MAX as f64), f32::MAX as f64) as f32
    } else {
        0.0
    }
}
