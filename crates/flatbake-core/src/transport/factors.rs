//! The form factors: exact point-to-patch factors at Gauss-Legendre points,
//! symmetrised into `S` with effective lengths `D` (see the module docs of
//! [`crate::transport`]).

use std::sync::{Arc, Mutex, OnceLock};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{Edge, Geometry, Normal};
use crate::transport::kernel::Reach;
use crate::transport::kernel::{FactorLine, Falloff, gauss_legendre};
use crate::transport::{Patches, axis_vec, normal_vec};
use crate::visibility::{Reaches, Span, Structures, View, VisitStats, for_each_visibility_counted};

/// The factors from point `x` on an edge with normal `nx` to every patch it
/// sees, appended to `out` as `(patch, K)`; `spans` is the point's visibility
/// (the falloff reach is applied there, see [`for_each_visibility_counted`]).
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
/// and the effective lengths `D`: `F_ij = S_ij / D_i`. Its columns are
/// shared with the [`SlopeRows`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FormFactors {
    /// Row starts of `S` (CSR).
    pub row_ptr: Vec<usize>,
    /// Column (patch) of each stored entry.
    pub col: Arc<Vec<u32>>,
    /// `S_ij` of each stored entry.
    pub val: Vec<f64>,
    /// Effective lengths `D_i`.
    pub dlen: Vec<f64>,
    /// Raw row sums `t_i` of F: the fraction of patch `i`'s light that lands
    /// on some patch (1 in a closed room without falloff), slivers included
    /// ([`form_factors`]).
    pub coverage: Vec<f64>,
    /// Entries of the patches' merged rows left out as slivers.
    #[serde(default)]
    pub dropped: u64,
    /// Entries of `S` whose pair only one of the two patches' rows holds
    /// (seen through a gap from one side only, or a sliver of one row
    /// alone): that row's entry stands for both.
    #[serde(default)]
    pub one_sided: u64,
}

impl FormFactors {
    /// Number of patches.
    pub fn n(&self) -> usize {
        self.dlen.len()
    }

    /// Number of stored entries.
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

