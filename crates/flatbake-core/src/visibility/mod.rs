//! Exact visibility in flatland.
//!
//! A query point sees, in each direction, the first edge that a ray from it
//! hits. Both query methods here return that exactly, as [`Span`]s: which
//! stretch of which edge is the first hit over which range of directions.
//!
//! * [`Sweeper::sweep`] is an angular sweep over a short candidate list.
//!   Between two consecutive endpoint directions the set of edges crossed by a
//!   ray does not change, and because edges never cross, the nearest of them
//!   is the same over the whole interval; it is found at the interval's
//!   middle, so rays that graze a vertex never need a tie-break.
//! * [`Sweeper::walk`] is output-sensitive, for places that see little of
//!   many edges (mazes, walls with gaps): it walks a hierarchy of blocks of
//!   edges from near to far, keeps a one-dimensional angular buffer of what is
//!   already covered and by what, and skips every block whose whole angular
//!   range is covered by surfaces nearer than the block. Many short walls
//!   together hide what is behind them ("occluder fusion") for free.
//!
//! Interval boundaries are always rays through edge endpoints, so two edges
//! that share a corner (including two diagonal wall pixels touching at a
//! corner) produce bit-identical boundary directions: no light leaks through
//! corners. Directions are ordered with a pseudo-angle (the "diamond angle"),
//! monotone in the true angle and needing one division instead of an `atan2`.
//!
//! [`TileTree`] gives every free region of every 8x8 tile a conservative list
//! of candidate edges, refined down a quadtree: an edge is dropped only when
//! that is proven — it faces away from the whole region, its free side
//! belongs to another region of free space, it lies beyond the falloff reach,
//! or one straight wall run ([`run_hides`]) or one rectangle of solid pixels
//! ([`box_hides`]) blocks every segment from the region to it (exact tests in
//! integer arithmetic). For a floor gather the region is its pixel centres,
//! for form factors its whole pixels ([`Zone`]). Regions whose list stays
//! long use the walk instead of the sweep.

pub mod marks;

use crate::geometry::{Edge, Geometry, Normal, Run};
use crate::visibility::marks::Marks;

/// Which directions a query point looks into.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum View {
    /// All directions (a floor pixel).
    Full,
    /// The open half-plane in front of a normal (a point on an edge).
    Half(Normal),
}

/// A visible part of an edge: edge `edge` is the first thing hit by every ray
/// whose direction lies strictly between the rays to the points at axis
/// coordinates `s0` and `s1` of that edge (`s0 < s1`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    pub edge: u32,
    pub s0: f64,
    pub s1: f64,
    /// Pseudo-angles of the span's boundaries as seen from the query point.
    pub k0: f64,
    pub k1: f64,
}

/// A front-facing edge (or the part of it on one side of the cut ray) as
/// seen from the query point.
#[derive(Clone, Copy, Debug)]
struct Piece {
    edge: u32,
    /// In local coordinates the piece lies on `u = c` (if `u_const`) or `v = c`.
    u_const: bool,
    c: f64,
    /// Pseudo-angles of its ends (`ka < kb`), their axis coordinates on the
    /// edge and their global positions.
    ka: f64,
    kb: f64,
    sa: f64,
    sb: f64,
    va: [f64; 2],
    vb: [f64; 2],
    /// Its spans are wanted (see [`Wanted`]); when not, `dim` says that its
    /// edge has light, only too far away to matter here.
    lit: bool,
    dim: bool,
}

impl Piece {
    /// Ray parameter of the piece's line along local direction `(du, dv)`.
    #[inline]
    fn t(&self, du: f64, dv: f64) -> f64 {
        if self.u_const {
            self.c / du
        } else {
            self.c / dv
        }
    }

    /// [`Piece::t`] times a positive factor that depends on the ray only:
    /// `|c| su` for a piece on `u = c`, `|c| sv` else. With `(su, sv) =
    /// (|dv|, |du|)` that is `t |du| |dv|` (for a ray that hits the piece in
    /// front, `c` has the sign of `du`, or of `dv`).
    #[inline]
    fn t_scaled(&self, su: f64, sv: f64) -> f64 {
        self.c.abs() * if self.u_const { su } else { sv }
    }

    /// Distance from the query point to the piece along pseudo-angle `k`.
    #[inline]
    fn distance_at(&self, k: f64) -> f64 {
        let (du, dv) = diamond_dir(k);
        self.t(du, dv) * (du * du + dv * dv).sqrt()
    }

    /// Axis coordinate on the piece's edge of the ray through `v` (pseudo-angle `k`).
    fn axis_at(&self, e: &Edge, p: [f64; 2], k: f64, v: [f64; 2]) -> f64 {
        if k == self.ka {
            return self.sa;
        }
        if k == self.kb {
            return self.sb;
        }
        let line = e.line();
        let s = if e.normal.is_vertical_edge() {
            if v[0] == line {
                v[1]
            } else {
                p[1] + (v[1] - p[1]) * (line - p[0]) / (v[0] - p[0])
            }
        } else if v[1] == line {
            v[0]
        } else {
            p[0] + (v[0] - p[0]) * (line - p[1]) / (v[1] - p[1])
        };
        s.clamp(self.sa.min(self.sb), self.sa.max(self.sb))
    }
}

/// A sweep event: where a piece starts or ends. Compact (16 bytes), since
/// every query sorts a few hundred of them, and packed so that comparing
/// two events is one integer comparison: the key (its bits mapped to the
/// order of [`f64::total_cmp`]), then the id, then the code.
///
/// * id: `edge * 4 + part * 2 + insert` (`part` 1 for the second half of
///   an edge split at the cut ray): breaks ties between equal keys the same
///   way whatever order the events were generated in.
/// * code: `piece * 2`, plus 1 for the end of the piece (then its `vb`,
///   else its `va`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Event(u128);

impl Event {
    #[inline]
    fn new(key: f64, id: u32, code: u32) -> Event {
        Event(((Self::ordered(key.to_bits()) as u128) << 64) | ((id as u128) << 32) | code as u128)
    }

    /// Maps a float's bits to an unsigned integer in the order of
    /// [`f64::total_cmp`] (its transform, then the sign bit flipped so that
    /// an unsigned comparison agrees): a key of NaN, which a query point on
    /// an edge's end can give, sorts where it always did.
    #[inline]
    fn ordered(bits: u64) -> u64 {
        Self::flip_magnitude(bits) ^ (1 << 63)
    }

    /// `total_cmp`'s transform: the magnitude bits of negative numbers
    /// inverted. It keeps the sign bit, so it is its own inverse.
    #[inline]
    fn flip_magnitude(bits: u64) -> u64 {
        bits ^ ((((bits as i64) >> 63) as u64) >> 1)
    }

    #[inline]
    fn key(&self) -> f64 {
        // Undo `ordered`: restore the sign bit, then undo the transform.
        f64::from_bits(Self::flip_magnitude(((self.0 >> 64) as u64) ^ (1 << 63)))
    }

    #[inline]
    fn id(&self) -> u32 {
        (self.0 >> 32) as u32
    }

    #[inline]
    fn code(&self) -> u32 {
        self.0 as u32
    }

    #[inline]
    fn piece(&self) -> u32 {
        self.code() >> 1
    }

    #[inline]
    fn insert(&self) -> bool {
        self.code() & 1 == 0
    }
}

/// Diamond pseudo-angle of direction `(u, v)`: `0` at `+u`, increasing
/// counter-clockwise (towards `+v`), `4` just below `+u` again.
#[inline]
pub fn diamond(u: f64, v: f64) -> f64 {
    if v >= 0.0 {
        if u > 0.0 {
            v / (u + v)
        } else {
            1.0 + (-u) / (v - u)
        }
    } else if u < 0.0 {
        2.0 + (-v) / (-u - v)
    } else {
        3.0 + u / (u - v)
    }
}

/// A direction (not normalised) with diamond pseudo-angle `k`.
#[inline]
fn diamond_dir(k: f64) -> (f64, f64) {
    if k < 1.0 {
        (1.0 - k, k)
    } else if k < 2.0 {
        (1.0 - k, 2.0 - k)
    } else if k < 3.0 {
        (k - 3.0, 2.0 - k)
    } else {
        (k - 3.0, k - 4.0)
    }
}

