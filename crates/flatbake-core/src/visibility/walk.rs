//! The output-sensitive walk: blocks of edges from near to far over an
//! angular coverage buffer that skips what nearer surfaces already hide.

use std::sync::OnceLock;

use super::sweep::silhouette;
use super::*;

/// How an axis-aligned box lies as seen from a query.
enum BoxView {
    /// The query point is inside (or on) the box.
    Around,
    /// Entirely behind a half view.
    Behind,
    /// The pseudo-angle range, as one or two `[a, b]` ranges.
    Ranges([(f64, f64); 2]),
}

fn box_range(q: &Query, x0: f64, y0: f64, x1: f64, y1: f64) -> BoxView {
    let p = q.p;
    if p[0] >= x0 && p[0] <= x1 && p[1] >= y0 && p[1] <= y1 {
        return BoxView::Around;
    }
    let corners = [[x0, y0], [x1, y0], [x0, y1], [x1, y1]];
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    if q.full {
        // The box holds part of the cut ray (+x from p): the range wraps.
        if y0 < p[1] && p[1] < y1 && x0 > p[0] {
            let (mut top, mut bottom) = (0.0f64, 4.0f64);
            for c in corners {
                let (u, v) = q.local(c);
                if v >= 0.0 {
                    top = top.max(diamond(u, v));
                } else {
                    bottom = bottom.min(diamond(u, v));
                }
            }
            return BoxView::Ranges([(0.0, top), (bottom, 4.0)]);
        }
        for c in corners {
            let (u, v) = q.local(c);
            let k = diamond(u, v);
            lo = lo.min(k);
            hi = hi.max(k);
        }
    } else {
        let mut any = false;
        for c in corners {
            let (u, v) = q.local(c);
            // Corners behind the half-plane project onto its boundary.
            let k = if v > 0.0 {
                any = true;
                diamond(u, v)
            } else if u > 0.0 {
                0.0
            } else {
                2.0
            };
            lo = lo.min(k);
            hi = hi.max(k);
        }
        if !any {
            return BoxView::Behind;
        }
    }
    BoxView::Ranges([(lo, hi), (lo, hi)])
}

const NONE: u32 = u32::MAX;

/// The code of piece `pi`'s start (`va`) or, if `end`, its end (`vb`).
#[inline]
fn vertex_code(pi: u32, end: bool) -> u32 {
    debug_assert!(pi < NONE / 2, "piece indices fit in 31 bits");
    pi * 2 + u32::from(end)
}

/// The vertex that [`vertex_code`] gave `code` (the origin for [`NONE`],
/// the end of the view, which no span reads).
#[inline]
fn vertex(pieces: &[Piece], code: u32) -> [f64; 2] {
    if code == NONE {
        return [0.0; 2];
    }
    let pc = &pieces[(code / 2) as usize];
    if code % 2 == 1 { pc.vb } else { pc.va }
}

/// [`Iv::far`] not yet known (a distance is never negative).
const UNKNOWN: f64 = f64::NEG_INFINITY;

/// One interval of the angular buffer, `[previous end, end)`.
#[derive(Clone, Copy, Debug)]
struct Iv {
    end: f64,
    /// The vertex whose direction is `end`: an end of a piece, as
    /// [`vertex_code`] writes it (kept as a code so that an interval takes
    /// 24 bytes: insertions shift the buffer's tail).
    vend: u32,
    /// Nearest piece found so far, or [`NONE`].
    owner: u32,
    /// Farthest distance of the owner over the interval (infinite if none).
    far: f64,
}

const _: () = assert!(std::mem::size_of::<Iv>() == 24);

/// The one-dimensional angular buffer of the walk: contiguous intervals of
/// pseudo-angle covering the view, each owned by the nearest piece found so
/// far (or none).
#[derive(Default)]
pub(super) struct Coverage {
    iv: Vec<Iv>,
    scratch: Vec<Iv>,
    out: Vec<Iv>,
    /// Where the last search ended: the walk inserts the edges of one
    /// block after another, so the next piece is usually close by.
    hint: usize,
    /// Where the last test of a block ([`Coverage::hides`]) started.
    seen: usize,
    /// How many intervals have no owner.
    open: usize,
    /// Once no interval is open: at least the farthest distance of every
    /// owner over its interval (found when the last open interval closed,
    /// then raised by every interval written), or infinity. A block
    /// farther than that is hidden in every direction
    /// ([`Coverage::closed_before`]).
    far_bound: f64,
}

impl Coverage {
    fn reset(&mut self, kmax: f64) {
        self.iv.clear();
        self.iv.push(Iv {
            end: kmax,
            vend: NONE,
            owner: NONE,
            far: f64::INFINITY,
        });
        self.open = 1;
        self.far_bound = f64::INFINITY;
    }

    /// Whether every direction already hits something nearer than `dmin`:
    /// what [`Coverage::hides`] would say of any range, without reading
    /// the intervals.
    #[inline]
    fn closed_before(&self, dmin: f64) -> bool {
        self.open == 0 && dmin > self.far_bound
    }

    /// The first interval that ends after `k` (`iv.partition_point(|v|
    /// v.end <= k)`), searched outwards from [`Coverage::hint`].
    #[inline]
    fn find(&mut self, k: f64) -> usize {
        let i = self.search(self.hint, k);
        self.hint = i;
        i
    }

    /// `iv.partition_point(|v| v.end <= k)`, searched outwards from `h`.
    #[inline]
    fn search(&self, h: usize, k: f64) -> usize {
        let n = self.iv.len();
        let before = |i: usize| self.iv[i].end <= k;
        let h = h.min(n);
        // The answer lies in `lo..=hi`: widen by doubling steps from `h`.
        let (mut lo, mut hi);
        if h < n && before(h) {
            let mut step = 1;
            lo = h + 1;
            loop {
                let probe = h + step;
                if probe >= n {
                    hi = n;
                    break;
                }
                if !before(probe) {
                    hi = probe;
                    break;
                }
                lo = probe + 1;
                step *= 2;
            }
        } else {
            hi = h;
            let mut step = 1;
            loop {
                if step > h {
                    lo = 0;
                    break;
                }
                let probe = h - step;
                if before(probe) {
                    lo = probe + 1;
                    break;
                }
                hi = probe;
                step *= 2;
            }
        }
        lo + self.iv[lo..hi].partition_point(|v| v.end <= k)
    }

    #[inline]
    fn start(&self, i: usize) -> f64 {
        if i == 0 { 0.0 } else { self.iv[i - 1].end }
    }