    /// Builds `S` and `D` from raw rows `F0` (each sorted by column, their
    /// pattern symmetric: [`symmetric_rows`]) and patch lengths, in `F0`'s
    /// values and on its pattern. Each row of `F` sums to its raw row's
    /// `sum`: where slivers were left out of the raw row, its other entries
    /// share their part.
    fn from_raw_rows(raw: RawRows<'_>, len: &[f64]) -> FormFactors {
        let n = raw.row_ptr.len().saturating_sub(1);
        let mut coverage = raw.sum;
        let col = &raw.col[..];
        // S = A + A^T with A_ij = L_i F0_ij / 2, each pair once, from the
        // row of its lower patch: both entries get `a + b` (the same bits
        // as `b + a`). A_ji is looked up in row j; rows are walked in
        // order, so the look-ups into each row j come in increasing i: one
        // cursor per row, moving forward only, finds them all in one pass.
        let mut cursor: Vec<usize> = raw.row_ptr[..n].to_vec();
        let mut val = raw.val;
        for i in 0..n {
            for k in raw.row_ptr[i]..raw.row_ptr[i + 1] {
                let j = col[k] as usize;
                if j < i {
                    continue;
                }
                let a = 0.5 * len[i] * val[k];
                if j == i {
                    val[k] = a + a;
                    continue;
                }
                let end = raw.row_ptr[j + 1];
                let mut c = cursor[j];
                while c < end && col[c] < i as u32 {
                    c += 1;
                }
                assert!(
                    c < end && col[c] == i as u32,
                    "the raw rows' pattern is symmetric"
                );
                cursor[j] = c + 1;
                let s = a + 0.5 * len[j] * val[c];
                val[k] = s;
                val[c] = s;
            }
        }
        let (row_ptr, col) = (raw.row_ptr.to_vec(), Arc::clone(raw.col));
        drop(cursor);
        let dlen = coverage
            .par_iter_mut()
            .enumerate()
            .map(|(i, coverage)| {
                let s: f64 = val[row_ptr[i]..row_ptr[i + 1]].iter().sum();
                if *coverage > 0.0 && s > 0.0 {
                    s / *coverage
                } else {
                    // A patch whose own row is empty (every pair culled by
                    // the falloff reach) can still be in other patches' rows,
                    // and so in its own row of the symmetric S. Its coverage
                    // is then that row's sum, not 0: otherwise the light it
                    // sends is counted as escaped as well as received, and
                    // emitted != absorbed + escaped.
                    *coverage = s / len[i];
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
            dropped: 0,
            one_sided: 0,
        }
    }
}

/// The raw rows `F0` of the form factors, one per patch (CSR, each row
/// sorted by column, the pattern symmetric), from which
/// [`FormFactors::from_raw_rows`] builds `S`. Their pattern is borrowed:
/// it is that of the [`SlopeRows`], which `S` shares.
struct RawRows<'a> {
    /// Row starts.
    row_ptr: &'a [usize],
    /// Patch of each entry.
    col: &'a Arc<Vec<u32>>,
    /// `F0` of each entry.
    val: Vec<f64>,
    /// Each row's sum before slivers were left out of it.
    sum: Vec<f64>,
}

/// What the quadrature points of each patch say of its light's profile:
/// `G_pj = sum_k w_k (x_k - 1/2) K(x_k, j)` (CSR, one row per patch), from
/// which each patch gets a slope once the radiosity is solved. The points'
/// own rows are merged into these as soon as a patch's last point is
/// visited, so they are never all kept.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SlopeRows {
    /// The preset's quadrature points per patch; a patch has its
    /// [`Patches::points`] of them.
    pub q: usize,
    /// Row starts, one row per patch (CSR).
    pub row_ptr: Vec<usize>,
    /// Patch of each entry (shared with [`FormFactors`] where the pattern
    /// of `S` is the same).
    pub col: Arc<Vec<u32>>,
    /// `G_pj` of each entry, in single precision: it serves only the
    /// slope, a first-order correction, where its rounding (a relative
    /// 6e-8) moves no value of the 32-bit lightmap by more than its own
    /// rounding (docs/transport.md, Floor gather). Four bytes per entry
    /// less, at the form factors' peak.
    pub val: Vec<f32>,
}

impl SlopeRows {
    /// Per-patch slope (per unit length along the edge's axis) of the
    /// radiosity profile through the quadrature points, least squares,
    /// limited so that `B` stays non-negative over the patch. `b` is the
    /// solved patch radiosity, `e` and `rho` per patch. With the radiosity at
    /// point `k`, `B_k = e + rho * sum_j K(x_k, j) B_j`, the least-squares
    /// numerator `sum_k w_k (x_k - 1/2) B_k` is
    /// `e * sum_k w_k (x_k - 1/2) + rho * sum_j G_pj B_j`.
    pub fn slopes(&self, patches: &Patches, rho: &[f64], e: &[f64], b: &[f64]) -> Vec<f64> {
        // Per number of points: the least-squares denominator and the
        // emission's odd moment.
        let moments: Vec<(f64, f64)> = (1..=self.q)
            .map(|q| {
                let (xs, ws) = gauss_legendre(q);
                let den = xs
                    .iter()
                    .zip(ws)
                    .map(|(x, w)| w * (x - 0.5) * (x - 0.5))
                    .sum();
                let odd = xs.iter().zip(ws).map(|(x, w)| w * (x - 0.5)).sum();
                (den, odd)
            })
            .collect();
        (0..patches.len())
            .into_par_iter()
            .map(|p| {
                let (den, odd) = moments[patches.points(p, self.q) - 1];
                if den == 0.0 || rho[p] == 0.0 {
                    return 0.0;
                }
                let r = self.row_ptr[p]..self.row_ptr[p + 1];
                let h: f64 = self.col[r.clone()]
                    .iter()
                    .zip(&self.val[r])
                    .map(|(&j, &v)| f64::from(v) * b[j as usize])
                    .sum();
                let num = e[p] * odd + rho[p] * h;
                let len = patches.length(p);
                let g = num / (den * len);
                // Keep B >= 0 at both ends of the patch.
                let limit = 2.0 * b[p].max(0.0) / len;
                g.clamp(-limit, limit)
            })
            .collect()
    }
}

