//! The patch tree: reflected light on runs of patches merged into bigger
//! pieces, within a per-pixel error bound.

use crate::geometry::Edge;
use crate::transport::Patches;
use crate::transport::kernel::Falloff;

use super::*;

/// The reflected light of every edge as a binary tree over its patches, for
/// gathering distant light in fewer pieces with a bounded error.
///
/// Level 0 is the patches themselves (`B - E`, linear along each patch).
/// A node above covers up to `2^level` consecutive patches and holds the
/// least-squares parabola through their piecewise-linear light (a parabola
/// costs the gather nothing more than a line: its closed form reuses the
/// same `atan`s, [`crate::transport::kernel::GatherPoints::antiderivatives`]), and `dev`, the largest
/// distance between that parabola and the light it stands for (over the
/// components that decide, exactly: on each patch the difference is a
/// quadratic, largest at an end of the patch or at its vertex).
///
/// Seen from a pixel, a node whose nearest visible point is at distance `r`
/// may stand in for its patches when `dev * w(r) <= tolerance`: its error
/// is then at most `tolerance` times the angle it covers over `2 pi`, so all
/// the nodes a pixel gathers together err by at most `tolerance`, however
/// many there are. Nodes far away (small `w`) and over smooth light (small
/// `dev`) are taken whole; near ones are split down to the patches. With a
/// tolerance of 0 only exactly quadratic runs merge.
#[derive(Clone, Debug)]
pub struct PatchTree {
    /// Unique to this tree (and its clones): what cuts made from it are
    /// cached under ([`TileCuts`]).
    pub(super) id: u64,
    pub(super) k: usize,
    /// Per node and component: `B(s) = c0 + c1 u + c2 u^2` with `u = s -
    /// mid` (`c2 = 0` on the patches).
    pub(super) c0: Vec<f64>,
    pub(super) c1: Vec<f64>,
    pub(super) c2: Vec<f64>,
    /// Per node: centre on the edge's axis, and the squared distance from
    /// which on it may stand in for its patches (`dev * w(r) <= tolerance`).
    pub(super) mid: Vec<f64>,
    pub(super) need: Vec<f64>,
    /// Per edge: where each level's nodes start in the arrays, bottom (the
    /// patches) to top (one node), and the end of the last level.
    pub(super) levels: Vec<u32>,
    /// Per edge: where its entries of `levels` start (edge `e`'s are
    /// `levels[edge_levels[e]..edge_levels[e + 1]]`).
    pub(super) edge_levels: Vec<u32>,
}

/// The moments `integral of B(s) (s - m)^j ds`, `j = 0, 1, 2`, over `[m - l/2,
/// m + l/2]` of `B(s) = c0 + c1 u + c2 u^2` (`u = s - m`), moved to centre
/// `mid`: summed over a node's children they are the node's moments, since a
/// least-squares parabola keeps the moments up to 2 of what it fits.
fn moments(c: [f64; 3], m: f64, l: f64, mid: f64) -> [f64; 3] {
    let (l3, e) = (l * l * l, m - mid);
    let m0 = c[0] * l + c[2] * l3 / 12.0;
    let m1 = c[1] * l3 / 12.0;
    let m2 = c[0] * l3 / 12.0 + c[2] * l3 * l * l / 80.0;
    [m0, m1 + e * m0, m2 + 2.0 * e * m1 + e * e * m0]
}

/// The least-squares parabola on `[mid - l/2, mid + l/2]` with moments
/// `mo` (about `mid`), as `[c0, c1, c2]`: in the orthogonal basis `1, u,
/// u^2 - l^2/12` its coefficients are `M0 / l`, `12 M1 / l^3` and
/// `180 (M2 - l^2 M0 / 12) / l^5`.
fn parabola(mo: [f64; 3], l: f64) -> [f64; 3] {
    let l2 = l * l;
    let a = mo[0] / l;
    let b = 12.0 * mo[1] / (l2 * l);
    let g = 180.0 * (mo[2] - l2 * mo[0] / 12.0) / (l2 * l2 * l);
    [a - g * l2 / 12.0, b, g]
}

