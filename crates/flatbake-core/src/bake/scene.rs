//! The first stage: the resolved level's walls traced into edges, cut into
//! patches, and each patch's material read out as numbers per channel.
//!
//! Later stages never look at the level's materials again: what a patch
//! emits and reflects is in [`Scene`], per channel.

use rayon::prelude::*;

use crate::geometry::{self, Geometry};
use crate::level::Level;
use crate::level::material::MaterialKind;
use crate::quality::Knobs;
use crate::transport::Patches;

/// A traced level with its materials resolved per patch and per edge.
pub struct Scene {
    /// The traced walls.
    pub geometry: Geometry,
    /// Every edge cut into patches no longer than the preset's patch length
    /// (and its multiple of the edge's clearance).
    pub patches: Patches,
    /// Which of the level's materials some edge is made of.
    pub used: Vec<bool>,
    /// Reflectance per channel, per patch.
    pub rho: [Vec<f64>; 3],
    /// Emission per channel, per patch.
    pub emit: [Vec<f64>; 3],
    /// Emission per channel, per edge.
    pub edge_emit: [Vec<f64>; 3],
    /// Patches of an emitter material, whatever its emission (a relight may
    /// switch on an emitter the palette leaves at 0).
    pub emitter_patch: Vec<bool>,
    /// The floor pixels, the query points of the gather.
    pub floor_pixels: Vec<[i32; 2]>,
    /// Edges given no patches: they face a closed region with no emitter,
    /// where no light can arrive, so their radiosity is exactly 0.
    pub dark_edges: usize,
}

impl Scene {
    /// Traces `level` and cuts its edges into patches as `knobs` set their
    /// length ([`Patches::new_where`]).
    pub fn new(level: &Level, knobs: &Knobs, exhaustive: bool) -> Scene {
        let geometry = geometry::trace(level);
        let lit = lit_components(level, &geometry);
        let edges = &geometry.edges;
        let keep = |e: usize| exhaustive || lit[edges[e].component as usize];
        let dark_edges = (0..edges.len()).filter(|&e| !keep(e)).count();
        let patches = Patches::new_where(&geometry, knobs.patch_len, knobs.per_clearance, keep);
        let np = patches.len();
        let mut used = vec![false; level.materials.len()];
        for e in edges {
            used[e.material as usize] = true;
        }
        // Read out per patch on the workers: on wall noise (180,000
        // patches) this took 11 ms on one core.
        let mat = |p: usize| &level.materials[edges[patches.edge[p] as usize].material as usize];
        let per_patch =
            |f: &(dyn Fn(usize) -> f64 + Sync)| (0..np).into_par_iter().map(f).collect();
        let rho = std::array::from_fn(|c| per_patch(&|p| mat(p).reflectance[c]));
        let emit = std::array::from_fn(|c| per_patch(&|p| mat(p).emission[c]));
        let edge_emit = std::array::from_fn(|c| {
            edges
                .par_iter()
                .map(|e| level.materials[e.material as usize].emission[c])
                .collect()
        });
        let emitter_patch = (0..np)
            .into_par_iter()
            .map(|p| mat(p).kind == MaterialKind::Emitter)
            .collect();
        Scene {
            dark_edges,
            floor_pixels: crate::gather::floor_pixels(level),
            geometry,
            patches,
            used,
            rho,
            emit,
            edge_emit,
            emitter_patch,
        }
    }

    /// Number of patches.
    pub fn patch_count(&self) -> usize {
        self.patches.len()
    }

    /// True when some edge's material emits light.
    pub fn has_emitters(&self, level: &Level) -> bool {
        self.geometry
            .edges
            .iter()
            .any(|e| level.materials[e.material as usize].emits())
    }

    /// True when some patch reflects in one of `channels`.
    pub fn reflects(&self, channels: &[usize]) -> bool {
        channels
            .iter()
            .any(|&c| self.rho[c].iter().any(|&r| r > 0.0))
    }
}

/// Which free-space components light can reach: those that some edge of an
/// emitter material faces (whatever its emission, since a relight may switch
/// it on). Light never passes between components, so every other one stays
/// dark exactly.
fn lit_components(level: &Level, geometry: &Geometry) -> Vec<bool> {
    let mut lit = vec![false; geometry.component_count as usize];
    for e in &geometry.edges {
        let m = &level.materials[e.material as usize];
        if m.kind == MaterialKind::Emitter || m.emits() {
            lit[e.component as usize] = true;
        }
    }
    lit
}
