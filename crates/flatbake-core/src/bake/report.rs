//! The per-level report (`NAME.report.json`): what happened, for people and
//! scripts — sizes, stage times, solves, the energy balance, what was
//! skipped and why, warnings and the files written.

use serde::{Deserialize, Serialize};

fn one() -> f64 {
    1.0
}

fn one_u32() -> u32 {
    1
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
    /// Floor points the bake gathered, lit or not: the floor pixels as
    /// painted at one texel per pixel and one point per texel; at other
    /// texel densities the floor pixels of the level baked upscaled, one per
    /// quadrature point (see [`Report::points_per_texel`]).
    pub floor_pixels: usize,
    /// Floor texels of the lightmap (a texel below one texel per pixel is
    /// floor when it holds any floor pixel); `floor_pixels` at density 1
    /// with one point per texel.
    #[serde(default)]
    pub floor_texels: usize,
    /// Non-zero entries of the form-factor matrix F.
    #[serde(default)]
    pub form_factor_entries: usize,
    /// Floor points (as counted in `floor_pixels`) that no light path
    /// reaches (left at 0 without gathering).
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
    /// Width and height of the lightmap in texels: the level's painted size
    /// (`painted_size`) times the texel density, so the painted size at
    /// one texel per pixel.
    pub size: [usize; 2],
    /// Width and height of the level as painted, in pixels.
    #[serde(default)]
    pub painted_size: [usize; 2],
    /// Texels per painted pixel along each axis (`--texels-per-pixel`:
    /// 2 for 2, 0.25 for 1/4).
    #[serde(default = "one")]
    pub texels_per_pixel: f64,
    /// Quadrature points per texel, where the light was gathered: `S x S`
    /// per texel above density 1 (`--texel-samples S`), `(m S) x (m S)`
    /// at density `1/m`, 1 at density 1 by default. A texel is their mean.
    #[serde(default = "one_u32")]
    pub points_per_texel: u32,
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
            painted_size: [level.width, level.height],
            texels_per_pixel: 1.0,
            points_per_texel: 1,
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
    /// (a grey scene, or one light colour on grey walls, solved once for
    /// three channels; a channel without light).
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
                    "{} floor {}{} no light reaches (left dark)",
                    self.counts.unreached_pixels,
                    if self.painted_pixels_are_points() {
                        "pixel"
                    } else {
                        "point"
                    },
                    if self.counts.unreached_pixels == 1 {
                        ""
                    } else {
                        "s"
                    }
                )),
                "falloff reach" => push("very faint light far from the lamps".to_string()),
                "distant patches" => push("fine detail of distant bounce light".to_string()),
                "pixels" => push("smooth floor interpolated between gathered pixels".to_string()),
                "far light of many lights" => {
                    push("the light of lamps far away blended between gathered pixels".to_string())
                }
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

    /// True when the bake gathered one point per painted pixel (density 1
    /// with one point per texel, or a density `1/m` with one point per
    /// pixel), so `counts.floor_pixels` counts painted pixels.
    pub fn painted_pixels_are_points(&self) -> bool {
        let per_pixel =
            self.points_per_texel as f64 * self.texels_per_pixel * self.texels_per_pixel;
        (per_pixel - 1.0).abs() < 1e-9
    }

    /// The size line of the report, in words: the painted size, and when
    /// they differ from it the texel grid and the quadrature points per
    /// texel ("512 x 512 pixels, 1024 x 1024 texels, 4 points per texel").
    pub fn size_words(&self) -> String {
        let [pw, ph] = if self.painted_size == [0, 0] {
            self.size
        } else {
            self.painted_size
        };
        let mut s = format!("{pw} x {ph} pixels");
        if self.size != [pw, ph] || self.points_per_texel != 1 {
            s.push_str(&format!(
                ", {} x {} texels, {} point{} per texel",
                self.size[0],
                self.size[1],
                self.points_per_texel,
                if self.points_per_texel == 1 { "" } else { "s" }
            ));
        }
        s
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
