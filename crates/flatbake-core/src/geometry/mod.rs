//! Geometry: the exact boundary of the solid pixels, traced into closed loops
//! of right-facing edges (docs/transport.md#edges).
//!
//! Every exposed side of a solid pixel becomes a unit edge whose normal points
//! into the free neighbour (or out of the image). Unit edges are linked into
//! closed loops; where two solid pixels touch only at a corner (a marching
//! squares saddle) each loop keeps following its own pixel, so the two pixels
//! stay separate solids and their boundaries meet at the shared corner point:
//! no light can pass between them because the corner is part of both.
//! Collinear runs of one material are merged into one [`Edge`]; a run splits
//! where the solid pixel's material changes.
//!
//! Free pixels (floor and void) are labelled with 4-connected components.
//! Light never passes between components: two free pixels that touch only at
//! a corner are separated by the two solid pixels that own that corner.

use serde::{Deserialize, Serialize};

use crate::level::{Cell, Level};

/// Direction of an edge's normal, pointing from the solid into free space.
/// Image coordinates: x to the right, y down, so `Up` is `-y`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Normal {
    /// Free space to the left (`-x`).
    Left,
    /// Free space to the right (`+x`).
    Right,
    /// Free space above (`-y`).
    Up,
    /// Free space below (`+y`).
    Down,
}

impl Normal {
    /// Unit vector of the normal.
    pub fn vec(self) -> [i32; 2] {
        match self {
            Normal::Left => [-1, 0],
            Normal::Right => [1, 0],
            Normal::Up => [0, -1],
            Normal::Down => [0, 1],
        }
    }

    /// Direction of travel along an edge with this normal: the normal is on the
    /// right of the travel direction, `n = (-d.y, d.x)`.
    pub fn travel(self) -> [i32; 2] {
        let n = self.vec();
        [n[1], -n[0]]
    }

    /// True for edges that lie on a vertical line (`x` = const).
    pub fn is_vertical_edge(self) -> bool {
        matches!(self, Normal::Left | Normal::Right)
    }

    /// `+1` when the normal points along `+x` or `+y`, else `-1`.
    pub fn sign(self) -> f64 {
        match self {
            Normal::Right | Normal::Down => 1.0,
            Normal::Left | Normal::Up => -1.0,
        }
    }

    /// The four normals.
    pub const ALL: [Normal; 4] = [Normal::Left, Normal::Right, Normal::Up, Normal::Down];
}

/// A maximal straight run of one material on a loop: the unit of transport.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Edge {
    /// Start and end points in level units, `a -> b` with the normal on the right.
    pub a: [i32; 2],
    /// End point (see `a`).
    pub b: [i32; 2],
    /// Which side the free space is on.
    pub normal: Normal,
    /// Index into [`Level::materials`].
    pub material: u16,
    /// The loop this edge belongs to.
    pub loop_id: u32,
    /// The straight occluder run (collinear edges of any material) it belongs to.
    pub run: u32,
    /// Component of the free pixels in front of the edge.
    pub component: u32,
    /// Its loop is a rectangle (four edges, one per side): the
    /// solid behind two of its edges that meet at a convex corner fills
    /// the triangle between them.
    #[serde(default)]
    pub rectangle: bool,
}

impl Edge {
    /// Length in level units (edges are axis-aligned).
    pub fn len(&self) -> f64 {
        ((self.b[0] - self.a[0]).abs() + (self.b[1] - self.a[1]).abs()) as f64
    }

    /// Has zero length.
    pub fn is_empty(&self) -> bool {
        self.a == self.b
    }

    /// The constant coordinate of the edge's line (`x` for vertical edges).
    pub fn line(&self) -> f64 {
        if self.normal.is_vertical_edge() {
            self.a[0] as f64
        } else {
            self.a[1] as f64
        }
    }

    /// Extent along the edge's axis, `lo < hi` (`y` range for vertical edges).
    pub fn extent(&self) -> (f64, f64) {
        let (p, q) = if self.normal.is_vertical_edge() {
            (self.a[1], self.b[1])
        } else {
            (self.a[0], self.b[0])
        };
        (p.min(q) as f64, p.max(q) as f64)
    }

    /// Signed distance of point `p` in front of the edge's line (`> 0` in front).
    pub fn front_distance(&self, p: [f64; 2]) -> f64 {
        let n = self.normal;
        if n.is_vertical_edge() {
            (p[0] - self.line()) * n.sign()
        } else {
            (p[1] - self.line()) * n.sign()
        }
    }

