//! Incremental bakes: `NAME.stamp.json` in the output folder records a
//! content hash of what a level's outputs were made from (image bytes,
//! palette bytes, settings, flatbake version) and which files were written.
//! A level whose hash is unchanged and whose outputs all still exist is up to
//! date and is not baked again. Hashes, not timestamps: touching a file or
//! checking it out again does not trigger a bake, and an edit that keeps the
//! same timestamp is never missed.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::batch::BatchOptions;
use crate::level::palette::Palette;

/// What one level's outputs were made from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Inputs {
    /// blake3 of the image file's bytes, hex.
    pub image_hash: String,
    /// blake3 of image, palette, settings and version, hex.
    pub key: String,
}

/// The stamp file's content.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Stamp {
    pub flatbake: String,
    pub inputs: String,
    /// Files written, relative to the output folder.
    pub outputs: Vec<String>,
}

/// The stamp file of level image `path` in `out_dir`.
pub fn stamp_path(path: &Path, out_dir: &Path) -> PathBuf {
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    out_dir.join(format!("{name}.stamp.json"))
}

/// Hashes what the outputs of level `path` depend on.
pub fn inputs(path: &Path, opts: &BatchOptions) -> Result<Inputs, String> {
    let image = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let image_hash = blake3::hash(&image).to_hex().to_string();
    let mut h = blake3::Hasher::new();
    h.update(b"flatbake ");
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(b"\0image\0");
    h.update(image_hash.as_bytes());
    // The palette that the lookup picks: which file, and its bytes.
    let palette_file = match &opts.palette {
        Some(p) => Some(p.clone()),
        None => Palette::candidate_paths(path)
            .into_iter()
            .find(|c| c.is_file()),
    };
    match palette_file {
        Some(p) => {
            let bytes =
                std::fs::read(&p).map_err(|e| format!("cannot read {}: {e}", p.display()))?;
            h.update(b"\0palette\0");
            h.update(p.to_string_lossy().as_bytes());
            h.update(b"\0");
            h.update(&bytes);
        }
        None => {
            h.update(b"\0palette\0built-in");
        }
    }
    // Every option that changes an output (not the output folder, not
    // --force, not the thread count).
    let settings = format!(
        "{:?}",
        (
            opts.quality,
            opts.falloff,
            opts.kernel,
            opts.gather,
            opts.bounces,
            opts.exposure,
            opts.hdr,
            opts.depth,
            opts.rgbm,
            opts.layers,
            opts.cache,
            opts.limits.max_pixels,
        )
    );
    h.update(b"\0settings\0");
    h.update(settings.as_bytes());
    // The preset's knobs too: a build that changes a preset re-bakes.
    h.update(format!("{:?}", opts.quality.knobs()).as_bytes());
    Ok(Inputs {
        image_hash,
        key: h.finalize().to_hex().to_string(),
    })
}

/// True when level `path`'s outputs in `opts.out_dir` were made from the
/// same inputs and all still exist. Any doubt (no stamp, unreadable stamp,
/// unreadable input) means "not up to date".
pub fn up_to_date(path: &Path, opts: &BatchOptions) -> bool {
    let Ok(text) = std::fs::read(stamp_path(path, &opts.out_dir)) else {
        return false;
    };
    let Ok(stamp) = serde_json::from_slice::<Stamp>(&text) else {
        return false;
    };
    let Ok(now) = inputs(path, opts) else {
        return false;
    };
    stamp.flatbake == env!("CARGO_PKG_VERSION")
        && stamp.inputs == now.key
        && !stamp.outputs.is_empty()
        && stamp.outputs.iter().all(|o| opts.out_dir.join(o).is_file())
}

/// Records that level `path`'s `outputs` were made from `inputs`; written
/// last, after every output, so that an interrupted bake is never stamped.
pub fn write(
    path: &Path,
    opts: &BatchOptions,
    inputs: &Inputs,
    outputs: &[String],
) -> Result<(), String> {
    let stamp = Stamp {
        flatbake: env!("CARGO_PKG_VERSION").into(),
        inputs: inputs.key.clone(),
        outputs: outputs.to_vec(),
    };
    let mut json = serde_json::to_vec_pretty(&stamp).map_err(|e| e.to_string())?;
    json.push(b'\n');
    crate::output::write_file_atomic(&stamp_path(path, &opts.out_dir), &json)
        .map_err(|e| e.to_string())
}
