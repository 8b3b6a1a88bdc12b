//! Writing results (SPEC section 5): the lightmap and lit PNGs, the optional
//! HDR EXR and RGBM PNG, and the report, for one baked level.
//!
//! Everything is encoded in memory first; only then is the disk touched, one
//! file at a time, each through a temporary file in the destination folder
//! that is flushed to disk and renamed over the old file. A failed or
//! interrupted write therefore never leaves a half-written file behind and
//! never destroys the previous good output of the same name. The report is
//! written last, so a report on disk always describes images that are there.
//! Output bytes depend only on the inputs: no timestamps, no thread-order
//! effects (which is why the EXR writer is our own, see [`encode_exr_rgb32f`]).

pub mod cache;
pub mod layers;

use std::io::{self, ErrorKind, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use image::codecs::png::PngEncoder;
use image::{DynamicImage, ImageBuffer, Rgba, RgbaImage};

pub use crate::bake::Lightmap;
use crate::bake::report::Report;
use crate::level::material::linear_to_srgb;
use crate::level::{Cell, Level};

/// Bits per channel of the PNG outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Depth {
    #[default]
    Eight,
    Sixteen,
}

/// How the outputs are encoded.
#[derive(Clone, Debug)]
pub struct OutputOptions {
    /// Multiplies I(p) before encoding the lightmap and lit PNGs (not the EXR,
    /// not the RGBM PNG). Default 1.
    pub exposure: f64,
    /// Bits per channel of the lightmap and lit PNGs. Default 8.
    pub depth: Depth,
    /// Also write `NAME.lightmap.exr`. Default off.
    pub hdr: bool,
    /// Also write `NAME.lightmap.rgbm.png` (see [`rgbm_encode`]). Default off.
    pub rgbm: bool,
}

impl Default for OutputOptions {
    fn default() -> Self {
        OutputOptions {
            exposure: 1.0,
            depth: Depth::Eight,
            hdr: false,
            rgbm: false,
        }
    }
}

/// The files flatbake writes for one level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    /// `NAME.lightmap.png`
    Lightmap,
    /// `NAME.lit.png`
    Lit,
    /// `NAME.lightmap.exr`
    Hdr,
    /// `NAME.lightmap.rgbm.png`
    Rgbm,
    /// `NAME.report.json`
    Report,
}

impl OutputKind {
    /// The file name suffix, after `NAME.`.
    pub fn suffix(self) -> &'static str {
        match self {
            OutputKind::Lightmap => "lightmap.png",
            OutputKind::Lit => "lit.png",
            OutputKind::Hdr => "lightmap.exr",
            OutputKind::Rgbm => "lightmap.rgbm.png",
            OutputKind::Report => "report.json",
        }
    }

    /// The file name of this output for level `name`.
    pub fn file_name(self, name: &str) -> String {
        format!("{name}.{}", self.suffix())
    }
}

/// Why an output could not be written (or read back). Every message names
/// the path and says the problem in plain words.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("output folder {} does not exist", .path.display())]
    MissingDir { path: PathBuf },
    /// `path` is the output folder; `file` is the regular file that is in the
    /// way (the folder itself or one of its parents).
    #[error("{}", not_a_dir_message(.path, .file))]
    NotADir { path: PathBuf, file: PathBuf },
    #[error("cannot create output folder {}: {}", .path.display(), describe_io(.error))]
    CreateDir { path: PathBuf, error: io::Error },
    #[error("cannot write {}: {}", .path.display(), describe_io(.error))]
    Write { path: PathBuf, error: io::Error },
    #[error("cannot encode {}: {message}", .path.display())]
    Encode { path: PathBuf, message: String },
    #[error("cannot read {}: {message}", .path.display())]
    Read { path: PathBuf, message: String },
    /// The level and the lightmap handed in do not fit together (a bug in
    /// the caller, reported instead of panicking).
    #[error("cannot write the outputs of level {level}: {message}")]
    Invalid { level: String, message: String },
}

impl OutputError {
    /// Maps an I/O error met while writing `path` to an error a person can
    /// read ("cannot write out/a.png: the disk is full").
    pub fn from_io(path: &Path, error: io::Error) -> OutputError {
        OutputError::Write {
            path: path.to_path_buf(),
            error,
        }
    }

    /// The path the error is about, if it is about one.
    pub fn path(&self) -> Option<&Path> {
        match self {
            OutputError::MissingDir { path }
            | OutputError::NotADir { path, .. }
            | OutputError::CreateDir { path, .. }
            | OutputError::Write { path, .. }
            | OutputError::Encode { path, .. }
            | OutputError::Read { path, .. } => Some(path),
            OutputError::Invalid { .. } => None,
        }
    }

