//! Visibility for many query points at once: points bucketed by tile, and
//! the driver that runs the right query (sweep or walk) for each point in
//! parallel over the leaf tiles of a [`TileTree`].

use std::cell::RefCell;
use std::sync::OnceLock;

use rayon::prelude::*;

use crate::geometry::Geometry;
use crate::visibility::{
    Blocks, Reachable, Reaches, Rect, Span, Sweeper, TileTree, View, Viewpoint, Wanted,
};

/// Query points bucketed by leaf tile, with a summed-area table of the
/// leaves' counts to answer "how many points does this tile hold" in
/// constant time.
pub struct PointGrid {
    leaves_x: usize,
    leaves_y: usize,
    leaf: usize,
    /// `sat[ly * (leaves_x + 1) + lx]`: the points of the leaves left of
    /// `lx` and above `ly`. Per leaf, not per pixel: a pass over a few
    /// points of a big level does not fill a table the level's size.
    sat: Vec<u32>,
    /// Points of leaf `l` are `order[start[l]..start[l + 1]]`.
    start: Vec<usize>,
    order: Vec<u32>,
}

impl PointGrid {
    /// `pixels[i]` is the pixel that query point `i` belongs to.
    pub fn new(width: usize, height: usize, leaf: usize, pixels: &[[i32; 2]]) -> PointGrid {
        let leaves_x = width.div_ceil(leaf);
        let leaves_y = height.div_ceil(leaf);
        let leaves = leaves_x * leaves_y;
        let mut start = vec![0usize; leaves + 1];
        // Each point's leaf, found on the workers (two divisions a point;
        // wall noise's form factors have 500,000 points).
        let leaf_of: Vec<u32> = pixels
            .par_iter()
            .map(|p| ((p[1] as usize / leaf) * leaves_x + p[0] as usize / leaf) as u32)
            .collect();
        for &l in &leaf_of {
            start[l as usize + 1] += 1;
        }
        let w = leaves_x + 1;
        let mut sat = vec![0u32; w * (leaves_y + 1)];
        for ly in 0..leaves_y {
            for lx in 0..leaves_x {
                let i = (ly + 1) * w + lx + 1;
                sat[i] =
                    start[ly * leaves_x + lx + 1] as u32 + sat[i - 1] + sat[i - w] - sat[i - w - 1];
            }
        }
        for l in 0..leaves {
            start[l + 1] += start[l];
        }
        let mut fill = start.clone();
        let mut order = vec![0u32; pixels.len()];
        for (i, &l) in leaf_of.iter().enumerate() {
            order[fill[l as usize]] = i as u32;
            fill[l as usize] += 1;
        }
        drop(leaf_of);
        // Within a leaf, rows alternate direction, so that each point is a
        // neighbour of the one before (the sweep reuses its event order).
        // (Leaf by leaf on the workers: several ms on one core for the
        // points of wall noise.)
        let mut by_leaf: Vec<&mut [u32]> = Vec::with_capacity(leaves);
        let mut rest = order.as_mut_slice();
        for l in 0..leaves {
            let (this, after) = rest.split_at_mut(start[l + 1] - start[l]);
            by_leaf.push(this);
            rest = after;
        }
        by_leaf.into_par_iter().for_each(|points| {
            points.sort_by_key(|&i| {
                let p = pixels[i as usize];
                (p[1], if p[1] % 2 == 0 { p[0] } else { -p[0] })
            })
        });
        PointGrid {
            leaves_x,
            leaves_y,
            leaf,
            sat,
            start,
            order,
        }
    }

    /// Number of points in the rectangle, whose sides lie on the leaves'
    /// grid or on the level's right and bottom sides (every tile of a
    /// [`TileTree`] does).
    pub fn count_in(&self, r: Rect) -> u64 {
        let leaf = self.leaf as i32;
        debug_assert!(
            r.x0 % leaf == 0 && r.y0 % leaf == 0,
            "{r:?} is not on the leaves' grid"
        );
        let (x0, y0) = ((r.x0 / leaf) as usize, (r.y0 / leaf) as usize);
        let x1 = (r.x1.max(0) as usize)
            .div_ceil(self.leaf)
            .min(self.leaves_x);
        let y1 = (r.y1.max(0) as usize)
            .div_ceil(self.leaf)
            .min(self.leaves_y);
        let w = self.leaves_x + 1;
        let at = |x: usize, y: usize| self.sat[y * w + x] as i64;
        (at(x1, y1) - at(x0, y1) - at(x1, y0) + at(x0, y0)) as u64
    }

