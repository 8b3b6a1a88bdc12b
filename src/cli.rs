//! The command line: flags parsed by clap into raw structs, validated into
//! library options, and the results reported to people.
//!
//! Exit status: 0 when everything asked for succeeded, 1 when at least one
//! level (or other input) failed, 2 when the command line itself is wrong.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Mutex;
use std::time::Duration;

use clap::{Args, Parser, Subcommand};
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};

use flatbake_core::bake::{GatherMethod, Report};
use flatbake_core::batch::{self, BatchOptions, LevelOutcome, Observer, Shard};
use flatbake_core::gather::Kernel;
use flatbake_core::level::LoadLimits;
use flatbake_core::output::{Depth, Engine, Exposure, ExrCompression};
use flatbake_core::quality::Quality;

use crate::flags::{
    FalloffArg, parse_bounces, parse_debounce, parse_depth, parse_falloff, parse_jobs,
    parse_max_pixels, parse_occluder_tolerance, parse_shard,
};

/// Exit status when every level baked.
pub const EXIT_OK: u8 = 0;

/// The most worker threads `--jobs` accepts: far above any core count, far
/// below what takes the system minutes to spawn.
pub const MAX_JOBS: i64 = 512;
/// Exit status when at least one level failed.
pub const EXIT_FAILED: u8 = 1;
/// Exit status for a malformed command line (clap's own convention).
pub const EXIT_USAGE: u8 = 2;

#[derive(Parser, Debug)]
#[command(
    name = "flatbake",
    version,
    about = "Bake 2D radiosity lightmaps for levels painted as bitmaps",
    after_help = "Exit status: 0 all levels baked, 1 at least one level failed, 2 bad command line.\n\
                  Examples for each subcommand: flatbake help SUBCOMMAND (e.g. flatbake help bake)."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Bake levels (image files, or folders of them) into lightmaps.
    #[command(after_help = crate::flags::BAKE_EXAMPLES)]
    Bake(BakeArgs),
    /// Show the palette a level gets (or the built-in one), or write it as a TOML file to start from.
    #[command(after_help = crate::flags::PALETTE_EXAMPLES)]
    Palette(PaletteArgs),
    /// Measure the price of accuracy: bake at every preset, time it, compare to reference.
    #[command(after_help = crate::flags::SWEEP_EXAMPLES)]
    Sweep(SweepArgs),
    /// New lightmaps for new emission from a `bake --cache` file, without baking again.
    #[command(after_help = crate::flags::RELIGHT_EXAMPLES)]
    Relight(RelightArgs),
    /// Bake every level in a folder, then re-bake each level whenever it or its palette is saved.
    #[command(after_help = crate::flags::WATCH_EXAMPLES)]
    Watch(WatchArgs),
}

#[derive(Args, Debug)]
pub struct RelightArgs {
    /// The cache written by `flatbake bake --cache` (NAME.flatbake).
    pub cache: PathBuf,
    /// New emission of an emitter colour: "#rrggbb=R,G,B" or "#rrggbb=X" (repeatable).
    #[arg(long, value_name = "COLOR=R,G,B")]
    pub emission: Vec<String>,
    /// Output folder; never the folder of the level's bake.
    #[arg(short = 'o', long = "out", default_value = "out/relit")]
    pub out: PathBuf,
    /// Refuse the cache unless it was baked from this level as it is now (an
    /// image, a map, or PROJECT.ldtk/LEVEL).
    #[arg(long, value_name = "FILE")]
    pub level: Option<PathBuf>,
    /// Also write the light layers with the new emission.
    #[arg(long)]
    pub layers: bool,
    /// Also write NAME.lightmap.exr.
    #[arg(long)]
    pub hdr: bool,
    /// Also write NAME.lightmap.rgbm-unity.png (Unity's RGBM: range 5, gamma space).
    #[arg(long)]
    pub rgbm_unity: bool,
    /// Also write NAME.lightmap.ktx2 (RGBA 16-bit float KTX2).
    #[arg(long)]
    pub ktx2: bool,
    /// Compression of the EXR outputs: none (flatbake's own encoder), zip or piz.
    #[arg(long, value_enum, value_name = "KIND", default_value_t = ExrCompressionArg::None)]
    pub exr_compression: ExrCompressionArg,
    /// Pad the lightmaps by N texels around the floor, with coverage in alpha (0: off).
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = crate::flags::parse_padding, allow_negative_numbers = true)]
    pub padding: u32,
    /// Print only errors.
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct WatchArgs {
    /// Folder of level images (and their palettes).
    pub dir: PathBuf,
    #[command(flatten)]
    pub output: OutputArgs,
    /// Quiet time after the last save before baking, in milliseconds.
    #[arg(long, value_name = "MS", default_value_t = 300, value_parser = parse_debounce, allow_negative_numbers = true)]
    pub debounce: u64,
    /// Print only errors.
    #[arg(long)]
    pub quiet: bool,
}

