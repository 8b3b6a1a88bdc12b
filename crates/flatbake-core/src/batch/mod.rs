//! Baking a batch of level files: finding levels, resolving each one's
//! palette and settings, baking, writing, and reporting per level.
//!
//! One bad level never stops the batch: every level ends as a
//! [`LevelOutcome`], and the caller turns the worst outcome into the exit
//! status.

pub mod stamp;

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;

use crate::bake::report::Report;
use crate::bake::{self, GatherMethod, Settings};
use crate::gather::Kernel;
use crate::level::palette::Palette;
use crate::level::{self, LoadLimits};
use crate::output::{self, Depth, OutputOptions};
use crate::quality::Quality;

/// Options for a batch, as given on the command line (palette `[bake]`
/// settings fill in what is `None` here, per level).
#[derive(Clone, Debug)]
pub struct BatchOptions {
    pub out_dir: PathBuf,
    pub quality: Quality,
    pub falloff: Option<f64>,
    pub kernel: Kernel,
    pub gather: GatherMethod,
    pub palette: Option<PathBuf>,
    pub bounces: Option<u32>,
    pub exposure: Option<f64>,
    pub hdr: bool,
    pub depth: Depth,
    pub rgbm: bool,
    pub limits: LoadLimits,
    /// Also write one layer per light group (implies the EXR lightmap).
    pub layers: bool,
    /// Also write the relight cache `NAME.flatbake`.
    pub cache: bool,
    /// Bake even levels whose outputs are up to date.
    pub force: bool,
}

impl Default for BatchOptions {
    fn default() -> Self {
        BatchOptions {
            out_dir: PathBuf::from("out"),
            quality: Quality::Normal,
            falloff: None,
            kernel: Kernel::Flatland,
            gather: GatherMethod::Fast,
            palette: None,
            bounces: None,
            exposure: None,
            hdr: false,
            depth: Depth::Eight,
            rgbm: false,
            limits: LoadLimits::default(),
            layers: false,
            cache: false,
            force: false,
        }
    }
}

/// What happened to one level.
#[derive(Debug)]
pub enum LevelOutcome {
    Baked {
        path: PathBuf,
        report: Box<Report>,
    },
    Failed {
        path: PathBuf,
        error: String,
    },
    /// Not baked: its outputs were made from the same image, palette,
    /// settings and flatbake version, and all still exist.
    UpToDate {
        path: PathBuf,
    },
}

impl LevelOutcome {
    pub fn path(&self) -> &Path {
        match self {
            LevelOutcome::Baked { path, .. }
            | LevelOutcome::Failed { path, .. }
            | LevelOutcome::UpToDate { path } => path,
        }
    }
}

/// Receives progress from a batch; implementations must be thread-safe
/// because levels bake in parallel.
pub trait Observer: Sync {
    /// A level starts; `index` counts from 0.
    fn level_started(&self, _path: &Path) {}
    /// A stage of a level starts ("geometry", "form factors", ...).
    fn stage(&self, _path: &Path, _stage: &str) {}
    /// A level is finished, baked or failed.
    fn level_done(&self, _outcome: &LevelOutcome) {}
}

/// An observer that ignores everything.
pub struct Silent;
impl Observer for Silent {}

/// Image extensions that are treated as levels inside folders.
const LEVEL_EXTENSIONS: &[&str] = &[
    "png", "bmp", "gif", "tga", "tif", "tiff", "webp", "qoi", "jpg", "jpeg", "pnm", "ppm",
];

/// Expands files and folders into the list of level files, in a stable
/// order. Folders contribute their image files (not recursively), except
/// flatbake's own outputs. A path that does not exist is kept so that the
/// batch reports it as a failed level.
pub fn collect_levels(paths: &[PathBuf]) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let mut found: Vec<PathBuf> = std::fs::read_dir(p)
                .map(|rd| {
                    rd.filter_map(Result::ok)
                        .map(|e| e.path())
                        .filter(|f| f.is_file() && is_level_file(f))
                        .collect()
                })
                .unwrap_or_default();
            found.sort();
            if found.is_empty() {
                // Reported as a failure: an empty folder is almost always a mistake.
                out.push(p.clone());
            }
            out.extend(found);
        } else {
            out.push(p.clone());
        }
    }
    out
}

/// True for image files that are levels (not flatbake's own outputs).
pub fn is_level_file(p: &Path) -> bool {
    let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
    let ext = p
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    LEVEL_EXTENSIONS.contains(&ext.as_str())
        && ![".lightmap.", ".lit.", ".layer-", ".rgbm."]
            .iter()
            .any(|s| name.contains(s))
}

/// Bakes every level; returns the outcomes in input order.
pub fn run(paths: &[PathBuf], opts: &BatchOptions, observer: &dyn Observer) -> Vec<LevelOutcome> {
    let levels = collect_levels(paths);
    let clashes = output_clashes(&levels);
    levels
        .par_iter()
        .zip(&clashes)
        .map(|(path, clash)| {
            if clash.is_none() && !opts.force && crate::batch::stamp::up_to_date(path, opts) {
                let outcome = LevelOutcome::UpToDate { path: path.clone() };
                observer.level_done(&outcome);
                return outcome;
            }
            observer.level_started(path);
            let result = match clash {
                Some(first) => Err(format!(
                    "{}: not baked: its outputs would overwrite those of {} (both are named {:?}); rename one or bake them into different output folders",
                    path.display(),
                    first.display(),
                    level_stem(path)
                )),
                None => bake_one(path, opts, observer),
            };
            let outcome = match result {
                Ok(report) => LevelOutcome::Baked {
                    path: path.clone(),
                    report: Box::new(report),
                },
                Err(error) => LevelOutcome::Failed {
                    path: path.clone(),
                    error,
                },
            };
            observer.level_done(&outcome);
            outcome
        })
        .collect()
}