    /// True when every direction in `[a, b]` already hits something nearer than `dmin`.
    /// The walk tests blocks near each other one after the other, so the
    /// search starts where the last test started ([`Coverage::seen`]).
    fn hides(&mut self, a: f64, b: f64, dmin: f64) -> bool {
        let mut i = self.search(self.seen, a);
        self.seen = i;
        while i < self.iv.len() && self.start(i) <= b {
            let v = &self.iv[i];
            // NaN distances count as not hidden.
            if v.owner == NONE || v.far >= dmin || v.far.is_nan() {
                return false;
            }
            i += 1;
        }
        true
    }

    /// Whether piece `pi` is nearer than the owner of interval `i` (which
    /// it overlaps), on the ray through the middle of their overlap; `near`
    /// is how near the piece comes to the query point, less a margin (see
    /// [`Coverage::insert`]).
    #[inline]
    fn wins(&self, pieces: &[Piece], pi: u32, near: f64, i: usize) -> bool {
        let (pc, v) = (&pieces[pi as usize], &self.iv[i]);
        if v.owner == NONE {
            return true;
        }
        if v.far < near {
            return false;
        }
        let (lo, hi) = (self.start(i).max(pc.ka), v.end.min(pc.kb));
        let (du, dv) = diamond_dir(0.5 * (lo + hi));
        let o = &pieces[v.owner as usize];
        let (tp, to) = (pc.t(du, dv), o.t(du, dv));
        tp < to || (tp == to && pi < v.owner)
    }

    /// Lets piece `pi` take every part of `[ka, kb)` where it is nearer
    /// (seen from `p`).
    ///
    /// Each run of consecutive intervals that the piece wins is rebuilt on
    /// its own; the intervals between runs stay as they are. A far piece
    /// seen through a few gaps overlaps many intervals and wins one or two.
    fn insert(&mut self, pieces: &[Piece], pi: u32, p: [f64; 2]) {
        let pc = pieces[pi as usize];
        let mut i = self.find(pc.ka);
        // An interval whose owner is nowhere as far as the piece comes
        // near `p` keeps its owner without a ray test (walked near to far,
        // most pieces lose everywhere). The margin covers the rounding of
        // both distances, so the test only decides what the ray test would.
        let near = pc.nearest(p) * (1.0 - 1e-9);
        loop {
            while i < self.iv.len() && self.start(i) < pc.kb {
                if self.wins(pieces, pi, near, i) {
                    break;
                }
                i += 1;
            }
            if i >= self.iv.len() || self.start(i) >= pc.kb {
                return;
            }
            i = self.rebuild_run(pieces, pi, near, i);
        }
    }

    /// Gives piece `pi` the run of intervals it wins from interval `i` on
    /// (it wins `i`), merged with equal neighbours; returns the index of
    /// the first interval after the run.
    fn rebuild_run(&mut self, pieces: &[Piece], pi: u32, near: f64, mut i: usize) -> usize {
        let pc = pieces[pi as usize];
        let n = self.iv.len();
        let piece_far = |o: u32, k0: f64, k1: f64| {
            if o == NONE {
                f64::INFINITY
            } else {
                let p = &pieces[o as usize];
                // A silhouette's own pieces are its surface (nearer than
                // its segment), and nearest at their corner.
                let at = |k: f64| {
                    if p.silhouette {
                        let face = o as usize - if k <= p.c { 2 } else { 1 };
                        pieces[face].distance_at(k)
                    } else {
                        p.distance_at(k)
                    }
                };
                at(k0).max(at(k1))
            }
        };
        let mut a = i;
        self.scratch.clear();
        while i < n && self.start(i) < pc.kb {
            let (s, v) = (self.start(i), self.iv[i]);
            if i > a && !self.wins(pieces, pi, near, i) {
                break;
            }
            let (lo, hi) = (s.max(pc.ka), v.end.min(pc.kb));
            if lo > s {
                self.scratch.push(Iv {
                    end: lo,
                    vend: vertex_code(pi, false),
                    owner: v.owner,
                    far: UNKNOWN,
                });
            }
            let vhi = if hi == pc.kb && hi < v.end {
                vertex_code(pi, true)
            } else {
                v.vend
            };
            self.scratch.push(Iv {
                end: hi,
                vend: vhi,
                owner: pi,
                far: UNKNOWN,
            });
            if v.end > hi {
                self.scratch.push(Iv {
                    end: v.end,
                    vend: v.vend,
                    owner: v.owner,
                    far: UNKNOWN,
                });
            }
            i += 1;
        }
        let mut b = i;
        // The run also takes in the interval before and the one after
        // (not in `scratch`) where they have the owner of its ends.
        if a > 0 && self.iv[a - 1].owner == self.scratch[0].owner {
            a -= 1;
        }
        if b < n && self.iv[b].owner == self.scratch[self.scratch.len() - 1].owner {
            self.scratch.push(self.iv[b]);
            b += 1;
        }
        // Consecutive pieces of one owner become one interval, with the
        // owner's farthest distance over it (every interval written here
        // is new or grown: the piece's, a part of one it split, or a
        // neighbour merged).
        let mut out = std::mem::take(&mut self.out);
        out.clear();
        let mut seg_start = self.start(a);
        for (j, t) in self.scratch.iter().enumerate() {
            if self
                .scratch
                .get(j + 1)
                .is_some_and(|next| next.owner == t.owner)
            {
                continue;
            }
            let far = piece_far(t.owner, seg_start, t.end);
            out.push(Iv { far, ..*t });
            seg_start = t.end;
        }
        let next = a + out.len();
        // An owner's distance that is NaN is never hidden behind: no bound.
        let far = |v: &Iv| if v.far.is_nan() { f64::INFINITY } else { v.far };
        let was_open = self.open;
        self.open -= self.iv[a..b].iter().filter(|v| v.owner == NONE).count();
        self.open += out.iter().filter(|v| v.owner == NONE).count();
        self.iv.splice(a..b, out.drain(..));
        if self.open == 0 {
            // Every interval when the last open one just closed; else
            // those written, raising the bound.
            let (read, from) = if was_open > 0 {
                (0..self.iv.len(), f64::NEG_INFINITY)
            } else {
                (a..next, self.far_bound)
            };
            self.far_bound = self.iv[read].iter().map(far).fold(from, f64::max);
        }
        self.out = out;
        next
    }
}

/// The squared least distance from `p` to the box `[x0, x1] x [y0, y1]`.
#[inline]
fn box_distance_sq(p: [f64; 2], x0: f64, y0: f64, x1: f64, y1: f64) -> f64 {
    let dx = (x0 - p[0]).max(p[0] - x1).max(0.0);
    let dy = (y0 - p[1]).max(p[1] - y1).max(0.0);
    dx * dx + dy * dy
}

