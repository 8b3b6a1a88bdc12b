//! Block sweeps (`draft` and `normal`; transport.md, Block sweeps): a
//! pixel whose full visibility query would walk the level's blocks gets
//! one only if it is an anchor (both coordinates multiples of the spacing,
//! [`ANCHOR`] by default); another is swept over a list: the edges that the
//! anchors at the corners of its block and of the ring around it see, and
//! every edge near the block. At `normal` ([`Lists::gather_walking`]) the
//! pixels whose query would sweep their tile's short list are gathered so,
//! exactly; `draft`'s lattice sends every pixel it gathers
//! ([`Lists::gather`]), and its lists hold the block's corners only.
//!
//! A full query walks the level's blocks of edges from near to far until
//! nearer surfaces hide the rest; most of its time goes into proving blocks
//! hidden. A sweep over a list is exact for the edges on it: every light
//! and wall on the list is seen exactly as a full query sees it, shadows
//! included, and every edge within [`NEAR`] px of the block is on the list,
//! so no pixel sees through a wall beside it. A pixel whose block is not floor
//! of its region throughout (nor, near a wall, the block of half the
//! spacing around it) gets a full query. What the list can miss is a
//! distant edge that no anchor of the ring sees but a pixel between them
//! does (through a gap narrower than the anchors' spacing, or around a
//! corner): the pixel then sees what lies behind it on the list, or
//! nothing. That error is measured per class of level in
//! docs/performance.md.

use rayon::prelude::*;

use crate::geometry::Geometry;
use crate::visibility::{Span, Sweeper, View, Viewpoint, VisitStats, Wanted, centre};

use super::fast::{Exact, GatherCounts, PixelScratch, pixel_light, signature};
use super::{Disjoint, PerThread};

/// Spacing of the anchor pixels, in pixels, unless the preset sets it.
pub const ANCHOR: i32 = 4;

/// Copies pixel `j` of an exact pass (its light, and its moments and
/// signature if the pass has them) to pixel `i` of `out`, marked gathered.
fn store(pass: &super::fast::Pass, j: usize, i: usize, k: usize, out: &mut Out) {
    let km = if pass.moments.is_empty() { 0 } else { 2 * k };
    out.0[i * k..(i + 1) * k].copy_from_slice(&pass.values[j * k..(j + 1) * k]);
    out.1[i * km..(i + 1) * km].copy_from_slice(&pass.moments[j * km..(j + 1) * km]);
    if !pass.signature.is_empty() {
        out.2[i] = pass.signature[j];
    }
    out.3[i] = 1;
}

/// Pixels per exact pass of [`Lists::gather_walking`].
const CHUNK: usize = 1 << 18;

/// Edges that come within this many pixels of a block's pixels are on the
/// block's list whatever its anchors see.
pub const NEAR: i32 = 2;

/// Per-thread buffers of the passes below.
#[derive(Default)]
struct Buffers {
    sweeper: Sweeper,
    spans: Vec<Span>,
    lit: Vec<Span>,
    list: Vec<u32>,
    scratch: PixelScratch,
    /// Per edge, the generation of the list it was last put on (lists are
    /// merged without sorting).
    stamp: Vec<u32>,
    generation: u32,
}

thread_local! {
    static BUFFERS: std::cell::RefCell<Buffers> = std::cell::RefCell::new(Buffers::default());
}

/// The edges near each block of `ANCHOR` x `ANCHOR` pixels (those whose
/// bounding box comes within [`NEAR`] of the block's pixels and of the
/// anchors on its far sides), kept for the blocks a pass sweeps only (a
/// level of millions of one-pixel edges would hold them for every block).
struct Near {
    nx: usize,
    start: Vec<u32>,
    list: Vec<u32>,
}

