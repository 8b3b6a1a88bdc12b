//! Gathering light onto floor pixels (SPEC section 4):
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

use std::f64::consts::TAU;

use crate::geometry::{Edge, Geometry};
use crate::level::{Cell, Level};
use crate::transport::kernel::Reach;
use crate::transport::kernel::{Falloff, GatherLine, GatherPoints};
use crate::transport::{Patches, for_each_visibility};
use crate::transport::{VisitStats, wanted_reach};
use crate::visibility::marks::Marks;
use crate::visibility::{Span, TileTree, View};

/// Radiosity in a form the gather can use: `components` values per edge
/// (uniform emission) and per patch (reflected light `B - E`).
#[derive(Clone, Debug)]
pub struct Radiosity {
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
    /// Exact flatland transport (SPEC 4).
    Flatland,
    /// The paper's equation 5: `A cos(theta) / (A + r^2) * Vis` per patch.
    Paper,
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

/// The reflected light of every edge as a binary tree over its patches, for
/// gathering distant light in fewer pieces with a bounded error.
///
/// Level 0 is the patches themselves (`B - E`, linear along each patch).
/// A node above covers up to `2^level` consecutive patches and holds the
/// least-squares parabola through their piecewise-linear light (a parabola
/// costs the gather nothing more than a line: its closed form reuses the
/// same `atan`s, [`GatherPoints::antiderivatives`]), and `dev`, the largest
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
    id: u64,
    k: usize,
    /// Per node and component: `B(s) = c0 + c1 u + c2 u^2` with `u = s -
    /// mid` (`c2 = 0` on the patches).
    c0: Vec<f64>,
    c1: Vec<f64>,
    c2: Vec<f64>,
    /// Per node: centre on the edge's axis, and the squared distance from
    /// which on it may stand in for its patches (`dev * w(r) <= tolerance`).
    mid: Vec<f64>,
    need: Vec<f64>,
    /// Per edge: where each level's nodes start in the arrays, bottom (the
    /// patches) to top (one node), and the end of the last level.
    levels: Vec<u32>,
    /// Per edge: where its entries of `levels` start (edge `e`'s are
    /// `levels[edge_levels[e]..edge_levels[e + 1]]`).
    edge_levels: Vec<u32>,
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
        for (ei, e) in edges.iter().enumerate() {
            let (lo, hi) = e.extent();
            let h = patches.step[ei];
            let range = patches.of_edge(ei);
            let first = range.start;
            let n = range.len();
            let mut starts = vec![t.mid.len() as u32];
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
fn node_range(lo: f64, hi: f64, h: f64, n: usize, lv: u32, i: usize) -> (f64, f64) {
    let (a, b) = (i << lv, ((i + 1) << lv).min(n));
    (
        lo + a as f64 * h,
        if b == n { hi } else { lo + b as f64 * h },
    )
}

/// What gathering merged, summed over pixels (what it culled, the
/// visibility query counts: [`VisitStats`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GatherCounts {
    /// Pieces of reflected light gathered ([`PatchTree`] nodes) ...
    pub pieces: u64,
    /// ... and the patch pieces they stand for (equal when nothing merged).
    pub patch_pieces: u64,
}

impl std::ops::AddAssign for GatherCounts {
    fn add_assign(&mut self, o: GatherCounts) {
        self.pieces += o.pieces;
        self.patch_pieces += o.patch_pieces;
    }
}

/// Reusable buffers of [`pixel_light`] (one per thread, so that a pixel
/// allocates nothing once they have grown). A pixel's visible spans are
/// first turned into the points at which the closed forms are needed, each
/// with its own line; those are then evaluated together, in loops without
/// branches that vectorise ([`GatherPoints`]), and summed.
#[derive(Default)]
pub struct PixelScratch {
    /// Emitting spans: their starts (with their lines), their ends, their
    /// edges, and the integrals between.
    em: GatherPoints,
    em_end: Vec<f64>,
    em_edge: Vec<u32>,
    em_g: Vec<f64>,
    /// Reflected light: for every reflecting span its start, then the end
    /// of each of its pieces; the three antiderivatives there.
    pts: GatherPoints,
    f: Vec<f64>,
    l: Vec<f64>,
    q: Vec<f64>,
    /// The pieces, in the order of their end points.
    pieces: Vec<PieceAt>,
    /// The patch trees as cut for the current tile.
    cuts: TileCuts,
}

impl PixelScratch {
    pub fn new() -> Self {
        Self::default()
    }
}

/// A piece of reflected light queued for a pixel: its tree node, the index
/// of its end point (it starts at the point before), and the node's centre
/// relative to the foot of the pixel on the edge (`foot - mid`).
#[derive(Clone, Copy, Debug)]
struct PieceAt {
    node: u32,
    end: u32,
    off: f64,
}

/// Adds to `acc` the light that pixel centre `p` receives from its visible
/// spans (all of them: the falloff reach is applied by the visibility query,
/// [`for_each_visibility`], which passes on only the spans within reach).
/// Reflected light is gathered from `tree`'s nodes ([`PatchTree`]), as cut
/// for `p`'s tile: `p` must be the centre of a pixel, since the cut's bound
/// is taken at the tile's pixel centres.
#[allow(clippy::too_many_arguments)]
pub fn pixel_light(
    edges: &[Edge],
    patches: &Patches,
    rad: &Radiosity,
    tree: &PatchTree,
    falloff: Option<Falloff>,
    kernel: Kernel,
    p: [f64; 2],
    spans: &[Span],
    acc: &mut [f64],
    scratch: &mut PixelScratch,
) -> GatherCounts {
    let k = rad.components;
    let mut counts = GatherCounts::default();
    let sc = scratch;
    sc.em.clear();
    sc.em_end.clear();
    sc.em_edge.clear();
    sc.pts.clear();
    sc.pieces.clear();
    sc.cuts.enter(tree, p, edges.len());
    for span in spans {
        let ei = span.edge as usize;
        let e = &edges[ei];
        if !(rad.edge_emits[ei] || rad.edge_reflects[ei]) {
            continue;
        }
        if kernel == Kernel::Paper {
            paper_span(edges, patches, rad, falloff, p, span, acc);
            continue;
        }
        let d = e.front_distance(p);
        let foot = if e.normal.is_vertical_edge() {
            p[1]
        } else {
            p[0]
        };
        let line = GatherLine::new(d, falloff);
        if rad.edge_emits[ei] {
            sc.em.line(&line);
            sc.em.push(span.s0 - foot);
            sc.em_end.push(span.s1 - foot);
            sc.em_edge.push(span.edge);
        }
        if rad.edge_reflects[ei] {
            reflected_pieces(patches, tree, edges, span, &line, foot, sc, &mut counts);
        }
    }
    let fall = falloff.is_some();
    // Uniform emission: one integral per emitting span.
    sc.em.between(&sc.em_end, fall, &mut sc.em_g);
    for (&ei, &g) in sc.em_edge.iter().zip(&sc.em_g) {
        let g = g / TAU;
        for c in 0..k {
            acc[c] += rad.edge_emission[ei as usize * k + c] * g;
        }
    }
    // Reflected light, quadratic along each piece.
    sc.pts
        .antiderivatives(fall, &mut sc.f, &mut sc.l, &mut sc.q);
    let (f, l, q) = (&sc.f, &sc.l, &sc.q);
    let k = tree.k;
    for pc in &sc.pieces {
        let (nd, i) = (pc.node as usize, pc.end as usize);
        let g0 = (f[i] - f[i - 1]) / TAU;
        let g1 = (l[i] - l[i - 1]) / TAU;
        let g2 = (q[i] - q[i - 1]) / TAU;
        // Express B = c0 + c1 u + c2 u^2, u = s - mid = t + off, in t = s - foot.
        let off = pc.off;
        for c in 0..k {
            let j = nd * k + c;
            let (c0, c1, c2) = (tree.c0[j], tree.c1[j], tree.c2[j]);
            let a1 = c1 + 2.0 * c2 * off;
            let a0 = c0 + (c1 + c2 * off) * off;
            acc[c] += a0 * g0 + a1 * g1 + c2 * g2;
        }
    }
    counts
}

/// Side of the square tiles of pixels that share their cuts of the patch
/// trees ([`TileCuts`]): that of the visibility tiles, whose pixels a thread
/// visits one after the other.
const CUT_TILE: i32 = TileTree::LEAF;

/// A node of a tile's cut of an edge's patch tree: the node, where its axis
/// range ends, and the patches under it.
#[derive(Clone, Copy, Debug)]
struct CutPiece {
    node: u32,
    b: f64,
    first: u32,
    last: u32,
}

/// The patch trees ([`PatchTree`]) cut into the nodes that may stand in for
/// their patches as seen from every pixel centre of one tile: a node is
/// taken whole when the tile's nearest pixel centre is far enough for it
/// (then so is every pixel's nearest visible point of it, so each pixel's
/// bound holds), else split. An edge is cut once per tile, when a pixel of
/// the tile first sees its reflected light; the pixels then read the pieces
/// under their spans off the cut instead of each walking the tree.
#[derive(Default)]
struct TileCuts {
    /// The tree and the tile the cached cuts are for.
    tree: Option<u64>,
    tile: Option<[i32; 2]>,
    /// Per edge whose cut is made: where it lies in `pieces`.
    made: Marks<(u32, u32)>,
    pieces: Vec<CutPiece>,
    /// Tree nodes still to visit: (level, index in the level).
    stack: Vec<(u32, u32)>,
}

impl TileCuts {
    /// Starts serving pixel centre `p` with `tree`: cuts made for another
    /// tile or another tree (the scratch outlives a gather) are dropped.
    fn enter(&mut self, tree: &PatchTree, p: [f64; 2], edges: usize) {
        let side = CUT_TILE as f64;
        let tile = [(p[0] / side).floor() as i32, (p[1] / side).floor() as i32];
        if self.tile == Some(tile) && self.tree == Some(tree.id) && self.made.len() == edges {
            return;
        }
        self.tile = Some(tile);
        self.tree = Some(tree.id);
        self.pieces.clear();
        self.made.clear(edges);
    }

