//! The relight cache (`bake --cache` writes `NAME.flatbake`; `flatbake
//! relight` reads it): everything about a level that does not depend on
//! emission, so that new emission gives new lightmaps without tracing
//! geometry, computing form factors, solving or gathering again.
//!
//! Light is linear in emission. The bake already traces every emitter
//! material on its own ([`Responses`]: solve and gather per emitter and
//! reflectance class, with visibility shared in one gather pass), so the
//! cache keeps those responses, and relighting is a weighted sum of images.
//! Reflectance cannot change in a relight: it is baked into the responses.
//!
//! File layout: the 16-byte [`MAGIC`], the format number (u32 LE), the
//! flatbake version (u32 LE length + UTF-8), the blake3 hash of the payload
//! (32 bytes), then the payload ([`Cache`], postcard). A file that is not a
//! cache, a cache of another format or flatbake version, and a damaged cache
//! are each refused with their own message.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::bake::Lightmap;
use crate::bake::Responses;
use crate::bake::report::{Energy, Report, Skip, Timings};
use crate::level::material::{Material, MaterialKind, hex_color};
use crate::level::{Cell, Level};
use crate::output::{self, Depth, OutputOptions};

/// First bytes of every cache file.
pub const MAGIC: &[u8; 16] = b"flatbake-cache\n\0";
/// Bumped whenever [`Cache`] changes shape.
pub const FORMAT: u32 = 1;
/// The flatbake version writing and reading caches.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// What a cache holds.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Cache {
    pub level: String,
    pub width: usize,
    pub height: usize,
    /// Per pixel: 0 void, 1 floor, `2 + m` solid of material `m`.
    pub cells: Vec<u32>,
    pub albedo: Vec<[f32; 3]>,
    pub materials: Vec<Material>,
    /// blake3 of the level image file's bytes, hex.
    pub image_hash: String,
    /// blake3 of image, palette and settings (the incremental-bake key), hex.
    pub inputs_hash: String,
    /// The report of the bake that wrote the cache.
    pub report: Report,
    /// Output encoding of that bake.
    pub exposure: f64,
    pub depth16: bool,
    pub rgbm: bool,
    pub responses: Responses,
}

impl Cache {
    /// Captures a baked level.
    pub fn new(
        level: &Level,
        responses: Responses,
        report: &Report,
        image_hash: String,
        inputs_hash: String,
        opts: &OutputOptions,
    ) -> Cache {
        Cache {
            level: level.name.clone(),
            width: level.width,
            height: level.height,
            cells: level
                .cells
                .iter()
                .map(|c| match c {
                    Cell::Void => 0,
                    Cell::Floor => 1,
                    Cell::Solid(m) => 2 + u32::from(*m),
                })
                .collect(),
            albedo: level.albedo.clone(),
            materials: level.materials.clone(),
            image_hash,
            inputs_hash,
            report: report.clone(),
            exposure: opts.exposure,
            depth16: opts.depth == Depth::Sixteen,
            rgbm: opts.rgbm,
            responses,
        }
    }

    /// The resolved level again (no image decoding, no palette).
    pub fn level(&self) -> Level {
        let cells = self
            .cells
            .iter()
            .map(|&c| match c {
                0 => Cell::Void,
                1 => Cell::Floor,
                m => Cell::Solid((m - 2) as u16),
            })
            .collect();
        Level {
            name: self.level.clone(),
            width: self.width,
            height: self.height,
            cells,
            albedo: self.albedo.clone(),
            materials: self.materials.clone(),
            warnings: Vec::new(),
        }
    }