/// A query: the point, what it looks into, and its free-space component.
#[derive(Clone, Copy, Debug)]
struct Query {
    p: [f64; 2],
    full: bool,
    /// Local frame: `u` and `v` axes as global unit vectors. For a half view
    /// `v` is the normal, so the visible half-plane is `v > 0`.
    eu: [f64; 2],
    ev: [f64; 2],
    comp: u32,
}

impl Query {
    fn new(p: [f64; 2], view: View, comp: u32) -> Query {
        let (eu, ev) = match view {
            View::Full => ([1.0, 0.0], [0.0, 1.0]),
            View::Half(n) => {
                let nv = n.vec();
                let t = n.travel();
                ([t[0] as f64, t[1] as f64], [nv[0] as f64, nv[1] as f64])
            }
        };
        Query {
            p,
            full: view == View::Full,
            eu,
            ev,
            comp,
        }
    }

    #[inline]
    fn local(&self, q: [f64; 2]) -> (f64, f64) {
        let d = [q[0] - self.p[0], q[1] - self.p[1]];
        if self.full {
            // The identity frame: the same numbers without the products.
            return (d[0], d[1]);
        }
        (
            d[0] * self.eu[0] + d[1] * self.eu[1],
            d[0] * self.ev[0] + d[1] * self.ev[1],
        )
    }

    #[inline]
    fn global(&self, u: f64, v: f64) -> [f64; 2] {
        if self.full {
            return [self.p[0] + u, self.p[1] + v];
        }
        [
            self.p[0] + u * self.eu[0] + v * self.ev[0],
            self.p[1] + u * self.eu[1] + v * self.ev[1],
        ]
    }

    /// Largest pseudo-angle of the view.
    fn kmax(&self) -> f64 {
        if self.full { 4.0 } else { 2.0 }
    }

    /// Appends the piece of edge `ei` between local points `(u, v, s)`
    /// (`s`: axis coordinate on the edge), ordered by pseudo-angle; none if
    /// it is seen edge-on.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn push_piece(
        &self,
        out: &mut Vec<Piece>,
        ei: u32,
        u_const: bool,
        c: f64,
        (pu, pv, ps): (f64, f64, f64),
        (qu, qv, qs): (f64, f64, f64),
    ) {
        let lower = pv < 0.0 || qv < 0.0;
        let key = |u: f64, v: f64| {
            if self.full && v == 0.0 && u > 0.0 && lower {
                4.0
            } else {
                diamond(u, v)
            }
        };
        let (k0, k1) = (key(pu, pv), key(qu, qv));
        if k0 == k1 {
            return;
        }
        let (v0, v1) = (self.global(pu, pv), self.global(qu, qv));
        let (ka, kb, sa, sb, va, vb) = if k0 < k1 {
            (k0, k1, ps, qs, v0, v1)
        } else {
            (k1, k0, qs, ps, v1, v0)
        };
        out.push(Piece {
            edge: ei,
            u_const,
            c,
            ka,
            kb,
            sa,
            sb,
            va,
            vb,
            lit: true,
            dim: false,
        });
    }

    /// Appends the pieces of edge `ei` that the query can see at all: front
    /// facing, same component, inside the half-plane (clipped), split at the
    /// cut ray `+u` for full views.
    fn pieces(&self, edges: &[Edge], ei: u32, out: &mut Vec<Piece>) {
        let e = &edges[ei as usize];
        if e.component != self.comp || e.front_distance(self.p) <= 0.0 {
            return;
        }
        let (lo, hi) = e.extent();
        let (a, b) = (e.point_at(lo), e.point_at(hi));
        let (au, av) = self.local(a);
        let (bu, bv) = self.local(b);
        let u_const = au == bu;
        let c = if u_const { au } else { av };
        let push = |out: &mut Vec<Piece>, p, q| self.push_piece(out, ei, u_const, c, p, q);
        let (pa, pb) = ((au, av, lo), (bu, bv, hi));
        // Where a u-const piece meets v = 0: level with `p` along its axis.
        let m = (
            c,
            0.0,
            if e.normal.is_vertical_edge() {
                self.p[1]
            } else {
                self.p[0]
            },
        );
        if self.full {
            if u_const && c > 0.0 && av.min(bv) < 0.0 && av.max(bv) > 0.0 {
                // Split at the cut ray (+u); the halves meet at v = 0.
                push(out, pa, m);
                push(out, m, pb);
            } else {
                push(out, pa, pb);
            }
        } else if av <= 0.0 && bv <= 0.0 {
            // Entirely outside the open half-plane v > 0.
        } else if av >= 0.0 && bv >= 0.0 {
            push(out, pa, pb);
        } else {
            // Perpendicular to the half-plane's boundary: clip at v = 0.
            push(out, m, if av > 0.0 { pa } else { pb });
        }
    }
}

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

/// One interval of the angular buffer, `[previous end, end)`.
#[derive(Clone, Copy, Debug)]
struct Iv {
    end: f64,
    /// The vertex whose direction is `end`.
    vend: [f64; 2],
    /// Nearest piece found so far, or [`NONE`].
    owner: u32,
    /// Farthest distance of the owner over the interval (infinite if none).
    far: f64,
}

/// The one-dimensional angular buffer of the walk: contiguous intervals of
/// pseudo-angle covering the view, each owned by the nearest piece found so
/// far (or none).
#[derive(Default)]
struct Coverage {
    iv: Vec<Iv>,
    scratch: Vec<Iv>,
}

impl Coverage {
    fn reset(&mut self, kmax: f64) {
        self.iv.clear();
        self.iv.push(Iv {
            end: kmax,
            vend: [0.0; 2],
            owner: NONE,
            far: f64::INFINITY,
        });
    }

    #[inline]
    fn start(&self, i: usize) -> f64 {
        if i == 0 { 0.0 } else { self.iv[i - 1].end }
    }

    /// True when every direction in `[a, b]` already hits something nearer than `dmin`.
    fn hides(&self, a: f64, b: f64, dmin: f64) -> bool {
        let mut i = self.iv.partition_point(|v| v.end <= a);
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

    /// Lets piece `pi` take every part of `[ka, kb)` where it is nearer.
    fn insert(&mut self, pieces: &[Piece], pi: u32) {
        let pc = pieces[pi as usize];
        let n = self.iv.len();
        let first = self.iv.partition_point(|v| v.end <= pc.ka);
        // Quick rejection: hidden everywhere it overlaps.
        let mut i = first;
        let mut wins_any = false;
        while i < n && self.start(i) < pc.kb {
            let (lo, hi) = (self.start(i).max(pc.ka), self.iv[i].end.min(pc.kb));
            let old = self.iv[i].owner;
            if old == NONE || {
                let (du, dv) = diamond_dir(0.5 * (lo + hi));
                let o = &pieces[old as usize];
                let (tp, to) = (pc.t(du, dv), o.t(du, dv));
                tp < to || (tp == to && pi < old)
            } {
                wins_any = true;
                break;
            }
            i += 1;
        }
        if !wins_any {
            return;
        }
        let piece_far = |o: u32, k0: f64, k1: f64| {
            if o == NONE {
                f64::INFINITY
            } else {
                let p = &pieces[o as usize];
                p.distance_at(k0).max(p.distance_at(k1))
            }
        };
        // Rebuild the overlapped range (and merge with equal neighbours).
        let mut a = first;
        let mut i = first;
        self.scratch.clear();
        while i < n && self.start(i) < pc.kb {
            let (s, v) = (self.start(i), self.iv[i]);
            let (lo, hi) = (s.max(pc.ka), v.end.min(pc.kb));
            let wins = v.owner == NONE || {
                let (du, dv) = diamond_dir(0.5 * (lo + hi));
                let o = &pieces[v.owner as usize];
                let (tp, to) = (pc.t(du, dv), o.t(du, dv));
                tp < to || (tp == to && pi < v.owner)
            };
            if lo > s {
                self.scratch.push(Iv {
                    end: lo,
                    vend: pc.va,
                    owner: v.owner,
                    far: 0.0,
                });
            }
            let vhi = if hi == pc.kb && hi < v.end {
                pc.vb
            } else {
                v.vend
            };
            self.scratch.push(Iv {
                end: hi,
                vend: vhi,
                owner: if wins { pi } else { v.owner },
                far: 0.0,
            });
            if v.end > hi {
                self.scratch.push(Iv {
                    end: v.end,
                    vend: v.vend,
                    owner: v.owner,
                    far: 0.0,
                });
            }
            i += 1;
        }
        let mut b = i;
        if a > 0 && self.iv[a - 1].owner == self.scratch[0].owner {
            a -= 1;
        }
        if b < n && self.iv[b].owner == self.scratch[self.scratch.len() - 1].owner {
            self.scratch.push(self.iv[b]);
            b += 1;
        }
        // Consecutive pieces of one owner become one interval.
        let mut out = Vec::with_capacity(self.scratch.len());
        let mut seg_start = self.start(a);
        for (j, t) in self.scratch.iter().enumerate() {
            if self
                .scratch
                .get(j + 1)
                .is_some_and(|next| next.owner == t.owner)
            {
                continue;
            }
            out.push(Iv {
                far: piece_far(t.owner, seg_start, t.end),
                ..*t
            });
            seg_start = t.end;
        }
        self.iv.splice(a..b, out);
    }
}

/// Edges binned into square blocks, with a pyramid of counts above them,
/// for [`Sweeper::walk`].
pub struct Blocks {
    size: i32,
    /// `(nx, ny)` per level; level 0 are the blocks.
    dims: Vec<(usize, usize)>,
    /// Edge counts per node per level.
    counts: Vec<Vec<u32>>,
    /// Edges of block `b`: `list[start[b]..start[b + 1]]`.
    start: Vec<usize>,
    list: Vec<u32>,
}

impl Blocks {
    pub const SIZE: i32 = 8;

