//! Cell-local visibility for the interpolated gather (`draft`): the pixels
//! of a lattice cell that failed its smoothness test are gathered with an
//! angular sweep over the edges that the cell's probes see, instead of a
//! full visibility query each (docs/performance.md, sixth pass).
//!
//! A full query walks the level's blocks of edges from near to far until
//! nearer surfaces hide the rest; most of its time goes into proving blocks
//! hidden. The probes of a 4 px cell (its corners, centre and side middles,
//! gathered exactly anyway) lie within 2.9 px of every pixel of the cell,
//! and what those nine points see is, but for edges glimpsed only through
//! a gap narrower than the probes' spacing, what the pixels between them
//! see. A sweep over that short list is exact for the edges on it: the
//! direct light of every light the probes see is exact, shadows included.
//! What it can miss is an edge that none of the nine probes sees (the
//! pixel then sees what lies behind it on the list, or nothing): the error
//! is measured per class of level in docs/performance.md.

use rayon::prelude::*;

use crate::visibility::{Span, Sweeper, View, Viewpoint, VisitStats, Wanted};

use super::Disjoint;
use super::fast::{Exact, GatherCounts, Pass, PixelScratch, pixel_light, signature};

/// Per-thread buffers of the passes below.
#[derive(Default)]
struct Buffers {
    sweeper: Sweeper,
    spans: Vec<Span>,
    lit: Vec<Span>,
    list: Vec<u32>,
    scratch: PixelScratch,
}

thread_local! {
    static BUFFERS: std::cell::RefCell<Buffers> = std::cell::RefCell::new(Buffers::default());
}

/// The spans of `spans` that [`Wanted`] with `reach2` would have returned
/// from `p` (edges with light, within their reach), appended to `out`; the
/// number of spans of edges with light left out.
fn within_reach(exact: &Exact, p: [f64; 2], spans: &[Span], out: &mut Vec<Span>) -> u64 {
    let edges = &exact.geometry.edges;
    let mut dropped = 0;
    out.clear();
    for s in spans {
        let r2 = exact.reach2[s.edge as usize];
        if r2 >= 0.0 && edges[s.edge as usize].distance_sq(p) <= r2 {
            out.push(*s);
        } else if r2 >= 0.0 {
            dropped += 1;
        }
    }
    dropped
}

/// [`Exact::run`] that also returns, per pixel, every edge it sees (lit or
/// not, sorted): the lists the cells' sweeps are made of. The light is the
/// same as `Exact::run`'s: the query returns every visible span and the
/// spans out of reach are left out here instead of in the query.
pub(super) fn run_recording(
    exact: &Exact,
    pixels: &[[i32; 2]],
    signatures: Option<f64>,
) -> (Pass, Vec<Vec<u32>>) {
    let (light, rad) = (exact.light, exact.light.rad);
    let k = rad.components;
    let mut out = vec![0.0; pixels.len() * k];
    let mut sigs = vec![0u64; if signatures.is_some() { pixels.len() } else { 0 }];
    let mut seen: Vec<Vec<u32>> = vec![Vec::new(); pixels.len()];
    let mut merged = vec![[0u32; 3]; pixels.len()];
    let pos: Vec<[f64; 2]> = pixels
        .iter()
        .map(|p| [p[0] as f64 + 0.5, p[1] as f64 + 0.5])
        .collect();
    {
        let (shared, shared_sig) = (Disjoint::new(&mut out), Disjoint::new(&mut sigs));
        let (shared_seen, shared_merged) = (Disjoint::new(&mut seen), Disjoint::new(&mut merged));
        crate::visibility::for_each_visibility_counted(
            exact.geometry,
            &pos,
            pixels,
            &|_| View::Full,
            exact.reach_max,
            None,
            &|n| exact.done(n),
            &|i, spans| {
                let mut edges: Vec<u32> = spans.iter().map(|s| s.edge).collect();
                edges.sort_unstable();
                edges.dedup();
                let mut acc = vec![0.0; k];
                let (c, sig, dropped) = BUFFERS.with(|b| {
                    let b = &mut *b.borrow_mut();
                    let dropped = within_reach(exact, pos[i], spans, &mut b.lit);
                    let c = pixel_light(light, pos[i], &b.lit, &mut acc, &mut b.scratch);
                    let sig = signatures.map(|rel| signature(light, &b.lit, &b.scratch, &acc, rel));
                    (c, sig, dropped)
                });
                let c = [c.pieces, c.patch_pieces, dropped].map(|v| v.min(u32::MAX as u64) as u32);
                // SAFETY: each pixel index is visited exactly once.
                unsafe {
                    shared_merged.write(i, c);
                    shared_seen.write(i, edges);
                    for (c, &v) in acc.iter().enumerate() {
                        shared.write(i * k + c, v);
                    }
                    if let Some(h) = sig {
                        shared_sig.write(i, h);
                    }
                }
            },
        );
    }
    let mut stats = VisitStats::default();
    let mut counts = GatherCounts::default();
    for c in &merged {
        counts.pieces += c[0] as u64;
        counts.patch_pieces += c[1] as u64;
        stats.culled_pairs += c[2] as u64;
    }
    let pass = Pass {
        values: out,
        signature: sigs,
        stats,
        counts,
    };
    (pass, seen)
}

