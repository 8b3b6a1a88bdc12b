//! Baking a batch of level files: finding levels, resolving each one's
//! palette and settings, baking, writing, and reporting per level.
//!
//! One bad level never stops the batch: every level ends as a
//! [`LevelOutcome`], and the caller turns the worst outcome into the exit
//! status.

pub mod relight;
pub mod shard;
pub mod stamp;
pub mod summary;

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;

use crate::bake::report::Report;
use crate::bake::{self, GatherMethod, Settings};
use crate::error::{Error, Result};
use crate::gather::Kernel;
use crate::level::palette::Palette;
use crate::level::{self, LoadLimits};
use crate::output::cache::{Cache, CacheError};
use crate::output::exposure::{self, Exposure};
use crate::output::{
    self, Depth, Encoded, ExrCompression, OutputError, OutputKind, OutputOptions, names,
};
use crate::quality::Quality;
pub use shard::{Shard, ShardError};
use stamp::Recipe;
pub use summary::BatchSummary;

/// Options for a batch, as given on the command line (palette `[bake]`
/// settings fill in what is `None` here, per level).
#[derive(Clone, Debug)]
pub struct BatchOptions {
    /// Output folder (created if missing). Default `out`.
    pub out_dir: PathBuf,
    /// Accuracy preset. Default `normal`.
    pub quality: Quality,
    /// Falloff, overriding the palette's `[bake] falloff`: `Some(Some(d))`
    /// a half-energy distance of `d` pixels, `Some(None)` no falloff
    /// whatever the palette says; `None`: the palette's, or none.
    pub falloff: Option<Option<f64>>,
    /// Transport kernel. Default flatland.
    pub kernel: Kernel,
    /// Floor gather. Default fast.
    pub gather: GatherMethod,
    /// Palette for every level; `None`: the lookup beside each level.
    pub palette: Option<PathBuf>,
    /// Truncate the bounce series; `None`: the palette's, or the full solve.
    pub bounces: Option<u32>,
    /// Multiplies the PNG lightmaps, or is chosen per level from its light
    /// ([`Exposure::Auto`]); `None`: the palette's, or 1.
    pub exposure: Option<Exposure>,
    /// Also write `NAME.lightmap.exr`.
    pub hdr: bool,
    /// Bits per channel of the PNG outputs. Default 8.
    pub depth: Depth,
    /// Also write `NAME.lightmap.rgbm.png`.
    pub rgbm: bool,
    /// Also write `NAME.lightmap.rgbm-unity.png` (Unity's RGBM).
    pub rgbm_unity: bool,
    /// Padding of the lightmap outputs in texels ([`output::padding`]);
    /// 0 (the default) pads nothing.
    pub padding: u32,
    /// Also write `NAME.lightmap.ktx2` (RGBA 16-bit float).
    pub ktx2: bool,
    /// Compression of the EXR outputs; `None`: the engine preset's, or
    /// none (flatbake's own encoder).
    pub exr_compression: Option<ExrCompression>,
    /// Limits checked before an image is decoded.
    pub limits: LoadLimits,
    /// Also write one layer per light group (implies the EXR lightmap).
    pub layers: bool,
    /// Also write the relight cache `NAME.flatbake`.
    pub cache: bool,
    /// Bake even levels whose outputs are up to date.
    pub force: bool,
    /// Refuse a level whose estimated peak memory is above this many bytes
    /// (see [`bake::MemoryEstimate`]); `None`: no limit. Changes no output
    /// byte, so it is not part of the stamp.
    pub max_memory: Option<u64>,
    /// Bake only this shard of the levels ([`shard`]); `None`: all of them.
    /// Not part of the stamp: a level's outputs do not depend on it.
    pub shard: Option<Shard>,
    /// Also write the wall loops as occluder polygons simplified within
    /// this many pixels ([`output::occluders`]); `None`: not written.
    pub occluders: Option<f64>,
    /// Also write the directional lightmap (`NAME.directional.exr`,
    /// `NAME.direction.png`, and `NAME.lit-normals.png` for a level with
    /// `NAME.normals.png` beside it; [`output::directional`]). Default off.
    pub directional: bool,
    /// Texel density, quadrature and wall faces of the lightmap
    /// ([`bake::texels`]). Default: one texel per pixel, lit walls.
    pub texels: bake::TexelOptions,
}