/// The cell of side `size` that coordinate `v` lies in, clamped to the
/// `n` cells of the grid.
#[inline]
fn cell_of(v: f64, size: f64, n: usize) -> usize {
    ((v / size).floor().max(0.0) as usize).min(n - 1)
}

/// Edges binned into square blocks, with a pyramid of boxes above them,
/// for [`Sweeper::walk`].
pub struct Blocks<'g> {
    /// The edges binned (the geometry's).
    edges: &'g [Edge],
    size: i32,
    /// `(nx, ny)` per level; level 0 are the blocks.
    dims: Vec<(usize, usize)>,
    /// Per node per level: the box around the parts of its edges that lie
    /// in its square (`x0, y0, x1, y1`: each edge cut to a block's square
    /// along its axis; `x0 > x1` where it has none), which the walk tests
    /// instead of the square. A block of a pillar or two is mostly empty,
    /// and a far block seen through a gap is often hidden where its square
    /// is not.
    boxes: Vec<Vec<[i32; 4]>>,
    /// Edges of block `b`: `list[start[b]..start[b + 1]]`.
    start: Vec<usize>,
    list: Vec<u32>,
}

impl<'g> Blocks<'g> {
    /// Side of a block in painted pixels (times [`Geometry::unit`] in pixels).
    pub const SIZE: i32 = 8;
    /// Side of a block on dense levels, in painted pixels: there a walk
    /// inserts fewer edges per block it cannot skip.
    pub const DENSE_SIZE: i32 = 4;
    /// Edges per [`Blocks::SIZE`] block, on average over the level, from
    /// which its blocks are [`Blocks::DENSE_SIZE`] (a field of one-pixel
    /// dots has 64; wall noise at 10 % has 21, the pillar field 5).
    pub const DENSE: usize = 32;

    /// Side of the blocks, in pixels.
    pub fn side(&self) -> i32 {
        self.size
    }

    /// Bins the edges of `g`, in blocks of [`Blocks::SIZE`] painted pixels,
    /// or of [`Blocks::DENSE_SIZE`] on a dense level.
    pub fn new(g: &'g Geometry) -> Blocks<'g> {
        let unit = g.unit.max(1);
        let area = (g.width * g.height) as f64 / (Self::SIZE as usize * unit).pow(2) as f64;
        let dense = g.edges.len() as f64 >= Self::DENSE as f64 * area.max(1.0);
        let size = if dense { Self::DENSE_SIZE } else { Self::SIZE } * unit as i32;
        let nx = g.width.div_ceil(size as usize).max(1);
        let ny = g.height.div_ceil(size as usize).max(1);
        let blocks_of = |e: &Edge| {
            let (lo, hi) = e.extent();
            let line = e.line() as i32;
            let (a0, a1) = (
                lo as i32 / size,
                ((hi as i32 + size - 1) / size - 1).max(lo as i32 / size),
            );
            let l = line / size;
            (a0, a1, l)
        };
        let mut count0 = vec![0usize; nx * ny + 1];
        let id = |e: &Edge, a: i32, l: i32| {
            let (bx, by) = if e.normal.is_vertical_edge() {
                (l, a)
            } else {
                (a, l)
            };
            by.clamp(0, ny as i32 - 1) as usize * nx + bx.clamp(0, nx as i32 - 1) as usize
        };
        for e in &g.edges {
            let (a0, a1, l) = blocks_of(e);
            for a in a0..=a1 {
                count0[id(e, a, l) + 1] += 1;
            }
        }
        for i in 0..nx * ny {
            count0[i + 1] += count0[i];
        }
        let start = count0.clone();
        let mut fill = count0;
        let mut list = vec![0u32; start[nx * ny]];
        const EMPTY: [i32; 4] = [i32::MAX, i32::MAX, i32::MIN, i32::MIN];
        let grow = |o: &mut [i32; 4], k: [i32; 4]| {
            *o = [
                o[0].min(k[0]),
                o[1].min(k[1]),
                o[2].max(k[2]),
                o[3].max(k[3]),
            ];
        };
        let mut boxes = vec![vec![EMPTY; nx * ny]];
        for (ei, e) in g.edges.iter().enumerate() {
            let (a0, a1, l) = blocks_of(e);
            let (lo, hi) = e.extent();
            let line = e.line() as i32;
            for a in a0..=a1 {
                let b = id(e, a, l);
                list[fill[b]] = ei as u32;
                fill[b] += 1;
                let (s0, s1) = ((lo as i32).max(a * size), (hi as i32).min((a + 1) * size));
                let part = if e.normal.is_vertical_edge() {
                    [line, s0, line, s1]
                } else {
                    [s0, line, s1, line]
                };
                grow(&mut boxes[0][b], part);
            }
        }
        let mut dims = vec![(nx, ny)];
        while dims.last().is_some_and(|&(x, y)| x > 1 || y > 1) {
            let (px, py) = *dims.last().expect("non-empty");
            let (cx, cy) = (px.div_ceil(2), py.div_ceil(2));
            let prev = boxes.last().expect("non-empty");
            let mut up = vec![EMPTY; cx * cy];
            for y in 0..py {
                for x in 0..px {
                    grow(&mut up[(y / 2) * cx + x / 2], prev[y * px + x]);
                }
            }
            dims.push((cx, cy));
            boxes.push(up);
        }
        Blocks {
            edges: &g.edges,
            size,
            dims,
            boxes,
            start,
            list,
        }
    }
}
/// The edges with light that a point may want farther than a radius, for
/// [`Sweeper::walk_wanted`]: past the radius, a walk only needs the
/// directions in which one of them lies. Anything else there is beyond its
/// own reach, and what it hides lies farther along the same directions, so
/// it is beyond its reach too; leaving those directions unwalked changes no
/// span that is wanted. Where every edge's reach is long (a level of long
/// walls, or form factors at a unit of radiosity), this finds nothing to
/// close and is not built.
///
/// An edge is listed when its reach plus its length exceeds the radius (it
/// may be wanted from a point and have a part farther than the radius).
/// Listed edges are grouped by the [`FarWanted::GROUP`] square their
/// middle lies in (or a square 2, 4 or 8 times as wide, where the lists
/// would be too long): a group is the box around its edges and the longest
/// of their reaches, and its directions from a point cover theirs. Each group is listed under every
/// cell (as wide as the radius) that has points within its reach.
pub struct FarWanted {
    radius: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    groups: Vec<Group>,
    start: Vec<u32>,
    list: Vec<u32>,
    /// Pseudo-angle by which each group's directions are widened on both
    /// sides ([`FarWanted::widened`]).
    widen: f64,
}

/// Listed edges of one block: the box around them (`x0, y0, x1, y1`) and
/// the longest of their reaches, rounded up.
#[derive(Clone, Copy)]
struct Group {
    bbox: [f64; 4],
    reach: f64,
}

impl Group {
    /// The cells of `cell` px (`nx` by `ny`) whose points the group may
    /// reach: columns and rows.
    fn cells(
        &self,
        cell: f64,
        nx: usize,
        ny: usize,
    ) -> (
        std::ops::RangeInclusive<usize>,
        std::ops::RangeInclusive<usize>,
    ) {
        let c = |v: f64, n: usize| cell_of(v, cell, n);
        let [x0, y0, x1, y1] = self.bbox;
        let r = self.reach;
        (c(x0 - r, nx)..=c(x1 + r, nx), c(y0 - r, ny)..=c(y1 + r, ny))
    }