/// What to bake and write: the flags `bake` and `watch` share.
#[derive(Args, Debug, Clone)]
pub struct OutputArgs {
    /// Output folder.
    #[arg(short = 'o', long = "out", default_value = "out")]
    pub out: PathBuf,
    /// Accuracy preset: draft (preview while painting), normal (daily), high (shipping), reference (converged).
    #[arg(short, long, value_enum, default_value_t = QualityArg::Normal)]
    pub quality: QualityArg,
    /// Light falloff: half-energy distance in pixels, or none (overrides the palette).
    #[arg(long, value_name = "PIXELS|none", value_parser = parse_falloff, allow_negative_numbers = true)]
    pub falloff: Option<FalloffArg>,
    /// Palette for every level (instead of the lookup beside each level).
    #[arg(long, value_name = "FILE")]
    pub palette: Option<PathBuf>,
    /// Also write NAME.lightmap.exr (linear 32-bit float).
    #[arg(long)]
    pub hdr: bool,
    /// Also write NAME.lightmap.rgbm.png (8-bit RGBM, range 6).
    #[arg(long)]
    pub rgbm: bool,
    /// Also write NAME.lightmap.rgbm-unity.png (Unity's RGBM: range 5, gamma space).
    #[arg(long)]
    pub rgbm_unity: bool,
    /// Also write NAME.lightmap.ktx2 (RGBA 16-bit float KTX2, as Bevy loads it).
    #[arg(long)]
    pub ktx2: bool,
    /// Compression of the EXR outputs: none (flatbake's own encoder; the default unless a preset says), zip or piz.
    #[arg(long, value_enum, value_name = "KIND")]
    pub exr_compression: Option<ExrCompressionArg>,
    /// Engine preset: the lightmap files, encoding and padding that engine imports (see the README).
    #[arg(long, alias = "preset", value_enum, value_name = "ENGINE")]
    pub engine: Option<EngineArg>,
    /// Pad the lightmaps by N texels around the floor (8 covers bilinear and 3 mip levels), with coverage in alpha (0: off).
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = crate::flags::parse_padding, allow_negative_numbers = true)]
    pub padding: u32,
    /// Lightmap texels per painted pixel along each axis: 1/16 to 16 (such as 1/4, 0.5, 2, 4); each texel is the light averaged over its area.
    #[arg(long, value_name = "N", default_value = "1", value_parser = crate::flags::parse_texels_per_pixel, allow_negative_numbers = true)]
    pub texels_per_pixel: flatbake_core::bake::Density,
    /// Quadrature points per texel side for the area average (default 1 up to density 1, 2 above).
    #[arg(long, value_name = "S", value_parser = crate::flags::parse_texel_samples, allow_negative_numbers = true)]
    pub texel_samples: Option<u32>,
    /// What solid texels carry: lit (each exposed wall face its radiosity, the default), glow (emitters only), dark (0).
    #[arg(long, value_enum, value_name = "MODE", default_value_t = WallsArg::Lit)]
    pub walls: WallsArg,
    /// Also write one lightmap per light group (NAME.layer-GROUP.exr/.png, NAME.layers.json).
    #[arg(long)]
    pub layers: bool,
    /// Also write NAME.flatbake, the cache `flatbake relight` reads.
    #[arg(long)]
    pub cache: bool,
    /// Also write the walls as simplified polygons for live lights (NAME.occluders.json/.svg/.tres).
    #[arg(long)]
    pub occluders: bool,
    /// How far (pixels) an occluder outline may stray from the traced walls.
    #[arg(long, value_name = "PX", default_value_t = flatbake_core::output::occluders::DEFAULT_TOLERANCE, value_parser = parse_occluder_tolerance, allow_negative_numbers = true)]
    pub occluder_tolerance: f64,
    /// Also write the directional lightmap: the light's mean and first circular moments (NAME.directional.exr), its dominant direction (NAME.direction.png) and, beside a normal map NAME.normals.png, NAME.lit-normals.png.
    #[arg(long)]
    pub directional: bool,
    /// Bits per channel of the PNG outputs.
    #[arg(long, value_name = "BITS", default_value_t = 8, value_parser = parse_depth, allow_negative_numbers = true)]
    pub depth: u8,
    /// Multiply the PNG lightmaps by this, or "auto": the 99th percentile of the floor's light at 90 % of full scale (overrides the palette).
    #[arg(long, value_name = "X|auto", value_parser = parse_exposure, allow_negative_numbers = true)]
    pub exposure: Option<ExposureArg>,
    /// Worker threads, 1 to 512 (default: all cores).
    #[arg(short, long, value_name = "N", value_parser = parse_jobs, allow_negative_numbers = true)]
    pub jobs: Option<u16>,
    /// Treat warnings as failures (exit status 1), for CI.
    #[arg(long)]
    pub strict: bool,
    /// Also print the technical detail of each level (what the report holds).
    #[arg(long)]
    pub verbose: bool,
}

/// `--exposure`: a factor, or chosen per level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ExposureArg {
    /// Multiply by this.
    Fixed(f64),
    /// Chosen from each level's light.
    Auto,
}

fn parse_exposure(s: &str) -> Result<ExposureArg, String> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(ExposureArg::Auto);
    }
    s.parse::<f64>()
        .map(ExposureArg::Fixed)
        .map_err(|_| format!("the exposure is a number (such as 0.5) or \"auto\", not {s:?}"))
}

#[derive(Args, Debug)]
pub struct SweepArgs {
    /// Level images or folders of level images.
    #[arg(required = true)]
    pub levels: Vec<PathBuf>,
    /// Folder for accuracy.csv, accuracy.md and accuracy.png.
    #[arg(short = 'o', long = "out", default_value = "out/sweep")]
    pub out: PathBuf,
    /// Print only errors.
    #[arg(long)]
    pub quiet: bool,
    /// Worker threads, 1 to 512 (default: all cores).
    #[arg(short, long, value_name = "N", value_parser = parse_jobs, allow_negative_numbers = true)]
    pub jobs: Option<u16>,
}

