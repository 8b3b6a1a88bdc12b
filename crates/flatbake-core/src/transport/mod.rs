//! Patches and the edge-to-edge form factors F (SPEC section 4).
//!
//! Each edge is cut into equal patches no longer than the patch length. Row
//! `i` of F is the mean, over Gauss-Legendre points `x` on patch `i`, of the
//! exact point-to-patch factors `K(x, j) = 1/2 * integral of cos(theta_x) w d psi`
//! over the part of patch `j` that `x` sees ([`crate::visibility`] finds the
//! visible parts, [`crate::transport::kernel`] integrates them in closed form). Because
//! every point's factors integrate exactly over the directions it sees, a row
//! of F sums to exactly the visible fraction of the half-plane (1 in a closed
//! room) whatever the quadrature.
//!
//! Reciprocity `L_i F_ij = L_j F_ji` holds only up to quadrature error for
//! the raw rows, so flatbake stores the symmetric average
//! `S_ij = (L_i F_ij + L_j F_ji) / 2` and defines `F = D^-1 S` with the
//! "effective lengths" `D_i = sum_j S_ij / t_i`, where `t_i` is the raw row
//! sum. Then rows still sum to `t_i` exactly, `D F` is symmetric, and
//! `D / rho - S` is symmetric positive definite: the solve can use Cholesky
//! or conjugate gradients, and energy balances exactly in the discrete system.
//! `D_i` differs from the true length `L_i` only by quadrature error.

pub mod kernel;
pub mod paper;
pub mod solve;

use std::cell::RefCell;
use std::ops::Range;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{Edge, Geometry, Normal};
use crate::transport::kernel::Reach;
use crate::transport::kernel::{FactorLine, Falloff, gauss_legendre};
use crate::visibility::{Blocks, Reachable, Rect, Span, Sweeper, TileTree, View, Wanted};

/// Patches: every edge cut into equal pieces.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Patches {
    /// Patches of edge `e` are `first[e]..first[e + 1]`.
    pub first: Vec<u32>,
    /// Patch length on each edge.
    pub step: Vec<f64>,
    /// Edge of each patch.
    pub edge: Vec<u32>,
}

impl Patches {
    /// Cuts every edge into `ceil(len / patch_len)` equal patches.
    pub fn new(geometry: &Geometry, patch_len: f64) -> Patches {
        let mut first = Vec::with_capacity(geometry.edges.len() + 1);
        let mut step = Vec::with_capacity(geometry.edges.len());
        let mut edge = Vec::new();
        first.push(0);
        for (i, e) in geometry.edges.iter().enumerate() {
            let len = e.len();
            let n = ((len / patch_len).ceil() as usize).max(1);
            step.push(len / n as f64);
            edge.extend(std::iter::repeat_n(i as u32, n));
            first.push(edge.len() as u32);
        }
        Patches { first, step, edge }
    }

    pub fn len(&self) -> usize {
        self.edge.len()
    }

    pub fn is_empty(&self) -> bool {
        self.edge.is_empty()
    }

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

/// Unit vector along an edge's axis (`+y` for vertical edges, `+x` otherwise).
pub fn axis_vec(n: Normal) -> [f64; 2] {
    if n.is_vertical_edge() {
        [0.0, 1.0]
    } else {
        [1.0, 0.0]
    }
}

pub fn normal_vec(n: Normal) -> [f64; 2] {
    let v = n.vec();
    [v[0] as f64, v[1] as f64]
}

/// The factors from point `x` on an edge with normal `nx` to every patch it
/// sees, appended to `out` as `(patch, K)`; `spans` is the point's visibility
/// (the falloff reach is applied there, see [`for_each_visibility`]).
pub fn point_factors(
    edges: &[Edge],
    patches: &Patches,
    x: [f64; 2],
    nx: Normal,
    spans: &[Span],
    falloff: Option<Falloff>,
    out: &mut Vec<(u32, f64)>,
) {
    let nxv = normal_vec(nx);
    for span in spans {
        let e = &edges[span.edge as usize];
        let d = e.front_distance(x);
        let nj = normal_vec(e.normal);
        let tj = axis_vec(e.normal);
        let alpha = -(nxv[0] * nj[0] + nxv[1] * nj[1]);
        let beta = nxv[0] * tj[0] + nxv[1] * tj[1];
        let foot = if e.normal.is_vertical_edge() {
            x[1]
        } else {
            x[0]
        };
        let line = FactorLine::new(d, alpha, beta, falloff);
        let mut prev: Option<(f64, f64)> = None;
        patches.for_each_piece(edges, span, |p, a, b| {
            let fa = match prev {
                Some((s, v)) if s == a => v,
                _ => line.at(a - foot),
            };
            let fb = line.at(b - foot);
            prev = Some((b, fb));
            let k = fb - fa;
            if k > 0.0 {
                out.push((p as u32, k));
            }
        });
    }
}

/// The form factors, stored as the symmetric matrix `S` (full storage, CSR)
/// and the effective lengths `D`: `F_ij = S_ij / D_i`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FormFactors {
    pub row_ptr: Vec<usize>,
    pub col: Vec<u32>,
    pub val: Vec<f64>,
    /// Effective lengths `D_i`.
    pub dlen: Vec<f64>,
    /// Raw row sums `t_i` of F: the fraction of patch `i`'s light that lands
    /// on some patch (1 in a closed room without falloff).
    pub coverage: Vec<f64>,
}

