//! Baking one resolved level: geometry, form factors, solves, gather.
//!
//! [`bake`] looks at the scene before simulating it and runs only the work
//! that changes the answer; each thing it leaves out is recorded in the
//! report's `skipped` list with the reason (see [`plan_channels`]).

pub mod report;

use std::time::Instant;

use crate::bake::report::{Counts, Energy, Report, Skip, Timings};
use crate::gather::{self, Kernel, Radiosity};
use crate::geometry::{self, Geometry};
use crate::level::{Cell, Level};
use crate::output::Lightmap;
use crate::quality::{Knobs, Quality};
use crate::transport::kernel::{Falloff, Reach};
use crate::transport::solve::{self, SolveError, SolveSettings};
use crate::transport::{self, FormFactors, Patches};

/// How the floor gather is done.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GatherMethod {
    /// Exact visible angles, tiled and parallel (the default).
    Fast,
    /// The paper's method: sampled rays per pixel and patch against every edge.
    Naive,
}

/// Everything that decides what a bake computes.
#[derive(Clone, Debug)]
pub struct Settings {
    pub quality: Quality,
    /// The discretisation; normally `quality.knobs()`.
    pub knobs: Knobs,
    /// Half-energy distance in pixels.
    pub falloff: Option<f64>,
    pub kernel: Kernel,
    pub gather: GatherMethod,
    /// Truncate the bounce series (0 = direct light only).
    pub bounces: Option<u32>,
    /// Sample points per patch for the naive gather.
    pub naive_samples: usize,
    /// Also compute the light of each emitter material on its own
    /// ([`Responses`]), for light layers and the relight cache.
    pub responses: bool,
    /// Skip nothing: solve every channel on its own, solve the bounce even
    /// where nothing reflects or sees light, gather every floor region and
    /// cull no faint pairs. The full computation that every skip is tested
    /// against; results agree with the default up to each skip's bound.
    pub exhaustive: bool,
}

impl Settings {
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
        }
    }
}

/// Why a level could not be baked.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    #[error("{message}")]
    Unbounded { message: String },
    #[error(transparent)]
    Solve(#[from] SolveError),
}

/// A baked level, with the intermediate results callers may want to keep.
pub struct Baked {
    pub geometry: Geometry,
    pub patches: Patches,
    pub form_factors: Option<FormFactors>,
    /// Radiosity per channel (R, G, B) per patch.
    pub radiosity: [Vec<f64>; 3],
    pub lightmap: Lightmap,
    pub report: Report,
    /// Per-emitter light, when [`Settings::responses`] asked for it.
    pub responses: Option<Responses>,
}

/// The light of every emitter material on its own, per reflectance class:
/// because light is linear in emission, the lightmap for any emission is
/// `sum over emitters m of emission_m[c] * image(m, rho_class_of[c])`.
///
/// Images are row-major `width * height` per unit emission (floor pixels:
/// gathered light; solid pixels: mean radiosity of their exposed sides;
/// void: 0).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Responses {
    pub width: usize,
    pub height: usize,
    /// Indices into [`Level::materials`] of the emitter materials, in order.
    pub emitters: Vec<usize>,
    /// Which reflectance class each channel uses.
    pub rho_class_of: [usize; 3],
    /// Number of reflectance classes (channels with equal reflectance for
    /// every material share one).
    pub rho_classes: usize,
    /// `images[m * rho_classes + r]` for emitter `m` (position in `emitters`).
    pub images: Vec<Vec<f32>>,
    /// The emission the responses were traced with (1; they are stored
    /// divided by it). With falloff, the pairs culled were chosen against it,
    /// independently of the palette's emission.
    pub traced_emission: f64,
}

impl Responses {
    /// The lightmap for `emission[m]` per emitter (in `emitters` order);
    /// negative or non-finite values (never expected) become 0.
    pub fn combine(&self, emission: &[[f64; 3]]) -> Vec<[f32; 3]> {
        let n = self.width * self.height;
        let mut rgb = vec![[0f32; 3]; n];
        for (m, e) in emission.iter().enumerate().take(self.emitters.len()) {
            for c in 0..3 {
                if e[c] == 0.0 {
                    continue;
                }
                let img = &self.images[m * self.rho_classes + self.rho_class_of[c]];
                for (px, v) in rgb.iter_mut().zip(img) {
                    px[c] += (e[c] * *v as f64) as f32;
                }
            }
        }
        for p in &mut rgb {
            for v in p.iter_mut() {
                if !v.is_finite() || *v < 0.0 {
                    *v = 0.0;
                }
            }
        }
        rgb
    }
}