#[derive(Args, Debug, Clone)]
pub struct BakeArgs {
    /// Level images or folders of level images.
    #[arg(required = true)]
    pub paths: Vec<PathBuf>,
    #[command(flatten)]
    pub output: OutputArgs,
    /// Transport kernel: exact flatland radiosity, or the paper's equations 4-5.
    #[arg(long, value_enum, default_value_t = KernelArg::Flatland)]
    pub kernel: KernelArg,
    /// Floor gather: fast exact visibility, or the paper's naive ray tests (baseline).
    #[arg(long, value_enum, default_value_t = GatherArg::Fast)]
    pub gather: GatherArg,
    /// Truncate the bounce series: 0 = direct light only, at most 1000 (overrides the palette).
    #[arg(long, value_name = "N", value_parser = parse_bounces, allow_negative_numbers = true)]
    pub bounces: Option<u32>,
    /// Refuse images with more pixels than this (checked before decoding).
    #[arg(long, value_name = "N", default_value_t = LoadLimits::default().max_pixels, value_parser = parse_max_pixels, allow_negative_numbers = true)]
    pub max_pixels: u64,
    /// Refuse a level whose estimated peak memory is above SIZE (e.g. 16G, 512M), checked after
    /// tracing its walls; `auto`: the memory the machine has free; `none`: no limit.
    #[arg(long, value_name = "SIZE", default_value = "auto", value_parser = parse_memory)]
    pub max_memory: MemoryLimit,
    /// Print only errors.
    #[arg(long)]
    pub quiet: bool,
    /// Bake levels even when their outputs are up to date.
    #[arg(long)]
    pub force: bool,
    /// Bake only shard K of N (1 <= K <= N): a fixed 1/N of the levels, chosen by a hash of each level's name.
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    pub shard: Option<Shard>,
}

/// `--max-memory`: how much memory one level's bake may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemoryLimit {
    /// What the machine has free when the batch starts.
    Auto,
    /// No limit.
    Unlimited,
    /// This many bytes.
    Bytes(u64),
}

impl MemoryLimit {
    /// The limit in bytes, if any (`Auto` reads the free memory now).
    pub fn bytes(self) -> Option<u64> {
        match self {
            MemoryLimit::Auto => flatbake_core::bake::memory::available(),
            MemoryLimit::Unlimited => None,
            MemoryLimit::Bytes(b) => Some(b),
        }
    }
}

fn parse_memory(s: &str) -> Result<MemoryLimit, String> {
    match s.to_ascii_lowercase().as_str() {
        "auto" => Ok(MemoryLimit::Auto),
        "none" | "off" | "unlimited" => Ok(MemoryLimit::Unlimited),
        _ => flatbake_core::bake::memory::parse_size(s).map(MemoryLimit::Bytes),
    }
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelArg {
    Flatland,
    Paper,
}

/// `--walls`: the library's [`Walls`](flatbake_core::bake::Walls), spelled for clap.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum WallsArg {
    /// Every exposed wall face texel carries its solved radiosity (emission plus reflected light).
    Lit,
    /// Emitter faces carry their emission; other walls 0.
    Glow,
    /// Every solid texel 0.
    Dark,
}

impl From<WallsArg> for flatbake_core::bake::Walls {
    fn from(w: WallsArg) -> Self {
        match w {
            WallsArg::Lit => flatbake_core::bake::Walls::Lit,
            WallsArg::Glow => flatbake_core::bake::Walls::Glow,
            WallsArg::Dark => flatbake_core::bake::Walls::Dark,
        }
    }
}

/// `--engine`: the library's [`Engine`] presets, spelled for clap.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum EngineArg {
    /// Godot 4: linear ZIP EXR, padded 8.
    Godot,
    /// Unity: Unity RGBM (range 5, gamma) and ZIP EXR, padded 8.
    Unity,
    /// Bevy: RGBA16F KTX2 and ZIP EXR, padded 8.
    Bevy,
    /// Any engine: 16-bit PNGs and uncompressed linear EXR, padded 8.
    Generic,
}

/// `--exr-compression`: the library's [`ExrCompression`], spelled for clap.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExrCompressionArg {
    /// Uncompressed (flatbake's own encoder).
    None,
    /// ZIP over 16 scan lines (Godot, Unity and Bevy import it).
    Zip,
    /// PIZ (wavelet and Huffman).
    Piz,
}

impl From<ExrCompressionArg> for ExrCompression {
    fn from(c: ExrCompressionArg) -> ExrCompression {
        match c {
            ExrCompressionArg::None => ExrCompression::None,
            ExrCompressionArg::Zip => ExrCompression::Zip,
            ExrCompressionArg::Piz => ExrCompression::Piz,
        }
    }
}

impl From<EngineArg> for Engine {
    fn from(e: EngineArg) -> Engine {
        match e {
            EngineArg::Godot => Engine::Godot,
            EngineArg::Unity => Engine::Unity,
            EngineArg::Bevy => Engine::Bevy,
            EngineArg::Generic => Engine::Generic,
        }
    }
}

/// `--quality`: the library's [`Quality`], spelled for clap.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum QualityArg {
    /// Preview while painting.
    Draft,
    /// Daily bakes.
    Normal,
    /// Shipping.
    High,
    /// Converged: the yardstick the others are measured against.
    Reference,
}

impl From<QualityArg> for Quality {
    fn from(q: QualityArg) -> Quality {
        match q {
            QualityArg::Draft => Quality::Draft,
            QualityArg::Normal => Quality::Normal,
            QualityArg::High => Quality::High,
            QualityArg::Reference => Quality::Reference,
        }
    }
}

/// `--gather`: the library's [`GatherMethod`], spelled for clap.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum GatherArg {
    /// Exact visible angles, tiled and parallel (the default).
    Fast,
    /// The paper's method: sampled rays per pixel and patch against every edge.
    Naive,
}