    /// Points of the leaf tile whose top-left pixel is `(r.x0, r.y0)`.
    pub fn in_leaf(&self, r: Rect) -> &[u32] {
        let l = (r.y0 as usize / self.leaf) * self.leaves_x + r.x0 as usize / self.leaf;
        &self.order[self.start[l]..self.start[l + 1]]
    }
}

/// The structures of one level that [`for_each_visibility_counted`] queries
/// through: its [`TileTree`] (one for pixel centres, one for other points)
/// and its [`Blocks`]. Each is built on first use and then kept, so that
/// the passes of one gather (a lattice's passes, the anchors of the block
/// sweeps, the pixels handed back to them) build each once instead of once
/// per pass: on a level of millions of edges a build takes tenths of a
/// second, and all of its memory is touched anew.
pub struct Structures<'g> {
    geometry: &'g Geometry,
    /// For other points, then for pixel centres.
    trees: [OnceLock<TileTree<'g>>; 2],
    blocks: OnceLock<Blocks<'g>>,
}

impl<'g> Structures<'g> {
    /// Nothing built yet.
    pub fn new(geometry: &'g Geometry) -> Structures<'g> {
        Structures {
            geometry,
            trees: [OnceLock::new(), OnceLock::new()],
            blocks: OnceLock::new(),
        }
    }

    /// The level.
    pub fn geometry(&self) -> &'g Geometry {
        self.geometry
    }

    /// The tile tree, culled for pixel centres only with `centres`.
    fn tree(&self, centres: bool) -> &TileTree<'g> {
        self.trees[usize::from(centres)].get_or_init(|| TileTree::new(self.geometry, centres))
    }

    /// The edges binned for the walk.
    fn blocks(&self) -> &Blocks<'g> {
        self.blocks.get_or_init(|| Blocks::new(self.geometry))
    }

    /// Builds the tile tree (for pixel centres with `centres`) and the
    /// blocks now, side by side, instead of one after the other on the
    /// first query (several ms each on one core for wall noise at 512 px).
    pub fn prepare(&self, centres: bool) {
        rayon::join(|| self.tree(centres), || self.blocks());
    }
}

thread_local! {
    static SWEEPER: RefCell<(Sweeper, Vec<Span>, Vec<u32>)> = RefCell::new((Sweeper::new(), Vec::new(), Vec::new()));
}

/// What [`for_each_visibility`] left out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VisitStats {
    /// (edge, point) pairs dropped because the edge lies beyond every reach.
    pub culled_pairs: u64,
    /// Points whose region sees no contributing edge: reported with no spans.
    pub unreached: u64,
    /// Points whose query walked the level's blocks (the others swept a
    /// candidate list, or were unreached).
    pub walks: u64,
}

impl std::ops::AddAssign for VisitStats {
    fn add_assign(&mut self, o: VisitStats) {
        self.culled_pairs += o.culled_pairs;
        self.unreached += o.unreached;
        self.walks += o.walks;
    }
}

/// Runs `f(point index, spans)` for every query point, with the exact
/// visibility of that point, in parallel over leaf tiles. `pixel[i]` is the
/// free pixel a point belongs to, `pos[i]` its position, `view[i]` its view.
/// Edges beyond `reach_max` are left out. With `reach2` (see [`Wanted`]),
/// only the spans of edges within their squared reach are passed on (the
/// others still occlude; they count as culled pairs), and a point whose
/// region has no candidate within reach gets no spans without a visibility
/// query.
pub fn for_each_visibility<F>(
    geometry: &Geometry,
    pos: &[[f64; 2]],
    pixel: &[[i32; 2]],
    view: &(dyn Fn(usize) -> View + Sync),
    reach_max: f64,
    reach2: Option<&[f64]>,
    f: &F,
) -> VisitStats
where
    F: Fn(usize, &[Span]) + Sync,
{
    for_each_visibility_counted(
        &Structures::new(geometry),
        Some(pos),
        pixel,
        view,
        reach_max,
        reach2.map(Reaches::new).as_ref(),
        &|_| {},
        None,
        f,
    )
}

