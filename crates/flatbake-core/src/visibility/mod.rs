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

mod cull;
pub mod marks;
mod points;
mod sweep;
mod tiles;
mod walk;

pub use cull::{Rect, Zone, box_hides, run_hides};
pub use points::{
    PointGrid, Structures, VisitStats, centre, for_each_visibility, for_each_visibility_counted,
};
pub use tiles::{Count, LeafRegions, Region, TileTree};
pub use walk::{Blocks, FarWanted, Reaches};

use crate::geometry::{Edge, Geometry, Normal, Run};
use crate::visibility::marks::Marks;
use walk::Coverage;

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
    /// The edge seen (index into the geometry's edges).
    pub edge: u32,
    /// Start of the visible stretch, axis coordinate along the edge.
    pub s0: f64,
    /// End of the visible stretch (`s0 < s1`).
    pub s1: f64,
    /// Pseudo-angle, seen from the query point, of the boundary through `s0`
    /// or `s1` that comes first ([`diamond`]; `k0 < k1`).
    pub k0: f64,
    /// Pseudo-angle of the other boundary.
    pub k1: f64,
}

/// A front-facing edge (or the part of it on one side of the cut ray) as
/// seen from the query point; or a silhouette: two pieces that meet at a
/// convex corner, taken as one (`silhouette` in sweep.rs).
#[derive(Clone, Copy, Debug)]
struct Piece {
    edge: u32,
    /// A silhouette's second edge (the one at `kb`); else `edge`.
    edge_b: u32,
    /// In local coordinates the piece lies on `u = c` (if `u_const`) or `v = c`.
    u_const: bool,
    /// A silhouette: the straight segment from `va` to `vb` across the
    /// solid behind the corner its two pieces meet at. Then `c` is that
    /// corner's pseudo-angle, and `(sa, sb)` is not the piece's extent on
    /// an edge but its line, `sa u + sb v = 1` in local coordinates. In a
    /// walk, its two pieces are the two before it, in order.
    silhouette: bool,
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
    /// edge has light, only too far away to matter here (for a silhouette,
    /// the edge of its first piece, and `dim_b` that of its second).
    lit: bool,
    dim: bool,
    dim_b: bool,
    /// In a sweep: one of the two pieces of the wanted silhouette that
    /// follows them (they have no events; the silhouette's spans are cut
    /// into theirs).
    face: bool,
}

impl Piece {
    /// Ray parameter of the piece's line along local direction `(du, dv)`.
    #[inline]
    fn t(&self, du: f64, dv: f64) -> f64 {
        if self.silhouette {
            return 1.0 / (self.sa * du + self.sb * dv);
        }
        if self.u_const {
            self.c / du
        } else {
            self.c / dv
        }
    }

    /// [`Piece::t`] times a positive factor that depends on the ray only:
    /// `|c| su` for a piece on `u = c`, `|c| sv` else. With `(su, sv) =
    /// (|dv|, |du|)` that is `t |du| |dv|` (for a ray that hits the piece in
    /// front, `c` has the sign of `du`, or of `dv`); with `(1 / |du|, 1 /
    /// |dv|)`, for a ray along an axis, it is `t`. (Not for a silhouette:
    /// the sweep scales its `t` the same way itself.)
    #[inline]
    fn t_scaled(&self, su: f64, sv: f64) -> f64 {
        debug_assert!(!self.silhouette, "a silhouette's line is not on an axis");
        self.c.abs() * if self.u_const { su } else { sv }
    }