impl From<GatherArg> for GatherMethod {
    fn from(g: GatherArg) -> GatherMethod {
        match g {
            GatherArg::Fast => GatherMethod::Fast,
            GatherArg::Naive => GatherMethod::Naive,
        }
    }
}

#[derive(Args, Debug)]
pub struct PaletteArgs {
    /// Level image whose palette to show, found as `bake` finds it (NAME.palette.toml beside it,
    /// else palette.toml in its folder, else the built-in palette).
    #[arg(value_name = "LEVEL")]
    pub level: Option<PathBuf>,
    /// Draw the palette as a labelled legend image.
    #[arg(long, value_name = "FILE.png")]
    pub legend: Option<PathBuf>,
    /// Palette file to show (its colours added to the built-in ones unless it says `builtin = false`).
    #[arg(long, value_name = "FILE")]
    pub palette: Option<PathBuf>,
    /// Write the palette as a commented TOML file to start from: to standard output, or to a new
    /// FILE.toml.
    #[arg(long, value_name = "FILE.toml", num_args = 0..=1, default_missing_value = "-")]
    pub toml: Option<PathBuf>,
}

/// Parses the process arguments and runs; the whole program.
pub fn main() -> ExitCode {
    // A panic inside a level's bake becomes that level's failure (the batch
    // catches it and names the file); say where it happened in one line, for
    // the bug report, instead of the default message and backtrace.
    std::panic::set_hook(Box::new(|info| {
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("flatbake: internal error{at}");
    }));
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { EXIT_USAGE } else { EXIT_OK };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    ExitCode::from(run(cli))
}

/// Runs a parsed command line; returns the exit status.
pub fn run(cli: Cli) -> u8 {
    match cli.command {
        Command::Bake(args) => bake(&args),
        Command::Palette(args) => palette(&args),
        Command::Sweep(args) => sweep(&args),
        Command::Relight(args) => relight(&args),
        Command::Watch(args) => watch(&args),
    }
}

fn sweep(a: &SweepArgs) -> u8 {
    let tty = !a.quiet && std::io::stderr().is_terminal();
    let spinner = if tty {
        ProgressBar::new_spinner()
    } else {
        ProgressBar::hidden()
    };
    spinner.enable_steady_tick(Duration::from_millis(120));
    let result = with_jobs(a.jobs, || {
        let (all, failures) =
            flatbake_core::accuracy::run(&a.levels, &|msg| spinner.set_message(msg.to_string()));
        flatbake_core::accuracy::write_tables(&a.out, &all).map_err(|e| e.to_string())?;
        let png = a.out.join("accuracy.png");
        flatbake_core::output::write_file_atomic(&png, &crate::plot::plot(&all)?)
            .map_err(|e| e.to_string())?;
        if failures.is_empty() {
            Ok(all)
        } else {
            let lines: Vec<String> = failures.iter().map(ToString::to_string).collect();
            Err(lines.join("\n"))
        }
    });
    spinner.finish_and_clear();
    match result {
        Ok(Ok(_)) if a.quiet => EXIT_OK,
        Ok(Ok(all)) => {
            for (level, rows, check) in &all {
                for r in rows {
                    eprintln!(
                        "{level:>14} {:>9}  patch {:>4}  {:>8.3} s  rel. RMS error {:>8.4}%  max {:.2e}",
                        r.quality,
                        r.knobs.patch_len,
                        r.seconds,
                        100.0 * r.rel_rmse,
                        r.max_err
                    );
                }
                eprintln!(
                    "{level:>14} reference check: {:.4}% change when refined",
                    100.0 * check
                );
            }
            eprintln!(
                "flatbake: wrote accuracy.csv, accuracy.md and accuracy.png to {}",
                a.out.display()
            );
            EXIT_OK
        }
        Ok(Err(e)) | Err(e) => {
            eprintln!("flatbake: {e}");
            EXIT_FAILED
        }
    }
}

/// Checks flag values that clap cannot, and builds the library options.
pub fn batch_options(a: &BakeArgs) -> Result<BatchOptions, String> {
    let o = &a.output;
    if let Some(ExposureArg::Fixed(x)) = o.exposure
        && !(x.is_finite() && x > 0.0)
    {
        return Err(format!("--exposure must be a positive number, not {x}"));
    }

    let opts = BatchOptions {
        out_dir: o.out.clone(),
        quality: o.quality.into(),
        falloff: o.falloff.map(FalloffArg::distance),
        kernel: match a.kernel {
            KernelArg::Flatland => Kernel::Flatland,
            KernelArg::Paper => Kernel::Paper,
        },
        gather: a.gather.into(),
        palette: o.palette.clone(),
        bounces: a.bounces,
        exposure: o.exposure.map(|e| match e {
            ExposureArg::Fixed(x) => Exposure::Fixed(x),
            ExposureArg::Auto => Exposure::Auto,
        }),
        hdr: o.hdr,
        depth: if o.depth == 16 {
            Depth::Sixteen
        } else {
            Depth::Eight
        },
        rgbm: o.rgbm,
        rgbm_unity: o.rgbm_unity,
        padding: o.padding,
        ktx2: o.ktx2,
        exr_compression: o.exr_compression.map(Into::into),
        limits: LoadLimits {
            max_pixels: a.max_pixels,
        },
        layers: o.layers,
        cache: o.cache,
        force: a.force,
        max_memory: a.max_memory.bytes(),
        shard: a.shard,
        occluders: o.occluders.then_some(o.occluder_tolerance),
        directional: o.directional,
        texels: flatbake_core::bake::TexelOptions {
            density: o.texels_per_pixel,
            samples: o.texel_samples,
            walls: o.walls.into(),
        },
    };
    if opts.directional && (opts.kernel != Kernel::Flatland || opts.gather != GatherMethod::Fast) {
        return Err(
            "--directional needs the flatland kernel and the fast gather: leave out --kernel paper and --gather naive".into(),
        );
    }
    Ok(match o.engine {
        Some(e) => opts.with_engine(e.into()),
        None => opts,
    })
}