/// The centre of pixel `px`, where a floor gather asks.
pub fn centre(px: [i32; 2]) -> [f64; 2] {
    [px[0] as f64 + 0.5, px[1] as f64 + 0.5]
}

/// [`for_each_visibility`], calling `done(n)` after each leaf tile with the
/// number of points it held, for progress reports. Without `pos` the points
/// are the pixels' [`centre`]s, not stored per point (a floor gather's
/// millions of pixels). With `defer`, a point that would walk the level's
/// blocks (no short candidate list in its leaf tile, or a long list that
/// culling left almost whole) is passed to `defer` instead of queried: `f`
/// is not called for it and `done` does not count it. The level and what
/// is built to query it come with `structures`, kept from call to call, and
/// the reaches (see [`Wanted`]) with `reaches`, kept likewise.
#[allow(clippy::too_many_arguments)]
pub fn for_each_visibility_counted<F>(
    structures: &Structures,
    pos: Option<&[[f64; 2]]>,
    pixel: &[[i32; 2]],
    view: &(dyn Fn(usize) -> View + Sync),
    reach_max: f64,
    reaches: Option<&Reaches>,
    done: &(dyn Fn(usize) + Sync),
    defer: Option<&(dyn Fn(usize) + Sync)>,
    f: &F,
) -> VisitStats
where
    F: Fn(usize, &[Span]) + Sync,
{
    if pixel.is_empty() {
        return VisitStats::default();
    }
    let geometry = structures.geometry();
    // A floor gather asks at pixel centres only: its regions cull more.
    let centres = pos.is_none_or(|pos| pos.iter().zip(pixel).all(|(&p, &px)| p == centre(px)));
    let at = |i: usize| pos.map_or_else(|| centre(pixel[i]), |pos| pos[i]);
    let tree = structures.tree(centres);
    let grid = PointGrid::new(geometry.width, geometry.height, tree.leaf as usize, pixel);
    let filtering = reaches.filter(|r| r.filters());
    let reach2 = filtering.map(|r| r.squared);
    let cosine = filtering.and_then(|r| r.cosine);
    let unreached = std::sync::atomic::AtomicU64::new(0);
    let left_out = std::sync::atomic::AtomicU64::new(0);
    let walks = std::sync::atomic::AtomicU64::new(0);
    let culled_pairs = tree.for_each_leaf(&|r| grid.count_in(r), reach_max, &|leaf| {
        // Per region with a known list: where each candidate's light reaches.
        let class: Vec<Option<Vec<Reachable>>> = leaf
            .regions
            .iter()
            .map(|r| {
                let (reach2, list) = (reach2?, r.candidates.as_ref()?);
                let mut c = Vec::new();
                Wanted::classify(reach2, &geometry.edges, &r.bbox, list, &mut c);
                Some(c)
            })
            .collect();
        // Regions where no candidate is within reach of any point.
        let dark: Vec<bool> = class
            .iter()
            .map(|c| {
                c.as_ref().is_some_and(|c| {
                    c.iter()
                        .all(|&k| k == Reachable::Beyond || k == Reachable::Never)
                })
            })
            .collect();
        let deferred = SWEEPER.with(|cell| {
            let (sweeper, spans, seen) = &mut *cell.borrow_mut();
            let mut skipped = 0;
            let mut dropped = 0;
            let mut walked = 0;
            // Per region with a long open list: sweep it (`Some(true)`) or
            // walk, decided by what its first point sees ([`Region::open`]).
            let mut sweep_open: Vec<Option<bool>> = vec![None; leaf.regions.len()];
            let mut deferred = 0;
            for &i in grid.in_leaf(leaf.rect) {
                let i = i as usize;
                let px = pixel[i];
                if let Some(defer) = defer {
                    let region = leaf.region_at(px);
                    let short = region.is_some_and(|r| {
                        leaf.regions[r].candidates.is_some() && !leaf.regions[r].open
                    });
                    if !short && !region.is_some_and(|r| dark[r]) {
                        defer(i);
                        deferred += 1;
                        continue;
                    }
                }
                let comp = geometry.components[px[1] as usize * geometry.width + px[0] as usize];
                spans.clear();
                let region = leaf.region_at(px);
                if region.is_some_and(|r| dark[r]) {
                    skipped += 1;
                } else {
                    let open = region.filter(|&r| leaf.regions[r].open);
                    let cands = leaf.candidates_at(px).filter(|c| {
                        open.is_none_or(|r| {
                            sweep_open[r].unwrap_or(c.len() <= TileTree::SWEEP_FIRST)
                        })
                    });
                    match cands {
                        Some(cands) => {
                            let class = region.and_then(|r| class[r].as_deref());
                            dropped += sweeper.sweep_wanted(
                                &geometry.edges,
                                cands,
                                Viewpoint::new(at(i), view(i), comp),
                                reach2.map(|reach2| Wanted {
                                    reach2,
                                    class,
                                    cosine,
                                }),
                                spans,
                            )
                        }
                        None => {
                            walked += 1;
                            dropped += sweeper.walk_wanted(
                                structures.blocks(),
                                Viewpoint::new(at(i), view(i), comp),
                                reach_max,
                                reach2.map(|reach2| Wanted {
                                    reach2,
                                    class: None,
                                    cosine,
                                }),
                                reaches.and_then(|r| r.far(geometry)),
                                spans,
                            );
                        }
                    }
                    // A point that sees most of its region's list has open
                    // ground around it: one sort of the list costs its
                    // neighbours less than walking every block. Where the
                    // list is mostly hidden (walls all round), the walk
                    // stops early.
                    if let Some(r) = open
                        && sweep_open[r].is_none()
                    {
                        let listed = leaf.regions[r].candidates.as_ref().map_or(0, Vec::len);
                        // The edges it sees (an edge's spans in a row
                        // counted once).
                        seen.clear();
                        seen.extend(spans.iter().map(|s| s.edge));
                        seen.dedup();
                        sweep_open[r] = Some(2 * seen.len() >= listed);
                    }
                }
                f(i, spans);
            }
            unreached.fetch_add(skipped, std::sync::atomic::Ordering::Relaxed);
            left_out.fetch_add(dropped, std::sync::atomic::Ordering::Relaxed);
            walks.fetch_add(walked, std::sync::atomic::Ordering::Relaxed);
            deferred
        });
        done(grid.in_leaf(leaf.rect).len() - deferred);
    });
    VisitStats {
        culled_pairs: culled_pairs + left_out.into_inner(),
        unreached: unreached.into_inner(),
        walks: walks.into_inner(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The count of every rectangle a tile tree can ask about (sides on the
    /// leaves' grid or on the level's right and bottom sides) is the count
    /// of the points in it, on a level whose sides are not whole leaves.
    #[test]
    fn counts_per_leaf_count_the_points_of_every_tile() {
        let (w, h, leaf) = (37usize, 29usize, 8usize);
        let pixels: Vec<[i32; 2]> = (0..400u64)
            .map(|i| {
                let k = i.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 17;
                [(k % w as u64) as i32, ((k / w as u64) % h as u64) as i32]
            })
            .collect();
        let grid = PointGrid::new(w, h, leaf, &pixels);
        let ends = |n: usize| -> Vec<i32> {
            (1..=n.div_ceil(leaf))
                .map(|l| (l * leaf).min(n) as i32)
                .collect()
        };
        for x0 in (0..w).step_by(leaf) {
            for y0 in (0..h).step_by(leaf) {
                for &x1 in ends(w).iter().filter(|&&x| x > x0 as i32) {
                    for &y1 in ends(h).iter().filter(|&&y| y > y0 as i32) {
                        let r = Rect {
                            x0: x0 as i32,
                            y0: y0 as i32,
                            x1,
                            y1,
                        };
                        let want = pixels
                            .iter()
                            .filter(|p| r.x0 <= p[0] && p[0] < r.x1 && r.y0 <= p[1] && p[1] < r.y1)
                            .count() as u64;
                        assert_eq!(grid.count_in(r), want, "{r:?}");
                    }
                }
            }
        }
    }
}
