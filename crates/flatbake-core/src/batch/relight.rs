//! Relighting (`flatbake relight`): new lightmaps for new emission from a
//! bake's cache ([`crate::output::cache`]), a weighted sum of the cached
//! per-emitter light, without tracing, solving or gathering again.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::bake::Lightmap;
use crate::bake::report::{Energy, Report, Skip, Timings};
use crate::error::{Error, Result};
use crate::output::cache::{Cache, CacheError};
use crate::output::names::OutputKind;
use crate::output::{self, Depth, ExrCompression, OutputOptions};

/// Why an `--emission` argument was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EmissionError {
    /// No `=`.
    #[error("--emission takes COLOR=R,G,B (like \"#fffadc=10,9,7\"), not {0:?}")]
    Form(String),
    /// The colour is not `#rrggbb` or `#rgb`.
    #[error("--emission: {0:?} is not a colour like #fffadc")]
    Color(String),
    /// A value is not a number.
    #[error("--emission: {0:?} is not a number or R,G,B")]
    Number(String),
    /// Neither 1 nor 3 numbers.
    #[error("--emission: {0:?} needs 1 or 3 numbers")]
    Count(String),
    /// Negative, infinite or NaN.
    #[error("--emission: emission must be finite and >= 0, not {0:?}")]
    Range(String),
    /// Larger than a palette may give.
    #[error(
        "--emission: {0:?} is too large: at most {max:e}, as in a palette (light beyond the 32-bit float range of the outputs cannot be stored)",
        max = crate::level::palette::MAX_EMISSION
    )]
    TooLarge(String),
}

/// Parses `--emission "#rrggbb=R,G,B"` (or `=X` for grey).
pub fn parse_emission(s: &str) -> Result<([u8; 3], [f64; 3]), EmissionError> {
    let (c, v) = s
        .split_once('=')
        .ok_or_else(|| EmissionError::Form(s.to_string()))?;
    let color = crate::level::palette::parse_hex(c.trim())
        .ok_or_else(|| EmissionError::Color(c.to_string()))?;
    let nums: Vec<f64> = v
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| EmissionError::Number(v.to_string()))?;
    let e = match nums.as_slice() {
        [x] => [*x; 3],
        [r, g, b] => [*r, *g, *b],
        _ => return Err(EmissionError::Count(v.to_string())),
    };
    if e.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return Err(EmissionError::Range(v.to_string()));
    }
    if e.iter().any(|&x| x > crate::level::palette::MAX_EMISSION) {
        return Err(EmissionError::TooLarge(v.to_string()));
    }
    Ok((color, e))
}

/// What `relight` should write.
#[derive(Clone, Debug, Default)]
pub struct RelightOptions {
    /// Output folder (created if missing).
    pub out_dir: PathBuf,
    /// New emission per colour; other emitters keep the palette's.
    pub emission: Vec<([u8; 3], [f64; 3])>,
    /// Refuse the cache unless it was baked from this image file.
    pub level_image: Option<PathBuf>,
    /// Also write the light layers with the new emission.
    pub layers: bool,
    /// Also write the EXR lightmap.
    pub hdr: bool,
    /// Padding of the lightmap outputs in texels ([`output::padding`]); 0
    /// pads nothing. Not in the cache: a relight chooses its own.
    pub padding: u32,
    /// Also write the Unity-convention RGBM lightmap (not in the cache
    /// either).
    pub rgbm_unity: bool,
    /// Also write the RGBA 16-bit float KTX2 lightmap.
    pub ktx2: bool,
    /// Compression of the EXR outputs (lightmap and layers).
    pub exr_compression: ExrCompression,
}

