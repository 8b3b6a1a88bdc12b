//! Incremental bakes: `NAME.stamp.json` in the output folder records a
//! content hash of what a level's outputs were made from (image bytes,
//! palette bytes, settings, flatbake version) and which files were written.
//! and the blake3 of every one of them. A level whose input hash is
//! unchanged and whose outputs all still hold exactly the bytes the bake
//! wrote is up to date and is not baked again; anything else that wrote into
//! the folder (a person, a relight, another process, a bake that failed
//! half-way) means a re-bake. The stamp is removed before a bake replaces
//! any output and written last, so a bake that fails leaves no stamp. Hashes, not timestamps: touching a file or
//! checking it out again does not trigger a bake, and an edit that keeps the
//! same timestamp is never missed.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::level::palette::Palette;
use crate::output::{OutputError, OutputKind, names};

/// What decides a level's outputs: its image, its palette, and every setting
/// that changes an output byte.
#[derive(Clone, Copy, Debug)]
pub struct Recipe<'a> {
    /// The level image.
    pub image: &'a Path,
    /// The palette given for every level; `None` means the lookup beside
    /// the image ([`Palette::candidate_paths`]).
    pub palette: Option<&'a Path>,
    /// Every setting that changes an output, spelled out (not the output
    /// folder, not `--force`, not the thread count).
    pub settings: &'a str,
}

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
    /// The flatbake version that baked the outputs.
    pub flatbake: String,
    /// [`Inputs::key`] of what they were made from.
    pub inputs: String,
    /// Files written, relative to the output folder.
    pub outputs: Vec<String>,
    /// blake3 of each of `outputs`' bytes, hex, in the same order.
    pub hashes: Vec<String>,
}

/// The bytes of a level's own source whose hash is its `image_hash`: the
/// image or map file, or for a level of an LDtk project what the project
/// says about that level (not the whole project file: editing one level
/// re-bakes only that one).
pub fn level_source(path: &Path) -> Result<Vec<u8>> {
    match crate::level::ldtk::project_level(path) {
        Some(_) => Ok(crate::level::ldtk::level_inputs(path)?),
        None => std::fs::read(path).map_err(|source| Error::Read {
            path: path.to_path_buf(),
            source,
        }),
    }
}

/// Hashes what the outputs of `recipe`'s level depend on.
pub fn inputs(recipe: &Recipe) -> Result<Inputs> {
    let read = |path: &Path| {
        std::fs::read(path).map_err(|source| Error::Read {
            path: path.to_path_buf(),
            source,
        })
    };
    let image = level_source(recipe.image)?;
    let image_hash = blake3::hash(&image).to_hex().to_string();
    let mut h = blake3::Hasher::new();
    h.update(b"flatbake ");
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(b"\0image\0");
    h.update(image_hash.as_bytes());
    // A Tiled map's external tilesets hold its tiles' properties.
    if crate::level::tiled_map::is_tiled_map(recipe.image) {
        for tsx in crate::level::tiled_map::tiled_dependencies(recipe.image) {
            h.update(b"\0tileset\0");
            h.update(tsx.to_string_lossy().as_bytes());
            h.update(b"\0");
            h.update(&read(&tsx)?);
        }
    }
    // A directional bake's lit preview reads the normal map beside the
    // level, when there is one (hashed only then: other stamps stay as
    // they were).
    if recipe.settings.contains(" directional")
        && let Some(normals) = crate::output::directional::normal_map_beside(recipe.image)
    {
        h.update(b"\0normals\0");
        h.update(&read(&normals)?);
    }
    // The palette that the lookup picks: which file, and its bytes.
    let palette_file = match recipe.palette {
        Some(p) => Some(p.to_path_buf()),
        None => Palette::candidate_paths(recipe.image)
            .into_iter()
            .find(|c| c.is_file()),
    };
    match palette_file {
        Some(p) => {
            let bytes = read(&p)?;
            h.update(b"\0palette\0");
            h.update(p.to_string_lossy().as_bytes());
            h.update(b"\0");
            h.update(&bytes);
        }
        None => {
            h.update(b"\0palette\0built-in");
        }
    }
    hash_builtin(&mut h, &Palette::builtin());
    h.update(b"\0settings\0");
    h.update(recipe.settings.as_bytes());
    Ok(Inputs {
        image_hash,
        key: h.finalize().to_hex().to_string(),
    })
}

