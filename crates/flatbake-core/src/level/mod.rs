//! Level loading: a painted image plus its palette become a resolved [`Level`]
//! (SPEC sections 1 and 2). Nothing after this module looks at pixel colours.
//!
//! Loading is where user files meet the program, so it refuses what it cannot
//! trust before spending memory on it (the header's dimensions are checked
//! against [`LoadLimits`] before any pixel is decoded), and every failure
//! names the file and says what is wrong with it in words a level designer
//! understands. Pixels that are *almost* a wall or emitter colour — the
//! anti-aliasing most paint programs add by default — are reported as one
//! warning per palette colour, or snapped to it when the palette sets
//! `[bake] tolerance`.

pub mod material;
pub mod palette;

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::hash::{BuildHasherDefault, Hasher};
use std::io::{BufReader, Read};
use std::path::Path;

use image::{ImageError, ImageFormat, ImageReader, RgbaImage};

use crate::level::material::{Material, MaterialKind, srgb_to_linear};
use crate::level::palette::{ColorClass, Palette, PaletteOrigin};

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
    pub name: String,
    pub width: usize,
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
}

/// Why a level could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LevelError {
    #[error("{path}: {message}")]
    Image { path: String, message: String },
    #[error(transparent)]
    Palette(#[from] crate::level::palette::PaletteError),
}

/// Pixels whose largest per-channel difference from a wall or emitter colour
/// is at most this are reported as probable anti-aliasing. Forty 8-bit steps
/// catch the soft edges editors paint while staying clear of colours that
/// are merely in the same family.
pub const NEAR_MISS_DISTANCE: u8 = 40;

impl Level {
    pub fn cell(&self, x: usize, y: usize) -> Cell {
        self.cells[y * self.width + x]
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
        classify_pixels(name, width, height, rgba.as_flattened(), palette)
    }
}

/// Loads a level image and classifies its pixels with `palette`.
///
/// The level is named after the file stem (`cave.png` is `cave`).
pub fn load_level(path: &Path, palette: &Palette, limits: LoadLimits) -> Result<Level, LevelError> {
    let img = read_image(path, limits)?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (w, h) = (img.width() as usize, img.height() as usize);
    Ok(classify_pixels(&name, w, h, img.as_raw(), palette))
}

/// Decodes a level image to 8-bit RGBA.
///
/// The format comes from the file's content (a PNG named `.jpg` loads); the
/// declared size is checked against `limits` before decoding, so a tiny file
/// that claims to be 100000 x 100000 fails at once without allocating.
/// 16-bit, grey, grey + alpha and paletted images are converted; 16-bit
/// values round to the nearest 8-bit value, so a colour saved as 16-bit
/// still matches its palette entry.
pub fn read_image(path: &Path, limits: LoadLimits) -> Result<RgbaImage, LevelError> {
    let fail = |message: String| LevelError::Image {
        path: path.display().to_string(),
        message,
    };
    let io_fail = |e: std::io::Error| {
        fail(match e.kind() {
            std::io::ErrorKind::NotFound => "file not found".to_string(),
            std::io::ErrorKind::PermissionDenied => {
                "permission denied: cannot read the file".to_string()
            }
            _ => format!("cannot read the file: {e}"),
        })
    };

    let meta = std::fs::metadata(path).map_err(io_fail)?;
    if meta.is_dir() {
        return Err(fail("is a folder, not an image file".into()));
    }
    if meta.len() == 0 {
        return Err(fail("the file is empty (0 bytes), not an image".into()));
    }

    let mut head = Vec::with_capacity(32);
    File::open(path)
        .and_then(|f| f.take(32).read_to_end(&mut head))
        .map_err(io_fail)?;
    let by_extension = ImageFormat::from_path(path).ok();
    let format = match image::guess_format(&head) {
        Ok(f) => f,
        // TGA has no signature to recognise; trust its extension.
        Err(_) if by_extension == Some(ImageFormat::Tga) => ImageFormat::Tga,
        Err(_) => return Err(fail(not_an_image(&head, by_extension))),
    };
    if !format.reading_enabled() {
        return Err(fail(format!(
            "{} images are not supported by this build of flatbake",
            format_name(format)
        )));
    }

    let open = || {
        File::open(path)
            .map(|f| ImageReader::with_format(BufReader::new(f), format))
            .map_err(io_fail)
    };
    // PNG's size sits at a fixed place in the first chunk; reading it there
    // refuses an oversized PNG even when the rest of the file is missing,
    // which the decoder would otherwise report first.
    let (w, h) = match png_dimensions(&head) {
        Some(d) => d,
        None => open()?
            .into_dimensions()
            .map_err(|e| fail(decode_message(e, format)))?,
    };
    let pixels = w as u64 * h as u64;
    if pixels == 0 {
        return Err(fail(format!("the image has no pixels ({w} x {h})")));
    }
    if pixels > limits.max_pixels {
        return Err(fail(format!(
            "the image is {w} x {h} = {pixels} pixels, more than the limit of {} pixels; \
             if the size is intended, raise the limit with --max-pixels {pixels}",
            limits.max_pixels
        )));
    }

    let mut reader = open()?;
    let mut decode_limits = image::Limits::default();
    // The declared size passed the check above; hold the decoder to it, and
    // give it room for a 16-bit RGBA buffer plus scratch space.
    decode_limits.max_image_width = Some(w);
    decode_limits.max_image_height = Some(h);
    decode_limits.max_alloc = Some((pixels * 16).max(512 << 20));
    reader.limits(decode_limits);
    let img = reader
        .decode()
        .map_err(|e| fail(decode_message(e, format)))?;
    Ok(img.into_rgba8())
}