    pub fn new(g: &Geometry) -> Blocks {
        let size = Self::SIZE;
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
        for (ei, e) in g.edges.iter().enumerate() {
            let (a0, a1, l) = blocks_of(e);
            for a in a0..=a1 {
                let b = id(e, a, l);
                list[fill[b]] = ei as u32;
                fill[b] += 1;
            }
        }
        let mut dims = vec![(nx, ny)];
        let mut counts = vec![
            (0..nx * ny)
                .map(|b| (start[b + 1] - start[b]) as u32)
                .collect::<Vec<u32>>(),
        ];
        while dims.last().is_some_and(|&(x, y)| x > 1 || y > 1) {
            let (px, py) = *dims.last().expect("non-empty");
            let (cx, cy) = (px.div_ceil(2), py.div_ceil(2));
            let prev = counts.last().expect("non-empty");
            let mut c = vec![0u32; cx * cy];
            for y in 0..py {
                for x in 0..px {
                    c[(y / 2) * cx + x / 2] += prev[y * px + x];
                }
            }
            dims.push((cx, cy));
            counts.push(c);
        }
        Blocks {
            size,
            dims,
            counts,
            start,
            list,
        }
    }
}

/// Which edges' spans a query returns: edge `e` only from points within
/// squared distance `reach2[e]` of it (negative: never, the edge has no
/// light). The others still hide what is behind them, but their spans are
/// left out (and counted, for edges with some light) instead of being found
/// and then discarded: most of what a pixel sees under falloff is far
/// walls that only hide other walls.
#[derive(Clone, Copy, Debug)]
pub struct Wanted<'a> {
    pub reach2: &'a [f64],
    /// For a sweep, optionally: per candidate, what holds for the query's
    /// whole region ([`Wanted::classify`]), so that only the candidates
    /// that are within reach of part of it are tested per point.
    pub class: Option<&'a [Reachable]>,
}

/// Where a candidate's light reaches, over a whole region of query points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reachable {
    /// Every point is within reach.
    All,
    /// No point is (the edge has light, but too far away).
    Beyond,
    /// The edge has no light at all.
    Never,
    /// Some points are: test each.
    Partly,
}

impl Wanted<'_> {
    /// Classifies `candidates` for the points of the closed rectangle `r`
    /// (distances to a segment are largest at a corner of the rectangle).
    pub fn classify(
        reach2: &[f64],
        edges: &[Edge],
        r: &Rect,
        candidates: &[u32],
        out: &mut Vec<Reachable>,
    ) {
        out.clear();
        let corners = [
            [r.x0 as f64, r.y0 as f64],
            [r.x1 as f64, r.y0 as f64],
            [r.x0 as f64, r.y1 as f64],
            [r.x1 as f64, r.y1 as f64],
        ];
        out.extend(candidates.iter().map(|&ei| {
            let (e, r2) = (&edges[ei as usize], reach2[ei as usize]);
            if r2 < 0.0 {
                return Reachable::Never;
            }
            let near = r.distance_to(e);
            if near * near > r2 {
                Reachable::Beyond
            } else if corners.iter().all(|&c| e.distance_sq(c) <= r2) {
                Reachable::All
            } else {
                Reachable::Partly
            }
        }));
    }

    /// Is edge `ei` (candidate number `j`, if the query has a list) wanted
    /// from `p`, and if not, does it have light?
    #[inline]
    fn at(&self, edges: &[Edge], ei: u32, j: Option<usize>, p: [f64; 2]) -> (bool, bool) {
        let r2 = self.reach2[ei as usize];
        match self.class.zip(j).map(|(c, j)| c[j]) {
            Some(Reachable::All) => (true, false),
            Some(Reachable::Beyond) => (false, true),
            Some(Reachable::Never) => (false, false),
            _ => {
                let lit = r2 >= 0.0 && edges[ei as usize].distance_sq(p) <= r2;
                (lit, !lit && r2 >= 0.0)
            }
        }
    }
}

/// Reusable buffers for visibility queries (one per thread).
#[derive(Default)]
pub struct Sweeper {
    pieces: Vec<Piece>,
    events: Vec<Event>,
    /// The previous sweep's events in sorted order, by id; the next query
    /// point is usually a neighbour, so listing its events in this order
    /// first leaves the sort little to do.
    order: Vec<u32>,
    /// The same order by code (index in `events`), and the pieces it was
    /// for (`edge * 4 + part * 2` each).
    codes: Vec<u32>,
    prev_shape: Vec<u32>,
    shape: Vec<u32>,
    /// Per event id: its index in `events`, while not yet laid out.
    slot: Marks<u32>,
    sorted: Vec<Event>,
    /// Per piece: its index in `active`, or `u32::MAX`.
    at: Vec<u32>,
    /// Pieces inserted at the current event key.
    fresh: Vec<u32>,
    active: Vec<u32>,
    cover: Coverage,
    stack: Vec<(u8, u32, u32)>,
    /// Edges already inserted by the current walk.
    inserted: Marks<()>,
}

impl Sweeper {
    pub fn new() -> Self {
        Self::default()
    }

    /// The visible spans seen from `p` looking into `view`, among `candidates`
    /// (indices into `edges`) that belong to free-space component `comp`.
    /// Spans are appended to `out` in increasing pseudo-angle.
    pub fn sweep(
        &mut self,
        edges: &[Edge],
        candidates: &[u32],
        p: [f64; 2],
        view: View,
        comp: u32,
        out: &mut Vec<Span>,
    ) {
        self.sweep_wanted(edges, candidates, p, view, comp, None, out);
    }

