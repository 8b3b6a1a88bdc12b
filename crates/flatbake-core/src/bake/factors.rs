//! The third stage: the form factors F between patches, when some bounce is
//! to be solved — the flatland kernel's exact ones, or the paper's per-patch
//! factors with `--kernel paper`. With F known, a bounce that no reflecting
//! patch can receive (no emitter in sight) is dropped from the plan.

use super::{Ctx, Log, Plan, Scene};
use crate::gather::Kernel;
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

/// Builds F for `scene` with the settings' kernel; drops the bounces that
/// no reflecting patch can receive from `plan` (recorded in `log`).
pub fn form_factors(
    ctx: &Ctx,
    scene: &Scene,
    plan: &mut Plan,
    structures: &Structures,
    log: &mut Log,
) -> Transport {
    let (geometry, patches) = (&scene.geometry, &scene.patches);
    let edges = &geometry.edges;
    let mut out = Transport::default();
    let lit = match ctx.settings.kernel {
        Kernel::Flatland => {
            // Factors below the preset's bound are not computed (falloff only).
            let lens: Vec<f64> = edges.iter().map(|e| e.len()).collect();
            let reach = Reach::new(
                &lens,
                &vec![1.0; edges.len()],
                ctx.falloff,
                0.5,
                ctx.reach_bound,
            );
            let (ff, slopes, stats) = transport::form_factors(
                structures,
                patches,
                ctx.settings.knobs.quad,
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
