//! Baking one resolved level: the pipeline as a list of stages.
//!
//! [`bake`] calls one stage after another, each taking the types the ones
//! before produced and returning the next:
//!
//! 1. [`Scene::new`] — the resolved [`Level`] traced into edges and patches,
//!    materials read out per patch ([`scene`]);
//! 2. [`Plan::new`] — what the scene calls for: which channels to solve,
//!    whether any bounce, which per-emitter responses ([`plan`]);
//! 3. [`factors::form_factors`] — F between patches, when a bounce is to be
//!    solved ([`factors`]);
//! 4. [`radiosity::solve`] — radiosity per channel class and per emitter,
//!    and the energy balance ([`radiosity`]);
//! 5. [`light::gather`] — the light of every floor pixel ([`light`]);
//! 6. [`lightmap::assemble`] — the [`Lightmap`] and the [`Responses`]
//!    ([`lightmap`]);
//!
//! and the [`Report`] is put together once, in memory, from what the
//! stages returned. Writing files is not part of a bake: see
//! [`crate::output`] and [`crate::batch`].
//!
//! Every stage that leaves something out records it in the report's
//! `skipped` list with the reason, so the report says what was not
//! simulated and why.

pub mod checks;
pub mod directional;
pub mod factors;
pub mod light;
pub mod lightmap;
pub mod memory;
pub mod plan;
pub mod radiosity;
pub mod report;
pub mod responses;
pub mod scene;
pub mod texels;

use std::time::Instant;

pub use directional::Directional;
pub use factors::{ReachPasses, Transport};
pub use light::Gathered;
pub use lightmap::Lightmap;
pub use memory::MemoryEstimate;
pub use plan::{ChannelPlan, Plan, ResponsePlan, plan_channels};
pub use radiosity::{Solved, energy_balance};
pub use report::{Counts, Energy, Problem, Report, Skip, Timings};
pub use responses::Responses;
pub use scene::Scene;
pub use texels::{Density, TexelBake, TexelOptions, Walls, bake_texels};

use crate::gather::Kernel;
use crate::geometry::Geometry;
use crate::level::Level;
use crate::quality::{Knobs, Quality};
use crate::transport::kernel::Falloff;
use crate::transport::solve::SolveError;
use crate::transport::{FormFactors, Patches};
use crate::visibility::Structures;

/// The most bounces a truncated series may have (`--bounces`, a palette's
/// `[bake] bounces`). Each costs one pass over the form factors, and by a
/// thousand bounces even reflectance 0.99 has converged to 4e-5: for more,
/// leave `bounces` out and get the full solve.
pub const MAX_BOUNCES: u32 = 1000;

/// How the floor gather is done.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GatherMethod {
    /// Exact visible angles, tiled and parallel (the default).
    Fast,
    /// The paper's method: sampled rays per pixel and patch against every edge.
    Naive,
}

impl GatherMethod {
    /// The method's name, as the report spells it.
    pub fn name(self) -> &'static str {
        match self {
            GatherMethod::Fast => "fast",
            GatherMethod::Naive => "naive",
        }
    }
}

/// Everything that decides what a bake computes.
#[derive(Clone, Debug)]
pub struct Settings {
    /// The preset, as the report names it.
    pub quality: Quality,
    /// The discretisation; normally `quality.knobs()`.
    pub knobs: Knobs,
    /// Half-energy distance in pixels; `None` for no falloff.
    pub falloff: Option<f64>,
    /// The transport kernel. Default: flatland.
    pub kernel: Kernel,
    /// The floor gather. Default: fast.
    pub gather: GatherMethod,
    /// Truncate the bounce series (0 = direct light only), at most
    /// [`MAX_BOUNCES`]. Default: none.
    pub bounces: Option<u32>,
    /// Sample points per patch for the naive gather. Default 8.
    pub naive_samples: usize,
    /// Also compute the light of each emitter material on its own
    /// ([`Responses`]), for light layers and the relight cache. Default off.
    pub responses: bool,
    /// Skip nothing: solve every channel on its own, solve the bounce even
    /// where nothing reflects or sees light, gather every floor region and
    /// cull no faint pairs. The full computation that every skip is tested
    /// against; results agree with the default up to each skip's bound.
    pub exhaustive: bool,
    /// Refuse the bake, before its form factors, when its estimated peak
    /// memory ([`MemoryEstimate`]) is above this many bytes. Default: no
    /// limit (the command line passes the memory the machine has free).
    pub max_memory: Option<u64>,
    /// Run the form factors in [`ReachPasses`] when the memory estimate
    /// counts at least this many entries at a unit of radiosity (and there
    /// is falloff). Default [`ReachPasses::FROM_ENTRIES`]; 0 always, with
    /// falloff; `u64::MAX` never.
    pub reach_passes_from: u64,
    /// Also compute the first circular moments of every floor pixel's light
    /// ([`Directional`]), for normal-mapped sprites. The flatland kernel and
    /// the fast gather only. Default off; off costs nothing.
    pub directional: bool,
    /// Bake pixels per painted pixel: 1, or the upscale factor of a texel
    /// bake ([`texels`]), which sizes visibility's blocks in painted pixels.
    pub unit: usize,
    /// Return the form factors in [`Baked::form_factors`]. Off, they are
    /// freed once the radiosity is solved, before the floor gather, which
    /// then does not hold them (the command line: at 640 px of one-pixel
    /// dots that is 4.6 GB for the two and a half minutes of the gather).
    /// Default on; outputs do not depend on it.
    pub keep_form_factors: bool,
}