/// Relights a cache; returns the report written (`NAME.report.json`).
pub fn relight(cache_path: &Path, opts: &RelightOptions) -> Result<Report> {
    let t0 = Instant::now();
    let cache = Cache::read(cache_path)?;
    if let Some(img) = &opts.level_image {
        let bytes = super::stamp::level_source(img)?;
        if blake3::hash(&bytes).to_hex().as_str() != cache.image_hash {
            return Err(CacheError::OtherImage {
                cache: cache_path.to_path_buf(),
                image: img.clone(),
            }
            .into());
        }
    }
    let emission = cache.emission(&opts.emission)?;
    let level = cache.level();
    let load = t0.elapsed().as_secs_f64();
    let t = Instant::now();
    let map = Lightmap {
        width: level.width,
        height: level.height,
        rgb: cache.responses.combine(&emission),
    };
    let gather = t.elapsed().as_secs_f64();

    let mut report = relit_report(&cache, cache_path);
    report.timings = Timings {
        load,
        gather,
        total: t0.elapsed().as_secs_f64(),
        ..Timings::default()
    };
    let out_opts = OutputOptions {
        exposure: cache.exposure,
        depth: if cache.depth16 {
            Depth::Sixteen
        } else {
            Depth::Eight
        },
        hdr: opts.hdr || opts.layers,
        rgbm: cache.rgbm,
        rgbm_unity: opts.rgbm_unity,
        padding: opts.padding,
        ktx2: opts.ktx2,
        exr_compression: opts.exr_compression,
    };
    // Everything is encoded before anything is written, so that the report
    // on disk lists every file of the relight, layers included.
    let write = Instant::now();
    // A bake's folder is the bake's: a relit lightmap there would sit
    // beside the bake's stamp, and the next bake would call it up to date.
    if opts
        .out_dir
        .join(OutputKind::Stamp.file_name(&level.name))
        .exists()
    {
        return Err(Error::RelightOverBake {
            dir: opts.out_dir.clone(),
            name: level.name.clone(),
        });
    }
    let _lock = super::FolderLock::acquire(&opts.out_dir, || {});
    output::ensure_output_dir(&opts.out_dir)?;
    let images = output::encode_images(&level, &map, &out_opts)?;
    let mut layers = if opts.layers {
        output::layers::encode_layers(&level, &cache.responses, &emission, &out_opts)?
    } else {
        Vec::new()
    };
    // A cache of a directional bake holds the moments: relit the same way.
    if let Some(d) = cache.responses.combine_moments(&emission) {
        let normals = match opts
            .level_image
            .as_deref()
            .and_then(output::directional::normal_map_beside)
        {
            Some(p) => Some(output::directional::NormalMap::read(
                &p,
                cache.painted,
                cache.density,
            )?),
            None => None,
        };
        layers.extend(output::directional::encode_directional(
            &level,
            &map,
            &d,
            normals.as_ref(),
            &out_opts,
        )?);
    }
    output::write_level_files(
        &opts.out_dir,
        &level.name,
        &images,
        &layers,
        &mut report,
        write,
        || Ok(()),
    )?;
    Ok(report)
}

/// The bake's report, saying that this is a relight and what it left out.
fn relit_report(cache: &Cache, cache_path: &Path) -> Report {
    let mut report = cache.report.clone();
    report.solves = 0;
    report.residual = 0.0;
    report.solver = "relight".into();
    report.energy = Energy::default();
    report.skipped = vec![Skip {
        effect: "geometry, form factors, solve, gather".into(),
        reason: format!(
            "relit from {}: a weighted sum of the cached per-emitter light",
            cache_path
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
        ),
    }];
    report
        .warnings
        .push("relit: the energy balance is not recomputed (all 0); bake for it".into());
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn emission_arguments_parse_or_say_why_not() {
        assert_eq!(
            parse_emission("#fffadc=10,9,7"),
            Ok(([255, 250, 220], [10.0, 9.0, 7.0]))
        );
        assert_eq!(parse_emission("#000001=2"), Ok(([0, 0, 1], [2.0; 3])));
        for bad in [
            "#fffadc",
            "fffadc=1",
            "#fffadc=1,2",
            "#fffadc=-1",
            "#fffadc=x",
            "#fffadc=1e300",
            "#fffadc=1,1,2e15",
        ] {
            assert!(parse_emission(bad).is_err(), "{bad}");
        }
    }
}
