//! The fifth stage: the light of every floor pixel, gathered from the
//! solved radiosity — the bake's own channel classes and the response
//! vectors together, so that visibility is found once per pixel for all of
//! them. Pixels in free regions that no lit edge faces are not gathered.

use std::borrow::Cow;

use super::radiosity::{Solved, TRACED_EMISSION};
use super::{Ctx, GatherMethod, Log, Plan, Scene, Transport};
use crate::gather::{self, Radiosity};
use crate::transport::kernel::Reach;

/// The gathered light.
pub struct Gathered<'a> {
    /// The floor pixels that were gathered, in order (the scene's own list
    /// when every floor pixel was).
    pub reached: Cow<'a, [[i32; 2]]>,
    /// `values[i * components + k]`: component `k` at `reached[i]`.
    pub values: Vec<f64>,
    /// With [`Settings::directional`](super::Settings::directional):
    /// `moments[i * 2 * components + k]` the cosine and
    /// `moments[i * 2 * components + components + k]` the sine moment of
    /// component `k` at `reached[i]` (else empty).
    pub moments: Vec<f64>,
    /// Whether moments were asked for.
    pub directional: bool,
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
pub fn gather<'a>(
    ctx: &Ctx,
    scene: &'a Scene,
    plan: &Plan,
    transport: &mut Transport,
    solved: &Solved,
    log: &mut Log,
) -> Gathered<'a> {
    let rad = components(scene, plan, transport, solved);
    // The slope rows served only the slopes: freed before the gather,
    // so that the bake's peak is the larger of the two stages, not their sum.
    transport.slope_rows = None;
    let kk = rad.components;
    let rule = ReachRule::new(ctx, scene, solved, &rad);
    let (reached, unreached) = reachable_pixels(ctx, scene, &rad);
    if unreached > 0 && kk > 0 {
        log.skip(
            "gather",
            format!("{unreached} floor pixels in regions no light reaches"),
        );
    }
    let run = if kk == 0 || reached.is_empty() {
        Run::default()
    } else {
        run(ctx, scene, &rad, rule, &reached, log)
    };
    if run.unreached > 0 {
        log.skip(
            "gather",
            format!(
                "{} floor pixels that no lit edge reaches: every one is hidden from them or beyond its falloff reach (left at 0)",
                run.unreached
            ),
        );
    }
    let all_culled = transport.culled_pairs + run.culled_pairs;
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
        values: run.values,
        moments: run.moments,
        directional: ctx.settings.directional,
        components: kk,
        unreached: if kk > 0 {
            unreached + run.unreached
        } else {
            scene.floor_pixels.len()
        },
        culled_pairs: run.culled_pairs,
    }
}

/// Which edge-pixel pairs are too faint to gather: the reach of every edge,
/// the threshold it was found for, and the components that decide it.
struct ReachRule {
    reach: Reach,
    threshold: f64,
    decide: std::ops::Range<usize>,
}

impl ReachRule {
    /// With falloff, pairs whose light is below the preset's bound (relative
    /// to the brightest emission) are not gathered.
    ///
    /// With responses, the lightmap is made of them alone, and the reach
    /// comes from them alone (unit emission, bound relative to it): then what
    /// is culled does not depend on emission, and a relight with any emission
    /// is exactly the bake of that emission. Each culled pair still stays
    /// below reach_bound x its emitter's emission.
    fn new(ctx: &Ctx, scene: &Scene, solved: &Solved, rad: &Radiosity) -> ReachRule {
        let (decide, emission) = rule_basis(ctx, scene, solved, rad);
        let threshold = ctx.reach_bound * emission;
        let reach = reach(ctx, scene, rad, decide.clone(), threshold);
        ReachRule {
            reach,
            threshold,
            decide,
        }
    }
}

/// What one gather returned.
#[derive(Default)]
struct Run {
    values: Vec<f64>,
    moments: Vec<f64>,
    culled_pairs: u64,
    /// Pixels whose every lit candidate edge is hidden or out of reach.
    unreached: usize,
}

