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
//! spacing around it, which on a dense level ([`DENSE`]) is tried only if
//! the near walk is not possible) gets a full query (with [`Exact::far`],
//! a near walk where its block's corners are floor of its region, or on
//! a dense level three of them where the fourth is a pillar of one
//! pixel). What the list can miss is a
//! distant edge that no anchor of the ring sees but a pixel between them
//! does (through a gap narrower than the anchors' spacing, or around a
//! corner): the pixel then sees what lies behind it on the list, or
//! nothing. That error is measured per class of level in
//! docs/performance.md. On a dense level with [`Exact::far`], an anchor
//! off the lattice four times as coarse walks everywhere only within
//! [`super::fast::OUTER`], and past it towards the lights; the light
//! reflected to it from farther is its coarse block's corners'
//! ([`Lists::gather`]; transport.md, Far reflected light). On a level of
//! many lights that is not dense, a swept pixel whose block's list holds
//! more than [`FAR_LAMPS`] of them sweeps only the edges within
//! [`super::LAMP_FAR`] and takes all the light from beyond, the lights'
//! too, from its block's corners, where that is at most [`LAMP_SHARE`]
//! of each corner's light (transport.md, Far light of many lights).

use rayon::prelude::*;

use crate::geometry::{Edge, Geometry};
use crate::visibility::{Reaches, Span, Sweeper, View, Viewpoint, VisitStats, Wanted, centre};

use super::fast::{
    Exact, GatherCounts, Part, PixelScratch, pixel_light, pixel_light_part, signature,
};
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
    /// The part of `list` that a sweep with [`Exact::far`] keeps
    /// ([`far_list`]), and the lights on the list, by loop.
    kept: Vec<u32>,
    lamps: Vec<(u32, Rect)>,
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
    /// With [`Exact::far`], per anchor of `seen`: the light reflected to it
    /// from beyond that distance, per component, then the angle open
    /// beyond that distance (not covered by what it sees nearer).
    far: std::collections::HashMap<usize, Vec<f64>>,
    /// With [`Exact::outer`], per anchor of the coarse lattice that a
    /// finer anchor took its light from beyond [`Exact::outer`]'s
    /// distance: that light, per component, then the angle open beyond
    /// that distance.
    outer: std::collections::HashMap<usize, Vec<f64>>,
    /// With [`Exact::lamp_far`], per anchor of `seen` gathered by a full
    /// walk: all the light from beyond that distance, the lights' too, per
    /// component, then the angle open beyond that distance.
    lamp_far: std::collections::HashMap<usize, Vec<f64>>,
    /// Spacing of the anchors, in pixels.
    spacing: i32,
    /// Also the anchors of the ring around a block ([`Lists::new`]).
    ring: bool,
}

/// Where a pixel's far reflected light comes from ([`Exact::far`]): the
/// corners of a block, in the order of [`Group::anchors`], and that
/// block's top left corner and side; with `missing`, the corner (0 to 3)
/// that is a pillar of one pixel, whose slot holds the opposite corner
/// and which the light of the other three stands for.
#[derive(Clone, Copy)]
struct FarFrom {
    corners: [usize; 4],
    origin: [i32; 2],
    step: i32,
    missing: Option<usize>,
}

impl FarFrom {
    /// Its corners' far reflected light ([`Lists::far`]), if every one's
    /// is known.
    fn values<'l>(&self, lists: &'l Lists) -> Option<[&'l Vec<f64>; 4]> {
        self.values_in(&lists.far)
    }

    /// Its corners' values in `map` ([`Lists::far`] or [`Lists::outer`]),
    /// if every one's is known.
    fn values_in<'l>(
        &self,
        map: &'l std::collections::HashMap<usize, Vec<f64>>,
    ) -> Option<[&'l Vec<f64>; 4]> {
        let f = self.corners.map(|c| map.get(&c));
        Some([f[0]?, f[1]?, f[2]?, f[3]?])
    }

    /// Adds to `acc` the far reflected light of the pixel at `p`, whose
    /// open angle beyond the distance is `open`, from its corners' `f`
    /// ([`FarFrom::values`], [`add_far`]): interpolated bilinearly, or
    /// with a corner missing on the plane through the other three.
    fn add(&self, f: &[&Vec<f64>; 4], p: [i32; 2], open: f64, acc: &mut [f64]) {
        let fx = (p[0] - self.origin[0]) as f64 / self.step as f64;
        let fy = (p[1] - self.origin[1]) as f64 / self.step as f64;
        let w = match self.missing {
            None => [
                (1.0 - fx) * (1.0 - fy),
                fx * (1.0 - fy),
                (1.0 - fx) * fy,
                fx * fy,
            ],
            Some(0) => [0.0, 1.0 - fy, 1.0 - fx, fx + fy - 1.0],
            Some(1) => [1.0 - fy, 0.0, fy - fx, fx],
            Some(2) => [1.0 - fx, fx - fy, 0.0, fy],
            Some(_) => [1.0 - fx - fy, fx, fy, 0.0],
        };
        add_far(acc, f, w, open);
    }
}