/// Runs `f` on a thread pool of `jobs` threads (all cores when `None`).
pub fn with_jobs<T: Send>(jobs: Option<u16>, f: impl FnOnce() -> T + Send) -> Result<T, String> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(n) = jobs {
        b = b.num_threads(usize::from(n));
    }
    let pool = b
        .build()
        .map_err(|e| format!("cannot start worker threads: {e}"))?;
    Ok(pool.install(f))
}

fn bake(a: &BakeArgs) -> u8 {
    let opts = match batch_options(a) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("flatbake: {e}");
            return EXIT_USAGE;
        }
    };
    let levels = batch::select_levels(&a.paths, &opts).len();
    if !a.quiet {
        crate::shard::announce(&a.paths, &opts, levels);
    }
    let voice = Voice {
        quiet: a.quiet,
        verbose: a.output.verbose,
        strict: a.output.strict,
    };
    let ui = Progress::new(voice, opts.out_dir.clone(), levels);
    let run = match with_jobs(a.output.jobs, || batch::run_batch(&a.paths, &opts, &ui)) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("flatbake: {e}");
            return EXIT_FAILED;
        }
    };
    ui.finish();
    let summary_failed = crate::shard::report_summary(&run.summary);
    let outcomes = run.outcomes;
    let reports: Vec<Option<Report>> = outcomes
        .iter()
        .map(|o| match o {
            LevelOutcome::Baked { report, .. } => Some((**report).clone()),
            LevelOutcome::UpToDate { path } => batch::stored_report(&opts.out_dir, path),
            LevelOutcome::Failed { .. } => None,
        })
        .collect();
    let failed = outcomes
        .iter()
        .filter(|o| matches!(o, LevelOutcome::Failed { .. }))
        .count();
    let current = outcomes
        .iter()
        .filter(|o| matches!(o, LevelOutcome::UpToDate { .. }))
        .count();
    let warned = reports
        .iter()
        .flatten()
        .filter(|r| !r.warnings.is_empty())
        .count();
    if !a.quiet {
        if outcomes.len() > 1 || failed > 0 {
            eprint!("{}", summary_table(&outcomes, &reports, voice.strict));
        }
        let baked = outcomes.len() - failed - current;
        eprintln!(
            "flatbake: {baked} level{} baked into {}, {current} up to date, {failed} failed{}",
            if baked == 1 { "" } else { "s" },
            a.output.out.display(),
            match warned {
                0 => String::new(),
                1 => ", 1 with warnings".to_string(),
                n => format!(", {n} with warnings"),
            }
        );
    }
    if voice.strict && warned > 0 {
        eprintln!(
            "flatbake: --strict: {warned} level{} with warnings count{} as failed",
            if warned == 1 { "" } else { "s" },
            if warned == 1 { "s" } else { "" }
        );
    }
    if failed > 0 || summary_failed || (voice.strict && warned > 0) {
        EXIT_FAILED
    } else {
        EXIT_OK
    }
}

fn relight(a: &RelightArgs) -> u8 {
    let mut emission = Vec::new();
    for e in &a.emission {
        match flatbake_core::batch::relight::parse_emission(e) {
            Ok(v) => emission.push(v),
            Err(msg) => {
                eprintln!("flatbake: {msg}");
                return EXIT_USAGE;
            }
        }
    }
    let opts = flatbake_core::batch::relight::RelightOptions {
        out_dir: a.out.clone(),
        emission,
        level_image: a.level.clone(),
        layers: a.layers,
        hdr: a.hdr,
        padding: a.padding,
        rgbm_unity: a.rgbm_unity,
        ktx2: a.ktx2,
        exr_compression: a.exr_compression.into(),
    };
    match flatbake_core::batch::relight::relight(&a.cache, &opts) {
        Ok(report) => {
            if !a.quiet {
                eprintln!(
                    "relit {} in {:.3} s into {} ({} files)",
                    a.cache.display(),
                    report.timings.total,
                    a.out.display(),
                    report.outputs.len()
                );
            }
            EXIT_OK
        }
        Err(e) => {
            eprintln!("flatbake: {e}");
            EXIT_FAILED
        }
    }
}