impl FormFactors {
    pub fn n(&self) -> usize {
        self.dlen.len()
    }

    pub fn nnz(&self) -> usize {
        self.val.len()
    }

    /// Row `i` as `(column, F_ij)`.
    pub fn row(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let d = self.dlen[i];
        (self.row_ptr[i]..self.row_ptr[i + 1]).map(move |k| (self.col[k] as usize, self.val[k] / d))
    }

    /// `F_ij`, or 0 (binary search in the row).
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let r = self.row_ptr[i]..self.row_ptr[i + 1];
        match self.col[r.clone()].binary_search(&(j as u32)) {
            Ok(k) => self.val[r.start + k] / self.dlen[i],
            Err(_) => 0.0,
        }
    }

    /// Builds `S` and `D` from raw rows `F0` (sorted by column) and patch lengths.
    pub fn from_raw_rows(rows: Vec<Vec<(u32, f64)>>, len: &[f64]) -> FormFactors {
        let n = rows.len();
        let coverage: Vec<f64> = rows.iter().map(|r| r.iter().map(|e| e.1).sum()).collect();
        // A_ij = L_i F0_ij / 2 and its transpose, merged row by row.
        let mut tcount = vec![0usize; n + 1];
        for r in &rows {
            for &(j, _) in r {
                tcount[j as usize + 1] += 1;
            }
        }
        for i in 0..n {
            tcount[i + 1] += tcount[i];
        }
        let mut tcol = vec![0u32; tcount[n]];
        let mut tval = vec![0f64; tcount[n]];
        let mut fill = tcount.clone();
        for (i, r) in rows.iter().enumerate() {
            for &(j, v) in r {
                let k = fill[j as usize];
                tcol[k] = i as u32;
                tval[k] = 0.5 * len[i] * v;
                fill[j as usize] += 1;
            }
        }
        let mut row_ptr = Vec::with_capacity(n + 1);
        let mut col = Vec::new();
        let mut val = Vec::new();
        row_ptr.push(0);
        for (i, r) in rows.iter().enumerate() {
            // Merge row i of A (sorted) with row i of A^T (sorted by construction).
            let t = tcount[i]..tcount[i + 1];
            let (mut a, mut b) = (0, t.start);
            while a < r.len() || b < t.end {
                let ca = r.get(a).map_or(u32::MAX, |e| e.0);
                let cb = if b < t.end { tcol[b] } else { u32::MAX };
                if ca == cb {
                    col.push(ca);
                    val.push(0.5 * len[i] * r[a].1 + tval[b]);
                    a += 1;
                    b += 1;
                } else if ca < cb {
                    col.push(ca);
                    val.push(0.5 * len[i] * r[a].1);
                    a += 1;
                } else {
                    col.push(cb);
                    val.push(tval[b]);
                    b += 1;
                }
            }
            row_ptr.push(col.len());
        }
        let mut coverage = coverage;
        let dlen = (0..n)
            .map(|i| {
                let s: f64 = val[row_ptr[i]..row_ptr[i + 1]].iter().sum();
                if coverage[i] > 0.0 && s > 0.0 {
                    s / coverage[i]
                } else {
                    // A patch whose own row is empty (every pair culled by
                    // the falloff reach) can still be in other patches' rows,
                    // and so in its own row of the symmetric S. Its coverage
                    // is then that row's sum, not 0: otherwise the light it
                    // sends is counted as escaped as well as received, and
                    // emitted != absorbed + escaped.
                    coverage[i] = s / len[i];
                    len[i]
                }
            })
            .collect();
        FormFactors {
            row_ptr,
            col,
            val,
            dlen,
            coverage,
        }
    }
}