    /// True when the underlying cause is a full disk (or an exhausted quota).
    pub fn is_disk_full(&self) -> bool {
        match self {
            OutputError::Write { error, .. } | OutputError::CreateDir { error, .. } => {
                is_disk_full(error)
            }
            _ => false,
        }
    }
}

fn not_a_dir_message(path: &Path, file: &Path) -> String {
    if path == file {
        format!("output folder {} is a file, not a folder", path.display())
    } else {
        format!(
            "output folder {} cannot be created: {} is a file, not a folder",
            path.display(),
            file.display()
        )
    }
}

fn is_disk_full(e: &io::Error) -> bool {
    // ENOSPC is 28 on Linux and the BSDs; on Windows 28 means something else,
    // and the kind alone is reliable there.
    (cfg!(unix) && e.raw_os_error() == Some(28))
        || matches!(e.kind(), ErrorKind::StorageFull | ErrorKind::QuotaExceeded)
}

/// The cause of an I/O error in words, without the OS error number.
fn describe_io(e: &io::Error) -> String {
    if is_disk_full(e) {
        if e.kind() == ErrorKind::QuotaExceeded {
            return "the disk quota is exceeded".into();
        }
        return "the disk is full".into();
    }
    match e.kind() {
        ErrorKind::PermissionDenied => "permission denied".into(),
        ErrorKind::ReadOnlyFilesystem => "the file system is read-only".into(),
        ErrorKind::NotFound => "the folder does not exist".into(),
        ErrorKind::NotADirectory => "a part of the path is a file, not a folder".into(),
        ErrorKind::IsADirectory => "a folder of that name is in the way".into(),
        _ => e.to_string(),
    }
}

/// The first existing ancestor of `dir` (or `dir` itself) if it is not a
/// folder: that is the file that keeps `dir` from being a folder.
fn file_in_the_way(dir: &Path) -> Option<PathBuf> {
    dir.ancestors()
        .filter(|p| !p.as_os_str().is_empty())
        .find_map(|p| match std::fs::metadata(p) {
            Ok(m) => Some((!m.is_dir()).then(|| p.to_path_buf())),
            Err(_) => None,
        })
        .flatten()
}

/// An empty path means the current folder, as `Path::parent` returns it.
fn dir_or_current(dir: &Path) -> &Path {
    if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    }
}

/// Checks that `dir` exists and is a folder, without creating it.
fn check_output_dir(dir: &Path) -> Result<(), OutputError> {
    match std::fs::metadata(dir_or_current(dir)) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => Err(OutputError::NotADir {
            path: dir.to_path_buf(),
            file: dir.to_path_buf(),
        }),
        Err(e) => Err(match file_in_the_way(dir) {
            Some(file) => OutputError::NotADir {
                path: dir.to_path_buf(),
                file,
            },
            None if e.kind() == ErrorKind::NotFound => OutputError::MissingDir {
                path: dir.to_path_buf(),
            },
            None => OutputError::CreateDir {
                path: dir.to_path_buf(),
                error: e,
            },
        }),
    }
}

/// Creates the output folder (and its parents) if needed. Used by the CLI
/// for its default `out/`; an explicit folder that is a file, or that cannot
/// be created, is reported clearly.
pub fn ensure_output_dir(dir: &Path) -> Result<(), OutputError> {
    let d = dir_or_current(dir);
    match std::fs::create_dir_all(d) {
        Ok(()) => check_output_dir(dir),
        Err(e) => Err(match file_in_the_way(dir) {
            Some(file) => OutputError::NotADir {
                path: dir.to_path_buf(),
                file,
            },
            None => OutputError::CreateDir {
                path: dir.to_path_buf(),
                error: e,
            },
        }),
    }
}