    /// [`Sweeper::sweep`], returning only the spans `wanted`; returns how
    /// many spans of edges with light it left out.
    #[allow(clippy::too_many_arguments)]
    pub fn sweep_wanted(
        &mut self,
        edges: &[Edge],
        candidates: &[u32],
        p: [f64; 2],
        view: View,
        comp: u32,
        wanted: Option<Wanted>,
        out: &mut Vec<Span>,
    ) -> u64 {
        let q = Query::new(p, view, comp);
        self.pieces.clear();
        self.events.clear();
        for (j, &ei) in candidates.iter().enumerate() {
            let from = self.pieces.len();
            q.pieces(edges, ei, &mut self.pieces);
            if let Some(w) = wanted
                && self.pieces.len() > from
            {
                Self::mark(&mut self.pieces[from..], w.at(edges, ei, Some(j), p));
            }
        }
        if self.pieces.is_empty() {
            return 0;
        }
        let mut left_out = 0;
        self.shape.clear();
        for (id, pc) in self.pieces.iter().enumerate() {
            let part = u32::from(id > 0 && self.pieces[id - 1].edge == pc.edge);
            let base = pc.edge * 4 + part * 2;
            self.events.push(Event::new(pc.ka, base + 1, 2 * id as u32));
            self.events.push(Event::new(pc.kb, base, 2 * id as u32 + 1));
            self.shape.push(base);
        }
        let same = self.shape == self.prev_shape;
        std::mem::swap(&mut self.shape, &mut self.prev_shape);
        self.sort_events(edges.len(), same);
        self.active.clear();
        let n = self.events.len();
        let mut i = 0;
        // The span under construction: (piece, start key, start vertex).
        let mut open: Option<(u32, f64, [f64; 2])> = None;
        // Position of each piece in `active` (for O(1) removal).
        self.at.clear();
        self.at.resize(self.pieces.len(), u32::MAX);
        // Nearest piece of the previous interval.
        let mut current: Option<u32> = None;
        while i < n {
            let key = self.events[i].key();
            let vertex = {
                let ev = self.events[i];
                let pc = &self.pieces[ev.piece() as usize];
                if ev.insert() { pc.va } else { pc.vb }
            };
            self.fresh.clear();
            let mut lost_nearest = false;
            while i < n && self.events[i].key() == key {
                let ev = self.events[i];
                let piece = ev.piece();
                if ev.insert() {
                    self.at[piece as usize] = self.active.len() as u32;
                    self.active.push(piece);
                    self.fresh.push(piece);
                } else {
                    let pos = self.at[piece as usize];
                    if pos != u32::MAX {
                        let pos = pos as usize;
                        self.active.swap_remove(pos);
                        if let Some(&moved) = self.active.get(pos) {
                            self.at[moved as usize] = pos as u32;
                        }
                        self.at[piece as usize] = u32::MAX;
                        lost_nearest |= current == Some(piece);
                    }
                }
                i += 1;
            }
            // Nearest active piece on the interval (key, next key). Edges do
            // not cross, so among pieces active on both sides of an event
            // the nearer stays nearer: unless the nearest piece just ended,
            // only the pieces that just started can take its place.
            let nearest = if i >= n || self.active.is_empty() {
                None
            } else if !lost_nearest && self.fresh.is_empty() && current.is_some() {
                // Only pieces behind the nearest ended: it stays nearest.
                current
            } else {
                let (du, dv) = diamond_dir(0.5 * (key + self.events[i].key()));
                // Compared along one ray, so any positive multiple of the
                // ray parameter will do: `t |du| |dv|` needs no division.
                // An axis-parallel ray keeps the plain parameter.
                let (su, sv) = if du == 0.0 || dv == 0.0 {
                    (1.0 / du.abs(), 1.0 / dv.abs())
                } else {
                    (dv.abs(), du.abs())
                };
                let mut best = u32::MAX;
                let mut best_t = f64::INFINITY;
                let mut consider = |a: u32| {
                    let t = self.pieces[a as usize].t_scaled(su, sv);
                    if t < best_t || (t == best_t && a < best) {
                        best_t = t;
                        best = a;
                    }
                };
                match current {
                    Some(c) if !lost_nearest => {
                        consider(c);
                        for &a in &self.fresh {
                            consider(a);
                        }
                    }
                    _ => {
                        for &a in &self.active {
                            consider(a);
                        }
                    }
                }
                Some(best)
            };
            // The nearest piece's span, unless it is not wanted (then it
            // only hides what is behind it).
            let shown = match nearest {
                Some(pc) if !self.pieces[pc as usize].lit => {
                    if current != nearest && self.pieces[pc as usize].dim {
                        left_out += 1;
                    }
                    None
                }
                _ => nearest,
            };
            current = nearest;
            if open.map(|o| o.0) != shown {
                if let Some((pc, k0, v0)) = open.take() {
                    self.emit(edges, p, pc, k0, v0, key, vertex, out);
                }
                if let Some(pc) = shown {
                    open = Some((pc, key, vertex));
                }
            }
        }
        debug_assert!(open.is_none(), "the last event closes every span");
        left_out
    }

    /// Marks the `pieces` of one edge as wanted or not (`(lit, dim)`, see
    /// [`Piece`]).
    #[inline]
    fn mark(pieces: &mut [Piece], (lit, dim): (bool, bool)) {
        for pc in pieces {
            pc.lit = lit;
            pc.dim = dim;
        }
    }

    /// Sorts `events` by key, ties by id: a total order, so the result does
    /// not depend on the order they came in. They are first laid out in the
    /// previous sweep's order (neighbouring points see nearly the same
    /// angular order), which an insertion sort then only has to patch up.
    ///
    /// `same`: the pieces are those of the previous sweep, in the same order
    /// (neighbours usually see the same edges, split the same way), so an
    /// event's index is that of its counterpart in the previous sweep.
    fn sort_events(&mut self, edges: usize, same: bool) {
        let keys = &mut self.sorted;
        keys.clear();
        if same && self.codes.len() == self.events.len() {
            keys.extend(self.codes.iter().map(|&c| self.events[c as usize]));
        } else {
            self.lay_out_by_id(edges);
        }
        let keys = &mut self.sorted;
        // Insertion sort: linear in the number of events plus the number
        // of pairs out of order, which is small between neighbours. Past a
        // budget of moves, a general sort finishes the job.
        let budget = 4 * keys.len() + 64;
        let mut moves = 0;
        let mut i = 1;
        while i < keys.len() && moves <= budget {
            let x = keys[i];
            let mut j = i;
            while j > 0 && x < keys[j - 1] {
                keys[j] = keys[j - 1];
                j -= 1;
            }
            moves += i - j;
            keys[j] = x;
            i += 1;
        }
        if i < keys.len() {
            keys.sort_unstable();
        }
        self.order.clear();
        self.order.extend(keys.iter().map(|k| k.id()));
        self.codes.clear();
        self.codes.extend(keys.iter().map(|k| k.code()));
        std::mem::swap(&mut self.events, &mut self.sorted);
    }

    /// Lays `events` out in the previous sweep's order by id (the events
    /// of pieces that are new come last), into `sorted`.
    fn lay_out_by_id(&mut self, edges: usize) {
        self.slot.clear(edges * 4);
        for (i, ev) in self.events.iter().enumerate() {
            self.slot.set(ev.id() as usize, i as u32);
        }
        // Laid out in the previous order first, then the new ones; ties
        // between equal keys and ids (a repeated candidate) by `code`.
        let keys = &mut self.sorted;
        for &id in &self.order {
            if let Some(i) = self.slot.get(id as usize) {
                keys.push(self.events[i as usize]);
                self.slot.unset(id as usize);
            }
        }
        for ev in &self.events {
            if self.slot.get(ev.id() as usize).is_some() {
                keys.push(*ev);
            }
        }
        if keys.len() != self.events.len() {
            // A repeated candidate gave two events one id: start afresh.
            keys.clear();
            keys.extend_from_slice(&self.events);
        }
    }

    /// Adds edge `ei`'s visible pieces to the coverage, once per walk.
    #[inline]
    fn insert_edge(&mut self, q: &Query, edges: &[Edge], ei: u32, wanted: Option<Wanted>) {
        if !self.inserted.insert(ei as usize) {
            return;
        }
        let from = self.pieces.len();
        q.pieces(edges, ei, &mut self.pieces);
        if let Some(w) = wanted {
            Self::mark(&mut self.pieces[from..], w.at(edges, ei, None, q.p));
        }
        for pi in from..self.pieces.len() {
            self.cover.insert(&self.pieces, pi as u32);
        }
    }