/// Which response vectors a bake traces besides its own channels.
struct ResponsePlan {
    emitters: Vec<usize>,
    rho_class_of: [usize; 3],
    rho_reps: Vec<usize>,
}

impl ResponsePlan {
    fn new(level: &Level, used: &[bool]) -> ResponsePlan {
        let emitters = level
            .materials
            .iter()
            .enumerate()
            .filter(|(i, m)| used[*i] && m.kind == crate::level::material::MaterialKind::Emitter)
            .map(|(i, _)| i)
            .collect();
        let mut rho_class_of = [0; 3];
        let mut rho_reps: Vec<usize> = Vec::new();
        for c in 0..3 {
            let same = |a: usize| {
                level
                    .materials
                    .iter()
                    .zip(used)
                    .all(|(m, &u)| !u || m.reflectance[a] == m.reflectance[c])
            };
            match rho_reps.iter().position(|&r| same(r)) {
                Some(k) => rho_class_of[c] = k,
                None => {
                    rho_class_of[c] = rho_reps.len();
                    rho_reps.push(c);
                }
            }
        }
        ResponsePlan {
            emitters,
            rho_class_of,
            rho_reps,
        }
    }
}

/// Which channels need a solve, and which can copy another or be zero.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelPlan {
    /// For each channel: `Some(k)` = uses the result of distinct class `k`;
    /// `None` = no emission anywhere, the channel is dark.
    pub class_of: [Option<usize>; 3],
    /// A representative channel per distinct class.
    pub classes: Vec<usize>,
}

/// Groups channels whose reflectance and emission are equal for every used
/// material (a grey scene has one class), and drops channels with no emission.
pub fn plan_channels(level: &Level, used: &[bool]) -> ChannelPlan {
    let mut class_of = [None; 3];
    let mut classes: Vec<usize> = Vec::new();
    for c in 0..3 {
        let emits = level
            .materials
            .iter()
            .zip(used)
            .any(|(m, &u)| u && m.emission[c] > 0.0);
        if !emits {
            continue;
        }
        let same = |a: usize, b: usize| {
            level.materials.iter().zip(used).all(|(m, &u)| {
                !u || (m.emission[a] == m.emission[b] && m.reflectance[a] == m.reflectance[b])
            })
        };
        match classes.iter().position(|&r| same(r, c)) {
            Some(k) => class_of[c] = Some(k),
            None => {
                class_of[c] = Some(classes.len());
                classes.push(c);
            }
        }
    }
    ChannelPlan { class_of, classes }
}

const CHANNEL: [&str; 3] = ["red", "green", "blue"];

