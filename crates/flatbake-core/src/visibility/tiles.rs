//! Candidate edge lists per free region of every tile, refined down a quadtree.

use super::cull::{ARC_SLACK, SolidBoxes, arc, arc_holds};
use super::*;

/// Query points per rectangle, to weigh culled pairs (0: nothing to do there).
pub type Count<'a> = &'a (dyn Fn(Rect) -> u64 + Sync);

/// What stays the same all the way down one [`TileTree::for_each_leaf`].
struct Descent<'a, V> {
    count: Count<'a>,
    reach_max: f64,
    /// (edge, point) pairs dropped as beyond `reach_max`, so far.
    culled: std::sync::atomic::AtomicU64,
    visit: &'a V,
}

/// Candidate edge lists for square tiles of pixels.
pub struct TileTree<'g> {
    /// The geometry whose edges the lists index.
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
    /// The leaf tile.
    pub rect: Rect,
    /// Region of each pixel of `rect`, row-major; `u8::MAX` for solid pixels.
    pub label: Vec<u8>,
    /// The regions, indexed by `label`.
    pub regions: Vec<Region>,
}

/// One free region of a leaf tile.
pub struct Region {
    /// Bounding box of the region's pixels.
    pub bbox: Rect,
    /// Free-space component of its pixels.
    pub component: u32,
    /// A short candidate list for [`Sweeper::sweep`], or `None`: use [`Sweeper::walk`].
    pub candidates: Option<Vec<u32>>,
    /// The list is long (over [`TileTree::SWEEP_SHORT`]) and culling left
    /// it almost whole: the region's first point sweeps it if it is at
    /// most [`TileTree::SWEEP_FIRST`] long and walks otherwise, and the
    /// others sweep only if it saw at least half the list.
    pub open: bool,
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
    /// Side of a leaf tile in pixels.
    pub const LEAF: i32 = 8;

    /// Longest candidate list a region sweeps; longer ones walk the blocks.
    pub const SWEEP_MAX: usize = 1024;
    /// Longest list a region sweeps whatever culling removed from it.
    pub const SWEEP_SHORT: usize = 192;
    /// Longest open list ([`Region::open`]) that a region's first point
    /// sweeps rather than walks. On open ground the walk visits every
    /// block (in a field of 200 lamps a pixel that walks takes 2.3 times
    /// as long as one that sweeps its list of about 400 edges); where a
    /// point sees little of its list (a courtyard's lists of about 960
    /// edges, of which a point sees 6 %) the walk stops early and the
    /// sweep would be wasted (measured: that courtyard 8 % slower with
    /// every list swept first).
    pub const SWEEP_FIRST: usize = 512;
    /// Longest list culled for hidden edges (`TileTree::cull_hidden`).
    pub const CULL_MAX: usize = 768;
    /// Longest list a quadtree node keeps refining; above it the subtree walks.
    pub const REFINE_MAX: usize = 3000;
    /// Fewest query points in a leaf for its regions' lists to be culled
    /// for hidden edges (`TileTree::cull_hidden`).
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
                    let seen = mine.len();
                    let mine = if seen <= Self::CULL_MAX && points >= Self::CULL_MIN_POINTS {
                        self.cull_hidden(bbox, mine)
                    } else {
                        mine
                    };
                    // A long list that culling left almost whole may be
                    // open ground, where the walk would visit every block
                    // and one sort of the list costs less: kept, and swept
                    // if the region's first point sees most of it
                    // (`Region::open`).
                    let whole = 4 * mine.len() > 3 * seen;
                    (mine.len() <= Self::SWEEP_SHORT || (whole && mine.len() <= Self::SWEEP_MAX))
                        .then_some(mine)
                });
                let open = candidates
                    .as_ref()
                    .is_some_and(|c| c.len() > Self::SWEEP_SHORT);
                regions.push(Region {
                    bbox,
                    component,
                    candidates,
                    open,
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
        let descent = Descent {
            count,
            reach_max,
            culled: std::sync::atomic::AtomicU64::new(0),
            visit,
        };
        self.node(root, size, Some(&all), &descent);
        descent.culled.into_inner()
    }

    /// `parent`: the parent's candidates, or `None` when they were too many
    /// to be worth refining (the subtree walks).
    fn node<V>(&self, r: Rect, size: i32, parent: Option<&[u32]>, descent: &Descent<V>)
    where
        V: Fn(&LeafRegions) + Sync,
    {
        let Descent {
            count,
            reach_max,
            ref culled,
            visit,
        } = *descent;
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
                s.spawn(move |_| self.node(k, h, cands, descent));
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
            let q = super::centre(px);
            spans.clear();
            sweeper.sweep(&g.edges, cands, Viewpoint::new(q, View::Full, comp), spans);
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