impl Settings {
    /// The defaults for a preset.
    pub fn new(quality: Quality) -> Settings {
        Settings {
            quality,
            knobs: quality.knobs(),
            falloff: None,
            kernel: Kernel::Flatland,
            gather: GatherMethod::Fast,
            bounces: None,
            naive_samples: 8,
            responses: false,
            exhaustive: false,
            max_memory: None,
            reach_passes_from: ReachPasses::FROM_ENTRIES,
            directional: false,
            unit: 1,
            keep_form_factors: true,
        }
    }
}

/// Why a level could not be baked.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// A closed region of perfect mirrors holds an emitter: its radiosity
    /// has no finite value.
    #[error("{}{region}", if *.light_layers { "light layers: " } else { "" })]
    Unbounded {
        /// Where the region is, and in which channel.
        region: UnboundedRegion,
        /// Found while tracing the per-emitter light of layers or caches.
        light_layers: bool,
    },
    /// The solver could not find the radiosity.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The bake would need more memory than it may use.
    #[error(
        "needs an estimated {} of memory at its peak ({} pixels, ~{:.1e} form-factor entries), more than the {} allowed (--max-memory; by default the memory this machine has free); bake it on a machine with more memory, or raise the limit with --max-memory {} if that much is free",
        memory::human_bytes(.estimate.bytes),
        .estimate.pixels,
        .estimate.factor_entries as f64,
        memory::human_bytes(*.limit),
        memory::flag_value_for(.estimate.bytes)
    )]
    TooMuchMemory {
        /// The estimate.
        estimate: MemoryEstimate,
        /// The limit it is over, in bytes.
        limit: u64,
    },
    /// A stage found an inconsistency between the stages before it: a bug,
    /// reported instead of a panic.
    #[error("internal error: {0} (please report this level)")]
    Internal(&'static str),
    /// Settings that do not go together.
    #[error("{0}")]
    Unsupported(&'static str),
}

/// The pixels of a closed region whose walls reflect everything, and the
/// channel in which they do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnboundedRegion {
    /// Smallest x of the region's edges.
    pub x0: i32,
    /// Smallest y.
    pub y0: i32,
    /// Largest x.
    pub x1: i32,
    /// Largest y.
    pub y1: i32,
    /// "red", "green" or "blue".
    pub channel: &'static str,
}

impl UnboundedRegion {
    /// The bounding box of patches `ps` of `scene`.
    pub fn of(scene: &Scene, ps: &[usize], channel: &'static str) -> UnboundedRegion {
        let (mut x0, mut y0, mut x1, mut y1) = (i32::MAX, i32::MAX, i32::MIN, i32::MIN);
        for &p in ps {
            let e = &scene.geometry.edges[scene.patches.edge[p] as usize];
            for q in [e.a, e.b] {
                x0 = x0.min(q[0]);
                y0 = y0.min(q[1]);
                x1 = x1.max(q[0]);
                y1 = y1.max(q[1]);
            }
        }
        UnboundedRegion {
            x0,
            y0,
            x1,
            y1,
            channel,
        }
    }
}

impl std::fmt::Display for UnboundedRegion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let UnboundedRegion {
            x0,
            y0,
            x1,
            y1,
            channel,
        } = self;
        write!(
            f,
            "the closed region within pixels ({x0},{y0})-({x1},{y1}) has walls of reflectance 1 in the {channel} channel and contains an emitter: no light can leave, so its brightness has no finite value; lower a reflectance below 1 or open the region"
        )
    }
}

