//! Pixels to image bytes: linear light to sRGB codes (8 or 16 bits), the
//! RGBM encoding, the lightmap and lit images of a level, and PNG bytes.

use image::codecs::png::PngEncoder;
use image::{DynamicImage, ImageBuffer, Rgba, RgbaImage};

use super::{Depth, OutputError, OutputOptions};
use crate::bake::Lightmap;
use crate::level::material::linear_to_srgb;
use crate::level::{Cell, Level};

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
    rgbm_encode_range(rgb.map(clean), RGBM_RANGE as f64)
}

/// RGBM of non-negative channels `c` with multiplier range `range`.
fn rgbm_encode_range(c: [f64; 3], range: f64) -> [u8; 4] {
    let max = c[0].max(c[1]).max(c[2]);
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

/// Range of Unity's RGBM: the largest gamma-space value it holds
/// (`UNITY_RGBM_RANGE^UNITY_RGBM_GAMMA`, about 34.5, in linear light).
pub const UNITY_RGBM_RANGE: f32 = 5.0;

/// The gamma of Unity's RGBM: values are stored as `v^(1/2.2)`.
pub const UNITY_RGBM_GAMMA: f32 = 2.2;

/// Encodes linear RGB as RGBM in Unity's convention (`DecodeLightmapRGBM`
/// in UnityCG.cginc): each channel goes to gamma space as
/// `g = v^(1/UNITY_RGBM_GAMMA)`, then `g` is encoded as [`rgbm_encode`]
/// does with range [`UNITY_RGBM_RANGE`] instead of [`RGBM_RANGE`]. Decode
/// with [`rgbm_unity_decode`]: `(rgb * a * 5)^2.2`. Linear values above
/// `5^2.2` (about 34.5) clamp to it; non-finite and negative channels
/// encode as 0.
///
/// Error bound: in gamma space each channel is within half a step of its
/// pixel's multiplier, `|g' - g| <= 5 a / 510` with `a = M` the stored
/// alpha in `[0, 1]` (`M <= max(g) / 5 + 1/255`), so in linear light
/// `|v' - v| <= (g + 5 a / 510)^2.2 - g^2.2`: about
/// `2.2 / 510 * (1 + 0.02 / max(g))` of the pixel's brightest channel, at
/// most 0.5 % of it when that channel is 0.01 or more (0.48 % measured).
pub fn rgbm_unity_encode(rgb: [f32; 3]) -> [u8; 4] {
    let gamma = 1.0 / UNITY_RGBM_GAMMA as f64;
    rgbm_encode_range(rgb.map(|v| clean(v).powf(gamma)), UNITY_RGBM_RANGE as f64)
}

/// Decodes a Unity-convention RGBM pixel ([`rgbm_unity_encode`]) to linear
/// RGB: `(rgb * a * UNITY_RGBM_RANGE)^UNITY_RGBM_GAMMA`.
pub fn rgbm_unity_decode(p: [u8; 4]) -> [f32; 3] {
    let m = p[3] as f32 / 255.0 * UNITY_RGBM_RANGE;
    [p[0], p[1], p[2]].map(|c| (c as f32 / 255.0 * m).powf(UNITY_RGBM_GAMMA))
}

/// Rejects a level and lightmap that do not describe the same pixels, or no
/// pixels at all (no image format can hold a 0-pixel image).
pub(crate) fn check_sizes(level: &Level, map: &Lightmap) -> Result<(), OutputError> {
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
pub(crate) fn sdr_image(
    level: &Level,
    map: &Lightmap,
    opts: &OutputOptions,
    lit: bool,
) -> DynamicImage {
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

/// The padded lightmap at the chosen depth: `padded` (linear, row-major,
/// see [`padded_hdr_pixels`]) x exposure in sRGB, alpha the coverage
/// ([`Level::coverage`]: opaque on floor, transparent on padding, wall and
/// void, the floor's share of the texel below one texel per pixel), rounded
/// to the nearest code.
pub(crate) fn padded_sdr_image(
    level: &Level,
    padded: &[[f32; 3]],
    opts: &OutputOptions,
) -> DynamicImage {
    let (w, h) = (level.width as u32, level.height as u32);
    let coverage = level.coverage();
    let px = |x: u32, y: u32| {
        let i = y as usize * level.width + x as usize;
        (
            padded[i].map(|c| clean(c) * opts.exposure),
            coverage[i] as f64,
        )
    };
    match opts.depth {
        Depth::Eight => DynamicImage::ImageRgba8(ImageBuffer::from_fn(w, h, |x, y| {
            let (c, a) = px(x, y);
            Rgba([
                srgb8(c[0]),
                srgb8(c[1]),
                srgb8(c[2]),
                (a * 255.0).round() as u8,
            ])
        })),
        Depth::Sixteen => DynamicImage::ImageRgba16(ImageBuffer::from_fn(w, h, |x, y| {
            let (c, a) = px(x, y);
            Rgba([
                srgb16(c[0]),
                srgb16(c[1]),
                srgb16(c[2]),
                (a * 65535.0).round() as u16,
            ])
        })),
    }
}

/// The linear HDR lightmap padded by `texels` (see [`super::padding`]):
/// [`lightmap_pixels`] with the non-floor texels within `texels` of the
/// floor filled from it ([`super::padding::pad_over`]); floor texels and
/// texels further away keep their values (what `--walls` put on wall
/// faces, 0 on void). With `texels == 0`, [`lightmap_pixels`] itself.
pub fn padded_hdr_pixels(
    level: &Level,
    map: &Lightmap,
    texels: u32,
) -> Result<Vec<[f32; 3]>, OutputError> {
    let mut hdr = lightmap_pixels(level, map)?;
    if texels > 0 {
        let floor: Vec<bool> = level.cells.iter().map(|c| *c == Cell::Floor).collect();
        super::padding::pad_over(level.width, level.height, &mut hdr, &floor, texels);
    }
    Ok(hdr)
}

/// The linear values every lightmap output (PNG, EXR, KTX2, both RGBMs,
/// layers) encodes before padding: I(p) on floor texels, the lightmap's
/// value on solid texels (what [`crate::bake::Walls`] puts there: the
/// radiosity of exposed wall faces by default, emission with glow, 0 with
/// dark), 0 on void; unscaled by exposure and unclamped above, 0 where the
/// value is negative or not finite. Row-major.
pub fn lightmap_pixels(level: &Level, map: &Lightmap) -> Result<Vec<[f32; 3]>, OutputError> {
    linear_pixels(level, map, |c| c != Cell::Void)
}

/// The map's values, cleaned, on the cells `keep` holds; 0 elsewhere.
fn linear_pixels(
    level: &Level,
    map: &Lightmap,
    keep: impl Fn(Cell) -> bool,
) -> Result<Vec<[f32; 3]>, OutputError> {
    check_sizes(level, map)?;
    Ok(level
        .cells
        .iter()
        .zip(&map.rgb)
        .map(|(&c, v)| {
            if keep(c) {
                v.map(|x| clean(x) as f32)
            } else {
                [0.0; 3]
            }
        })
        .collect())
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

/// The linear light of the floor: I(p) on floor pixels, unscaled by
/// exposure and unclamped above; 0 on solid and void pixels, and 0 where
/// the solve produced a negative or non-finite value (light is never
/// negative). Row-major. The mean beside the directional moments; the
/// lightmap outputs encode [`lightmap_pixels`], which adds the walls.
pub fn hdr_pixels(level: &Level, map: &Lightmap) -> Result<Vec<[f32; 3]>, OutputError> {
    linear_pixels(level, map, |c| c == Cell::Floor)
}

/// `NAME.lightmap.rgbm.png` in memory: [`lightmap_pixels`] encoded with
/// [`rgbm_encode`] (the values of the unpadded EXR).
pub fn rgbm_image(level: &Level, map: &Lightmap) -> Result<RgbaImage, OutputError> {
    let hdr = lightmap_pixels(level, map)?;
    Ok(rgbm_image_of(level, &hdr))
}

/// RGBM (linear, [`rgbm_encode`]) of linear HDR pixels of `level`'s size.
pub(crate) fn rgbm_image_of(level: &Level, hdr: &[[f32; 3]]) -> RgbaImage {
    rgbm_image_with(level, hdr, rgbm_encode)
}

/// `hdr` (linear, `level`'s size) with each pixel encoded by `encode`.
pub(crate) fn rgbm_image_with(
    level: &Level,
    hdr: &[[f32; 3]],
    encode: fn([f32; 3]) -> [u8; 4],
) -> RgbaImage {
    let w = level.width;
    ImageBuffer::from_fn(level.width as u32, level.height as u32, |x, y| {
        Rgba(encode(hdr[y as usize * w + x as usize]))
    })
}

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