    /// Distance from `p` (the query point) to the nearest point of the
    /// piece (pieces are axis-aligned).
    #[inline]
    fn nearest(&self, p: [f64; 2]) -> f64 {
        let gap = |a: f64, b: f64, x: f64| (a.min(b) - x).max(x - a.max(b)).max(0.0);
        let (dx, dy) = (
            gap(self.va[0], self.vb[0], p[0]),
            gap(self.va[1], self.vb[1], p[1]),
        );
        (dx * dx + dy * dy).sqrt()
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

/// Where a visibility query looks from: a point, what it looks into, and
/// the free-space component it lies in (edges of other components are never
/// seen, whatever the geometry says).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Viewpoint {
    /// The query point.
    pub p: [f64; 2],
    /// The directions it looks into.
    pub view: View,
    /// Its free-space component ([`Edge::component`] of the edges it may see).
    pub comp: u32,
}

impl Viewpoint {
    /// A viewpoint at `p` looking into `view` in free-space component `comp`.
    pub fn new(p: [f64; 2], view: View, comp: u32) -> Viewpoint {
        Viewpoint { p, view, comp }
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
    fn new(Viewpoint { p, view, comp }: Viewpoint) -> Query {
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

    /// Whether the receiving cosine ([`Wanted::cosine`], falloff constant
    /// `a`) keeps light from the hull of `points` (an edge's ends, or the
    /// box of a group of edges) at least `d2` away (squared) with reach `r2`
    /// (squared, the longest of the group's): always for a full view,
    /// nearer than [`COSINE_FROM`] and for an unlimited reach; else where
    /// the largest cosine passes [`receiver_keeps`]. The test per edge and
    /// the walk's closure of a group's directions both ask it, so that a
    /// closed group holds no edge that is kept.
    fn receives(&self, points: &[[f64; 2]], a: f64, d2: f64, r2: f64) -> bool {
        self.full
            || d2 < COSINE_FROM * COSINE_FROM
            || !r2.is_finite()
            || self.cosine_above(points, cosine2_needed(a, d2, r2))
    }

    /// Whether the largest cosine between a half view's normal and a
    /// direction from the point to the convex hull of `points` (segment
    /// ends or box corners, whose hull does not hold the point) has a
    /// square above `c2` (always for `c2 < 0`). The cosine is 1 where the
    /// hull meets the normal's ray, else it is largest at one of the
    /// points (0 for those on or behind the half-plane's line). No
    /// division: `v^2 > c2 (u^2 + v^2)`.
    fn cosine_above(&self, points: &[[f64; 2]], c2: f64) -> bool {
        let (mut umin, mut umax) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut ahead = false;
        for &pt in points {
            let (u, v) = self.local(pt);
            if v > 0.0 && v * v > c2 * (u * u + v * v) {
                return true;
            }
            umin = umin.min(u);
            umax = umax.max(u);
            ahead |= v > 0.0;
        }
        // Where the `u` range holds 0 and a point is ahead, the hull may
        // meet the normal's ray `u = 0, v > 0` (it does for an axis-aligned
        // segment or box, as edges and blocks are): a cosine of 1, which is
        // never less.
        (ahead && umin <= 0.0 && umax >= 0.0 && c2 < 1.0) || c2 < 0.0
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
            edge_b: ei,
            u_const,
            silhouette: false,
            c,
            ka,
            kb,
            sa,
            sb,
            va,
            vb,
            lit: true,
            dim: false,
            dim_b: false,
            face: false,
        });
    }

    /// Appends the pieces of edge `ei` that the query can see at all: front
    /// facing, same component, inside the half-plane (clipped), split at the
    /// cut ray `+u` for full views.
    ///
    /// Inlined: about half the edges a walk or a sweep reads face away
    /// from its point (a pillar's far sides) and return here, without the
    /// call (and its frame) that cuts the others: 1-3 % of the dense
    /// levels' bakes (docs/performance.md, forty-second pass).
    #[inline]
    fn pieces(&self, edges: &[Edge], ei: u32, out: &mut Vec<Piece>) {
        let e = &edges[ei as usize];
        if e.component != self.comp || e.front_distance(self.p) <= 0.0 {
            return;
        }
        self.cut(e, ei, out);
    }

