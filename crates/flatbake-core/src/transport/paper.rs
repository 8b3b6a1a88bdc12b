//! The paper's own kernel (`--kernel paper`), its equations 4 and 5 as written.
//!
//! `F_ij = A w / (A + r^2) * Vis(i, j)` between patch centres, with
//! `w = cos(theta_i) cos(theta_j)`, `F_ii = 1`, and `A` infinite without
//! falloff. `Vis` is the fraction of paired sample segments (the k-th sample
//! of patch i joined to the k-th sample of patch j) that no edge blocks.
//! These factors are per patch, not per unit length, so rows can sum far
//! above 1 and the solve would explode or go negative. flatbake guards it:
//! a row whose `rho F` sum reaches 1 is normalised so that `F` sums to 1 on
//! it, and where `rho = 1` scaled further to [`MAX_ROW`]; a row whose sum is
//! in `(MAX_ROW, 1)` is scaled to [`MAX_ROW`] (less than 0.1%) so that the
//! iterative solve of large systems always converges. The result is then
//! always finite and non-negative (`|rho F|_inf < 1` with non-negative
//! entries), and the report counts the rescaled rows.

use nalgebra::{DMatrix, DVector};

use crate::geometry::Geometry;
use crate::transport::Patches;
use crate::transport::kernel::Falloff;
use crate::visibility::{View, diamond, for_each_visibility};

/// Sample segments per patch pair.
pub const SAMPLES: usize = 4;
/// Largest row sum of `rho F` after rescaling.
pub const MAX_ROW: f64 = 0.999;

/// The paper's F as sparse rows `(j, F_ij)`, symmetric, `F_ii = 1` included.
pub fn form_factors(
    g: &Geometry,
    patches: &Patches,
    falloff: Option<Falloff>,
) -> Vec<Vec<(u32, f64)>> {
    let edges = &g.edges;
    let n = patches.len();
    let centre = |p: usize| {
        let (s0, s1) = patches.bounds(edges, p);
        edges[patches.edge[p] as usize].point_at(0.5 * (s0 + s1))
    };
    let sample = |p: usize, k: usize| {
        let (s0, s1) = patches.bounds(edges, p);
        (
            s0 + (k as f64 + 0.5) / SAMPLES as f64 * (s1 - s0),
            edges[patches.edge[p] as usize]
                .point_at(s0 + (k as f64 + 0.5) / SAMPLES as f64 * (s1 - s0)),
        )
    };
    let mut pos = Vec::with_capacity(n * SAMPLES);
    let mut pixel = Vec::with_capacity(n * SAMPLES);
    for p in 0..n {
        let e = &edges[patches.edge[p] as usize];
        for k in 0..SAMPLES {
            let (s, pt) = sample(p, k);
            pos.push(pt);
            pixel.push(e.free_pixel_at(s.floor() as i32));
        }
    }
    // visible[i * SAMPLES + k] lists the patches j > i whose k-th sample the
    // k-th sample of i sees.
    let visible: Vec<std::sync::Mutex<Vec<u32>>> =
        (0..n * SAMPLES).map(|_| Default::default()).collect();
    let view = |i: usize| View::Half(edges[patches.edge[i / SAMPLES] as usize].normal);
    for_each_visibility(
        g,
        &pos,
        &pixel,
        &view,
        f64::INFINITY,
        None,
        &|q, spans: &[crate::visibility::Span]| {
            let (i, k) = (q / SAMPLES, q % SAMPLES);
            let x = pos[q];
            let mut out = Vec::new();
            for j in i + 1..n {
                let (s, y) = sample(j, k);
                let key = diamond_from(x, y, edges[patches.edge[i] as usize].normal);
                let at = spans.partition_point(|sp| sp.k1 <= key);
                if let Some(sp) = spans.get(at)
                    && sp.k0 <= key
                    && sp.edge == patches.edge[j]
                    && sp.s0 <= s
                    && s <= sp.s1
                {
                    out.push(j as u32);
                }
            }
            *visible[q].lock().expect("no panics while holding the lock") = out;
        },
    );
    let mut rows: Vec<Vec<(u32, f64)>> = (0..n).map(|i| vec![(i as u32, 1.0)]).collect();
    for i in 0..n {
        let mut count: Vec<(u32, u32)> = Vec::new();
        for k in 0..SAMPLES {
            for &j in visible[i * SAMPLES + k]
                .lock()
                .expect("no panics while holding the lock")
                .iter()
            {
                match count.iter_mut().find(|c| c.0 == j) {
                    Some(c) => c.1 += 1,
                    None => count.push((j, 1)),
                }
            }
        }
        count.sort_unstable();
        let ci = centre(i);
        let ni = edges[patches.edge[i] as usize].normal.vec();
        for (j, c) in count {
            let cj = centre(j as usize);
            let nj = edges[patches.edge[j as usize] as usize].normal.vec();
            let d = [cj[0] - ci[0], cj[1] - ci[1]];
            let r = d[0].hypot(d[1]);
            let w = ((ni[0] as f64 * d[0] + ni[1] as f64 * d[1]) / r)
                * ((-(nj[0] as f64) * d[0] - nj[1] as f64 * d[1]) / r);
            if w <= 0.0 {
                continue;
            }
            let att = falloff.map_or(1.0, |f| f.weight(r));
            let f = att * w * c as f64 / SAMPLES as f64;
            rows[i].push((j, f));
            rows[j as usize].push((i as u32, f));
        }
    }
    for r in &mut rows {
        r.sort_by_key(|e| e.0);
    }
    rows
}

