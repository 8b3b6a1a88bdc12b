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

use serde::{Deserialize, Serialize};

use crate::bake::report::Report;
use crate::bake::{Density, Responses};
use crate::level::material::{Material, MaterialKind, hex_color};
use crate::level::{Cell, Level};
use crate::output::{Depth, OutputOptions};

/// The largest cache `relight` reads: 8 GiB, far above the cache of any
/// level that bakes on a desktop machine (a 2048 x 2048 level with eight
/// light groups writes about 400 MB).
pub const MAX_CACHE_BYTES: u64 = 8 << 30;

/// First bytes of every cache file.
pub const MAGIC: &[u8; 16] = b"flatbake-cache\n\0";
/// Bumped whenever [`Cache`] changes shape.
pub const FORMAT: u32 = 5;
/// The flatbake version writing and reading caches.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// Why a cache could not be read, written or used. Every message names the
/// file and says what to do.
#[derive(Debug, thiserror::Error)]
pub enum CacheError {
    /// The file does not start with [`MAGIC`].
    #[error("{} is not a flatbake cache (write one with `flatbake bake --cache`)", .path.display())]
    NotACache {
        /// The file.
        path: PathBuf,
    },
    /// Another flatbake version or cache format wrote it.
    #[error(
        "{} was written by flatbake {version} (cache format {format}); this is flatbake {VERSION} (format {FORMAT}): bake the level again with --cache",
        .path.display()
    )]
    OtherVersion {
        /// The file.
        path: PathBuf,
        /// The version that wrote it.
        version: String,
        /// The format number it has.
        format: u32,
    },
    /// The header, checksum or content is broken.
    #[error("{} is a damaged flatbake cache ({why}): bake the level again with --cache", .path.display())]
    Damaged {
        /// The file.
        path: PathBuf,
        /// What is broken.
        why: String,
    },
    /// The file cannot be read.
    #[error("cannot read {}: {source}", .path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The cache could not be serialised.
    #[error("cannot encode the cache {}: {message}", .path.display())]
    Encode {
        /// The file it was for.
        path: PathBuf,
        /// The serialiser's message.
        message: String,
    },
    /// `--level` names another image than the one the cache was baked from.
    #[error(
        "{} was baked from another level than {} (or the level changed since): bake it again with --cache",
        .cache.display(),
        .image.display()
    )]
    OtherImage {
        /// The cache.
        cache: PathBuf,
        /// The image it was checked against.
        image: PathBuf,
    },
    /// A relight names a colour that is not an emitter of the level.
    #[error("{color} {}; level {level}'s emitters are: {}", if *.wall { "is a wall, not an emitter, in this level (relight changes emitters only; make it an emitter in the palette and bake again)" } else { "is not an emitter of this level" }, if .emitters.is_empty() { "none".to_string() } else { .emitters.join(", ") })]
    NotAnEmitter {
        /// The colour, `#rrggbb`.
        color: String,
        /// True when the colour is a wall of the level.
        wall: bool,
        /// The level's name.
        level: String,
        /// The level's emitter colours.
        emitters: Vec<String>,
    },
}

/// What a cache holds.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Cache {
    /// The level's name.
    pub level: String,
    /// Width in texels (pixels at one texel per pixel).
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// The level's size as painted, in pixels (width, height).
    pub painted: [usize; 2],
    /// Texels per painted pixel of the bake.
    pub density: Density,
    /// Per texel: 0 void, 1 floor, `2 + m` solid of material `m`.
    pub cells: Vec<u32>,
    /// Linear floor albedo per pixel.
    pub albedo: Vec<[f32; 3]>,
    /// Per texel, the fraction that is floor ([`Level::floor_fraction`]);
    /// empty when the cells say it (1 on floor, 0 elsewhere).
    pub floor_fraction: Vec<f32>,
    /// The level's materials, as resolved from its palette.
    pub materials: Vec<Material>,
    /// blake3 of the level image file's bytes, hex.
    pub image_hash: String,
    /// blake3 of image, palette and settings (the incremental-bake key), hex.
    pub inputs_hash: String,
    /// The report of the bake that wrote the cache.
    pub report: Report,
    /// Output encoding of that bake.
    pub exposure: f64,
    /// PNG outputs at 16 bits per channel.
    pub depth16: bool,
    /// The RGBM lightmap was written too.
    pub rgbm: bool,
    /// The per-emitter light the relight weights.
    pub responses: Responses,
}