fn watch(a: &WatchArgs) -> u8 {
    let bake_args = BakeArgs {
        paths: vec![a.dir.clone()],
        output: a.output.clone(),
        kernel: KernelArg::Flatland,
        gather: GatherArg::Fast,
        bounces: None,
        max_pixels: LoadLimits::default().max_pixels,
        max_memory: MemoryLimit::Auto,
        quiet: a.quiet,
        force: false,
        shard: None,
    };
    let batch = match batch_options(&bake_args) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("flatbake: {e}");
            return EXIT_USAGE;
        }
    };
    let voice = Voice {
        quiet: a.quiet,
        verbose: a.output.verbose,
        strict: a.output.strict,
    };
    let out_dir = batch.out_dir.clone();
    let opts = crate::watch::WatchOptions {
        dir: a.dir.clone(),
        batch,
        debounce: Duration::from_millis(a.debounce),
    };
    let quiet = a.quiet;
    // Every line carries the time it was printed: a designer glancing at
    // the terminal sees whether the last line is from the last save.
    let say = |line: &str| eprintln!("{} {line}", crate::watch::clock());
    // Runs until the process is interrupted (Ctrl-C ends it).
    let stop = std::sync::atomic::AtomicBool::new(false);
    let result = with_jobs(a.output.jobs, || {
        crate::watch::run(&opts, &stop, &mut |ev| match ev {
            crate::watch::WatchEvent::Watching { .. } if quiet => {}
            crate::watch::WatchEvent::Watching { dir } => {
                say(&format!("watching {} (Ctrl-C stops)", dir.display()))
            }
            crate::watch::WatchEvent::WatchError(e) => say(&format!("watch error: {e}")),
            crate::watch::WatchEvent::Level(o) => {
                let stored = match &o {
                    LevelOutcome::UpToDate { path } => batch::stored_report(&out_dir, path),
                    _ => None,
                };
                // Quiet: only errors (and, with --strict, warnings, which are then failures).
                for (line, error) in outcome_lines(&o, stored.as_ref(), voice) {
                    if error || !quiet {
                        say(&line);
                    }
                }
            }
        })
    });
    match result {
        Ok(Ok(())) => EXIT_OK,
        Ok(Err(e)) | Err(e) => {
            eprintln!("flatbake: {e}");
            EXIT_FAILED
        }
    }
}

/// How much the console says about each level.
#[derive(Clone, Copy, Debug)]
struct Voice {
    /// Only errors (and, with `strict`, warnings, which are then failures).
    quiet: bool,
    /// Also the technical detail of the report.
    verbose: bool,
    /// Warnings are failures.
    strict: bool,
}

/// `n thing` or `n things`.
fn count(n: usize, thing: &str) -> String {
    if n == 1 {
        format!("1 {thing}")
    } else {
        format!("{n} {thing}s")
    }
}

/// A fraction as a percentage with one decimal.
fn percent(f: f64) -> String {
    format!("{:.1}%", 100.0 * f)
}

/// The one plain line about a baked level: its time, quality, exposure,
/// warnings, clipping, and what was left out in a designer's words.
fn level_line(path: &Path, r: &Report) -> String {
    let mut parts = vec![if r.warnings.is_empty() {
        "no warnings".to_string()
    } else {
        count(r.warnings.len(), "warning")
    }];
    if r.counts.floor_pixels > 0 {
        parts.push(format!("{} of the floor clipped", percent(r.clipped)));
    }
    if r.exposure_auto {
        parts.push(format!("exposure {} (auto)", r.exposure));
    } else if r.exposure != 1.0 {
        parts.push(format!("exposure {}", r.exposure));
    }
    let mut line = format!(
        "baked {} in {:.2} s ({} quality): {}",
        path.display(),
        r.timings.total,
        r.quality,
        parts.join(", ")
    );
    let skips = r.plain_skips();
    if !skips.is_empty() {
        line.push_str("; left out: ");
        line.push_str(&skips.join(", "));
    }
    if !r.removed.is_empty() {
        line.push_str(&format!(
            "; removed what this bake no longer writes: {}",
            r.removed.join(", ")
        ));
    }
    line
}

/// The report's technical detail, for `--verbose`.
fn detail_lines(r: &Report) -> Vec<String> {
    let t = &r.timings;
    let c = &r.counts;
    vec![
        format!("  detail: {}", r.summary()),
        format!(
            "  size: {}, {}, {} edges, {} patches, {} form-factor entries, solver {}, residual {:.1e}",
            r.size_words(),
            if r.painted_pixels_are_points() && r.counts.floor_texels == c.floor_pixels {
                format!("{} floor pixels", c.floor_pixels)
            } else {
                format!(
                    "{} floor texels, {} floor points",
                    c.floor_texels, c.floor_pixels
                )
            },
            c.edges,
            c.patches,
            c.form_factor_entries,
            r.solver,
            r.residual
        ),
        format!(
            "  seconds: load {:.3}, geometry {:.3}, form factors {:.3}, solve {:.3}, gather {:.3}, write {:.3}",
            t.load, t.geometry, t.form_factors, t.solve, t.gather, t.write
        ),
    ]
}

/// The warning lines of a level: first the problems (a result that looks
/// wrong), then the other warnings.
fn warning_lines(path: &Path, r: &Report) -> Vec<String> {
    let mut out: Vec<String> = r
        .problems
        .iter()
        .map(|p| {
            format!(
                "warning: {}: the result looks wrong ({}): {}",
                path.display(),
                p.kind,
                p.message
            )
        })
        .collect();
    out.extend(
        r.warnings
            .iter()
            .filter(|w| !r.problems.iter().any(|p| &p.message == *w))
            .map(|w| format!("warning: {}: {w}", path.display())),
    );
    out
}