/// A baked level, with the intermediate results callers may want to keep.
pub struct Baked {
    /// The traced walls.
    pub geometry: Geometry,
    /// The patches the radiosity lives on.
    pub patches: Patches,
    /// The flatland kernel's form factors, when a bounce was solved and
    /// [`Settings::keep_form_factors`] asked for them.
    pub form_factors: Option<FormFactors>,
    /// Radiosity per channel (R, G, B) per patch.
    pub radiosity: [Vec<f64>; 3],
    /// Linear light per pixel.
    pub lightmap: Lightmap,
    /// What was computed, skipped and measured.
    pub report: Report,
    /// Per-emitter light, when [`Settings::responses`] asked for it.
    pub responses: Option<Responses>,
    /// The light's first circular moments, when [`Settings::directional`]
    /// asked for them.
    pub directional: Option<Directional>,
}

/// What every stage of one bake reads: the level, the settings and what
/// follows from them.
pub struct Ctx<'a> {
    /// The level being baked.
    pub level: &'a Level,
    /// How it is baked.
    pub settings: &'a Settings,
    /// The falloff, if any.
    pub falloff: Option<Falloff>,
    /// The preset's reach bound; 0 for an exhaustive bake, which culls no
    /// faint pairs.
    pub reach_bound: f64,
    /// Told the fraction of the floor gathered so far, from worker threads.
    pub gather_progress: Option<&'a (dyn Fn(f64) + Sync)>,
}

impl<'a> Ctx<'a> {
    /// The context of baking `level` with `settings`.
    pub fn new(level: &'a Level, settings: &'a Settings) -> Ctx<'a> {
        Ctx {
            level,
            settings,
            falloff: settings.falloff.map(Falloff::new),
            reach_bound: if settings.exhaustive {
                0.0
            } else {
                settings.knobs.reach_bound
            },
            gather_progress: None,
        }
    }
}

/// What the stages left out and what they warn about, in report order.
#[derive(Clone, Debug, Default)]
pub struct Log {
    /// Effects not simulated, with the reason.
    pub skipped: Vec<Skip>,
    /// Problems worth telling the user that do not stop the bake.
    pub warnings: Vec<String>,
    /// The warnings that mean the result is probably not what was meant.
    pub problems: Vec<Problem>,
}

impl Log {
    /// Records that `effect` was not simulated, and why.
    pub fn skip(&mut self, effect: impl Into<String>, reason: impl Into<String>) {
        self.skipped.push(Skip {
            effect: effect.into(),
            reason: reason.into(),
        });
    }

    /// Records a warning.
    pub fn warn(&mut self, warning: impl Into<String>) {
        self.warnings.push(warning.into());
    }

    /// Records a result that is probably not what was meant: among the
    /// problems, and its message among the warnings.
    pub fn problem(&mut self, kind: &str, message: impl Into<String>) {
        let message = message.into();
        self.warnings.push(message.clone());
        self.problems.push(Problem {
            kind: kind.into(),
            message,
        });
    }
}

/// Bakes a level. `progress(stage)` is called as each stage starts
/// ("geometry", "form factors", "solve", "gather").
pub fn bake(
    level: &Level,
    settings: &Settings,
    progress: &dyn Fn(&str),
) -> Result<Baked, BakeError> {
    bake_with_progress(level, settings, progress, &|_| {})
}

