//! The per-level report (`NAME.report.json`): what happened, for people and
//! scripts — sizes, stage times, solves, the energy balance, what was
//! skipped and why, warnings and the files written.

use serde::{Deserialize, Serialize};

fn one() -> f64 {
    1.0
}

/// Seconds of wall time per stage.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Timings {
    /// Reading the image and palette, and hashing the inputs.
    pub load: f64,
    /// Tracing the walls and cutting patches.
    pub geometry: f64,
    /// The form factors between patches.
    pub form_factors: f64,
    /// The channel solves.
    pub solve: f64,
    /// The floor gather and the lightmap's assembly.
    pub gather: f64,
    /// Encoding and writing the output files.
    pub write: f64,
    /// The whole level, writing included.
    pub total: f64,
}

/// Sizes of the problem.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Counts {
    /// Transport edges (merged runs of one material facing free space).
    pub edges: usize,
    /// Patches the edges are cut into.
    pub patches: usize,
    /// Floor pixels, lit or not.
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
    /// The bake's estimated peak memory in bytes, checked against
    /// `--max-memory` before the form factors.
    #[serde(default)]
    pub memory_estimate: u64,
}

/// Light power per unit time, summed over the three channels. `emitted`
/// equals `absorbed + escaped` up to the solver tolerance for the flatland
/// kernel (escaped includes light lost to falloff).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Energy {
    /// Power emitted by every emitter.
    pub emitted: f64,
    /// Power absorbed by walls.
    pub absorbed: f64,
    /// Power leaving the level (out of the image, into void, or lost to falloff).
    pub escaped: f64,
}

/// One thing the baker decided not to simulate, and why.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Skip {
    /// The effect left out ("bounce", "red channel", "falloff reach", ...).
    pub effect: String,
    /// Why it could be left out, and what that costs.
    pub reason: String,
}

/// A result that looks like success but is probably not what was meant:
/// no floor, nothing that gives light, a black lightmap, or a mostly
/// clipped one. Its message, with the likely cause, is also among the
/// report's warnings.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Problem {
    /// What is wrong, in two or three words: "no floor", "no light",
    /// "black" or "clipped".
    pub kind: String,
    /// What is wrong, the likely cause and what to do.
    pub message: String,
}

/// The report of one baked level.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Report {
    /// The level's name (its image's file stem).
    pub level: String,
    /// Width and height in pixels.
    pub size: [usize; 2],
    /// The quality preset.
    pub quality: String,
    /// The transport kernel ("flatland" or "paper").
    pub kernel: String,
    /// The floor gather ("fast" or "naive").
    pub gather: String,
    /// Half-energy distance of the falloff in pixels; `null` for none.
    pub falloff: Option<f64>,
    /// The bounce series' truncation; `null` for the full solve.
    pub bounces: Option<u32>,
    /// The exposure the PNG lightmaps were encoded with (1 for a bake in
    /// memory, which encodes nothing).
    #[serde(default = "one")]
    pub exposure: f64,
    /// Whether `exposure` was chosen from the lightmap (`--exposure auto`).
    #[serde(default)]
    pub exposure_auto: bool,
    /// Fraction of the floor pixels whose PNG lightmap value is at full
    /// scale (255 in 8 bits) in some channel: light brighter than the image
    /// can show.
    #[serde(default)]
    pub clipped: f64,
    /// Sizes of the problem.
    pub counts: Counts,
    /// Seconds per stage.
    pub timings: Timings,
    /// Channel solves actually run (0 to 3).
    pub solves: usize,
    /// Largest relative residual `|E - (I - rho F) B| / |E|` over the solves.
    pub residual: f64,
    /// Which solver ran ("none", "cholesky", "cg", "lu", "bounces", ...).
    pub solver: String,
    /// Power emitted, absorbed and escaped.
    pub energy: Energy,
    /// What was not simulated, and why.
    pub skipped: Vec<Skip>,
    /// Problems worth telling the user that did not stop the bake.
    pub warnings: Vec<String>,
    /// The warnings that mean the result is probably not what was meant.
    #[serde(default)]
    pub problems: Vec<Problem>,
    /// Files written, relative to the output folder.
    #[serde(default)]
    pub outputs: Vec<String>,
    /// Outputs that the level's previous bake into the same folder wrote
    /// and this one does not (a flag such as `--hdr` or `--occluders`
    /// dropped): removed, so that nothing stale sits beside the new files.
    #[serde(default)]
    pub removed: Vec<String>,
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
            kernel: settings.kernel.name().into(),
            gather: settings.gather.name().into(),
            falloff: settings.falloff,
            bounces: settings.bounces,
            exposure: 1.0,
            exposure_auto: false,
            clipped: 0.0,
            counts,
            timings,
            solves: solved.solves,
            residual: solved.residual,
            solver: solved.solver.clone(),
            energy: solved.energy.clone(),
            skipped: log.skipped,
            warnings: log.warnings,
            problems: log.problems,
            outputs: vec![],
            removed: vec![],
            version: env!("CARGO_PKG_VERSION").into(),
        }
    }

    /// Records `problem`: among the problems, and its message among the
    /// warnings.
    pub fn add_problem(&mut self, problem: Problem) {
        self.warnings.push(problem.message.clone());
        self.problems.push(problem);
    }

    /// What the bake left out or approximated, in a level designer's words
    /// (the technical account is [`Report::summary`] and the `skipped` list):
    /// only what can change what the lightmap shows, not the exact shortcuts
    /// (a grey scene solved once for three channels, a channel without light).
    pub fn plain_skips(&self) -> Vec<String> {
        let mut out = Vec::new();
        let mut push = |s: String| {
            if !out.contains(&s) {
                out.push(s);
            }
        };
        for s in &self.skipped {
            match s.effect.as_str() {
                "bounce" => push(match s.reason.as_str() {
                    r if r.starts_with("bounces = 0") => {
                        "bounce light (bounces = 0: direct light only)".to_string()
                    }
                    "no wall reflects" => "bounce light (no wall reflects light)".to_string(),
                    _ => "bounce light (no wall that reflects is lit)".to_string(),
                }),
                "gather" if self.counts.unreached_pixels > 0 => push(format!(
                    "{} floor pixel{} no light reaches (left dark)",
                    self.counts.unreached_pixels,
                    if self.counts.unreached_pixels == 1 {
                        ""
                    } else {
                        "s"
                    }
                )),
                "falloff reach" => push("very faint light far from the lamps".to_string()),
                "distant patches" => push("fine detail of distant bounce light".to_string()),
                "pixels" => push("smooth floor interpolated between gathered pixels".to_string()),
                "patches" => push("walls of sealed regions no light reaches".to_string()),
                _ => {}
            }
        }
        if let Some(n) = self.bounces
            && n > 0
        {
            push(format!(
                "light after {n} bounce{}",
                if n == 1 { "" } else { "s" }
            ));
        }
        out
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