/// Writes `bytes` to `path` through a temporary file in the same folder that
/// is flushed to disk and renamed into place, so a failure never leaves a
/// half-written file and never destroys the previous file of that name.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let dir = dir_or_current(path.parent().unwrap_or(Path::new("")));
    let mut builder = tempfile::Builder::new();
    // A leftover from a killed process is recognisable and hidden.
    builder.prefix(".flatbake-").suffix(".tmp");
    // Temporary files are created owner-only (0600); ask for 0666 instead so
    // the umask decides, as for any file the user creates.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir)?;
    tmp.write_all(bytes)?;
    tmp.as_file().sync_all()?;
    // On failure the temporary file is dropped, which deletes it.
    tmp.persist(path).map_err(|e| e.error)?;
    // Make the rename itself durable. The new file is already in place, so a
    // failure here is not worth failing the bake for.
    #[cfg(unix)]
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// [`write_atomic`] with errors that name the path in plain words.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    write_atomic(path, bytes).map_err(|e| {
        let dir = path.parent().unwrap_or(Path::new(""));
        match e.kind() {
            // The folder vanished or was never there: say so about the folder.
            ErrorKind::NotFound | ErrorKind::NotADirectory => match check_output_dir(dir) {
                Err(folder_error) => folder_error,
                Ok(()) => OutputError::from_io(path, e),
            },
            _ => OutputError::from_io(path, e),
        }
    })
}

// ---------------------------------------------------------------------------
// Pixel encodings

/// Range of the RGBM encoding: the largest linear value it can hold.
///
/// RGBM convention (8 bits per channel, all channels linear, no sRGB curve):
/// `M = ceil(255 * clamp(max(r, g, b) / RGBM_RANGE, 1/255, 1)) / 255` is
/// stored in alpha, and each colour channel stores
/// `round(255 * min(1, c / (M * RGBM_RANGE))) / 255`. A shader decodes with
/// `rgb * a * RGBM_RANGE` (texture sampled as linear, alpha not
/// premultiplied). Rounding M up keeps the brightest channel at or below 1,
/// so values up to `RGBM_RANGE` survive; larger values clamp to it.
pub const RGBM_RANGE: f32 = 6.0;

/// A linear value that can be encoded: non-finite and negative become 0.
fn clean(v: f32) -> f64 {
    if v.is_finite() && v > 0.0 {
        v as f64
    } else {
        0.0
    }
}

/// Linear value to an 8-bit sRGB code, clamped, rounded to nearest; NaN is 0.
pub fn srgb8(v: f64) -> u8 {
    (linear_to_srgb(v) * 255.0).round() as u8
}

/// Linear value to a 16-bit sRGB code, clamped, rounded to nearest; NaN is 0.
pub fn srgb16(v: f64) -> u16 {
    (linear_to_srgb(v) * 65535.0).round() as u16
}

/// Encodes linear RGB as RGBM (see [`RGBM_RANGE`] for the convention).
/// Non-finite and negative channels encode as 0.
pub fn rgbm_encode(rgb: [f32; 3]) -> [u8; 4] {
    let c = rgb.map(clean);
    let max = c[0].max(c[1]).max(c[2]);
    let range = RGBM_RANGE as f64;
    let m = (max / range * 255.0).ceil().clamp(1.0, 255.0);
    let scale = m / 255.0 * range;
    let q = c.map(|v| ((v / scale).min(1.0) * 255.0).round() as u8);
    [q[0], q[1], q[2], m as u8]
}

/// Decodes an RGBM pixel to linear RGB: `rgb * a * RGBM_RANGE`.
pub fn rgbm_decode(p: [u8; 4]) -> [f32; 3] {
    let m = p[3] as f32 / 255.0 * RGBM_RANGE;
    [p[0], p[1], p[2]].map(|c| c as f32 / 255.0 * m)
}

// ---------------------------------------------------------------------------
// Images in memory

/// Rejects a level and lightmap that do not describe the same pixels, or no
/// pixels at all (no image format can hold a 0-pixel image).
fn check_sizes(level: &Level, map: &Lightmap) -> Result<(), OutputError> {
    let invalid = |message: String| OutputError::Invalid {
        level: level.name.clone(),
        message,
    };
    let (w, h) = (level.width, level.height);
    if w == 0 || h == 0 {
        return Err(invalid(format!(
            "the level is {w}x{h} pixels, there is nothing to write"
        )));
    }
    if u32::try_from(w).is_err() || u32::try_from(h).is_err() {
        return Err(invalid(format!(
            "the level is {w}x{h} pixels, too large for an image"
        )));
    }
    if map.width != w || map.height != h {
        return Err(invalid(format!(
            "the lightmap is {}x{} pixels but the level is {w}x{h}",
            map.width, map.height
        )));
    }
    let n = w * h;
    if level.cells.len() != n || level.albedo.len() != n || map.rgb.len() != n {
        return Err(invalid(format!(
            "expected {n} pixels, got {} cells, {} albedos and {} lightmap values",
            level.cells.len(),
            level.albedo.len(),
            map.rgb.len()
        )));
    }
    Ok(())
}