    /// The same result as [`Sweeper::sweep`] over all edges within
    /// `reach_max`, found by walking `blocks` from near to far and skipping
    /// what is already hidden. `seeds` are inserted first: the edges a nearby
    /// point saw fill the coverage early, so more of the walk is skipped (any
    /// list gives the same result).
    #[allow(clippy::too_many_arguments)]
    pub fn walk(
        &mut self,
        edges: &[Edge],
        blocks: &Blocks,
        p: [f64; 2],
        view: View,
        comp: u32,
        reach_max: f64,
        seeds: &[u32],
        out: &mut Vec<Span>,
    ) {
        self.walk_wanted(edges, blocks, p, view, comp, reach_max, seeds, None, out);
    }

    /// [`Sweeper::walk`], returning only the spans `wanted`; returns how
    /// many spans of edges with light it left out.
    #[allow(clippy::too_many_arguments)]
    pub fn walk_wanted(
        &mut self,
        edges: &[Edge],
        blocks: &Blocks,
        p: [f64; 2],
        view: View,
        comp: u32,
        reach_max: f64,
        seeds: &[u32],
        wanted: Option<Wanted>,
        out: &mut Vec<Span>,
    ) -> u64 {
        let q = Query::new(p, view, comp);
        self.pieces.clear();
        self.cover.reset(q.kmax());
        self.inserted.clear(edges.len());
        for &ei in seeds {
            self.insert_edge(&q, edges, ei, wanted);
        }
        let top = blocks.dims.len() - 1;
        self.stack.clear();
        self.stack.push((top as u8, 0, 0));
        while let Some((level, x, y)) = self.stack.pop() {
            let (nx, _) = blocks.dims[level as usize];
            if blocks.counts[level as usize][y as usize * nx + x as usize] == 0 {
                continue;
            }
            let side = (blocks.size << level) as f64;
            let (x0, y0) = (x as f64 * side, y as f64 * side);
            let (x1, y1) = (x0 + side, y0 + side);
            let dx = (x0 - p[0]).max(p[0] - x1).max(0.0);
            let dy = (y0 - p[1]).max(p[1] - y1).max(0.0);
            let dmin = (dx * dx + dy * dy).sqrt();
            if dmin > reach_max {
                continue;
            }
            match box_range(&q, x0, y0, x1, y1) {
                BoxView::Around => {}
                BoxView::Behind => continue,
                BoxView::Ranges(ranges) => {
                    if ranges.iter().all(|&(a, b)| self.cover.hides(a, b, dmin)) {
                        continue;
                    }
                }
            }
            if level == 0 {
                let b = y as usize * nx + x as usize;
                for &ei in &blocks.list[blocks.start[b]..blocks.start[b + 1]] {
                    self.insert_edge(&q, edges, ei, wanted);
                }
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
        // Read the spans off the buffer (intervals of one owner are merged).
        let cover = &self.cover;
        let mut left_out = 0;
        for i in 0..cover.iv.len() {
            let o = cover.iv[i].owner;
            if o == NONE {
                continue;
            }
            let pc = &self.pieces[o as usize];
            if !pc.lit {
                left_out += u64::from(pc.dim);
                continue;
            }
            let (k0, k1) = (cover.start(i), cover.iv[i].end);
            let v0 = if i == 0 { pc.va } else { cover.iv[i - 1].vend };
            self.emit(edges, p, o, k0, v0, k1, cover.iv[i].vend, out);
        }
        left_out
    }

    #[allow(clippy::too_many_arguments)]
    fn emit(
        &self,
        edges: &[Edge],
        p: [f64; 2],
        piece: u32,
        k0: f64,
        v0: [f64; 2],
        k1: f64,
        v1: [f64; 2],
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

/// An axis-aligned rectangle of pixels `[x0, x1) x [y0, y1)`; as a region of
/// the plane it is the closed rectangle `[x0, x1] x [y0, y1]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    pub x0: i32,
    pub y0: i32,
    pub x1: i32,
    pub y1: i32,
}

impl Rect {
    pub fn width(&self) -> i32 {
        self.x1 - self.x0
    }
    pub fn height(&self) -> i32 {
        self.y1 - self.y0
    }
    pub fn is_empty(&self) -> bool {
        self.x1 <= self.x0 || self.y1 <= self.y0
    }
    fn intersects(&self, o: &Rect) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1
    }
    /// Distance from the closed rectangle to edge `e` (0 if they touch).
    pub fn distance_to(&self, e: &Edge) -> f64 {
        let (lo, hi) = e.extent();
        let line = e.line();
        let (r_lo, r_hi, p_lo, p_hi) = if e.normal.is_vertical_edge() {
            (
                self.y0 as f64,
                self.y1 as f64,
                self.x0 as f64,
                self.x1 as f64,
            )
        } else {
            (
                self.x0 as f64,
                self.x1 as f64,
                self.y0 as f64,
                self.y1 as f64,
            )
        };
        let da = (r_lo - hi).max(lo - r_hi).max(0.0);
        let dp = (p_lo - line).max(line - p_hi).max(0.0);
        (da * da + dp * dp).sqrt()
    }
    /// True when some point of the closed rectangle is strictly in front of `e`.
    pub fn sees_front_of(&self, e: &Edge) -> bool {
        let line = e.line();
        match e.normal {
            Normal::Right => self.x1 as f64 > line,
            Normal::Left => (self.x0 as f64) < line,
            Normal::Down => self.y1 as f64 > line,
            Normal::Up => (self.y0 as f64) < line,
        }
    }
}

/// The closed rectangle that holds every query point of a region, in half
/// pixels (all coordinates doubled, so that the tests below stay exact in
/// integers): the region's whole pixels, sides included, or only their
/// centres when every query point is a pixel centre (a floor gather).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Zone {
    pub x0: i64,
    pub y0: i64,
    pub x1: i64,
    pub y1: i64,
}

impl Zone {
    /// The zone of the pixels of `r`; `centres`: of their centres only.
    pub fn of(r: Rect, centres: bool) -> Zone {
        let i = i64::from(centres);
        Zone {
            x0: 2 * r.x0 as i64 + i,
            y0: 2 * r.y0 as i64 + i,
            x1: 2 * r.x1 as i64 - i,
            y1: 2 * r.y1 as i64 - i,
        }
    }

    /// The closed square of the pixels of `r`.
    fn solid(r: &Rect) -> Zone {
        Zone::of(*r, false)
    }

    /// The closed segment of edge `e`, as a degenerate rectangle.
    fn edge(e: &Edge) -> Zone {
        Zone {
            x0: 2 * e.a[0].min(e.b[0]) as i64,
            y0: 2 * e.a[1].min(e.b[1]) as i64,
            x1: 2 * e.a[0].max(e.b[0]) as i64,
            y1: 2 * e.a[1].max(e.b[1]) as i64,
        }
    }

    fn corners(&self) -> [(i64, i64); 4] {
        [
            (self.x0, self.y0),
            (self.x1, self.y0),
            (self.x0, self.y1),
            (self.x1, self.y1),
        ]
    }

    /// Do the two closed rectangles share a point?
    fn meets(&self, o: &Zone) -> bool {
        self.x0 <= o.x1 && o.x0 <= self.x1 && self.y0 <= o.y1 && o.y0 <= self.y1
    }

