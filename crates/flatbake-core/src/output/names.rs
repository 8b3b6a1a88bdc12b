//! Every file name flatbake writes or recognises, in one place: a level's
//! outputs are named `NAME.SUFFIX` after the level image's file stem, and
//! nothing else in the crate spells a suffix.

use std::path::Path;

/// Prefix of the temporary files that writes go through (hidden, and
/// recognisable as flatbake's own when a killed process leaves one behind).
pub const TEMP_PREFIX: &str = ".flatbake-";
/// Suffix of the temporary files that writes go through.
pub const TEMP_SUFFIX: &str = ".tmp";

/// The batch summary a run without shards writes into its output folder.
pub const BATCH_SUMMARY: &str = "batch.json";

/// The batch summary's file name: `batch.json` for a whole batch,
/// `batch-K-of-N.json` for shard K of N, so that shards baking into one
/// folder do not replace each other's summary.
pub fn batch_summary(shard: Option<(u32, u32)>) -> String {
    match shard {
        None => BATCH_SUMMARY.into(),
        Some((k, n)) => format!("batch-{k}-of-{n}.json"),
    }
}

/// The name a level's outputs are written under: its image's file stem
/// (`levels/cave.png` is `cave`); for a level of an LDtk project,
/// `PROJECT.LEVEL` (`levels/world.ldtk/Cellar` is `world.Cellar`).
pub fn level_name(image: &Path) -> String {
    if let Some((project, level)) = crate::level::ldtk::project_level(image) {
        return project_level_name(project, level);
    }
    image
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The name of level `level` of the LDtk project `project`: `PROJECT.LEVEL`.
pub fn project_level_name(project: &Path, level: &str) -> String {
    format!("{}.{level}", level_name(project))
}

/// True when a file name is one of flatbake's own image outputs (so a
/// folder of levels baked into itself does not take them for levels).
pub fn is_output_image(file_name: &str) -> bool {
    [
        ".lightmap.",
        ".lit.",
        ".layer-",
        ".rgbm.",
        ".direction.",
        ".lit-normals.",
        ".normals.",
    ]
    .iter()
    .any(|s| file_name.contains(s))
}

/// The normal map flatbake reads beside level `name` for the lit preview of
/// a directional bake: `NAME.normals.png` (an input, never written; a folder
/// of levels does not take it for a level, see [`is_output_image`]).
pub fn normal_map(name: &str) -> String {
    format!("{name}.normals.png")
}

/// The files flatbake writes for one level.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OutputKind {
    /// `NAME.lightmap.png`
    Lightmap,
    /// `NAME.lit.png`
    Lit,
    /// `NAME.lightmap.exr`
    Hdr,
    /// `NAME.lightmap.ktx2`: the HDR lightmap as RGBA 16-bit float KTX2.
    Ktx2,
    /// `NAME.lightmap.rgbm.png`
    Rgbm,
    /// `NAME.lightmap.rgbm-unity.png`: RGBM in Unity's convention.
    RgbmUnity,
    /// `NAME.report.json`
    Report,
    /// `NAME.stamp.json`: what the outputs were made from (incremental bakes).
    Stamp,
    /// `NAME.flatbake`: the relight cache.
    Cache,
    /// `NAME.layers.json`: the light layers' manifest.
    LayersManifest,
    /// `NAME.layer-TAG.exr`: one light group's linear layer.
    LayerExr(String),
    /// `NAME.layer-TAG.png`: one light group's sRGB preview.
    LayerPng(String),
    /// `NAME.occluders.json`: the wall loops as simplified polygons.
    OccludersJson,
    /// `NAME.occluders.svg`: the occluder polygons, to look at.
    OccludersSvg,
    /// `NAME.occluders.tres`: the occluder polygons as Godot `OccluderPolygon2D`s.
    OccludersTres,
    /// `NAME.directional.exr`: the mean and first circular moments of the light.
    DirectionalExr,
    /// `NAME.direction.png`: the dominant direction of the light, to look at.
    DirectionPng,
    /// `NAME.lit-normals.png`: the lit image shaded by the level's normal map.
    LitNormalsPng,
    /// `NAME.layer-TAG.directional.exr`: one light group's mean and moments.
    LayerDirectionalExr(String),
    /// `NAME.directional.cos.ktx2`: the cosine moments as RGBA 16-bit float
    /// KTX2 (signed), alpha the floor coverage.
    DirectionalCosKtx2,
    /// `NAME.directional.sin.ktx2`: the sine moments, the same way.
    DirectionalSinKtx2,
}

/// True for the characters a light layer's file tag keeps from its group's
/// name (others become `_`).
pub fn is_tag_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '-' || c == '_'
}