/// [`Wanted`](crate::visibility::Wanted) squared reaches for `reach`: edges that `lit` says have light
/// reach out to their radius, the others nowhere.
pub fn wanted_reach(reach: &Reach, lit: impl Fn(usize) -> bool) -> Vec<f64> {
    reach
        .radius
        .iter()
        .enumerate()
        .map(|(e, &r)| if lit(e) { r * r } else { -1.0 })
        .collect()
}

/// The quadrature points of patches `which`, each patch's
/// [`Patches::points`] of a preset's `q` at their Gauss-Legendre abscissae,
/// one patch after another: per point its position, the free pixel in
/// front of it, and which of `which` it belongs to; and where each of
/// `which`'s points start.
struct QueryPoints {
    pos: Vec<[f64; 2]>,
    pixel: Vec<[i32; 2]>,
    owner: Vec<u32>,
    start: Vec<usize>,
}

impl QueryPoints {
    fn new(geometry: &Geometry, patches: &Patches, q: usize, which: &[usize]) -> QueryPoints {
        let edges = &geometry.edges;
        // On the workers, in order (wall noise's 500,000 points took 11 ms
        // on one core).
        let (pos, (pixel, owner)) = which
            .par_iter()
            .enumerate()
            .flat_map_iter(|(w, &p)| {
                let e = &edges[patches.edge[p] as usize];
                let (s0, s1) = patches.bounds(edges, p);
                gauss_legendre(patches.points(p, q))
                    .0
                    .iter()
                    .map(move |&x| {
                        let s = s0 + x * (s1 - s0);
                        (e.point_at(s), (e.free_pixel_at(s.floor() as i32), w as u32))
                    })
            })
            .unzip();
        let start = std::iter::once(0)
            .chain(which.iter().scan(0, |n, &p| {
                *n += patches.points(p, q);
                Some(*n)
            }))
            .collect();
        QueryPoints {
            pos,
            pixel,
            owner,
            start,
        }
    }
}

/// Runs `f(w, k, row)` for point `k` of each patch `which[w]` (its
/// [`Patches::points`] of a preset's `q`): the point's exact visibility and
/// its factors `K(x, j)` towards the patches it sees within their reach.
/// The one visit behind both [`form_factors`] and [`estimate_entries`].
fn visit_point_rows(
    structures: &Structures,
    patches: &Patches,
    q: usize,
    which: &[usize],
    falloff: Option<Falloff>,
    reach: &Reach,
    f: &(dyn Fn(usize, usize, Vec<(u32, f64)>) + Sync),
) -> VisitStats {
    let geometry = structures.geometry();
    let edges = &geometry.edges;
    let pts = QueryPoints::new(geometry, patches, q, which);
    let normal = |i: usize| edges[patches.edge[which[pts.owner[i] as usize]] as usize].normal;
    let view = |i: usize| View::Half(normal(i));
    // Every edge receives light: each is wanted within its reach.
    let reach2 = wanted_reach(reach, |_| true);
    for_each_visibility_counted(
        structures,
        Some(&pts.pos),
        &pts.pixel,
        &view,
        reach.max,
        Some(&match falloff {
            Some(f) => Reaches::receiving(&reach2, f.a()),
            None => Reaches::new(&reach2),
        }),
        &|_| {},
        None,
        &|i, spans| {
            // Found in a buffer of the thread's and copied out at its size:
            // one allocation per point instead of one per doubling (the
            // threads' allocations contend where they share a heap).
            let out = SCRATCH.with_borrow_mut(|Scratch { point: out, .. }| {
                out.clear();
                point_factors(edges, patches, pts.pos[i], normal(i), spans, falloff, out);
                out.to_vec()
            });
            let w = pts.owner[i] as usize;
            f(w, i - pts.start[w], out);
        },
    )
}

