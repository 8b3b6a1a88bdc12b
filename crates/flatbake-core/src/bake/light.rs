//! The fifth stage: the light of every floor pixel, gathered from the
//! solved radiosity — the bake's own channel classes and the response
//! vectors together, so that visibility is found once per pixel for all of
//! them. Pixels in free regions that no lit edge faces are not gathered.

use super::radiosity::{Solved, TRACED_EMISSION};
use super::{Ctx, GatherMethod, Log, Plan, Scene, Transport};
use crate::gather::{self, Radiosity};
use crate::transport::kernel::Reach;

/// The gathered light.
pub struct Gathered {
    /// The floor pixels that were gathered, in order.
    pub reached: Vec<[i32; 2]>,
    /// `values[i * components + k]`: component `k` at `reached[i]`.
    pub values: Vec<f64>,
    /// Values per pixel: the plan's channel classes, then the responses.
    pub components: usize,
    /// Floor pixels left at 0: in regions no light reaches, or with every
    /// lit edge hidden or beyond its reach.
    pub unreached: usize,
    /// Edge-pixel pairs not gathered because they lie beyond the falloff
    /// reach.
    pub culled_pairs: u64,
}

/// Gathers the light of every reachable floor pixel.
pub fn gather(
    ctx: &Ctx,
    scene: &Scene,
    plan: &Plan,
    transport: &Transport,
    solved: &Solved,
    log: &mut Log,
) -> Gathered {
    let (settings, geometry, patches) = (ctx.settings, &scene.geometry, &scene.patches);
    let edges = &geometry.edges;
    let k_main = solved.class_b.len();
    let kk = k_main + solved.responses.len();
    // Per-edge emission of every component.
    let mut edge_e: Vec<Vec<f64>> = plan
        .channels
        .classes
        .iter()
        .map(|&c| scene.edge_emit[c].clone())
        .collect();
    edge_e.extend(solved.responses.iter().map(|r| r.edge_emission.clone()));
    let slopes = slopes(scene, plan, transport, solved, &edge_e);
    let mut all_b = solved.class_b.clone();
    all_b.extend(solved.responses.iter().map(|r| r.b.clone()));
    let rad = Radiosity::new(patches, &all_b, &slopes, &edge_e);
    // With falloff, pairs whose light is below the preset's bound (relative
    // to the brightest emission) are not gathered.
    // With responses, the lightmap is made of them alone, and the reach comes
    // from them alone (unit emission, bound relative to it): then what is
    // culled does not depend on emission, and a relight with any emission is
    // exactly the bake of that emission. Each culled pair still stays below
    // reach_bound x its emitter's emission.
    let (reach_comps, reach_threshold) = if solved.responses.is_empty() {
        (0..kk, ctx.reach_bound * brightest_emission(ctx, scene))
    } else {
        (k_main..kk, ctx.reach_bound * TRACED_EMISSION)
    };
    let reach = {
        let bmax: Vec<f64> = (0..edges.len())
            .map(|ei| {
                let mut m: f64 = 0.0;
                for p in patches.of_edge(ei) {
                    for c in reach_comps.clone() {
                        m = m.max(
                            rad.patch(patches, p, c)
                                + rad.slope[p * kk + c].abs() * 0.5 * patches.length(p),
                        );
                    }
                }
                m
            })
            .collect();
        let lens: Vec<f64> = edges.iter().map(|e| e.len()).collect();
        Reach::new(
            &lens,
            &bmax,
            ctx.falloff,
            1.0 / std::f64::consts::TAU,
            reach_threshold,
        )
    };
    // Free components that no lit edge faces receive nothing: not gathered.
    let mut lit_comp = vec![false; geometry.component_count as usize];
    for (i, e) in edges.iter().enumerate() {
        if rad.edge_emits[i] || rad.edge_reflects[i] {
            lit_comp[e.component as usize] = true;
        }
    }
    let width = ctx.level.width;
    let (reached, unreached): (Vec<[i32; 2]>, Vec<[i32; 2]>) =
        scene.floor_pixels.iter().partition(|p| {
            kk > 0
                && (settings.exhaustive
                    || lit_comp
                        [geometry.components[p[1] as usize * width + p[0] as usize] as usize])
        });
    if !unreached.is_empty() && kk > 0 {
        log.skip(
            "gather",
            format!(
                "{} floor pixels in regions no light reaches",
                unreached.len()
            ),
        );
    }
    let mut culled_pairs = 0;
    let mut unreached_in_reach = 0usize;
    let values = if kk == 0 || reached.is_empty() {
        Vec::new()
    } else {
        match settings.gather {
            GatherMethod::Fast => {
                let (v, stats, counts) = gather::gather(
                    geometry,
                    patches,
                    &rad,
                    ctx.falloff,
                    settings.kernel,
                    &reached,
                    &reach,
                    reach_threshold,
                    reach_comps.clone(),
                );
                culled_pairs += stats.culled_pairs;
                unreached_in_reach = stats.unreached as usize;
                if ctx.reach_bound > 0.0 && counts.pieces < counts.patch_pieces {
                    log.skip(
                        "distant patches",
                        format!(
                            "reflected light gathered as {} pieces for {} patch pieces (nearly quadratic runs far from the pixel taken whole; error at most {:e} of the brightest emission per pixel)",
                            counts.pieces, counts.patch_pieces, ctx.reach_bound
                        ),
                    );
                }
                v
            }
            GatherMethod::Naive => gather::gather_naive(
                geometry,
                patches,
                &rad,
                ctx.falloff,
                settings.kernel,
                &reached,
                settings.naive_samples,
            ),
        }
    };
    if unreached_in_reach > 0 {
        log.skip(
            "gather",
            format!(
                "{unreached_in_reach} floor pixels that no lit edge reaches: every one is hidden from them or beyond its falloff reach (left at 0)"
            ),
        );
    }
    let all_culled = transport.culled_pairs + culled_pairs;
    if all_culled > 0 {
        log.skip(
            "falloff reach",
            format!(
                "{all_culled} edge-point pairs whose light would be below {:e} of the brightest emission",
                ctx.reach_bound
            ),
        );
    }
    Gathered {
        reached,
        values,
        components: kk,
        unreached: if kk > 0 {
            unreached.len() + unreached_in_reach
        } else {
            scene.floor_pixels.len()
        },
        culled_pairs,
    }
}