/// Pseudo-angle of `y` seen from `x` in the half view of normal `n`
/// (the same frame the sweep uses).
fn diamond_from(x: [f64; 2], y: [f64; 2], n: crate::geometry::Normal) -> f64 {
    let t = n.travel();
    let v = n.vec();
    let d = [y[0] - x[0], y[1] - x[1]];
    diamond(
        d[0] * t[0] as f64 + d[1] * t[1] as f64,
        d[0] * v[0] as f64 + d[1] * v[1] as f64,
    )
}

/// Solves `(I - rho F) B = E` with the guard described above; returns the
/// radiosity and how many rows were rescaled.
pub fn solve(
    rows: &[Vec<(u32, f64)>],
    rho: &[f64],
    e: &[f64],
    tolerance: f64,
) -> (Vec<f64>, usize) {
    let n = rows.len();
    let mut rescaled = 0;
    // Row scale so that sum_j rho_i F_ij stays at or below MAX_ROW.
    let scale: Vec<f64> = (0..n)
        .map(|i| {
            let sum: f64 = rows[i].iter().map(|x| x.1).sum();
            let rs = rho[i] * sum;
            if rs <= MAX_ROW {
                return rho[i];
            }
            if rs < 1.0 {
                // Within 0.1% of 1: capped at MAX_ROW (a change below 0.1%)
                // so that every row, not only those reaching 1, keeps the
                // iteration below contracting by at least MAX_ROW per sweep.
                return MAX_ROW / sum;
            }
            rescaled += 1;
            // Normalise F's row to 1, then cap rho F's row at MAX_ROW.
            rho[i].min(MAX_ROW) / sum
        })
        .collect();
    if n <= 2500 {
        let mut m = DMatrix::<f64>::identity(n, n);
        for i in 0..n {
            for &(j, f) in &rows[i] {
                m[(i, j as usize)] -= scale[i] * f;
            }
        }
        if let Some(x) = m.lu().solve(&DVector::from_column_slice(e)) {
            return (x.iter().map(|v| v.max(0.0)).collect(), rescaled);
        }
    }
    // Jacobi iteration: converges because |rho F|_inf <= MAX_ROW, so the
    // error shrinks by MAX_ROW per sweep, so the 1e-10 of the reference
    // preset takes about 25000 sweeps (before every row was capped, rows just
    // below 1 stopped at the sweep limit unconverged).
    let mut b = e.to_vec();
    for _ in 0..100_000 {
        let next: Vec<f64> = (0..n)
            .map(|i| e[i] + scale[i] * rows[i].iter().map(|&(j, f)| f * b[j as usize]).sum::<f64>())
            .collect();
        let diff = next
            .iter()
            .zip(&b)
            .map(|(a, c)| (a - c).abs())
            .fold(0.0, f64::max);
        let size = next.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        b = next;
        if diff <= tolerance * size.max(1e-300) {
            break;
        }
    }
    (b, rescaled)
}