impl Near {
    fn new(g: &Geometry, s: i32, groups: &[Group]) -> Near {
        let nx = (g.width as i32 / s + 1) as usize;
        let ny = (g.height as i32 / s + 1) as usize;
        let mut used = vec![false; nx * ny];
        for gr in groups {
            used[gr.block[1] as usize * nx + gr.block[0] as usize] = true;
        }
        // Block (bx, by) holds the pixels from s * bx to s * bx + s (the far
        // anchors included), so the area [s bx - NEAR, s bx + s + 1 + NEAR].
        let range = |lo: i32, hi: i32, n: usize| {
            let a = (lo - s - 1 - NEAR + s - 1).div_euclid(s).max(0);
            let b = (hi + NEAR).div_euclid(s).min(n as i32 - 1);
            a..=b
        };
        let mut count = vec![0u32; nx * ny + 1];
        let each = |f: &mut dyn FnMut(usize, u32)| {
            for (ei, e) in g.edges.iter().enumerate() {
                let (x0, x1) = (e.a[0].min(e.b[0]), e.a[0].max(e.b[0]));
                let (y0, y1) = (e.a[1].min(e.b[1]), e.a[1].max(e.b[1]));
                for by in range(y0, y1, ny) {
                    for bx in range(x0, x1, nx) {
                        let b = by as usize * nx + bx as usize;
                        if used[b] {
                            f(b, ei as u32);
                        }
                    }
                }
            }
        };
        each(&mut |b, _| count[b + 1] += 1);
        for i in 0..nx * ny {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut list = vec![0u32; count[nx * ny] as usize];
        each(&mut |b, ei| {
            list[fill[b] as usize] = ei;
            fill[b] += 1;
        });
        Near {
            nx,
            start: count,
            list,
        }
    }

    fn of(&self, bx: i32, by: i32) -> &[u32] {
        let b = by as usize * self.nx + bx as usize;
        &self.list[self.start[b] as usize..self.start[b + 1] as usize]
    }
}

/// The index of each of a list of floor pixels, by position.
pub(super) struct PixelIndex {
    at: Vec<u32>,
    width: i32,
    height: i32,
}

impl PixelIndex {
    pub fn new(g: &Geometry, pixels: &[[i32; 2]]) -> PixelIndex {
        let (width, height) = (g.width as i32, g.height as i32);
        let mut at = vec![u32::MAX; g.width * g.height];
        for (i, p) in pixels.iter().enumerate() {
            at[(p[1] * width + p[0]) as usize] = i as u32;
        }
        PixelIndex { at, width, height }
    }

    /// The index of the pixel at `(x, y)`, if it is one of the list.
    pub fn get(&self, x: i32, y: i32) -> Option<usize> {
        (x >= 0 && y >= 0 && x < self.width && y < self.height)
            .then(|| self.at[(y * self.width + x) as usize])
            .filter(|&i| i != u32::MAX)
            .map(|i| i as usize)
    }
}

/// What the anchors see, kept for the sweeps of the pixels between them.
pub(super) struct Lists {
    /// Per anchor gathered by a full query (by index into the pixels):
    /// every edge it sees, lit or not, sorted.
    seen: std::collections::HashMap<usize, Vec<u32>>,
    /// Spacing of the anchors, in pixels.
    spacing: i32,
    /// Also the anchors of the ring around a block ([`Lists::new`]).
    ring: bool,
}

/// A block's pixels to sweep, and the anchors whose lists they use.
struct Group {
    /// The block of `ANCHOR` px holding it (for the near edges), and the
    /// top left corner of its own block (of `ANCHOR` or half that).
    block: [i32; 2],
    origin: [i32; 2],
    anchors: Vec<usize>,
    pixels: Vec<usize>,
}

/// Where a pass writes: per pixel its values, its signature and its state
/// (set to 1, gathered, for every pixel a pass gathers).
pub(super) type Out<'a> = (&'a mut [f64], &'a mut [f64], &'a mut [u64], &'a mut [u8]);

impl Lists {
    /// Lists for anchors `spacing` px apart; with `ring`, a block's list
    /// also holds what the anchors of the ring around it see.
    pub fn new(spacing: i32, ring: bool) -> Lists {
        Lists {
            spacing,
            ring,
            seen: Default::default(),
        }
    }