impl PatchTree {
    /// The tree of `rad`'s reflected light for gathering within `tolerance`
    /// under `falloff`; deviations are measured over the components
    /// `decide` (the others are carried along).
    pub fn new(
        edges: &[Edge],
        patches: &Patches,
        rad: &Radiosity,
        decide: std::ops::Range<usize>,
        falloff: Option<Falloff>,
        tolerance: f64,
    ) -> PatchTree {
        let k = rad.components;
        // dev * A / (A + r^2) <= tolerance  <=>  r^2 >= A (dev / tolerance - 1).
        let need = |dev: f64| {
            if dev <= tolerance {
                0.0
            } else {
                falloff.map_or(f64::INFINITY, |f| {
                    let r2 = f.a() * (dev / tolerance - 1.0);
                    if r2.is_finite() { r2 } else { f64::INFINITY }
                })
            }
        };
        static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let mut t = PatchTree {
            id: NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            k,
            c0: Vec::new(),
            c1: Vec::new(),
            c2: Vec::new(),
            mid: Vec::new(),
            need: Vec::new(),
            levels: Vec::with_capacity(2 * edges.len()),
            edge_levels: vec![0],
        };
        // Each edge's level starts, in one buffer for every edge.
        let mut starts = Vec::new();
        for (ei, e) in edges.iter().enumerate() {
            let (lo, hi) = e.extent();
            let h = patches.step[ei];
            let range = patches.of_edge(ei);
            let first = range.start;
            let n = range.len();
            starts.clear();
            starts.push(t.mid.len() as u32);
            if !rad.edge_reflects[ei] {
                // Never walked: one empty level keeps the indexing uniform.
                starts.push(t.mid.len() as u32);
                t.levels.extend_from_slice(&starts);
                t.edge_levels.push(t.levels.len() as u32);
                continue;
            }
            // Level 0: the patches.
            for j in 0..n {
                let p = first + j;
                t.c0.extend_from_slice(&rad.reflected[p * k..(p + 1) * k]);
                t.c1.extend_from_slice(&rad.slope[p * k..(p + 1) * k]);
                t.c2.extend(std::iter::repeat_n(0.0, k));
                t.mid.push(lo + (j as f64 + 0.5) * h);
                t.need.push(0.0);
            }
            let range = |lv: u32, i: usize| node_range(lo, hi, h, n, lv, i);
            let mut lv = 0;
            let mut count = n;
            while count > 1 {
                let below = *starts.last().expect("level 0 exists") as usize;
                starts.push(t.mid.len() as u32);
                lv += 1;
                count = count.div_ceil(2);
                for i in 0..count {
                    let (a, b) = (i << lv, ((i + 1) << lv).min(n));
                    let (s0, s1) = range(lv, i);
                    let (len, mid) = (s1 - s0, 0.5 * (s0 + s1));
                    let kids = [2 * i, 2 * i + 1];
                    let kids = &kids[..if b - a > 1 << (lv - 1) { 2 } else { 1 }];
                    let node = t.mid.len();
                    for c in 0..k {
                        let mut mo = [0.0; 3];
                        for &kid in kids {
                            let (k0, k1) = range(lv - 1, kid);
                            let ch = (below + kid) * k + c;
                            let cc = [t.c0[ch], t.c1[ch], t.c2[ch]];
                            let m = moments(cc, t.mid[below + kid], k1 - k0, mid);
                            for (x, y) in mo.iter_mut().zip(m) {
                                *x += y;
                            }
                        }
                        let [c0, c1, c2] = parabola(mo, len);
                        t.c0.push(c0);
                        t.c1.push(c1);
                        t.c2.push(c2);
                    }
                    t.mid.push(mid);
                    // Deviation over every patch under the node: the
                    // difference is quadratic along each patch.
                    let mut dev: f64 = 0.0;
                    for j in a..b {
                        let p = first + j;
                        let e = lo + (j as f64 + 0.5) * h - mid;
                        for c in decide.clone() {
                            let (r, g) = (rad.reflected[p * k + c], rad.slope[p * k + c]);
                            let i = node * k + c;
                            let (c0, c1, c2) = (t.c0[i], t.c1[i], t.c2[i]);
                            // At offset w from the patch's centre.
                            let diff =
                                |w: f64| r + g * w - (c0 + c1 * (w + e) + c2 * (w + e) * (w + e));
                            dev = dev.max(diff(-0.5 * h).abs()).max(diff(0.5 * h).abs());
                            if c2 != 0.0 {
                                let w = (g - c1) / (2.0 * c2) - e;
                                if w.abs() < 0.5 * h {
                                    dev = dev.max(diff(w).abs());
                                }
                            }
                        }
                    }
                    // Rounding in the fit is far below any tolerance in use,
                    // but keep the bound an upper bound.
                    t.need.push(need(dev * (1.0 + 1e-12)) * (1.0 + 1e-12));
                }
            }
            starts.push(t.mid.len() as u32);
            t.levels.extend_from_slice(&starts);
            t.edge_levels.push(t.levels.len() as u32);
        }
        t
    }
}

/// Axis range of node `i` of level `lv` (patches `i 2^lv ..` up to
/// `(i + 1) 2^lv`) of an edge from `lo` to `hi` cut into `n` patches of
/// length `h`: the same boundaries as [`Patches::bounds`].
#[inline]
pub(super) fn node_range(lo: f64, hi: f64, h: f64, n: usize, lv: u32, i: usize) -> (f64, f64) {
    let (a, b) = (i << lv, ((i + 1) << lv).min(n));
    (
        lo + a as f64 * h,
        if b == n { hi } else { lo + b as f64 * h },
    )
}
