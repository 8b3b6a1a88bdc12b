//! The third stage: the form factors F between patches, when some bounce is
//! to be solved — the flatland kernel's exact ones, or the paper's per-patch
//! factors with `--kernel paper`. With F known, a bounce that no reflecting
//! patch can receive (no emitter in sight) is dropped from the plan.

use super::memory::SAMPLED_PATCHES;
use super::{Ctx, Log, Plan, Scene};
use crate::gather::Kernel;
use crate::geometry::Geometry;
use crate::transport::kernel::Reach;
use crate::transport::{self, FormFactors, SlopeRows};
use crate::visibility::Structures;

/// The form factors of a scene, whichever kernel built them.
#[derive(Default)]
pub struct Transport {
    /// The flatland kernel's F (symmetric storage, effective lengths).
    pub form_factors: Option<FormFactors>,
    /// The paper kernel's F as sparse rows.
    pub paper_rows: Option<Vec<Vec<(u32, f64)>>>,
    /// The flatland kernel's slope rows, for patch slopes.
    pub slope_rows: Option<SlopeRows>,
    /// Patch-point pairs left out beyond the falloff reach.
    pub culled_pairs: u64,
}

impl Transport {
    /// Non-zero entries of whichever F was built.
    pub fn entries(&self) -> usize {
        self.form_factors.as_ref().map_or_else(
            || {
                self.paper_rows
                    .as_ref()
                    .map_or(0, |r| r.iter().map(Vec::len).sum())
            },
            FormFactors::nnz,
        )
    }
}

/// Builds F for `scene` with the settings' kernel, with the reach of
/// `passes`' current pass if given (else for a unit of radiosity); drops
/// the bounces that no reflecting patch can receive from `plan` (recorded
/// in `log`).
pub fn form_factors(
    ctx: &Ctx,
    scene: &Scene,
    plan: &mut Plan,
    structures: &Structures,
    passes: Option<&ReachPasses>,
    log: &mut Log,
) -> Transport {
    let (geometry, patches) = (&scene.geometry, &scene.patches);
    let mut out = Transport::default();
    let lit = match ctx.settings.kernel {
        Kernel::Flatland => {
            // Factors below the preset's bound are not computed (falloff
            // only): for a unit of radiosity, or as the passes say.
            let (reach, quad) = match passes {
                Some(p) => (p.reach.clone(), p.quad(ctx)),
                None => (unit_reach(ctx, geometry), ctx.settings.knobs.quad),
            };
            let (ff, slopes, stats) = transport::form_factors(
                structures,
                patches,
                quad,
                ctx.falloff,
                &reach,
                ctx.reach_bound,
            );
            out.culled_pairs += stats.culled_pairs;
            if ff.dropped > 0 {
                log.skip(
                    "slivers",
                    format!(
                        "{} of {} form-factor entries left out: each patch's smallest, together at most {:e} of what its row sends, their part shared by the rest of the row",
                        ff.dropped,
                        ff.dropped + ff.nnz() as u64 - ff.one_sided,
                        ctx.reach_bound
                    ),
                );
            }
            let lit = sees_light(scene, plan, &|i| ff.row(i).collect());
            out.form_factors = Some(ff);
            out.slope_rows = Some(slopes);
            lit
        }
        Kernel::Paper => {
            let rows = transport::paper::form_factors(geometry, patches, ctx.falloff);
            let lit = sees_light(scene, plan, &|i| {
                rows[i].iter().map(|&(j, f)| (j as usize, f)).collect()
            });
            out.paper_rows = Some(rows);
            lit
        }
    };
    let (lit, responses_lit) = lit;
    plan.response_bounce &= responses_lit;
    // Reflecting patches that see no emitter receive nothing: no bounce.
    if plan.bounce && !lit && !ctx.settings.exhaustive {
        log.skip("bounce", "no reflecting patch sees an emitter");
        plan.bounce = false;
    }
    out
}

/// Does some reflecting patch see an emitter: for the bake's own channels
/// (emission above 0), and for the responses (any emitter material)?
fn sees_light(
    scene: &Scene,
    plan: &Plan,
    row: &dyn Fn(usize) -> Vec<(usize, f64)>,
) -> (bool, bool) {
    let sees = |channels: &[usize], source: &dyn Fn(usize) -> bool| {
        (0..scene.patch_count()).any(|i| {
            channels.iter().any(|&c| scene.rho[c][i] > 0.0)
                && row(i).iter().any(|&(j, f)| j != i && f > 0.0 && source(j))
        })
    };
    let response_channels = plan
        .responses
        .as_ref()
        .map_or(&[][..], |rp| &rp.rho_reps[..]);
    (
        sees(&plan.channels.classes, &|j| {
            (0..3).any(|c| scene.emit[c][j] > 0.0)
        }),
        sees(response_channels, &|j| scene.emitter_patch[j]),
    )
}