/// The linear, exposed colour of pixel `i` in the lightmap (`lit == false`)
/// or lit image, or `None` on void.
fn sdr_linear(
    level: &Level,
    map: &Lightmap,
    i: usize,
    exposure: f64,
    lit: bool,
) -> Option<[f64; 3]> {
    let v = map.rgb[i].map(clean);
    match level.cells[i] {
        Cell::Void => None,
        Cell::Floor if lit => {
            let a = level.albedo[i].map(clean);
            Some([0, 1, 2].map(|k| a[k] * v[k] * exposure))
        }
        // Solid pixels show their own radiosity in both images: emitters glow.
        Cell::Floor | Cell::Solid(_) => Some(v.map(|c| c * exposure)),
    }
}

/// The lightmap (`lit == false`) or lit image at the chosen depth.
fn sdr_image(level: &Level, map: &Lightmap, opts: &OutputOptions, lit: bool) -> DynamicImage {
    let (w, h) = (level.width as u32, level.height as u32);
    let px = |x: u32, y: u32| {
        sdr_linear(
            level,
            map,
            y as usize * level.width + x as usize,
            opts.exposure,
            lit,
        )
    };
    match opts.depth {
        Depth::Eight => {
            DynamicImage::ImageRgba8(ImageBuffer::from_fn(w, h, |x, y| match px(x, y) {
                Some(c) => Rgba([srgb8(c[0]), srgb8(c[1]), srgb8(c[2]), u8::MAX]),
                None => Rgba([0; 4]),
            }))
        }
        Depth::Sixteen => {
            DynamicImage::ImageRgba16(ImageBuffer::from_fn(w, h, |x, y| match px(x, y) {
                Some(c) => Rgba([srgb16(c[0]), srgb16(c[1]), srgb16(c[2]), u16::MAX]),
                None => Rgba([0; 4]),
            }))
        }
    }
}

/// `NAME.lightmap.png` in memory: I(p) x exposure, sRGB, void transparent.
pub fn lightmap_image(
    level: &Level,
    map: &Lightmap,
    opts: &OutputOptions,
) -> Result<DynamicImage, OutputError> {
    check_sizes(level, map)?;
    Ok(sdr_image(level, map, opts, false))
}

/// `NAME.lit.png` in memory: albedo x I(p) x exposure on floor, the
/// lightmap's value on solid pixels, sRGB, void transparent.
pub fn lit_image(
    level: &Level,
    map: &Lightmap,
    opts: &OutputOptions,
) -> Result<DynamicImage, OutputError> {
    check_sizes(level, map)?;
    Ok(sdr_image(level, map, opts, true))
}

/// The linear HDR lightmap: I(p) on floor pixels, unscaled by exposure and
/// unclamped above; 0 on solid and void pixels (SPEC section 5), and 0 where
/// the solve produced a negative or non-finite value (light is never
/// negative). Row-major.
pub fn hdr_pixels(level: &Level, map: &Lightmap) -> Result<Vec<[f32; 3]>, OutputError> {
    check_sizes(level, map)?;
    Ok(level
        .cells
        .iter()
        .zip(&map.rgb)
        .map(|(c, v)| {
            if *c == Cell::Floor {
                v.map(|x| clean(x) as f32)
            } else {
                [0.0; 3]
            }
        })
        .collect())
}

/// `NAME.lightmap.rgbm.png` in memory: [`hdr_pixels`] encoded with
/// [`rgbm_encode`] (so solid and void pixels decode to 0, as in the EXR).
pub fn rgbm_image(level: &Level, map: &Lightmap) -> Result<RgbaImage, OutputError> {
    let hdr = hdr_pixels(level, map)?;
    let w = level.width;
    Ok(ImageBuffer::from_fn(
        level.width as u32,
        level.height as u32,
        |x, y| Rgba(rgbm_encode(hdr[y as usize * w + x as usize])),
    ))
}

// ---------------------------------------------------------------------------
// Encoders

/// PNG bytes of any image (8 or 16 bits per channel, as the image holds).
pub fn encode_png(img: &DynamicImage) -> Result<Vec<u8>, image::ImageError> {
    let mut bytes = Vec::new();
    img.write_with_encoder(PngEncoder::new(&mut bytes))?;
    Ok(bytes)
}

/// PNG bytes of an 8-bit RGBA image.
pub fn encode_png_rgba8(img: &RgbaImage) -> Result<Vec<u8>, image::ImageError> {
    let mut bytes = Vec::new();
    img.write_with_encoder(PngEncoder::new(&mut bytes))?;
    Ok(bytes)
}

