//! The light of every emitter on its own: what light layers and the relight
//! cache are made of. Light is linear in emission, so any emission's
//! lightmap is a weighted sum of these images.

/// The light of every emitter material on its own, per reflectance class:
/// because light is linear in emission, the lightmap for any emission is
/// `sum over emitters m of emission_m[c] * image(m, rho_class_of[c])`.
///
/// Images are row-major `width * height` per unit emission (floor pixels:
/// gathered light; solid pixels: mean radiosity of their exposed sides;
/// void: 0).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Responses {
    /// Width of the images in pixels.
    pub width: usize,
    /// Height of the images in pixels.
    pub height: usize,
    /// Indices into [`Level::materials`](crate::level::Level::materials) of the emitter materials, in order.
    pub emitters: Vec<usize>,
    /// Which reflectance class each channel uses.
    pub rho_class_of: [usize; 3],
    /// Number of reflectance classes (channels with equal reflectance for
    /// every material share one).
    pub rho_classes: usize,
    /// `images[m * rho_classes + r]` for emitter `m` (position in `emitters`).
    pub images: Vec<Vec<f32>>,
    /// The emission the responses were traced with (1; they are stored
    /// divided by it). With falloff, the pairs culled were chosen against it,
    /// independently of the palette's emission.
    pub traced_emission: f64,
    /// With [`Settings::directional`](super::Settings::directional), the
    /// first circular moments `[cos, sin]` per pixel of each image, in the
    /// order of `images` and per unit emission (0 on solid and void pixels);
    /// empty otherwise.
    pub moments: Vec<Vec<[f32; 2]>>,
}

impl Responses {
    /// The lightmap for `emission[m]` per emitter (in `emitters` order);
    /// negative or non-finite values (never expected) become 0.
    pub fn combine(&self, emission: &[[f64; 3]]) -> Vec<[f32; 3]> {
        let n = self.width * self.height;
        let mut rgb = vec![[0f32; 3]; n];
        for (m, e) in emission.iter().enumerate().take(self.emitters.len()) {
            for c in 0..3 {
                if e[c] == 0.0 {
                    continue;
                }
                let img = &self.images[m * self.rho_classes + self.rho_class_of[c]];
                for (px, v) in rgb.iter_mut().zip(img) {
                    px[c] += (e[c] * *v as f64) as f32;
                }
            }
        }
        for p in &mut rgb {
            for v in p.iter_mut() {
                if !v.is_finite() || *v < 0.0 {
                    *v = 0.0;
                }
            }
        }
        rgb
    }

    /// The moments for `emission[m]` per emitter, as [`Responses::combine`]
    /// weights the images: `None` when the responses hold no moments.
    pub fn combine_moments(&self, emission: &[[f64; 3]]) -> Option<super::Directional> {
        if self.moments.len() != self.images.len() || self.moments.is_empty() {
            return None;
        }
        let mut d = super::Directional::zero(self.width, self.height);
        for (m, e) in emission.iter().enumerate().take(self.emitters.len()) {
            for c in 0..3 {
                if e[c] == 0.0 {
                    continue;
                }
                let img = &self.moments[m * self.rho_classes + self.rho_class_of[c]];
                for (i, v) in img.iter().enumerate() {
                    d.cos[i][c] += (e[c] * v[0] as f64) as f32;
                    d.sin[i][c] += (e[c] * v[1] as f64) as f32;
                }
            }
        }
        for v in d.cos.iter_mut().chain(d.sin.iter_mut()).flatten() {
            if !v.is_finite() {
                *v = 0.0;
            }
        }
        Some(d)
    }
}