    /// How many cells [`Group::cells`] holds.
    fn cell_count(&self, cell: f64, nx: usize, ny: usize) -> usize {
        let (xs, ys) = self.cells(cell, nx, ny);
        (xs.end() + 1 - xs.start()) * (ys.end() + 1 - ys.start())
    }
}

impl FarWanted {
    /// Side of a cell, in painted pixels; the radius is one cell.
    pub const CELL: i32 = 32;
    /// Side of the squares whose edges are grouped, in pixels: the box of
    /// a group covers little more than its edges (one one-pixel dot), and
    /// the lists are several times shorter than lists of edges.
    pub const GROUP: f64 = 2.0;
    /// A point whose cell lists more groups than this walks everywhere:
    /// reading their directions would cost more than the walk saves.
    pub const MOST: usize = 256;
    /// Narrower cells, in painted pixels, tried before [`FarWanted::CELL`]:
    /// the narrower the radius, the less of the view a walk resolves
    /// everywhere.
    pub const NARROW: [i32; 2] = [8, 16];
    /// A narrower cell is taken when at most one edge with light in this
    /// many is listed for it: most of what a point wants then lies within
    /// the radius, and few directions are open past it. (On the dots most
    /// light fades within a few pixels: 8 px; the pillar field and the real
    /// maps, with many edges reaching farther, keep 32 px.)
    pub const LISTED: usize = 16;
    /// A walk reads its point's list only once it has inserted, past the
    /// radius, this many edges per group listed: most walks in wall noise
    /// close within a few blocks past the radius, and reading ~160 groups
    /// cost its gather a fifth of its time, while a walk on the dots runs
    /// down open rows for hundreds of pixels unless it reads them. Measured
    /// (docs/performance.md, twenty-ninth pass): 0.25 / 0.5 / 1 took wall
    /// noise at 30 %'s gather from 1.47 s to 1.25 / 1.18 / 1.15 s (1.13 s
    /// never reading), the 640 px dots from 35.2 s to 36.4 / 36.9 / 38.8 s.
    pub const LAZY: f64 = 0.5;

    /// For the squared reaches `reach2` of `g`'s edges (negative: no
    /// light), with the narrowest cell of [`FarWanted::NARROW`] for which
    /// few edges are listed (else [`FarWanted::CELL`]); `None` when the
    /// lists would hold more entries than [`FarWanted::MOST`] per cell on
    /// average even with the coarsest groups: most points would walk
    /// everywhere anyway.
    pub fn new(g: &Geometry, reach2: &[f64]) -> Option<FarWanted> {
        let lit = reach2.iter().filter(|&&r2| r2 >= 0.0).count();
        let unit = g.unit.max(1) as i32;
        let listed = |radius: f64| {
            g.edges
                .iter()
                .zip(reach2)
                .filter(|&(e, &r2)| Self::listed(e, r2, radius))
                .count()
        };
        let cell = Self::NARROW
            .into_iter()
            .find(|&c| listed((c * unit) as f64) * Self::LISTED <= lit)
            .unwrap_or(Self::CELL);
        Self::with_cell(g, reach2, cell)
    }

    /// [`FarWanted::new`] with cells (and radius) of `cell` painted pixels.
    pub fn with_cell(g: &Geometry, reach2: &[f64], cell: i32) -> Option<FarWanted> {
        Self::with_cell_of(g, reach2, cell, None)
    }

    /// [`FarWanted::with_cell`], listing only the edges marked in `only`
    /// (if given) of those it would list.
    pub fn with_cell_of(
        g: &Geometry,
        reach2: &[f64],
        cell: i32,
        only: Option<&[bool]>,
    ) -> Option<FarWanted> {
        let cell = (cell * g.unit.max(1) as i32) as f64;
        let nx = (g.width as f64 / cell).ceil().max(1.0) as usize;
        let ny = (g.height as f64 / cell).ceil().max(1.0) as usize;
        // Squares of GROUP px, or coarser where their lists would be too
        // long (many edges reaching far: coarser boxes, fewer of them).
        (0..4).find_map(|k| {
            let side = Self::GROUP * (1 << k) as f64 * g.unit.max(1) as f64;
            let groups = Self::groups(g, reach2, only, cell, side, nx, ny)?;
            let (start, list) = Self::lists(&groups, cell, nx, ny);
            Some(FarWanted {
                radius: cell,
                cell,
                nx,
                ny,
                groups,
                start,
                list,
                widen: 0.0,
            })
        })
    }

    /// The same lists, with each group's directions from a point widened
    /// by `angle` radians on both sides: past the radius a walk then also
    /// finds what hides a listed edge from any point within `angle` of the
    /// walking one as seen from the edge's side (within `radius * sin
    /// angle` of it, for what lies past the radius). The diamond
    /// pseudo-angle changes by at most a radian per radian, so widening
    /// it by `angle` covers the angle.
    pub fn widened(self, angle: f64) -> FarWanted {
        FarWanted {
            widen: angle.max(0.0),
            ..self
        }
    }

    /// Whether an edge of squared reach `r2` is listed for `radius`: it has
    /// light, and its reach plus its length exceeds the radius.
    fn listed(e: &Edge, r2: f64, radius: f64) -> bool {
        r2 >= 0.0 && r2.sqrt() + e.len() > radius
    }

