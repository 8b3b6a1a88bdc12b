//! The last step of a bake: encoding a level's results as files and writing
//! them — the lightmap and lit PNGs, the optional HDR EXR, KTX2 and RGBM PNGs, the
//! light layers ([`layers`]), the relight cache ([`cache`]) and the report.
//!
//! Everything is encoded in memory first ([`encode_images`],
//! [`layers::encode_layers`]); only then is the disk touched, one file at a
//! time, each replaced atomically ([`files`]). The report is written after
//! every other output of the level, so a report on disk always describes
//! files that are there. Output bytes depend only on the inputs: no
//! timestamps, no thread-order effects (which is why the EXR writer is our
//! own, see [`exr::encode_exr_rgb32f`]). Every file name comes from
//! [`names`].

pub mod cache;
pub mod directional;
pub mod engine;
pub mod exposure;
pub mod exr;
pub mod exr_compressed;
pub mod files;
pub mod image;
pub mod ktx2;
pub mod layers;
pub mod names;
pub mod occluders;
pub mod padding;

use std::path::{Path, PathBuf};
use std::time::Instant;

use ::image::DynamicImage;

pub use self::engine::{Engine, EngineOutputs};
pub use self::exposure::Exposure;
pub use self::exr::{
    encode_exr_rgb, encode_exr_rgb32f, encode_exr_rgba, encode_exr_rgba32f, read_lightmap_exr,
};
pub use self::exr_compressed::ExrCompression;
pub use self::files::{
    OutputError, StagedFile, ensure_output_dir, remove_output, write_atomic, write_file_atomic,
};
pub use self::image::{
    RGBM_RANGE, UNITY_RGBM_GAMMA, UNITY_RGBM_RANGE, encode_png, encode_png_rgba8,
    encode_png_rgba16, hdr_pixels, lightmap_image, lightmap_pixels, lit_image, padded_hdr_pixels,
    rgbm_decode, rgbm_encode, rgbm_image, rgbm_unity_decode, rgbm_unity_encode, srgb8, srgb16,
};
pub use self::ktx2::encode_ktx2_rgba16f;
pub use self::names::OutputKind;
pub use crate::bake::Lightmap;
use crate::bake::report::Report;
use crate::level::Level;
use files::check_output_dir;

/// Bits per channel of the PNG outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Depth {
    /// 8 bits per channel (the default).
    #[default]
    Eight,
    /// 16 bits per channel: less banding in dark gradients.
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
    /// Also write `NAME.lightmap.rgbm-unity.png`: RGBM in Unity's
    /// convention, range 5 in gamma space (see [`rgbm_unity_encode`]).
    /// Default off.
    pub rgbm_unity: bool,
    /// Padding of the lightmap outputs (PNG, EXR, KTX2, RGBM, layers) in
    /// texels, see [`padding`]: non-floor texels within this many of the
    /// floor are filled from it (further ones keep what `--walls` put
    /// there, [`padded_hdr_pixels`]), and the lightmap PNG's alpha, an EXR
    /// `A` channel and the KTX2's alpha give the coverage
    /// ([`Level::coverage`]: 1 floor, 0 elsewhere, the floor's share of a
    /// texel below one texel per pixel). 0 (the default,
    /// [`padding::DEFAULT_PADDING`]) writes the lightmaps as without it.
    pub padding: u32,
    /// Also write `NAME.lightmap.ktx2`: the EXR's values as RGBA 16-bit
    /// float KTX2 ([`ktx2`]), alpha the coverage when padded, else 1.
    /// Default off.
    pub ktx2: bool,
    /// How the EXR outputs (lightmap and layers) are compressed. Default
    /// none: flatbake's own encoder.
    pub exr_compression: ExrCompression,
}

impl Default for OutputOptions {
    fn default() -> Self {
        OutputOptions {
            exposure: 1.0,
            depth: Depth::Eight,
            hdr: false,
            rgbm: false,
            rgbm_unity: false,
            padding: padding::DEFAULT_PADDING,
            ktx2: false,
            exr_compression: ExrCompression::None,
        }
    }
}

/// One encoded output file: what it is and its bytes.
#[derive(Clone, Debug)]
pub struct Encoded {
    /// Which output (and so its name).
    pub kind: OutputKind,
    /// The file's content.
    pub bytes: Vec<u8>,
}