impl Cache {
    /// Captures a baked level.
    /// `level` is the level at texel resolution, `grid` its painted size
    /// and the texel density.
    pub fn new(
        level: &Level,
        grid: ([usize; 2], Density),
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
            painted: grid.0,
            density: grid.1,
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
            floor_fraction: level.floor_fraction.clone().unwrap_or_default(),
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
            lossy_format: None,
            origin: Default::default(),
            floor_fraction: (!self.floor_fraction.is_empty()).then(|| self.floor_fraction.clone()),
        }
    }

    /// Serialises with header and checksum.
    pub fn to_bytes(&self) -> Result<Vec<u8>, postcard::Error> {
        let payload = postcard::to_allocvec(self)?;
        let mut out = Vec::with_capacity(payload.len() + 64);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT.to_le_bytes());
        out.extend_from_slice(&(VERSION.len() as u32).to_le_bytes());
        out.extend_from_slice(VERSION.as_bytes());
        out.extend_from_slice(blake3::hash(&payload).as_bytes());
        out.extend_from_slice(&payload);
        Ok(out)
    }

    /// Reads a cache; `path` is how the file is called in messages.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Cache, CacheError> {
        let Some(rest) = bytes.strip_prefix(MAGIC.as_slice()) else {
            return Err(CacheError::NotACache {
                path: path.to_path_buf(),
            });
        };
        let damaged = |why: &str| CacheError::Damaged {
            path: path.to_path_buf(),
            why: why.to_string(),
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
            return Err(CacheError::OtherVersion {
                path: path.to_path_buf(),
                version: version.to_string(),
                format,
            });
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
        // The outputs are named after the level: a name with a path in it
        // would write them outside the output folder.
        if cache.level.contains(['/', '\\', '\0']) {
            return Err(damaged("the level name is not a file name"));
        }
        // Cross-checks, so that a well-formed but inconsistent file cannot
        // index out of bounds later.
        let Some(n) = cache.width.checked_mul(cache.height) else {
            return Err(damaged("inconsistent sizes"));
        };
        if n == 0 {
            return Err(damaged("the level has no pixels"));
        }
        let r = &cache.responses;
        let [pw, ph] = cache.painted;
        if cache.cells.len() != n
            || cache.density.texels(pw, ph) != (cache.width, cache.height)
            || cache.report.size != [cache.width, cache.height]
            || cache.albedo.len() != n
            || !(cache.floor_fraction.is_empty() || cache.floor_fraction.len() == n)
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
    ///
    /// Only a regular file of at most [`MAX_CACHE_BYTES`] is read: a device
    /// such as `/dev/zero`, or a file that grows while it is read, is
    /// refused instead of filling memory.
    pub fn read(path: &Path) -> Result<Cache, CacheError> {
        use std::io::Read;
        let read_err = |source| CacheError::Read {
            path: path.to_path_buf(),
            source,
        };
        let meta = std::fs::metadata(path).map_err(read_err)?;
        if !meta.is_file() {
            return Err(CacheError::NotACache {
                path: path.to_path_buf(),
            });
        }
        let too_large = || CacheError::Damaged {
            path: path.to_path_buf(),
            why: format!("larger than the {MAX_CACHE_BYTES}-byte limit of a cache"),
        };
        if meta.len() > MAX_CACHE_BYTES {
            return Err(too_large());
        }
        let mut bytes = Vec::with_capacity(meta.len() as usize);
        std::fs::File::open(path)
            .and_then(|f| f.take(MAX_CACHE_BYTES + 1).read_to_end(&mut bytes))
            .map_err(read_err)?;
        if bytes.len() as u64 > MAX_CACHE_BYTES {
            return Err(too_large());
        }
        Cache::from_bytes(&bytes, path)
    }

    /// The emission per emitter (in [`Responses::emitters`] order): the
    /// palette's, with `overrides` (colour, emission) applied. A colour that is
    /// not an emitter of this level is refused with a message naming it.
    pub fn emission(&self, overrides: &[([u8; 3], [f64; 3])]) -> Result<Vec<[f64; 3]>, CacheError> {
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
                    return Err(CacheError::NotAnEmitter {
                        color: hex_color(*color),
                        wall: self
                            .materials
                            .iter()
                            .any(|m| m.color == *color && m.kind == MaterialKind::Wall),
                        level: self.level.clone(),
                        emitters: r
                            .emitters
                            .iter()
                            .map(|&m| self.materials[m].hex())
                            .collect(),
                    });
                }
            }
        }
        Ok(e)
    }
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
            painted: [2, 1],
            density: Density::Up(1),
            cells: vec![1, 3],
            albedo: vec![[0.5; 3]; 2],
            floor_fraction: Vec::new(),
            materials: vec![wall, lamp],
            image_hash: String::new(),
            inputs_hash: String::new(),
            report: Report {
                size: [2, 1],
                ..Report::default()
            },
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
                moments: Vec::new(),
            },
        }
    }

    #[test]
    fn a_cache_reads_back_and_relights_linearly() {
        let bytes = tiny().to_bytes().expect("encodes");
        let c = Cache::from_bytes(&bytes, Path::new("t")).expect("reads");
        let e = c
            .emission(&[([255, 255, 255], [4.0, 0.0, 1.0])])
            .expect("emitter");
        assert_eq!(
            c.responses.combine(&e),
            vec![[1.0, 0.0, 0.25], [4.0, 0.0, 1.0]]
        );
        let err = c.emission(&[([1, 2, 3], [1.0; 3])]).expect_err("a wall");
        assert!(err.to_string().contains("#010203 is a wall"), "{err}");
    }

    #[test]
    fn inconsistent_sizes_are_damaged_not_a_panic() {
        for broken in [
            |c: &mut Cache| c.cells.push(1),
            |c: &mut Cache| c.responses.images[0].truncate(1),
            |c: &mut Cache| c.responses.rho_classes = 0,
            |c: &mut Cache| c.responses.emitters[0] = 7,
            |c: &mut Cache| c.cells[1] = 9,
            |c: &mut Cache| c.report.size = [1, 2],
        ] {
            let mut c = tiny();
            broken(&mut c);
            let err = Cache::from_bytes(&c.to_bytes().expect("encodes"), Path::new("t"))
                .expect_err("refused");
            assert!(err.to_string().contains("damaged"), "{err}");
        }
    }
}