/// The point-to-patch factors of every quadrature point, `q` points per
/// patch in order (CSR). After a solve they give the radiosity at each point,
/// `B(x) = E + rho * sum_j K(x, j) B_j`, from which each patch gets a slope.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PointRows {
    pub q: usize,
    pub row_ptr: Vec<usize>,
    pub col: Vec<u32>,
    pub val: Vec<f64>,
}

impl PointRows {
    /// Per-patch slope (per unit length along the edge's axis) of the
    /// radiosity profile through the quadrature points, least squares, limited
    /// so that `B` stays non-negative over the patch. `b` is the solved patch
    /// radiosity, `e` and `rho` per patch.
    pub fn slopes(&self, patches: &Patches, rho: &[f64], e: &[f64], b: &[f64]) -> Vec<f64> {
        let (xs, ws) = gauss_legendre(self.q);
        let q = xs.len();
        let den: f64 = xs
            .iter()
            .zip(ws)
            .map(|(x, w)| w * (x - 0.5) * (x - 0.5))
            .sum();
        (0..patches.len())
            .into_par_iter()
            .map(|p| {
                if den == 0.0 || rho[p] == 0.0 {
                    return 0.0;
                }
                let mut num = 0.0;
                for k in 0..q {
                    let r = self.row_ptr[p * q + k]..self.row_ptr[p * q + k + 1];
                    let h: f64 = self.col[r.clone()]
                        .iter()
                        .zip(&self.val[r])
                        .map(|(&j, &v)| v * b[j as usize])
                        .sum();
                    num += ws[k] * (e[p] + rho[p] * h) * (xs[k] - 0.5);
                }
                let len = patches.length(p);
                let g = num / (den * len);
                // Keep B >= 0 at both ends of the patch.
                let limit = 2.0 * b[p].max(0.0) / len;
                g.clamp(-limit, limit)
            })
            .collect()
    }
}

/// Query points bucketed by leaf tile, with a summed-area table to answer
/// "does this rectangle hold any point" in constant time.
pub struct PointGrid {
    width: usize,
    leaves_x: usize,
    leaf: usize,
    sat: Vec<u32>,
    /// Points of leaf `l` are `order[start[l]..start[l + 1]]`.
    start: Vec<usize>,
    order: Vec<u32>,
}

impl PointGrid {
    /// `pixels[i]` is the pixel that query point `i` belongs to.
    pub fn new(width: usize, height: usize, leaf: usize, pixels: &[[i32; 2]]) -> PointGrid {
        let mut sat = vec![0u32; (width + 1) * (height + 1)];
        let leaves_x = width.div_ceil(leaf);
        let leaves = leaves_x * height.div_ceil(leaf);
        let mut start = vec![0usize; leaves + 1];
        let leaf_of = |p: [i32; 2]| (p[1] as usize / leaf) * leaves_x + p[0] as usize / leaf;
        for &p in pixels {
            sat[(p[1] as usize + 1) * (width + 1) + p[0] as usize + 1] += 1;
            start[leaf_of(p) + 1] += 1;
        }
        for y in 1..=height {
            for x in 1..=width {
                let i = y * (width + 1) + x;
                sat[i] += sat[i - 1] + sat[i - width - 1] - sat[i - width - 2];
            }
        }
        for l in 0..leaves {
            start[l + 1] += start[l];
        }
        let mut fill = start.clone();
        let mut order = vec![0u32; pixels.len()];
        for (i, &p) in pixels.iter().enumerate() {
            let l = leaf_of(p);
            order[fill[l]] = i as u32;
            fill[l] += 1;
        }
        // Within a leaf, rows alternate direction, so that each point is a
        // neighbour of the one before (the sweep reuses its event order).
        for l in 0..leaves {
            order[start[l]..start[l + 1]].sort_by_key(|&i| {
                let p = pixels[i as usize];
                (p[1], if p[1] % 2 == 0 { p[0] } else { -p[0] })
            });
        }
        PointGrid {
            width,
            leaves_x,
            leaf,
            sat,
            start,
            order,
        }
    }