    /// The radius, in pixels of the level: past it only the directions of
    /// listed edges are walked.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The listed edges of `g` (reach plus length past `radius`) grouped
    /// by the `side` px square their middle lies in; `None` as soon as the
    /// groups found so far would list more than [`FarWanted::MOST`] entries
    /// per cell of `radius` px (`nx` by `ny`) on average. A group's cells
    /// only grow as edges join it, so the count so far is a lower bound of
    /// what [`FarWanted::lists`] would count: where every edge reaches far
    /// (wall noise's form factors at a unit of radiosity), the edges seen
    /// so far say so, without a pass over all of them per try.
    fn groups(
        g: &Geometry,
        reach2: &[f64],
        only: Option<&[bool]>,
        radius: f64,
        side: f64,
        nx: usize,
        ny: usize,
    ) -> Option<Vec<Group>> {
        let (bx, by) = (
            (g.width as f64 / side).ceil().max(1.0) as usize,
            (g.height as f64 / side).ceil().max(1.0) as usize,
        );
        let mut of_square: Vec<u32> = vec![u32::MAX; bx * by];
        let mut groups: Vec<Group> = Vec::new();
        let (mut entries, budget) = (0usize, Self::MOST * nx * ny);
        for (i, (e, &r2)) in g.edges.iter().zip(reach2).enumerate() {
            if !Self::listed(e, r2, radius) || only.is_some_and(|o| !o[i]) {
                continue;
            }
            let (x0, x1) = (e.a[0].min(e.b[0]) as f64, e.a[0].max(e.b[0]) as f64);
            let (y0, y1) = (e.a[1].min(e.b[1]) as f64, e.a[1].max(e.b[1]) as f64);
            let b = cell_of(0.5 * (y0 + y1), side, by) * bx + cell_of(0.5 * (x0 + x1), side, bx);
            let reach = r2.sqrt() + 1.0;
            if of_square[b] == u32::MAX {
                of_square[b] = groups.len() as u32;
                let gr = Group {
                    bbox: [x0, y0, x1, y1],
                    reach,
                };
                entries += gr.cell_count(radius, nx, ny);
                groups.push(gr);
            } else {
                let gr = &mut groups[of_square[b] as usize];
                entries -= gr.cell_count(radius, nx, ny);
                gr.bbox = [
                    gr.bbox[0].min(x0),
                    gr.bbox[1].min(y0),
                    gr.bbox[2].max(x1),
                    gr.bbox[3].max(y1),
                ];
                gr.reach = gr.reach.max(reach);
                entries += gr.cell_count(radius, nx, ny);
            }
            if entries > budget {
                return None;
            }
        }
        Some(groups)
    }

    /// Per cell of `cell` px (`nx` by `ny`), the groups whose reach has
    /// points in it (CSR starts and list).
    fn lists(groups: &[Group], cell: f64, nx: usize, ny: usize) -> (Vec<u32>, Vec<u32>) {
        let cells = |gr: &Group| gr.cells(cell, nx, ny);
        let mut start = vec![0u32; nx * ny + 1];
        for gr in groups {
            let (xs, ys) = cells(gr);
            for y in ys {
                for x in xs.clone() {
                    start[y * nx + x + 1] += 1;
                }
            }
        }
        for i in 0..nx * ny {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut list = vec![0u32; start[nx * ny] as usize];
        for (gi, gr) in groups.iter().enumerate() {
            let (xs, ys) = cells(gr);
            for y in ys {
                for x in xs.clone() {
                    let c = y * nx + x;
                    list[fill[c] as usize] = gi as u32;
                    fill[c] += 1;
                }
            }
        }
        (start, list)
    }

    /// The groups listed under the cell of `p`.
    fn at(&self, p: [f64; 2]) -> &[u32] {
        let i = cell_of(p[1], self.cell, self.ny) * self.nx + cell_of(p[0], self.cell, self.nx);
        &self.list[self.start[i] as usize..self.start[i + 1] as usize]
    }
}

/// Per edge, the squared distance within which its spans are wanted
/// (negative: the edge has no light), for [`crate::visibility::for_each_visibility_counted`],
/// with the [`FarWanted`] built from it on the first walk and then kept:
/// the passes of a gather, which share one `Reaches`, build it once.
pub struct Reaches<'a> {
    /// Squared reach per edge.
    pub squared: &'a [f64],
    /// See [`Wanted::cosine`].
    pub cosine: Option<f64>,
    /// With [`Reaches::closing`] or [`Reaches::listing`]: the radius of
    /// its [`FarWanted`], the angle its directions are widened by and the
    /// edges it lists.
    only: Option<(i32, f64, &'a [bool])>,
    /// Whether the spans are filtered by reach ([`Reaches::filters`]).
    filtering: bool,
    far: OnceLock<Option<FarWanted>>,
}

impl<'a> Reaches<'a> {
    /// Nothing built yet.
    pub fn new(squared: &'a [f64]) -> Reaches<'a> {
        Reaches {
            squared,
            cosine: None,
            only: None,
            filtering: true,
            far: OnceLock::new(),
        }
    }

    /// [`Reaches::new`], whose [`FarWanted`] lists only the edges marked
    /// in `listed` and has a radius of `radius` painted pixels.
    pub fn listing(squared: &'a [f64], listed: &'a [bool], radius: i32) -> Reaches<'a> {
        Reaches {
            only: Some((radius, 0.0, listed)),
            ..Reaches::new(squared)
        }
    }

    /// Reaches that only close the directions of a walk past `radius`
    /// painted pixels ([`FarWanted::with_cell_of`]) where no edge marked in
    /// `listed` and with light in `squared` lies, widened by `angle`
    /// radians ([`FarWanted::widened`]): every span visible within the
    /// radius is returned, lit or not, and past it every span in those
    /// directions.
    pub fn closing(squared: &'a [f64], listed: &'a [bool], radius: i32, angle: f64) -> Reaches<'a> {
        Reaches {
            only: Some((radius, angle, listed)),
            filtering: false,
            ..Reaches::new(squared)
        }
    }

    /// Whether the spans are filtered by reach ([`Wanted`]): not with
    /// [`Reaches::closing`].
    pub fn filters(&self) -> bool {
        self.filtering
    }

