//! Gathering light onto floor pixels (docs/transport.md#floor-gather):
//! `I(p) = 1/(2 pi) * integral over directions of B(first hit) * w(distance)`.
//!
//! The fast gather finds exactly which stretches of which edges a pixel
//! centre sees ([`crate::visibility`]) and integrates them in closed form
//! ([`crate::transport::kernel`]). An edge's emission is uniform along it, so it is one
//! term per visible stretch: direct light is exact at every quality. Only the
//! reflected part `B - E`, which lives on patches, is walked patch by patch,
//! and only on edges that reflect anything.
//!
//! The naive gather is the paper's method, kept as the yardstick for speed:
//! per pixel, per patch, a few sample points on the patch, each ray tested
//! against every edge.

mod directional;
mod fast;
pub mod lattice;
mod local;
mod naive;
mod patch_tree;

pub use fast::{
    Gather, GatherCounts, GatherOptions, LAMP_FAR, Lighting, OUTER, OnProgress, PixelScratch,
    floor_pixels, gather, gather_with_moments, pixel_light,
};
pub use local::{FAR_LAMPS, FAR_SCALE, LAMP_SHARE};
pub use naive::gather_naive;
pub use patch_tree::PatchTree;

use crate::transport::Patches;

/// Radiosity in a form the gather can use: `components` values per edge
/// (uniform emission) and per patch (reflected light `B - E`).
#[derive(Clone, Debug)]
pub struct Radiosity {
    /// Values per edge and per patch (channels, or lights for responses).
    pub components: usize,
    /// `edge_emission[e * components + k]`.
    pub edge_emission: Vec<f64>,
    /// `reflected[p * components + k]`, the patch's mean `B - E`.
    pub reflected: Vec<f64>,
    /// `slope[p * components + k]`: `B` varies linearly along the patch with
    /// this slope (per unit of the edge's axis coordinate) around its mean.
    pub slope: Vec<f64>,
    /// Edges with some non-zero reflected light.
    pub edge_reflects: Vec<bool>,
    /// Edges with some non-zero emission.
    pub edge_emits: Vec<bool>,
}

impl Radiosity {
    /// From per-patch radiosity `b[k][p]`, slopes `g[k][p]` (empty for flat
    /// patches) and per-edge emission `e[k][edge]`.
    pub fn new(patches: &Patches, b: &[Vec<f64>], g: &[Vec<f64>], e: &[Vec<f64>]) -> Radiosity {
        let k = b.len();
        let edges = patches.first.len() - 1;
        let mut edge_emission = vec![0.0; edges * k];
        let mut reflected = vec![0.0; patches.len() * k];
        let mut slope = vec![0.0; patches.len() * k];
        let mut edge_reflects = vec![false; edges];
        let mut edge_emits = vec![false; edges];
        for c in 0..k {
            for ed in 0..edges {
                edge_emission[ed * k + c] = e[c][ed];
                edge_emits[ed] |= e[c][ed] != 0.0;
                for p in patches.of_edge(ed) {
                    let r = b[c][p] - e[c][ed];
                    reflected[p * k + c] = r;
                    let s = g.get(c).and_then(|v| v.get(p)).copied().unwrap_or(0.0);
                    slope[p * k + c] = s;
                    edge_reflects[ed] |= r != 0.0 || s != 0.0;
                }
            }
        }
        Radiosity {
            components: k,
            edge_emission,
            reflected,
            slope,
            edge_reflects,
            edge_emits,
        }
    }

    /// Radiosity of patch `p` in component `k`.
    pub fn patch(&self, patches: &Patches, p: usize, k: usize) -> f64 {
        let e = patches.edge[p] as usize;
        self.edge_emission[e * self.components + k] + self.reflected[p * self.components + k]
    }
}

/// Which kernel turns radiosity into pixel light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// Exact flatland transport (docs/transport.md#radiosity-equation).
    Flatland,
    /// The paper's equation 5: `A cos(theta) / (A + r^2) * Vis` per patch.
    Paper,
}

impl Kernel {
    /// The kernel's name, as on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Kernel::Flatland => "flatland",
            Kernel::Paper => "paper",
        }
    }
}

/// `N` counters summed over parallel tasks, one slot per worker thread of
/// the current rayon pool (and one for any other thread), each on its own
/// cache line: a thread adds to its own slot without contention, and no
/// task keeps counts of its own to be summed afterwards.
pub(crate) struct PerThread<const N: usize> {
    slots: Vec<Slot<N>>,
}

#[repr(align(64))]
struct Slot<const N: usize>([std::sync::atomic::AtomicU64; N]);

impl<const N: usize> PerThread<N> {
    pub(crate) fn new() -> Self {
        PerThread {
            slots: (0..=rayon::current_num_threads())
                .map(|_| Slot(std::array::from_fn(|_| Default::default())))
                .collect(),
        }
    }

    /// Adds `v` to this thread's counters.
    pub(crate) fn add(&self, v: [u64; N]) {
        use std::sync::atomic::Ordering::Relaxed;
        let last = self.slots.len() - 1;
        let slot = &self.slots[rayon::current_thread_index().map_or(last, |t| t.min(last))];
        for (c, v) in slot.0.iter().zip(v) {
            c.fetch_add(v, Relaxed);
        }
    }

    /// The counters summed over every thread.
    pub(crate) fn sum(&self) -> [u64; N] {
        use std::sync::atomic::Ordering::Relaxed;
        std::array::from_fn(|c| self.slots.iter().map(|s| s.0[c].load(Relaxed)).sum())
    }
}

/// Shared output slice written at disjoint indices from parallel tasks.
pub(crate) struct Disjoint<'a, T> {
    ptr: *mut T,
    len: usize,
    _life: std::marker::PhantomData<&'a mut [T]>,
}

// SAFETY: callers only write each index from one task at a time.
unsafe impl<T: Send> Sync for Disjoint<'_, T> {}

impl<'a, T> Disjoint<'a, T> {
    pub(crate) fn new(s: &'a mut [T]) -> Self {
        Disjoint {
            ptr: s.as_mut_ptr(),
            len: s.len(),
            _life: std::marker::PhantomData,
        }
    }
    /// # Safety
    /// No other task may access index `i` concurrently.
    pub(crate) unsafe fn write(&self, i: usize, v: T) {
        assert!(i < self.len);
        // SAFETY: in bounds (checked above); exclusive per the caller's contract.
        unsafe { *self.ptr.add(i) = v };
    }
}