impl OutputKind {
    /// The file name suffix, after `NAME.`.
    pub fn suffix(&self) -> String {
        match self {
            OutputKind::Lightmap => "lightmap.png".into(),
            OutputKind::Lit => "lit.png".into(),
            OutputKind::Hdr => "lightmap.exr".into(),
            OutputKind::Ktx2 => "lightmap.ktx2".into(),
            OutputKind::Rgbm => "lightmap.rgbm.png".into(),
            OutputKind::RgbmUnity => "lightmap.rgbm-unity.png".into(),
            OutputKind::Report => "report.json".into(),
            OutputKind::Stamp => "stamp.json".into(),
            OutputKind::Cache => "flatbake".into(),
            OutputKind::LayersManifest => "layers.json".into(),
            OutputKind::LayerExr(tag) => format!("layer-{tag}.exr"),
            OutputKind::LayerPng(tag) => format!("layer-{tag}.png"),
            OutputKind::OccludersJson => "occluders.json".into(),
            OutputKind::OccludersSvg => "occluders.svg".into(),
            OutputKind::OccludersTres => "occluders.tres".into(),
            OutputKind::DirectionalExr => "directional.exr".into(),
            OutputKind::DirectionPng => "direction.png".into(),
            OutputKind::LitNormalsPng => "lit-normals.png".into(),
            OutputKind::LayerDirectionalExr(tag) => format!("layer-{tag}.directional.exr"),
            OutputKind::DirectionalCosKtx2 => "directional.cos.ktx2".into(),
            OutputKind::DirectionalSinKtx2 => "directional.sin.ktx2".into(),
        }
    }

    /// Every kind whose file name does not depend on a tag (all but the
    /// light layers').
    pub const UNTAGGED: [OutputKind; 18] = [
        OutputKind::Lightmap,
        OutputKind::Lit,
        OutputKind::Hdr,
        OutputKind::Ktx2,
        OutputKind::Rgbm,
        OutputKind::RgbmUnity,
        OutputKind::Report,
        OutputKind::Stamp,
        OutputKind::Cache,
        OutputKind::LayersManifest,
        OutputKind::OccludersJson,
        OutputKind::OccludersSvg,
        OutputKind::OccludersTres,
        OutputKind::DirectionalExr,
        OutputKind::DirectionPng,
        OutputKind::LitNormalsPng,
        OutputKind::DirectionalCosKtx2,
        OutputKind::DirectionalSinKtx2,
    ];

    /// True when `file` is a file name an output of level `name` can have
    /// (`NAME.` and a known suffix, a layer's with any tag; no folder).
    pub fn is_output_of(file: &str, name: &str) -> bool {
        let Some(suffix) = file.strip_prefix(name).and_then(|s| s.strip_prefix('.')) else {
            return false;
        };
        let layer = suffix.strip_prefix("layer-").is_some_and(|rest| {
            let tag = rest
                .strip_suffix(".directional.exr")
                .or_else(|| rest.strip_suffix(".exr"))
                .or_else(|| rest.strip_suffix(".png"));
            tag.is_some_and(|t| !t.is_empty() && t.chars().all(is_tag_char))
        });
        !file.contains(['/', '\\'])
            && (layer || Self::UNTAGGED.iter().any(|k| k.suffix() == suffix))
    }

    /// The file name of this output for level `name`.
    pub fn file_name(&self, name: &str) -> String {
        format!("{name}.{}", self.suffix())
    }
}

#[cfg(test)]
mod tests {
    use super::OutputKind;

    #[test]
    fn every_output_file_is_recognised_as_one_and_nothing_else_is() {
        let t = || "ff00aa".to_string();
        let tagged = [
            OutputKind::LayerExr(t()),
            OutputKind::LayerPng(t()),
            OutputKind::LayerDirectionalExr(t()),
        ];
        let all: Vec<OutputKind> = OutputKind::UNTAGGED.into_iter().chain(tagged).collect();
        for k in &all {
            // Exhaustive: a new kind must be added to UNTAGGED or `tagged`
            // (and so checked).
            match k {
                OutputKind::Lightmap
                | OutputKind::Lit
                | OutputKind::Hdr
                | OutputKind::Ktx2
                | OutputKind::Rgbm
                | OutputKind::RgbmUnity
                | OutputKind::Report
                | OutputKind::Stamp
                | OutputKind::Cache
                | OutputKind::LayersManifest
                | OutputKind::LayerExr(_)
                | OutputKind::LayerPng(_)
                | OutputKind::OccludersJson
                | OutputKind::OccludersSvg
                | OutputKind::OccludersTres
                | OutputKind::DirectionalExr
                | OutputKind::DirectionPng
                | OutputKind::LitNormalsPng
                | OutputKind::LayerDirectionalExr(_)
                | OutputKind::DirectionalCosKtx2
                | OutputKind::DirectionalSinKtx2 => {}
            }
            let f = k.file_name("world.cellar");
            assert!(OutputKind::is_output_of(&f, "world.cellar"), "{f}");
            assert!(!OutputKind::is_output_of(&f, "world"), "{f} is not world's");
        }
        for f in [
            "world.cellar.notes.txt",
            "world.cellar.layer-a.b.png",
            "world.cellar.layer-.exr",
            "../world.cellar.lit.png",
            "sub/world.cellar.lit.png",
            "world.cellarlit.png",
        ] {
            assert!(!OutputKind::is_output_of(f, "world.cellar"), "{f}");
        }
    }
}