    /// Number of points in the rectangle.
    pub fn count_in(&self, r: Rect) -> u64 {
        let w = self.width + 1;
        let at = |x: i32, y: i32| self.sat[y as usize * w + x as usize] as i64;
        (at(r.x1, r.y1) - at(r.x0, r.y1) - at(r.x1, r.y0) + at(r.x0, r.y0)) as u64
    }

    /// Points of the leaf tile whose top-left pixel is `(r.x0, r.y0)`.
    pub fn in_leaf(&self, r: Rect) -> &[u32] {
        let l = (r.y0 as usize / self.leaf) * self.leaves_x + r.x0 as usize / self.leaf;
        &self.order[self.start[l]..self.start[l + 1]]
    }
}

thread_local! {
    static SWEEPER: RefCell<(Sweeper, Vec<Span>, Vec<u32>)> = RefCell::new((Sweeper::new(), Vec::new(), Vec::new()));
}

/// What [`for_each_visibility`] left out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VisitStats {
    /// (edge, point) pairs dropped because the edge lies beyond every reach.
    pub culled_pairs: u64,
    /// Points whose region sees no contributing edge: reported with no spans.
    pub unreached: u64,
}

/// Runs `f(point index, spans)` for every query point, with the exact
/// visibility of that point, in parallel over leaf tiles. `pixel[i]` is the
/// free pixel a point belongs to, `pos[i]` its position, `view[i]` its view.
/// Edges beyond `reach.max` are left out. With `reach2` (see [`Wanted`]),
/// only the spans of edges within their squared reach are passed on (the
/// others still occlude; they count as culled pairs), and a point whose
/// region has no candidate within reach gets no spans without a visibility
/// query.
pub fn for_each_visibility<F>(
    geometry: &Geometry,
    pos: &[[f64; 2]],
    pixel: &[[i32; 2]],
    view: &(dyn Fn(usize) -> View + Sync),
    reach: &Reach,
    reach2: Option<&[f64]>,
    f: &F,
) -> VisitStats
where
    F: Fn(usize, &[Span]) + Sync,
{
    // A floor gather asks at pixel centres only: its regions cull more.
    let centres = pos
        .iter()
        .zip(pixel)
        .all(|(p, px)| p[0] == px[0] as f64 + 0.5 && p[1] == px[1] as f64 + 0.5);
    let tree = TileTree::new(geometry, centres);
    let blocks = Blocks::new(geometry);
    let grid = PointGrid::new(geometry.width, geometry.height, tree.leaf as usize, pixel);
    let unreached = std::sync::atomic::AtomicU64::new(0);
    let left_out = std::sync::atomic::AtomicU64::new(0);
    let culled_pairs = tree.for_each_leaf(&|r| grid.count_in(r), reach.max, &|leaf| {
        // Per region with a known list: where each candidate's light reaches.
        let class: Vec<Option<Vec<Reachable>>> = leaf
            .regions
            .iter()
            .map(|r| {
                let (reach2, list) = (reach2?, r.candidates.as_ref()?);
                let mut c = Vec::new();
                Wanted::classify(reach2, &geometry.edges, &r.bbox, list, &mut c);
                Some(c)
            })
            .collect();
        // Regions where no candidate is within reach of any point.
        let dark: Vec<bool> = class
            .iter()
            .map(|c| {
                c.as_ref().is_some_and(|c| {
                    c.iter()
                        .all(|&k| k == Reachable::Beyond || k == Reachable::Never)
                })
            })
            .collect();
        SWEEPER.with(|cell| {
            let (sweeper, spans, seeds) = &mut *cell.borrow_mut();
            let mut skipped = 0;
            let mut dropped = 0;
            // Walks are seeded with what the previous point of the region saw.
            let mut seed_region = usize::MAX;
            for &i in grid.in_leaf(leaf.rect) {
                let i = i as usize;
                let px = pixel[i];
                let comp = geometry.components[px[1] as usize * geometry.width + px[0] as usize];
                spans.clear();
                let region = leaf.region_at(px);
                if region.is_some_and(|r| dark[r]) {
                    skipped += 1;
                } else {
                    match leaf.candidates_at(px) {
                        Some(cands) => {
                            let class = region.and_then(|r| class[r].as_deref());
                            dropped += sweeper.sweep_wanted(
                                &geometry.edges,
                                cands,
                                pos[i],
                                view(i),
                                comp,
                                reach2.map(|reach2| Wanted { reach2, class }),
                                spans,
                            )
                        }
                        None => {
                            if region != Some(seed_region) {
                                seeds.clear();
                            }
                            dropped += sweeper.walk_wanted(
                                &geometry.edges,
                                &blocks,
                                pos[i],
                                view(i),
                                comp,
                                reach.max,
                                seeds,
                                reach2.map(|reach2| Wanted {
                                    reach2,
                                    class: None,
                                }),
                                spans,
                            );
                            seeds.clear();
                            seeds.extend(spans.iter().map(|s| s.edge));
                            seeds.dedup();
                            seed_region = region.unwrap_or(usize::MAX);
                        }
                    }
                }
                f(i, spans);
            }
            unreached.fetch_add(skipped, std::sync::atomic::Ordering::Relaxed);
            left_out.fetch_add(dropped, std::sync::atomic::Ordering::Relaxed);
        })
    });
    VisitStats {
        culled_pairs: culled_pairs + left_out.into_inner(),
        unreached: unreached.into_inner(),
    }
}