/// Width and height from a PNG signature followed by its IHDR chunk.
fn png_dimensions(head: &[u8]) -> Option<(u32, u32)> {
    if head.len() < 24 || &head[..8] != b"\x89PNG\r\n\x1a\n" || &head[12..16] != b"IHDR" {
        return None;
    }
    let be = |i: usize| u32::from_be_bytes([head[i], head[i + 1], head[i + 2], head[i + 3]]);
    Some((be(16), be(20)))
}

fn format_name(f: ImageFormat) -> String {
    f.extensions_str()
        .first()
        .map(|e| e.to_uppercase())
        .unwrap_or_else(|| format!("{f:?}"))
}

/// Why a file that is not a recognisable image was refused, with a glimpse
/// of what it is instead (text is shown, binary as hex).
fn not_an_image(head: &[u8], by_extension: Option<ImageFormat>) -> String {
    let claim = match by_extension {
        Some(f) => format!(
            "its content is not {} despite the file name",
            format_name(f)
        ),
        None => "its content is not PNG or any other image format flatbake reads".to_string(),
    };
    let start = &head[..head.len().min(16)];
    let looks_like_text = start
        .iter()
        .all(|&b| b == b'\t' || b == b'\n' || b == b'\r' || (0x20..0x7f).contains(&b));
    let glimpse = if looks_like_text {
        let text: String = String::from_utf8_lossy(start)
            .chars()
            .map(|c| if c.is_control() { ' ' } else { c })
            .collect();
        format!("it starts with the text {:?}", text.trim())
    } else {
        let hex: Vec<String> = start.iter().take(8).map(|b| format!("{b:02x}")).collect();
        format!("it starts with the bytes {}", hex.join(" "))
    };
    format!("not an image: {claim} ({glimpse})")
}

/// Words for a decoding failure; truncation is by far the most common cause.
fn decode_message(e: ImageError, format: ImageFormat) -> String {
    let name = format_name(format);
    match e {
        ImageError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            format!("the {name} file is truncated: it ends before the image data does")
        }
        ImageError::IoError(io) => format!("cannot read the file: {io}"),
        ImageError::Decoding(d) => {
            let detail = d.to_string();
            let lower = detail.to_lowercase();
            if lower.contains("eof") || lower.contains("end of") || lower.contains("truncat") {
                format!("the {name} file is truncated ({detail})")
            } else {
                format!("the {name} file is corrupt ({detail})")
            }
        }
        ImageError::Limits(l) => {
            format!("the image is too large to decode ({l}); raise --max-pixels if it is intended")
        }
        ImageError::Unsupported(u) => format!("unsupported {name} image: {u}"),
        other => format!("cannot decode the {name} image: {other}"),
    }
}

