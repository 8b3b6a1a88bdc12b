//! Patches: every edge cut into equal pieces no longer than the patch length,
//! and, where a preset asks, no longer than a multiple of the free distance
//! in front of the edge ([`clearance`]).

use std::ops::Range;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{Edge, Geometry, Normal};
use crate::visibility::Span;

/// Patches: every edge cut into equal pieces.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Patches {
    /// Patches of edge `e` are `first[e]..first[e + 1]`.
    pub first: Vec<u32>,
    /// Patch length on each edge.
    pub step: Vec<f64>,
    /// Edge of each patch.
    pub edge: Vec<u32>,
    /// Per edge: the length over which a preset's quadrature points are
    /// spread ([`Patches::points`]): the patch length, or the edge's own
    /// patch length where those keep every point (shortened by the
    /// clearance rule, or meeting a concave corner).
    pub spread: Vec<f64>,
}

impl Patches {
    /// Cuts every edge into `ceil(len / patch_len)` equal patches.
    pub fn new(geometry: &Geometry, patch_len: f64) -> Patches {
        Patches::new_where(geometry, patch_len, None, |_| true)
    }

    /// Cuts the edges that `keep` says may carry light into equal patches
    /// no longer than `patch_len` and, with `per_clearance` = `Some(k)`, no
    /// longer than `k` times the edge's [`clearance`]; gives the others none
    /// (their radiosity is 0 and nothing reads it).
    pub fn new_where(
        geometry: &Geometry,
        patch_len: f64,
        per_clearance: Option<f64>,
        keep: impl Fn(usize) -> bool + Sync,
    ) -> Patches {
        // Per edge, its patch count and spread, found on the workers (the
        // clearances read the level around each edge).
        let cut: Vec<(usize, f64)> = geometry
            .edges
            .par_iter()
            .enumerate()
            .map(|(i, e)| {
                if !keep(i) {
                    return (0, patch_len);
                }
                let len = e.len();
                let longest = match per_clearance {
                    // Clearances past patch_len / k cannot shorten a patch.
                    Some(k) if k < patch_len => {
                        let cap = (patch_len / k).ceil() as usize;
                        patch_len.min(k * clearance(geometry, e, cap) as f64)
                    }
                    _ => patch_len,
                };
                let n = ((len / longest).ceil() as usize).max(1);
                // Patches its clearance shortened, or beside a concave
                // corner, keep every point: the light they exchange with
                // walls a pixel or two away varies steeply along them.
                let keeps_all = longest < patch_len || concave_end(geometry, e);
                (n, if keeps_all { len / n as f64 } else { patch_len })
            })
            .collect();
        let mut first = Vec::with_capacity(geometry.edges.len() + 1);
        let mut step = Vec::with_capacity(geometry.edges.len());
        let mut edge = Vec::new();
        let mut spread = Vec::with_capacity(geometry.edges.len());
        first.push(0);
        for (i, (e, &(n, over))) in geometry.edges.iter().zip(&cut).enumerate() {
            step.push(e.len() / n as f64);
            spread.push(over);
            edge.extend(std::iter::repeat_n(i as u32, n));
            first.push(edge.len() as u32);
        }
        Patches {
            first,
            step,
            edge,
            spread,
        }
    }

    /// How many of a preset's `q` quadrature points patch `p` takes: as
    /// many as keep them no farther apart than `q` points on the edge's
    /// [`Patches::spread`], `ceil(q L_p / spread)`, at least 1 and at most
    /// `q`. A one-pixel face of a pillar in the open is a patch a quarter
    /// of `normal`'s length and takes one point; a patch that its
    /// clearance shortened, or that meets a concave corner, keeps all `q`.
    pub fn points(&self, p: usize, q: usize) -> usize {
        let e = self.edge[p] as usize;
        // The relative slack keeps a patch as long as the spread, cut with
        // rounding, at `q`.
        let share = self.step[e] / self.spread[e] * (1.0 - 1e-9);
        ((q as f64 * share).ceil() as usize).clamp(1, q)
    }

    /// Number of patches.
    pub fn len(&self) -> usize {
        self.edge.len()
    }

    /// No patches (a level without walls).
    pub fn is_empty(&self) -> bool {
        self.edge.is_empty()
    }