/// PNG bytes of a 16-bit RGBA image.
pub fn encode_png_rgba16(
    img: &ImageBuffer<Rgba<u16>, Vec<u16>>,
) -> Result<Vec<u8>, image::ImageError> {
    let mut bytes = Vec::new();
    img.write_with_encoder(PngEncoder::new(&mut bytes))?;
    Ok(bytes)
}

/// Bytes of a single-part, scan-line, uncompressed OpenEXR file holding
/// `rgb` (row-major, `width * height`) as 32-bit float R, G, B channels.
///
/// Written by hand rather than through `image`'s encoder because that one
/// compresses tiles in parallel and writes them in completion order, so the
/// same lightmap could give different bytes from run to run.
pub fn encode_exr_rgb32f(width: usize, height: usize, rgb: &[[f32; 3]]) -> Result<Vec<u8>, String> {
    let (w, h) = match (i32::try_from(width), i32::try_from(height)) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 => (w, h),
        _ => return Err(format!("an EXR image cannot be {width}x{height} pixels")),
    };
    if rgb.len() != width * height {
        return Err(format!(
            "{} pixels given for a {width}x{height} image",
            rgb.len()
        ));
    }
    fn attr(out: &mut Vec<u8>, name: &str, kind: &str, value: &[u8]) {
        out.extend_from_slice(name.as_bytes());
        out.push(0);
        out.extend_from_slice(kind.as_bytes());
        out.push(0);
        out.extend_from_slice(&(value.len() as i32).to_le_bytes());
        out.extend_from_slice(value);
    }
    let le = |v: &[i32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let line_bytes = width * 3 * 4;
    let mut out = Vec::with_capacity(400 + height * (16 + line_bytes));
    out.extend_from_slice(&20000630i32.to_le_bytes()); // magic number
    out.extend_from_slice(&[2, 0, 0, 0]); // version 2, single-part scan lines
    // Channels are listed, and stored in each line, in alphabetical order.
    let mut chlist = Vec::new();
    for name in ["B", "G", "R"] {
        chlist.extend_from_slice(name.as_bytes());
        chlist.push(0);
        chlist.extend_from_slice(&2i32.to_le_bytes()); // FLOAT
        chlist.extend_from_slice(&[0, 0, 0, 0]); // pLinear, reserved
        chlist.extend_from_slice(&le(&[1, 1])); // x and y sampling
    }
    chlist.push(0);
    attr(&mut out, "channels", "chlist", &chlist);
    attr(&mut out, "compression", "compression", &[0]); // none
    let window = le(&[0, 0, w - 1, h - 1]);
    attr(&mut out, "dataWindow", "box2i", &window);
    attr(&mut out, "displayWindow", "box2i", &window);
    attr(&mut out, "lineOrder", "lineOrder", &[0]); // increasing y
    attr(&mut out, "pixelAspectRatio", "float", &1f32.to_le_bytes());
    attr(&mut out, "screenWindowCenter", "v2f", &[0; 8]);
    attr(&mut out, "screenWindowWidth", "float", &1f32.to_le_bytes());
    out.push(0); // end of header
    // Offset table: one chunk per scan line, each 8 bytes of header + data.
    let first = (out.len() + height * 8) as u64;
    for y in 0..height as u64 {
        out.extend_from_slice(&(first + y * (8 + line_bytes as u64)).to_le_bytes());
    }
    for (y, row) in rgb.chunks_exact(width).enumerate() {
        out.extend_from_slice(&(y as i32).to_le_bytes());
        out.extend_from_slice(&(line_bytes as i32).to_le_bytes());
        for k in [2, 1, 0] {
            for p in row {
                out.extend_from_slice(&p[k].to_le_bytes());
            }
        }
    }
    Ok(out)
}

/// Reads an HDR lightmap (any RGB or RGBA float EXR) back: width, height and
/// row-major linear RGB.
pub fn read_lightmap_exr(path: &Path) -> Result<(usize, usize, Vec<[f32; 3]>), OutputError> {
    let read = |message: String| OutputError::Read {
        path: path.to_path_buf(),
        message,
    };
    let bytes = std::fs::read(path).map_err(|e| read(describe_io(&e)))?;
    let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::OpenExr)
        .map_err(|e| read(format!("not a readable EXR image ({e})")))?
        .into_rgb32f();
    let (w, h) = (img.width() as usize, img.height() as usize);
    Ok((w, h, img.pixels().map(|p| p.0).collect()))
}