/// An estimate of how many entries [`form_factors`] would store per patch
/// (its merged row: one entry per patch that any of its quadrature points
/// sees, less its slivers), from the exact visibility of at most `samples`
/// patches spread evenly over the patch list: their mean times the number
/// of patches. It costs a small part of the form factors themselves; it
/// lets a bake that would need more memory than the machine has be
/// refused before it starts.
pub fn estimate_entries(
    structures: &Structures,
    patches: &Patches,
    quad: usize,
    falloff: Option<Falloff>,
    reach: &Reach,
    sliver: f64,
    samples: usize,
) -> u64 {
    let n = patches.len();
    if n == 0 || samples == 0 {
        return 0;
    }
    let k = samples.min(n);
    // Patch i * n / k for i < k: evenly spread, deterministic.
    let picked: Vec<usize> = (0..k).map(|i| i * n / k).collect();
    // Per sampled patch, its points' rows (in point order).
    let seen: Vec<Mutex<Vec<PointRow>>> = picked
        .iter()
        .map(|&p| Mutex::new(vec![Vec::new(); patches.points(p, quad)]))
        .collect();
    visit_point_rows(
        structures,
        patches,
        quad,
        &picked,
        falloff,
        reach,
        &|w, k, row| {
            seen[w].lock().expect("no panics while holding the lock")[k] = row;
        },
    );
    let counted: usize = seen
        .into_iter()
        .map(|s| {
            let rows = s.into_inner().expect("no panics while holding the lock");
            let (xs, ws) = gauss_legendre(rows.len());
            merge_points(&rows, xs, ws, sliver).0.len()
        })
        .sum();
    (counted as f64 * n as f64 / k as f64).ceil() as u64
}

/// Computes the form factors with Gauss-Legendre points on every patch
/// (its [`Patches::points`] of `quad`), and the slope rows that the points'
/// rows leave behind.
///
/// A patch's smallest factors, together at most `sliver` of its row's sum,
/// are left out of its row, and the rest of the row shares their part (the
/// row's sum is kept: no light is lost). On a level of one-pixel dots,
/// each quadrature point sees slivers of hundreds of dots through the gaps
/// between nearer ones: at `1e-5` 38 % of the entries go at 256 px, 66 %
/// at 640 px (see docs/transport.md, Slivers).
///
/// Each point's row is held only until the last point of its patch is
/// visited (the points of a patch are neighbours, so they are visited close
/// together); then the patch's rows are merged into its row of `F0` and its
/// row of [`SlopeRows`] at once. The merge adds in the points' order, so
/// `F` does not depend on the order the points were visited in.
pub fn form_factors(
    structures: &Structures,
    patches: &Patches,
    quad: usize,
    falloff: Option<Falloff>,
    reach: &Reach,
    sliver: f64,
) -> (FormFactors, SlopeRows, VisitStats) {
    let n = patches.len();
    // (The tables per patch are set up, and read out below, on the
    // workers: on wall noise's 180,000 patches each step took several ms
    // on one core.)
    let pending: Vec<Mutex<Arrived>> = (0..n).into_par_iter().map(|_| Default::default()).collect();
    // Per patch, once merged: `(j, F0_pj, G_pj)`, the raw row's sum and
    // how many slivers left it.
    let merged: Vec<OnceLock<Merged>> = (0..n).into_par_iter().map(|_| OnceLock::new()).collect();
    let all: Vec<usize> = (0..n).collect();
    let stats = visit_point_rows(
        structures,
        patches,
        quad,
        &all,
        falloff,
        reach,
        &|p, k, row| {
            let q = patches.points(p, quad);
            let complete = {
                let mut slot = pending[p].lock().expect("no panics while holding the lock");
                let (arrived, rows) = &mut *slot;
                if rows.is_empty() {
                    rows.resize_with(q, Vec::new);
                }
                rows[k] = row;
                *arrived += 1;
                (*arrived == q).then(|| std::mem::take(rows))
            };
            if let Some(rows) = complete {
                let (xs, ws) = gauss_legendre(q);
                let row = merge_points(&rows, xs, ws, sliver);
                merged[p].set(row).expect("each patch is merged once");
            }
        },
    );
    // A point that was never visited has an empty row, as every point of a
    // patch that nothing reaches.
    pending
        .into_par_iter()
        .zip(&merged)
        .enumerate()
        .for_each(|(p, (slot, merged))| {
            let (_, mut rows) = slot.into_inner().expect("no panics while holding the lock");
            if merged.get().is_none() {
                let q = patches.points(p, quad);
                let (xs, ws) = gauss_legendre(q);
                rows.resize_with(q, Vec::new);
                merged
                    .set(merge_points(&rows, xs, ws, sliver))
                    .expect("not merged yet");
            }
        });
    let merged: Vec<Merged> = merged
        .into_par_iter()
        .map(|m| m.into_inner().unwrap_or_default())
        .collect();
    let len: Vec<f64> = (0..n).into_par_iter().map(|p| patches.length(p)).collect();
    let (slopes, raw_val, sum, counts) = symmetric_rows(merged, quad);
    let raw = RawRows {
        row_ptr: &slopes.row_ptr,
        col: &slopes.col,
        val: raw_val,
        sum,
    };
    let mut ff = FormFactors::from_raw_rows(raw, &len);
    (ff.dropped, ff.one_sided) = counts;
    (ff, slopes, stats)
}

