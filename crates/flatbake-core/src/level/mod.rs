//! Level loading: a painted image plus its palette become a resolved [`Level`]
//! (docs/transport.md, units and pixels, and the palette). Nothing after this module looks at pixel colours.
//!
//! Loading is where user files meet the program, so it refuses what it cannot
//! trust before spending memory on it (the header's dimensions are checked
//! against [`LoadLimits`] before any pixel is decoded), and every failure
//! names the file and says what is wrong with it in words a level designer
//! understands. Pixels that are *almost* a wall or emitter colour along its
//! edges — the anti-aliasing most paint programs add by default — are
//! reported as one warning per palette colour, or snapped to it when the
//! palette sets `[bake] tolerance`; a colour painted as an area of its own is
//! floor on purpose and is never reported.

mod classify;
mod decode;
pub mod ldtk;
mod map_grid;
pub mod material;
pub mod palette;
pub mod tiled_map;

use std::path::{Path, PathBuf};

pub use decode::read_image;

use crate::level::material::Material;
use crate::level::palette::Palette;
use classify::classify_pixels;

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
    /// A wall or emitter pixel.
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
    /// Largest accepted `width * height` (the CLI's `--max-pixels`).
    pub max_pixels: u64,
}

impl Default for LoadLimits {
    fn default() -> Self {
        LoadLimits {
            max_pixels: 64 * 1024 * 1024,
        }
    }
}

/// A resolved level: pixel classes, floor albedo and the materials used.
#[derive(Clone, Debug)]
pub struct Level {
    /// The level's name (an image's file stem).
    pub name: String,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Row-major, `width * height`.
    pub cells: Vec<Cell>,
    /// Linear floor albedo per pixel (zero for solid and void pixels).
    pub albedo: Vec<[f32; 3]>,
    /// Materials referenced by [`Cell::Solid`], in palette order; only the
    /// materials the level actually uses.
    pub materials: Vec<Material>,
    /// Problems worth telling the user that do not stop the bake.
    pub warnings: Vec<String>,
    /// The lossy format the image was stored in ("JPEG", "WebP"), whose
    /// colours are not exactly the painted ones; `None` for lossless images
    /// and levels built in memory.
    pub lossy_format: Option<&'static str>,
    /// What the level was made from, so that a message can say what to
    /// change there (a palette colour, a tile property, an entity).
    pub origin: Origin,
    /// The fraction of each cell that is floor, where that is not simply 1
    /// on floor and 0 elsewhere: a level at texel resolution below one
    /// texel per pixel ([`crate::bake::texels`]), whose floor texel holds
    /// some floor pixels and maybe some wall. What the lightmap outputs'
    /// coverage channel holds ([`Level::coverage`]). `None` for levels as
    /// painted.
    pub floor_fraction: Option<Vec<f32>>,
}

/// What a [`Level`] was made from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Origin {
    /// An image whose colours the palette classifies (and levels built in
    /// memory).
    #[default]
    Image,
    /// A Tiled map: tile properties and objects.
    Tiled,
    /// An LDtk project's level: IntGrid values and entities.
    Ldtk,
}

/// Why a level could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LevelError {
    /// The image file could not be read as a level.
    #[error("{}: {problem}", path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// What is wrong with it.
        problem: ImageProblem,
    },
    /// The level's palette is broken.
    #[error(transparent)]
    Palette(#[from] crate::level::palette::PaletteError),
    /// A Tiled map could not be read as a level.
    #[error(transparent)]
    Tiled(#[from] tiled_map::TiledError),
    /// An LDtk project or one of its levels could not be read as a level.
    #[error(transparent)]
    Ldtk(#[from] ldtk::LdtkError),
}

/// What is wrong with a level image, in words a level designer understands.
#[derive(Debug, thiserror::Error)]
pub enum ImageProblem {
    /// There is no such file.
    #[error("file not found")]
    NotFound,
    /// The file may not be read.
    #[error("permission denied: cannot read the file")]
    PermissionDenied,
    /// Reading failed for another reason.
    #[error("cannot read the file: {0}")]
    Read(#[source] std::io::Error),
    /// The path is a folder.
    #[error("is a folder, not an image file")]
    Folder,
    /// The file has no bytes.
    #[error("the file is empty (0 bytes), not an image")]
    Empty,
    /// The content is no image format flatbake reads.
    #[error(
        "not an image: {} ({glimpse})",
        match named {
            Some(f) => format!("its content is not {f} despite the file name"),
            None => "its content is not PNG or any other image format flatbake reads".to_string(),
        }
    )]
    NotAnImage {
        /// The format the file name claims, if it names one.
        named: Option<String>,
        /// What the file starts with instead (text, or bytes in hex).
        glimpse: String,
    },
    /// A known format that this build cannot decode.
    #[error("{format} images are not supported by this build of flatbake")]
    FormatNotBuilt {
        /// The format's usual extension, upper case.
        format: String,
    },
    /// The declared size is zero.
    #[error("the image has no pixels ({width} x {height})")]
    NoPixels {
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
    },
    /// The declared size is over [`LoadLimits::max_pixels`].
    #[error(
        "the image is {width} x {height} = {pixels} pixels, more than the limit of {limit} pixels; \
         if the size is intended, raise the limit with --max-pixels {pixels}",
        pixels = *width as u64 * *height as u64
    )]
    TooLarge {
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
        /// The limit it is over.
        limit: u64,
    },
    /// The file ends before the image data does.
    #[error(
        "the {format} file is truncated{}",
        detail.as_ref().map_or_else(|| ": it ends before the image data does".to_string(), |d| format!(" ({d})"))
    )]
    Truncated {
        /// The format, upper case.
        format: String,
        /// The decoder's words, when it gave any.
        detail: Option<String>,
    },
    /// The image data is damaged.
    #[error("the {format} file is corrupt ({detail})")]
    Corrupt {
        /// The format, upper case.
        format: String,
        /// The decoder's words.
        detail: String,
    },
    /// The decoder's own limits refused it.
    #[error("the image is too large to decode ({detail}); raise --max-pixels if it is intended")]
    DecodeLimit {
        /// The decoder's words.
        detail: String,
    },
    /// A feature of the format the decoder does not support.
    #[error("unsupported {format} image: {detail}")]
    Unsupported {
        /// The format, upper case.
        format: String,
        /// The decoder's words.
        detail: String,
    },
    /// Any other decoding failure.
    #[error("cannot decode the {format} image: {detail}")]
    Decode {
        /// The format, upper case.
        format: String,
        /// The decoder's words.
        detail: String,
    },
}

