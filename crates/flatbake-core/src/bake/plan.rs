//! The second stage: what this scene calls for. It looks at the materials
//! before anything is simulated and decides which channels need a solve,
//! whether there is a bounce to solve at all, and which per-emitter
//! responses to trace; every effect it leaves out goes into the report's
//! `skipped` list with the reason.

use super::{Ctx, Log, Scene};
use crate::level::Level;
use crate::level::material::MaterialKind;

/// The names of the channels, for messages.
pub const CHANNEL: [&str; 3] = ["red", "green", "blue"];

/// What a bake computes, decided before simulating.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// Which channels are solved, shared or dark.
    pub channels: ChannelPlan,
    /// Solve the bounce of the bake's own channels (otherwise the radiosity
    /// is the emission).
    pub bounce: bool,
    /// The per-emitter responses to trace, for layers and caches.
    pub responses: Option<ResponsePlan>,
    /// Solve the bounce of the responses.
    pub response_bounce: bool,
}

impl Plan {
    /// Plans a bake of `scene`; records what it skips, and a problem for a
    /// level with nothing to light or nothing that emits ([`super::checks`]).
    pub fn new(ctx: &Ctx, scene: &Scene, log: &mut Log) -> Plan {
        let (level, settings) = (ctx.level, ctx.settings);
        super::checks::level(level, scene, log);
        let channels = if settings.exhaustive {
            ChannelPlan::every_channel()
        } else {
            plan_channels(level, &scene.used)
        };
        channels.log_skips(log);

        let np = scene.patch_count();
        let any_reflects = scene.reflects(&channels.classes);
        let lit = !channels.classes.is_empty();
        let mut bounce = lit && (any_reflects || settings.exhaustive) && np > 0;
        if scene.dark_edges > 0 {
            log.skip(
                "patches",
                format!(
                    "{} edges facing closed regions with no emitter, where no light can arrive (their radiosity is 0)",
                    scene.dark_edges
                ),
            );
        }
        if lit && !any_reflects && !settings.exhaustive {
            log.skip(
                "bounce",
                if scene.dark_edges > 0 {
                    "no wall that light can reach reflects"
                } else {
                    "no wall reflects"
                },
            );
        }
        if bounce && settings.bounces == Some(0) {
            log.skip("bounce", "bounces = 0: direct light only");
            bounce = false;
        }
        // Responses trace every emitter material, whatever its palette
        // emission, so that a relight may switch it on.
        let responses = settings
            .responses
            .then(|| ResponsePlan::new(level, &scene.used));
        let response_bounce = responses.as_ref().is_some_and(|rp| {
            !rp.emitters.is_empty()
                && np > 0
                && settings.bounces != Some(0)
                && scene.reflects(&rp.rho_reps)
        });
        Plan {
            channels,
            bounce,
            responses,
            response_bounce,
        }
    }

    /// True when form factors are needed: some bounce is to be solved.
    pub fn needs_form_factors(&self) -> bool {
        self.bounce || self.response_bounce
    }
}

/// Which channels need a solve, and which can scale another's or be zero.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelPlan {
    /// For each channel: `Some(k)` = `scale[c]` times the result of
    /// distinct class `k`; `None` = no emission anywhere, the channel is
    /// dark.
    pub class_of: [Option<usize>; 3],
    /// A representative channel per distinct class: its brightest channel.
    pub classes: Vec<usize>,
    /// For each channel: the factor on its class's result (1 for the
    /// representative and for channels equal to it; 0 for dark channels).
    pub scale: [f64; 3],
}

impl ChannelPlan {
    /// Every channel solved on its own (the exhaustive bake).
    pub fn every_channel() -> ChannelPlan {
        ChannelPlan {
            class_of: [Some(0), Some(1), Some(2)],
            classes: vec![0, 1, 2],
            scale: [1.0; 3],
        }
    }