    /// [`Query::pieces`] of an edge `e` (index `ei`) that faces the query.
    #[inline(never)]
    fn cut(&self, e: &Edge, ei: u32, out: &mut Vec<Piece>) {
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

/// Which edges' spans a query returns: edge `e` only from points within
/// squared distance `reach2[e]` of it (negative: never, the edge has no
/// light). The others still hide what is behind them, but their spans are
/// left out (and counted, for edges with some light) instead of being found
/// and then discarded: most of what a pixel sees under falloff is far
/// walls that only hide other walls.
///
/// With [`Wanted::cosine`], a half view's point also leaves out an edge
/// within reach whose light its own cosine cuts below the bound the reach
/// was found for ([`receiver_keeps`]), where it tests the edge at all: a
/// sweep's candidate that [`Wanted::classify`] finds within reach of its
/// whole region is taken without a test per point, as without the cosine
/// (a test per point cost the form factors of the dots cut to 256 px a
/// tenth more time than the pairs it left out saved).
#[derive(Clone, Copy, Debug)]
pub struct Wanted<'a> {
    /// Per edge: squared reach (negative: the edge has no light).
    pub reach2: &'a [f64],
    /// For a sweep, optionally: per candidate, what holds for the query's
    /// whole region ([`Wanted::classify`]), so that only the candidates
    /// that are within reach of part of it are tested per point.
    pub class: Option<&'a [Reachable]>,
    /// For half views (the form factors' points): the falloff constant `A`
    /// of the bound the reaches were found for ([`crate::transport::kernel::Reach`]),
    /// whose receiving side the point's cosine scales ([`receiver_keeps`]).
    /// `None`: distance alone decides (the floor gather, which has no
    /// receiving cosine).
    pub cosine: Option<f64>,
}

/// The least distance, in pixels, at which [`Wanted::cosine`] is tested:
/// nearer, distance alone decides (most of a form factor's candidates are
/// near, and their light is rarely below the bound; the edges it leaves out
/// are far ones seen at a grazing angle, such as a lamp far down a
/// corridor that runs along the point's own edge). A walk closes a
/// direction for the cosine only past it too, where every edge it would
/// find there is tested.
pub const COSINE_FROM: f64 = 32.0;

/// Whether an edge of reach `r` (squared: `r2`) at least `d` away (squared:
/// `d2`) may still send a half view's point light above the bound its
/// reach was found for, once that bound is scaled by `c`, the largest
/// cosine between the point's normal and a direction to the edge (squared:
/// `c2`).
///
/// The bound on what an edge sends a point at distance `r` is `K w(r)
/// min(pi, L / r)` with `w(r) = A / (A + r^2)` ([`crate::transport::kernel::Reach`]),
/// equal to the threshold at the reach. A form factor carries the
/// receiver's cosine as well, so `c` times the bound at `d` is still a
/// bound. Its ratio to the bound at the reach, `(w(d) / w(r))
/// (min(pi, L / d) / min(pi, L / r))`, is at most `(A + r^2) r / ((A + d^2) d)`
/// whenever `d <= r` (the second factor is at most `r / d`): the edge
/// matters only where `c (A + r^2) r > (A + d^2) d`. Both sides grow with
/// their distance, so a group of edges can be tested with its largest
/// reach and cosine and its least distance.
///
/// Takes `c2 = c^2` and tests the square, `c^2 > cosine2_needed(A, d^2,
/// r^2)`.
#[inline]
pub fn receiver_keeps(c2: f64, a: f64, d2: f64, r2: f64) -> bool {
    !r2.is_finite() || c2 > cosine2_needed(a, d2, r2)
}

/// The square of the cosine above which [`receiver_keeps`] keeps a pair:
/// `((A + d^2) / (A + r^2))^2 d^2 / r^2` (no square root, and no overflow
/// for the largest falloff); 0 for an unlimited reach.
#[inline]
pub fn cosine2_needed(a: f64, d2: f64, r2: f64) -> f64 {
    if !r2.is_finite() {
        return 0.0;
    }
    let q = (a + d2) / (a + r2);
    q * q * d2 / r2
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
    fn at(&self, edges: &[Edge], ei: u32, j: Option<usize>, q: &Query) -> (bool, bool) {
        let r2 = self.reach2[ei as usize];
        match self.class.zip(j).map(|(c, j)| c[j]) {
            Some(Reachable::All) => (true, false),
            Some(Reachable::Beyond) => (false, true),
            Some(Reachable::Never) => (false, false),
            _ => {
                let e = &edges[ei as usize];
                let d2 = e.distance_sq(q.p);
                let lit = r2 >= 0.0
                    && d2 <= r2
                    && self.cosine.is_none_or(|a| {
                        let (lo, hi) = e.extent();
                        q.receives(&[e.point_at(lo), e.point_at(hi)], a, d2, r2)
                    });
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
    /// The same order by index in `events`, and the pieces it was for
    /// (`edge * 4 + part * 2` each).
    codes: Vec<u32>,
    /// Per piece of the current sweep: the index of its first event (a
    /// face of a wanted silhouette has none, and the pieces after it are
    /// not at twice their index).
    first_event: Vec<u32>,
    prev_shape: Vec<u32>,
    shape: Vec<u32>,
    /// Per event id: its index in `events`, while not yet laid out.
    slot: Marks<u32>,
    sorted: Vec<Event>,
    /// [`Sweeper::bucket_sort`]'s buckets: where each starts, and each
    /// event's.
    bucket_start: Vec<u32>,
    bucket_of: Vec<u32>,
    /// Sweeps left that sort with [`Sweeper::bucket_sort`] without first
    /// trying the insertion sort (which gave up on a recent sweep).
    bucket_sweeps: u32,
    /// Per piece: its index in `active`, or `u32::MAX`.
    at: Vec<u32>,
    /// Pieces inserted at the current event key.
    fresh: Vec<u32>,
    active: Vec<u32>,
    cover: Coverage,
    stack: Vec<(u8, u32, u32)>,
    /// Edges already inserted by the current walk.
    inserted: Marks<()>,
    /// The walk's open directions past [`FarWanted`]'s radius, merged and
    /// sorted.
    open: Vec<(f64, f64)>,
    /// Sweeps and walks take no silhouettes ([`Sweeper::set_silhouettes`]).
    no_silhouettes: bool,
    /// Silhouettes taken so far.
    silhouettes: u64,
}

impl Sweeper {
    /// Empty buffers; they grow to what the queries need.
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether sweeps and walks take two pieces that meet at a pillar's
    /// corner as one silhouette (they do unless told not to, which only
    /// serves to check that the spans are the same either way).
    pub fn set_silhouettes(&mut self, on: bool) {
        self.no_silhouettes = !on;
    }

    /// How many silhouettes this sweeper's sweeps and walks have taken.
    pub fn silhouettes(&self) -> u64 {
        self.silhouettes
    }
}
