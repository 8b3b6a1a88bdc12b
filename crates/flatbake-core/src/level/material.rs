//! Materials: what a palette colour means once it is resolved to linear numbers.
//!
//! Everything after loading works with these resolved values only; no later
//! stage looks at palette text or pixel colours again.

use serde::{Deserialize, Serialize};

/// A linear RGB triple (reflectance, emission, albedo or radiosity).
pub type Rgb = [f64; 3];

/// What a solid pixel is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum MaterialKind {
    /// Blocks light and reflects a fraction `reflectance` of what it receives.
    Wall,
    /// A wall that also emits `emission` (radiosity per unit length).
    Emitter,
}

/// A solid material: a wall or an emitter, fully resolved.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// The exact sRGB colour that paints this material.
    pub color: [u8; 3],
    /// Wall or emitter.
    pub kind: MaterialKind,
    /// Linear reflectance per channel, each in `0..=1`.
    pub reflectance: Rgb,
    /// Linear emitted radiosity per unit length, each finite and `>= 0`.
    pub emission: Rgb,
    /// Light group for `bake --layers`; `None` means "one group per emitter colour".
    pub group: Option<String>,
    /// Line of the palette entry, for messages (`None` for the built-in palette).
    pub line: Option<usize>,
}

impl Material {
    /// `#rrggbb` spelling of the material's colour.
    pub fn hex(&self) -> String {
        hex_color(self.color)
    }

    /// True when some channel emits light.
    pub fn emits(&self) -> bool {
        self.emission.iter().any(|&e| e > 0.0)
    }

    /// True when some channel reflects light.
    pub fn reflects(&self) -> bool {
        self.reflectance.iter().any(|&r| r > 0.0)
    }

    /// The light group this material belongs to (its colour when unnamed).
    pub fn group_name(&self) -> String {
        self.group
            .clone()
            .unwrap_or_else(|| self.hex().trim_start_matches('#').to_string())
    }
}

/// `#rrggbb` spelling of a colour.
pub fn hex_color(c: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// sRGB-encoded byte to linear value in `0..=1`.
pub fn srgb_to_linear(c: u8) -> f64 {
    let c = c as f64 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear value to sRGB-encoded value in `0..=1` (input clamped to `0..=1`).
pub fn linear_to_srgb(v: f64) -> f64 {
    let v = if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    };
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}