    /// Gathers the pixels `want` (indices into `pixels`, found by position
    /// with `index`): anchors, and pixels with no block that is floor of
    /// their own free region throughout, by a full query; the others by a
    /// sweep over their block's list. The anchors a block needs are
    /// gathered too. With `signatures`, each pixel's signature as in
    /// [`Exact::run`].
    pub fn gather(
        &mut self,
        exact: &Exact,
        pixels: &[[i32; 2]],
        index: &dyn Fn(i32, i32) -> Option<usize>,
        want: &[usize],
        signatures: Option<f64>,
        mut out: Out,
    ) -> (VisitStats, GatherCounts) {
        let g = exact.geometry;
        let k = exact.components();
        let km = if exact.directional { 2 * k } else { 0 };
        let comp = |p: [i32; 2]| g.components[p[1] as usize * g.width + p[0] as usize];
        let mut stats = VisitStats::default();
        let mut counts = GatherCounts::default();
        let mut anchors: Vec<usize> = Vec::new();
        let mut full: Vec<usize> = Vec::new();
        let mut blocks: std::collections::HashMap<[i32; 3], usize> = Default::default();
        let mut groups: Vec<Group> = Vec::new();
        let mut pending = vec![false; pixels.len()];
        for &i in want {
            let [x, y] = pixels[i];
            let s = self.spacing;
            if x % s == 0 && y % s == 0 {
                if !self.seen.contains_key(&i) && !pending[i] {
                    pending[i] = true;
                    anchors.push(i);
                }
                continue;
            }
            let (bx, by) = (x.div_euclid(s), y.div_euclid(s));
            // The pixel's block, or near a wall the block of half the
            // spacing around it, if all of it is floor of the pixel's region.
            // A block with a corner in a wall or in another region is not
            // used: its anchors may not see around the wall's end
            // (measured: a pixel above the end of a thin wall then missed
            // what lay beyond it).
            let corners_of = |step: i32| -> Option<[usize; 4]> {
                let (x0, y0) = (x - x.rem_euclid(step), y - y.rem_euclid(step));
                // Every pixel of the block floor of the region, not only its
                // corners: a solid pixel inside it hides from the corners
                // what the pixels around it see (measured on wall noise).
                let open = (y0..=y0 + step).all(|by| {
                    (x0..=x0 + step)
                        .all(|bx| index(bx, by).is_some_and(|c| comp(pixels[c]) == comp([x, y])))
                });
                if !open {
                    return None;
                }
                let c = [
                    (x0, y0),
                    (x0 + step, y0),
                    (x0, y0 + step),
                    (x0 + step, y0 + step),
                ]
                .map(|(cx, cy)| index(cx, cy).filter(|&c| comp(pixels[c]) == comp([x, y])));
                Some([c[0]?, c[1]?, c[2]?, c[3]?])
            };
            let Some((step, corners)) = [s, s / 2]
                .into_iter()
                .filter(|&step| step >= 2)
                .find_map(|step| Some((step, corners_of(step)?)))
            else {
                full.push(i);
                continue;
            };
            let origin = [x - x.rem_euclid(step), y - y.rem_euclid(step)];
            let gi = *blocks
                .entry([origin[0], origin[1], step])
                .or_insert_with(|| {
                    groups.push(Group {
                        block: [bx, by],
                        origin,
                        anchors: Vec::new(),
                        pixels: Vec::new(),
                    });
                    groups.len() - 1
                });
            let gr = &mut groups[gi];
            for c in corners {
                if !gr.anchors.contains(&c) {
                    gr.anchors.push(c);
                }
                if !self.seen.contains_key(&c) && !pending[c] {
                    pending[c] = true;
                    anchors.push(c);
                }
            }
            gr.pixels.push(i);
        }
        // A pixel that is a corner of another block is gathered as an anchor.
        for gr in &mut groups {
            gr.pixels.retain(|&i| !pending[i]);
        }
        // The anchors of the ring around a block's corners (those gathered
        // as anchors anyway) add to its list what a pixel sees through a gap
        // that none of the corners sees through: measured, wall noise at
        // 10 % came from 1.13 % to 0.32 % against `reference` (0.26 % with a
        // full query at every pixel). (`draft` goes without: 10 % more
        // time on its real maps.)
        for gr in groups.iter_mut().filter(|_| self.ring) {
            let Some(&p0) = gr.pixels.first() else {
                continue;
            };
            let c0 = comp(pixels[p0]);
            let s = self.spacing;
            let [bx, by] = [gr.block[0] * s, gr.block[1] * s];
            for dy in [-s, 0, s, 2 * s] {
                for dx in [-s, 0, s, 2 * s] {
                    if let Some(c) = index(bx + dx, by + dy)
                        && comp(pixels[c]) == c0
                        && (pending[c] || self.seen.contains_key(&c))
                        && !gr.anchors.contains(&c)
                    {
                        gr.anchors.push(c);
                    }
                }
            }
        }
        // Anchors: a full query, keeping what each sees.
        let pts: Vec<[i32; 2]> = anchors.iter().map(|&i| pixels[i]).collect();
        let (pass, seen, dropped) = run_recording(exact, &pts, signatures);
        for ((j, &i), list) in anchors.iter().enumerate().zip(seen) {
            store(&pass, j, i, k, &mut out);
            self.seen.insert(i, list);
        }
        // (Progress: the wanted pixels that neither the full queries nor
        // the sweeps below count.)
        let swept: usize = groups.iter().map(|gr| gr.pixels.len()).sum();
        exact.done(want.len().saturating_sub(full.len() + swept));
        stats.culled_pairs += dropped;
        counts += pass.counts;
        // Pixels with no anchor: a full query each.
        let pts: Vec<[i32; 2]> = full.iter().map(|&i| pixels[i]).collect();
        let pass = exact.run(&pts, signatures);
        for (j, &i) in full.iter().enumerate() {
            store(&pass, j, i, k, &mut out);
        }
        stats += pass.stats;
        counts += pass.counts;
        // The rest: a sweep over their block's list. Blocks of one 8 px tile
        // one after the other, as the patch cuts are per tile.
        groups.sort_by_key(|gr| {
            let [x0, y0] = gr.origin;
            (y0 / 8, x0 / 8, y0, x0)
        });
        let near = (!groups.is_empty()).then(|| Near::new(g, self.spacing, &groups));
        let (sv, smo, ss, sm) = self.sweep(exact, pixels, &groups, near.as_ref(), signatures);
        drop(near);
        for (j, i) in groups.iter().flat_map(|gr| gr.pixels.iter()).enumerate() {
            out.0[i * k..(i + 1) * k].copy_from_slice(&sv[j * k..(j + 1) * k]);
            out.1[i * km..(i + 1) * km].copy_from_slice(&smo[j * km..(j + 1) * km]);
            if signatures.is_some() {
                out.2[*i] = ss[j];
            }
            out.3[*i] = 1;
        }
        stats.culled_pairs += sm.1;
        counts += sm.0;
        (stats, counts)
    }