    /// Serialises with header and checksum.
    pub fn to_bytes(&self) -> Result<Vec<u8>, String> {
        let payload = postcard::to_allocvec(self).map_err(|e| e.to_string())?;
        let mut out = Vec::with_capacity(payload.len() + 64);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT.to_le_bytes());
        out.extend_from_slice(&(VERSION.len() as u32).to_le_bytes());
        out.extend_from_slice(VERSION.as_bytes());
        out.extend_from_slice(blake3::hash(&payload).as_bytes());
        out.extend_from_slice(&payload);
        Ok(out)
    }

    /// Reads a cache; `name` is how the file is called in messages.
    pub fn from_bytes(bytes: &[u8], name: &str) -> Result<Cache, String> {
        let Some(rest) = bytes.strip_prefix(MAGIC.as_slice()) else {
            return Err(format!(
                "{name} is not a flatbake cache (write one with `flatbake bake --cache`)"
            ));
        };
        let damaged = |why: &str| {
            format!("{name} is a damaged flatbake cache ({why}): bake the level again with --cache")
        };
        let u32_at = |b: &[u8], i: usize| -> Option<u32> {
            Some(u32::from_le_bytes(b.get(i..i + 4)?.try_into().ok()?))
        };
        let format = u32_at(rest, 0).ok_or_else(|| damaged("truncated header"))?;
        let vlen = u32_at(rest, 4).ok_or_else(|| damaged("truncated header"))? as usize;
        let version = rest
            .get(8..8 + vlen.min(64))
            .filter(|_| vlen <= 64)
            .and_then(|v| std::str::from_utf8(v).ok())
            .ok_or_else(|| damaged("unreadable version"))?;
        if format != FORMAT || version != VERSION {
            return Err(format!(
                "{name} was written by flatbake {version} (cache format {format}); this is flatbake {VERSION} (format {FORMAT}): bake the level again with --cache"
            ));
        }
        let rest = &rest[8 + vlen..];
        let (hash, payload) = (
            rest.get(..32).ok_or_else(|| damaged("truncated header"))?,
            &rest[32.min(rest.len())..],
        );
        if blake3::hash(payload).as_bytes() != hash {
            return Err(damaged("checksum mismatch"));
        }
        let cache: Cache = postcard::from_bytes(payload).map_err(|e| damaged(&e.to_string()))?;
        // Cross-checks, so that a well-formed but inconsistent file cannot
        // index out of bounds later.
        let n = cache.width * cache.height;
        let r = &cache.responses;
        if cache.cells.len() != n
            || cache.albedo.len() != n
            || r.width != cache.width
            || r.height != cache.height
            || r.images.len() != r.emitters.len() * r.rho_classes
            || r.images.iter().any(|i| i.len() != n)
            || r.rho_classes == 0
            || r.rho_class_of.iter().any(|&k| k >= r.rho_classes)
            || r.emitters.iter().any(|&m| m >= cache.materials.len())
            || cache
                .cells
                .iter()
                .any(|&c| c >= 2 && (c - 2) as usize >= cache.materials.len())
        {
            return Err(damaged("inconsistent sizes"));
        }
        Ok(cache)
    }

    /// Reads a cache file.
    pub fn read(path: &Path) -> Result<Cache, String> {
        let bytes =
            std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        Cache::from_bytes(&bytes, &path.display().to_string())
    }

    /// The emission per emitter (in [`Responses::emitters`] order): the
    /// palette's, with `overrides` (colour, emission) applied. A colour that is
    /// not an emitter of this level is refused with a message naming it.
    pub fn emission(&self, overrides: &[([u8; 3], [f64; 3])]) -> Result<Vec<[f64; 3]>, String> {
        let r = &self.responses;
        let mut e: Vec<[f64; 3]> = r
            .emitters
            .iter()
            .map(|&m| self.materials[m].emission)
            .collect();
        for (color, value) in overrides {
            match r
                .emitters
                .iter()
                .position(|&m| self.materials[m].color == *color)
            {
                Some(i) => e[i] = *value,
                None => {
                    let known: Vec<String> = r
                        .emitters
                        .iter()
                        .map(|&m| self.materials[m].hex())
                        .collect();
                    let what = match self.materials.iter().find(|m| m.color == *color) {
                        Some(m) if m.kind == MaterialKind::Wall => {
                            "is a wall, not an emitter, in this level (relight changes emitters only; make it an emitter in the palette and bake again)"
                        }
                        _ => "is not an emitter of this level",
                    };
                    return Err(format!(
                        "{} {what}; level {}'s emitters are: {}",
                        hex_color(*color),
                        self.level,
                        if known.is_empty() {
                            "none".to_string()
                        } else {
                            known.join(", ")
                        }
                    ));
                }
            }
        }
        Ok(e)
    }
}

/// Parses `--emission "#rrggbb=R,G,B"` (or `=X` for grey).
pub fn parse_emission(s: &str) -> Result<([u8; 3], [f64; 3]), String> {
    let (c, v) = s.split_once('=').ok_or_else(|| {
        format!("--emission takes COLOR=R,G,B (like \"#fffadc=10,9,7\"), not {s:?}")
    })?;
    let color = crate::level::palette::parse_hex(c.trim())
        .ok_or_else(|| format!("--emission: {c:?} is not a colour like #fffadc"))?;
    let nums: Vec<f64> = v
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("--emission: {v:?} is not a number or R,G,B"))?;
    let e = match nums.as_slice() {
        [x] => [*x; 3],
        [r, g, b] => [*r, *g, *b],
        _ => return Err(format!("--emission: {v:?} needs 1 or 3 numbers")),
    };
    if e.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return Err(format!(
            "--emission: emission must be finite and >= 0, not {v:?}"
        ));
    }
    Ok((color, e))
}