/// Splits the patches' merged rows into the slope rows and `F0`'s values,
/// on one pattern made symmetric: where patch `i`'s row has patch `j` and
/// `j`'s row lacks `i` (a pair seen from one side only: through a gap that
/// `j`'s points miss, or a sliver in one row alone), row `j` gets `i` with
/// `F0 = G = 0`. `S` is then built in place in `F0`'s values and shares
/// the pattern ([`FormFactors::from_raw_rows`]). Returns the slope rows,
/// `F0`'s values, the rows' sums before slivers and the counts of entries
/// left out as slivers and of entries added.
fn symmetric_rows(merged: Vec<Merged>, q: usize) -> (SlopeRows, Vec<f64>, Vec<f64>, (u64, u64)) {
    let n = merged.len();
    let mut added = missing_pairs(&merged);
    let one_sided = added.len() as u64;
    // Row starts: each row's own entries and those added to it.
    let mut row_ptr = Vec::with_capacity(n + 1);
    row_ptr.push(0);
    let mut a = 0;
    for (j, (row, ..)) in merged.iter().enumerate() {
        let from = a;
        while a < added.len() && added[a].0 as usize == j {
            a += 1;
        }
        row_ptr.push(row_ptr[j] + row.len() + (a - from));
    }
    let entries = row_ptr[n];
    // Zeroed, so only the pages written below are ever taken.
    let mut col = vec![0u32; entries];
    let mut raw_val = vec![0.0f64; entries];
    let mut g_val = vec![0.0f32; entries];
    let (mut sum, mut dropped) = (vec![0.0; n], 0);
    // From the last row to the first, so that the entries to add are taken
    // from the end of their list, which is shortened as it goes, and the
    // merged rows freed as they are copied: the tables' pages come as the
    // others go, and the peak is the tables' own size. The freed memory,
    // scattered over the heaps in the order the threads allocated it, is
    // handed back every sixteenth of the patches.
    let every = n.div_ceil(16).max(1);
    for (p, (row, s, d)) in merged.into_iter().enumerate().rev() {
        if p % every == 0 {
            added.shrink_to_fit();
            release_freed_memory();
        }
        sum[p] = s;
        dropped += d;
        // Row `p`'s entries to add: the last of the list, as many as its
        // start counted beyond its own.
        let from = added.len() - (row_ptr[p + 1] - row_ptr[p] - row.len());
        let r = row_ptr[p]..row_ptr[p + 1];
        if from == added.len() {
            // Nothing to add (most rows): a straight copy.
            let out = col[r.clone()].iter_mut().zip(&mut raw_val[r.clone()]);
            for ((c, v), (gv, &(j, f, g))) in out.zip(g_val[r].iter_mut().zip(&row)) {
                (*c, *v, *gv) = (j, f, g);
            }
            continue;
        }
        let mut extra = added[from..].iter().map(|e| (e.1, 0.0, 0.0)).peekable();
        let mut own = row.iter().copied().peekable();
        for w in r {
            let next = match (own.peek(), extra.peek()) {
                (Some(o), Some(x)) if x.0 < o.0 => extra.next(),
                (Some(_), _) => own.next(),
                (None, _) => extra.next(),
            };
            let (j, f, g) = next.expect("the row's start counts its entries");
            col[w] = j;
            raw_val[w] = f;
            g_val[w] = g;
        }
        added.truncate(from);
    }
    release_freed_memory();
    let slopes = SlopeRows {
        q,
        row_ptr,
        col: Arc::new(col),
        val: g_val,
    };
    (slopes, raw_val, sum, (dropped, one_sided))
}

