//! The fourth stage: the radiosity of every patch, per channel class —
//! `(I - diag(rho) F) B = E` solved, or truncated after `bounces`, or the
//! emission itself where the plan has no bounce — and, for layers and
//! caches, the radiosity of every emitter on its own at unit emission.
//! Ends with the energy balance of the solved channels.

use super::plan::CHANNEL;
use super::report::Energy;
use super::{BakeError, Ctx, Log, Plan, Scene, Transport, UnboundedRegion};
use crate::transport::solve::{self, SolveError, SolveSettings};
use crate::transport::{FormFactors, Patches, paper};

/// The emission response vectors are traced with: they are stored divided
/// by it. With falloff, the pairs culled are chosen against it, so nothing
/// in a response depends on the palette's emission.
pub const TRACED_EMISSION: f64 = 1.0;

/// One emitter's light on its own, in one reflectance class.
pub struct ResponseVector {
    /// Radiosity per patch.
    pub b: Vec<f64>,
    /// The channel whose reflectance it was solved with.
    pub rho_channel: usize,
    /// Emission per edge ([`TRACED_EMISSION`] on the emitter's edges).
    pub edge_emission: Vec<f64>,
}

/// The solved radiosity.
pub struct Solved {
    /// Radiosity per patch of each channel class of the plan.
    pub class_b: Vec<Vec<f64>>,
    /// Per-emitter responses, in plan order (emitter-major).
    pub responses: Vec<ResponseVector>,
    /// Channel solves run (0 to 3).
    pub solves: usize,
    /// Largest relative residual over the solves.
    pub residual: f64,
    /// Which solver ran last ("none" when nothing was solved).
    pub solver: String,
    /// Power emitted, absorbed and escaped, summed over the channels.
    pub energy: Energy,
}

/// One channel's solution.
struct ChannelSolve {
    b: Vec<f64>,
    residual: f64,
    method: String,
    /// Rows of the paper kernel's F that had to be rescaled.
    rescaled: usize,
}

/// Solves every channel class of the plan and every response vector.
pub fn solve(
    ctx: &Ctx,
    scene: &Scene,
    plan: &Plan,
    transport: &Transport,
    log: &mut Log,
) -> Result<Solved, BakeError> {
    let mut class_b: Vec<Vec<f64>> = Vec::new();
    let mut solves = 0;
    let mut residual: f64 = 0.0;
    let mut solver = "none".to_string();
    for &c in &plan.channels.classes {
        if !plan.bounce {
            class_b.push(scene.emit[c].clone());
            continue;
        }
        solves += 1;
        let s = solve_one(ctx, scene, transport, c, &scene.emit[c])?;
        residual = residual.max(s.residual);
        solver = s.method;
        if s.rescaled > 0 {
            log.warn(format!(
                "paper kernel, {} channel: {} rows of rho F summed to 1 or more and were rescaled (F normalised per row, rho F capped at {})",
                CHANNEL[c],
                s.rescaled,
                paper::MAX_ROW
            ));
        }
        class_b.push(s.b);
    }
    let responses = solve_responses(ctx, scene, plan, transport)?;
    let energy = energy(scene, plan, transport, &class_b);
    Ok(Solved {
        class_b,
        responses,
        solves,
        residual,
        solver,
        energy,
    })
}

/// Each emitter material alone at unit emission, once per reflectance class.
fn solve_responses(
    ctx: &Ctx,
    scene: &Scene,
    plan: &Plan,
    transport: &Transport,
) -> Result<Vec<ResponseVector>, BakeError> {
    let Some(rp) = &plan.responses else {
        return Ok(Vec::new());
    };
    let (edges, patches) = (&scene.geometry.edges, &scene.patches);
    let mut out = Vec::new();
    for &m in &rp.emitters {
        let alone = |material: u16| {
            if material as usize == m {
                TRACED_EMISSION
            } else {
                0.0
            }
        };
        let e: Vec<f64> = (0..patches.len())
            .map(|p| alone(edges[patches.edge[p] as usize].material))
            .collect();
        let edge_emission: Vec<f64> = edges.iter().map(|ed| alone(ed.material)).collect();
        for &c in &rp.rho_reps {
            let b = if plan.response_bounce {
                solve_one(ctx, scene, transport, c, &e)
                    .map_err(|err| match err {
                        BakeError::Unbounded { region, .. } => BakeError::Unbounded {
                            region,
                            light_layers: true,
                        },
                        other => other,
                    })?
                    .b
            } else {
                e.clone()
            };
            out.push(ResponseVector {
                b,
                rho_channel: c,
                edge_emission: edge_emission.clone(),
            });
        }
    }
    Ok(out)
}