/// What the console says about one finished level, line by line, each with
/// whether it is an error (printed even when quiet). `stored` is the report
/// of an up-to-date level's last bake.
fn outcome_lines(o: &LevelOutcome, stored: Option<&Report>, voice: Voice) -> Vec<(String, bool)> {
    let mut out = Vec::new();
    match o {
        LevelOutcome::Baked { path, report } => {
            out.push((level_line(path, report), false));
            if voice.verbose {
                out.extend(detail_lines(report).into_iter().map(|l| (l, false)));
            }
            // Warnings are for people: shown by default, and failures
            // (so printed even when quiet) with --strict.
            out.extend(
                warning_lines(path, report)
                    .into_iter()
                    .map(|l| (l, voice.strict)),
            );
            if voice.strict && !report.warnings.is_empty() {
                out.push((strict_line(path, report.warnings.len()), true));
            }
        }
        LevelOutcome::Failed { error, .. } => out.push((format!("error: {error}"), true)),
        LevelOutcome::UpToDate { path } => {
            let warned = stored.map_or(0, |r| r.warnings.len());
            let last = if warned > 0 {
                format!("; its last bake had {}", count(warned, "warning"))
            } else {
                String::new()
            };
            out.push((
                format!(
                    "up to date: {} (same image, palette and settings; --force bakes it again){last}",
                    path.display()
                ),
                false,
            ));
            if voice.strict
                && let Some(r) = stored
                && warned > 0
            {
                out.extend(warning_lines(path, r).into_iter().map(|l| (l, true)));
                out.push((strict_line(path, warned), true));
            }
        }
    }
    out
}

fn strict_line(path: &Path, warnings: usize) -> String {
    format!(
        "error: {}: {} and --strict makes warnings failures",
        path.display(),
        count(warnings, "warning")
    )
}

/// The table printed at the end of a batch: one row per level with its
/// size, time, warnings, clipped floor and status.
fn summary_table(outcomes: &[LevelOutcome], reports: &[Option<Report>], strict: bool) -> String {
    let mut rows = vec![[
        "level".to_string(),
        "size".to_string(),
        "time".to_string(),
        "warnings".to_string(),
        "clipped".to_string(),
        "status".to_string(),
    ]];
    for (o, r) in outcomes.iter().zip(reports) {
        let dash = || "-".to_string();
        let status = match (o, r) {
            (LevelOutcome::Failed { .. }, _) => "failed".to_string(),
            (LevelOutcome::UpToDate { .. }, _) => "up to date".to_string(),
            (_, Some(r)) if !r.problems.is_empty() => {
                let kinds: Vec<&str> = r.problems.iter().map(|p| p.kind.as_str()).collect();
                format!("looks wrong: {}", kinds.join(", "))
            }
            (_, Some(r)) if !r.warnings.is_empty() => "baked, with warnings".to_string(),
            _ => "ok".to_string(),
        };
        let status = match r {
            Some(r) if strict && !r.warnings.is_empty() => format!("failed (--strict): {status}"),
            _ => status,
        };
        rows.push(match r {
            Some(r) => [
                o.path().display().to_string(),
                format!("{}x{}", r.size[0], r.size[1]),
                match o {
                    LevelOutcome::Baked { .. } => format!("{:.2} s", r.timings.total),
                    _ => dash(),
                },
                r.warnings.len().to_string(),
                if r.counts.floor_pixels > 0 {
                    percent(r.clipped)
                } else {
                    dash()
                },
                status,
            ],
            None => [
                o.path().display().to_string(),
                dash(),
                dash(),
                dash(),
                dash(),
                status,
            ],
        });
    }
    let widths: Vec<usize> = (0..6)
        .map(|c| rows.iter().map(|r| r[c].chars().count()).max().unwrap_or(0))
        .collect();
    let mut out = String::new();
    for row in &rows {
        let mut line = String::new();
        for (c, cell) in row.iter().enumerate() {
            let w = widths[c];
            // Names and status read left to right; numbers line up on the right.
            let cell = match c {
                0 | 5 => format!("{cell:<w$}"),
                _ => format!("{cell:>w$}"),
            };
            line.push_str(&cell);
            line.push_str("  ");
        }
        out.push_str(line.trim_end());
        out.push('\n');
    }
    out
}

fn palette(a: &PaletteArgs) -> u8 {
    use flatbake_core::level::palette::Palette;
    if let Some(level) = &a.level {
        // A typo must not show the built-in palette as if it were the level's.
        match std::fs::metadata(level) {
            Ok(m) if m.is_dir() => {
                eprintln!(
                    "flatbake: {}: is a folder; name one level image (each level may have its own palette)",
                    level.display()
                );
                return EXIT_FAILED;
            }
            Ok(_) => {}
            Err(e) => {
                let why = match e.kind() {
                    std::io::ErrorKind::NotFound => "file not found".to_string(),
                    _ => format!("cannot read it: {e}"),
                };
                eprintln!("flatbake: {}: {why}", level.display());
                return EXIT_FAILED;
            }
        }
    }
    let resolved = match &a.level {
        Some(level) => Palette::resolve_for_level(level, a.palette.as_deref()),
        None => match &a.palette {
            Some(p) => Palette::load(p),
            None => Ok(Palette::builtin()),
        },
    };
    let pal = match resolved {
        Ok(p) => p,
        Err(e) => {
            eprintln!("flatbake: {e}");
            return EXIT_FAILED;
        }
    };
    let mut status = EXIT_OK;
    match a.toml.as_deref() {
        Some(path) if path == Path::new("-") => print!("{}", pal.to_toml()),
        Some(path) => {
            if let Err(why) = write_palette_toml(path, &pal) {
                eprintln!("flatbake: {}: {why}", path.display());
                return EXIT_FAILED;
            }
            eprintln!("flatbake: wrote the palette to {}", path.display());
        }
        None => {}
    }
    if let Some(path) = &a.legend {
        status = match crate::legend::legend_png(&pal) {
            Ok(bytes) => match flatbake_core::output::write_atomic(path, &bytes) {
                Ok(()) => {
                    eprintln!("flatbake: wrote the palette legend to {}", path.display());
                    EXIT_OK
                }
                Err(e) => {
                    eprintln!("flatbake: cannot write {}: {e}", path.display());
                    EXIT_FAILED
                }
            },
            Err(e) => {
                eprintln!("flatbake: cannot draw the legend: {e}");
                EXIT_FAILED
            }
        };
    }
    if a.toml.is_none() && a.legend.is_none() {
        if let Some(level) = &a.level {
            println!("palette of {}:", level.display());
        }
        print!("{}", pal.table());
    }
    status
}