    /// [`Reaches::new`] for half views whose light carries their cosine,
    /// for reaches found with falloff constant `a` ([`Wanted::cosine`]).
    pub fn receiving(squared: &'a [f64], a: f64) -> Reaches<'a> {
        Reaches {
            cosine: Some(a),
            ..Reaches::new(squared)
        }
    }

    /// Builds the [`FarWanted`] of `g`'s edges now, instead of on the first
    /// walk while the other workers wait for it (several ms on one core
    /// for the gather of wall noise at 512 px).
    pub fn prepare(&self, g: &Geometry) {
        self.far(g);
    }

    /// The edges a point of `g` may want past [`FarWanted`]'s radius, if
    /// they are worth listing.
    pub(super) fn far(&self, g: &Geometry) -> Option<&FarWanted> {
        self.far
            .get_or_init(|| match self.only {
                None => FarWanted::new(g, self.squared),
                Some((radius, angle, listed)) => {
                    FarWanted::with_cell_of(g, self.squared, radius, Some(listed))
                        .map(|f| f.widened(angle))
                }
            })
            .as_ref()
    }
}

impl Sweeper {
    /// The directions from `q` in which an edge of `far` is wanted and has
    /// a part farther than its radius, merged into [`Sweeper::open`], and
    /// that radius; `None` when they are most of the view, or too many to
    /// read, and the walk goes on everywhere.
    fn open_directions(&mut self, far: &FarWanted, q: &Query, cosine: Option<f64>) -> Option<f64> {
        let list = far.at(q.p);
        if list.len() > FarWanted::MOST {
            return None;
        }
        let d2 = far.radius * far.radius;
        self.open.clear();
        let p = q.p;
        for &gi in list {
            let gr = &far.groups[gi as usize];
            let [x0, y0, x1, y1] = gr.bbox;
            let (near2, r2) = (box_distance_sq(p, x0, y0, x1, y1), gr.reach * gr.reach);
            if near2 > r2 {
                continue;
            }
            // A half view's cosine may leave the whole group below the
            // bound (its least distance, longest reach and largest cosine
            // stand for each of its edges: see `receiver_keeps`).
            if cosine.is_some_and(|a| {
                !q.receives(&[[x0, y0], [x1, y0], [x0, y1], [x1, y1]], a, near2, r2)
            }) {
                continue;
            }
            // Its farthest point is a corner.
            let fx = (x0 - p[0]).abs().max((x1 - p[0]).abs());
            let fy = (y0 - p[1]).abs().max((y1 - p[1]).abs());
            if fx * fx + fy * fy <= d2 {
                continue;
            }
            match box_range(q, x0, y0, x1, y1) {
                BoxView::Around => return None,
                BoxView::Behind => {}
                BoxView::Ranges([r0, r1]) => {
                    let w = far.widen;
                    for (i, (a, b)) in [r0, r1].into_iter().enumerate() {
                        if i == 1 && r1 == r0 {
                            break;
                        }
                        let (a, b) = (a - w, b + w);
                        // Widened past the cut ray, a full view's range
                        // wraps; a half view's stops at its ends.
                        let kmax = q.kmax();
                        self.open.push((a.max(0.0), b.min(kmax)));
                        if q.full && a < 0.0 {
                            self.open.push((kmax + a, kmax));
                        }
                        if q.full && b > kmax {
                            self.open.push((0.0, b - kmax));
                        }
                    }
                }
            }
        }
        self.open.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let mut merged = 0;
        for i in 0..self.open.len() {
            let iv = self.open[i];
            if merged > 0 && iv.0 <= self.open[merged - 1].1 {
                self.open[merged - 1].1 = self.open[merged - 1].1.max(iv.1);
            } else {
                self.open[merged] = iv;
                merged += 1;
            }
        }
        self.open.truncate(merged);
        // Mostly open: testing every block costs more than it skips.
        let open: f64 = self.open.iter().map(|iv| iv.1 - iv.0).sum();
        (open < 0.9 * q.kmax()).then_some(far.radius)
    }

    /// Whether every open direction in `[a, b]` (each widened by a margin
    /// for rounding) already hits something nearer than `dmin`; true when
    /// `[a, b]` meets none.
    fn open_parts_hidden(&mut self, a: f64, b: f64, dmin: f64) -> bool {
        const MARGIN: f64 = 1e-9;
        let mut i = self.open.partition_point(|iv| iv.1 < a - MARGIN);
        while let Some(&(oa, ob)) = self.open.get(i) {
            if oa > b + MARGIN {
                break;
            }
            let (lo, hi) = (a.max(oa - MARGIN), b.min(ob + MARGIN));
            if !self.cover.hides(lo, hi, dmin) {
                return false;
            }
            i += 1;
        }
        true
    }

    /// Adds edge `ei`'s visible pieces to the coverage, once per walk
    /// (each piece on its own, without silhouettes).
    #[cfg(test)]
    fn insert_edge(&mut self, q: &Query, edges: &[Edge], ei: u32) {
        if !self.inserted.insert(ei as usize) {
            return;
        }
        let from = self.pieces.len();
        q.pieces(edges, ei, &mut self.pieces);
        for pi in from..self.pieces.len() {
            self.cover.insert(&self.pieces, pi as u32, q.p);
        }
    }

    /// The same result as [`Sweeper::sweep`] over all edges within
    /// `reach_max`, found by walking `blocks` from near to far and skipping
    /// what is already hidden. (Each walk starts from an empty coverage:
    /// seeding it with the edges the previous point saw made every class
    /// of level slower, measured in docs/performance.md.)
    pub fn walk(&mut self, blocks: &Blocks, at: Viewpoint, reach_max: f64, out: &mut Vec<Span>) {
        self.walk_wanted(blocks, at, reach_max, None, None, out);
    }