/// [`Wanted`] squared reaches for `reach`: edges that `lit` says have light
/// reach out to their radius, the others nowhere.
pub fn wanted_reach(reach: &Reach, lit: impl Fn(usize) -> bool) -> Vec<f64> {
    reach
        .radius
        .iter()
        .enumerate()
        .map(|(e, &r)| if lit(e) { r * r } else { -1.0 })
        .collect()
}

/// Computes the form factors with `quad` Gauss-Legendre points per patch,
/// and the per-point rows behind them.
pub fn form_factors(
    geometry: &Geometry,
    patches: &Patches,
    quad: usize,
    falloff: Option<Falloff>,
    reach: &Reach,
) -> (FormFactors, PointRows, VisitStats) {
    let edges = &geometry.edges;
    let (xs, ws) = gauss_legendre(quad);
    let q = xs.len();
    let n = patches.len();
    // Query points: q per patch, each with the free pixel in front of it.
    let mut pos = Vec::with_capacity(n * q);
    let mut pixel = Vec::with_capacity(n * q);
    for p in 0..n {
        let e = &edges[patches.edge[p] as usize];
        let (s0, s1) = patches.bounds(edges, p);
        for &x in xs {
            let s = s0 + x * (s1 - s0);
            pos.push(e.point_at(s));
            pixel.push(e.free_pixel_at(s.floor() as i32));
        }
    }
    let results: Vec<std::sync::Mutex<Vec<(u32, f64)>>> =
        (0..n * q).map(|_| Default::default()).collect();
    let view = |i: usize| View::Half(edges[patches.edge[i / q] as usize].normal);
    // Every edge receives light: each is wanted within its reach.
    let reach2 = wanted_reach(reach, |_| true);
    let stats = for_each_visibility(
        geometry,
        &pos,
        &pixel,
        &view,
        reach,
        Some(&reach2),
        &|i, spans| {
            let mut out = Vec::new();
            point_factors(
                edges,
                patches,
                pos[i],
                edges[patches.edge[i / q] as usize].normal,
                spans,
                falloff,
                &mut out,
            );
            *results[i].lock().expect("no panics while holding the lock") = out;
        },
    );
    let rows: Vec<Vec<(u32, f64)>> = (0..n)
        .into_par_iter()
        .map(|p| {
            let mut row: Vec<(u32, f64)> = Vec::new();
            for (k, w) in ws.iter().enumerate() {
                let r = results[p * q + k]
                    .lock()
                    .expect("no panics while holding the lock");
                row.extend(r.iter().map(|&(j, v)| (j, v * w)));
            }
            row.sort_by_key(|e| e.0);
            let mut merged: Vec<(u32, f64)> = Vec::with_capacity(row.len());
            for (j, v) in row {
                match merged.last_mut() {
                    Some(last) if last.0 == j => last.1 += v,
                    _ => merged.push((j, v)),
                }
            }
            merged
        })
        .collect();
    let mut points = PointRows {
        q,
        row_ptr: Vec::with_capacity(n * q + 1),
        col: Vec::new(),
        val: Vec::new(),
    };
    points.row_ptr.push(0);
    for r in results {
        let r = r.into_inner().expect("no panics while holding the lock");
        points.col.extend(r.iter().map(|e| e.0));
        points.val.extend(r.iter().map(|e| e.1));
        points.row_ptr.push(points.col.len());
    }
    let len: Vec<f64> = (0..n).map(|p| patches.length(p)).collect();
    (FormFactors::from_raw_rows(rows, &len), points, stats)
}