/// Writes `--toml FILE`: only to a new `.toml` file, so that a level image
/// named after `--toml` by mistake, or a palette someone edited, is never
/// overwritten.
fn write_palette_toml(
    path: &Path,
    pal: &flatbake_core::level::palette::Palette,
) -> Result<(), String> {
    if path.extension().and_then(|e| e.to_str()) != Some("toml") {
        return Err(
            "--toml writes a .toml file; name one ending in .toml (a level to show goes before --toml)"
                .to_string(),
        );
    }
    match std::fs::symlink_metadata(path) {
        Ok(_) => {
            return Err(
                "already exists; not overwritten (remove it first, or give --toml alone to print to standard output)"
                    .to_string(),
            );
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(format!("cannot check it: {e}")),
    }
    flatbake_core::output::write_atomic(path, pal.to_toml().as_bytes())
        .map_err(|e| format!("cannot write it: {e}"))
}

/// Progress on a terminal: one bar for the batch and one line per level
/// being baked, a spinner with its stage, and during the gather a bar with
/// the percentage done and the time left; finished levels print their lines
/// above the bars. When standard error is not a terminal nothing is drawn,
/// only the lines. Lines are printed whole, never interleaved, whatever the
/// thread count.
struct Progress {
    voice: Voice,
    out_dir: PathBuf,
    multi: MultiProgress,
    total: ProgressBar,
    spinners: Mutex<Vec<(PathBuf, ProgressBar)>>,
}

/// The look of a level's line while a stage without a known length runs.
fn spinner_style() -> ProgressStyle {
    ProgressStyle::with_template("  {spinner} {msg} {elapsed}")
        .unwrap_or_else(|_| ProgressStyle::default_spinner())
}

/// The look of a level's line while the gather reports how far it is.
fn gather_style() -> ProgressStyle {
    ProgressStyle::with_template("  {msg} {bar:24.cyan/blue} {percent:>3}%  {eta} left")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
}

impl Progress {
    fn new(voice: Voice, out_dir: PathBuf, levels: usize) -> Progress {
        let draw = if voice.quiet || !std::io::stderr().is_terminal() {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr()
        };
        let multi = MultiProgress::with_draw_target(draw);
        let total = multi.add(ProgressBar::new(levels as u64));
        total.set_style(
            ProgressStyle::with_template("{bar:30.cyan/blue} {pos}/{len} levels {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Progress {
            voice,
            out_dir,
            multi,
            total,
            spinners: Mutex::new(Vec::new()),
        }
    }

    fn println(&self, line: String, error: bool) {
        if self.multi.is_hidden() {
            if error || !self.voice.quiet {
                eprintln!("{line}");
            }
        } else {
            let _ = self.multi.println(line);
        }
    }

    fn finish(&self) {
        self.total.finish_and_clear();
    }

    /// Runs `f` on the progress line of level `path`, if it has one.
    fn with_line(&self, path: &Path, f: impl FnOnce(&ProgressBar)) {
        if let Ok(v) = self.spinners.lock()
            && let Some((_, sp)) = v.iter().find(|(p, _)| p == path)
        {
            f(sp);
        }
    }
}

impl Observer for Progress {
    fn waiting_for_folder(&self, dir: &Path) {
        self.println(
            format!(
                "flatbake: {} is being written by another flatbake; waiting for it to finish",
                dir.display()
            ),
            false,
        );
    }

    fn level_started(&self, path: &Path) {
        if self.multi.is_hidden() {
            return;
        }
        let sp = self
            .multi
            .insert_before(&self.total, ProgressBar::new_spinner());
        sp.set_style(spinner_style());
        sp.set_message(format!("{}: loading", display_name(path)));
        sp.enable_steady_tick(Duration::from_millis(120));
        if let Ok(mut v) = self.spinners.lock() {
            v.push((path.to_path_buf(), sp));
        }
    }

    fn stage(&self, path: &Path, stage: &str) {
        self.with_line(path, |sp| {
            if sp.length().is_some() {
                sp.unset_length();
                sp.set_style(spinner_style());
            }
            sp.set_message(format!("{}: {stage}", display_name(path)));
        });
    }

    fn fraction(&self, path: &Path, _stage: &str, done: f64) {
        self.with_line(path, |sp| {
            if sp.length().is_none() {
                sp.set_style(gather_style());
                sp.set_length(1000);
                sp.reset_eta();
            }
            sp.set_position((done.clamp(0.0, 1.0) * 1000.0) as u64);
        });
    }

    fn level_done(&self, outcome: &LevelOutcome) {
        if let Ok(mut v) = self.spinners.lock()
            && let Some(i) = v.iter().position(|(p, _)| p == outcome.path())
        {
            let (_, sp) = v.swap_remove(i);
            sp.finish_and_clear();
            self.multi.remove(&sp);
        }
        self.total.inc(1);
        let stored = match outcome {
            LevelOutcome::UpToDate { path } => batch::stored_report(&self.out_dir, path),
            _ => None,
        };
        for (line, error) in outcome_lines(outcome, stored.as_ref(), self.voice) {
            self.println(line, error);
        }
    }
}

fn display_name(p: &Path) -> String {
    p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}