    /// Does the closed segment `p q` share a point with the closed rectangle?
    /// Their bounding boxes overlap and the rectangle's corners are not all
    /// strictly on one side of the segment's line (separating axes).
    fn meets_segment(&self, p: (i64, i64), q: (i64, i64)) -> bool {
        if p.0.min(q.0) > self.x1
            || p.0.max(q.0) < self.x0
            || p.1.min(q.1) > self.y1
            || p.1.max(q.1) < self.y0
        {
            return false;
        }
        let (dx, dy) = (q.0 - p.0, q.1 - p.1);
        let side = self
            .corners()
            .map(|(x, y)| (dx * (y - p.1) - dy * (x - p.0)).signum());
        !(side.iter().all(|&s| s > 0) || side.iter().all(|&s| s < 0))
    }
}

/// True when every segment from a point of zone `z` to a point of edge `e`
/// crosses the straight run `s` (touching counts): then no point of `z` sees
/// any part of `e`. Exact integer arithmetic.
///
/// Each such segment crosses the run's line once (the zone is on the front
/// side, the edge behind). The crossing coordinate is a linear-fractional
/// function of each endpoint, so over the zone and the edge its extremes are
/// reached at their vertices: checking the 4 x 2 vertex pairs is exact.
pub fn run_hides(z: &Zone, e: &Edge, s: &Run) -> bool {
    let vertical = s.normal.is_vertical_edge();
    let sign: i64 = if matches!(s.normal, Normal::Right | Normal::Down) {
        1
    } else {
        -1
    };
    // (perpendicular coordinate, along coordinate) of a point, in half pixels.
    let split = |x: i64, y: i64| if vertical { (x, y) } else { (y, x) };
    let line = 2 * s.line as i64;
    let corners = z.corners().map(|(x, y)| {
        let (pp, al) = split(x, y);
        ((pp - line) * sign, al)
    });
    let ends = [e.a, e.b].map(|q| {
        let (pp, al) = split(2 * q[0] as i64, 2 * q[1] as i64);
        ((pp - line) * sign, al)
    });
    if corners.iter().any(|c| c.0 < 0) || ends.iter().any(|q| q.0 > 0) {
        return false;
    }
    let (lo, hi) = (2 * s.lo as i64, 2 * s.hi as i64);
    for &(dc, cu) in &corners {
        for &(dy, yu) in &ends {
            let den = dc - dy;
            if den == 0 {
                return false; // both on the run's line: a grazing segment
            }
            let num = yu * dc - cu * dy;
            if num < lo * den || num > hi * den {
                return false;
            }
        }
    }
    true
}

/// True when every segment from a point of zone `z` to a point of edge `e`
/// meets the solid rectangle `s` (pixels), which touches neither: then no
/// point of `z` sees any part of `e`. Exact integer arithmetic.
///
/// The points `y` from which every segment to `z` meets `s` form a convex
/// set (for each point `p` of `z`, the points whose segment to `p` meets `s`
/// form a convex shadow, and this set is their intersection; for fixed `y`
/// the same holds with the roles swapped). So it is enough that the segments
/// between the 4 corners of `z` and the 2 ends of `e` meet `s`. A segment
/// from a query point that meets `s` enters the solid, crossing an edge
/// before it reaches `e` (except along at most the two directions that only
/// graze `s`, which carry no light), so `e` is hidden.
pub fn box_hides(z: &Zone, e: &Edge, s: &Rect) -> bool {
    let sz = Zone::solid(s);
    if z.meets(&sz) || Zone::edge(e).meets(&sz) {
        return false;
    }
    z.corners().iter().all(|&c| {
        [e.a, e.b]
            .iter()
            .all(|y| sz.meets_segment(c, (2 * y[0] as i64, 2 * y[1] as i64)))
    })
}

/// The solid pixels as rectangles, to prove edges hidden with [`box_hides`]:
/// each row's runs of solid pixels, merged with the run right above when
/// it spans the same columns (a rectangular obstacle is one box).
struct SolidBoxes {
    rects: Vec<Rect>,
    /// The boxes behind edge `e`: `list[start[e]..start[e + 1]]`.
    start: Vec<u32>,
    list: Vec<u32>,
}

impl SolidBoxes {
    fn new(g: &Geometry) -> SolidBoxes {
        let (w, h) = (g.width, g.height);
        let solid = |x: usize, y: usize| g.components[y * w + x] == u32::MAX;
        let mut rects: Vec<Rect> = Vec::new();
        let mut box_of = vec![u32::MAX; w * h];
        // Per start column: (end column, box) of a run in the row above.
        let mut above: Vec<(usize, u32)> = vec![(0, u32::MAX); w];
        let mut here: Vec<(usize, u32)> = vec![(0, u32::MAX); w];
        for y in 0..h {
            here.fill((0, u32::MAX));
            let mut x = 0;
            while x < w {
                if !solid(x, y) {
                    x += 1;
                    continue;
                }
                let x0 = x;
                while x < w && solid(x, y) {
                    x += 1;
                }
                let id = match above[x0] {
                    (x1, id) if id != u32::MAX && x1 == x => {
                        rects[id as usize].y1 = y as i32 + 1;
                        id
                    }
                    _ => {
                        rects.push(Rect {
                            x0: x0 as i32,
                            y0: y as i32,
                            x1: x as i32,
                            y1: y as i32 + 1,
                        });
                        rects.len() as u32 - 1
                    }
                };
                here[x0] = (x, id);
                box_of[y * w + x0..y * w + x].fill(id);
            }
            std::mem::swap(&mut above, &mut here);
        }
        let mut start = vec![0u32];
        let mut list = Vec::new();
        for e in &g.edges {
            let (lo, hi) = e.extent();
            let from = list.len();
            for s in lo as i32..hi as i32 {
                let p = e.solid_pixel_at(s);
                let b = box_of[p[1] as usize * w + p[0] as usize];
                // Along a straight line, each box is one stretch.
                if list.len() == from || list.last() != Some(&b) {
                    list.push(b);
                }
            }
            start.push(list.len() as u32);
        }
        SolidBoxes { rects, start, list }
    }

    fn behind(&self, e: u32) -> &[u32] {
        &self.list[self.start[e as usize] as usize..self.start[e as usize + 1] as usize]
    }
}

/// The arc of pseudo-angles that `points` span as seen from `q`, as
/// `(start, end)` with `start` in `[0, 4)` and `end - start < 2`, for points
/// that lie within less than a half turn (pseudo-angle 2) of each other, as
/// the corners of a box or the ends of an edge that do not hold `q` do.
fn arc(q: [f64; 2], points: &[[f64; 2]]) -> (f64, f64) {
    let a0 = diamond(points[0][0] - q[0], points[0][1] - q[1]);
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for p in &points[1..] {
        let mut d = diamond(p[0] - q[0], p[1] - q[1]) - a0;
        if d > 2.0 {
            d -= 4.0;
        } else if d <= -2.0 {
            d += 4.0;
        }
        lo = lo.min(d);
        hi = hi.max(d);
    }
    let start = a0 + lo;
    let start = if start < 0.0 { start + 4.0 } else { start };
    (start, start + (hi - lo))
}

/// Rounding margin of [`arc_holds`], in pseudo-angle. [`ArcBins`] files
/// each arc this much wider, so that every box whose arc holds an edge's
/// start direction within the margin is under that direction's bin.
const ARC_SLACK: f64 = 1e-9;

/// Does arc `outer` hold arc `inner` (with a margin for rounding: this only
/// picks which boxes to test exactly)?
#[inline]
fn arc_holds(outer: (f64, f64), inner: (f64, f64)) -> bool {
    // Both start in [0, 4); the inner one may sit a turn later.
    let (a, b) = if inner.0 < outer.0 - ARC_SLACK {
        (inner.0 + 4.0, inner.1 + 4.0)
    } else {
        inner
    };
    a >= outer.0 - ARC_SLACK && b <= outer.1 + ARC_SLACK
}

/// Query points per rectangle, to weigh culled pairs (0: nothing to do there).
pub type Count<'a> = &'a (dyn Fn(Rect) -> u64 + Sync);

/// Candidate edge lists for square tiles of pixels.
pub struct TileTree<'g> {
    pub geometry: &'g Geometry,
    /// Side of a leaf tile in pixels.
    pub leaf: i32,
    /// Bounding box of each free-space component.
    comp_bbox: Vec<Rect>,
    /// Every query point is the centre of its pixel: regions are culled
    /// for their pixel centres only (a tighter zone, see [`Zone`]).
    centres: bool,
    boxes: SolidBoxes,
}

/// The free regions of one leaf tile: its free pixels split into pieces that
/// are 4-connected inside the tile, each with its own candidate edges. A
/// corridor on one side of a wall is culled without the pixels beyond it.
pub struct LeafRegions {
    pub rect: Rect,
    /// Region of each pixel of `rect`, row-major; `u8::MAX` for solid pixels.
    pub label: Vec<u8>,
    pub regions: Vec<Region>,
}

/// One free region of a leaf tile.
pub struct Region {
    /// Bounding box of the region's pixels.
    pub bbox: Rect,
    pub component: u32,
    /// A short candidate list for [`Sweeper::sweep`], or `None`: use [`Sweeper::walk`].
    pub candidates: Option<Vec<u32>>,
}