impl BatchOptions {
    /// Every option that changes an output byte, spelled out for the stamp
    /// (not the output folder, not `force`, not the thread count), and the
    /// preset's knobs: a build that changes a preset re-bakes.
    pub fn fingerprint(&self) -> String {
        // Options added later are spelled only when not at their default, so
        // the stamps of bakes that do not use them stay up to date.
        let mut added = String::new();
        if self.padding != 0 {
            added.push_str(&format!(" padding {}", self.padding));
        }
        if self.rgbm_unity {
            added.push_str(" rgbm-unity");
        }
        if self.ktx2 {
            added.push_str(" ktx2");
        }
        let exr = self.exr_compression.unwrap_or_default();
        if exr != ExrCompression::None {
            added.push_str(&format!(" exr-{}", exr.name()));
        }
        if let Some(t) = self.occluders {
            added.push_str(&format!(" occluders {t:?}"));
        }
        if self.directional {
            added.push_str(" directional");
        }
        added.push_str(&self.texels.fingerprint());
        format!(
            "{:?}{:?}{added}",
            (
                self.quality,
                self.falloff,
                self.kernel,
                self.gather,
                self.bounces,
                self.exposure,
                self.hdr,
                self.depth,
                self.rgbm,
                self.layers,
                self.cache,
                self.limits.max_pixels,
            ),
            self.quality.knobs()
        )
    }

    /// These options with `engine`'s preset added: its outputs turned on,
    /// 16-bit PNGs if it asks for them, its padding where none is set and
    /// its EXR compression where none is chosen.
    pub fn with_engine(mut self, engine: output::Engine) -> Self {
        let e = engine.outputs();
        self.hdr |= e.hdr;
        self.rgbm |= e.rgbm;
        self.rgbm_unity |= e.rgbm_unity;
        self.ktx2 |= e.ktx2;
        self.exr_compression = self.exr_compression.or(Some(e.exr_compression));
        if e.depth == Depth::Sixteen {
            self.depth = Depth::Sixteen;
        }
        if self.padding == 0 {
            self.padding = e.padding;
        }
        self
    }

    /// The stamp recipe of level `path` with these options.
    pub fn recipe<'a>(&'a self, path: &'a Path, fingerprint: &'a str) -> Recipe<'a> {
        Recipe {
            image: path,
            palette: self.palette.as_deref(),
            settings: fingerprint,
        }
    }

    /// The bake settings of a level whose palette is `palette`: the
    /// command line's, with the palette's `[bake]` filling in the rest.
    pub fn settings(&self, palette: &Palette) -> Settings {
        let mut settings = Settings::new(self.quality);
        settings.falloff = self.falloff.unwrap_or(palette.settings.falloff);
        settings.bounces = self.bounces.or(palette.settings.bounces);
        settings.kernel = self.kernel;
        settings.gather = self.gather;
        settings.responses = self.layers || self.cache;
        settings.max_memory = self.max_memory;
        settings.directional = self.directional;
        // Nothing in a batch reads them after the solve.
        settings.keep_form_factors = false;
        settings
    }

    /// How the exposure of a level whose palette is `palette` is chosen:
    /// the command line's, else the palette's, else 1.
    pub fn exposure(&self, palette: &Palette) -> Exposure {
        self.exposure
            .or(palette.settings.exposure.map(Exposure::Fixed))
            .unwrap_or(Exposure::Fixed(1.0))
    }

    /// How a level is encoded, at `exposure` (see [`BatchOptions::exposure()`]).
    pub fn output_options(&self, exposure: f64) -> OutputOptions {
        OutputOptions {
            exposure,
            depth: self.depth,
            hdr: self.hdr || self.layers,
            rgbm: self.rgbm,
            rgbm_unity: self.rgbm_unity,
            padding: self.padding,
            ktx2: self.ktx2,
            exr_compression: self.exr_compression.unwrap_or_default(),
        }
    }
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
            rgbm_unity: false,
            padding: output::padding::DEFAULT_PADDING,
            ktx2: false,
            exr_compression: None,
            limits: LoadLimits::default(),
            layers: false,
            cache: false,
            force: false,
            max_memory: None,
            shard: None,
            occluders: None,
            directional: false,
            texels: bake::TexelOptions::default(),
        }
    }
}