    /// Squared distance from point `p` to the closed segment.
    #[inline]
    pub fn distance_sq(&self, p: [f64; 2]) -> f64 {
        let (lo, hi) = self.extent();
        let s = if self.normal.is_vertical_edge() {
            p[1]
        } else {
            p[0]
        };
        let along = (lo - s).max(s - hi).max(0.0);
        let d = self.front_distance(p);
        d * d + along * along
    }

    /// The point of the edge at axis coordinate `s`.
    pub fn point_at(&self, s: f64) -> [f64; 2] {
        if self.normal.is_vertical_edge() {
            [self.line(), s]
        } else {
            [s, self.line()]
        }
    }

    /// The solid pixel behind the unit segment of the edge that starts at axis
    /// coordinate `s` (an integer between `lo` and `hi - 1`).
    pub fn solid_pixel_at(&self, s: i32) -> [i32; 2] {
        let c = self.line() as i32;
        match self.normal {
            Normal::Left => [c, s],
            Normal::Right => [c - 1, s],
            Normal::Up => [s, c],
            Normal::Down => [s, c - 1],
        }
    }

    /// The free pixel in front of the unit segment that starts at `s`.
    pub fn free_pixel_at(&self, s: i32) -> [i32; 2] {
        let p = self.solid_pixel_at(s);
        let n = self.normal.vec();
        [p[0] + n[0], p[1] + n[1]]
    }
}

/// A closed loop of unit edges, merged into edges.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Loop {
    /// Vertices in travel order; the loop closes from the last back to the first.
    pub vertices: Vec<[i32; 2]>,
    /// Every merged edge of the loop in order, including edges facing out of
    /// the image (those are not transport edges).
    pub edges: Vec<LoopEdge>,
}

/// A merged edge as it sits in its loop.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoopEdge {
    /// Start point, level units.
    pub a: [i32; 2],
    /// End point, level units.
    pub b: [i32; 2],
    /// Which side the free space is on.
    pub normal: Normal,
    /// Index into [`Level::materials`].
    pub material: u16,
    /// Index into [`Geometry::edges`], or `None` when the edge faces out of the image.
    pub transport: Option<u32>,
}

/// A straight occluder: collinear consecutive transport edges of one loop,
/// whatever their materials. Used to prove that whole regions are hidden.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Run {
    /// Which side the free space is on.
    pub normal: Normal,
    /// Line coordinate (`x` for vertical runs).
    pub line: i32,
    /// First coordinate along the line covered.
    pub lo: i32,
    /// Last coordinate along the line covered.
    pub hi: i32,
}

/// The traced level.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Geometry {
    /// Level width in pixels.
    pub width: usize,
    /// Level height in pixels.
    pub height: usize,
    /// Transport edges: every merged edge that faces into the image.
    pub edges: Vec<Edge>,
    /// Closed boundary loops between solid pixels and the rest, each traced once.
    pub loops: Vec<Loop>,
    /// Straight occluder runs, for culling ([`crate::visibility::run_hides`]).
    pub runs: Vec<Run>,
    /// Component label per pixel (`u32::MAX` for solid pixels).
    pub components: Vec<u32>,
    /// Number of free-space components.
    pub component_count: u32,
    /// Pixels per painted pixel: 1, or the upscale factor of a texel bake.
    /// Visibility's blocks are [`crate::visibility::Blocks::SIZE`] (or
    /// [`crate::visibility::Blocks::DENSE_SIZE`]) painted pixels, so a
    /// finer bake does not walk more of them per point.
    pub unit: usize,
}

impl Geometry {
    /// Component of the free pixel `(x, y)`, `None` if solid or outside.
    pub fn component_at(&self, x: i64, y: i64) -> Option<u32> {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return None;
        }
        let c = self.components[y as usize * self.width + x as usize];
        (c != u32::MAX).then_some(c)
    }

    /// Total length of the transport edges.
    pub fn perimeter(&self) -> f64 {
        self.edges.iter().map(Edge::len).sum()
    }
}

/// A unit boundary segment, before merging.
#[derive(Clone, Copy, Debug)]
struct Unit {
    from: [i32; 2],
    normal: Normal,
    /// The solid pixel this side belongs to.
    pixel: [i32; 2],
    material: u16,
}

impl Unit {
    fn to(&self) -> [i32; 2] {
        let d = self.normal.travel();
        [self.from[0] + d[0], self.from[1] + d[1]]
    }
}