/// What `relight` should write.
#[derive(Clone, Debug, Default)]
pub struct RelightOptions {
    pub out_dir: PathBuf,
    /// New emission per colour; other emitters keep the palette's.
    pub emission: Vec<([u8; 3], [f64; 3])>,
    /// Refuse the cache unless it was baked from this image file.
    pub level_image: Option<PathBuf>,
    /// Also write the light layers with the new emission.
    pub layers: bool,
    /// Also write the EXR lightmap.
    pub hdr: bool,
}

/// Relights a cache; returns the report written (`NAME.report.json`).
pub fn relight(cache_path: &Path, opts: &RelightOptions) -> Result<Report, String> {
    let t0 = Instant::now();
    let cache = Cache::read(cache_path)?;
    if let Some(img) = &opts.level_image {
        let bytes =
            std::fs::read(img).map_err(|e| format!("cannot read {}: {e}", img.display()))?;
        if blake3::hash(&bytes).to_hex().as_str() != cache.image_hash {
            return Err(format!(
                "{} was baked from another image than {} (or the image changed since): bake it again with --cache",
                cache_path.display(),
                img.display()
            ));
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

    let mut report = cache.report.clone();
    report.timings = Timings {
        load,
        gather,
        total: t0.elapsed().as_secs_f64(),
        ..Timings::default()
    };
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
    let out_opts = OutputOptions {
        exposure: cache.exposure,
        depth: if cache.depth16 {
            Depth::Sixteen
        } else {
            Depth::Eight
        },
        hdr: opts.hdr || opts.layers,
        rgbm: cache.rgbm,
    };
    output::ensure_output_dir(&opts.out_dir).map_err(|e| e.to_string())?;
    let mut written = output::write_level_outputs(&opts.out_dir, &level, &map, &report, &out_opts)
        .map_err(|e| e.to_string())?;
    if opts.layers {
        written.extend(
            crate::output::layers::write_layers(
                &opts.out_dir,
                &level,
                &cache.responses,
                &emission,
                &out_opts,
            )
            .map_err(|e| e.to_string())?,
        );
    }
    report.outputs = written
        .iter()
        .filter_map(|p| p.file_name())
        .map(|n| n.to_string_lossy().into_owned())
        .collect();
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> Cache {
        let wall = Material {
            color: [1, 2, 3],
            kind: MaterialKind::Wall,
            reflectance: [0.5; 3],
            emission: [0.0; 3],
            group: None,
            line: None,
        };
        let lamp = Material {
            color: [255, 255, 255],
            kind: MaterialKind::Emitter,
            reflectance: [0.0; 3],
            emission: [2.0; 3],
            group: None,
            line: None,
        };
        Cache {
            level: "tiny".into(),
            width: 2,
            height: 1,
            cells: vec![1, 3],
            albedo: vec![[0.5; 3]; 2],
            materials: vec![wall, lamp],
            image_hash: String::new(),
            inputs_hash: String::new(),
            report: Report::default(),
            exposure: 1.0,
            depth16: false,
            rgbm: false,
            responses: Responses {
                width: 2,
                height: 1,
                emitters: vec![1],
                rho_class_of: [0; 3],
                rho_classes: 1,
                images: vec![vec![0.25, 1.0]],
                traced_emission: 1.0,
            },
        }
    }

    #[test]
    fn a_cache_reads_back_and_relights_linearly() {
        let bytes = tiny().to_bytes().expect("encodes");
        let c = Cache::from_bytes(&bytes, "t").expect("reads");
        let e = c
            .emission(&[([255, 255, 255], [4.0, 0.0, 1.0])])
            .expect("emitter");
        assert_eq!(
            c.responses.combine(&e),
            vec![[1.0, 0.0, 0.25], [4.0, 0.0, 1.0]]
        );
        let err = c.emission(&[([1, 2, 3], [1.0; 3])]).expect_err("a wall");
        assert!(err.contains("#010203 is a wall"), "{err}");
    }

    #[test]
    fn inconsistent_sizes_are_damaged_not_a_panic() {
        for broken in [
            |c: &mut Cache| c.cells.push(1),
            |c: &mut Cache| c.responses.images[0].truncate(1),
            |c: &mut Cache| c.responses.rho_classes = 0,
            |c: &mut Cache| c.responses.emitters[0] = 7,
            |c: &mut Cache| c.cells[1] = 9,
        ] {
            let mut c = tiny();
            broken(&mut c);
            let err = Cache::from_bytes(&c.to_bytes().expect("encodes"), "t").expect_err("refused");
            assert!(err.contains("damaged"), "{err}");
        }
    }

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
        ] {
            assert!(parse_emission(bad).is_err(), "{bad}");
        }
    }
}