/// [`bake`], also telling `gathered(fraction)` how much of the floor the
/// gather, usually the longest stage, has done: from worker threads, once
/// per tile of pixels at most and only when the fraction has grown by a
/// thousandth, so that reporting costs the gather nothing measurable.
pub fn bake_with_progress(
    level: &Level,
    settings: &Settings,
    progress: &dyn Fn(&str),
    gathered: &(dyn Fn(f64) + Sync),
) -> Result<Baked, BakeError> {
    let t_total = Instant::now();
    if settings.directional
        && (settings.kernel != Kernel::Flatland || settings.gather != GatherMethod::Fast)
    {
        return Err(BakeError::Unsupported(
            "directional lightmaps need the flatland kernel and the fast gather (leave out --kernel paper and --gather naive)",
        ));
    }
    let mut ctx = Ctx::new(level, settings);
    ctx.gather_progress = Some(gathered);
    let mut timings = Timings::default();
    let mut log = Log {
        warnings: level.warnings.clone(),
        ..Log::default()
    };
    let timed = |seconds: &mut f64, t: Instant| *seconds = t.elapsed().as_secs_f64();

    progress("geometry");
    let t = Instant::now();
    let mut scene = Scene::new(level, &settings.knobs, settings.exhaustive);
    scene.geometry.unit = settings.unit.max(1);
    timed(&mut timings.geometry, t);

    let mut plan = Plan::new(&ctx, &scene, &mut log);
    // The estimate's sample of the form factors' points and the form
    // factors query through the same structures: built once.
    let structures = Structures::new(&scene.geometry);
    if plan.needs_form_factors() {
        structures.prepare(false);
    }
    let memory = MemoryEstimate::new(&ctx, &scene, &plan, &structures);
    if let Some(limit) = settings.max_memory
        && memory.bytes > limit
    {
        return Err(BakeError::TooMuchMemory {
            estimate: memory,
            limit,
        });
    }

    // Under falloff, the form factors' reach follows each edge's solved
    // light, found in passes of form factors and solve (each with its own
    // plan and log: the pass that stands keeps them).
    let mut passes = plan
        .needs_form_factors()
        .then(|| ReachPasses::new(&ctx, &scene, memory.factor_entries))
        .flatten();
    let (mut transport, solved) = loop {
        let (mut pass_plan, mut pass_log) = (plan.clone(), log.clone());
        let transport = if pass_plan.needs_form_factors() {
            progress("form factors");
            let t = Instant::now();
            let transport = factors::form_factors(
                &ctx,
                &scene,
                &mut pass_plan,
                &structures,
                passes.as_ref(),
                &mut pass_log,
            );
            timings.form_factors += t.elapsed().as_secs_f64();
            transport
        } else {
            Transport::default()
        };
        progress("solve");
        let t = Instant::now();
        let solved = radiosity::solve(&ctx, &scene, &pass_plan, &transport, &mut pass_log)?;
        timings.solve += t.elapsed().as_secs_f64();
        let again = passes.as_mut().is_some_and(|p| {
            let need = light::relative_radiosity(&ctx, &scene, &pass_plan, &transport, &solved);
            p.next(&ctx, &scene, &structures, &need)
        });
        if !again {
            (plan, log) = (pass_plan, pass_log);
            break (transport, solved);
        }
    };
    if let Some(p) = &passes {
        log.skip(
            "form-factor reach",
            if p.at_unit_radiosity() {
                format!(
                    "an estimate of each edge's light found that following it would save little: the form factors reach as far as a unit of radiosity ({} passes of form factors and solve)",
                    p.passes
                )
            } else {
                format!(
                    "each edge's form factors reach as far as its solved light calls for, found in {} passes of form factors and solve",
                    p.passes
                )
            },
        );
    }
    // The gather builds its own (for pixel centres), after the solve.
    drop(structures);

    let form_factor_entries = transport.entries();
    if !settings.keep_form_factors {
        transport.form_factors = None;
    }

    progress("gather");
    let t = Instant::now();
    let gathered = light::gather(&ctx, &scene, &plan, &mut transport, &solved, &mut log);
    let mut assembled = lightmap::assemble(&ctx, &scene, &plan, &solved, &gathered);
    // With responses the lightmap is their sum (so that layers add up to
    // it), and so are the moments.
    let directional = match &assembled.responses {
        Some(r) if settings.directional => {
            let e: Vec<[f64; 3]> = r
                .emitters
                .iter()
                .map(|&m| level.materials[m].emission)
                .collect();
            r.combine_moments(&e)
                .or_else(|| directional::assemble(level.width, level.height, &plan, &gathered))
        }
        _ => directional::assemble(level.width, level.height, &plan, &gathered),
    };
    timed(&mut timings.gather, t);
    timed(&mut timings.total, t_total);
    let allowed = light::approximation_bound(&ctx, &scene);
    lightmap::clamp(&mut assembled.lightmap, allowed, &mut log);
    checks::lightmap(level, &assembled.lightmap.rgb, &mut log);

    let counts = Counts {
        edges: scene.geometry.edges.len(),
        patches: scene.patch_count(),
        floor_pixels: scene.floor_pixels.len(),
        floor_texels: scene.floor_pixels.len(),
        form_factor_entries,
        unreached_pixels: gathered.unreached,
        culled_pairs: transport.culled_pairs + gathered.culled_pairs,
        memory_estimate: memory.bytes,
    };
    let report = Report::new(&ctx, counts, timings, &solved, log);
    Ok(Baked {
        geometry: scene.geometry,
        patches: scene.patches,
        form_factors: transport.form_factors,
        radiosity: assembled.radiosity,
        lightmap: assembled.lightmap,
        report,
        responses: assembled.responses,
        directional,
    })
}