// ---------------------------------------------------------------------------
// Writing

/// Encodes the image outputs of one level in memory, in writing order.
fn encode_images(
    level: &Level,
    map: &Lightmap,
    opts: &OutputOptions,
) -> Result<Vec<(OutputKind, Vec<u8>)>, OutputError> {
    check_sizes(level, map)?;
    let name = &level.name;
    let png = |kind: OutputKind, img: &DynamicImage| {
        encode_png(img).map_err(|e| OutputError::Encode {
            path: kind.file_name(name).into(),
            message: e.to_string(),
        })
    };
    // The two images are independent: encoded side by side (the end of a
    // bake leaves the other cores idle, and deflate is most of the time).
    let (lightmap, lit) = rayon::join(
        || png(OutputKind::Lightmap, &sdr_image(level, map, opts, false)),
        || png(OutputKind::Lit, &sdr_image(level, map, opts, true)),
    );
    let mut files = vec![(OutputKind::Lightmap, lightmap?), (OutputKind::Lit, lit?)];
    if opts.hdr {
        let bytes = encode_exr_rgb32f(level.width, level.height, &hdr_pixels(level, map)?)
            .map_err(|message| OutputError::Encode {
                path: OutputKind::Hdr.file_name(name).into(),
                message,
            })?;
        files.push((OutputKind::Hdr, bytes));
    }
    if opts.rgbm {
        files.push((
            OutputKind::Rgbm,
            png(
                OutputKind::Rgbm,
                &DynamicImage::ImageRgba8(rgbm_image(level, map)?),
            )?,
        ));
    }
    Ok(files)
}

/// Writes every output of one level into `dir` (which must exist, see
/// [`ensure_output_dir`]): `NAME.lightmap.png`, `NAME.lit.png`, with
/// `opts.hdr` `NAME.lightmap.exr`, with `opts.rgbm` `NAME.lightmap.rgbm.png`,
/// and last `NAME.report.json`. Returns the paths written, in that order.
///
/// The report written is a copy of `report` with `outputs` set to the file
/// names written (report included, relative to `dir`), `timings.write` set
/// to the seconds spent encoding and writing the images, and that time
/// added to `timings.total`.
///
/// Nothing is written when the inputs are inconsistent or an image fails to
/// encode. Each file is replaced atomically; if a later file fails, the
/// earlier ones of this call are already new and the report is not written.
pub fn write_level_outputs(
    dir: &Path,
    level: &Level,
    map: &Lightmap,
    report: &Report,
    opts: &OutputOptions,
) -> Result<Vec<PathBuf>, OutputError> {
    let start = Instant::now();
    check_output_dir(dir)?;
    let files = encode_images(level, map, opts)?;
    let mut written = Vec::with_capacity(files.len() + 1);
    let mut names = Vec::with_capacity(files.len() + 1);
    for (kind, bytes) in &files {
        let name = kind.file_name(&level.name);
        let path = dir.join(&name);
        write_file_atomic(&path, bytes)?;
        written.push(path);
        names.push(name);
    }
    let report_name = OutputKind::Report.file_name(&level.name);
    let report_path = dir.join(&report_name);
    names.push(report_name);
    let mut report = report.clone();
    report.outputs = names;
    let seconds = start.elapsed().as_secs_f64();
    report.timings.write = seconds;
    report.timings.total += seconds;
    let mut json = serde_json::to_vec_pretty(&report).map_err(|e| OutputError::Encode {
        path: report_path.clone(),
        message: e.to_string(),
    })?;
    json.push(b'\n');
    write_file_atomic(&report_path, &json)?;
    written.push(report_path);
    Ok(written)
}

/// Writes only `NAME.lightmap.png` and `NAME.lit.png`; returns their paths.
/// Kept for early callers; [`write_level_outputs`] writes everything.
pub fn write_images(
    dir: &Path,
    level: &Level,
    map: &Lightmap,
    opts: &OutputOptions,
) -> io::Result<Vec<PathBuf>> {
    let opts = OutputOptions {
        hdr: false,
        rgbm: false,
        ..opts.clone()
    };
    let files = encode_images(level, map, &opts).map_err(io::Error::other)?;
    let mut out = Vec::with_capacity(files.len());
    for (kind, bytes) in files {
        let path = dir.join(kind.file_name(&level.name));
        write_atomic(&path, &bytes)?;
        out.push(path);
    }
    Ok(out)
}
