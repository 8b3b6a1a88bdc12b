//! OpenEXR: the HDR lightmap and layers as linear 32-bit float RGB, written
//! by our own encoder so that the bytes depend only on the pixels, and read
//! back through `image`.

use std::path::Path;

use super::OutputError;
use super::exr_compressed::{ExrCompression, encode_exr_f32_compressed};
use super::files::describe_io;

/// `rgb` (row-major, `width * height`) as a 32-bit float RGB EXR
/// compressed with `compression`: [`encode_exr_rgb32f`] for
/// [`ExrCompression::None`], else the `exr` crate's encoder
/// ([`super::exr_compressed`]). Both are lossless and deterministic.
pub fn encode_exr_rgb(
    width: usize,
    height: usize,
    rgb: &[[f32; 3]],
    compression: ExrCompression,
) -> Result<Vec<u8>, String> {
    match compression {
        ExrCompression::None => encode_exr_rgb32f(width, height, rgb),
        c => encode_exr_f32_compressed(
            width,
            height,
            planes(rgb, &[("B", 2), ("G", 1), ("R", 0)]),
            c,
        ),
    }
}

/// `rgba` as [`encode_exr_rgb`] writes RGB, with the `A` channel.
pub fn encode_exr_rgba(
    width: usize,
    height: usize,
    rgba: &[[f32; 4]],
    compression: ExrCompression,
) -> Result<Vec<u8>, String> {
    match compression {
        ExrCompression::None => encode_exr_rgba32f(width, height, rgba),
        c => encode_exr_f32_compressed(
            width,
            height,
            planes(rgba, &[("A", 3), ("B", 2), ("G", 1), ("R", 0)]),
            c,
        ),
    }
}

/// One plane per named channel index of `pixels`.
fn planes<const N: usize>(
    pixels: &[[f32; N]],
    channels: &[(&'static str, usize)],
) -> Vec<(&'static str, Vec<f32>)> {
    channels
        .iter()
        .map(|&(name, k)| (name, pixels.iter().map(|p| p[k]).collect()))
        .collect()
}

/// Bytes of a single-part, scan-line, uncompressed OpenEXR file holding
/// `rgb` (row-major, `width * height`) as 32-bit float R, G, B channels.
///
/// Written by hand rather than through `image`'s encoder because that one
/// compresses tiles in parallel and writes them in completion order, so the
/// same lightmap could give different bytes from run to run.
pub fn encode_exr_rgb32f(width: usize, height: usize, rgb: &[[f32; 3]]) -> Result<Vec<u8>, String> {
    if rgb.len() != width * height {
        return Err(format!(
            "{} pixels given for a {width}x{height} image",
            rgb.len()
        ));
    }
    encode_exr_f32(width, height, &[("B", 2), ("G", 1), ("R", 0)], |i, k| {
        rgb[i][k]
    })
}

/// Bytes of a single-part, scan-line, uncompressed OpenEXR file holding
/// `rgba` (row-major, `width * height`) as 32-bit float R, G, B and A
/// channels, A not premultiplied into the colour (the padded lightmap's
/// coverage, see [`super::padding`]). Same encoder as
/// [`encode_exr_rgb32f`], one channel more.
pub fn encode_exr_rgba32f(
    width: usize,
    height: usize,
    rgba: &[[f32; 4]],
) -> Result<Vec<u8>, String> {
    if rgba.len() != width * height {
        return Err(format!(
            "{} pixels given for a {width}x{height} image",
            rgba.len()
        ));
    }
    encode_exr_f32(
        width,
        height,
        &[("A", 3), ("B", 2), ("G", 1), ("R", 0)],
        |i, k| rgba[i][k],
    )
}

/// Bytes of a single-part, scan-line, uncompressed OpenEXR file of 32-bit
/// float channels with any names (`channels`: name and the index
/// `value(pixel, index)` reads), sorted here into the alphabetical order
/// OpenEXR lists and stores them in. The same encoder as
/// [`encode_exr_rgb32f`].
pub fn encode_exr_channels(
    width: usize,
    height: usize,
    channels: &[(&str, usize)],
    value: impl Fn(usize, usize) -> f32,
) -> Result<Vec<u8>, String> {
    let mut sorted = channels.to_vec();
    sorted.sort_by(|a, b| a.0.as_bytes().cmp(b.0.as_bytes()));
    encode_exr_f32(width, height, &sorted, value)
}

/// The shared encoder: `channels` in alphabetical order (as OpenEXR lists
/// and stores them), each with the index `value(pixel, index)` reads.
fn encode_exr_f32(
    width: usize,
    height: usize,
    channels: &[(&str, usize)],
    value: impl Fn(usize, usize) -> f32,
) -> Result<Vec<u8>, String> {
    let (w, h) = match (i32::try_from(width), i32::try_from(height)) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 => (w, h),
        _ => return Err(format!("an EXR image cannot be {width}x{height} pixels")),
    };
    fn attr(out: &mut Vec<u8>, name: &str, kind: &str, value: &[u8]) {
        out.extend_from_slice(name.as_bytes());
        out.push(0);
        out.extend_from_slice(kind.as_bytes());
        out.push(0);
        out.extend_from_slice(&(value.len() as i32).to_le_bytes());
        out.extend_from_slice(value);
    }
    let le = |v: &[i32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let line_bytes = width * channels.len() * 4;
    let mut out = Vec::with_capacity(400 + height * (16 + line_bytes));
    out.extend_from_slice(&20000630i32.to_le_bytes()); // magic number
    out.extend_from_slice(&[2, 0, 0, 0]); // version 2, single-part scan lines
    // Channels are listed, and stored in each line, in alphabetical order.
    let mut chlist = Vec::new();
    for (name, _) in channels {
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
    for y in 0..height {
        out.extend_from_slice(&(y as i32).to_le_bytes());
        out.extend_from_slice(&(line_bytes as i32).to_le_bytes());
        for &(_, k) in channels {
            for x in 0..width {
                out.extend_from_slice(&value(y * width + x, k).to_le_bytes());
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
