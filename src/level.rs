//! Level loading: a painted image plus its palette become a resolved [`Level`]
//! (SPEC sections 1 and 2). Nothing after this module looks at pixel colours.

use std::path::Path;

use crate::material::{Material, srgb_to_linear};
use crate::palette::Palette;

/// What one pixel of the level is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Cell {
    /// Transparent: light passes, nothing is lit.
    Void,
    /// Receives light.
    Floor,
    /// A wall or emitter pixel; the index is into [`Level::materials`].
    Solid(u16),
}

impl Cell {
    pub fn is_solid(self) -> bool {
        matches!(self, Cell::Solid(_))
    }
    /// Light passes through floor and void.
    pub fn is_free(self) -> bool {
        !self.is_solid()
    }
}

/// Limits applied before any pixel memory is allocated.
#[derive(Clone, Copy, Debug)]
pub struct LoadLimits {
    /// Largest accepted `width * height`.
    pub max_pixels: u64,
}

impl Default for LoadLimits {
    fn default() -> Self {
        LoadLimits { max_pixels: 64 * 1024 * 1024 }
    }
}

/// A resolved level: pixel classes, floor albedo and the materials used.
#[derive(Clone, Debug)]
pub struct Level {
    pub name: String,
    pub width: usize,
    pub height: usize,
    /// Row-major, `width * height`.
    pub cells: Vec<Cell>,
    /// Linear floor albedo per pixel (zero for solid and void pixels).
    pub albedo: Vec<[f32; 3]>,
    /// Materials referenced by [`Cell::Solid`].
    pub materials: Vec<Material>,
    /// Problems worth telling the user that do not stop the bake.
    pub warnings: Vec<String>,
}

/// Why a level could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LevelError {
    #[error("{path}: {message}")]
    Image { path: String, message: String },
    #[error(transparent)]
    Palette(#[from] crate::palette::PaletteError),
}

impl Level {
    pub fn cell(&self, x: usize, y: usize) -> Cell {
        self.cells[y * self.width + x]
    }

    /// Builds a level from already-decoded RGBA pixels (row-major).
    pub fn from_rgba(name: &str, width: usize, height: usize, rgba: &[[u8; 4]], palette: &Palette) -> Level {
        let mut materials: Vec<Material> = Vec::new();
        let mut cells = Vec::with_capacity(width * height);
        let mut albedo = Vec::with_capacity(width * height);
        for px in rgba {
            if px[3] == 0 {
                cells.push(Cell::Void);
                albedo.push([0.0; 3]);
                continue;
            }
            let rgb = [px[0], px[1], px[2]];
            if let Some(m) = palette.solids.iter().find(|m| m.color == rgb) {
                let idx = match materials.iter().position(|x| x.color == rgb) {
                    Some(i) => i,
                    None => {
                        materials.push(m.clone());
                        materials.len() - 1
                    }
                };
                cells.push(Cell::Solid(idx as u16));
                albedo.push([0.0; 3]);
            } else if let Some(f) = palette.floors.iter().find(|f| f.color == rgb) {
                cells.push(Cell::Floor);
                albedo.push([f.albedo[0] as f32, f.albedo[1] as f32, f.albedo[2] as f32]);
            } else {
                cells.push(Cell::Floor);
                albedo.push(rgb.map(|c| srgb_to_linear(c) as f32));
            }
        }
        Level { name: name.to_string(), width, height, cells, albedo, materials, warnings: vec![] }
    }
}

/// Loads a level image and classifies its pixels with `palette`.
pub fn load_level(path: &Path, palette: &Palette, _limits: LoadLimits) -> Result<Level, LevelError> {
    let err = |m: String| LevelError::Image { path: path.display().to_string(), message: m };
    let img = image::open(path).map_err(|e| err(e.to_string()))?.to_rgba8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let px: Vec<[u8; 4]> = img.pixels().map(|p| p.0).collect();
    let name = path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
    Ok(Level::from_rgba(&name, w, h, &px, palette))
}
