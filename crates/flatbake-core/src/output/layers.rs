//! Light layers (`bake --layers`): one lightmap per light group, so that a
//! game can dim, tint or switch off each group at runtime.
//!
//! Light is linear in emission, so a layer is the bake's per-emitter
//! [`Responses`] combined with the emission of that group's emitters only,
//! and the layers add up to the full lightmap. A group is the palette's
//! `group = "NAME"` of an emitter, or the emitter's colour when it has none.

use serde::{Deserialize, Serialize};

use crate::bake::Lightmap;
use crate::bake::Responses;
use crate::level::Level;
use crate::output::{self, Encoded, OutputError, OutputKind, OutputOptions};

/// One light group: the emitters (positions in [`Responses::emitters`]) that
/// switch together.
#[derive(Clone, Debug, PartialEq)]
pub struct Group {
    /// The group's name: the palette's `group`, or the emitter's colour.
    pub name: String,
    /// File-name-safe spelling of `name`, unique within the level.
    pub file_tag: String,
    /// Positions in [`Responses::emitters`] of the group's emitters.
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
                    .map(|c| if super::names::is_tag_char(c) { c } else { '_' })
                    .collect();
                // Two names that spell the same file name get a number, the
                // first free one: a numbered tag may itself be taken ("b_2"
                // and "b_" before "b!"). Tags that differ only in case would
                // be one file on a case-insensitive disk, so they clash too.
                let taken = |t: &str| {
                    t.is_empty() || out.iter().any(|g| g.file_tag.eq_ignore_ascii_case(t))
                };
                if taken(&tag) {
                    let base = std::mem::take(&mut tag);
                    let mut k = out.len();
                    tag = format!("{base}{k}");
                    while taken(&tag) {
                        k += 1;
                        tag = format!("{base}{k}");
                    }
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

/// `emission` with every emitter outside `group` switched off.
fn group_emission(emission: &[[f64; 3]], group: &Group) -> Vec<[f64; 3]> {
    emission
        .iter()
        .enumerate()
        .map(|(i, e)| {
            if group.emitters.contains(&i) {
                *e
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

/// The lightmap of one group: the other emitters switched off.
pub fn layer(r: &Responses, emission: &[[f64; 3]], group: &Group) -> Lightmap {
    let only = group_emission(emission, group);
    Lightmap {
        width: r.width,
        height: r.height,
        rgb: r.combine(&only),
    }
}

/// The moments of one group, when the responses hold moments
/// ([`crate::bake::Settings::directional`]): as [`layer`], the other
/// emitters switched off.
pub fn layer_moments(
    r: &Responses,
    emission: &[[f64; 3]],
    group: &Group,
) -> Option<crate::bake::Directional> {
    let only = group_emission(emission, group);
    r.combine_moments(&only)
}

/// `NAME.layers.json`: what a game needs to load and combine the layers.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Manifest {
    /// The level's name.
    pub level: String,
    /// Width and height in pixels.
    pub size: [usize; 2],
    /// The full lightmap the layers add up to.
    pub lightmap_exr: String,
    /// The full lightmap's sRGB preview.
    pub lightmap_png: String,
    /// How the layers combine (for people reading the file).
    pub combine: String,
    /// The groups, in palette order.
    pub groups: Vec<ManifestGroup>,
}

/// One group in the manifest.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ManifestGroup {
    /// The group's name.
    pub name: String,
    /// Linear emission of the group's emitters as baked into the layer.
    pub emitters: Vec<ManifestEmitter>,
    /// Linear float layer (unscaled by exposure).
    pub exr: String,
    /// sRGB preview of the layer (times exposure, clamped).
    pub png: String,
    /// With `--directional`, the layer's mean and first circular moments
    /// (`NAME.layer-TAG.directional.exr`); left out of the file otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub directional_exr: Option<String>,
}

/// An emitter colour of a group and its emission.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ManifestEmitter {
    /// The emitter's colour, `#rrggbb`.
    pub color: String,
    /// Its linear emission per channel, as baked into the layer.
    pub emission: [f64; 3],
}

/// Encodes every layer (EXR and PNG) of `level` with `emission` per
/// emitter, then `NAME.layers.json`, in writing order (manifest last).
/// With `opts.padding > 0` each layer is padded as the lightmap is
/// ([`output::padding`]): the EXR gains the coverage as `A` and the PNG's
/// alpha is the coverage. The EXRs are compressed as `opts.exr_compression`
/// says.
pub fn encode_layers(
    level: &Level,
    r: &Responses,
    emission: &[[f64; 3]],
    opts: &OutputOptions,
) -> Result<Vec<Encoded>, OutputError> {
    let name = &level.name;
    let mut files = Vec::new();
    let mut manifest = Manifest {
        level: name.clone(),
        size: [level.width, level.height],
        lightmap_exr: OutputKind::Hdr.file_name(name),
        lightmap_png: OutputKind::Lightmap.file_name(name),
        combine: "lightmap = sum over groups of scale_g * layer_g (linear values, from the EXRs); \
                  scale 1 reproduces the bake"
            .into(),
        groups: Vec::new(),
    };
    for g in groups(level, r) {
        let map = layer(r, emission, &g);
        let exr_kind = OutputKind::LayerExr(g.file_tag.clone());
        let png_kind = OutputKind::LayerPng(g.file_tag.clone());
        // Padded like the lightmap (same mask, same width): padding is
        // linear in the values, so the padded layers still add up to the
        // padded lightmap.
        let hdr = output::padded_hdr_pixels(level, &map, opts.padding)?;
        let exr = if opts.padding > 0 {
            output::encode_exr_rgba(
                level.width,
                level.height,
                &output::with_coverage(level, &hdr),
                opts.exr_compression,
            )
        } else {
            output::encode_exr_rgb(level.width, level.height, &hdr, opts.exr_compression)
        }
        .map_err(|message| OutputError::Encode {
            path: exr_kind.file_name(name).into(),
            message,
        })?;
        let img = if opts.padding > 0 {
            output::image::padded_sdr_image(level, &hdr, opts)
        } else {
            output::lightmap_image(level, &map, opts)?
        };
        let png = output::encode_png(&img).map_err(|e| OutputError::Encode {
            path: png_kind.file_name(name).into(),
            message: e.to_string(),
        })?;
        let moments = layer_moments(r, emission, &g)
            .map(|d| {
                let kind = OutputKind::LayerDirectionalExr(g.file_tag.clone());
                output::directional::moments_exr(level, &map, &d, kind)
            })
            .transpose()?;
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
            exr: exr_kind.file_name(name),
            png: png_kind.file_name(name),
            directional_exr: moments
                .as_ref()
                .map(|_| OutputKind::LayerDirectionalExr(g.file_tag.clone()).file_name(name)),
        });
        files.push(Encoded {
            kind: exr_kind,
            bytes: exr,
        });
        files.push(Encoded {
            kind: png_kind,
            bytes: png,
        });
        files.extend(moments);
    }
    let kind = OutputKind::LayersManifest;
    let mut json = serde_json::to_vec_pretty(&manifest).map_err(|e| OutputError::Encode {
        path: kind.file_name(name).into(),
        message: e.to_string(),
    })?;
    json.push(b'\n');
    files.push(Encoded { kind, bytes: json });
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::level::material::{Material, MaterialKind};

    fn emitter(group: &str) -> Material {
        Material {
            color: [255, 255, 255],
            kind: MaterialKind::Emitter,
            reflectance: [0.0; 3],
            emission: [1.0; 3],
            group: Some(group.into()),
            line: None,
        }
    }

    /// Groups whose names spell the same file name, directly or once
    /// numbered, or only differ in case, still get one file each.
    #[test]
    fn every_group_gets_its_own_file_tag() {
        for names in [
            vec!["b_2", "b_", "b!"],
            vec!["b!", "b?", "b_", "b_1", "b_2"],
            vec!["Lamp", "lamp", "LAMP"],
            vec!["", "!", "_"],
        ] {
            let level = Level {
                name: "t".into(),
                width: 1,
                height: 1,
                cells: vec![crate::level::Cell::Floor],
                albedo: vec![[0.0; 3]],
                materials: names.iter().map(|n| emitter(n)).collect(),
                warnings: vec![],
                lossy_format: None,
                origin: Default::default(),
                floor_fraction: None,
            };
            let r = Responses {
                width: 1,
                height: 1,
                emitters: (0..names.len()).collect(),
                rho_class_of: [0; 3],
                rho_classes: 1,
                images: vec![vec![0.0]; names.len()],
                traced_emission: 1.0,
                moments: Vec::new(),
            };
            let g = groups(&level, &r);
            assert_eq!(g.len(), names.len(), "{names:?}");
            for (i, a) in g.iter().enumerate() {
                assert!(!a.file_tag.is_empty(), "{names:?}: {g:?}");
                for b in &g[i + 1..] {
                    assert!(
                        !a.file_tag.eq_ignore_ascii_case(&b.file_tag),
                        "{names:?}: {} and {} share {}",
                        a.name,
                        b.name,
                        a.file_tag
                    );
                }
            }
        }
    }
}
