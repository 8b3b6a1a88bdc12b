//! The naive gather: the paper's method, kept as the yardstick for speed.

use std::f64::consts::TAU;

use crate::geometry::{Edge, Geometry};
use crate::transport::Patches;
use crate::transport::kernel::Falloff;

use super::*;

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
            let p = crate::visibility::centre(*px);
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