/// One channel's solve for emission `e` per patch, with the reflectance of
/// channel `c`.
fn solve_one(
    ctx: &Ctx,
    scene: &Scene,
    transport: &Transport,
    c: usize,
    e: &[f64],
) -> Result<ChannelSolve, BakeError> {
    let (settings, rho) = (ctx.settings, &scene.rho[c]);
    if let Some(rows) = &transport.paper_rows {
        let (b, rescaled) = paper::solve(rows, rho, e, settings.knobs.tolerance);
        return Ok(ChannelSolve {
            b,
            residual: 0.0,
            method: "paper".into(),
            rescaled,
        });
    }
    let Some(ff) = &transport.form_factors else {
        return Err(BakeError::Internal(
            "a bounce was planned without form factors",
        ));
    };
    if let Some(n) = settings.bounces {
        return Ok(ChannelSolve {
            b: solve::truncated(ff, rho, e, n),
            residual: 0.0,
            method: "bounces".into(),
            rescaled: 0,
        });
    }
    let solve_settings = SolveSettings {
        tolerance: settings.knobs.tolerance,
        ..SolveSettings::default()
    };
    let s = solve::solve_channel(ff, rho, e, &solve_settings).map_err(|err| match err {
        SolveError::Unbounded { patches: ps } => BakeError::Unbounded {
            region: UnboundedRegion::of(scene, &ps, CHANNEL[c]),
            light_layers: false,
        },
        other => BakeError::Solve(other),
    })?;
    Ok(ChannelSolve {
        b: s.radiosity,
        residual: s.residual,
        method: s.method.to_string(),
        rescaled: 0,
    })
}

/// Energy of the solved channels, summed.
fn energy(scene: &Scene, plan: &Plan, transport: &Transport, class_b: &[Vec<f64>]) -> Energy {
    let mut energy = Energy::default();
    for c in 0..3 {
        let Some(k) = plan.channels.class_of[c] else {
            continue;
        };
        let (em, ab, es) = energy_balance(
            transport.form_factors.as_ref(),
            &scene.patches,
            &scene.rho[c],
            &scene.emit[c],
            &super::lightmap::scaled(&class_b[k], plan.channels.scale[c]),
        );
        energy.emitted += em;
        energy.absorbed += ab;
        energy.escaped += es;
    }
    energy
}

/// `(emitted, absorbed, escaped)` power of one channel. With form factors the
/// effective lengths are used, for which the discrete system conserves energy
/// exactly; without them nothing is reflected and everything emitted escapes
/// or is absorbed on first hit.
pub fn energy_balance(
    ff: Option<&FormFactors>,
    patches: &Patches,
    rho: &[f64],
    e: &[f64],
    b: &[f64],
) -> (f64, f64, f64) {
    let n = patches.len();
    let Some(ff) = ff else {
        let emitted: f64 = (0..n).map(|p| patches.length(p) * e[p]).sum();
        // Without a bounce solve the fate of light is not tracked patch by
        // patch: report it as escaped/absorbed by first hit unknown = escaped.
        return (emitted, 0.0, emitted);
    };
    // Per patch in parallel, summed in patch order: the same bits for any
    // thread count.
    use rayon::prelude::*;
    let terms: Vec<[f64; 3]> = (0..n)
        .into_par_iter()
        .with_min_len(1024)
        .map(|i| {
            let d = ff.dlen[i];
            let h: f64 = ff.row(i).map(|(j, f)| f * b[j]).sum();
            [
                d * e[i],
                d * (1.0 - rho[i]) * h,
                d * b[i] * (1.0 - ff.coverage[i]),
            ]
        })
        .collect();
    let (mut em, mut ab, mut es) = (0.0, 0.0, 0.0);
    for [m, a, s] in terms {
        em += m;
        ab += a;
        es += s;
    }
    (em, ab, es)
}
