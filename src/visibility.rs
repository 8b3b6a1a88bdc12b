//! Exact visibility in flatland.
//!
//! [`Sweeper::sweep`] finds, for one point, exactly which parts of which edges
//! it sees: an angular sweep over the candidate edges' endpoints. Between two
//! consecutive endpoint directions the set of edges crossed by a ray does not
//! change, and because edges never cross, the nearest of them is the same for
//! the whole angular interval; it is found at the interval's middle, so rays
//! that graze a vertex never need a tie-break. Interval boundaries are rays
//! through edge endpoints, so the pieces of the boundary that two neighbouring
//! edges share (a corner, or the corner where two diagonal wall pixels touch)
//! produce bit-identical directions: no light leaks through corners.
//!
//! Directions are ordered with a pseudo-angle (the "diamond angle"), which is
//! monotone in the true angle and needs one division instead of an `atan2`.
//!
//! [`TileTree`] gives every 8x8 tile of pixels a conservative list of
//! candidate edges, refined down a quadtree: an edge is dropped for a tile
//! only when that is proven — it faces away from the whole tile, its free
//! side belongs to a region of free space the tile does not touch, it lies
//! beyond the falloff reach, or one straight wall run blocks every segment
//! from the tile to it (an exact test in integer arithmetic).

use crate::geometry::{Edge, Geometry, Normal, Run};

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

#[derive(Clone, Copy, Debug)]
struct Piece {
    edge: u32,
    /// In local coordinates: the piece lies on `u = c` (if `u_const`) or `v = c`.
    u_const: bool,
    c: f64,
    /// Clipped extent along the edge's own axis, in global coordinates.
    s_lo: f64,
    s_hi: f64,
    /// Pseudo-angles of the piece's ends and their axis coordinates, so a
    /// span that ends at the piece's own end uses the exact coordinate.
    ka: f64,
    sa: f64,
    kb: f64,
    sb: f64,
}

#[derive(Clone, Copy, Debug)]
struct Event {
    key: f64,
    /// The endpoint that produced the event, global coordinates.
    vertex: [f64; 2],
    piece: u32,
    insert: bool,
}

/// Reusable buffers for sweeps (one per thread).
#[derive(Default)]
pub struct Sweeper {
    pieces: Vec<Piece>,
    events: Vec<Event>,
    active: Vec<u32>,
}