impl LeafRegions {
    /// The region of the free pixel `px` (which must lie in the leaf).
    pub fn region_at(&self, px: [i32; 2]) -> Option<usize> {
        let w = self.rect.width();
        let l = self.label[((px[1] - self.rect.y0) * w + px[0] - self.rect.x0) as usize];
        (l != u8::MAX).then_some(l as usize)
    }

    /// The candidates for the free pixel `px` (which must lie in the leaf):
    /// `Some(list)` to sweep, `None` to walk.
    pub fn candidates_at(&self, px: [i32; 2]) -> Option<&[u32]> {
        let w = self.rect.width();
        let l = self.label[((px[1] - self.rect.y0) * w + px[0] - self.rect.x0) as usize];
        self.regions
            .get(l as usize)
            .map_or(Some(&[]), |r| r.candidates.as_deref())
    }
}

impl<'g> TileTree<'g> {
    pub const LEAF: i32 = 8;

    /// Longest candidate list a region sweeps; longer ones walk the blocks.
    pub const SWEEP_MAX: usize = 192;
    /// Longest list a quadtree node keeps refining; above it the subtree walks.
    pub const REFINE_MAX: usize = 3000;
    /// Fewest query points in a leaf for its regions' lists to be culled
    /// for hidden edges ([`TileTree::cull_hidden`]).
    pub const CULL_MIN_POINTS: u64 = 8;

    /// Splits leaf `r` (holding `points` query points) into free regions and
    /// culls `cands` (if known) for each.
    fn leaf_regions(&self, r: Rect, cands: Option<&[u32]>, points: u64) -> LeafRegions {
        let g = self.geometry;
        let (w, h) = (r.width(), r.height());
        let mut label = vec![u8::MAX; (w * h) as usize];
        let free = |x: i32, y: i32| g.components[y as usize * g.width + x as usize] != u32::MAX;
        let mut regions = Vec::new();
        let mut stack = Vec::new();
        for y0 in 0..h {
            for x0 in 0..w {
                if label[(y0 * w + x0) as usize] != u8::MAX || !free(r.x0 + x0, r.y0 + y0) {
                    continue;
                }
                let id = regions.len() as u8;
                let mut bbox = Rect {
                    x0: i32::MAX,
                    y0: i32::MAX,
                    x1: i32::MIN,
                    y1: i32::MIN,
                };
                label[(y0 * w + x0) as usize] = id;
                stack.push((x0, y0));
                while let Some((x, y)) = stack.pop() {
                    bbox = Rect {
                        x0: bbox.x0.min(r.x0 + x),
                        y0: bbox.y0.min(r.y0 + y),
                        x1: bbox.x1.max(r.x0 + x + 1),
                        y1: bbox.y1.max(r.y0 + y + 1),
                    };
                    for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                        let (nx, ny) = (x + dx, y + dy);
                        if nx >= 0
                            && ny >= 0
                            && nx < w
                            && ny < h
                            && label[(ny * w + nx) as usize] == u8::MAX
                            && free(r.x0 + nx, r.y0 + ny)
                        {
                            label[(ny * w + nx) as usize] = id;
                            stack.push((nx, ny));
                        }
                    }
                }
                let component = g.components[(r.y0 + y0) as usize * g.width + (r.x0 + x0) as usize];
                let candidates = cands.and_then(|cands| {
                    let mine: Vec<u32> = cands
                        .iter()
                        .copied()
                        .filter(|&ei| {
                            let e = &g.edges[ei as usize];
                            e.component == component && bbox.sees_front_of(e)
                        })
                        .collect();
                    // Culling costs about two sweeps; a leaf with fewer
                    // points than this (a wall's form-factor points) gains
                    // less from shorter lists than it pays.
                    let mine =
                        if mine.len() <= 4 * Self::SWEEP_MAX && points >= Self::CULL_MIN_POINTS {
                            self.cull_hidden(bbox, mine)
                        } else {
                            mine
                        };
                    (mine.len() <= Self::SWEEP_MAX).then_some(mine)
                });
                regions.push(Region {
                    bbox,
                    component,
                    candidates,
                });
            }
        }
        LeafRegions {
            rect: r,
            label,
            regions,
        }
    }

    /// `centres`: every query point will be the centre of its pixel (a
    /// floor gather); otherwise points may lie anywhere on their pixel,
    /// sides included (points on edges, for form factors).
    pub fn new(geometry: &'g Geometry, centres: bool) -> Self {
        let mut comp_bbox = vec![
            Rect {
                x0: i32::MAX,
                y0: i32::MAX,
                x1: i32::MIN,
                y1: i32::MIN
            };
            geometry.component_count as usize
        ];
        for y in 0..geometry.height {
            for x in 0..geometry.width {
                let c = geometry.components[y * geometry.width + x];
                if c == u32::MAX {
                    continue;
                }
                let b = &mut comp_bbox[c as usize];
                b.x0 = b.x0.min(x as i32);
                b.y0 = b.y0.min(y as i32);
                b.x1 = b.x1.max(x as i32 + 1);
                b.y1 = b.y1.max(y as i32 + 1);
            }
        }
        TileTree {
            geometry,
            leaf: Self::LEAF,
            comp_bbox,
            centres,
            boxes: SolidBoxes::new(geometry),
        }
    }

    /// Calls `visit(leaf)` for every leaf tile holding query points
    /// (`count(rect) > 0`), in parallel. Each free region of the leaf gets a
    /// conservative candidate list: every edge that any point of the region
    /// (pixel centres and points on the sides of its pixels) can see and that
    /// is within `reach_max` is in it. Returns the number of (edge, point)
    /// pairs dropped for being beyond `reach_max`.
    pub fn for_each_leaf<V>(&self, count: Count, reach_max: f64, visit: &V) -> u64
    where
        V: Fn(&LeafRegions) + Sync,
    {
        let g = self.geometry;
        let mut size = self.leaf;
        while size < g.width.max(g.height) as i32 {
            size *= 2;
        }
        let root = Rect {
            x0: 0,
            y0: 0,
            x1: g.width as i32,
            y1: g.height as i32,
        };
        let all: Vec<u32> = (0..g.edges.len() as u32).collect();
        let culled = std::sync::atomic::AtomicU64::new(0);
        self.node(root, size, Some(&all), count, reach_max, &culled, visit);
        culled.into_inner()
    }

    /// `parent`: the parent's candidates, or `None` when they were too many
    /// to be worth refining (the subtree walks).
    #[allow(clippy::too_many_arguments)]
    fn node<V>(
        &self,
        r: Rect,
        size: i32,
        parent: Option<&[u32]>,
        count: Count,
        reach_max: f64,
        culled: &std::sync::atomic::AtomicU64,
        visit: &V,
    ) where
        V: Fn(&LeafRegions) + Sync,
    {
        let points = if r.is_empty() { 0 } else { count(r) };
        if points == 0 {
            return;
        }
        let g = self.geometry;
        let mut far = 0u64;
        let cands: Option<Vec<u32>> = parent.map(|parent| {
            parent
                .iter()
                .copied()
                .filter(|&ei| {
                    let e = &g.edges[ei as usize];
                    let keep =
                        r.sees_front_of(e) && self.comp_bbox[e.component as usize].intersects(&r);
                    if keep && reach_max.is_finite() && r.distance_to(e) > reach_max {
                        far += 1;
                        return false;
                    }
                    keep
                })
                .collect()
        });
        if far > 0 {
            culled.fetch_add(far * points, std::sync::atomic::Ordering::Relaxed);
        }
        if size <= self.leaf {
            visit(&self.leaf_regions(r, cands.as_deref(), points));
            return;
        }
        let cands = cands.filter(|c| c.len() <= Self::REFINE_MAX);
        let h = size / 2;
        let kids = [
            Rect {
                x0: r.x0,
                y0: r.y0,
                x1: (r.x0 + h).min(r.x1),
                y1: (r.y0 + h).min(r.y1),
            },
            Rect {
                x0: r.x0 + h,
                y0: r.y0,
                x1: r.x1,
                y1: (r.y0 + h).min(r.y1),
            },
            Rect {
                x0: r.x0,
                y0: r.y0 + h,
                x1: (r.x0 + h).min(r.x1),
                y1: r.y1,
            },
            Rect {
                x0: r.x0 + h,
                y0: r.y0 + h,
                x1: r.x1,
                y1: r.y1,
            },
        ];
        rayon::scope(|s| {
            for k in kids {
                let cands = cands.as_deref();
                s.spawn(move |_| self.node(k, h, cands, count, reach_max, culled, visit));
            }
        });
    }

    /// Drops the candidates that one straight run ([`run_hides`]) or one
    /// solid box ([`box_hides`]) provably hides from every query point of
    /// region `r`. Runs are looked for among those that a free point near
    /// the middle of `r` sees in the direction of the candidate; boxes among
    /// those behind the candidates whose arc, seen from that point, holds
    /// the candidate's arc (a box that hides an edge from the whole region
    /// hides it from that point too).
    fn cull_hidden(&self, r: Rect, cands: Vec<u32>) -> Vec<u32> {
        let g = self.geometry;
        // Free pixel nearest the centre, per component present in the tile.
        let (cx2, cy2) = (r.x0 + r.x1, r.y0 + r.y1);
        let mut reps: Vec<(u32, i64, [i32; 2])> = Vec::new();
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                let c = g.components[y as usize * g.width + x as usize];
                if c == u32::MAX {
                    continue;
                }
                let d = ((2 * x + 1 - cx2) as i64).pow(2) + ((2 * y + 1 - cy2) as i64).pow(2);
                match reps.iter_mut().find(|t| t.0 == c) {
                    Some(t) if d < t.1 => *t = (c, d, [x, y]),
                    Some(_) => {}
                    None => reps.push((c, d, [x, y])),
                }
            }
        }
        if reps.is_empty() {
            return Vec::new();
        }
        let mut keep = vec![true; cands.len()];
        CULL.with(|cell| {
            let scratch = &mut *cell.borrow_mut();
            self.cull_with(r, &cands, &reps, &mut keep, scratch);
        });
        cands
            .into_iter()
            .zip(keep)
            .filter_map(|(c, k)| k.then_some(c))
            .collect()
    }

    /// [`TileTree::cull_hidden`] for the representative points `reps`.
    fn cull_with(
        &self,
        r: Rect,
        cands: &[u32],
        reps: &[(u32, i64, [i32; 2])],
        keep: &mut [bool],
        scratch: &mut CullScratch,
    ) {
        let g = self.geometry;
        let zone = Zone::of(r, self.centres);
        let CullScratch {
            sweeper,
            spans,
            pooled,
            arcs,
            bins,
        } = scratch;
        for &(comp, _, px) in reps {
            let q = [px[0] as f64 + 0.5, px[1] as f64 + 0.5];
            spans.clear();
            sweeper.sweep(&g.edges, cands, q, View::Full, comp, spans);
            if spans.is_empty() {
                continue;
            }
            let owner = |k: f64| -> Option<u32> {
                let i = spans.partition_point(|s| s.k1 <= k);
                spans
                    .get(i)
                    .filter(|s| s.k0 <= k)
                    .map(|s| g.edges[s.edge as usize].run)
            };
            for (i, &ei) in cands.iter().enumerate() {
                let e = &g.edges[ei as usize];
                if e.component != comp || !keep[i] {
                    continue;
                }
                let (lo, hi) = e.extent();
                let mut tried: [u32; 3] = [u32::MAX; 3];
                for (t, s) in [
                    0.5 * (lo + hi),
                    lo + 0.25 * (hi - lo),
                    hi - 0.25 * (hi - lo),
                ]
                .into_iter()
                .enumerate()
                {
                    let pt = e.point_at(s);
                    let k = diamond(pt[0] - q[0], pt[1] - q[1]);
                    let Some(run) = owner(k) else { continue };
                    if tried.contains(&run) || run == e.run {
                        continue;
                    }
                    tried[t] = run;
                    if run_hides(&zone, e, &g.runs[run as usize]) {
                        keep[i] = false;
                        break;
                    }
                }
            }
            // Boxes behind this component's candidates that touch neither
            // the zone nor (checked in box_hides) the edge, with their arcs.
            arcs.clear();
            pooled.clear(self.boxes.rects.len());
            for &ei in cands {
                if g.edges[ei as usize].component != comp {
                    continue;
                }
                for &b in self.boxes.behind(ei) {
                    // Each box once.
                    if !pooled.insert(b as usize) {
                        continue;
                    }
                    let s = &self.boxes.rects[b as usize];
                    if zone.meets(&Zone::solid(s)) {
                        continue;
                    }
                    let (x0, y0, x1, y1) = (s.x0 as f64, s.y0 as f64, s.x1 as f64, s.y1 as f64);
                    arcs.push((b, arc(q, &[[x0, y0], [x1, y0], [x0, y1], [x1, y1]])));
                }
            }
            bins.fill(arcs);
            for (i, &ei) in cands.iter().enumerate() {
                let e = &g.edges[ei as usize];
                if e.component != comp || !keep[i] {
                    continue;
                }
                let a = [e.a[0] as f64, e.a[1] as f64];
                let b = [e.b[0] as f64, e.b[1] as f64];
                let ea = arc(q, &[a, b]);
                // A box that holds the edge's arc holds its start: only the
                // boxes filed under that direction need looking at.
                let bin = ArcBins::bin(ea.0);
                if bins.list[bins.start[bin] as usize..bins.start[bin + 1] as usize]
                    .iter()
                    .any(|&j| {
                        let (bx, ba) = arcs[j as usize];
                        arc_holds(ba, ea) && box_hides(&zone, e, &self.boxes.rects[bx as usize])
                    })
                {
                    keep[i] = false;
                }
            }
        }
    }
}