    /// [`Sweeper::walk`], returning only the spans `wanted`; returns how
    /// many spans of edges with light it left out. With `far` (built for
    /// the same reaches as `wanted`), blocks farther than its radius are
    /// walked only in the directions of the edges it lists as wanted from
    /// the point, once the walk has gone past the radius for a while
    /// ([`FarWanted::LAZY`]): the spans are the same, and the spans left
    /// out that lie in the other directions past the radius are not
    /// counted from then on.
    pub fn walk_wanted(
        &mut self,
        blocks: &Blocks,
        at: Viewpoint,
        reach_max: f64,
        wanted: Option<Wanted>,
        far: Option<&FarWanted>,
        out: &mut Vec<Span>,
    ) -> u64 {
        let (edges, p) = (blocks.edges, at.p);
        let q = Query::new(at);
        self.pieces.clear();
        self.cover.reset(q.kmax());
        self.inserted.clear(edges.len());
        // The far directions are read only once the walk has inserted, past
        // the radius, edges in proportion to the groups it would read: this
        // many more.
        let mut reading = far.map(|far| {
            let cosine = wanted.and_then(|w| w.cosine);
            (far, cosine, FarWanted::LAZY * far.at(p).len() as f64)
        });
        let mut closed_past = None;
        let top = blocks.dims.len() - 1;
        self.stack.clear();
        self.stack.push((top as u8, 0, 0));
        while let Some((level, x, y)) = self.stack.pop() {
            let (nx, _) = blocks.dims[level as usize];
            let node = y as usize * nx + x as usize;
            let [x0, y0, x1, y1] = blocks.boxes[level as usize][node];
            if x0 > x1 {
                // No edges.
                continue;
            }
            let [x0, y0, x1, y1] = [x0, y0, x1, y1].map(f64::from);
            let side = (blocks.size << level) as f64;
            // How far the node's square is: when to read the far
            // directions was measured by it ([`FarWanted::LAZY`]). (Defined
            // here rather than where it is read: the walk ran 17 % slower
            // on the corridors with it there, the same work laid out
            // differently by the compiler.)
            let square = || {
                let (sx, sy) = (x as f64 * side, y as f64 * side);
                box_distance_sq(p, sx, sy, sx + side, sy + side).sqrt()
            };
            let dmin = box_distance_sq(p, x0, y0, x1, y1).sqrt();
            if dmin > reach_max || self.cover.closed_before(dmin) {
                continue;
            }
            match box_range(&q, x0, y0, x1, y1) {
                BoxView::Around => {}
                BoxView::Behind => continue,
                BoxView::Ranges(ranges) => {
                    // Past the radius only the open directions count: the
                    // closed ones are never walked there, so the coverage
                    // stays empty in them and would keep every block open.
                    // (A node whose edges all lie past it, whatever its
                    // square, is tested so too.)
                    let hidden = if closed_past.is_some_and(|d| dmin > d) {
                        ranges
                            .iter()
                            .all(|&(a, b)| self.open_parts_hidden(a, b, dmin))
                    } else {
                        ranges.iter().all(|&(a, b)| self.cover.hides(a, b, dmin))
                    };
                    if hidden {
                        continue;
                    }
                }
            }
            if level == 0 {
                let b = node;
                if let Some((far, cosine, left)) = &mut reading
                    && square() > far.radius
                {
                    *left -= (blocks.start[b + 1] - blocks.start[b]) as f64;
                    if *left <= 0.0 {
                        closed_past = self.open_directions(far, &q, *cosine);
                        reading = None;
                    }
                }
                self.insert_block(
                    &q,
                    edges,
                    &blocks.list[blocks.start[b]..blocks.start[b + 1]],
                );
                continue;
            }
            // Children, nearest popped first.
            let (cnx, cny) = blocks.dims[level as usize - 1];
            let mut kids: [(f64, u32, u32); 4] = [(f64::INFINITY, 0, 0); 4];
            let mut k = 0;
            for (cx, cy) in [
                (2 * x, 2 * y),
                (2 * x + 1, 2 * y),
                (2 * x, 2 * y + 1),
                (2 * x + 1, 2 * y + 1),
            ] {
                if (cx as usize) < cnx && (cy as usize) < cny {
                    let half = side / 2.0;
                    let (mx, my) = ((cx as f64 + 0.5) * half, (cy as f64 + 0.5) * half);
                    kids[k] = ((mx - p[0]).powi(2) + (my - p[1]).powi(2), cx, cy);
                    k += 1;
                }
            }
            kids[..k].sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
            for &(_, cx, cy) in &kids[..k] {
                self.stack.push((level - 1, cx, cy));
            }
        }
        // Read the spans off the buffer (intervals of one owner are merged;
        // a silhouette's, cut at its corner, are its two pieces').
        let cover = &self.cover;
        let mut left_out = 0;
        let mut read = |piece: u32, from: (f64, [f64; 2]), to: (f64, [f64; 2])| {
            let pc = &self.pieces[piece as usize];
            let (lit, dim) = wanted.map_or((pc.lit, pc.dim), |w| w.at(edges, pc.edge, None, &q));
            if lit {
                self.emit(edges, p, piece, from, to, out);
            } else {
                left_out += u64::from(dim);
            }
        };
        for i in 0..cover.iv.len() {
            let o = cover.iv[i].owner;
            if o == NONE {
                continue;
            }
            let pc = &self.pieces[o as usize];
            let (k0, k1) = (cover.start(i), cover.iv[i].end);
            let v0 = if i == 0 {
                pc.va
            } else {
                vertex(&self.pieces, cover.iv[i - 1].vend)
            };
            let v1 = vertex(&self.pieces, cover.iv[i].vend);
            if !pc.silhouette {
                read(o, (k0, v0), (k1, v1));
                continue;
            }
            let (corner, at) = (pc.c, self.pieces[o as usize - 2].vb);
            if k0 < corner {
                let to = if k1 <= corner { (k1, v1) } else { (corner, at) };
                read(o - 2, (k0, v0), to);
            }
            if k1 > corner {
                let from = if k0 >= corner { (k0, v0) } else { (corner, at) };
                read(o - 1, from, (k1, v1));
            }
        }
        left_out
    }

    /// Adds the visible pieces of a block's edges `list` to the coverage
    /// (each edge once per walk), taking two pieces that meet at a
    /// pillar's corner as one silhouette ([`silhouette`]), as sweeps do:
    /// the block lists a pillar's edges one after the other. A piece that
    /// is an edge's only one waits for the next edge's before it is
    /// inserted.
    fn insert_block(&mut self, q: &Query, edges: &[Edge], list: &[u32]) {
        let mut waiting: Option<usize> = None;
        for &ei in list {
            if !self.inserted.insert(ei as usize) {
                continue;
            }
            let from = self.pieces.len();
            q.pieces(edges, ei, &mut self.pieces);
            if self.pieces.len() == from {
                // Facing away (a pillar's other edges, between the two
                // that face the point).
                continue;
            }
            let single = self.pieces.len() == from + 1 && !self.no_silhouettes;
            if let Some(w) = waiting.take() {
                let pair = single
                    .then(|| silhouette(edges, q, &self.pieces[w], &self.pieces[from]))
                    .flatten();
                if let Some((m, swapped)) = pair {
                    // The two pieces before the silhouette, in order
                    // (nothing was cut in between: `w` is the last piece).
                    debug_assert_eq!(w + 1, from);
                    if swapped {
                        self.pieces.swap(w, from);
                    }
                    self.silhouettes += 1;
                    self.pieces.push(m);
                    self.cover.insert(&self.pieces, from as u32 + 1, q.p);
                    continue;
                }
                self.cover.insert(&self.pieces, w as u32, q.p);
            }
            if single {
                waiting = Some(from);
                continue;
            }
            for pi in from..self.pieces.len() {
                self.cover.insert(&self.pieces, pi as u32, q.p);
            }
        }
        if let Some(w) = waiting {
            self.cover.insert(&self.pieces, w as u32, q.p);
        }
    }