/// Traces the solid pixels of `level` into loops and transport edges.
pub fn trace(level: &Level) -> Geometry {
    // Steps 1-4 on one worker while the other labels step 5's components
    // (on wall noise at 512 px, 30 ms and 5 ms).
    let ((loops, mut edges, runs), (components, component_count)) = rayon::join(
        || {
            // 1. Every exposed side of a solid pixel, as a directed unit edge.
            let units = exposed_sides(level);
            // 2, 3. Unit edges linked into loops, collinear runs of one
            //    material merged into edges.
            let (loops, mut edges) = link_loops(level.width as i32, level.height as i32, &units);
            // 4. Straight occluder runs.
            let runs = straight_runs(&loops, &mut edges);
            (loops, edges, runs)
        },
        || label_components(level),
    );
    for lp in loops.iter().filter(|lp| lp.edges.len() == 4) {
        for le in &lp.edges {
            if let Some(t) = le.transport {
                edges[t as usize].rectangle = true;
            }
        }
    }

    // 5. Components of free pixels, 4-connected.
    for e in &mut edges {
        let (lo, _) = e.extent();
        let fp = e.free_pixel_at(lo as i32);
        e.component = components[fp[1] as usize * level.width + fp[0] as usize];
    }

    Geometry {
        width: level.width,
        height: level.height,
        edges,
        loops,
        runs,
        components,
        component_count,
        unit: 1,
    }
}

/// Every exposed side of a solid pixel, as a directed unit edge.
fn exposed_sides(level: &Level) -> Vec<Unit> {
    let (w, h) = (level.width as i32, level.height as i32);
    let solid = |x: i32, y: i32| {
        x >= 0 && y >= 0 && x < w && y < h && level.cell(x as usize, y as usize).is_solid()
    };

    let mut units: Vec<Unit> = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let Cell::Solid(m) = level.cell(x as usize, y as usize) else {
                continue;
            };
            for n in Normal::ALL {
                let v = n.vec();
                if solid(x + v[0], y + v[1]) {
                    continue;
                }
                // Start point: travel keeps the normal on the right.
                let from = match n {
                    Normal::Up => [x + 1, y],
                    Normal::Left => [x, y],
                    Normal::Down => [x, y + 1],
                    Normal::Right => [x + 1, y + 1],
                };
                units.push(Unit {
                    from,
                    normal: n,
                    pixel: [x, y],
                    material: m,
                });
            }
        }
    }

    units
}

/// Links unit edges at their vertices into closed loops, and merges
/// collinear runs of one material into edges: the loops, and the transport
/// edges among them (those facing into the image).
fn link_loops(width: i32, height: i32, units: &[Unit]) -> (Vec<Loop>, Vec<Edge>) {
    let (w, h) = (width, height);
    // Link unit edges at their vertices. A vertex has one outgoing unit
    //    edge, or two at a saddle; there the loop stays on its own pixel.
    let vw = (w + 1) as usize;
    let vid = |p: [i32; 2]| p[1] as usize * vw + p[0] as usize;
    let mut out_first: Vec<u32> = vec![u32::MAX; vw * (h as usize + 1)];
    let mut out_second: Vec<u32> = vec![u32::MAX; vw * (h as usize + 1)];
    for (i, u) in units.iter().enumerate() {
        let v = vid(u.from);
        if out_first[v] == u32::MAX {
            out_first[v] = i as u32;
        } else {
            out_second[v] = i as u32;
        }
    }
    let next = |i: usize| -> usize {
        let u = &units[i];
        let v = vid(u.to());
        let (a, b) = (out_first[v], out_second[v]);
        if b != u32::MAX && units[b as usize].pixel == u.pixel {
            b as usize
        } else if b != u32::MAX && units[a as usize].pixel != u.pixel {
            // Neither continues this pixel (cannot happen for a saddle); keep
            // the first for determinism.
            a as usize
        } else {
            a as usize
        }
    };

    let mut visited = vec![false; units.len()];
    let mut loops: Vec<Loop> = Vec::new();
    let mut edges: Vec<Edge> = Vec::new();
    // One buffer for every chain (wall noise has tens of thousands of
    // small loops).
    let mut chain = Vec::new();
    for start in 0..units.len() {
        if visited[start] {
            continue;
        }
        chain.clear();
        let mut i = start;
        while !visited[i] {
            visited[i] = true;
            chain.push(i);
            i = next(i);
        }
        debug_assert_eq!(i, start, "unit edges always close into loops");
        let lp = merge_chain(units, &mut chain, [w, h], loops.len() as u32, &mut edges);
        loops.push(lp);
    }

    (loops, edges)
}

