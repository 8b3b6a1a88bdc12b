//! The first circular moments of a pixel's light (docs/transport.md#directional-lightmaps):
//! `(1/2 pi) integral of L(theta) w cos(theta) d theta` and the same with
//! `sin`, over exactly the spans [`pixel_light`](super::pixel_light)
//! integrated, with the same radiosity on them (uniform emission per edge,
//! the patch tree's quadratic pieces of reflected light), in closed form
//! ([`crate::transport::moments`]).
//!
//! It reads what `pixel_light` left in the scratch for the pixel (the
//! emitting spans' ends, the reflected pieces and their end points), so it
//! runs right after it and only when moments are asked for: a plain gather
//! does not touch this file.

use std::f64::consts::TAU;

use crate::transport::moments::{MomentLine, MomentsAt, to_level};
use crate::visibility::Span;

use super::Kernel;
use super::fast::{Lighting, PixelScratch};

/// Adds the moments of pixel centre `p`'s light to `out`: `out[c]` the
/// cosine and `out[k + c]` the sine moment of component `c` (`k`
/// components), angles counter-clockwise from `+x` with `+y` up. `spans` and
/// `sc` must be what [`pixel_light`](super::pixel_light) was just called with.
pub(super) fn pixel_moments(
    light: &Lighting,
    p: [f64; 2],
    spans: &[Span],
    sc: &PixelScratch,
    out: &mut [f64],
) {
    let Lighting {
        edges,
        rad,
        tree,
        falloff,
        kernel,
        ..
    } = *light;
    if kernel != Kernel::Flatland {
        return;
    }
    let k = rad.components;
    // Uniform emission: one difference per emitting span.
    for (j, &ei) in sc.em_edge.iter().enumerate() {
        let e = &edges[ei as usize];
        let line = MomentLine::new(e.front_distance(p), falloff);
        let (a, b) = (line.at(sc.em.t[j]), line.at(sc.em_end[j]));
        let (cx, sy) = to_level(e.normal, (b.n0 - a.n0) / TAU, (b.t0 - a.t0) / TAU);
        for c in 0..k {
            let em = rad.edge_emission[ei as usize * k + c];
            out[c] += em * cx;
            out[k + c] += em * sy;
        }
    }
    // Reflected light: the pieces in order; a piece that does not start at
    // the end point of the one before starts the next reflecting span.
    let mut reflecting = spans.iter().filter(|s| {
        let ei = s.edge as usize;
        rad.edge_reflects[ei]
    });
    let tk = tree.k;
    let mut prev_end = u32::MAX;
    let mut line = MomentLine::new(1.0, None);
    let mut normal = crate::geometry::Normal::Up;
    let mut at_prev = MomentsAt::default();
    for pc in sc.pieces_at() {
        let (nd, end, off) = pc;
        if end.wrapping_sub(1) != prev_end {
            let Some(span) = reflecting.next() else {
                debug_assert!(false, "a piece for every reflecting span");
                return;
            };
            let e = &edges[span.edge as usize];
            line = MomentLine::new(e.front_distance(p), falloff);
            normal = e.normal;
            at_prev = line.at(sc.pts.t[end as usize - 1]);
        }
        let at_end = line.at(sc.pts.t[end as usize]);
        let d = line.d();
        // The moments of 1, t and t^2 over the piece (N_1 = d T_0, N_2 = d T_1).
        let dt0 = at_end.t0 - at_prev.t0;
        let dt1 = at_end.t1 - at_prev.t1;
        let n = [at_end.n0 - at_prev.n0, d * dt0, d * dt1];
        let t = [dt0, dt1, at_end.t2 - at_prev.t2];
        for c in 0..tk {
            let j = nd as usize * tk + c;
            let (c0, c1, c2) = (tree.c0[j], tree.c1[j], tree.c2[j]);
            // As in `pixel_light`: B = a0 + a1 t + c2 t^2 in t = s - foot.
            let a1 = c1 + 2.0 * c2 * off;
            let a0 = c0 + (c1 + c2 * off) * off;
            let along_n = (a0 * n[0] + a1 * n[1] + c2 * n[2]) / TAU;
            let along_axis = (a0 * t[0] + a1 * t[1] + c2 * t[2]) / TAU;
            let (cx, sy) = to_level(normal, along_n, along_axis);
            out[c] += cx;
            out[k + c] += sy;
        }
        at_prev = at_end;
        prev_end = end;
    }
}