/// Gathers `reached` with the settings' method.
fn run(
    ctx: &Ctx,
    scene: &Scene,
    rad: &Radiosity,
    rule: ReachRule,
    reached: &[[i32; 2]],
    log: &mut Log,
) -> Run {
    let (geometry, patches, settings) = (&scene.geometry, &scene.patches, ctx.settings);
    match settings.gather {
        GatherMethod::Fast => {
            let options = gather::GatherOptions {
                falloff: ctx.falloff,
                kernel: settings.kernel,
                reach: &rule.reach,
                tolerance: rule.threshold,
                decide: rule.decide,
                progress: ctx.gather_progress.map(gather::OnProgress),
                lattice: settings.knobs.lattice.filter(|_| !settings.exhaustive),
                anchors: settings.knobs.anchors.filter(|_| !settings.exhaustive),
                sweep_every: settings.knobs.sweep_every,
                coarse: settings.knobs.coarse,
                far: settings.knobs.far.filter(|_| !settings.exhaustive),
                directional: settings.directional,
            };
            let gather::Gather {
                values,
                moments,
                stats,
                counts,
            } = gather::gather_with_moments(geometry, patches, rad, reached, &options);
            let tested = counts.interpolated - counts.untested;
            if tested > 0 {
                log.skip(
                    "pixels",
                    format!(
                        "{} of {} floor pixels interpolated in cells of 8 or 4 px between pixels gathered exactly, where the cell's centre matched the interpolation within {}% and saw the same lights and shadow lines as its corners",
                        tested,
                        reached.len(),
                        100.0 * options.lattice.unwrap_or(0.0)
                    ),
                );
            }
            if counts.untested > 0 {
                log.skip(
                    "pixels",
                    format!(
                        "{} of {} floor pixels interpolated in cells of {} px (the other cells' pixels) between their corners, gathered exactly, where those were within {}% of each other (a shadow line between them that changes neither by more is blurred over 2 px; never across a wall)",
                        counts.untested,
                        reached.len(),
                        gather::lattice::COARSE,
                        100.0 * gather::lattice::SPREAD,
                    ),
                );
            }
            if counts.local > 0 {
                let every = options.sweep_every;
                log.skip(
                    "pixels",
                    format!(
                        "{} of {} floor pixels gathered with a sweep over the edges that the anchors at the corners of their {} px block{} see and the edges within {} px of it, instead of a full visibility query{} (exact for those edges; a distant edge that no anchor sees is missed)",
                        counts.local,
                        reached.len(),
                        options.anchors.unwrap_or(gather::lattice::ANCHOR),
                        // `draft` sweeps every pixel it gathers over the
                        // corners' lists; otherwise only pixels whose query
                        // would walk are swept, with the ring too.
                        if every { "" } else { " and of the ring around it" },
                        gather::lattice::NEAR,
                        if every { "" } else { " that would walk the level" },
                    ),
                );
            }
            if counts.far > 0 {
                let r = options.far.unwrap_or(0.0);
                log.skip(
                    "far reflected light",
                    format!(
                        "{} of {} floor pixels (swept, or beside a wall with a full query that went past {r} px only where a light was left to find) took the light that walls reflect to them from more than {r} px away from the anchors at the corners of their block, interpolated and scaled by the angle each has open beyond that distance against theirs, at most {scale} times (their direct light exact; a swept pixel saw only the lights, the edges within {r} px and what may hide a light, where that left out enough of its block's list)",
                        counts.far,
                        reached.len(),
                        scale = gather::FAR_SCALE,
                    ),
                );
            }
            if counts.far_lights > 0 {
                let r = gather::LAMP_FAR;
                log.skip(
                    "far light of many lights",
                    format!(
                        "{} of {} floor pixels, swept in blocks whose list held more than {} lights, took all the light from more than {r} px away, the lights' own too, from the anchors at the corners of their block, where it was at most {}% of each corner's light, interpolated and scaled by the angle the pixel has open past {r} px against theirs, at most {scale} times (the light from nearer exact; they swept only the edges within {r} px)",
                        counts.far_lights,
                        reached.len(),
                        gather::FAR_LAMPS,
                        100.0 * gather::LAMP_SHARE,
                        scale = gather::FAR_SCALE,
                    ),
                );
            }
            if counts.outer > 0 {
                let (r, s) = (
                    gather::OUTER,
                    4 * options.anchors.unwrap_or(gather::lattice::ANCHOR),
                );
                log.skip(
                    "anchors' far light",
                    format!(
                        "{} anchors walked everywhere within {r} px only, and past it only towards the lights (their direct light exact), and took the light that walls reflect to them from farther from the anchors at the corners of their {s} px block, interpolated",
                        counts.outer,
                    ),
                );
            }
            if ctx.reach_bound > 0.0 && counts.pieces < counts.patch_pieces {
                log.skip(
                    "distant patches",
                    format!(
                        "reflected light gathered as {} pieces for {} patch pieces (nearly quadratic runs far from the pixel taken whole; error at most {:e} of the brightest emission per pixel)",
                        counts.pieces, counts.patch_pieces, ctx.reach_bound
                    ),
                );
            }
            Run {
                values,
                moments,
                culled_pairs: stats.culled_pairs,
                unreached: stats.unreached as usize,
            }
        }
        GatherMethod::Naive => Run {
            values: gather::gather_naive(
                geometry,
                patches,
                rad,
                ctx.falloff,
                settings.kernel,
                reached,
                settings.naive_samples,
            ),
            ..Run::default()
        },
    }
}

/// The radiosity of every component the gather computes together: the
/// plan's channel classes, then the response vectors.
fn components(scene: &Scene, plan: &Plan, transport: &Transport, solved: &Solved) -> Radiosity {
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
    Radiosity::new(&scene.patches, &all_b, &slopes, &edge_e)
}