/// `img` as a PNG output of `kind` for level `name`; an encoder failure
/// names the file.
pub(crate) fn encoded_png(
    name: &str,
    kind: OutputKind,
    img: &DynamicImage,
) -> Result<Encoded, OutputError> {
    encode_png(img)
        .map(|bytes| Encoded {
            kind: kind.clone(),
            bytes,
        })
        .map_err(|e| OutputError::Encode {
            path: kind.file_name(name).into(),
            message: e.to_string(),
        })
}

/// Encodes the image outputs of one level in memory, in writing order:
/// `NAME.lightmap.png`, `NAME.lit.png`, with `opts.hdr` `NAME.lightmap.exr`,
/// with `opts.ktx2` `NAME.lightmap.ktx2`, with `opts.rgbm`
/// `NAME.lightmap.rgbm.png`, with `opts.rgbm_unity`
/// `NAME.lightmap.rgbm-unity.png`. With `opts.padding > 0` the
/// lightmap outputs (not the lit image) are padded ([`padding`]).
pub fn encode_images(
    level: &Level,
    map: &Lightmap,
    opts: &OutputOptions,
) -> Result<Vec<Encoded>, OutputError> {
    image::check_sizes(level, map)?;
    let name = &level.name;
    let png = |kind: OutputKind, img: &DynamicImage| encoded_png(name, kind, img);
    let padded = if opts.padding > 0 {
        Some(padded_hdr_pixels(level, map, opts.padding)?)
    } else {
        None
    };
    // The two images are independent: encoded side by side (the end of a
    // bake leaves the other cores idle, and deflate is most of the time).
    let (lightmap, lit) = rayon::join(
        || {
            let img = match &padded {
                Some(p) => image::padded_sdr_image(level, p, opts),
                None => image::sdr_image(level, map, opts, false),
            };
            png(OutputKind::Lightmap, &img)
        },
        || png(OutputKind::Lit, &image::sdr_image(level, map, opts, true)),
    );
    let mut files = vec![lightmap?, lit?];
    if opts.hdr {
        let bytes = match &padded {
            Some(p) => encode_exr_rgba(
                level.width,
                level.height,
                &with_coverage(level, p),
                opts.exr_compression,
            ),
            None => encode_exr_rgb(
                level.width,
                level.height,
                &lightmap_pixels(level, map)?,
                opts.exr_compression,
            ),
        }
        .map_err(|message| OutputError::Encode {
            path: OutputKind::Hdr.file_name(name).into(),
            message,
        })?;
        files.push(Encoded {
            kind: OutputKind::Hdr,
            bytes,
        });
    }
    if opts.ktx2 {
        let rgba = match &padded {
            Some(p) => with_coverage(level, p),
            None => lightmap_pixels(level, map)?
                .into_iter()
                .map(|c| [c[0], c[1], c[2], 1.0])
                .collect(),
        };
        let bytes = encode_ktx2_rgba16f(level.width, level.height, &rgba).map_err(|message| {
            OutputError::Encode {
                path: OutputKind::Ktx2.file_name(name).into(),
                message,
            }
        })?;
        files.push(Encoded {
            kind: OutputKind::Ktx2,
            bytes,
        });
    }
    if opts.rgbm {
        files.push(png(
            OutputKind::Rgbm,
            &DynamicImage::ImageRgba8(match &padded {
                Some(p) => image::rgbm_image_of(level, p),
                None => rgbm_image(level, map)?,
            }),
        )?);
    }
    if opts.rgbm_unity {
        let hdr = match padded {
            Some(p) => p,
            None => lightmap_pixels(level, map)?,
        };
        files.push(png(
            OutputKind::RgbmUnity,
            &DynamicImage::ImageRgba8(image::rgbm_image_with(level, &hdr, rgbm_unity_encode)),
        )?);
    }
    Ok(files)
}

/// Padded linear pixels of `level` with the coverage ([`Level::coverage`])
/// as a fourth channel: 1 on floor (the floor's share of the texel below
/// one texel per pixel), 0 on padding, walls and void.
pub(crate) fn with_coverage(level: &Level, padded: &[[f32; 3]]) -> Vec<[f32; 4]> {
    padded
        .iter()
        .zip(level.coverage())
        .map(|(c, a)| [c[0], c[1], c[2], a])
        .collect()
}

