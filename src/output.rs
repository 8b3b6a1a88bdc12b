//! Writing results: lightmap and lit PNGs, the HDR EXR and the report, each
//! written atomically (SPEC section 5).

use std::io;
use std::path::{Path, PathBuf};

use crate::level::{Cell, Level};
use crate::material::linear_to_srgb;

/// Linear light per pixel, ready to encode.
#[derive(Clone, Debug)]
pub struct Lightmap {
    pub width: usize,
    pub height: usize,
    /// Row-major linear RGB: I(p) on floor pixels, the mean radiosity of the
    /// exposed edges on solid pixels, zero on void pixels.
    pub rgb: Vec<[f32; 3]>,
}

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
    /// Multiplies I(p) before encoding the PNGs (not the EXR).
    pub exposure: f64,
    pub depth: Depth,
    /// Also write `NAME.lightmap.exr`.
    pub hdr: bool,
}

impl Default for OutputOptions {
    fn default() -> Self {
        OutputOptions { exposure: 1.0, depth: Depth::Eight, hdr: false }
    }
}

/// Writes `bytes` to `path` through a temporary file in the same folder that
/// is renamed into place, so a failure never leaves a half-written file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    use std::io::Write;
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let mut tmp = tempfile::NamedTempFile::new_in(dir)?;
    tmp.write_all(bytes)?;
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

/// Writes the image outputs of one level; returns the paths written.
pub fn write_images(dir: &Path, level: &Level, map: &Lightmap, opts: &OutputOptions) -> io::Result<Vec<PathBuf>> {
    let (w, h) = (map.width, map.height);
    let mut light = image::RgbaImage::new(w as u32, h as u32);
    let mut lit = image::RgbaImage::new(w as u32, h as u32);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let c = level.cells[i];
            if c == Cell::Void {
                continue;
            }
            let v = map.rgb[i];
            let enc = |v: f64| (linear_to_srgb(v) * 255.0).round() as u8;
            let l = [0, 1, 2].map(|k| enc(v[k] as f64 * opts.exposure));
            light.put_pixel(x as u32, y as u32, image::Rgba([l[0], l[1], l[2], 255]));
            let a = if c == Cell::Floor { level.albedo[i] } else { [1.0; 3] };
            let p = [0, 1, 2].map(|k| enc(v[k] as f64 * a[k] as f64 * opts.exposure));
            lit.put_pixel(x as u32, y as u32, image::Rgba([p[0], p[1], p[2], 255]));
        }
    }
    let mut out = vec![];
    for (suffix, img) in [("lightmap.png", &light), ("lit.png", &lit)] {
        let path = dir.join(format!("{}.{}", level.name, suffix));
        let mut bytes = Vec::new();
        img.write_to(&mut io::Cursor::new(&mut bytes), image::ImageFormat::Png).map_err(io::Error::other)?;
        write_atomic(&path, &bytes)?;
        out.push(path);
    }
    Ok(out)
}