/// What happened to one level.
#[derive(Debug)]
pub enum LevelOutcome {
    /// Baked and written.
    Baked {
        /// The level image.
        path: PathBuf,
        /// Its report, as written.
        report: Box<Report>,
    },
    /// Not baked, or not written; the batch went on.
    Failed {
        /// The level image (or the folder, or the missing path).
        path: PathBuf,
        /// Why.
        error: Error,
    },
    /// Not baked: its outputs were made from the same image, palette,
    /// settings and flatbake version, and all still exist.
    UpToDate {
        /// The level image.
        path: PathBuf,
    },
}

impl LevelOutcome {
    /// The level image (or path) the outcome is about.
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
    /// Part `done` (0 to 1) of a level's stage is done; called from worker
    /// threads, at most about a thousand times per stage (today only the
    /// gather reports).
    fn fraction(&self, _path: &Path, _stage: &str, _done: f64) {}
    /// A level is finished, baked or failed.
    fn level_done(&self, _outcome: &LevelOutcome) {}
    /// Another process is writing the output folder: the batch waits for
    /// it to finish before baking anything.
    fn waiting_for_folder(&self, _dir: &Path) {}
}

/// The output folder, held for one process while it writes: two bakes (or a
/// bake and a watch) into one folder take turns instead of mixing their
/// files. An advisory lock on the folder itself (no lock file is left in
/// it), released when this is dropped. Where the folder cannot be created,
/// opened or locked (another platform, a file system without locks), it is
/// not held and each level reports its own output error.
#[derive(Debug)]
pub struct FolderLock(#[allow(dead_code)] Option<std::fs::File>);

impl FolderLock {
    /// Takes the lock on `dir` (creating it), waiting for another holder;
    /// `waiting` is called once if it has to wait.
    pub fn acquire(dir: &Path, waiting: impl FnOnce()) -> FolderLock {
        if output::ensure_output_dir(dir).is_err() {
            return FolderLock(None);
        }
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        let Ok(f) = std::fs::File::open(dir) else {
            return FolderLock(None);
        };
        match f.try_lock() {
            Ok(()) => FolderLock(Some(f)),
            Err(std::fs::TryLockError::WouldBlock) => {
                waiting();
                FolderLock(f.lock().is_ok().then_some(f))
            }
            Err(_) => FolderLock(None),
        }
    }

    /// Whether the lock is held.
    pub fn is_held(&self) -> bool {
        self.0.is_some()
    }
}

/// An observer that ignores everything.
pub struct Silent;
impl Observer for Silent {}

/// Image extensions that are treated as levels inside folders.
const LEVEL_EXTENSIONS: &[&str] = &[
    "png", "bmp", "gif", "tga", "tif", "tiff", "webp", "qoi", "jpg", "jpeg", "pnm", "ppm", "tmx",
    "ldtk",
];

/// Expands files and folders into the list of level files, in a stable
/// order. Folders contribute their image files (not recursively), except
/// flatbake's own outputs; an LDtk project contributes each of its levels
/// (`PROJECT.ldtk/LEVEL`), or itself when it cannot be read, so that its
/// problem is reported. A path that does not exist is kept so that the
/// batch reports it as a failed level.
pub fn collect_levels(paths: &[PathBuf]) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for p in collect_files(paths) {
        match level::ldtk::is_ldtk_project(&p).then(|| level::ldtk::project_levels(&p)) {
            Some(Ok(levels)) if !levels.is_empty() => out.extend(levels),
            _ => out.push(p),
        }
    }
    out
}