/// One closed chain of unit edges (indices into `units`) as a loop:
/// collinear runs of one material merged into edges; those facing into the
/// `size` of the image are appended to `edges` as transport edges.
fn merge_chain(
    units: &[Unit],
    chain: &mut [usize],
    [w, h]: [i32; 2],
    loop_id: u32,
    edges: &mut Vec<Edge>,
) -> Loop {
    // Rotate the chain so that it starts at a break, so no run wraps
    // around the start.
    let brk = |k: usize| {
        let p = &units[chain[(k + chain.len() - 1) % chain.len()]];
        let q = &units[chain[k]];
        p.normal != q.normal || p.material != q.material
    };
    let s = (0..chain.len()).find(|&k| brk(k)).unwrap_or(0);
    // As many runs as breaks (a loop turns, so it has some).
    let runs = (s..chain.len()).filter(|&k| brk(k)).count().max(1);
    chain.rotate_left(s);
    let mut lp = Loop {
        vertices: Vec::with_capacity(runs),
        edges: Vec::with_capacity(runs),
    };
    let mut k = 0;
    while k < chain.len() {
        let first = units[chain[k]];
        let mut last = first;
        let mut j = k + 1;
        while j < chain.len() {
            let u = units[chain[j]];
            if u.normal != first.normal || u.material != first.material {
                break;
            }
            last = u;
            j += 1;
        }
        let (a, b) = (first.from, last.to());
        let n = first.normal.vec();
        let fp = [first.pixel[0] + n[0], first.pixel[1] + n[1]];
        let outside = fp[0] < 0 || fp[1] < 0 || fp[0] >= w || fp[1] >= h;
        let transport = if outside {
            None
        } else {
            edges.push(Edge {
                a,
                b,
                normal: first.normal,
                material: first.material,
                loop_id,
                run: u32::MAX,
                component: u32::MAX,
                rectangle: false,
            });
            Some(edges.len() as u32 - 1)
        };
        lp.vertices.push(a);
        lp.edges.push(LoopEdge {
            a,
            b,
            normal: first.normal,
            material: first.material,
            transport,
        });
        k = j;
    }
    lp
}

/// Straight occluder runs: consecutive collinear transport edges of a loop.
/// Sets each member edge's `run`.
fn straight_runs(loops: &[Loop], edges: &mut [Edge]) -> Vec<Run> {
    let mut runs: Vec<Run> = Vec::new();
    for lp in loops {
        let n = lp.edges.len();
        // Start at an edge whose predecessor is not a collinear transport edge.
        let joins = |k: usize| {
            let p = &lp.edges[(k + n - 1) % n];
            let q = &lp.edges[k];
            p.normal == q.normal && p.transport.is_some() && q.transport.is_some()
        };
        let Some(s) = (0..n).find(|&k| !joins(k)) else {
            // A loop that is one straight run cannot exist (loops turn).
            continue;
        };
        let mut k = 0;
        while k < n {
            let e = &lp.edges[(s + k) % n];
            let Some(first) = e.transport else {
                k += 1;
                continue;
            };
            let mut members = vec![first];
            let mut j = k + 1;
            while j < n && joins((s + j) % n) {
                members.push(
                    lp.edges[(s + j) % n]
                        .transport
                        .expect("joined edges are transport edges"),
                );
                j += 1;
            }
            let id = runs.len() as u32;
            let (mut lo, mut hi) = (i32::MAX, i32::MIN);
            for &m in &members {
                let (l, h) = edges[m as usize].extent();
                lo = lo.min(l as i32);
                hi = hi.max(h as i32);
                edges[m as usize].run = id;
            }
            let e0 = &edges[first as usize];
            runs.push(Run {
                normal: e0.normal,
                line: e0.line() as i32,
                lo,
                hi,
            });
            k = j;
        }
    }

    runs
}

/// 4-connected components of the free (non-solid) pixels.
fn label_components(level: &Level) -> (Vec<u32>, u32) {
    let (w, h) = (level.width, level.height);
    let mut label = vec![u32::MAX; w * h];
    let mut count = 0u32;
    let mut stack = Vec::new();
    for start in 0..w * h {
        if label[start] != u32::MAX || level.cells[start].is_solid() {
            continue;
        }
        label[start] = count;
        stack.push(start);
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            let mut visit = |j: usize| {
                if label[j] == u32::MAX && !level.cells[j].is_solid() {
                    label[j] = count;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
            }
        }
        count += 1;
    }
    (label, count)
}