/// The name a level's outputs are written under (`NAME.lightmap.png`, ...).
fn level_stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// For each level, the earlier level of the batch with the same output
/// names, if any (`a/room.png` and `b/room.png`, or `room.png` and
/// `room.bmp`): baking both would silently overwrite the first one's
/// outputs. The same file listed twice is not a clash.
fn output_clashes(levels: &[PathBuf]) -> Vec<Option<PathBuf>> {
    let mut first: std::collections::HashMap<String, &PathBuf> = Default::default();
    levels
        .iter()
        .map(|p| {
            let f = *first.entry(level_stem(p)).or_insert(p);
            (f != p).then(|| f.clone())
        })
        .collect()
}

/// Bakes one level file and writes its outputs; the error is a complete
/// sentence naming the file.
pub fn bake_one(
    path: &Path,
    opts: &BatchOptions,
    observer: &dyn Observer,
) -> Result<Report, String> {
    let t_total = Instant::now();
    if path.is_dir() {
        return Err(format!(
            "{}: the folder holds no level images",
            path.display()
        ));
    }
    let t = Instant::now();
    let palette =
        Palette::resolve_for_level(path, opts.palette.as_deref()).map_err(|e| e.to_string())?;
    let level = level::load_level(path, &palette, opts.limits).map_err(|e| e.to_string())?;
    // What the stamp and cache record; hashed right after loading.
    let inputs = crate::batch::stamp::inputs(path, opts)?;
    let load = t.elapsed().as_secs_f64();

    let mut settings = Settings::new(opts.quality);
    settings.falloff = opts.falloff.or(palette.settings.falloff);
    settings.bounces = opts.bounces.or(palette.settings.bounces);
    settings.kernel = opts.kernel;
    settings.gather = opts.gather;
    settings.responses = opts.layers || opts.cache;
    let exposure = opts.exposure.or(palette.settings.exposure).unwrap_or(1.0);

    let baked = bake::bake(&level, &settings, &|stage| observer.stage(path, stage))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut report = baked.report;
    report.timings.load = load;

    observer.stage(path, "write");
    output::ensure_output_dir(&opts.out_dir).map_err(|e| e.to_string())?;
    let out_opts = OutputOptions {
        exposure,
        depth: opts.depth,
        hdr: opts.hdr || opts.layers,
        rgbm: opts.rgbm,
    };
    // Writing adds its own time to `write` and `total`.
    report.timings.total = t_total.elapsed().as_secs_f64();
    let mut written =
        output::write_level_outputs(&opts.out_dir, &level, &baked.lightmap, &report, &out_opts)
            .map_err(|e| e.to_string())?;
    if let Some(resp) = baked.responses {
        if opts.layers {
            let emission = crate::output::layers::palette_emission(&level, &resp);
            written.extend(
                crate::output::layers::write_layers(
                    &opts.out_dir,
                    &level,
                    &resp,
                    &emission,
                    &out_opts,
                )
                .map_err(|e| e.to_string())?,
            );
        }
        if opts.cache {
            let cache_path = opts.out_dir.join(format!("{}.flatbake", level.name));
            let cache = crate::output::cache::Cache::new(
                &level,
                resp,
                &report,
                inputs.image_hash.clone(),
                inputs.key.clone(),
                &out_opts,
            );
            let bytes = cache
                .to_bytes()
                .map_err(|e| format!("cannot encode the cache {}: {e}", cache_path.display()))?;
            output::write_file_atomic(&cache_path, &bytes).map_err(|e| e.to_string())?;
            written.push(cache_path);
        }
    }
    report.outputs = written
        .iter()
        .filter_map(|p| p.file_name())
        .map(|n| n.to_string_lossy().into_owned())
        .collect();
    if opts.layers || opts.cache {
        list_extra_outputs(&opts.out_dir, &level.name, &report.outputs)?;
    }
    crate::batch::stamp::write(path, opts, &inputs, &report.outputs)?;
    Ok(report)
}

/// The report is written before the layers and the cache (it comes from
/// [`output::write_level_outputs`]); list those files in it too, so that
/// scripts find every output in `NAME.report.json`.
fn list_extra_outputs(dir: &Path, name: &str, outputs: &[String]) -> Result<(), String> {
    let path = dir.join(output::OutputKind::Report.file_name(name));
    let text = std::fs::read(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let mut written: Report = serde_json::from_slice(&text)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    written.outputs = outputs.to_vec();
    let mut json = serde_json::to_vec_pretty(&written).map_err(|e| e.to_string())?;
    json.push(b'\n');
    output::write_file_atomic(&path, &json).map_err(|e| e.to_string())
}