    /// Gathers the pixels `want` as `normal` does: a full query each,
    /// except the pixels whose query would walk the level's blocks, which
    /// the exact pass hands back to [`Lists::gather`].
    pub fn gather_walking(
        &mut self,
        exact: &Exact,
        pixels: &[[i32; 2]],
        index: &dyn Fn(i32, i32) -> Option<usize>,
        want: &[usize],
        signatures: Option<f64>,
        mut out: Out,
    ) -> (VisitStats, GatherCounts) {
        let k = exact.components();
        let (mut stats, mut counts) = (VisitStats::default(), GatherCounts::default());
        let mut rest = Vec::new();
        // In chunks of pixels (in the order asked for, rows of tiles): the
        // exact pass's own arrays stay small beside the caller's.
        for want in want.chunks(CHUNK) {
            let pts: Vec<[i32; 2]> = want.iter().map(|&i| pixels[i]).collect();
            let (pass, walks) = exact_or_walks(exact, &pts, signatures);
            drop(pts);
            let mut handed_back = vec![false; want.len()];
            for &j in &walks {
                handed_back[j] = true;
                rest.push(want[j]);
            }
            for (j, &i) in want.iter().enumerate().filter(|&(j, _)| !handed_back[j]) {
                store(&pass, j, i, k, &mut out);
            }
            stats += pass.stats;
            counts += pass.counts;
        }
        if !rest.is_empty() {
            rest.sort_unstable();
            let (s, c) = self.gather(exact, pixels, index, &rest, signatures, out);
            stats += s;
            counts += c;
        }
        (stats, counts)
    }

