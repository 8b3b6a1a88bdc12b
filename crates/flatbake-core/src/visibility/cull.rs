//! Exact, conservative culling tests: when one straight wall run or one
//! rectangle of solid pixels blocks every segment from a region to an edge.

use super::*;

/// An axis-aligned rectangle of pixels `[x0, x1) x [y0, y1)`; as a region of
/// the plane it is the closed rectangle `[x0, x1] x [y0, y1]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    /// Left column (inclusive).
    pub x0: i32,
    /// Top row (inclusive).
    pub y0: i32,
    /// Right column (exclusive).
    pub x1: i32,
    /// Bottom row (exclusive).
    pub y1: i32,
}

impl Rect {
    /// Columns covered.
    pub fn width(&self) -> i32 {
        self.x1 - self.x0
    }
    /// Rows covered.
    pub fn height(&self) -> i32 {
        self.y1 - self.y0
    }
    /// Covers no pixel.
    pub fn is_empty(&self) -> bool {
        self.x1 <= self.x0 || self.y1 <= self.y0
    }
    pub(super) fn intersects(&self, o: &Rect) -> bool {
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
    /// Left side, half pixels.
    pub x0: i64,
    /// Top side, half pixels.
    pub y0: i64,
    /// Right side, half pixels.
    pub x1: i64,
    /// Bottom side, half pixels.
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
    pub(super) fn solid(r: &Rect) -> Zone {
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
    pub(super) fn meets(&self, o: &Zone) -> bool {
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
pub(super) struct SolidBoxes {
    pub(super) rects: Vec<Rect>,
    /// The boxes behind edge `e`: `list[start[e]..start[e + 1]]`.
    start: Vec<u32>,
    list: Vec<u32>,
}

impl SolidBoxes {
    pub(super) fn new(g: &Geometry) -> SolidBoxes {
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

    pub(super) fn behind(&self, e: u32) -> &[u32] {
        &self.list[self.start[e as usize] as usize..self.start[e as usize + 1] as usize]
    }
}

/// The arc of pseudo-angles that `points` span as seen from `q`, as
/// `(start, end)` with `start` in `[0, 4)` and `end - start < 2`, for points
/// that lie within less than a half turn (pseudo-angle 2) of each other, as
/// the corners of a box or the ends of an edge that do not hold `q` do.
pub(super) fn arc(q: [f64; 2], points: &[[f64; 2]]) -> (f64, f64) {
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
pub(super) const ARC_SLACK: f64 = 1e-9;

/// Does arc `outer` hold arc `inner` (with a margin for rounding: this only
/// picks which boxes to test exactly)?
#[inline]
pub(super) fn arc_holds(outer: (f64, f64), inner: (f64, f64)) -> bool {
    // Both start in [0, 4); the inner one may sit a turn later.
    let (a, b) = if inner.0 < outer.0 - ARC_SLACK {
        (inner.0 + 4.0, inner.1 + 4.0)
    } else {
        inner
    };
    a >= outer.0 - ARC_SLACK && b <= outer.1 + ARC_SLACK
}