    /// Records the dark channels and the shared solves.
    fn log_skips(&self, log: &mut Log) {
        for c in 0..3 {
            if self.class_of[c].is_none() {
                log.skip(
                    format!("{} channel", CHANNEL[c]),
                    "no emission in this channel",
                );
            }
        }
        let scaled = (0..3).any(|c| self.class_of[c].is_some() && self.scale[c] != 1.0);
        if self.classes.len() == 1 && self.class_of.iter().all(Option::is_some) {
            let reason = if scaled {
                "one light colour, grey walls: 3 channels solved and gathered as 1, scaled"
            } else {
                "grey scene: 1 solve for 3 channels"
            };
            log.skip("channel solves", reason);
            return;
        }
        for c in 0..3 {
            if let Some(k) = self.class_of[c]
                && self.classes[k] != c
            {
                let rep = CHANNEL[self.classes[k]];
                log.skip(
                    format!("{} channel", CHANNEL[c]),
                    if self.scale[c] == 1.0 {
                        format!("same materials as {rep}: result shared")
                    } else {
                        format!(
                            "same reflectance as {rep}, emission {} times it: result scaled",
                            self.scale[c]
                        )
                    },
                );
            }
        }
    }
}

/// Groups channels whose reflectance is equal and whose emission is in one
/// ratio for every used material (a grey scene has one class, and so has a
/// scene of grey walls and lights of one colour), and drops channels with
/// no emission. The light is linear in the emission, so a channel whose
/// emission is `k` times its class's is `k` times its class's answer.
pub fn plan_channels(level: &Level, used: &[bool]) -> ChannelPlan {
    let materials = || {
        level
            .materials
            .iter()
            .zip(used)
            .filter(|(_, u)| **u)
            .map(|(m, _)| m)
    };
    // The ratio of channel `a`'s emission to channel `b`'s where it is the
    // same for every used material (within rounding), else `None`.
    let ratio = |a: usize, b: usize| {
        let rho_same = materials().all(|m| m.reflectance[a] == m.reflectance[b]);
        let top = materials().max_by(|x, y| x.emission[b].total_cmp(&y.emission[b]))?;
        if !rho_same || top.emission[b] <= 0.0 {
            return None;
        }
        let k = top.emission[a] / top.emission[b];
        materials()
            .all(|m| {
                let (ea, eb) = (m.emission[a], m.emission[b]);
                (ea - k * eb).abs() <= 1e-12 * ea.abs().max(eb.abs())
            })
            .then_some(k)
    };
    let emits = |c: usize| materials().any(|m| m.emission[c] > 0.0);
    // Channels grouped with their emission's ratio to the group's first.
    let mut groups: Vec<Vec<(usize, f64)>> = Vec::new();
    for c in (0..3).filter(|&c| emits(c)) {
        let joined = groups
            .iter_mut()
            .find_map(|g| ratio(c, g[0].0).map(|k| (g, k)));
        match joined {
            Some((g, k)) => g.push((c, k)),
            None => groups.push(vec![(c, 1.0)]),
        }
    }
    let mut class_of = [None; 3];
    let mut classes = Vec::with_capacity(groups.len());
    let mut scale = [0.0; 3];
    for (i, g) in groups.iter().enumerate() {
        // The brightest channel represents the group (the first of equals),
        // so that the others are its answer times at most 1 and the bounds
        // relative to the brightest emission hold for them.
        let (rep, top) = g
            .iter()
            .copied()
            .fold(g[0], |best, (c, k)| if k > best.1 { (c, k) } else { best });
        classes.push(rep);
        for &(c, k) in g {
            class_of[c] = Some(i);
            scale[c] = if c == rep { 1.0 } else { k / top };
        }
    }
    ChannelPlan {
        class_of,
        classes,
        scale,
    }
}

/// Which response vectors a bake traces besides its own channels: every
/// emitter material on its own, once per reflectance class.
#[derive(Clone, Debug, PartialEq)]
pub struct ResponsePlan {
    /// Indices into [`Level::materials`] of the emitter materials, in order.
    pub emitters: Vec<usize>,
    /// Which reflectance class each channel uses.
    pub rho_class_of: [usize; 3],
    /// A representative channel per reflectance class.
    pub rho_reps: Vec<usize>,
}

impl ResponsePlan {
    /// The emitter materials some edge uses, and the channels whose
    /// reflectance is equal for every used material, grouped.
    pub fn new(level: &Level, used: &[bool]) -> ResponsePlan {
        let emitters = level
            .materials
            .iter()
            .enumerate()
            .filter(|(i, m)| used[*i] && m.kind == MaterialKind::Emitter)
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