/// How one distinct colour resolves; computed once per colour and cached.
#[derive(Clone, Copy, Debug)]
enum Resolved {
    /// Index into `palette.solids`.
    Solid(usize),
    Floor([f32; 3]),
    /// Floor, but within [`NEAR_MISS_DISTANCE`] of `palette.solids[solid]`.
    NearMiss {
        solid: usize,
        diff: u8,
        albedo: [f32; 3],
    },
}

fn resolve(palette: &Palette, rgb: [u8; 3], lut: &[f32; 256]) -> Resolved {
    let floor_albedo = |i: usize| match palette.floors.get(i) {
        Some(f) => f.albedo.map(|a| a as f32),
        None => rgb.map(|c| lut[c as usize]),
    };
    let class = palette.classify(rgb).or_else(|| {
        // A tolerance snaps near-misses to the nearest palette colour of any
        // kind: an anti-aliased pixel closest to a listed floor is that floor.
        let t = palette.settings.tolerance.filter(|&t| t > 0)?;
        palette.nearest(rgb, t).map(|(class, _)| class)
    });
    match class {
        Some(ColorClass::Solid(i)) => Resolved::Solid(i),
        Some(ColorClass::Floor(i)) => Resolved::Floor(floor_albedo(i)),
        None => {
            let albedo = rgb.map(|c| lut[c as usize]);
            match palette.nearest(rgb, NEAR_MISS_DISTANCE) {
                Some((ColorClass::Solid(solid), diff)) => Resolved::NearMiss {
                    solid,
                    diff,
                    albedo,
                },
                _ => Resolved::Floor(albedo),
            }
        }
    }
}

/// Near-miss pixels of one palette colour, gathered for a single warning.
struct NearMisses {
    pixels: u64,
    colors: u64,
    example: (usize, usize, [u8; 3]),
    min: (usize, usize),
    max: (usize, usize),
    max_diff: u8,
}

/// Hashes a packed `0x00bbggrr` colour with one multiply: the keys are
/// small integers, so SipHash's flood resistance buys nothing here and its
/// cost shows on 2048 x 2048 levels with many colours.
#[derive(Default)]
struct ColorHasher(u64);

impl Hasher for ColorHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ b as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }
    fn write_u32(&mut self, n: u32) {
        self.0 = (n as u64)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .rotate_right(29);
    }
}