    /// The sweeps of the groups' pixels: values, moments (with
    /// [`Exact::directional`]) and signatures in the order of the groups and
    /// their pixels, and what they merged and left out.
    fn sweep(
        &self,
        exact: &Exact,
        pixels: &[[i32; 2]],
        groups: &[Group],
        near: Option<&Near>,
        signatures: Option<f64>,
    ) -> (Vec<f64>, Vec<f64>, Vec<u64>, (GatherCounts, u64)) {
        let (light, g) = (exact.light, exact.geometry);
        let k = light.rad.components;
        let km = if exact.directional { 2 * k } else { 0 };
        let mut start = Vec::with_capacity(groups.len() + 1);
        start.push(0usize);
        for gr in groups {
            start.push(start.last().copied().unwrap_or(0) + gr.pixels.len());
        }
        let total = start[groups.len()];
        let mut out = vec![0.0; total * k];
        let mut moments = vec![0.0; total * km];
        let mut sigs = vec![0u64; if signatures.is_some() { total } else { 0 }];
        let mut merged = vec![[0u64; 3]; groups.len()];
        {
            let shared = Disjoint::new(&mut out);
            let shared_moments = Disjoint::new(&mut moments);
            let shared_sig = Disjoint::new(&mut sigs);
            let shared_merged = Disjoint::new(&mut merged);
            groups.par_iter().enumerate().for_each(|(gi, gr)| {
                BUFFERS.with(|b| {
                    let b = &mut *b.borrow_mut();
                    b.list.clear();
                    if b.stamp.len() != g.edges.len() {
                        b.stamp = vec![0; g.edges.len()];
                        b.generation = 0;
                    }
                    b.generation = b.generation.wrapping_add(1);
                    if b.generation == 0 {
                        b.stamp.iter_mut().for_each(|s| *s = 0);
                        b.generation = 1;
                    }
                    let near = near.map(|n| n.of(gr.block[0], gr.block[1]));
                    for part in gr
                        .anchors
                        .iter()
                        .filter_map(|a| self.seen.get(a).map(|l| &l[..]))
                        .chain(near)
                    {
                        for &e in part {
                            if b.stamp[e as usize] != b.generation {
                                b.stamp[e as usize] = b.generation;
                                b.list.push(e);
                            }
                        }
                    }
                    // In edge order, a pillar's edges are neighbours, and
                    // so are its pieces in a sweep (where two that meet at
                    // its corner are taken as one silhouette).
                    b.list.sort_unstable();
                    let mut tally = [0u64; 3];
                    let mut acc = vec![0.0; k];
                    let mut m = vec![0.0; km];
                    for (j, &i) in gr.pixels.iter().enumerate() {
                        let px = pixels[i];
                        let p = centre(px);
                        let comp = g.components[px[1] as usize * g.width + px[0] as usize];
                        b.spans.clear();
                        tally[2] += b.sweeper.sweep_wanted(
                            &g.edges,
                            &b.list,
                            Viewpoint::new(p, View::Full, comp),
                            Some(Wanted {
                                reach2: exact.reaches.squared,
                                class: None,
                                cosine: None,
                            }),
                            &mut b.spans,
                        );
                        acc.iter_mut().for_each(|a| *a = 0.0);
                        let c = pixel_light(light, p, &b.spans, &mut acc, &mut b.scratch);
                        tally[0] += c.pieces;
                        tally[1] += c.patch_pieces;
                        let o = start[gi] + j;
                        for (c, &v) in acc.iter().enumerate() {
                            // SAFETY: each output index belongs to one group's pixel.
                            unsafe { shared.write(o * k + c, v) };
                        }
                        if km > 0 {
                            m.iter_mut().for_each(|v| *v = 0.0);
                            super::directional::pixel_moments(
                                light, p, &b.spans, &b.scratch, &mut m,
                            );
                            for (c, &v) in m.iter().enumerate() {
                                // SAFETY: as above.
                                unsafe { shared_moments.write(o * km + c, v) };
                            }
                        }
                        if let Some(rel) = signatures {
                            let h = signature(light, &b.spans, &b.scratch, &acc, rel);
                            // SAFETY: as above.
                            unsafe { shared_sig.write(o, h) };
                        }
                    }
                    // SAFETY: one write per group.
                    unsafe { shared_merged.write(gi, tally) };
                });
                exact.done(gr.pixels.len());
            });
        }
        let mut counts = GatherCounts::default();
        let mut dropped = 0;
        for c in &merged {
            counts.pieces += c[0];
            counts.patch_pieces += c[1];
            dropped += c[2];
        }
        counts.local = total as u64;
        (out, moments, sigs, (counts, dropped))
    }
}

/// The spans of `spans` that [`Wanted`] with `reach2` would have returned
/// from `p` (edges with light, within their reach), in `out`; the number
/// of spans of edges with light left out.
fn within_reach(exact: &Exact, p: [f64; 2], spans: &[Span], out: &mut Vec<Span>) -> u64 {
    let edges = &exact.geometry.edges;
    let mut dropped = 0;
    out.clear();
    for s in spans {
        let r2 = exact.reaches.squared[s.edge as usize];
        if r2 >= 0.0 && edges[s.edge as usize].distance_sq(p) <= r2 {
            out.push(*s);
        } else if r2 >= 0.0 {
            dropped += 1;
        }
    }
    dropped
}

/// What [`Exact::run`] returns for `pixels`, with, per pixel, every edge it
/// sees (lit or not, sorted), and the number of spans out of reach. The
/// light is `Exact::run`'s: the query returns every visible span and those
/// out of reach are left out here instead of in the query.
fn run_recording(
    exact: &Exact,
    pixels: &[[i32; 2]],
    signatures: Option<f64>,
) -> (super::fast::Pass, Vec<Vec<u32>>, u64) {
    let (light, rad) = (exact.light, exact.light.rad);
    let k = rad.components;
    let km = if exact.directional { 2 * k } else { 0 };
    let mut out = vec![0.0; pixels.len() * k];
    let mut moments = vec![0.0; pixels.len() * km];
    let mut sigs = vec![
        0u64;
        if signatures.is_some() {
            pixels.len()
        } else {
            0
        }
    ];
    let mut seen: Vec<Vec<u32>> = vec![Vec::new(); pixels.len()];
    // Pieces, patch pieces and pairs beyond reach, summed per thread.
    let merged = PerThread::<3>::new();
    {
        let (shared, shared_sig) = (Disjoint::new(&mut out), Disjoint::new(&mut sigs));
        let shared_moments = Disjoint::new(&mut moments);
        let shared_seen = Disjoint::new(&mut seen);
        crate::visibility::for_each_visibility_counted(
            exact.structures,
            None,
            pixels,
            &|_| View::Full,
            exact.reach_max,
            None,
            &|_| {},
            None,
            &|i, spans| {
                let at = centre(pixels[i]);
                let mut edges: Vec<u32> = spans.iter().map(|s| s.edge).collect();
                edges.sort_unstable();
                edges.dedup();
                edges.shrink_to_fit();
                let mut acc = vec![0.0; k];
                let mut m = vec![0.0; km];
                let (c, sig, dropped) = BUFFERS.with(|b| {
                    let b = &mut *b.borrow_mut();
                    let dropped = within_reach(exact, at, spans, &mut b.lit);
                    let c = pixel_light(light, at, &b.lit, &mut acc, &mut b.scratch);
                    if km > 0 {
                        super::directional::pixel_moments(light, at, &b.lit, &b.scratch, &mut m);
                    }
                    let sig = signatures.map(|rel| signature(light, &b.lit, &b.scratch, &acc, rel));
                    (c, sig, dropped)
                });
                merged.add([c.pieces, c.patch_pieces, dropped]);
                // SAFETY: each pixel index is visited exactly once.
                unsafe {
                    shared_seen.write(i, edges);
                    for (c, &v) in acc.iter().enumerate() {
                        shared.write(i * k + c, v);
                    }
                    for (c, &v) in m.iter().enumerate() {
                        shared_moments.write(i * km + c, v);
                    }
                    if let Some(h) = sig {
                        shared_sig.write(i, h);
                    }
                }
            },
        );
    }
    let [pieces, patch_pieces, dropped] = merged.sum();
    let counts = GatherCounts {
        pieces,
        patch_pieces,
        ..GatherCounts::default()
    };
    let pass = super::fast::Pass {
        values: out,
        moments,
        signature: sigs,
        stats: VisitStats::default(),
        counts,
    };
    (pass, seen, dropped)
}

/// Gathers every one of `pixels` as [`Lists::gather_walking`] does, with
/// anchors `spacing` px apart (and no copy of the exact pass's values).
pub(super) fn gather_all(exact: &Exact, pixels: &[[i32; 2]], spacing: i32) -> super::fast::Gather {
    let (pass, mut walks) = exact_or_walks(exact, pixels, None);
    let (mut values, mut moments) = (pass.values, pass.moments);
    let (mut stats, mut counts) = (pass.stats, pass.counts);
    if !walks.is_empty() {
        walks.sort_unstable();
        let at = PixelIndex::new(exact.geometry, pixels);
        let index = |x: i32, y: i32| at.get(x, y);
        let mut state = vec![0u8; pixels.len()];
        let (s, c) = Lists::new(spacing, true).gather(
            exact,
            pixels,
            &index,
            &walks,
            None,
            (&mut values, &mut moments, &mut [], &mut state),
        );
        stats += s;
        counts += c;
    }
    super::fast::Gather {
        values,
        moments,
        stats,
        counts,
    }
}

/// The exact pass over `pixels`, and the indices of those it handed back
/// because their query would walk the level's blocks (their values left 0).
fn exact_or_walks(
    exact: &Exact,
    pixels: &[[i32; 2]],
    signatures: Option<f64>,
) -> (super::fast::Pass, Vec<usize>) {
    let walks = std::sync::Mutex::new(Vec::new());
    let pass = exact.run_deferring(
        pixels,
        signatures,
        Some(&|i| walks.lock().unwrap_or_else(|e| e.into_inner()).push(i)),
    );
    (pass, walks.into_inner().unwrap_or_else(|e| e.into_inner()))
}