/// Writes `files` of level `name` into `dir` (which must exist, see
/// [`ensure_output_dir`]), each atomically, in order; returns their paths.
/// If a file fails, the earlier ones are already new.
pub fn write_files(dir: &Path, name: &str, files: &[Encoded]) -> Result<Vec<PathBuf>, OutputError> {
    check_output_dir(dir)?;
    let mut written = Vec::with_capacity(files.len());
    for f in files {
        let path = dir.join(f.kind.file_name(name));
        write_file_atomic(&path, &f.bytes)?;
        written.push(path);
    }
    Ok(written)
}

/// Stages `files` of level `name` in `dir` (each in full in a temporary file
/// beside it, see [`StagedFile`]) without replacing anything yet: on an
/// error nothing of `dir` has changed.
pub fn stage_files(
    dir: &Path,
    name: &str,
    files: &[Encoded],
) -> Result<Vec<StagedFile>, OutputError> {
    check_output_dir(dir)?;
    files
        .iter()
        .map(|f| StagedFile::new(&dir.join(f.kind.file_name(name)), &f.bytes))
        .collect()
}

/// Puts staged files in place, in order.
pub fn commit_files(staged: Vec<StagedFile>) -> Result<Vec<PathBuf>, OutputError> {
    staged.into_iter().map(StagedFile::commit).collect()
}

/// The report file of level `name`, in the encoding flatbake writes it in
/// (pretty JSON and a final newline).
pub fn encode_report(dir: &Path, name: &str, report: &Report) -> Result<Encoded, OutputError> {
    let kind = OutputKind::Report;
    let mut bytes = serde_json::to_vec_pretty(report).map_err(|e| OutputError::Encode {
        path: dir.join(kind.file_name(name)),
        message: e.to_string(),
    })?;
    bytes.push(b'\n');
    Ok(Encoded { kind, bytes })
}

/// Writes the image outputs of one level into `dir` (which must exist, see
/// [`ensure_output_dir`]), and `NAME.report.json` after them; returns the
/// paths written, in that order (see [`write_level_files`]).
///
/// The report written is a copy of `report` with `outputs` set to the file
/// names written (report included, relative to `dir`), `timings.write` set
/// to the seconds spent encoding and writing the images, and that time
/// added to `timings.total`.
///
/// Nothing is written when the inputs are inconsistent or an image fails to
/// encode or to be written.
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
    let mut report = report.clone();
    let written = write_level_files(dir, &level.name, &files, &[], &mut report, start, || Ok(()))?;
    Ok(written.into_iter().map(|(n, _)| dir.join(n)).collect())
}

/// Writes one level's outputs into `dir` as one transaction, and returns
/// each file's name and content hash ([`content_hash`]) in the order they
/// are listed and put in place: `images`, then `NAME.report.json`, then
/// `extra` (layers, cache).
///
/// `report.outputs` is set to that list, `report.timings.write` to the
/// seconds since `start` (encoding and staging), and that time is added to
/// `report.timings.total`, before the report is encoded. Every file is
/// staged in full ([`StagedFile`]) before any is replaced, so a full disk or
/// a failed write changes nothing in `dir`; `before_commit` runs between
/// the staging and the renames (the batch removes the level's stamp there).
pub fn write_level_files(
    dir: &Path,
    name: &str,
    images: &[Encoded],
    extra: &[Encoded],
    report: &mut Report,
    start: Instant,
    before_commit: impl FnOnce() -> Result<(), OutputError>,
) -> Result<Vec<(String, String)>, OutputError> {
    report.outputs = images
        .iter()
        .map(|f| &f.kind)
        .chain([&OutputKind::Report])
        .chain(extra.iter().map(|f| &f.kind))
        .map(|k| k.file_name(name))
        .collect();
    let mut staged = stage_files(dir, name, images)?;
    staged.extend(stage_files(dir, name, extra)?);
    let seconds = start.elapsed().as_secs_f64();
    report.timings.write = seconds;
    report.timings.total += seconds;
    let json = encode_report(dir, name, report)?;
    staged.splice(
        images.len()..images.len(),
        stage_files(dir, name, std::slice::from_ref(&json))?,
    );
    before_commit()?;
    commit_files(staged)?;
    Ok(images
        .iter()
        .chain([&json])
        .chain(extra)
        .map(|f| (f.kind.file_name(name), content_hash(&f.bytes)))
        .collect())
}

/// The blake3 of an output's bytes, hex: what a stamp records of it.
pub fn content_hash(bytes: &[u8]) -> String {
    blake3::hash(bytes).to_hex().to_string()
}