    /// The cut of edge `ei` for the current tile.
    fn of(
        &mut self,
        tree: &PatchTree,
        edges: &[Edge],
        patches: &Patches,
        ei: usize,
    ) -> &[CutPiece] {
        if let Some((from, to)) = self.made.get(ei) {
            return &self.pieces[from as usize..to as usize];
        }
        let tile = self.tile.expect("enter() comes first");
        let from = self.pieces.len();
        self.cut(tree, &edges[ei], patches, ei, tile);
        self.made.set(ei, (from as u32, self.pieces.len() as u32));
        &self.pieces[from..]
    }

    fn cut(&mut self, tree: &PatchTree, e: &Edge, patches: &Patches, ei: usize, tile: [i32; 2]) {
        let (lo, hi) = e.extent();
        let h = patches.step[ei];
        let n = patches.of_edge(ei).len();
        let levels = &tree.levels[tree.edge_levels[ei] as usize..tree.edge_levels[ei + 1] as usize];
        // The tile's pixel centres: their nearest distance in front of the
        // edge's line, and their range along its axis.
        let side = CUT_TILE as f64;
        let (x0, y0) = (tile[0] as f64 * side + 0.5, tile[1] as f64 * side + 0.5);
        let (x1, y1) = (x0 + side - 1.0, y0 + side - 1.0);
        let front = e
            .front_distance([x0, y0])
            .min(e.front_distance([x1, y1]))
            .max(0.0);
        let (ta, tb) = if e.normal.is_vertical_edge() {
            (y0, y1)
        } else {
            (x0, x1)
        };
        let d2 = front * front;
        self.stack.clear();
        self.stack.push((levels.len() as u32 - 2, 0));
        while let Some((lv, i)) = self.stack.pop() {
            let (a, b) = node_range(lo, hi, h, n, lv, i as usize);
            let nd = levels[lv as usize] as usize + i as usize;
            let gap = (a - tb).max(ta - b).max(0.0);
            if lv > 0 && d2 + gap * gap < tree.need[nd] {
                // The right child pushed first, so that the left one comes first.
                let below = levels[lv as usize] - levels[lv as usize - 1];
                if 2 * i + 1 < below {
                    self.stack.push((lv - 1, 2 * i + 1));
                }
                self.stack.push((lv - 1, 2 * i));
                continue;
            }
            let first = (i as usize) << lv;
            let last = (((i as usize + 1) << lv) - 1).min(n - 1);
            self.pieces.push(CutPiece {
                node: nd as u32,
                b,
                first: first as u32,
                last: last as u32,
            });
        }
    }
}

/// Queues the reflected light (`B - E`, quadratic along each piece) under
/// `span` for pixel centre `p` at `foot` on the edge: the pieces of the
/// tile's cut of the edge's tree that overlap the span, clipped to it, in
/// order along the edge. The span's start point goes into `sc.pts`, then
/// each piece's end point; each piece goes into `sc.pieces`.
#[allow(clippy::too_many_arguments)]
fn reflected_pieces(
    patches: &Patches,
    tree: &PatchTree,
    edges: &[Edge],
    span: &Span,
    line: &GatherLine,
    foot: f64,
    sc: &mut PixelScratch,
    counts: &mut GatherCounts,
) {
    let ei = span.edge as usize;
    let (lo, _) = edges[ei].extent();
    let h = patches.step[ei];
    let n = patches.of_edge(ei).len();
    // (`as` truncates towards 0 and saturates: the floor, clamped at 0.)
    let patch_of = |s: f64| (((s - lo) / h) as usize).min(n - 1);
    let (j0, j1) = (patch_of(span.s0), patch_of(span.s1));
    let PixelScratch {
        pts, pieces, cuts, ..
    } = sc;
    let cut = cuts.of(tree, edges, patches, ei);
    pts.line(line);
    pts.push(span.s0 - foot);
    // The first piece that ends after the span starts.
    let from = cut.partition_point(|c| c.b <= span.s0);
    for c in &cut[from.min(cut.len() - 1)..] {
        // The last piece ends the span.
        let end = if c.last as usize >= j1 { span.s1 } else { c.b };
        pts.push(end - foot);
        pieces.push(PieceAt {
            node: c.node,
            end: pts.len() as u32 - 1,
            off: foot - tree.mid[c.node as usize],
        });
        counts.pieces += 1;
        counts.patch_pieces +=
            ((c.last as usize).min(j1) + 1).saturating_sub((c.first as usize).max(j0)) as u64;
        if c.last as usize >= j1 {
            break;
        }
    }
}

/// Equation 5 of the paper for the patches of one visible span: each patch
/// adds `B * A cos(theta) / (A + r^2) * (visible fraction)`, with `theta` and
/// `r` taken at the patch centre and `A` infinite without falloff.
fn paper_span(
    edges: &[Edge],
    patches: &Patches,
    rad: &Radiosity,
    falloff: Option<Falloff>,
    p: [f64; 2],
    span: &Span,
    acc: &mut [f64],
) {
    let e = &edges[span.edge as usize];
    let d = e.front_distance(p);
    patches.for_each_piece(edges, span, |pt, a, b| {
        let (s0, s1) = patches.bounds(edges, pt);
        let centre = e.point_at(0.5 * (s0 + s1));
        let r = (p[0] - centre[0]).hypot(p[1] - centre[1]);
        let w = falloff.map_or(1.0, |f| f.weight(r));
        let vis = (b - a) / (s1 - s0);
        for c in 0..rad.components {
            acc[c] += rad.patch(patches, pt, c) * (d / r) * w * vis;
        }
    });
}

thread_local! {
    static SCRATCH: std::cell::RefCell<PixelScratch> = std::cell::RefCell::new(PixelScratch::new());
}

/// The floor pixels of a level, as query points.
pub fn floor_pixels(level: &Level) -> Vec<[i32; 2]> {
    let mut v = Vec::new();
    for y in 0..level.height {
        for x in 0..level.width {
            if level.cell(x, y) == Cell::Floor {
                v.push([x as i32, y as i32]);
            }
        }
    }
    v
}

/// Fast gather: light at each of `pixels`, `components` values per pixel,
/// and what was left out (beyond reach, or in regions no lit edge reaches).
/// Distant reflected light is gathered in merged pieces whose total error
/// per pixel is at most `tolerance` ([`PatchTree`], deviations measured
/// over the components `decide`); how much was merged is counted.
#[allow(clippy::too_many_arguments)]
pub fn gather(
    geometry: &Geometry,
    patches: &Patches,
    rad: &Radiosity,
    falloff: Option<Falloff>,
    kernel: Kernel,
    pixels: &[[i32; 2]],
    reach: &Reach,
    tolerance: f64,
    decide: std::ops::Range<usize>,
) -> (Vec<f64>, VisitStats, GatherCounts) {
    let k = rad.components;
    let tree = PatchTree::new(&geometry.edges, patches, rad, decide, falloff, tolerance);
    let mut out = vec![0.0; pixels.len() * k];
    let pos: Vec<[f64; 2]> = pixels
        .iter()
        .map(|p| [p[0] as f64 + 0.5, p[1] as f64 + 0.5])
        .collect();
    let shared = Disjoint::new(&mut out);
    // What each pixel merged, summed afterwards (a lock or an atomic shared
    // by every pixel costs more than the pixel's own bookkeeping).
    let mut merged = vec![[0u32; 2]; pixels.len()];
    let shared_merged = Disjoint::new(&mut merged);
    // Edges with light, each within its reach.
    let reach2 = wanted_reach(reach, |e| rad.edge_emits[e] || rad.edge_reflects[e]);
    let stats = for_each_visibility(
        geometry,
        &pos,
        pixels,
        &|_| View::Full,
        reach,
        Some(&reach2),
        &|i, spans| {
            // Bakes have at most three channels: no allocation per pixel.
            let mut small = [0.0; 3];
            let mut big = Vec::new();
            let acc = if k <= 3 {
                &mut small[..k]
            } else {
                big.resize(k, 0.0);
                &mut big[..]
            };
            let c = SCRATCH.with(|sc| {
                pixel_light(
                    &geometry.edges,
                    patches,
                    rad,
                    &tree,
                    falloff,
                    kernel,
                    pos[i],
                    spans,
                    acc,
                    &mut sc.borrow_mut(),
                )
            });
            let c = [c.pieces, c.patch_pieces].map(|v| v.min(u32::MAX as u64) as u32);
            // SAFETY: each pixel index is visited exactly once.
            unsafe { shared_merged.write(i, c) };
            for (c, &v) in acc.iter().enumerate() {
                // SAFETY: as above.
                unsafe { shared.write(i * k + c, v) };
            }
        },
    );
    let counts = merged.iter().fold(GatherCounts::default(), |mut t, c| {
        t.pieces += c[0] as u64;
        t.patch_pieces += c[1] as u64;
        t
    });
    (out, stats, counts)
}

/// Does the segment `p -> q` touch edge `e` (closed segments)?
fn segment_hits(p: [f64; 2], q: [f64; 2], e: &Edge) -> bool {
    let a = [e.a[0] as f64, e.a[1] as f64];
    let b = [e.b[0] as f64, e.b[1] as f64];
    let cross = |o: [f64; 2], u: [f64; 2], v: [f64; 2]| {
        (u[0] - o[0]) * (v[1] - o[1]) - (u[1] - o[1]) * (v[0] - o[0])
    };
    let d1 = cross(a, b, p);
    let d2 = cross(a, b, q);
    let d3 = cross(p, q, a);
    let d4 = cross(p, q, b);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |o: [f64; 2], u: [f64; 2], v: [f64; 2], d: f64| {
        d == 0.0
            && v[0] >= o[0].min(u[0])
            && v[0] <= o[0].max(u[0])
            && v[1] >= o[1].min(u[1])
            && v[1] <= o[1].max(u[1])
    };
    on(a, b, p, d1) || on(a, b, q, d2) || on(p, q, a, d3) || on(p, q, b, d4)
}

/// The paper's gather: for every pixel and every patch, `samples` points on
/// the patch, each ray tested against every edge. Same output as [`gather`].
pub fn gather_naive(
    geometry: &Geometry,
    patches: &Patches,
    rad: &Radiosity,
    falloff: Option<Falloff>,
    kernel: Kernel,
    pixels: &[[i32; 2]],
    samples: usize,
) -> Vec<f64> {
    use rayon::prelude::*;
    let k = rad.components;
    let edges = &geometry.edges;
    let samples = samples.max(1);
    let mut out = vec![0.0; pixels.len() * k];
    out.par_chunks_mut(k)
        .zip(pixels.par_iter())
        .for_each(|(acc, px)| {
            let p = [px[0] as f64 + 0.5, px[1] as f64 + 0.5];
            let comp = geometry.components[px[1] as usize * geometry.width + px[0] as usize];
            for pt in 0..patches.len() {
                let ei = patches.edge[pt] as usize;
                let e = &edges[ei];
                let d = e.front_distance(p);
                if d <= 0.0 || e.component != comp {
                    continue;
                }
                let (s0, s1) = patches.bounds(edges, pt);
                let len = s1 - s0;
                let mut visible = 0usize;
                let mut sum = 0.0;
                for s in 0..samples {
                    let y = e.point_at(s0 + (s as f64 + 0.5) / samples as f64 * len);
                    // Nudge the target off the edge so the edge itself does not block.
                    let n = e.normal.vec();
                    let yq = [y[0] + n[0] as f64 * 1e-9, y[1] + n[1] as f64 * 1e-9];
                    let blocked = edges
                        .iter()
                        .enumerate()
                        .any(|(j, o)| j != ei && segment_hits(p, yq, o));
                    if blocked {
                        continue;
                    }
                    visible += 1;
                    let r = (p[0] - y[0]).hypot(p[1] - y[1]);
                    let w = falloff.map_or(1.0, |f| f.weight(r));
                    sum += (d / r) / r * w * (len / samples as f64);
                }
                for c in 0..k {
                    let b = rad.patch(patches, pt, c);
                    acc[c] += match kernel {
                        Kernel::Flatland => b * sum / TAU,
                        Kernel::Paper => {
                            let centre = e.point_at(0.5 * (s0 + s1));
                            let r = (p[0] - centre[0]).hypot(p[1] - centre[1]);
                            let w = falloff.map_or(1.0, |f| f.weight(r));
                            b * (d / r) * w * visible as f64 / samples as f64
                        }
                    };
                }
            }
        });
    out
}