/// Arcs filed by the directions they cover, in [`ArcBins::N`] equal bins
/// of pseudo-angle, so that the arcs that may hold a given direction are
/// found without scanning them all: arc `j` is listed in every bin it
/// touches (with the margin of [`arc_holds`]).
#[derive(Default)]
struct ArcBins {
    start: Vec<u32>,
    list: Vec<u32>,
}

impl ArcBins {
    const N: usize = 32;

    /// The bin of direction `k` (in `[0, 4)`).
    #[inline]
    fn bin(k: f64) -> usize {
        ((k * (Self::N as f64 / 4.0)) as usize).min(Self::N - 1)
    }

    fn fill(&mut self, arcs: &[(u32, (f64, f64))]) {
        let per = Self::N as f64 / 4.0;
        // Bins `first..=last` of an arc, counted past N where it wraps.
        let span = |(a, b): (f64, f64)| {
            let first = ((a - ARC_SLACK).max(0.0) * per) as usize;
            let last = (((b + ARC_SLACK) * per) as usize).min(first + Self::N - 1);
            (first, last)
        };
        self.start.clear();
        self.start.resize(Self::N + 1, 0);
        for &(_, a) in arcs {
            let (first, last) = span(a);
            for b in first..=last {
                self.start[b % Self::N + 1] += 1;
            }
        }
        for b in 0..Self::N {
            self.start[b + 1] += self.start[b];
        }
        self.list.clear();
        self.list.resize(self.start[Self::N] as usize, 0);
        let mut fill: [u32; Self::N] = std::array::from_fn(|b| self.start[b]);
        for (j, &(_, a)) in arcs.iter().enumerate() {
            let (first, last) = span(a);
            for b in first..=last {
                let b = b % Self::N;
                self.list[fill[b] as usize] = j as u32;
                fill[b] += 1;
            }
        }
    }
}

/// Buffers of [`TileTree::cull_hidden`], one per thread.
#[derive(Default)]
struct CullScratch {
    sweeper: Sweeper,
    spans: Vec<Span>,
    /// The boxes in the current pool.
    pooled: Marks<()>,
    /// Pooled boxes and their arcs seen from the representative point.
    arcs: Vec<(u32, (f64, f64))>,
    bins: ArcBins,
}

thread_local! {
    static CULL: std::cell::RefCell<CullScratch> = std::cell::RefCell::new(CullScratch::default());
}