/// Bakes a level. `progress(stage)` is called as each stage starts.
pub fn bake(
    level: &Level,
    settings: &Settings,
    progress: &dyn Fn(&str),
) -> Result<Baked, BakeError> {
    let t_total = Instant::now();
    let mut timings = Timings::default();
    let mut skipped: Vec<Skip> = Vec::new();
    let mut warnings: Vec<String> = level.warnings.clone();
    let skip = |s: &mut Vec<Skip>, effect: &str, reason: String| {
        s.push(Skip {
            effect: effect.into(),
            reason,
        })
    };
    let falloff = settings.falloff.map(Falloff::new);
    // The exhaustive bake culls no faint pairs.
    let reach_bound = if settings.exhaustive {
        0.0
    } else {
        settings.knobs.reach_bound
    };

    progress("geometry");
    let t = Instant::now();
    let geometry = geometry::trace(level);
    let patches = Patches::new(&geometry, settings.knobs.patch_len);
    timings.geometry = t.elapsed().as_secs_f64();
    let edges = &geometry.edges;
    let np = patches.len();

    // Per-patch materials, per channel.
    let mut used = vec![false; level.materials.len()];
    for e in edges {
        used[e.material as usize] = true;
    }
    let mat = |p: usize| &level.materials[edges[patches.edge[p] as usize].material as usize];
    let rho: [Vec<f64>; 3] =
        std::array::from_fn(|c| (0..np).map(|p| mat(p).reflectance[c]).collect());
    let emit: [Vec<f64>; 3] =
        std::array::from_fn(|c| (0..np).map(|p| mat(p).emission[c]).collect());
    let edge_emit: [Vec<f64>; 3] = std::array::from_fn(|c| {
        edges
            .iter()
            .map(|e| level.materials[e.material as usize].emission[c])
            .collect()
    });

    let floor_pixels = gather::floor_pixels(level);
    if floor_pixels.is_empty() {
        warnings.push("the level has no floor pixels: nothing to light".into());
    }
    if !edges
        .iter()
        .any(|e| level.materials[e.material as usize].emits())
    {
        warnings.push(
            "the level has no emitter pixels facing free space: the lightmap is black".into(),
        );
    }

    let plan = if settings.exhaustive {
        ChannelPlan {
            class_of: [Some(0), Some(1), Some(2)],
            classes: vec![0, 1, 2],
        }
    } else {
        plan_channels(level, &used)
    };
    for c in 0..3 {
        if plan.class_of[c].is_none() {
            skip(
                &mut skipped,
                &format!("{} channel", CHANNEL[c]),
                "no emission in this channel".into(),
            );
        }
    }
    if plan.classes.len() == 1 && plan.class_of.iter().all(Option::is_some) {
        skip(
            &mut skipped,
            "channel solves",
            "grey scene: 1 solve for 3 channels".into(),
        );
    } else {
        for c in 0..3 {
            if let Some(k) = plan.class_of[c]
                && plan.classes[k] != c
            {
                skip(
                    &mut skipped,
                    &format!("{} channel", CHANNEL[c]),
                    format!(
                        "same materials as {}: result shared",
                        CHANNEL[plan.classes[k]]
                    ),
                );
            }
        }
    }

    // Is there any bounce to simulate?
    let any_reflects = plan
        .classes
        .iter()
        .any(|&c| rho[c].iter().any(|&r| r > 0.0));
    let mut need_bounce =
        !plan.classes.is_empty() && (any_reflects || settings.exhaustive) && np > 0;
    if !plan.classes.is_empty() && !any_reflects && !settings.exhaustive {
        skip(&mut skipped, "bounce", "no wall reflects".into());
    }
    if need_bounce && settings.bounces == Some(0) {
        skip(
            &mut skipped,
            "bounce",
            "bounces = 0: direct light only".into(),
        );
        need_bounce = false;
    }
    // Responses trace every emitter material, whatever its palette emission,
    // so that a relight may switch it on.
    let resp_plan = settings.responses.then(|| ResponsePlan::new(level, &used));
    let emitter_patch: Vec<bool> = (0..np)
        .map(|p| mat(p).kind == crate::level::material::MaterialKind::Emitter)
        .collect();
    let mut resp_bounce = resp_plan.as_ref().is_some_and(|rp| {
        !rp.emitters.is_empty()
            && np > 0
            && settings.bounces != Some(0)
            && rp.rho_reps.iter().any(|&c| rho[c].iter().any(|&r| r > 0.0))
    });

    let mut form_factors = None;
    let mut paper_rows: Option<Vec<Vec<(u32, f64)>>> = None;
    let mut point_rows = None;
    let mut culled_pairs = 0u64;
    if need_bounce || resp_bounce {
        progress("form factors");
        let t = Instant::now();
        // Row iterator over whichever F was built, to look for light.
        let sees = |row: &dyn Fn(usize) -> Vec<(usize, f64)>,
                    channels: &[usize],
                    source: &dyn Fn(usize) -> bool| {
            (0..np).any(|i| {
                channels.iter().any(|&c| rho[c][i] > 0.0)
                    && row(i).iter().any(|&(j, f)| j != i && f > 0.0 && source(j))
            })
        };
        let resp_reps: Vec<usize> = resp_plan
            .as_ref()
            .map_or_else(Vec::new, |rp| rp.rho_reps.clone());
        let sees_light = |row: &dyn Fn(usize) -> Vec<(usize, f64)>| {
            (
                sees(row, &plan.classes, &|j| (0..3).any(|c| emit[c][j] > 0.0)),
                sees(row, &resp_reps, &|j| emitter_patch[j]),
            )
        };
        let lit = match settings.kernel {
            Kernel::Flatland => {
                // Factors below the preset's bound are not computed (falloff only).
                let lens: Vec<f64> = edges.iter().map(|e| e.len()).collect();
                let reach = Reach::new(&lens, &vec![1.0; edges.len()], falloff, 0.5, reach_bound);
                let (ff, points, stats) = transport::form_factors(
                    &geometry,
                    &patches,
                    settings.knobs.quad,
                    falloff,
                    &reach,
                );
                culled_pairs += stats.culled_pairs;
                let lit = sees_light(&|i| ff.row(i).collect());
                form_factors = Some(ff);
                point_rows = Some(points);
                lit
            }
            Kernel::Paper => {
                let rows = crate::transport::paper::form_factors(&geometry, &patches, falloff);
                let lit = sees_light(&|i| rows[i].iter().map(|&(j, f)| (j as usize, f)).collect());
                paper_rows = Some(rows);
                lit
            }
        };
        timings.form_factors = t.elapsed().as_secs_f64();
        let (lit, resp_lit) = lit;
        resp_bounce &= resp_lit;
        // Reflecting patches that see no emitter receive nothing: no bounce.
        if need_bounce && !lit && !settings.exhaustive {
            skip(
                &mut skipped,
                "bounce",
                "no reflecting patch sees an emitter".into(),
            );
            need_bounce = false;
        }
    }

    progress("solve");
    let t = Instant::now();
    let mut class_b: Vec<Vec<f64>> = Vec::new();
    let mut solves = 0;
    let mut residual: f64 = 0.0;
    let mut solver = "none".to_string();
    let solve_settings = SolveSettings {
        tolerance: settings.knobs.tolerance,
        ..SolveSettings::default()
    };
    // One channel's solve for emission `e`: (B, residual, solver, rows rescaled).
    let solve_one = |c: usize, e: &[f64]| -> Result<(Vec<f64>, f64, String, usize), BakeError> {
        if let Some(rows) = &paper_rows {
            let (b, rescaled) =
                crate::transport::paper::solve(rows, &rho[c], e, settings.knobs.tolerance);
            return Ok((b, 0.0, "paper".into(), rescaled));
        }
        let ff = form_factors
            .as_ref()
            .expect("flatland kernel builds F when a bounce is needed");
        if let Some(n) = settings.bounces {
            return Ok((
                solve::truncated(ff, &rho[c], e, n),
                0.0,
                "bounces".into(),
                0,
            ));
        }
        let s = solve::solve_channel(ff, &rho[c], e, &solve_settings).map_err(|err| match err {
            SolveError::Unbounded { patches: ps } => BakeError::Unbounded {
                message: unbounded_message(&geometry, &patches, &ps, CHANNEL[c]),
            },
            other => BakeError::Solve(other),
        })?;
        Ok((s.radiosity, s.residual, s.method.to_string(), 0))
    };
    for &c in &plan.classes {
        if !need_bounce {
            class_b.push(emit[c].clone());
            continue;
        }
        solves += 1;
        let (b, res, method, rescaled) = solve_one(c, &emit[c])?;
        residual = residual.max(res);
        solver = method;
        if rescaled > 0 {
            warnings.push(format!(
                "paper kernel, {} channel: {rescaled} rows of rho F summed to 1 or more and were rescaled (F normalised per row, rho F capped at {})",
                CHANNEL[c],
                crate::transport::paper::MAX_ROW
            ));
        }
        class_b.push(b);
    }
    // Response vectors: each emitter material alone at unit emission, once per
    // reflectance class.
    let e_max = level
        .materials
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .flat_map(|(m, _)| m.emission)
        .fold(0.0, f64::max);
    let traced_emission = 1.0;
    let mut resp_b: Vec<Vec<f64>> = Vec::new();
    let mut resp_rho: Vec<usize> = Vec::new();
    let mut resp_edge_e: Vec<Vec<f64>> = Vec::new();
    if let Some(rp) = &resp_plan {
        for &m in &rp.emitters {
            let e: Vec<f64> = (0..np)
                .map(|p| {
                    if edges[patches.edge[p] as usize].material as usize == m {
                        traced_emission
                    } else {
                        0.0
                    }
                })
                .collect();
            let ee: Vec<f64> = edges
                .iter()
                .map(|ed| {
                    if ed.material as usize == m {
                        traced_emission
                    } else {
                        0.0
                    }
                })
                .collect();
            for &c in &rp.rho_reps {
                let b = if resp_bounce {
                    solve_one(c, &e)
                        .map_err(|err| match err {
                            BakeError::Unbounded { message } => BakeError::Unbounded {
                                message: format!("light layers: {message}"),
                            },
                            other => other,
                        })?
                        .0
                } else {
                    e.clone()
                };
                resp_b.push(b);
                resp_rho.push(c);
                resp_edge_e.push(ee.clone());
            }
        }
    }
    timings.solve = t.elapsed().as_secs_f64();

    // Energy, per channel, summed.
    let mut energy = Energy::default();
    for c in 0..3 {
        let Some(k) = plan.class_of[c] else { continue };
        let b = &class_b[k];
        let (em, ab, es) = energy_balance(form_factors.as_ref(), &patches, &rho[c], &emit[c], b);
        energy.emitted += em;
        energy.absorbed += ab;
        energy.escaped += es;
    }

    // Gather.
    progress("gather");
    let t = Instant::now();
    // Components gathered together (visibility found once per pixel): the
    // bake's own channel classes, then the response vectors.
    let k_main = class_b.len();
    let kk = k_main + resp_b.len();
    let mut edge_e: Vec<Vec<f64>> = plan.classes.iter().map(|&c| edge_emit[c].clone()).collect();
    edge_e.extend(resp_edge_e);
    // Linear profiles along patches from the radiosity at the quadrature points.
    let slopes: Vec<Vec<f64>> = match &point_rows {
        Some(pr) if need_bounce || resp_bounce => {
            let mut v: Vec<Vec<f64>> = plan
                .classes
                .iter()
                .zip(&class_b)
                .map(|(&c, b)| {
                    if need_bounce {
                        pr.slopes(&patches, &rho[c], &emit[c], b)
                    } else {
                        vec![0.0; np]
                    }
                })
                .collect();
            for (j, b) in resp_b.iter().enumerate() {
                v.push(if resp_bounce {
                    // The emission of this vector, per patch.
                    let e: Vec<f64> = (0..np)
                        .map(|p| edge_e[k_main + j][patches.edge[p] as usize])
                        .collect();
                    pr.slopes(&patches, &rho[resp_rho[j]], &e, b)
                } else {
                    vec![0.0; np]
                });
            }
            v
        }
        _ => Vec::new(),
    };
    let mut all_b = class_b.clone();
    all_b.extend(resp_b.iter().cloned());
    let rad = Radiosity::new(&patches, &all_b, &slopes, &edge_e);
    // With falloff, pairs whose light is below the preset's bound (relative
    // to the brightest emission) are not gathered.
    // With responses, the lightmap is made of them alone, and the reach comes
    // from them alone (unit emission, bound relative to it): then what is
    // culled does not depend on emission, and a relight with any emission is
    // exactly the bake of that emission. Each culled pair still stays below
    // reach_bound x its emitter's emission.
    let (reach_comps, reach_threshold) = if resp_b.is_empty() {
        (0..kk, reach_bound * e_max)
    } else {
        (k_main..kk, reach_bound * traced_emission)
    };
    let reach = {
        let bmax: Vec<f64> = (0..edges.len())
            .map(|ei| {
                let mut m: f64 = 0.0;
                for p in patches.of_edge(ei) {
                    for c in reach_comps.clone() {
                        m = m.max(
                            rad.patch(&patches, p, c)
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
            falloff,
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
    let (reached, unreached): (Vec<[i32; 2]>, Vec<[i32; 2]>) = floor_pixels.iter().partition(|p| {
        kk > 0
            && (settings.exhaustive
                || lit_comp
                    [geometry.components[p[1] as usize * level.width + p[0] as usize] as usize])
    });
    if !unreached.is_empty() && kk > 0 {
        skip(
            &mut skipped,
            "gather",
            format!(
                "{} floor pixels in regions no light reaches",
                unreached.len()
            ),
        );
    }
    let mut unreached_in_reach = 0usize;
    let values = if kk == 0 || reached.is_empty() {
        Vec::new()
    } else {
        match settings.gather {
            GatherMethod::Fast => {
                let (v, stats, counts) = gather::gather(
                    &geometry,
                    &patches,
                    &rad,
                    falloff,
                    settings.kernel,
                    &reached,
                    &reach,
                    reach_threshold,
                    reach_comps.clone(),
                );
                culled_pairs += stats.culled_pairs;
                unreached_in_reach = stats.unreached as usize;
                if reach_bound > 0.0 && counts.pieces < counts.patch_pieces {
                    skip(
                        &mut skipped,
                        "distant patches",
                        format!(
                            "reflected light gathered as {} pieces for {} patch pieces (nearly quadratic runs far from the pixel taken whole; error at most {:e} of the brightest emission per pixel)",
                            counts.pieces, counts.patch_pieces, reach_bound
                        ),
                    );
                }
                v
            }
            GatherMethod::Naive => gather::gather_naive(
                &geometry,
                &patches,
                &rad,
                falloff,
                settings.kernel,
                &reached,
                settings.naive_samples,
            ),
        }
    };
    if unreached_in_reach > 0 {
        skip(
            &mut skipped,
            "gather",
            format!(
                "{unreached_in_reach} floor pixels that no lit edge reaches: every one is hidden from them or beyond its falloff reach (left at 0)"
            ),
        );
    }
    if culled_pairs > 0 {
        skip(
            &mut skipped,
            "falloff reach",
            format!(
                "{culled_pairs} edge-point pairs whose light would be below {:e} of the brightest emission",
                reach_bound
            ),
        );
    }
    let mut rgb = vec![[0f32; 3]; level.width * level.height];
    for (i, p) in reached.iter().enumerate() {
        let px = &mut rgb[p[1] as usize * level.width + p[0] as usize];
        for c in 0..3 {
            if let Some(k) = plan.class_of[c] {
                px[c] = light_f32(values[i * kk + k]);
            }
        }
    }
    let responses = resp_plan.map(|rp| {
        let n = level.width * level.height;
        let zeros = vec![0.0; np];
        let images = resp_b
            .iter()
            .enumerate()
            .map(|(j, b)| {
                let mut img = vec![[0f32; 3]; n];
                for (i, p) in reached.iter().enumerate() {
                    img[p[1] as usize * level.width + p[0] as usize][0] =
                        values[i * kk + k_main + j] as f32;
                }
                let one = [b.clone(), zeros.clone(), zeros.clone()];
                solid_pixels(level, &geometry, &patches, &one, &mut img);
                img.iter()
                    .map(|v| (v[0] as f64 / traced_emission) as f32)
                    .collect()
            })
            .collect();
        Responses {
            width: level.width,
            height: level.height,
            emitters: rp.emitters,
            rho_class_of: rp.rho_class_of,
            rho_classes: rp.rho_reps.len(),
            images,
            traced_emission,
        }
    });
    // Solid pixels: mean radiosity of their exposed sides.
    let radiosity: [Vec<f64>; 3] = std::array::from_fn(|c| {
        plan.class_of[c].map_or_else(|| vec![0.0; np], |k| class_b[k].clone())
    });
    solid_pixels(level, &geometry, &patches, &radiosity, &mut rgb);
    // With responses, the lightmap is their sum at the palette's emission, so
    // that layers (and a relight with unchanged emission) add up to it
    // exactly. It differs from the direct result only where the positivity
    // limiter on patch slopes (`PointRows::slopes`) acts differently on one
    // emitter's light than on the sum, a small fraction of a percent.
    if let Some(r) = &responses {
        let e: Vec<[f64; 3]> = r
            .emitters
            .iter()
            .map(|&m| level.materials[m].emission)
            .collect();
        rgb = r.combine(&e);
    }
    timings.gather = t.elapsed().as_secs_f64();
    timings.total = t_total.elapsed().as_secs_f64();

    if rgb
        .iter()
        .any(|p| p.iter().any(|v| !v.is_finite() || *v < 0.0))
    {
        // Never hand out NaN or negative light: this would be a bug upstream.
        warnings.push(
            "non-finite or negative light was clamped to 0 (please report this level)".into(),
        );
        for p in &mut rgb {
            for v in p.iter_mut() {
                if !v.is_finite() || *v < 0.0 {
                    *v = 0.0;
                }
            }
        }
    }

    let report = Report {
        level: level.name.clone(),
        size: [level.width, level.height],
        quality: settings.quality.name().into(),
        kernel: match settings.kernel {
            Kernel::Flatland => "flatland".into(),
            Kernel::Paper => "paper".into(),
        },
        gather: match settings.gather {
            GatherMethod::Fast => "fast".into(),
            GatherMethod::Naive => "naive".into(),
        },
        falloff: settings.falloff,
        bounces: settings.bounces,
        counts: Counts {
            edges: edges.len(),
            patches: np,
            floor_pixels: floor_pixels.len(),
            form_factor_entries: form_factors.as_ref().map_or_else(
                || {
                    paper_rows
                        .as_ref()
                        .map_or(0, |r| r.iter().map(Vec::len).sum())
                },
                FormFactors::nnz,
            ),
            unreached_pixels: if kk > 0 {
                unreached.len() + unreached_in_reach
            } else {
                floor_pixels.len()
            },
            culled_pairs,
        },
        timings,
        solves,
        residual,
        solver,
        energy,
        skipped,
        warnings,
        outputs: vec![],
        version: env!("CARGO_PKG_VERSION").into(),
    };
    Ok(Baked {
        geometry,
        patches,
        form_factors,
        radiosity,
        lightmap: Lightmap {
            width: level.width,
            height: level.height,
            rgb,
        },
        report,
        responses,
    })
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
    let (mut em, mut ab, mut es) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let d = ff.dlen[i];
        let h: f64 = ff.row(i).map(|(j, f)| f * b[j]).sum();
        em += d * e[i];
        ab += d * (1.0 - rho[i]) * h;
        es += d * b[i] * (1.0 - ff.coverage[i]);
    }
    (em, ab, es)
}

fn unbounded_message(g: &Geometry, patches: &Patches, ps: &[usize], channel: &str) -> String {
    let (mut x0, mut y0, mut x1, mut y1) = (i32::MAX, i32::MAX, i32::MIN, i32::MIN);
    for &p in ps {
        let e = &g.edges[patches.edge[p] as usize];
        for q in [e.a, e.b] {
            x0 = x0.min(q[0]);
            y0 = y0.min(q[1]);
            x1 = x1.max(q[0]);
            y1 = y1.max(q[1]);
        }
    }
    format!(
        "the closed region within pixels ({x0},{y0})-({x1},{y1}) has walls of reflectance 1 in the {channel} channel and contains an emitter: no light can leave, so its brightness has no finite value; lower a reflectance below 1 or open the region"
    )
}

/// Light as stored in the lightmap: values beyond the f32 range saturate at
/// the largest f32 instead of becoming infinite (which the final check would
/// clamp to black); NaN stays NaN so that the check still catches it.
fn light_f32(v: f64) -> f32 {
    if v > f32::MAX as f64 {
        f32::MAX
    } else {
        v as f32
    }
}

/// Fills solid pixels with the mean radiosity of their exposed sides.
fn solid_pixels(
    level: &Level,
    g: &Geometry,
    patches: &Patches,
    b: &[Vec<f64>; 3],
    rgb: &mut [[f32; 3]],
) {
    let w = level.width;
    let mut sum = vec![[0f64; 3]; level.width * level.height];
    let mut count = vec![0u32; level.width * level.height];
    for (ei, e) in g.edges.iter().enumerate() {
        let (lo, hi) = e.extent();
        let range = patches.of_edge(ei);
        let step = patches.step[ei];
        for u in lo as i32..hi as i32 {
            let px = e.solid_pixel_at(u);
            let i = px[1] as usize * w + px[0] as usize;
            // Length-weighted mean of the patches covering [u, u + 1].
            let (a, bnd) = (u as f64, u as f64 + 1.0);
            let k0 = (((a - lo) / step).floor() as usize).min(range.len() - 1);
            let mut v = [0f64; 3];
            let mut k = k0;
            while k < range.len() {
                let (s0, s1) = (lo + k as f64 * step, lo + (k + 1) as f64 * step);
                let ov = s1.min(bnd) - s0.max(a);
                if ov > 0.0 {
                    for c in 0..3 {
                        v[c] += ov * b[c][range.start + k];
                    }
                }
                if s1 >= bnd {
                    break;
                }
                k += 1;
            }
            for c in 0..3 {
                sum[i][c] += v[c];
            }
            count[i] += 1;
        }
    }
    for (i, cell) in level.cells.iter().enumerate() {
        if matches!(cell, Cell::Solid(_)) && count[i] > 0 {
            rgb[i] = [0, 1, 2].map(|c| light_f32(sum[i][c] / count[i] as f64));
        }
    }
}