/// A palette file's entries are added to the built-in palette, so the
/// palette a level gets depends on the built-in entries too: hash them (as
/// their TOML spelling, which holds every number exactly), with the rule
/// that combines them, so a change to either means a re-bake even when the
/// file's bytes are the same.
fn hash_builtin(h: &mut blake3::Hasher, builtin: &Palette) {
    h.update(b"\0a palette file extends\0");
    h.update(builtin.to_toml().as_bytes());
}

/// The stamp file of `recipe`'s level in `out_dir`.
fn stamp_path(recipe: &Recipe, out_dir: &Path) -> std::path::PathBuf {
    out_dir.join(OutputKind::Stamp.file_name(&names::level_name(recipe.image)))
}

/// The stamp of level image `image` in `out_dir`, if there is a readable one.
pub fn read(image: &Path, out_dir: &Path) -> Option<Stamp> {
    let path = out_dir.join(OutputKind::Stamp.file_name(&names::level_name(image)));
    let text = std::fs::read(path).ok()?;
    serde_json::from_slice(&text).ok()
}

/// True when the outputs of `recipe`'s level in `out_dir` were made from the
/// same inputs and all still hold the bytes the bake wrote. Any doubt (no
/// stamp, unreadable stamp, unreadable input or output) means "not up to
/// date".
pub fn up_to_date(recipe: &Recipe, out_dir: &Path) -> bool {
    let Ok(text) = std::fs::read(stamp_path(recipe, out_dir)) else {
        return false;
    };
    let Ok(stamp) = serde_json::from_slice::<Stamp>(&text) else {
        return false;
    };
    let Ok(now) = inputs(recipe) else {
        return false;
    };
    stamp.flatbake == env!("CARGO_PKG_VERSION")
        && stamp.inputs == now.key
        && !stamp.outputs.is_empty()
        && stamp.outputs.len() == stamp.hashes.len()
        && stamp.outputs.iter().zip(&stamp.hashes).all(|(o, h)| {
            std::fs::read(out_dir.join(o))
                .is_ok_and(|bytes| crate::output::content_hash(&bytes) == *h)
        })
}

/// Removes the stamp of `recipe`'s level from `out_dir`, if there is one:
/// done before a bake replaces any output, so that from then on, until the
/// new stamp is written last, the level is not up to date whatever happens.
pub fn invalidate(recipe: &Recipe, out_dir: &Path) -> Result<(), OutputError> {
    crate::output::remove_output(&stamp_path(recipe, out_dir))
}

/// Records that the `outputs` (file name and content hash) of `recipe`'s
/// level were made from `inputs`; written last, after every output, so that
/// an interrupted bake is never stamped.
pub fn write(
    recipe: &Recipe,
    out_dir: &Path,
    inputs: &Inputs,
    outputs: &[(String, String)],
) -> Result<(), OutputError> {
    let stamp = Stamp {
        flatbake: env!("CARGO_PKG_VERSION").into(),
        inputs: inputs.key.clone(),
        outputs: outputs.iter().map(|(name, _)| name.clone()).collect(),
        hashes: outputs.iter().map(|(_, hash)| hash.clone()).collect(),
    };
    let path = stamp_path(recipe, out_dir);
    let mut json = serde_json::to_vec_pretty(&stamp).map_err(|e| OutputError::Encode {
        path: path.clone(),
        message: e.to_string(),
    })?;
    json.push(b'\n');
    crate::output::write_file_atomic(&path, &json)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(builtin: &Palette) -> String {
        let mut h = blake3::Hasher::new();
        hash_builtin(&mut h, builtin);
        h.finalize().to_hex().to_string()
    }

    /// Any change to a built-in entry, even one far below the precision
    /// of a message, changes the key: levels whose palette file extends
    /// the built-in palette are baked again.
    #[test]
    fn the_key_follows_every_built_in_entry() {
        let builtin = Palette::builtin();
        let base = key(&builtin);
        assert_eq!(base, key(&Palette::builtin()), "deterministic");
        let mut emission = builtin.clone();
        emission.solids[6].emission[1] *= 1.0 + 1e-15;
        let mut kind = builtin.clone();
        kind.solids[0].kind = crate::level::material::MaterialKind::Emitter;
        let mut gone = builtin.clone();
        gone.solids.pop();
        let mut name = builtin.clone();
        name.solid_names[3] = Some("brick".into());
        for (what, changed) in [
            ("emission", emission),
            ("kind", kind),
            ("entry", gone),
            ("name", name),
        ] {
            assert_ne!(base, key(&changed), "{what}");
        }
    }
}
