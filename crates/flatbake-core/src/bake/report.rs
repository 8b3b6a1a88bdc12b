//! The per-level report (`NAME.report.json`): what happened, for people and
//! scripts — sizes, stage times, solves, the energy balance, what was
//! skipped and why, warnings and the files written.

use serde::{Deserialize, Serialize};

/// Seconds of wall time per stage.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Timings {
    pub load: f64,
    pub geometry: f64,
    pub form_factors: f64,
    pub solve: f64,
    pub gather: f64,
    pub write: f64,
    pub total: f64,
}

/// Sizes of the problem.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Counts {
    pub edges: usize,
    pub patches: usize,
    pub floor_pixels: usize,
    /// Non-zero entries of the form-factor matrix F.
    #[serde(default)]
    pub form_factor_entries: usize,
    /// Floor pixels that no light path reaches (left at 0 without gathering).
    #[serde(default)]
    pub unreached_pixels: usize,
    /// Edge-pixel pairs skipped because they lie beyond the falloff reach.
    #[serde(default)]
    pub culled_pairs: u64,
}

/// Light power per unit time, summed over the three channels. `emitted`
/// equals `absorbed + escaped` up to the solver tolerance for the flatland
/// kernel (escaped includes light lost to falloff).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Energy {
    pub emitted: f64,
    pub absorbed: f64,
    pub escaped: f64,
}

/// One thing the baker decided not to simulate, and why.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Skip {
    pub effect: String,
    pub reason: String,
}

/// The report of one baked level.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Report {
    pub level: String,
    pub size: [usize; 2],
    pub quality: String,
    pub kernel: String,
    pub gather: String,
    pub falloff: Option<f64>,
    pub bounces: Option<u32>,
    pub counts: Counts,
    pub timings: Timings,
    /// Channel solves actually run (0 to 3).
    pub solves: usize,
    /// Largest relative residual `|E - (I - rho F) B| / |E|` over the solves.
    pub residual: f64,
    /// Which solver ran ("none", "cholesky", "cg", "lu", "bounces", ...).
    pub solver: String,
    pub energy: Energy,
    pub skipped: Vec<Skip>,
    pub warnings: Vec<String>,
    /// Files written, relative to the output folder.
    #[serde(default)]
    pub outputs: Vec<String>,
    /// flatbake version that wrote the report.
    #[serde(default)]
    pub version: String,
}

impl Report {
    /// The report of a bake, assembled from what its stages returned.
    pub fn new(
        ctx: &super::Ctx,
        counts: Counts,
        timings: Timings,
        solved: &super::Solved,
        log: super::Log,
    ) -> Report {
        let (level, settings) = (ctx.level, ctx.settings);
        Report {
            level: level.name.clone(),
            size: [level.width, level.height],
            quality: settings.quality.name().into(),
            kernel: match settings.kernel {
                crate::gather::Kernel::Flatland => "flatland".into(),
                crate::gather::Kernel::Paper => "paper".into(),
            },
            gather: settings.gather.name().into(),
            falloff: settings.falloff,
            bounces: settings.bounces,
            counts,
            timings,
            solves: solved.solves,
            residual: solved.residual,
            solver: solved.solver.clone(),
            energy: solved.energy.clone(),
            skipped: log.skipped,
            warnings: log.warnings,
            outputs: vec![],
            version: env!("CARGO_PKG_VERSION").into(),
        }
    }

    /// One-line human summary of what was simulated and what was skipped.
    pub fn summary(&self) -> String {
        let mut parts = vec![format!(
            "{} solve{}",
            self.solves,
            if self.solves == 1 { "" } else { "s" }
        )];
        for s in &self.skipped {
            parts.push(format!("{}: {}", s.effect, s.reason));
        }
        parts.join("; ")
    }
}