/// The brightest emission of any channel of any material some edge uses.
fn brightest_emission(ctx: &Ctx, scene: &Scene) -> f64 {
    ctx.level
        .materials
        .iter()
        .zip(&scene.used)
        .filter(|(_, u)| **u)
        .flat_map(|(m, _)| m.emission)
        .fold(0.0, f64::max)
}

/// Linear profiles along patches from the radiosity at the quadrature
/// points, one vector per component (empty when nothing bounces).
fn slopes(
    scene: &Scene,
    plan: &Plan,
    transport: &Transport,
    solved: &Solved,
    edge_e: &[Vec<f64>],
) -> Vec<Vec<f64>> {
    let Some(pr) = &transport.point_rows else {
        return Vec::new();
    };
    if !plan.needs_form_factors() {
        return Vec::new();
    }
    let (patches, np) = (&scene.patches, scene.patch_count());
    let k_main = solved.class_b.len();
    let mut v: Vec<Vec<f64>> = plan
        .channels
        .classes
        .iter()
        .zip(&solved.class_b)
        .map(|(&c, b)| {
            if plan.bounce {
                pr.slopes(patches, &scene.rho[c], &scene.emit[c], b)
            } else {
                vec![0.0; np]
            }
        })
        .collect();
    for (j, r) in solved.responses.iter().enumerate() {
        v.push(if plan.response_bounce {
            // The emission of this vector, per patch.
            let e: Vec<f64> = (0..np)
                .map(|p| edge_e[k_main + j][patches.edge[p] as usize])
                .collect();
            pr.slopes(patches, &scene.rho[r.rho_channel], &e, &r.b)
        } else {
            vec![0.0; np]
        });
    }
    v
}