/// The entries that make the rows' pattern symmetric, as `(row, patch)`
/// sorted: `(j, i)` for every patch `j` in row `i` whose own row lacks
/// `i`. Read off the transposed pattern, built by counting (the rows in
/// order, one scattered write per entry), and merged with each row: a
/// search of row `j` for every entry read a row anywhere in memory per
/// entry (on the pillar field 234 ms against 68, docs/performance.md).
fn missing_pairs(rows: &[Merged]) -> Vec<(u32, u32)> {
    let n = rows.len();
    // `listed[start[j]..start[j + 1]]`: the rows that hold `j`, rising.
    let mut start = vec![0usize; n + 1];
    for (row, ..) in rows {
        for e in row {
            start[e.0 as usize + 1] += 1;
        }
    }
    for j in 0..n {
        start[j + 1] += start[j];
    }
    let mut listed = vec![0u32; start[n]];
    let mut next = start.clone();
    for (i, (row, ..)) in rows.iter().enumerate() {
        for e in row {
            let at = &mut next[e.0 as usize];
            listed[*at] = i as u32;
            *at += 1;
        }
    }
    drop(next);
    // Both sides sorted: a merge per row. Collecting keeps the rows' order.
    (0..n)
        .into_par_iter()
        .flat_map_iter(|j| {
            let mut own = rows[j].0.iter().map(|e| e.0).peekable();
            listed[start[j]..start[j + 1]]
                .iter()
                .filter(move |&&i| {
                    while own.next_if(|&o| o < i).is_some() {}
                    own.peek() != Some(&i)
                })
                .map(move |&i| (j as u32, i))
        })
        .collect()
}

/// Hands the heap memory freed so far back to the system (glibc's
/// `malloc_trim`; elsewhere nothing).
fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free memory of glibc's heaps.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// One quadrature point's row: `(patch, K)` per patch it sees.
type PointRow = Vec<(u32, f64)>;

/// Per patch while its points are visited: how many have arrived, and
/// their rows (in point order).
type Arrived = (usize, Vec<PointRow>);

/// A patch's merged row ([`merge_points`]), its sum before slivers were
/// left out, and how many were.
type Merged = (Vec<(u32, f64, f32)>, f64, u64);

/// A patch's row from its points' rows (in point order, weights `ws` at
/// abscissae `xs`): `(j, sum_k w_k K(x_k, j), sum_k w_k (x_k - 1/2) K(x_k, j))`
/// sorted by patch `j`, each sum taken in point order, the second kept in
/// single precision ([`SlopeRows`]), without slack; less its slivers: the
/// smallest entries (ties by patch), as many as sum to at most `sliver` of
/// the row's sum. Returns the row, its sum before (in patch order) and how
/// many entries were left out.
fn merge_points(rows: &[Vec<(u32, f64)>], xs: &[f64], ws: &[f64], sliver: f64) -> Merged {
    SCRATCH.with_borrow_mut(|Scratch { row, by_value, .. }| {
        merge_points_in(rows, xs, ws, sliver, row, by_value)
    })
}