fn classify_pixels(
    name: &str,
    width: usize,
    height: usize,
    rgba: &[u8],
    palette: &Palette,
) -> Level {
    let mut warnings = Vec::new();
    let (width, height) = match width.checked_mul(height) {
        Some(_) => (width, height),
        None => {
            warnings.push(format!(
                "level size {width} x {height} overflows; treated as empty"
            ));
            (0, 0)
        }
    };
    let n = width * height;
    let available = rgba.len() / 4;
    if available < n {
        warnings.push(format!(
            "pixel data holds {available} pixels but the level is {width} x {height} = {n}; the rest is void"
        ));
    }

    let lut: [f32; 256] = std::array::from_fn(|c| srgb_to_linear(c as u8) as f32);
    let mut cache: HashMap<u32, Resolved, BuildHasherDefault<ColorHasher>> = HashMap::default();
    // Material slot of each palette solid in first-use order; remapped to
    // palette order at the end so indices do not depend on where in the
    // image a material first appears.
    let mut slot_of: Vec<Option<u16>> = vec![None; palette.solids.len()];
    let mut used: Vec<usize> = Vec::new();
    let mut overflowed = false;
    let mut near: BTreeMap<usize, NearMisses> = BTreeMap::new();

    let mut cells = Vec::with_capacity(n);
    let mut albedo = Vec::with_capacity(n);
    // Levels are painted in flat areas, so most pixels repeat their left
    // neighbour: remember the last answer and skip the hash lookup.
    let mut last: Option<(u32, Resolved)> = None;

    for (i, px) in rgba.chunks_exact(4).take(n).enumerate() {
        if px[3] == 0 {
            cells.push(Cell::Void);
            albedo.push([0.0; 3]);
            continue;
        }
        let key = u32::from_le_bytes([px[0], px[1], px[2], 0]);
        let (resolved, first_time) = match last {
            Some((k, r)) if k == key => (r, false),
            _ => {
                let mut first_time = false;
                let r = *cache.entry(key).or_insert_with(|| {
                    first_time = true;
                    resolve(palette, [px[0], px[1], px[2]], &lut)
                });
                last = Some((key, r));
                (r, first_time)
            }
        };
        match resolved {
            Resolved::Solid(p) => {
                let slot = match slot_of.get(p).copied().flatten() {
                    Some(s) => Some(s),
                    None if used.len() <= u16::MAX as usize && p < slot_of.len() => {
                        let s = used.len() as u16;
                        slot_of[p] = Some(s);
                        used.push(p);
                        Some(s)
                    }
                    None => {
                        overflowed = true;
                        None
                    }
                };
                match slot {
                    Some(s) => {
                        cells.push(Cell::Solid(s));
                        albedo.push([0.0; 3]);
                    }
                    None => {
                        cells.push(Cell::Floor);
                        albedo.push([0.0; 3]);
                    }
                }
            }
            Resolved::Floor(a) => {
                cells.push(Cell::Floor);
                albedo.push(a);
            }
            Resolved::NearMiss {
                solid,
                diff,
                albedo: a,
            } => {
                cells.push(Cell::Floor);
                albedo.push(a);
                let (x, y) = (i % width, i / width);
                let e = near.entry(solid).or_insert(NearMisses {
                    pixels: 0,
                    colors: 0,
                    example: (x, y, [px[0], px[1], px[2]]),
                    min: (x, y),
                    max: (x, y),
                    max_diff: 0,
                });
                e.pixels += 1;
                e.colors += first_time as u64;
                e.min = (e.min.0.min(x), e.min.1.min(y));
                e.max = (e.max.0.max(x), e.max.1.max(y));
                e.max_diff = e.max_diff.max(diff);
            }
        }
    }
    cells.resize(n, Cell::Void);
    albedo.resize(n, [0.0; 3]);

    if overflowed {
        warnings.push(format!(
            "the level uses more than {} wall and emitter colours; the rest are floor",
            u16::MAX as usize + 1
        ));
    }

    // Palette order for the materials actually used.
    let mut order: Vec<usize> = (0..used.len()).collect();
    order.sort_by_key(|&s| used[s]);
    let mut new_slot = vec![0u16; used.len()];
    for (new, &old) in order.iter().enumerate() {
        new_slot[old] = new as u16;
    }
    if order.iter().enumerate().any(|(new, &old)| new != old) {
        for c in &mut cells {
            if let Cell::Solid(s) = c {
                *s = new_slot[*s as usize];
            }
        }
    }
    let materials = order
        .iter()
        .map(|&s| palette.solids[used[s]].clone())
        .collect();

    for (&solid, m) in &near {
        warnings.push(near_miss_warning(palette, name, solid, m));
    }

    Level {
        name: name.to_string(),
        width,
        height,
        cells,
        albedo,
        materials,
        warnings,
    }
}

fn near_miss_warning(palette: &Palette, level: &str, solid: usize, m: &NearMisses) -> String {
    let what = palette.describe(ColorClass::Solid(solid));
    let kind = match palette.solids.get(solid).map(|s| s.kind) {
        Some(MaterialKind::Emitter) => "emitter",
        _ => "wall",
    };
    let plural = |n: u64, word: &str| {
        if n == 1 {
            format!("1 {word}")
        } else {
            format!("{n} {word}s")
        }
    };
    let (x, y, c) = m.example;
    let fix = match palette.settings.tolerance {
        Some(t) if t > 0 => format!("raise `[bake] tolerance` from {t} to {}", m.max_diff),
        _ => format!("set `[bake] tolerance = {}`", m.max_diff),
    };
    let where_ = match palette.origin {
        PaletteOrigin::BuiltIn => format!(" in a palette file (e.g. {level}.palette.toml)"),
        PaletteOrigin::File(_) => " in the palette".to_string(),
    };
    format!(
        "{} in {} are close to {what} but not exactly that colour, probably anti-aliasing \
         (e.g. {} at ({x}, {y}); all within x {}..={}, y {}..={}; up to {} steps off per channel); \
         they are treated as floor, not {kind}. Paint with hard edges (no anti-aliasing), or {fix}{where_} \
         to snap them to the nearest palette colour",
        plural(m.pixels, "pixel"),
        plural(m.colors, "colour"),
        crate::level::material::hex_color(c),
        m.min.0,
        m.max.0,
        m.min.1,
        m.max.1,
        m.max_diff,
    )
}