/// The form factors' reach for a unit of radiosity on every edge: a pair
/// is left out where its factor is below the preset's bound.
pub fn unit_reach(ctx: &Ctx, geometry: &Geometry) -> Reach {
    let lens: Vec<f64> = geometry.edges.iter().map(|e| e.len()).collect();
    unit_reach_of(ctx, &lens)
}

/// [`unit_reach`] for edges of lengths `lens`.
fn unit_reach_of(ctx: &Ctx, lens: &[f64]) -> Reach {
    reach_for(ctx, lens, &vec![1.0; lens.len()])
}

/// The form factors' reach for edges of lengths `lens` whose radiosity is
/// `b` (relative): a pair is left out where its factor times `b` is below
/// the preset's bound.
fn reach_for(ctx: &Ctx, lens: &[f64], b: &[f64]) -> Reach {
    Reach::new(lens, b, ctx.falloff, 0.5, ctx.reach_bound)
}

/// The form factors' reach under falloff, made to follow each edge's own
/// light, found in passes of form factors and solve (docs/transport.md,
/// "Reach and culling"). A pair is left out where its factor times the
/// edge's solved radiosity (relative to the emission the gather's reach is
/// relative to) is below the preset's bound: the gather's own rule. Since
/// the radiosity is only known once the factors are solved, the passes
/// are:
///
/// 1. an estimate: one quadrature point per patch, emitters reaching as
///    far as a unit of radiosity, every other edge at most
///    [`ReachPasses::ESTIMATE_REACH`];
/// 2. the reach [`ReachPasses::MARGIN`] times the estimate's radiosity
///    calls for;
/// 3. after a pass whose own solved radiosity calls for more reach on some
///    edge than it had, those edges' reach grown the same way; after
///    [`ReachPasses::MOST`] such passes, a pass at a unit of radiosity, as
///    without passes.
///
/// A pass stands once no edge's solved radiosity calls for more reach than
/// the pass gave it (never the estimate): then every pair left out is below
/// the bound at the radiosity it is solved with.
pub struct ReachPasses {
    /// The current pass's reach.
    reach: Reach,
    /// What the current pass is.
    stage: Stage,
    /// Passes run, the current one included.
    pub passes: usize,
    /// The memory estimate's entries at a unit of radiosity.
    unit_entries: u64,
    /// The edges' lengths, for their reaches.
    lens: Vec<f64>,
}

/// What a pass of [`ReachPasses`] is.
enum Stage {
    /// The estimate.
    Estimate,
    /// A pass whose reach is for this radiosity per edge (relative).
    Following(Vec<f64>),
    /// A pass at a unit of radiosity, which stands.
    Unit,
}

impl ReachPasses {
    /// How much more radiosity than a pass found the next pass's reach is
    /// for.
    pub const MARGIN: f64 = 16.0;
    /// The estimate's reach for edges that do not emit, in pixels of the
    /// level (less than the walk's widest [`FarWanted`](crate::visibility::FarWanted)
    /// radius, which the estimate gets since its narrower ones would list
    /// every edge: the estimate walks past it only towards emitters).
    pub const ESTIMATE_REACH: f64 = 16.0;
    /// Passes after the estimate before falling back to a unit of
    /// radiosity.
    pub const MOST: usize = 2;
    /// The least radiosity (relative, in units of the preset's bound) any
    /// edge's reach is for after the estimate: a unit edge then reaches
    /// about half this many pixels. An edge the estimate finds dark may
    /// still get faint light from farther than it looked; this covers it
    /// without another pass.
    pub const FLOOR: f64 = 2.0;
    /// A pass after the estimate is run only when a sample of its patches
    /// has less than this part of the factors a unit of radiosity gives
    /// them; else the next pass is at a unit of radiosity.
    pub const WORTH: f64 = 0.1;
    /// The form factors of a unit of radiosity (the memory estimate's
    /// entries) below which no estimate is run by default
    /// ([`Settings::reach_passes_from`](super::Settings::reach_passes_from)):
    /// they are cheap anyway.
    pub const FROM_ENTRIES: u64 = 8_000_000;