/// A group of pixels gathered over one candidate list: the indices (into
/// `seen`) of the probes whose visible edges make the list, and the pixels.
pub(super) struct Group {
    pub probes: Vec<usize>,
    pub pixels: Vec<[i32; 2]>,
}

/// Gathers every group's pixels with a sweep over the union of what its
/// probes see (`seen`, per probe, from [`run_recording`]). Values are
/// returned in the order of the groups and their pixels.
pub(super) fn run_local(exact: &Exact, groups: &[Group], seen: &[Vec<u32>]) -> Pass {
    let (light, g) = (exact.light, exact.geometry);
    let k = light.rad.components;
    let mut start = Vec::with_capacity(groups.len() + 1);
    start.push(0usize);
    for gr in groups {
        start.push(start.last().copied().unwrap_or(0) + gr.pixels.len());
    }
    let total = start[groups.len()];
    let mut out = vec![0.0; total * k];
    let mut merged = vec![[0u64; 3]; groups.len()];
    {
        let shared = Disjoint::new(&mut out);
        let shared_merged = Disjoint::new(&mut merged);
        groups.par_iter().enumerate().for_each(|(gi, gr)| {
            BUFFERS.with(|b| {
                let b = &mut *b.borrow_mut();
                b.list.clear();
                for &pr in &gr.probes {
                    b.list.extend_from_slice(&seen[pr]);
                }
                b.list.sort_unstable();
                b.list.dedup();
                let mut tally = [0u64; 3];
                let mut acc = vec![0.0; k];
                for (j, px) in gr.pixels.iter().enumerate() {
                    let p = [px[0] as f64 + 0.5, px[1] as f64 + 0.5];
                    let comp = g.components[px[1] as usize * g.width + px[0] as usize];
                    b.spans.clear();
                    tally[2] += b.sweeper.sweep_wanted(
                        &g.edges,
                        &b.list,
                        Viewpoint::new(p, View::Full, comp),
                        Some(Wanted {
                            reach2: exact.reach2,
                            class: None,
                        }),
                        &mut b.spans,
                    );
                    acc.iter_mut().for_each(|a| *a = 0.0);
                    let c = pixel_light(light, p, &b.spans, &mut acc, &mut b.scratch);
                    tally[0] += c.pieces;
                    tally[1] += c.patch_pieces;
                    for (c, &v) in acc.iter().enumerate() {
                        // SAFETY: each output index belongs to one group's pixel.
                        unsafe { shared.write((start[gi] + j) * k + c, v) };
                    }
                }
                // SAFETY: one write per group.
                unsafe { shared_merged.write(gi, tally) };
            });
            exact.done(gr.pixels.len());
        });
    }
    let mut stats = VisitStats::default();
    let mut counts = GatherCounts::default();
    for c in &merged {
        counts.pieces += c[0];
        counts.patch_pieces += c[1];
        stats.culled_pairs += c[2];
    }
    counts.local = total as u64;
    Pass {
        values: out,
        signature: Vec::new(),
        stats,
        counts,
    }
}