    pub(super) fn emit(
        &self,
        edges: &[Edge],
        p: [f64; 2],
        piece: u32,
        (k0, v0): (f64, [f64; 2]),
        (k1, v1): (f64, [f64; 2]),
        out: &mut Vec<Span>,
    ) {
        let pc = &self.pieces[piece as usize];
        let e = &edges[pc.edge as usize];
        let (a, b) = (pc.axis_at(e, p, k0, v0), pc.axis_at(e, p, k1, v1));
        let (s0, s1) = if a <= b { (a, b) } else { (b, a) };
        if s1 > s0 {
            out.push(Span {
                edge: pc.edge,
                s0,
                s1,
                k0,
                k1,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The search from a hint finds what a plain binary search finds, from
    /// every hint, for keys before, between, on and after the ends.
    #[test]
    fn find_from_any_hint_agrees_with_a_binary_search() {
        let mut c = Coverage::default();
        for n in [1usize, 2, 3, 7, 40] {
            c.iv = (1..=n)
                .map(|i| Iv {
                    end: i as f64 * 0.1,
                    vend: NONE,
                    owner: NONE,
                    far: f64::INFINITY,
                })
                .collect();
            for hint in 0..=n + 2 {
                for step in 0..=(2 * n + 4) {
                    let k = step as f64 * 0.05 - 0.05;
                    c.hint = hint;
                    let want = c.iv.partition_point(|v| v.end <= k);
                    assert_eq!(c.find(k), want, "n {n}, hint {hint}, k {k}");
                    assert_eq!(c.hint, want);
                }
            }
        }
    }

    /// A room `side` px square with a wall all round and one-pixel dots
    /// scattered in it, traced.
    fn dotted_room(side: usize, seed: u64) -> Geometry {
        use crate::level::{Cell, Level};
        use crate::{Material, MaterialKind};
        let cells = (0..side * side)
            .map(|i| {
                let (x, y) = (i % side, i / side);
                let h = (i as u64 ^ seed).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 58;
                let border = x == 0 || y == 0 || x == side - 1 || y == side - 1;
                if border || (x % 2 == 1 && y % 2 == 1 && h < 12) {
                    Cell::Solid(0)
                } else {
                    Cell::Floor
                }
            })
            .collect();
        let wall = Material {
            color: [128; 3],
            kind: MaterialKind::Wall,
            reflectance: [0.5; 3],
            emission: [0.0; 3],
            group: None,
            line: None,
        };
        crate::geometry::trace(&Level {
            name: "dots".into(),
            width: side,
            height: side,
            cells,
            albedo: vec![[0.5; 3]; side * side],
            materials: vec![wall],
            warnings: vec![],
            lossy_format: None,
            origin: Default::default(),
            floor_fraction: None,
        })
    }

    /// The blocks' boxes hold what the walk may skip by them: every unit
    /// of every edge lies in the box of a block that lists the edge, and
    /// every box in the box above it.
    #[test]
    fn every_edge_lies_in_the_boxes_that_list_it() {
        let g = dotted_room(45, 3);
        let blocks = Blocks::new(&g);
        let within = |b: [i32; 4], [x0, y0, x1, y1]: [i32; 4]| {
            b[0] <= x0 && b[1] <= y0 && x1 <= b[2] && y1 <= b[3]
        };
        let mut blocks_of_edge = vec![Vec::new(); g.edges.len()];
        for b in 0..blocks.boxes[0].len() {
            for &ei in &blocks.list[blocks.start[b]..blocks.start[b + 1]] {
                blocks_of_edge[ei as usize].push(b);
            }
        }
        let mut units = 0;
        for (ei, e) in g.edges.iter().enumerate() {
            let (lo, hi) = e.extent();
            let line = e.line() as i32;
            for s in lo as i32..hi as i32 {
                let unit = if e.normal.is_vertical_edge() {
                    [line, s, line, s + 1]
                } else {
                    [s, line, s + 1, line]
                };
                assert!(
                    blocks_of_edge[ei]
                        .iter()
                        .any(|&b| within(blocks.boxes[0][b], unit)),
                    "edge {ei}: the unit at {s} is in no box that lists it"
                );
                units += 1;
            }
        }
        for level in 1..blocks.dims.len() {
            let (nx, ny) = blocks.dims[level - 1];
            let up = blocks.dims[level].0;
            for y in 0..ny {
                for x in 0..nx {
                    let child = blocks.boxes[level - 1][y * nx + x];
                    if child[0] <= child[2] {
                        assert!(within(blocks.boxes[level][(y / 2) * up + x / 2], child));
                    }
                }
            }
        }
        // The wall all round (172 units) and the dots' four each.
        assert!(units > 400, "{units}");
    }

    /// Through every insertion of a walk (edges near to far, then far to
    /// near), the coverage's count of open intervals is theirs, and once
    /// none is open its bound is at least every owner's farthest distance:
    /// so that [`Coverage::closed_before`] only skips what
    /// [`Coverage::hides`] would hide, over the whole view.
    #[test]
    fn a_closed_coverage_bounds_every_owner() {
        let g = dotted_room(24, 5);
        let mut sw = Sweeper::new();
        let (mut checked, mut closed) = (0, 0);
        for y in (1..23).step_by(3) {
            for x in (1..23).step_by(2) {
                let Some(comp) = g.component_at(x, y) else {
                    continue;
                };
                let p = [x as f64 + 0.5, y as f64 + 0.5];
                let q = Query::new(Viewpoint::new(p, View::Full, comp));
                let mut order: Vec<u32> = (0..g.edges.len() as u32).collect();
                order.sort_by(|&a, &b| {
                    let d = |e: u32| g.edges[e as usize].distance_sq(p);
                    d(a).total_cmp(&d(b))
                });
                for reversed in [false, true] {
                    if reversed {
                        order.reverse();
                    }
                    sw.pieces.clear();
                    sw.cover.reset(q.kmax());
                    sw.inserted.clear(g.edges.len());
                    for &ei in &order {
                        sw.insert_edge(&q, &g.edges, ei);
                        let c = &mut sw.cover;
                        let open = c.iv.iter().filter(|v| v.owner == NONE).count();
                        assert_eq!(c.open, open, "{p:?}");
                        checked += 1;
                        if open > 0 {
                            assert!(!c.closed_before(f64::MAX));
                            continue;
                        }
                        closed += 1;
                        let far = c.iv.iter().map(|v| v.far).fold(0.0, f64::max);
                        assert!(c.far_bound >= far, "{p:?}: {} < {far}", c.far_bound);
                        let past = c.far_bound * (1.0 + 1e-12) + 1e-12;
                        assert!(c.closed_before(past));
                        assert!(c.hides(0.0, q.kmax(), past), "{p:?}");
                        assert!(!c.closed_before(far * 0.5));
                    }
                }
            }
        }
        // Both states are reached, many times each.
        assert!(
            closed > 100 && checked > 2 * closed,
            "{closed} of {checked}"
        );
    }
}
