//! The directional lightmap's files (docs/transport.md#directional-lightmaps):
//! `NAME.directional.exr` (the mean and the first circular moments, linear
//! HDR), `NAME.direction.png` (an 8-bit preview of the dominant direction)
//! and, for a level with a normal map `NAME.normals.png` beside it,
//! `NAME.lit-normals.png` (the lit image with each floor texel shaded by
//! its normal).
//!
//! Normal maps are RGB = `n * 0.5 + 0.5` with green up (OpenGL style: `+y`
//! points up on screen, the way the moments' angles are measured), blue out
//! of the level towards the viewer. A DirectX-style map (green down) needs
//! its green channel inverted first.

use std::path::Path;

use ::image::DynamicImage;

use super::files::describe_io;
use super::{Encoded, OutputError, OutputKind, OutputOptions, image};
use crate::bake::{Density, Directional, Lightmap};
use crate::level::{Cell, Level};

/// `cot` of the elevation the baked light is taken to arrive at when a
/// normal shades it: 45 degrees, so 1. See [`shade`].
pub const SLOPE: f32 = 1.0;

/// The light on a surface of unit normal `n` from the mean `mean` and the
/// moments `cos`, `sin` of one channel: `max(0, nz mean + SLOPE (nx cos +
/// ny sin))`. That is the Lambert response to the baked light arriving from
/// its directions in the level's plane at an elevation of 45 degrees,
/// normalised so that a flat texel (`n = (0, 0, 1)`) gets the lightmap's
/// value; it is exact for every normal tilted at most 45 degrees from
/// `+z` (where no direction is clamped) and underestimates steeper ones by at
/// most `mean * max(0, |n_xy| - nz)` (README, "Directional lightmaps and
/// normal maps").
pub fn shade(mean: f32, cos: f32, sin: f32, n: [f32; 3]) -> f32 {
    (n[2] * mean + SLOPE * (n[0] * cos + n[1] * sin)).max(0.0)
}

/// A level's normal map: a unit normal per pixel, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMap {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Unit normals, `+x` right, `+y` up, `+z` towards the viewer.
    pub normals: Vec<[f32; 3]>,
}

impl NormalMap {
    /// Decodes a normal map image (any format `image` reads; RGB =
    /// `n * 0.5 + 0.5`, green up). A texel whose vector is zero counts as
    /// flat.
    pub fn decode(bytes: &[u8]) -> Result<NormalMap, String> {
        let img = ::image::load_from_memory(bytes)
            .map_err(|e| format!("not a readable image ({e})"))?
            .into_rgb8();
        let (width, height) = (img.width() as usize, img.height() as usize);
        let normals = img
            .pixels()
            .map(|p| {
                let v = p.0.map(|c| c as f32 / 127.5 - 1.0);
                let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                if len > 1e-3 {
                    v.map(|c| c / len)
                } else {
                    [0.0, 0.0, 1.0]
                }
            })
            .collect();
        Ok(NormalMap {
            width,
            height,
            normals,
        })
    }

    /// Reads `path` for a level painted `painted` pixels (width, height)
    /// and baked at `density`: a normal map painted pixel for pixel, or one
    /// texel for texel of the lightmap; the first is brought to the texel
    /// grid ([`NormalMap::to_texels`]).
    pub fn read(
        path: &Path,
        painted: [usize; 2],
        density: Density,
    ) -> Result<NormalMap, OutputError> {
        let fail = |message: String| OutputError::NormalMap {
            path: path.to_path_buf(),
            message,
        };
        let bytes = std::fs::read(path).map_err(|e| fail(describe_io(&e)))?;
        let map = NormalMap::decode(&bytes).map_err(fail)?;
        let [w, h] = painted;
        let (tw, th) = density.texels(w, h);
        if (map.width, map.height) == (tw, th) {
            return Ok(map);
        }
        if (map.width, map.height) != (w, h) {
            let texels = if (tw, th) == (w, h) {
                String::new()
            } else {
                format!(" or its lightmap's {tw}x{th} texels")
            };
            return Err(fail(format!(
                "it is {}x{} pixels but the level is {w}x{h}; a normal map must match its level pixel for pixel{texels}",
                map.width, map.height
            )));
        }
        Ok(map.to_texels(density))
    }