/// [`collect_levels`] before LDtk projects are expanded into their levels.
fn collect_files(paths: &[PathBuf]) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let mut found: Vec<PathBuf> = std::fs::read_dir(p)
                .map(|rd| {
                    rd.filter_map(Result::ok)
                        .map(|e| e.path())
                        // A symlink that points nowhere is kept: loading
                        // it fails with its name, instead of it vanishing
                        // from the batch without a word.
                        .filter(|f| (f.is_file() || f.is_symlink()) && is_level_file(f))
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
    LEVEL_EXTENSIONS.contains(&ext.as_str()) && !names::is_output_image(name)
}

/// The levels a batch of `paths` bakes with `opts`: [`collect_levels`],
/// and of those only the ones in `opts.shard` ([`Shard::holds`], by level
/// name), in the same order.
pub fn select_levels(paths: &[PathBuf], opts: &BatchOptions) -> Vec<PathBuf> {
    let mut levels = collect_levels(paths);
    if let Some(shard) = opts.shard {
        levels.retain(|p| shard.holds(&names::level_name(p)));
    }
    levels
}

/// Removes the temporary files that a killed flatbake left in `dir`. Only
/// called while holding the folder's lock: then no other flatbake is writing
/// there, and every such file is a leftover.
fn remove_stale_temporaries(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let name = name.to_string_lossy();
        if name.starts_with(names::TEMP_PREFIX)
            && name.ends_with(names::TEMP_SUFFIX)
            && e.file_type().is_ok_and(|t| t.is_file())
        {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// Bakes every level (of `opts.shard`); returns the outcomes in input
/// order. Writes no batch summary (see [`run_batch`]).
pub fn run(paths: &[PathBuf], opts: &BatchOptions, observer: &dyn Observer) -> Vec<LevelOutcome> {
    let levels = select_levels(paths, opts);
    let _lock = lock_folder(opts, observer);
    bake_levels(&levels, opts, observer)
}

/// What [`run_batch`] did: every level's outcome, and where the batch
/// summary went.
#[derive(Debug)]
pub struct BatchRun {
    /// The outcomes, in input order.
    pub outcomes: Vec<LevelOutcome>,
    /// The batch summary as written, or why it could not be.
    pub summary: Result<(PathBuf, BatchSummary), OutputError>,
}

/// [`run`], then the batch summary ([`BatchSummary`]: `batch.json`, or
/// `batch-K-of-N.json` for a shard) written into the output folder while
/// the folder is still held. This is what `flatbake bake` runs.
pub fn run_batch(paths: &[PathBuf], opts: &BatchOptions, observer: &dyn Observer) -> BatchRun {
    let start = Instant::now();
    let levels = select_levels(paths, opts);
    let _lock = lock_folder(opts, observer);
    let outcomes = bake_levels(&levels, opts, observer);
    let summary = BatchSummary::new(opts, &outcomes, start.elapsed().as_secs_f64());
    let summary = summary.write(&opts.out_dir).map(|path| (path, summary));
    BatchRun { outcomes, summary }
}

/// Takes the output folder for this process (and, when that worked, clears
/// what a killed flatbake left there). Up-to-date checks and writes happen
/// under the folder's lock, so that they see no other process's
/// half-written set.
fn lock_folder(opts: &BatchOptions, observer: &dyn Observer) -> FolderLock {
    let lock = FolderLock::acquire(&opts.out_dir, || observer.waiting_for_folder(&opts.out_dir));
    if lock.is_held() {
        remove_stale_temporaries(&opts.out_dir);
    }
    lock
}

/// Bakes `levels` in parallel (the caller holds the folder).
fn bake_levels(
    levels: &[PathBuf],
    opts: &BatchOptions,
    observer: &dyn Observer,
) -> Vec<LevelOutcome> {
    let clashes = output_clashes(levels);
    let fingerprint = opts.fingerprint();
    levels
        .par_iter()
        .zip(&clashes)
        .map(|(path, clash)| {
            if clash.is_none()
                && !opts.force
                && stamp::up_to_date(&opts.recipe(path, &fingerprint), &opts.out_dir)
            {
                let outcome = LevelOutcome::UpToDate { path: path.clone() };
                observer.level_done(&outcome);
                return outcome;
            }
            observer.level_started(path);
            let result = match clash {
                Some(first) => Err(Error::NameClash {
                    path: path.clone(),
                    first: first.clone(),
                    name: names::level_name(path),
                }),
                None => bake_isolated(path, opts, observer),
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

/// [`bake_one`], with a panic anywhere in it (a decoder's, or a bug of
/// ours) turned into this level's failure, so that the batch goes on.
fn bake_isolated(path: &Path, opts: &BatchOptions, observer: &dyn Observer) -> Result<Report> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        bake_one(path, opts, observer)
    }))
    .unwrap_or_else(|payload| {
        let message = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "no message".into());
        Err(Error::Panic {
            path: path.to_path_buf(),
            message,
        })
    })
}

/// Records the PNG lightmap's exposure and clipping in the report, and a
/// problem when most of the floor is clipped or none of it shows.
fn check_brightness(
    level: &level::Level,
    map: &bake::Lightmap,
    opts: &BatchOptions,
    exposure: f64,
    report: &mut Report,
) {
    let auto = opts.exposure == Some(Exposure::Auto);
    report.exposure = exposure;
    report.exposure_auto = auto;
    report.clipped = exposure::clipped_fraction(level, map, exposure, opts.depth);
    if !report.problems.is_empty() {
        return;
    }
    let suggestion = (!auto).then(|| exposure::auto_exposure(level, map));
    if let Some(p) = exposure::clipping_problem(report.clipped, exposure, suggestion) {
        report.add_problem(p);
    } else if let Some(p) = exposure::too_dark_problem(level, map, exposure) {
        report.add_problem(p);
    }
}

/// The report a level's last bake into `out_dir` wrote, if it is there and
/// readable: what an up-to-date level's warnings and times were.
pub fn stored_report(out_dir: &Path, level: &Path) -> Option<Report> {
    let name = OutputKind::Report.file_name(&names::level_name(level));
    let text = std::fs::read_to_string(out_dir.join(name)).ok()?;
    serde_json::from_str(&text).ok()
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
            let f = *first.entry(names::level_name(p)).or_insert(p);
            (f != p).then(|| f.clone())
        })
        .collect()
}