/// Diamond pseudo-angle of direction `(u, v)`: `0` at `+u`, increasing
/// counter-clockwise (towards `+v`), `4` just below `+u` again.
#[inline]
pub fn diamond(u: f64, v: f64) -> f64 {
    if v >= 0.0 {
        if u > 0.0 { v / (u + v) } else { 1.0 + (-u) / (v - u) }
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

/// Local frame of a view: `u` and `v` axes as global unit vectors. For a
/// half view `v` is the normal, so the visible half-plane is `v > 0`.
#[inline]
fn frame(view: View) -> ([f64; 2], [f64; 2]) {
    match view {
        View::Full => ([1.0, 0.0], [0.0, 1.0]),
        View::Half(n) => {
            let nv = n.vec();
            let t = n.travel();
            ([t[0] as f64, t[1] as f64], [nv[0] as f64, nv[1] as f64])
        }
    }
}

impl Sweeper {
    pub fn new() -> Self {
        Self::default()
    }

    /// The visible spans seen from `p` looking into `view`, among `candidates`
    /// (indices into `edges`) that belong to free-space component `comp`.
    /// Spans are appended to `out` in increasing pseudo-angle.
    pub fn sweep(&mut self, edges: &[Edge], candidates: &[u32], p: [f64; 2], view: View, comp: u32, out: &mut Vec<Span>) {
        self.pieces.clear();
        self.events.clear();
        let (eu, ev) = frame(view);
        let local = |q: [f64; 2]| {
            let d = [q[0] - p[0], q[1] - p[1]];
            (d[0] * eu[0] + d[1] * eu[1], d[0] * ev[0] + d[1] * ev[1])
        };
        let global = |u: f64, v: f64| [p[0] + u * eu[0] + v * ev[0], p[1] + u * eu[1] + v * ev[1]];
        let full = view == View::Full;
        for &ei in candidates {
            let e = &edges[ei as usize];
            if e.component != comp || e.front_distance(p) <= 0.0 {
                continue;
            }
            let (lo, hi) = e.extent();
            let (a, b) = (e.point_at(lo), e.point_at(hi));
            let (au, av) = local(a);
            let (bu, bv) = local(b);
            let u_const = au == bu;
            let c = if u_const { au } else { av };
            // Adds the piece between two local points `(u, v, axis coordinate)`.
            let mut push = |s: &mut Self, (pu, pv, ps): (f64, f64, f64), (qu, qv, qs): (f64, f64, f64)| {
                let lower = pv < 0.0 || qv < 0.0;
                let key = |u: f64, v: f64| {
                    if full && v == 0.0 && u > 0.0 && lower { 4.0 } else { diamond(u, v) }
                };
                let (k0, k1) = (key(pu, pv), key(qu, qv));
                if k0 == k1 {
                    return;
                }
                let (ka, va, sa, kb, vb, sb) =
                    if k0 < k1 { (k0, (pu, pv), ps, k1, (qu, qv), qs) } else { (k1, (qu, qv), qs, k0, (pu, pv), ps) };
                let id = s.pieces.len() as u32;
                s.pieces.push(Piece { edge: ei, u_const, c, s_lo: sa.min(sb), s_hi: sa.max(sb), ka, sa, kb, sb });
                s.events.push(Event { key: ka, vertex: global(va.0, va.1), piece: id, insert: true });
                s.events.push(Event { key: kb, vertex: global(vb.0, vb.1), piece: id, insert: false });
            };
            let (pa, pb) = ((au, av, lo), (bu, bv, hi));
            // Where a u-const piece meets v = 0: level with `p` along its axis.
            let m = (c, 0.0, if e.normal.is_vertical_edge() { p[1] } else { p[0] });
            if full {
                if u_const && c > 0.0 && av.min(bv) < 0.0 && av.max(bv) > 0.0 {
                    // Split at the cut ray (+u); the halves meet at v = 0.
                    push(self, pa, m);
                    push(self, m, pb);
                } else {
                    push(self, pa, pb);
                }
            } else if av <= 0.0 && bv <= 0.0 {
                // Entirely outside the open half-plane v > 0.
                continue;
            } else if av >= 0.0 && bv >= 0.0 {
                push(self, pa, pb);
            } else {
                // Perpendicular to the half-plane's boundary: clip at v = 0.
                push(self, m, if av > 0.0 { pa } else { pb });
            }
        }
        if self.events.is_empty() {
            return;
        }
        self.events.sort_unstable_by(|x, y| x.key.total_cmp(&y.key));
        self.active.clear();
        let n = self.events.len();
        let mut i = 0;
        // The span under construction: (piece, start key, start vertex).
        let mut open: Option<(u32, f64, [f64; 2])> = None;
        while i < n {
            let key = self.events[i].key;
            let vertex = self.events[i].vertex;
            while i < n && self.events[i].key == key {
                let ev = self.events[i];
                if ev.insert {
                    self.active.push(ev.piece);
                } else if let Some(pos) = self.active.iter().position(|&a| a == ev.piece) {
                    self.active.swap_remove(pos);
                }
                i += 1;
            }
            // Nearest active piece on the interval (key, next key).
            let nearest = if i < n && !self.active.is_empty() {
                let (du, dv) = diamond_dir(0.5 * (key + self.events[i].key));
                let mut best = u32::MAX;
                let mut best_t = f64::INFINITY;
                for &a in &self.active {
                    let pc = &self.pieces[a as usize];
                    let t = if pc.u_const { pc.c / du } else { pc.c / dv };
                    if t < best_t || (t == best_t && a < best) {
                        best_t = t;
                        best = a;
                    }
                }
                Some(best)
            } else {
                None
            };
            let cur = open.map(|o| o.0);
            if cur != nearest {
                if let Some((pc, k0, v0)) = open.take() {
                    self.emit(edges, p, pc, k0, v0, key, vertex, out);
                }
                if let Some(pc) = nearest {
                    open = Some((pc, key, vertex));
                }
            }
        }
        debug_assert!(open.is_none(), "the last event closes every span");
    }

    #[allow(clippy::too_many_arguments)]
    fn emit(&self, edges: &[Edge], p: [f64; 2], piece: u32, k0: f64, v0: [f64; 2], k1: f64, v1: [f64; 2], out: &mut Vec<Span>) {
        let pc = &self.pieces[piece as usize];
        let e = &edges[pc.edge as usize];
        let line = e.line();
        let axis = |k: f64, v: [f64; 2]| -> f64 {
            if k == pc.ka {
                return pc.sa;
            }
            if k == pc.kb {
                return pc.sb;
            }
            let s = if e.normal.is_vertical_edge() {
                if v[0] == line { v[1] } else { p[1] + (v[1] - p[1]) * (line - p[0]) / (v[0] - p[0]) }
            } else if v[1] == line {
                v[0]
            } else {
                p[0] + (v[0] - p[0]) * (line - p[1]) / (v[1] - p[1])
            };
            s.clamp(pc.s_lo, pc.s_hi)
        };
        let (a, b) = (axis(k0, v0), axis(k1, v1));
        let (s0, s1) = if a <= b { (a, b) } else { (b, a) };
        if s1 > s0 {
            out.push(Span { edge: pc.edge, s0, s1, k0, k1 });
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
            (self.y0 as f64, self.y1 as f64, self.x0 as f64, self.x1 as f64)
        } else {
            (self.x0 as f64, self.x1 as f64, self.y0 as f64, self.y1 as f64)
        };
        let da = (r_lo - hi).max(lo - r_hi).max(0.0);
        let dp = (p_lo - line).max(line - p_hi).max(0.0);
        da.hypot(dp)
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

/// True when every segment from a point of the closed rectangle `r` to a
/// point of edge `e` crosses the straight run `s` (touching counts): then no
/// point of `r` sees any part of `e`. Exact integer arithmetic.
///
/// Each such segment crosses the run's line once (the rectangle is on the
/// front side, the edge behind). The crossing coordinate is a
/// linear-fractional function of each endpoint, so over the rectangle and the
/// edge its extremes are reached at their vertices: checking the 4 x 2 vertex
/// pairs is exact.
pub fn run_hides(r: &Rect, e: &Edge, s: &Run) -> bool {
    let vertical = s.normal.is_vertical_edge();
    let sign: i64 = if matches!(s.normal, Normal::Right | Normal::Down) { 1 } else { -1 };
    // (perpendicular coordinate, along coordinate) of a point.
    let split = |x: i64, y: i64| if vertical { (x, y) } else { (y, x) };
    let line = s.line as i64;
    let corners = [(r.x0, r.y0), (r.x1, r.y0), (r.x0, r.y1), (r.x1, r.y1)].map(|(x, y)| {
        let (pp, al) = split(x as i64, y as i64);
        ((pp - line) * sign, al)
    });
    let ends = [e.a, e.b].map(|q| {
        let (pp, al) = split(q[0] as i64, q[1] as i64);
        ((pp - line) * sign, al)
    });
    if corners.iter().any(|c| c.0 < 0) || ends.iter().any(|q| q.0 > 0) {
        return false;
    }
    let (lo, hi) = (s.lo as i64, s.hi as i64);
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

/// How far each edge's light matters, by edge index (`f64::INFINITY`: everywhere).
pub type Reach<'a> = &'a (dyn Fn(u32) -> f64 + Sync);

/// Candidate edge lists for square tiles of pixels.
pub struct TileTree<'g> {
    pub geometry: &'g Geometry,
    /// Side of a leaf tile in pixels.
    pub leaf: i32,
    /// Bounding box of each free-space component.
    comp_bbox: Vec<Rect>,
}

impl<'g> TileTree<'g> {
    pub const LEAF: i32 = 8;

    pub fn new(geometry: &'g Geometry) -> Self {
        let mut comp_bbox =
            vec![Rect { x0: i32::MAX, y0: i32::MAX, x1: i32::MIN, y1: i32::MIN }; geometry.component_count as usize];
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
        TileTree { geometry, leaf: Self::LEAF, comp_bbox }
    }

    /// Calls `visit(tile, candidates)` for every leaf tile for which `wants`
    /// holds, in parallel. `candidates` is conservative: every edge that any
    /// point of the tile (pixel centres and points on the tile's edges) can
    /// see is in it. `reach(e)` bounds how far edge `e` matters.
    pub fn for_each_leaf<W, V>(&self, wants: &W, reach: Reach, visit: &V)
    where
        W: Fn(Rect) -> bool + Sync,
        V: Fn(Rect, &[u32]) + Sync,
    {
        let g = self.geometry;
        let mut size = self.leaf;
        while size < g.width.max(g.height) as i32 {
            size *= 2;
        }
        let root = Rect { x0: 0, y0: 0, x1: g.width as i32, y1: g.height as i32 };
        let all: Vec<u32> = (0..g.edges.len() as u32).collect();
        self.node(root, size, &all, wants, reach, visit);
    }

    fn node<W, V>(&self, r: Rect, size: i32, parent: &[u32], wants: &W, reach: Reach, visit: &V)
    where
        W: Fn(Rect) -> bool + Sync,
        V: Fn(Rect, &[u32]) + Sync,
    {
        if r.is_empty() || !wants(r) {
            return;
        }
        let g = self.geometry;
        let mut cands: Vec<u32> = parent
            .iter()
            .copied()
            .filter(|&ei| {
                let e = &g.edges[ei as usize];
                r.sees_front_of(e) && self.comp_bbox[e.component as usize].intersects(&r) && {
                    let lim = reach(ei);
                    lim.is_infinite() || r.distance_to(e) <= lim
                }
            })
            .collect();
        if size <= 4 * self.leaf {
            cands = self.cull_hidden(r, cands);
        }
        if size <= self.leaf {
            visit(r, &cands);
            return;
        }
        let h = size / 2;
        let kids = [
            Rect { x0: r.x0, y0: r.y0, x1: (r.x0 + h).min(r.x1), y1: (r.y0 + h).min(r.y1) },
            Rect { x0: r.x0 + h, y0: r.y0, x1: r.x1, y1: (r.y0 + h).min(r.y1) },
            Rect { x0: r.x0, y0: r.y0 + h, x1: (r.x0 + h).min(r.x1), y1: r.y1 },
            Rect { x0: r.x0 + h, y0: r.y0 + h, x1: r.x1, y1: r.y1 },
        ];
        rayon::scope(|s| {
            for k in kids {
                let cands = &cands;
                s.spawn(move |_| self.node(k, h, cands, wants, reach, visit));
            }
        });
    }

    /// Drops the candidates that one straight run provably hides from all of
    /// `r`. Occluders are looked for among the runs that a free point near the
    /// middle of `r` sees in the direction of the candidate.
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
        let mut sweeper = Sweeper::new();
        let mut spans = Vec::new();
        let mut keep = vec![true; cands.len()];
        for &(comp, _, px) in &reps {
            let q = [px[0] as f64 + 0.5, px[1] as f64 + 0.5];
            spans.clear();
            sweeper.sweep(&g.edges, &cands, q, View::Full, comp, &mut spans);
            if spans.is_empty() {
                continue;
            }
            let owner = |k: f64| -> Option<u32> {
                let i = spans.partition_point(|s| s.k1 <= k);
                spans.get(i).filter(|s| s.k0 <= k).map(|s| g.edges[s.edge as usize].run)
            };
            for (i, &ei) in cands.iter().enumerate() {
                let e = &g.edges[ei as usize];
                if e.component != comp || !keep[i] {
                    continue;
                }
                let (lo, hi) = e.extent();
                let mut tried: [u32; 3] = [u32::MAX; 3];
                for (t, s) in [0.5 * (lo + hi), lo + 0.25 * (hi - lo), hi - 0.25 * (hi - lo)].into_iter().enumerate() {
                    let pt = e.point_at(s);
                    let k = diamond(pt[0] - q[0], pt[1] - q[1]);
                    let Some(run) = owner(k) else { continue };
                    if tried.contains(&run) || run == e.run {
                        continue;
                    }
                    tried[t] = run;
                    if run_hides(&r, e, &g.runs[run as usize]) {
                        keep[i] = false;
                        break;
                    }
                }
            }
        }
        cands.into_iter().zip(keep).filter_map(|(c, k)| k.then_some(c)).collect()
    }
}