    /// This map of a painted level at the texel grid of `density`: at `N`
    /// texels per pixel each normal covers its pixel's `N x N` texels; at
    /// `1/m` a texel's normal is the normalised mean of its `m x m` pixels'
    /// (flat where they cancel).
    pub fn to_texels(&self, density: Density) -> NormalMap {
        let (tw, th) = density.texels(self.width, self.height);
        let mut normals = vec![[0.0, 0.0, 1.0]; tw * th];
        for ty in 0..th {
            for tx in 0..tw {
                let n = match density {
                    Density::Up(n) => {
                        let (x, y) = (tx / n as usize, ty / n as usize);
                        self.normals[y * self.width + x]
                    }
                    Density::Down(m) => {
                        let m = m as usize;
                        let mut sum = [0f32; 3];
                        for y in ty * m..((ty + 1) * m).min(self.height) {
                            for x in tx * m..((tx + 1) * m).min(self.width) {
                                let v = self.normals[y * self.width + x];
                                for c in 0..3 {
                                    sum[c] += v[c];
                                }
                            }
                        }
                        let len = (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]).sqrt();
                        if len > 1e-6 {
                            sum.map(|c| c / len)
                        } else {
                            [0.0, 0.0, 1.0]
                        }
                    }
                };
                normals[ty * tw + tx] = n;
            }
        }
        NormalMap {
            width: tw,
            height: th,
            normals,
        }
    }
}

/// The normal map of the level image `level_image` if there is one:
/// `NAME.normals.png` beside it.
pub fn normal_map_beside(level_image: &Path) -> Option<std::path::PathBuf> {
    let name = super::names::level_name(level_image);
    let p = level_image.with_file_name(super::names::normal_map(&name));
    p.is_file().then_some(p)
}

/// The mean of `map` and the moments `dir` as one EXR (`NAME.directional.exr`,
/// or a layer's): channels `R`, `G`, `B` the mean, `cos.R` ... `sin.B` the
/// moments, 0 off the floor.
pub fn moments_exr(
    level: &Level,
    map: &Lightmap,
    dir: &Directional,
    kind: OutputKind,
) -> Result<Encoded, OutputError> {
    let name = &level.name;
    let mean = image::hdr_pixels(level, map)?;
    let n = level.width * level.height;
    if dir.cos.len() != n || dir.sin.len() != n {
        return Err(OutputError::Invalid {
            level: name.clone(),
            message: format!("the moments have {} pixels, the level {n}", dir.cos.len()),
        });
    }
    let floor = |i: usize| level.cells[i] == Cell::Floor;
    // Channels in alphabetical order: the mean as plain R, G, B (what a
    // viewer shows), then the layers `cos` and `sin`.
    let channels: [(&str, usize); 9] = [
        ("B", 2),
        ("G", 1),
        ("R", 0),
        ("cos.B", 5),
        ("cos.G", 4),
        ("cos.R", 3),
        ("sin.B", 8),
        ("sin.G", 7),
        ("sin.R", 6),
    ];
    let value = |i: usize, k: usize| -> f32 {
        if !floor(i) {
            return 0.0;
        }
        match k {
            0..=2 => mean[i][k],
            3..=5 => dir.cos[i][k - 3],
            _ => dir.sin[i][k - 6],
        }
    };
    let bytes = super::exr::encode_exr_channels(level.width, level.height, &channels, value)
        .map_err(|message| OutputError::Encode {
            path: kind.file_name(name).into(),
            message,
        })?;
    Ok(Encoded { kind, bytes })
}