/// A thread's buffers for the form factors' rows.
#[derive(Default)]
struct Scratch {
    /// A point's row while it is found.
    point: PointRow,
    /// A patch's merged row while it is merged.
    row: Vec<(u32, f64, f64)>,
    /// Its entries by value, for the slivers.
    by_value: Vec<(f64, u32)>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = Default::default();
}

/// [`merge_points`] in the buffers `row` and `by_value`.
fn merge_points_in(
    rows: &[Vec<(u32, f64)>],
    xs: &[f64],
    ws: &[f64],
    sliver: f64,
    row: &mut Vec<(u32, f64, f64)>,
    by_value: &mut Vec<(f64, u32)>,
) -> Merged {
    row.clear();
    for ((r, &x), &w) in rows.iter().zip(xs).zip(ws) {
        let t = w * (x - 0.5);
        row.extend(r.iter().map(|&(j, v)| (j, v * w, v * t)));
    }
    // Stable: equal patches stay in point order, and are summed in it.
    row.sort_by_key(|e| e.0);
    row.dedup_by(|next, kept| {
        let same = next.0 == kept.0;
        if same {
            kept.1 += next.1;
            kept.2 += next.2;
        }
        same
    });
    let sum: f64 = row.iter().map(|e| e.1).sum();
    let mut last = None;
    if sliver > 0.0 && row.len() > 1 {
        let (budget, mut spent) = (sliver * sum, 0.0);
        // Only entries no larger than the budget can go (the entries are
        // positive): sorted, they are the head of the whole row sorted,
        // and usually few.
        by_value.clear();
        by_value.extend(row.iter().filter(|e| e.1 <= budget).map(|e| (e.1, e.0)));
        by_value.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // The last entry to leave out, as (value, patch): every entry
        // ordered before it goes too.
        for &(v, j) in by_value.iter() {
            if spent + v > budget {
                break;
            }
            spent += v;
            last = Some((v, j));
        }
    }
    let out = |e: &&(u32, f64, f64)| last.is_some_and(|last| (e.1, e.0) <= last);
    let dropped = row.iter().filter(out).count();
    let mut kept = Vec::with_capacity(row.len() - dropped);
    kept.extend(
        row.iter()
            .filter(|e| !out(e))
            .map(|&(j, f, g)| (j, f, g as f32)),
    );
    (kept, sum, dropped as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Builds `S` from `rows` of `F0` (with `G = F0 / 4`) and checks it
    /// against the definition `S = A + A^T`, `A_ij = L_i F0_ij / 2`, entry
    /// by entry, bit for bit, with no other entries; and the slope rows
    /// against `rows` (`G = 0` where an entry was added). Returns `S` and
    /// how many entries were added.
    fn s_against_the_definition(rows: &[&[(u32, f64)]], len: &[f64]) -> (FormFactors, u64) {
        let n = rows.len();
        let merged: Vec<Merged> = rows
            .iter()
            .map(|r| {
                let row = r.iter().map(|&(j, f)| (j, f, (f / 4.0) as f32)).collect();
                (row, r.iter().map(|e| e.1).sum(), 0)
            })
            .collect();
        let (slopes, val, sum, (dropped, added)) = symmetric_rows(merged, 3);
        assert_eq!(dropped, 0);
        let raw = RawRows {
            row_ptr: &slopes.row_ptr,
            col: &slopes.col,
            val,
            sum,
        };
        let a = |i: usize, j: usize| {
            rows[i]
                .iter()
                .find(|e| e.0 as usize == j)
                .map(|e| 0.5 * len[i] * e.1)
        };
        let ff = FormFactors::from_raw_rows(raw, len);
        assert!(Arc::ptr_eq(&ff.col, &slopes.col), "one pattern");
        for i in 0..n {
            let r = ff.row_ptr[i]..ff.row_ptr[i + 1];
            let cols = &ff.col[r.clone()];
            assert!(cols.windows(2).all(|w| w[0] < w[1]), "row {i} sorted");
            for j in 0..n {
                let want = match (a(i, j), a(j, i)) {
                    (None, None) => None,
                    (x, y) => Some(x.unwrap_or(0.0) + y.unwrap_or(0.0)),
                };
                let at = cols.iter().position(|&c| c as usize == j);
                assert_eq!(at.map(|k| ff.val[r.start + k]), want, "S[{i}][{j}]");
                let g = rows[i].iter().find(|e| e.0 as usize == j);
                let want_g = g.map(|e| (e.1 / 4.0) as f32).or(want.map(|_| 0.0));
                assert_eq!(at.map(|k| slopes.val[r.start + k]), want_g, "G[{i}][{j}]");
            }
        }
        (ff, added)
    }

    /// On a pattern with entries whose transpose is missing (both ways), a
    /// diagonal entry, an empty row and an empty column, the rows are
    /// padded to a symmetric pattern.
    #[test]
    fn s_is_a_plus_its_transpose_on_an_asymmetric_pattern() {
        let rows: [&[(u32, f64)]; 5] = [
            &[(1, 0.25), (3, 0.125)],
            &[(0, 0.5), (2, 0.0625), (4, 0.375)],
            &[(2, 0.03125), (3, 0.2)],
            &[],
            &[(0, 0.1), (1, 0.3)],
        ];
        let (ff, added) = s_against_the_definition(&rows, &[1.0, 2.0, 0.5, 3.0, 1.5]);
        // (0,3) (1,2) (2,3) (4,0) each lack their transpose.
        assert_eq!(added, 4);
        // Row 3 sent nothing: its coverage is what it receives, per length.
        let s3: f64 = ff.val[ff.row_ptr[3]..ff.row_ptr[4]].iter().sum();
        assert!((ff.coverage[3] - s3 / 3.0).abs() < 1e-15);
    }

    /// The entries found missing from the transposed pattern are those a
    /// search of every row for every entry's transpose finds, in order, on
    /// random patterns from nearly empty to nearly full.
    #[test]
    fn missing_pairs_are_the_transposes_a_search_misses() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for (n, per_mille) in [(1, 500), (7, 300), (60, 20), (60, 500), (120, 950)] {
            let merged: Vec<Merged> = (0..n)
                .map(|_| {
                    let row = (0..n as u32)
                        .filter(|_| next() % 1000 < per_mille)
                        .map(|j| (j, 1.0, 0.0))
                        .collect();
                    (row, 0.0, 0)
                })
                .collect();
            let mut searched = Vec::new();
            for (i, (row, ..)) in merged.iter().enumerate() {
                for e in row {
                    let other = &merged[e.0 as usize].0;
                    if other.binary_search_by_key(&(i as u32), |t| t.0).is_err() {
                        searched.push((e.0, i as u32));
                    }
                }
            }
            searched.sort_unstable();
            assert_eq!(
                missing_pairs(&merged),
                searched,
                "{n} rows, {per_mille} per mille"
            );
        }
    }

    /// On a symmetric pattern (with a diagonal entry and an empty row)
    /// nothing is added.
    #[test]
    fn a_symmetric_pattern_is_kept() {
        let rows: [&[(u32, f64)]; 5] = [
            &[(1, 0.25), (3, 0.125), (4, 0.7)],
            &[(0, 0.5), (1, 0.01), (3, 0.0625)],
            &[],
            &[(0, 0.1), (1, 0.3), (4, 0.2)],
            &[(0, 0.3), (3, 0.15)],
        ];
        let (_, added) = s_against_the_definition(&rows, &[1.0, 2.0, 0.5, 3.0, 1.5]);
        assert_eq!(added, 0);
    }
}
