//! Light layers (`bake --layers`): one lightmap per light group, so that a
//! game can dim, tint or switch off each group at runtime.
//!
//! Light is linear in emission, so a layer is the bake's per-emitter
//! [`Responses`] combined with the emission of that group's emitters only,
//! and the layers add up to the full lightmap. A group is the palette's
//! `group = "NAME"` of an emitter, or the emitter's colour when it has none.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::bake::Lightmap;
use crate::bake::Responses;
use crate::level::Level;
use crate::output::{self, OutputError, OutputKind, OutputOptions};

/// One light group: the emitters (positions in [`Responses::emitters`]) that
/// switch together.
#[derive(Clone, Debug, PartialEq)]
pub struct Group {
    pub name: String,
    /// File-name-safe spelling of `name`, unique within the level.
    pub file_tag: String,
    pub emitters: Vec<usize>,
}

/// The groups of a level's emitters, in palette order of first appearance.
pub fn groups(level: &Level, r: &Responses) -> Vec<Group> {
    let mut out: Vec<Group> = Vec::new();
    for (pos, &mi) in r.emitters.iter().enumerate() {
        let name = level
            .materials
            .get(mi)
            .map_or_else(|| format!("emitter{pos}"), |m| m.group_name());
        match out.iter_mut().find(|g| g.name == name) {
            Some(g) => g.emitters.push(pos),
            None => {
                let mut tag: String = name
                    .chars()
                    .map(|c| {
                        if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                            c
                        } else {
                            '_'
                        }
                    })
                    .collect();
                // Two names that spell the same file name get a number.
                if tag.is_empty() || out.iter().any(|g| g.file_tag == tag) {
                    tag = format!("{tag}{}", out.len());
                }
                out.push(Group {
                    name,
                    file_tag: tag,
                    emitters: vec![pos],
                });
            }
        }
    }
    out
}

/// The emission of each emitter in `r` as the level's palette sets it.
pub fn palette_emission(level: &Level, r: &Responses) -> Vec<[f64; 3]> {
    r.emitters
        .iter()
        .map(|&mi| level.materials.get(mi).map_or([0.0; 3], |m| m.emission))
        .collect()
}

/// The lightmap of one group: the other emitters switched off.
pub fn layer(r: &Responses, emission: &[[f64; 3]], group: &Group) -> Lightmap {
    let only: Vec<[f64; 3]> = emission
        .iter()
        .enumerate()
        .map(|(i, e)| {
            if group.emitters.contains(&i) {
                *e
            } else {
                [0.0; 3]
            }
        })
        .collect();
    Lightmap {
        width: r.width,
        height: r.height,
        rgb: r.combine(&only),
    }
}

/// `NAME.layers.json`: what a game needs to load and combine the layers.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Manifest {
    pub level: String,
    pub size: [usize; 2],
    /// The full lightmap the layers add up to.
    pub lightmap_exr: String,
    pub lightmap_png: String,
    /// How the layers combine (for people reading the file).
    pub combine: String,
    pub groups: Vec<ManifestGroup>,
}

/// One group in the manifest.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ManifestGroup {
    pub name: String,
    /// Linear emission of the group's emitters as baked into the layer.
    pub emitters: Vec<ManifestEmitter>,
    /// Linear float layer (unscaled by exposure).
    pub exr: String,
    /// sRGB preview of the layer (times exposure, clamped).
    pub png: String,
}

/// An emitter colour of a group and its emission.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ManifestEmitter {
    pub color: String,
    pub emission: [f64; 3],
}

/// File name of a group's layer: `NAME.layer-TAG.exr` or `.png`.
pub fn layer_file(level: &str, tag: &str, ext: &str) -> String {
    format!("{level}.layer-{tag}.{ext}")
}

/// Writes every layer (EXR and PNG) of `level` with `emission` per emitter,
/// then `NAME.layers.json`; returns the paths written, manifest last.
pub fn write_layers(
    dir: &Path,
    level: &Level,
    r: &Responses,
    emission: &[[f64; 3]],
    opts: &OutputOptions,
) -> Result<Vec<PathBuf>, OutputError> {
    let mut written = Vec::new();
    let mut manifest = Manifest {
        level: level.name.clone(),
        size: [level.width, level.height],
        lightmap_exr: OutputKind::Hdr.file_name(&level.name),
        lightmap_png: OutputKind::Lightmap.file_name(&level.name),
        combine: "lightmap = sum over groups of scale_g * layer_g (linear values, from the EXRs); \
                  scale 1 reproduces the bake"
            .into(),
        groups: Vec::new(),
    };
    for g in groups(level, r) {
        let map = layer(r, emission, &g);
        let exr_name = layer_file(&level.name, &g.file_tag, "exr");
        let png_name = layer_file(&level.name, &g.file_tag, "png");
        let exr_path = dir.join(&exr_name);
        let hdr = output::hdr_pixels(level, &map)?;
        let exr =
            output::encode_exr_rgb32f(level.width, level.height, &hdr).map_err(|message| {
                OutputError::Encode {
                    path: exr_path.clone(),
                    message,
                }
            })?;
        output::write_file_atomic(&exr_path, &exr)?;
        written.push(exr_path);
        let png_path = dir.join(&png_name);
        let img = output::lightmap_image(level, &map, opts)?;
        let png = output::encode_png(&img).map_err(|e| OutputError::Encode {
            path: png_path.clone(),
            message: e.to_string(),
        })?;
        output::write_file_atomic(&png_path, &png)?;
        written.push(png_path);
        manifest.groups.push(ManifestGroup {
            name: g.name.clone(),
            emitters: g
                .emitters
                .iter()
                .map(|&i| ManifestEmitter {
                    color: level
                        .materials
                        .get(r.emitters[i])
                        .map_or_else(String::new, |m| m.hex()),
                    emission: emission.get(i).copied().unwrap_or([0.0; 3]),
                })
                .collect(),
            exr: exr_name,
            png: png_name,
        });
    }
    let path = dir.join(format!("{}.layers.json", level.name));
    let mut json = serde_json::to_vec_pretty(&manifest).map_err(|e| OutputError::Encode {
        path: path.clone(),
        message: e.to_string(),
    })?;
    json.push(b'\n');
    output::write_file_atomic(&path, &json)?;
    written.push(path);
    Ok(written)
}