/// Bakes one level file and writes its outputs: every file is encoded in
/// memory first, then written, the report after every other output and the
/// stamp last.
pub fn bake_one(path: &Path, opts: &BatchOptions, observer: &dyn Observer) -> Result<Report> {
    let t_total = Instant::now();
    if path.is_dir() {
        return Err(Error::NoLevels {
            path: path.to_path_buf(),
        });
    }
    let t = Instant::now();
    let mut palette = Palette::resolve_for_level(path, opts.palette.as_deref())?;
    // A map's own properties or fields beat its palette file's `[bake]`.
    palette.settings = level::map_settings(path)?.over(&palette.settings);
    let level = level::load_level(path, &palette, opts.limits)?;
    // What the stamp and cache record; hashed right after loading.
    let fingerprint = opts.fingerprint();
    let recipe = opts.recipe(path, &fingerprint);
    let inputs = stamp::inputs(&recipe)?;
    let load = t.elapsed().as_secs_f64();

    let texel_bake = bake::bake_texels(
        &level,
        &opts.settings(&palette),
        &opts.texels,
        &|stage| observer.stage(path, stage),
        &|done| observer.fraction(path, "gather", done),
    )
    .map_err(|source| Error::Bake {
        path: path.to_path_buf(),
        source,
    })?;
    // The outputs encode the level at texel resolution; the occluders
    // follow the walls as painted.
    let occluder_geometry = opts
        .occluders
        .map(|_| texel_bake.painted_geometry(&level).into_owned());
    let painted = [level.width, level.height];
    let (baked, level) = (texel_bake.baked, texel_bake.level);
    let mut report = baked.report;
    report.timings.load = load;

    observer.stage(path, "write");
    output::ensure_output_dir(&opts.out_dir)?;
    let exposure = match opts.exposure(&palette) {
        Exposure::Fixed(x) => x,
        Exposure::Auto => exposure::auto_exposure(&level, &baked.lightmap),
    };
    let out_opts = opts.output_options(exposure);
    check_brightness(&level, &baked.lightmap, opts, exposure, &mut report);
    // Writing adds its own time to `write` and `total`.
    report.timings.total = t_total.elapsed().as_secs_f64();
    let start = Instant::now();
    let images = output::encode_images(&level, &baked.lightmap, &out_opts)?;
    let mut extra: Vec<Encoded> = Vec::new();
    if let Some(resp) = baked.responses {
        if opts.layers {
            let emission = output::layers::palette_emission(&level, &resp);
            extra.extend(output::layers::encode_layers(
                &level, &resp, &emission, &out_opts,
            )?);
        }
        if opts.cache {
            let cache = Cache::new(
                &level,
                (painted, opts.texels.density),
                resp,
                &report,
                inputs.image_hash.clone(),
                inputs.key.clone(),
                &out_opts,
            );
            let bytes = cache.to_bytes().map_err(|e| CacheError::Encode {
                path: opts.out_dir.join(OutputKind::Cache.file_name(&level.name)),
                message: e.to_string(),
            })?;
            extra.push(Encoded {
                kind: OutputKind::Cache,
                bytes,
            });
        }
    }
    if let Some(dir) = &baked.directional {
        let normals = match output::directional::normal_map_beside(path) {
            Some(p) => Some(output::directional::NormalMap::read(
                &p,
                painted,
                opts.texels.density,
            )?),
            None => None,
        };
        extra.extend(output::directional::encode_directional(
            &level,
            &baked.lightmap,
            dir,
            normals.as_ref(),
            &out_opts,
        )?);
    }
    if let (Some(tolerance), Some(g)) = (opts.occluders, &occluder_geometry) {
        extra.extend(output::occluders::encode_occluders(
            &level.name,
            g,
            tolerance,
        )?);
    }
    // One transaction: every output staged first (a full disk replaces
    // nothing), the stamp removed before the renames, the new stamp last.
    // Whatever fails in between leaves no stamp: not up to date.
    let dir = &opts.out_dir;
    // Outputs the previous bake wrote (its stamp says which) that this one
    // does not: removed with the old stamp, before the new files go in.
    let writes: Vec<String> = images
        .iter()
        .chain(&extra)
        .map(|f| f.kind.file_name(&level.name))
        .chain([OutputKind::Report, OutputKind::Stamp].map(|k| k.file_name(&level.name)))
        .collect();
    report.removed = stamp::read(path, dir)
        .map(|s| s.outputs)
        .unwrap_or_default()
        .into_iter()
        .filter(|o| OutputKind::is_output_of(o, &level.name) && !writes.contains(o))
        .filter(|o| dir.join(o).is_file())
        .collect();
    let stale = report.removed.clone();
    let written = output::write_level_files(
        dir,
        &level.name,
        &images,
        &extra,
        &mut report,
        start,
        || {
            stamp::invalidate(&recipe, dir)?;
            stale
                .iter()
                .try_for_each(|o| output::remove_output(&dir.join(o)))
        },
    )?;
    stamp::write(&recipe, dir, &inputs, &written)?;
    Ok(report)
}