    /// The patches of edge `e`, in order along it.
    pub fn of_edge(&self, e: usize) -> Range<usize> {
        self.first[e] as usize..self.first[e + 1] as usize
    }

    /// Length of patch `p`.
    pub fn length(&self, p: usize) -> f64 {
        self.step[self.edge[p] as usize]
    }

    /// Axis range `[s0, s1]` of patch `p` on its edge.
    pub fn bounds(&self, edges: &[Edge], p: usize) -> (f64, f64) {
        let e = self.edge[p] as usize;
        let (lo, hi) = edges[e].extent();
        let k = p - self.first[e] as usize;
        let n = self.first[e + 1] as usize - self.first[e] as usize;
        let h = self.step[e];
        let s0 = lo + k as f64 * h;
        let s1 = if k + 1 == n {
            hi
        } else {
            lo + (k + 1) as f64 * h
        };
        (s0, s1)
    }

    /// Calls `f(patch, a, b)` for each patch of the span's edge that overlaps
    /// the span, with `[a, b]` the overlap (axis coordinates, in order).
    #[inline]
    pub fn for_each_piece(&self, edges: &[Edge], span: &Span, mut f: impl FnMut(usize, f64, f64)) {
        let e = span.edge as usize;
        let (lo, _) = edges[e].extent();
        let h = self.step[e];
        let first = self.first[e] as usize;
        let n = self.first[e + 1] as usize - first;
        if n == 0 {
            return;
        }
        let k0 = (((span.s0 - lo) / h).floor().max(0.0) as usize).min(n - 1);
        let mut a = span.s0;
        let mut k = k0;
        loop {
            let end = if k + 1 == n {
                span.s1
            } else {
                (lo + (k + 1) as f64 * h).min(span.s1)
            };
            if end > a {
                f(first + k, a, end);
            }
            a = end;
            k += 1;
            if k >= n || a >= span.s1 {
                break;
            }
        }
    }
}

/// The clearance of edge `e`: for each unit segment of it, the free pixels
/// straight out in front of it, counted until a solid pixel or the level's
/// border and at most `cap`; of those counts, the lower quartile, so that an
/// edge a quarter of whose length faces a narrow gap counts as narrow.
/// At least 1 (the pixel in front of an edge is free).
pub fn clearance(geometry: &Geometry, e: &Edge, cap: usize) -> usize {
    let (lo, hi) = e.extent();
    let n = e.normal.vec();
    let mut probes: Vec<usize> = (lo as i32..hi as i32)
        .map(|s| {
            let [x, y] = e.free_pixel_at(s);
            (0..cap as i64)
                .take_while(|&d| {
                    let at = (x as i64 + d * n[0] as i64, y as i64 + d * n[1] as i64);
                    geometry.component_at(at.0, at.1).is_some()
                })
                .count()
        })
        .collect();
    if probes.is_empty() {
        return 1;
    }
    let quartile = (probes.len() - 1) / 4;
    let (_, q, _) = probes.select_nth_unstable(quartile);
    (*q).max(1)
}

/// Whether edge `e` meets a concave corner at either end: the wall goes
/// on in front of it there (the pixel beyond the end, beside the free
/// pixel in front of the edge's last unit segment, is solid or outside).
fn concave_end(geometry: &Geometry, e: &Edge) -> bool {
    let (lo, hi) = e.extent();
    let a = axis_vec(e.normal);
    let (ax, ay) = (a[0] as i64, a[1] as i64);
    let solid = |[x, y]: [i32; 2], step: i64| {
        geometry
            .component_at(x as i64 + step * ax, y as i64 + step * ay)
            .is_none()
    };
    solid(e.free_pixel_at(lo as i32), -1) || solid(e.free_pixel_at(hi as i32 - 1), 1)
}

/// Unit vector along an edge's axis (`+y` for vertical edges, `+x` otherwise).
pub fn axis_vec(n: Normal) -> [f64; 2] {
    if n.is_vertical_edge() {
        [0.0, 1.0]
    } else {
        [1.0, 0.0]
    }
}

/// Unit normal of an edge, as floats.
pub fn normal_vec(n: Normal) -> [f64; 2] {
    let v = n.vec();
    [v[0] as f64, v[1] as f64]
}