    /// The estimate pass, where it can save anything: with falloff, a
    /// reach bound, the flatland kernel, and at least
    /// [`Settings::reach_passes_from`](super::Settings::reach_passes_from)
    /// entries at a unit of radiosity (`unit_entries`, the memory
    /// estimate's count).
    pub fn new(ctx: &Ctx, scene: &Scene, unit_entries: u64) -> Option<ReachPasses> {
        if unit_entries < ctx.settings.reach_passes_from
            || ctx.falloff.is_none()
            || ctx.reach_bound <= 0.0
            || ctx.settings.kernel != Kernel::Flatland
        {
            return None;
        }
        let geometry = &scene.geometry;
        let lens: Vec<f64> = geometry.edges.iter().map(|e| e.len()).collect();
        let mut reach = unit_reach_of(ctx, &lens);
        let most = Self::ESTIMATE_REACH * geometry.unit.max(1) as f64;
        for (e, r) in reach.radius.iter_mut().enumerate() {
            let emits = scene
                .patches
                .of_edge(e)
                .any(|p| scene.emitter_patch[p] || (0..3).any(|c| scene.emit[c][p] > 0.0));
            if !emits {
                *r = r.min(most);
            }
        }
        reach.max = reach.radius.iter().copied().fold(0.0, f64::max);
        Some(ReachPasses {
            reach,
            stage: Stage::Estimate,
            passes: 1,
            unit_entries,
            lens,
        })
    }

    /// Whether the current pass reaches as far as a unit of radiosity (the
    /// passes fell back to it).
    pub fn at_unit_radiosity(&self) -> bool {
        matches!(self.stage, Stage::Unit)
    }

    /// Quadrature points per patch for the current pass.
    fn quad(&self, ctx: &Ctx) -> usize {
        match self.stage {
            Stage::Estimate => 1,
            _ => ctx.settings.knobs.quad,
        }
    }

    /// After a pass whose solve gave `need` (per edge, its light relative
    /// to the emission the gather's reach is relative to, as the gather
    /// stage computes it): `true` and the next pass set up when the pass
    /// does not stand, `false` when it does.
    pub fn next(
        &mut self,
        ctx: &Ctx,
        scene: &Scene,
        structures: &Structures,
        need: &[f64],
    ) -> bool {
        let reach_for = |b: &[f64]| reach_for(ctx, &self.lens, b);
        let capped = |b: f64| b.min(1.0);
        let relative = match &mut self.stage {
            Stage::Unit => return false,
            Stage::Estimate => {
                // The reach the estimate's radiosity calls for, worth a
                // pass only where a sample of patches has far fewer factors
                // with it than at a unit of radiosity (the memory
                // estimate's count, sampled the same way).
                let floor = Self::FLOOR * ctx.reach_bound;
                let relative: Vec<f64> = need
                    .iter()
                    .map(|&b| capped(Self::MARGIN * b).max(floor))
                    .collect();
                let ours = transport::estimate_entries(
                    structures,
                    &scene.patches,
                    ctx.settings.knobs.quad,
                    ctx.falloff,
                    &reach_for(&relative),
                    ctx.reach_bound,
                    SAMPLED_PATCHES,
                );
                if ours as f64 > Self::WORTH * self.unit_entries as f64 {
                    return self.at_unit(ctx);
                }
                relative
            }
            Stage::Following(relative) => {
                // Edges whose light reaches farther than the pass gave
                // them. (Only where the radiosity is above what the reach
                // was for can it call for more: the others are left at 0.)
                let above: Vec<f64> = need
                    .iter()
                    .zip(relative.iter())
                    .map(|(&b, &r)| if capped(b) > r { capped(b) } else { 0.0 })
                    .collect();
                let wanted = reach_for(&above);
                let short: Vec<usize> = (0..need.len())
                    .filter(|&e| wanted.radius[e] > self.reach.radius[e] + 1e-9)
                    .collect();
                if short.is_empty() {
                    return false;
                }
                if self.passes > Self::MOST {
                    return self.at_unit(ctx);
                }
                let mut relative = std::mem::take(relative);
                for e in short {
                    relative[e] = relative[e].max(capped(Self::MARGIN * need[e]));
                }
                relative
            }
        };
        self.reach = reach_for(&relative);
        self.stage = Stage::Following(relative);
        self.passes += 1;
        true
    }

    /// Sets up the next pass at a unit of radiosity, which stands.
    fn at_unit(&mut self, ctx: &Ctx) -> bool {
        self.reach = unit_reach_of(ctx, &self.lens);
        self.stage = Stage::Unit;
        self.passes += 1;
        true
    }
}