/// The components that decide the reach, and the emission its bound is
/// relative to: the bake's own channels and the brightest emission, or,
/// with responses, the responses and their unit emission (then what is
/// culled does not depend on emission).
fn rule_basis(
    ctx: &Ctx,
    scene: &Scene,
    solved: &Solved,
    rad: &Radiosity,
) -> (std::ops::Range<usize>, f64) {
    let kk = rad.components;
    if solved.responses.is_empty() {
        (0..kk, brightest_emission(ctx, scene))
    } else {
        (solved.class_b.len()..kk, TRACED_EMISSION)
    }
}

/// Per edge, its brightest radiosity over the components that decide the
/// gather's reach, relative to the emission that reach is relative to: how
/// far the edge's light reaches, by the gather's own rule, which the form
/// factors' reach follows ([`super::factors::ReachPasses`]).
pub fn relative_radiosity(
    ctx: &Ctx,
    scene: &Scene,
    plan: &Plan,
    transport: &Transport,
    solved: &Solved,
) -> Vec<f64> {
    let rad = components(scene, plan, transport, solved);
    let (decide, emission) = rule_basis(ctx, scene, solved, &rad);
    let mut b = brightest(scene, &rad, decide);
    for v in &mut b {
        *v = if emission > 0.0 { *v / emission } else { 1.0 };
    }
    b
}

/// How far each edge's light reaches: where its brightest radiosity over
/// the components `decide`, under the falloff, falls below `threshold`.
fn reach(
    ctx: &Ctx,
    scene: &Scene,
    rad: &Radiosity,
    decide: std::ops::Range<usize>,
    threshold: f64,
) -> Reach {
    let bmax = brightest(scene, rad, decide);
    let lens: Vec<f64> = scene.geometry.edges.iter().map(|e| e.len()).collect();
    Reach::new(
        &lens,
        &bmax,
        ctx.falloff,
        1.0 / std::f64::consts::TAU,
        threshold,
    )
}

/// Per edge, its brightest radiosity over the components `decide` (at a
/// patch's brighter end).
fn brightest(scene: &Scene, rad: &Radiosity, decide: std::ops::Range<usize>) -> Vec<f64> {
    let (edges, patches) = (&scene.geometry.edges, &scene.patches);
    let kk = rad.components;
    (0..edges.len())
        .map(|ei| {
            let mut m: f64 = 0.0;
            for p in patches.of_edge(ei) {
                for c in decide.clone() {
                    m = m.max(
                        rad.patch(patches, p, c)
                            + rad.slope[p * kk + c].abs() * 0.5 * patches.length(p),
                    );
                }
            }
            m
        })
        .collect()
}

/// The floor pixels split into those in free regions that some lit edge
/// faces and the rest, which receive nothing (all of them, with nothing to
/// gather; none of them, for the exhaustive bake).
fn reachable_pixels<'a>(
    ctx: &Ctx,
    scene: &'a Scene,
    rad: &Radiosity,
) -> (Cow<'a, [[i32; 2]]>, usize) {
    let geometry = &scene.geometry;
    let mut lit_comp = vec![false; geometry.component_count as usize];
    for (i, e) in geometry.edges.iter().enumerate() {
        if rad.edge_emits[i] || rad.edge_reflects[i] {
            lit_comp[e.component as usize] = true;
        }
    }
    let width = ctx.level.width;
    let lit = |p: &&[i32; 2]| {
        rad.components > 0
            && (ctx.settings.exhaustive
                || lit_comp[geometry.components[p[1] as usize * width + p[0] as usize] as usize])
    };
    let all = &scene.floor_pixels;
    match all.iter().position(|p| !lit(&p)) {
        None => (Cow::Borrowed(&all[..]), 0),
        Some(first) => {
            let mut list = all[..first].to_vec();
            list.extend(all[first + 1..].iter().filter(lit));
            let unreached = all.len() - list.len();
            (Cow::Owned(list), unreached)
        }
    }
}

/// The most the gather's approximations (pairs beyond the falloff reach,
/// merged runs of distant patches) may take from a pixel's light: the
/// preset's bound times the emission of each emitter some edge uses (a
/// plain bake errs by at most the bound times the brightest emission; a
/// lightmap summed from per-emitter responses, by the bound times each
/// emitter's emission in each response). 0 when nothing is approximated.
pub fn approximation_bound(ctx: &Ctx, scene: &Scene) -> f64 {
    ctx.reach_bound * used_emissions(ctx, scene).sum::<f64>()
}

/// The brightest emission of any channel of any material some edge uses.
fn brightest_emission(ctx: &Ctx, scene: &Scene) -> f64 {
    used_emissions(ctx, scene).fold(0.0, f64::max)
}

/// The brightest channel's emission of each material some edge uses.
fn used_emissions<'a>(ctx: &'a Ctx, scene: &'a Scene) -> impl Iterator<Item = f64> + 'a {
    ctx.level
        .materials
        .iter()
        .zip(&scene.used)
        .filter(|(_, u)| **u)
        .map(|(m, _)| m.emission.into_iter().fold(0.0, f64::max))
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
    let Some(pr) = &transport.slope_rows else {
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