/// A block's pixels to sweep, and the anchors whose lists they use.
struct Group {
    /// The block of `ANCHOR` px holding it (for the near edges), and the
    /// top left corner of its own block (of `ANCHOR` or half that).
    block: [i32; 2],
    origin: [i32; 2],
    /// Its own block's side; its first four anchors are that block's
    /// corners, in the order (x0, y0), (x1, y0), (x0, y1), (x1, y1).
    step: i32,
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
            far: Default::default(),
            outer: Default::default(),
            lamp_far: Default::default(),
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
        // Pixels of `full` that walk near ([`Exact::run_near`]), with the
        // corners of their 4 px block.
        let mut near: Vec<(usize, FarFrom)> = Vec::new();
        let mut blocks: std::collections::HashMap<[i32; 3], usize> = Default::default();
        let mut groups: Vec<Group> = Vec::new();
        let mut pending = vec![false; pixels.len()];
        let s = self.spacing;
        // The far split: a pixel with no block of floor around it walks for
        // its near light and the lights only, and takes its far reflected
        // light from its block's corners if they are floor of its region.
        let split = exact.far.is_some() && exact.near_reaches.is_some() && km == 0;
        // The pixel at `(x, y)`, if it is floor of region `c0`.
        let floor_of = |x: i32, y: i32, c0| index(x, y).filter(|&c| comp(pixels[c]) == c0);
        // Offsets of the corners of a block of side `step`, in
        // [`Group::anchors`]' order.
        let corner_offsets = |step: i32| [(0, 0), (step, 0), (0, step), (step, step)];
        // The corners of the block of side `step` at `(x0, y0)`, if they are
        // all floor of region `c0`.
        let corners_at = |x0: i32, y0: i32, step: i32, c0| -> Option<[usize; 4]> {
            let c = corner_offsets(step).map(|(dx, dy)| floor_of(x0 + dx, y0 + dy, c0));
            Some([c[0]?, c[1]?, c[2]?, c[3]?])
        };
        let dense = is_dense(g, pixels.len());
        // The block's corners, or on a dense level three of them where the
        // fourth is a pillar of one pixel (its eight neighbours floor of
        // the region: a longer wall there would part the far light of the
        // corners on its two sides), the pillar's slot holding the
        // opposite corner. As [`FarFrom`]'s corners and missing corner.
        let far_corners = |x0: i32, y0: i32, c0| -> Option<([usize; 4], Option<usize>)> {
            let at = corner_offsets(s);
            let c = at.map(|(dx, dy)| floor_of(x0 + dx, y0 + dy, c0));
            if let [Some(a), Some(b), Some(c), Some(d)] = c {
                return Some(([a, b, c, d], None));
            }
            let missing = c.iter().position(Option::is_none)?;
            let opposite = c[3 - missing]?;
            let (mx, my) = (x0 + at[missing].0, y0 + at[missing].1);
            let pillar = index(mx, my).is_none()
                && (-1..=1).all(|dy| {
                    (-1..=1)
                        .all(|dx| (dx, dy) == (0, 0) || floor_of(mx + dx, my + dy, c0).is_some())
                });
            (dense && pillar && c.iter().filter(|c| c.is_none()).count() == 1)
                .then(|| (c.map(|c| c.unwrap_or(opposite)), Some(missing)))
        };
        for &i in want {
            let [x, y] = pixels[i];
            if x % s == 0 && y % s == 0 {
                if !self.seen.contains_key(&i) && !pending[i] {
                    pending[i] = true;
                    anchors.push(i);
                }
                continue;
            }
            let (bx, by) = (x.div_euclid(s), y.div_euclid(s));
            // The corners of the pixel's block, with the far split, if they
            // are floor of its region: then a pixel with no block of floor
            // around it walks near, on a dense level before a block of half
            // the spacing is tried ([`DENSE`]).
            let near_corners = split
                .then(|| far_corners(bx * s, by * s, comp([x, y])))
                .flatten();
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
                let c0 = comp([x, y]);
                let open = (y0..=y0 + step)
                    .all(|by| (x0..=x0 + step).all(|bx| floor_of(bx, by, c0).is_some()));
                if !open {
                    return None;
                }
                corners_at(x0, y0, step, c0)
            };
            let Some((step, corners)) = [s, s / 2]
                .into_iter()
                .filter(|&step| step >= 2 && (step == s || !dense || near_corners.is_none()))
                .find_map(|step| Some((step, corners_of(step)?)))
            else {
                match near_corners {
                    Some((c, missing)) => {
                        for c in c {
                            if !self.seen.contains_key(&c) && !pending[c] {
                                pending[c] = true;
                                anchors.push(c);
                            }
                        }
                        near.push((
                            i,
                            FarFrom {
                                corners: c,
                                origin: [bx * s, by * s],
                                step: s,
                                missing,
                            },
                        ));
                    }
                    None => full.push(i),
                }
                continue;
            };
            let origin = [x - x.rem_euclid(step), y - y.rem_euclid(step)];
            let gi = *blocks
                .entry([origin[0], origin[1], step])
                .or_insert_with(|| {
                    groups.push(Group {
                        block: [bx, by],
                        origin,
                        step,
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
        near.retain(|&(i, _)| !pending[i]);
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
            let [bx, by] = [gr.block[0] * s, gr.block[1] * s];
            for dy in [-s, 0, s, 2 * s] {
                for dx in [-s, 0, s, 2 * s] {
                    if let Some(c) = floor_of(bx + dx, by + dy, c0)
                        && (pending[c] || self.seen.contains_key(&c))
                        && !gr.anchors.contains(&c)
                    {
                        gr.anchors.push(c);
                    }
                }
            }
        }
        // On a dense level with the far split, an anchor off the lattice
        // four times as coarse whose block of that lattice has its corners
        // floor of its region, and no solid pixel in it but pillars of at
        // most 2 x 2 pixels, walks everywhere only within the outer
        // distance ([`Exact::outer`]), and past it towards the lights;
        // the light reflected to it from farther is its coarse corners'.
        // (Measured: a block across walls 6 px apart took its far light from
        // corners in other corridors, a pixel 45 % too bright.)
        let coarse = 4 * s;
        let mut fine: Vec<(usize, FarFrom)> = Vec::new();
        if dense && split && exact.outer.is_some() {
            let walls = Walls::new(g);
            anchors.retain(|&i| {
                let [x, y] = pixels[i];
                if x % coarse == 0 && y % coarse == 0 {
                    return true;
                }
                let origin = [x - x.rem_euclid(coarse), y - y.rem_euclid(coarse)];
                if walls.within(origin, coarse) {
                    return true;
                }
                match corners_at(origin[0], origin[1], coarse, comp([x, y])) {
                    Some(corners) => {
                        fine.push((
                            i,
                            FarFrom {
                                corners,
                                origin,
                                step: coarse,
                                missing: None,
                            },
                        ));
                        false
                    }
                    None => true,
                }
            });
        }
        // The coarse corners not yet known: those that are anchors of this
        // pass record it, the others are gathered for it alone.
        let mut wanted_outer = std::collections::HashSet::new();
        let mut helpers: Vec<usize> = Vec::new();
        for c in fine.iter().flat_map(|(_, f)| f.corners) {
            if !self.outer.contains_key(&c)
                && wanted_outer.insert(c)
                && (!pending[c] || self.seen.contains_key(&c))
            {
                helpers.push(c);
            }
        }
        // Anchors: a full query, keeping what each sees.
        let all: Vec<usize> = anchors.iter().chain(&helpers).copied().collect();
        let pts: Vec<[i32; 2]> = all.iter().map(|&i| pixels[i]).collect();
        let record: Vec<bool> = all.iter().map(|i| wanted_outer.contains(i)).collect();
        let how = match exact.outer.as_ref() {
            Some((r, _)) if !fine.is_empty() => Outer::Record(*r, &record),
            _ => Outer::None,
        };
        let rec = run_recording(exact, &pts, signatures, how);
        for ((j, &i), list) in all.iter().enumerate().zip(rec.seen) {
            // Anchor `j`'s values per component, then an open angle.
            let row = j * (k + 1)..(j + 1) * (k + 1);
            if record[j] {
                self.outer.insert(i, rec.beyond[row.clone()].to_vec());
            }
            if j >= anchors.len() {
                continue;
            }
            store(&rec.pass, j, i, k, &mut out);
            self.seen.insert(i, list);
            if !rec.far.is_empty() {
                self.far.insert(i, rec.far[row.clone()].to_vec());
            }
            // (An anchor that sees few lights, or whose far light is more
            // than a small share of its light, has none: `run_recording`.)
            if let Some(v) = rec.lamp_far.get(row)
                && !v[k].is_nan()
            {
                self.lamp_far.insert(i, v.to_vec());
            }
        }
        stats.culled_pairs += rec.dropped;
        counts += rec.pass.counts;
        // The finer anchors: a walk within the outer distance.
        if let Some((r, reaches)) = exact.outer.as_ref().filter(|_| !fine.is_empty()) {
            let from: Vec<(FarFrom, [&Vec<f64>; 4])> = fine
                .iter()
                .map(|(_, f)| {
                    let v = f.values_in(&self.outer);
                    debug_assert!(v.is_some(), "a finer anchor's coarse corners were gathered");
                    v.map(|v| (*f, v))
                })
                .collect::<Option<_>>()
                .unwrap_or_default();
            let pts: Vec<[i32; 2]> = fine.iter().map(|&(i, _)| pixels[i]).collect();
            let how = Outer::Near(*r, reaches, &from);
            let rec = run_recording(exact, &pts, signatures, how);
            for ((j, &(i, _)), list) in fine.iter().enumerate().zip(rec.seen) {
                store(&rec.pass, j, i, k, &mut out);
                self.seen.insert(i, list);
                self.far
                    .insert(i, rec.far[j * (k + 1)..(j + 1) * (k + 1)].to_vec());
            }
            stats.culled_pairs += rec.dropped;
            counts += rec.pass.counts;
            counts.outer += fine.len() as u64;
        }
        // (Progress: the wanted pixels that neither the full queries nor
        // the sweeps below count.)
        let swept: usize = groups.iter().map(|gr| gr.pixels.len()).sum();
        exact.done(want.len().saturating_sub(full.len() + near.len() + swept));
        // Pixels with no anchor: a full query each.
        let pts: Vec<[i32; 2]> = full.iter().map(|&i| pixels[i]).collect();
        let pass = exact.run(&pts, signatures);
        for (j, &i) in full.iter().enumerate() {
            store(&pass, j, i, k, &mut out);
        }
        stats += pass.stats;
        counts += pass.counts;
        // Pixels with no block of floor but the corners of their 4 px one:
        // a walk for the near light and the lights.
        let pts: Vec<[i32; 2]> = near.iter().map(|&(i, _)| pixels[i]).collect();
        let far_light = |j: usize, open: f64, acc: &mut [f64]| {
            let (i, from) = near[j];
            // (Its corners were gathered above, as anchors, with their far
            // light.)
            let f = from.values(self);
            debug_assert!(f.is_some(), "a near walk's corners have their far light");
            if let Some(f) = f {
                from.add(&f, pixels[i], open, acc);
            }
        };
        // (`near` is empty without the far split; a full query otherwise.)
        let pass = match exact.run_near(&pts, signatures, &far_light) {
            Some(pass) => {
                counts.far += near.len() as u64;
                pass
            }
            None => exact.run(&pts, signatures),
        };
        for (j, &(i, _)) in near.iter().enumerate() {
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
        let mut merged = vec![[0u64; 5]; groups.len()];
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
                    // With the far reflected light from the corners (where
                    // they have it): the edges that can matter otherwise,
                    // if few enough, else the whole list.
                    let (o, step) = (gr.origin, gr.step);
                    let rect = Rect {
                        lo: [o[0] as f64 + 0.5, o[1] as f64 + 0.5],
                        hi: [(o[0] + step) as f64 + 0.5, (o[1] + step) as f64 + 0.5],
                    };
                    let corners = exact.far.filter(|_| km == 0).and_then(|r| {
                        let c = gr.anchors.get(..4)?;
                        let from = FarFrom {
                            corners: [c[0], c[1], c[2], c[3]],
                            origin: o,
                            step,
                            missing: None,
                        };
                        let f = from.values(self)?;
                        let cut =
                            far_list(g, light.rad, &b.list, rect, r, &mut b.kept, &mut b.lamps);
                        // Many lights: all the light from beyond the
                        // lights' distance comes from the corners, if
                        // they have it.
                        if cut == FarCut::ManyLights
                            && let Some(rl) = exact.lamp_far
                            && let Some(f) = from.values_in(&self.lamp_far)
                        {
                            near_list(g, &b.list, rect, rl, &mut b.kept);
                            return Some((Part::Inside(rl), from, f, true));
                        }
                        Some((Part::Near(r), from, f, cut == FarCut::Kept))
                    });
                    let list = match corners {
                        Some((_, _, _, true)) => &b.kept,
                        _ => &b.list,
                    };
                    let mut tally = [0u64; 5];
                    let mut acc = vec![0.0; k];
                    let mut m = vec![0.0; km];
                    for (j, &i) in gr.pixels.iter().enumerate() {
                        let px = pixels[i];
                        let p = centre(px);
                        let comp = g.components[px[1] as usize * g.width + px[0] as usize];
                        b.spans.clear();
                        tally[2] += b.sweeper.sweep_wanted(
                            &g.edges,
                            list,
                            Viewpoint::new(p, View::Full, comp),
                            Some(Wanted {
                                reach2: exact.reaches.squared,
                                class: None,
                                cosine: None,
                            }),
                            &mut b.spans,
                        );
                        acc.iter_mut().for_each(|a| *a = 0.0);
                        let c = match &corners {
                            None => pixel_light(light, p, &b.spans, &mut acc, &mut b.scratch),
                            Some((part, from, f, _)) => {
                                let part = *part;
                                let c = pixel_light_part(
                                    light,
                                    p,
                                    &b.spans,
                                    &mut acc,
                                    &mut b.scratch,
                                    part,
                                );
                                let open = std::f64::consts::TAU - b.scratch.near_angle;
                                from.add(f, px, open, &mut acc);
                                // (Counted apart: the far light of the
                                // lights, or the walls' only.)
                                tally[if matches!(part, Part::Inside(_)) {
                                    4
                                } else {
                                    3
                                }] += 1;
                                c
                            }
                        };
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
            counts.far += c[3];
            counts.far_lights += c[4];
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

/// How [`run_recording`] treats the light from beyond [`Exact::outer`]'s
/// distance (the first field of each variant).
enum Outer<'l> {
    /// Gathered with the rest.
    None,
    /// Gathered with the rest, and also recorded on its own (with the
    /// angle open beyond the distance) for the pixels marked.
    Record(f64, &'l [bool]),
    /// Not walked but towards the lights (with these reaches,
    /// [`Reaches::closing`]); per pixel, interpolated from the corners of
    /// its coarse block, whose recorded values are given.
    Near(f64, &'l Reaches<'l>, &'l [(FarFrom, [&'l Vec<f64>; 4])]),
}

/// What [`run_recording`] finds for its pixels.
struct Recorded {
    /// The light, as [`Exact::run`] gives it. The query returns every
    /// visible span and those out of reach are left out here instead of
    /// in the query. With [`Outer::Near`], the light and the far light are
    /// the walk's within the outer distance, plus the interpolation
    /// beyond it.
    pass: super::fast::Pass,
    /// Per pixel, every edge it sees (lit or not, sorted).
    seen: Vec<Vec<u32>>,
    /// With [`Exact::far`], the light reflected to each pixel from beyond
    /// that distance (per pixel its components, then the angle open
    /// beyond it); else empty.
    far: Vec<f64>,
    /// With [`Outer::Record`], likewise the light from beyond its
    /// distance (for the pixels marked; 0 for the others); else empty.
    beyond: Vec<f64>,
    /// With [`Exact::lamp_far`], likewise all the light from beyond it,
    /// the lights' too; the open angle NaN where a pixel has none (it sees
    /// few lights, or that light is more than [`LAMP_SHARE`] of its own);
    /// else empty.
    lamp_far: Vec<f64>,
    /// Spans out of reach.
    dropped: u64,
}

/// [`Exact::run`] for `pixels`, recording what [`Recorded`] holds.
fn run_recording(
    exact: &Exact,
    pixels: &[[i32; 2]],
    signatures: Option<f64>,
    outer: Outer,
) -> Recorded {
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
    let mut far = vec![
        0.0;
        if exact.far.is_some() {
            pixels.len() * (k + 1)
        } else {
            0
        }
    ];
    let mut beyond = vec![
        0.0;
        if matches!(outer, Outer::Record(..)) {
            pixels.len() * (k + 1)
        } else {
            0
        }
    ];
    let (reaches, near) = match outer {
        Outer::Near(r, reaches, from) => (Some(reaches), Some((r, from))),
        _ => (None, None),
    };
    // All the light from beyond [`Exact::lamp_far`], for the pixels that
    // walk everywhere and see more than half of [`FAR_LAMPS`] lights, where
    // it is at most [`LAMP_SHARE`] of their light (the others' open angle
    // NaN: they have none). Only a block whose list holds more than
    // [`FAR_LAMPS`] lights takes it from its corners, and an anchor that
    // sees few lights is rarely the corner of one; a block with a corner
    // that has none sweeps as without many lights. On the shooter map (70
    // lights, none of its lists with more than 32) no anchor gathers it.
    let lamp_far_r = exact.lamp_far.filter(|_| near.is_none());
    let g = exact.geometry;
    let mut lamp_far = vec![
        0.0;
        if lamp_far_r.is_some() {
            pixels.len() * (k + 1)
        } else {
            0
        }
    ];
    // Pieces, patch pieces and pairs beyond reach, summed per thread.
    let merged = PerThread::<3>::new();
    {
        let (shared, shared_sig) = (Disjoint::new(&mut out), Disjoint::new(&mut sigs));
        let shared_far = Disjoint::new(&mut far);
        let shared_lamp_far = Disjoint::new(&mut lamp_far);
        let record = !beyond.is_empty();
        let shared_beyond = Disjoint::new(&mut beyond);
        let shared_moments = Disjoint::new(&mut moments);
        let shared_seen = Disjoint::new(&mut seen);
        crate::visibility::for_each_visibility_counted(
            exact.structures,
            None,
            pixels,
            &|_| View::Full,
            exact.reach_max,
            reaches,
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
                let mut f = vec![0.0; if exact.far.is_some() { k + 1 } else { 0 }];
                let mut o = vec![0.0; if record { k + 1 } else { 0 }];
                let mut lf = vec![0.0; if lamp_far_r.is_some() { k + 1 } else { 0 }];
                let lamp_far_r = lamp_far_r
                    .filter(|_| sees_lights(g, rad, edges.iter().copied(), FAR_LAMPS / 2));
                let (c, sig, dropped) = BUFFERS.with(|b| {
                    let b = &mut *b.borrow_mut();
                    let dropped = within_reach(exact, at, spans, &mut b.lit);
                    // With `near`: its corners, and the angle open beyond
                    // the outer distance.
                    let mut from = None;
                    let c = match near {
                        None => pixel_light(light, at, &b.lit, &mut acc, &mut b.scratch),
                        Some((r, corners)) => {
                            let part = Part::Near(r);
                            let c =
                                pixel_light_part(light, at, &b.lit, &mut acc, &mut b.scratch, part);
                            let open = std::f64::consts::TAU - b.scratch.near_angle;
                            // (Every one's corners are known: see the
                            // caller. Else the light beyond is left out.)
                            if let Some((ff, v)) = corners.get(i) {
                                ff.add(v, pixels[i], open, &mut acc);
                                from = Some((ff, v, open, r));
                            }
                            c
                        }
                    };
                    if km > 0 {
                        super::directional::pixel_moments(light, at, &b.lit, &b.scratch, &mut m);
                    }
                    let sig = signatures.map(|rel| signature(light, &b.lit, &b.scratch, &acc, rel));
                    // (Last: it reuses the scratch that the moments and the
                    // signature read.)
                    if let Some(r) = exact.far {
                        let part = match from {
                            None => Part::Far(r),
                            Some((.., outer)) => Part::Band(r, outer),
                        };
                        pixel_light_part(light, at, &b.lit, &mut f[..k], &mut b.scratch, part);
                        f[k] = std::f64::consts::TAU - b.scratch.near_angle;
                        if let Some((ff, v, open, _)) = from {
                            ff.add(v, pixels[i], open, &mut f[..k]);
                        }
                    }
                    if let Outer::Record(r, marked) = outer
                        && marked[i]
                    {
                        let part = Part::Far(r);
                        pixel_light_part(light, at, &b.lit, &mut o[..k], &mut b.scratch, part);
                        o[k] = std::f64::consts::TAU - b.scratch.near_angle;
                    }
                    if let Some(r) = lamp_far_r {
                        let part = Part::Outside(r);
                        pixel_light_part(light, at, &b.lit, &mut lf[..k], &mut b.scratch, part);
                        // Only where it is a small share of the anchor's
                        // light in every component.
                        let share = (0..k)
                            .map(|c| lf[c] / acc[c].max(f64::MIN_POSITIVE))
                            .fold(0.0, f64::max);
                        lf[k] = if share <= LAMP_SHARE {
                            std::f64::consts::TAU - b.scratch.near_angle
                        } else {
                            f64::NAN
                        };
                    } else if let Some(open) = lf.get_mut(k) {
                        *open = f64::NAN;
                    }
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
                    for (c, &v) in f.iter().enumerate() {
                        shared_far.write(i * (k + 1) + c, v);
                    }
                    for (c, &v) in o.iter().enumerate() {
                        shared_beyond.write(i * (k + 1) + c, v);
                    }
                    for (c, &v) in lf.iter().enumerate() {
                        shared_lamp_far.write(i * (k + 1) + c, v);
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
    Recorded {
        pass,
        seen,
        far,
        beyond,
        lamp_far,
        dropped,
    }
}

/// Whether the edges `seen` hold edges of more than `n` lights (loops
/// that emit).
pub(super) fn sees_lights(
    g: &Geometry,
    rad: &super::Radiosity,
    seen: impl IntoIterator<Item = u32>,
    n: usize,
) -> bool {
    let mut loops: Vec<u32> = Vec::with_capacity(n + 1);
    for e in seen {
        let l = g.edges[e as usize].loop_id;
        if rad.edge_emits[e as usize] && !loops.contains(&l) {
            loops.push(l);
            if loops.len() > n {
                return true;
            }
        }
    }
    false
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

/// The solid pixels of a level that are not pillars of at most 2 x 2
/// pixels (their 4-connected solid pixels span more), counted over any
/// rectangle from a table of sums.
struct Walls {
    width: usize,
    height: usize,
    /// `sum[y * (width + 1) + x]`: such pixels in `[0, x) x [0, y)`.
    sum: Vec<u32>,
}

impl Walls {
    fn new(g: &Geometry) -> Walls {
        let (w, h) = (g.width, g.height);
        let solid = |x: usize, y: usize| g.component_at(x as i64, y as i64).is_none();
        let mut wall = vec![false; w * h];
        let mut done = vec![false; w * h];
        let (mut stack, mut blob) = (Vec::new(), Vec::new());
        for start in 0..w * h {
            if done[start] || !solid(start % w, start / w) {
                continue;
            }
            // The 4-connected solid pixels of `start`, and their extent.
            done[start] = true;
            stack.push(start);
            blob.clear();
            let (mut lo, mut hi) = ([usize::MAX; 2], [0usize; 2]);
            while let Some(i) = stack.pop() {
                blob.push(i);
                let (x, y) = (i % w, i / w);
                lo = [lo[0].min(x), lo[1].min(y)];
                hi = [hi[0].max(x), hi[1].max(y)];
                let next = [
                    (x > 0).then(|| i - 1),
                    (x + 1 < w).then(|| i + 1),
                    (y > 0).then(|| i - w),
                    (y + 1 < h).then(|| i + w),
                ];
                for j in next.into_iter().flatten() {
                    if !done[j] && solid(j % w, j / w) {
                        done[j] = true;
                        stack.push(j);
                    }
                }
            }
            if hi[0] - lo[0] >= 2 || hi[1] - lo[1] >= 2 {
                blob.iter().for_each(|&i| wall[i] = true);
            }
        }
        let mut sum = vec![0u32; (w + 1) * (h + 1)];
        for y in 0..h {
            for x in 0..w {
                sum[(y + 1) * (w + 1) + x + 1] = u32::from(wall[y * w + x])
                    + sum[y * (w + 1) + x + 1]
                    + sum[(y + 1) * (w + 1) + x]
                    - sum[y * (w + 1) + x];
            }
        }
        Walls {
            width: w,
            height: h,
            sum,
        }
    }

    /// Whether the block of `side` px at `origin` (its far sides included)
    /// holds such a pixel, or lies partly outside the level.
    fn within(&self, origin: [i32; 2], side: i32) -> bool {
        let (x0, y0) = (origin[0], origin[1]);
        let (x1, y1) = (x0 + side + 1, y0 + side + 1);
        if x0 < 0 || y0 < 0 || x1 as usize > self.width || y1 as usize > self.height {
            return true;
        }
        let (x0, y0, x1, y1) = (x0 as usize, y0 as usize, x1 as usize, y1 as usize);
        let at = |x: usize, y: usize| self.sum[y * (self.width + 1) + x];
        at(x1, y1) + at(x0, y0) - at(x0, y1) - at(x1, y0) > 0
    }
}

/// The most that a pixel's far light from its block's corners is scaled
/// by (`add_far` in `gather/local.rs`): the corners' interpolated far
/// light at most doubled, however much wider than theirs the pixel's
/// open angle beyond the distance is.
///
/// Where the corners lie in pockets of wall and see out past the
/// distance through a few narrow gaps, their light per radian comes from
/// those few directions, and the scale would spread it over all of the
/// pixel's. Unbounded, it made a pixel of wall noise at 10 % at `draft`
/// ten times too bright (10.5 against 1.10 in `high`: the level's error
/// from `high` 11.9 % instead of 2.0 %). A cap of 1.5 or 2 changes no
/// other class's error from `high` at full size at `draft` or `normal`
/// (to 0.001 points; it also bounds the far light of many lights, taken
/// the same way, which moved nowhere measured); a cap of 1 (never more
/// than the corners) doubles the courtyard's at `normal`, 0.275 ->
/// 0.624 % (docs/performance.md, forty-second pass).
pub const FAR_SCALE: f64 = 2.0;

/// Adds to `acc` the light reflected from far away to a pixel at `(fx,
/// fy)` (0 to 1) between the corners of its block, whose far light and
/// open angle are `f` (in the order (x0, y0), (x1, y0), (x0, y1), (x1,
/// y1); each its components, then its open angle): their bilinear
/// interpolation, scaled by the angle `open` that the pixel has open
/// beyond the distance against the corners' interpolated one (a wall
/// beside the pixel hides more of the far light from it than its corners
/// see hidden), by at most [`FAR_SCALE`]. The interpolation's weights
/// are `w`; where one is negative (a missing corner's plane,
/// [`FarFrom::add`]), a value below 0 is 0.
fn add_far(acc: &mut [f64], f: &[&Vec<f64>; 4], w: [f64; 4], open: f64) {
    let floor = w.iter().any(|&w| w < 0.0);
    let at = |c: usize| {
        let v = (0..4).map(|q| w[q] * f[q][c]).sum::<f64>();
        if floor { v.max(0.0) } else { v }
    };
    let corners_open = at(acc.len());
    let scale = if corners_open > 0.0 {
        (open / corners_open).min(FAR_SCALE)
    } else {
        1.0
    };
    for (c, a) in acc.iter_mut().enumerate() {
        *a += at(c) * scale;
    }
}

/// An axis-aligned rectangle (`lo <= hi`).
#[derive(Clone, Copy, Debug)]
struct Rect {
    lo: [f64; 2],
    hi: [f64; 2],
}

impl Rect {
    fn of_edge(e: &crate::geometry::Edge) -> Rect {
        let (a, b) = (e.a.map(f64::from), e.b.map(f64::from));
        Rect {
            lo: [a[0].min(b[0]), a[1].min(b[1])],
            hi: [a[0].max(b[0]), a[1].max(b[1])],
        }
    }

    fn union(self, o: Rect) -> Rect {
        Rect {
            lo: [self.lo[0].min(o.lo[0]), self.lo[1].min(o.lo[1])],
            hi: [self.hi[0].max(o.hi[0]), self.hi[1].max(o.hi[1])],
        }
    }

    /// Squared distance between two rectangles.
    fn distance_sq(self, o: Rect) -> f64 {
        let dx = (o.lo[0] - self.hi[0]).max(self.lo[0] - o.hi[0]).max(0.0);
        let dy = (o.lo[1] - self.hi[1]).max(self.lo[1] - o.hi[1]).max(0.0);
        dx * dx + dy * dy
    }
}

/// Whether segment `p q` may meet the convex hull of rectangles `a` and
/// `b`: `false` only if a line separates them (the hull's bounding box, or
/// one of the hull's sides through two like corners of `a` and `b`). Every
/// segment from a point of `a` to a point of `b` lies in that hull, so an
/// edge for which this is `false` hides nothing of `b` from `a`.
fn may_cross_hull(a: Rect, b: Rect, p: [f64; 2], q: [f64; 2]) -> bool {
    let u = a.union(b);
    if p[0].max(q[0]) < u.lo[0]
        || p[0].min(q[0]) > u.hi[0]
        || p[1].max(q[1]) < u.lo[1]
        || p[1].min(q[1]) > u.hi[1]
    {
        return false;
    }
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        let corner = |r: Rect| {
            [
                if sx > 0.0 { r.hi[0] } else { r.lo[0] },
                if sy > 0.0 { r.hi[1] } else { r.lo[1] },
            ]
        };
        let (ca, cb) = (corner(a), corner(b));
        let d = [cb[0] - ca[0], cb[1] - ca[1]];
        let mut n = [-d[1], d[0]];
        if n[0] * sx + n[1] * sy < 0.0 {
            n = [d[1], -d[0]];
        }
        // Both rectangles' corners of this kind maximise `n . x` over them
        // only if `n` points into the corner's quadrant: then the line
        // through the two corners has the hull on one side.
        if n[0] * sx < 0.0 || n[1] * sy < 0.0 {
            continue;
        }
        let m = n[0] * ca[0] + n[1] * ca[1];
        if n[0] * p[0] + n[1] * p[1] > m && n[0] * q[0] + n[1] * q[1] > m {
            return false;
        }
    }
    true
}

/// The part of a block's `list` (sorted) that a sweep needs when the light
/// reflected from beyond `r` comes from the block's corners ([`Exact::far`]),
/// into `kept` (sorted): the lights, the edges within `r` of the block's
/// pixel centres `block` (everything that can hide a point within `r` of a
/// pixel lies within `r` of it), and the edges that may hide a light on the
/// list from some pixel of the block ([`may_cross_hull`]). [`FarCut::Whole`]
/// where that would keep more than three quarters of the list, and
/// [`FarCut::ManyLights`] where the list holds more than [`FAR_LAMPS`]
/// lights (`kept` then unset).
fn far_list(
    g: &Geometry,
    rad: &super::Radiosity,
    list: &[u32],
    block: Rect,
    r: f64,
    kept: &mut Vec<u32>,
    lamps: &mut Vec<(u32, Rect)>,
) -> FarCut {
    kept.clear();
    lamps.clear();
    let r2 = r * r;
    let mut far = 0;
    for &e in list {
        let edge = &g.edges[e as usize];
        if rad.edge_emits[e as usize] {
            let at = Rect::of_edge(edge);
            match lamps.iter().position(|(l, _)| *l == edge.loop_id) {
                Some(i) => lamps[i].1 = lamps[i].1.union(at),
                None if lamps.len() < FAR_LAMPS => lamps.push((edge.loop_id, at)),
                None => return FarCut::ManyLights,
            }
        } else if !near_block(edge, block, r2) {
            far += 1;
        }
    }
    if 4 * far < list.len() {
        return FarCut::Whole;
    }
    for &e in list {
        let edge = &g.edges[e as usize];
        let keep = rad.edge_emits[e as usize] || near_block(edge, block, r2) || {
            let (p, q) = (edge.a.map(f64::from), edge.b.map(f64::from));
            lamps
                .iter()
                .any(|&(_, lamp)| may_cross_hull(block, lamp, p, q))
        };
        if keep {
            kept.push(e);
        }
    }
    if 4 * kept.len() <= 3 * list.len() {
        FarCut::Kept
    } else {
        FarCut::Whole
    }
}

/// What a block's sweep takes from its corners ([`far_list`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FarCut {
    /// The light reflected from beyond the far split, and the sweep needs
    /// only the list's part `kept`.
    Kept,
    /// The light reflected from beyond the far split; the sweep needs the
    /// whole list.
    Whole,
    /// The list holds more lights than [`FAR_LAMPS`]: with
    /// [`Exact::lamp_far`], all the light from beyond that distance, and
    /// the sweep needs the edges within it ([`near_list`]); else as
    /// [`FarCut::Whole`].
    ManyLights,
}

/// The edges of a block's `list` (sorted) within `r` of its pixel centres
/// `block`, into `kept` (sorted): everything that can hide from a pixel of
/// the block a point within `r` of it.
fn near_list(g: &Geometry, list: &[u32], block: Rect, r: f64, kept: &mut Vec<u32>) {
    let r2 = r * r;
    kept.clear();
    kept.extend(
        list.iter()
            .copied()
            .filter(|&e| near_block(&g.edges[e as usize], block, r2)),
    );
}

/// Whether `edge` comes within the distance whose square is `r2` of
/// `block` ([`far_list`], [`near_list`]).
fn near_block(edge: &Edge, block: Rect, r2: f64) -> bool {
    Rect::of_edge(edge).distance_sq(block) <= r2
}

/// A pixel with no block of the spacing that is floor around it walks
/// near ([`Exact::run_near`]) rather than sweep a block of half the
/// spacing only on levels with at least one edge per this many floor
/// pixels ([`Lists::gather`]). On a dense level (the pillar field: 13 %
/// faster) that spares the anchors of the small blocks, whose full walks
/// cost several near walks each; on a real map the near walk costs about
/// what the small block's sweep and anchors do (the shooter map 3 %
/// slower, the courtyard 2 %).
pub(super) const DENSE: usize = 64;

/// Whether a level of geometry `g` gathering `floor` pixels is dense: at
/// least one edge per [`DENSE`] floor pixels.
pub(super) fn is_dense(g: &Geometry, floor: usize) -> bool {
    DENSE * g.edges.len() >= floor
}

/// At most this many lights (loops that emit) on a block's list for its
/// sweep to keep only the edges that may hide a light (`far_list`: each
/// far edge is tested against each light's hull). With the far split, on
/// a level of more lights that is not dense, a list with more takes all
/// its light from beyond [`super::LAMP_FAR`] from its block's corners, the
/// lights' too, where they have it ([`LAMP_SHARE`]).
pub const FAR_LAMPS: usize = 32;

/// The largest share of an anchor's light (in any component) that its
/// light from beyond [`super::LAMP_FAR`] may be for the blocks it is a
/// corner of to take theirs from it (`Exact::lamp_far`).
pub const LAMP_SHARE: f64 = 0.25;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A block's far light from its corners: bilinear from four, and from
    /// three where the fourth is missing, on the plane through them, which
    /// reproduces light that varies linearly across the block at every
    /// pixel and never goes below 0.
    #[test]
    fn far_light_from_three_corners_lies_on_their_plane() {
        let light = |x: f64, y: f64| 2.0 + 0.3 * x - 0.2 * y;
        let at = [(0, 0), (4, 0), (0, 4), (4, 4)];
        // Per corner: one component, then the open angle (equal, so the
        // pixel's own open angle scales nothing).
        let values: Vec<Vec<f64>> = at
            .iter()
            .map(|&(x, y)| vec![light(x as f64, y as f64), 1.0])
            .collect();
        for missing in [None, Some(0), Some(1), Some(2), Some(3)] {
            let slot = |q: usize| match missing {
                Some(m) if m == q => 3 - q,
                _ => q,
            };
            let f = [0, 1, 2, 3].map(|q| &values[slot(q)]);
            let from = FarFrom {
                corners: [0, 1, 2, 3].map(slot),
                origin: [8, 12],
                step: 4,
                missing,
            };
            for y in 0..4 {
                for x in 0..4 {
                    let mut acc = [0.0];
                    from.add(&f, [8 + x, 12 + y], 1.0, &mut acc);
                    let want = light(x as f64, y as f64);
                    assert!(
                        (acc[0] - want).abs() < 1e-12,
                        "{missing:?} at ({x}, {y}): {} against {want}",
                        acc[0]
                    );
                }
            }
        }
        // Light that falls off towards the missing corner faster than
        // linearly: the plane would go below 0 there; the light stops at 0.
        let values = [vec![1.0, 1.0], vec![0.0, 1.0], vec![0.0, 1.0]];
        let f = [&values[0], &values[1], &values[2], &values[0]];
        let from = FarFrom {
            corners: [0, 1, 2, 0],
            origin: [0, 0],
            step: 4,
            missing: Some(3),
        };
        for (x, y) in [(3, 3), (2, 3), (3, 2)] {
            let mut acc = [0.0];
            from.add(&f, [x, y], 1.0, &mut acc);
            assert!(acc[0] >= 0.0, "({x}, {y}): {}", acc[0]);
        }
    }

    /// A pixel whose open angle beyond the distance is far wider than its
    /// corners' (they see out through narrow gaps) takes at most
    /// [`FAR_SCALE`] times their interpolated far light; one whose angle
    /// is narrower (a wall beside it) takes its share; and within the cap
    /// the light follows the angle.
    #[test]
    fn far_light_scales_with_the_open_angle_up_to_its_cap() {
        // Each corner: two components, then an open angle of 0.1 rad.
        let values = vec![3.0, 1.5, 0.1];
        let f = [&values; 4];
        let from = FarFrom {
            corners: [0, 1, 2, 3],
            origin: [0, 0],
            step: 4,
            missing: None,
        };
        for (open, scale) in [(6.0, FAR_SCALE), (0.05, 0.5), (0.15, 1.5), (0.1, 1.0)] {
            for (x, y) in [(0, 0), (1, 2), (3, 3)] {
                let mut acc = [0.25, 0.0];
                from.add(&f, [x, y], open, &mut acc);
                let want = [0.25 + 3.0 * scale, 1.5 * scale];
                for c in 0..2 {
                    assert!(
                        (acc[c] - want[c]).abs() < 1e-12,
                        "open {open} at ({x}, {y}), component {c}: {} against {}",
                        acc[c],
                        want[c]
                    );
                }
            }
        }
    }

    /// Whether segments `a b` and `c d` meet (touching counts).
    fn cross(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
        let side = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
            (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
        };
        let (d1, d2) = (side(c, d, a), side(c, d, b));
        let (d3, d4) = (side(a, b, c), side(a, b, d));
        let within = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
            r[0] >= p[0].min(q[0])
                && r[0] <= p[0].max(q[0])
                && r[1] >= p[1].min(q[1])
                && r[1] <= p[1].max(q[1])
        };
        ((d1 > 0.0) != (d2 > 0.0) && (d3 > 0.0) != (d4 > 0.0) && d1 != 0.0 && d3 != 0.0)
            || (d1 == 0.0 && within(c, d, a))
            || (d2 == 0.0 && within(c, d, b))
            || (d3 == 0.0 && within(a, b, c))
            || (d4 == 0.0 && within(a, b, d))
    }

    fn rect() -> impl Strategy<Value = Rect> {
        (-20i32..20, -20i32..20, 0i32..6, 0i32..6).prop_map(|(x, y, w, h)| Rect {
            lo: [x as f64 + 0.5, y as f64 + 0.5],
            hi: [(x + w) as f64 + 0.5, (y + h) as f64 + 0.5],
        })
    }

    proptest! {
        /// An edge (axis-aligned, on the pixel grid) that the hull test
        /// lets go hides no ray from a point of the block to a point of the
        /// light: sampled rays between the two rectangles never cross it.
        #[test]
        fn an_edge_let_go_crosses_no_ray_from_block_to_light(
            a in rect(),
            b in rect(),
            x in -25i32..25,
            y in -25i32..25,
            len in 1i32..12,
            vertical in any::<bool>(),
            ts in proptest::collection::vec((0.0..=1.0f64, 0.0..=1.0f64, 0.0..=1.0f64, 0.0..=1.0f64), 64),
        ) {
            let p = [x as f64, y as f64];
            let q = if vertical { [p[0], p[1] + len as f64] } else { [p[0] + len as f64, p[1]] };
            if !may_cross_hull(a, b, p, q) {
                let at = |r: Rect, u: f64, v: f64| {
                    [r.lo[0] + u * (r.hi[0] - r.lo[0]), r.lo[1] + v * (r.hi[1] - r.lo[1])]
                };
                // The rectangles' corners, and points inside them.
                let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)];
                for &(u, v) in &corners {
                    for &(s, t) in &corners {
                        prop_assert!(!cross(at(a, u, v), at(b, s, t), p, q));
                    }
                }
                for &(u, v, s, t) in &ts {
                    prop_assert!(!cross(at(a, u, v), at(b, s, t), p, q));
                }
            }
        }
    }

    /// The hull test does let go of edges off to the side (else the far
    /// split would keep every edge).
    #[test]
    fn an_edge_off_to_the_side_is_let_go() {
        let block = Rect {
            lo: [0.5, 0.5],
            hi: [4.5, 4.5],
        };
        let lamp = Rect {
            lo: [100.0, 0.0],
            hi: [102.0, 2.0],
        };
        // Beside the ray from the block to the lamp, past its hull.
        assert!(!may_cross_hull(block, lamp, [50.0, 10.0], [50.0, 11.0]));
        assert!(!may_cross_hull(block, lamp, [50.0, -6.0], [51.0, -6.0]));
        // Across it.
        assert!(may_cross_hull(block, lamp, [50.0, 1.0], [50.0, 2.0]));
        assert!(may_cross_hull(block, lamp, [50.0, -10.0], [50.0, 10.0]));
    }
}
