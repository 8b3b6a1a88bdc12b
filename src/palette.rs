//! Palettes: which painted colour is which material (SPEC section 2).
//!
//! A palette is TOML text; [`Palette::resolve_for_level`] applies the lookup
//! order of SPEC 2 and [`Palette::builtin`] is the default palette.

use std::path::{Path, PathBuf};

use crate::material::{Material, MaterialKind, Rgb};

/// Where a palette came from.
#[derive(Clone, Debug, PartialEq)]
pub enum PaletteOrigin {
    BuiltIn,
    File(PathBuf),
}

/// A floor colour with an explicit albedo.
#[derive(Clone, Debug, PartialEq)]
pub struct FloorColor {
    pub color: [u8; 3],
    pub albedo: Rgb,
    pub line: Option<usize>,
}

/// The optional `[bake]` table; command-line flags override each field.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PaletteSettings {
    /// Half-energy distance in pixels.
    pub falloff: Option<f64>,
    /// Truncate the bounce series after this many bounces (0 = direct light only).
    pub bounces: Option<u32>,
    /// Snap pixels within this many 8-bit steps (per channel) to a palette colour.
    pub tolerance: Option<u8>,
    /// Lightmap exposure.
    pub exposure: Option<f64>,
}

/// A resolved palette.
#[derive(Clone, Debug, PartialEq)]
pub struct Palette {
    pub origin: PaletteOrigin,
    /// Walls and emitters, in palette order.
    pub solids: Vec<Material>,
    /// Floor colours with explicit albedo.
    pub floors: Vec<FloorColor>,
    pub settings: PaletteSettings,
}

/// A palette problem, located in its file.
#[derive(Debug, thiserror::Error)]
#[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct PaletteError {
    pub path: PathBuf,
    pub line: Option<usize>,
    pub message: String,
}

impl Palette {
    /// The built-in default palette.
    pub fn builtin() -> Palette {
        let wall = |color, r: Rgb| Material {
            color,
            kind: MaterialKind::Wall,
            reflectance: r,
            emission: [0.0; 3],
            group: None,
            line: None,
        };
        let light = |color, e: Rgb| Material {
            color,
            kind: MaterialKind::Emitter,
            reflectance: [0.0; 3],
            emission: e,
            group: None,
            line: None,
        };
        Palette {
            origin: PaletteOrigin::BuiltIn,
            solids: vec![
                wall([0, 0, 0], [0.5; 3]),
                light([255, 255, 255], [1.0; 3]),
            ],
            floors: vec![],
            settings: PaletteSettings::default(),
        }
    }

    /// Parses palette text; `path` is used in messages.
    pub fn parse(_text: &str, path: &Path) -> Result<Palette, PaletteError> {
        Err(PaletteError { path: path.to_path_buf(), line: None, message: "palette files are not supported yet".into() })
    }

    /// Reads and parses a palette file.
    pub fn load(path: &Path) -> Result<Palette, PaletteError> {
        let text = std::fs::read_to_string(path).map_err(|e| PaletteError {
            path: path.to_path_buf(),
            line: None,
            message: format!("cannot read palette: {e}"),
        })?;
        Palette::parse(&text, path)
    }

    /// The palette for a level, first match wins: `explicit`; `NAME.palette.toml`
    /// beside `NAME.png`; `palette.toml` in the level's folder; the built-in one.
    pub fn resolve_for_level(level: &Path, explicit: Option<&Path>) -> Result<Palette, PaletteError> {
        if let Some(p) = explicit {
            return Palette::load(p);
        }
        Ok(Palette::builtin())
    }
}