/// Pixels whose largest per-channel difference from a wall or emitter colour
/// is at most this are reported as probable anti-aliasing. Forty 8-bit steps
/// catch the soft edges editors paint while staying clear of colours that
/// are merely in the same family.
pub const NEAR_MISS_DISTANCE: u8 = 40;

/// How far (in pixels, in any direction) a near-miss pixel may lie from a
/// pixel of the wall or emitter colour it is near and still count as that
/// colour's anti-aliased fringe: a soft brush's edge is one to two pixels
/// wide. Near-miss colours painted as areas of their own are never a fringe.
pub const FRINGE_REACH: usize = 2;

impl Level {
    /// The cell of pixel `(x, y)`, which must lie inside the level.
    pub fn cell(&self, x: usize, y: usize) -> Cell {
        self.cells[y * self.width + x]
    }

    /// The coverage of each cell, row-major: the fraction of it that is
    /// floor ([`Level::floor_fraction`] when it has one of the right
    /// length, else 1 on floor and 0 elsewhere). Never above 1, 0 on every
    /// cell that is not floor.
    pub fn coverage(&self) -> Vec<f32> {
        match &self.floor_fraction {
            Some(f) if f.len() == self.cells.len() => f
                .iter()
                .zip(&self.cells)
                .map(|(&v, &c)| {
                    if c == Cell::Floor && v.is_finite() {
                        v.clamp(0.0, 1.0)
                    } else {
                        0.0
                    }
                })
                .collect(),
            _ => self
                .cells
                .iter()
                .map(|&c| if c == Cell::Floor { 1.0 } else { 0.0 })
                .collect(),
        }
    }

    /// Builds a level from already-decoded RGBA pixels (row-major).
    ///
    /// Alpha 0 is void; any other alpha counts as opaque. If `rgba` holds
    /// fewer than `width * height` pixels the rest is void (and a warning
    /// says so) rather than a panic: this is also the entry point for levels
    /// built in code.
    pub fn from_rgba(
        name: &str,
        width: usize,
        height: usize,
        rgba: &[[u8; 4]],
        palette: &Palette,
    ) -> Level {
        classify_pixels(name, width, height, rgba.as_flattened(), palette, None)
    }
}

/// The files besides its own that the level at `path` is read from: a
/// Tiled map's external tilesets (`.tsx`), the level file (`.ldtkl`) of a
/// level of an LDtk project that keeps its levels in separate files. Watch
/// mode bakes the level again when one of them changes.
pub fn dependencies(path: &Path) -> Vec<PathBuf> {
    if tiled_map::is_tiled_map(path) {
        return tiled_map::tiled_dependencies(path);
    }
    ldtk::level_file(path).into_iter().collect()
}

/// The `[bake]` settings a map itself gives (Tiled map properties, LDtk
/// level fields `flatbake_falloff`, `flatbake_bounces`, `flatbake_exposure`);
/// none for an image.
pub fn map_settings(path: &Path) -> Result<palette::PaletteSettings, LevelError> {
    if tiled_map::is_tiled_map(path) {
        return tiled_map::tiled_settings(path);
    }
    if ldtk::project_level(path).is_some() {
        return ldtk::ldtk_settings(path);
    }
    Ok(Default::default())
}

/// Loads a level image and classifies its pixels with `palette`.
///
/// The level is named after the file stem (`cave.png` is `cave`).
/// A Tiled map (`.tmx`) is read by [`tiled_map::load_tiled`] instead, and
/// a level of an LDtk project (`PROJECT.ldtk/LEVEL`) by [`ldtk::load_ldtk`]
/// (no palette).
pub fn load_level(path: &Path, palette: &Palette, limits: LoadLimits) -> Result<Level, LevelError> {
    if tiled_map::is_tiled_map(path) {
        return tiled_map::load_tiled(path, limits);
    }
    if ldtk::is_ldtk_project(path) || ldtk::project_level(path).is_some() {
        return ldtk::load_ldtk(path, limits);
    }
    let img = read_image(path, limits)?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (w, h) = (img.width() as usize, img.height() as usize);
    // With the built-in palette, near-miss advice names the file that would
    // add to it: NAME.palette.toml beside the image.
    let [named, _] = Palette::candidate_paths(path);
    let mut level = classify_pixels(&name, w, h, img.as_raw(), palette, Some(&named));
    if let Some(format) = decode::lossy_format(path) {
        level.warnings.insert(
            0,
            format!(
                "the image is {format}, a lossy format: compression shifts colours, so pixels \
                 painted in a wall or lamp colour may no longer match the palette exactly (they \
                 become floor); save levels as PNG"
            ),
        );
        level.lossy_format = Some(format);
    }
    Ok(level)
}