/// Encodes the directional outputs of one level: `NAME.directional.exr`,
/// `NAME.direction.png`, and `NAME.lit-normals.png` when `normals` is given.
pub fn encode_directional(
    level: &Level,
    map: &Lightmap,
    dir: &Directional,
    normals: Option<&NormalMap>,
    opts: &OutputOptions,
) -> Result<Vec<Encoded>, OutputError> {
    let name = &level.name;
    let mut files = vec![moments_exr(level, map, dir, OutputKind::DirectionalExr)?];
    let mean = image::hdr_pixels(level, map)?;
    let n = level.width * level.height;
    let floor = |i: usize| level.cells[i] == Cell::Floor;
    let png = |kind: OutputKind, img: &DynamicImage| super::encoded_png(name, kind, img);
    let (w, h) = (level.width as u32, level.height as u32);
    let preview = ::image::RgbImage::from_fn(w, h, |x, y| {
        let i = y as usize * level.width + x as usize;
        if !floor(i) {
            return ::image::Rgb([0, 0, 0]);
        }
        ::image::Rgb(direction_colour(
            luminance(mean[i]),
            luminance(dir.cos[i]),
            luminance(dir.sin[i]),
        ))
    });
    files.push(png(
        OutputKind::DirectionPng,
        &DynamicImage::ImageRgb8(preview),
    )?);
    if let Some(nm) = normals {
        if nm.normals.len() != n {
            return Err(OutputError::Invalid {
                level: name.clone(),
                message: format!(
                    "the normal map has {} pixels, the level {n}",
                    nm.normals.len()
                ),
            });
        }
        let shaded = Lightmap {
            width: level.width,
            height: level.height,
            rgb: (0..n)
                .map(|i| {
                    if floor(i) {
                        [0, 1, 2]
                            .map(|c| shade(mean[i][c], dir.cos[i][c], dir.sin[i][c], nm.normals[i]))
                    } else {
                        map.rgb[i]
                    }
                })
                .collect(),
        };
        files.push(png(
            OutputKind::LitNormalsPng,
            &image::sdr_image(level, &shaded, opts, true),
        )?);
    }
    if opts.ktx2 {
        // The moments as the lightmap's KTX2: RGB the moment, A the floor.
        for (kind, m) in [
            (OutputKind::DirectionalCosKtx2, &dir.cos),
            (OutputKind::DirectionalSinKtx2, &dir.sin),
        ] {
            let on_floor: Vec<[f32; 3]> = (0..n)
                .map(|i| if floor(i) { m[i] } else { [0.0; 3] })
                .collect();
            let rgba = super::with_coverage(level, &on_floor);
            let bytes = super::ktx2::encode_ktx2_rgba16f_signed(level.width, level.height, &rgba)
                .map_err(|message| OutputError::Encode {
                path: kind.file_name(name).into(),
                message,
            })?;
            files.push(Encoded { kind, bytes });
        }
    }
    Ok(files)
}

/// Rec. 709 luminance weights of linear RGB.
fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The preview colour of a texel: hue the angle of the moment vector `(cos,
/// sin)` (0 degrees red: light from the right; 120 green: from up-left;
/// 240 blue: from down-left), full saturation, value its length relative to
/// the mean (0: light from all sides alike, 1: from one direction).
pub fn direction_colour(mean: f32, cos: f32, sin: f32) -> [u8; 3] {
    let len = cos.hypot(sin);
    if mean.is_nan() || mean <= 0.0 || !len.is_finite() {
        return [0, 0, 0];
    }
    let v = (len / mean).clamp(0.0, 1.0);
    let hue = sin.atan2(cos).rem_euclid(std::f32::consts::TAU) / std::f32::consts::TAU * 6.0;
    let f = hue - hue.floor();
    let (p, q, t) = (0.0, v * (1.0 - f), v * f);
    let rgb = match hue.floor() as i32 {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    };
    rgb.map(|c| (c * 255.0).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(width: usize, height: usize, normals: Vec<[f32; 3]>) -> NormalMap {
        NormalMap {
            width,
            height,
            normals,
        }
    }

    #[test]
    fn normals_are_replicated_above_one_texel_per_pixel() {
        let (l, r) = ([0.6, 0.0, 0.8], [0.0, -0.6, 0.8]);
        let t = map(2, 1, vec![l, r]).to_texels(Density::Up(2));
        assert_eq!((t.width, t.height), (4, 2));
        assert_eq!(t.normals, vec![l, l, r, r, l, l, r, r]);
    }

    #[test]
    fn normals_are_averaged_below_one_texel_per_pixel() {
        // A 3x2 map at 1/2: texel 0 the mean of four, texel 1 of the last
        // column's two, which cancel in x and y: flat.
        let (a, b) = ([0.6, 0.0, 0.8], [-0.6, 0.0, 0.8]);
        let t = map(3, 2, vec![a, a, a, a, a, b]).to_texels(Density::Down(2));
        assert_eq!((t.width, t.height), (2, 1));
        assert!((t.normals[0][0] - 0.6).abs() < 1e-6 && (t.normals[0][2] - 0.8).abs() < 1e-6);
        assert_eq!(t.normals[1], [0.0, 0.0, 1.0]);
        // Opposite normals in the plane cancel to nothing: flat too.
        let t = map(2, 1, vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]).to_texels(Density::Down(2));
        assert_eq!(t.normals, vec![[0.0, 0.0, 1.0]]);
    }
}
