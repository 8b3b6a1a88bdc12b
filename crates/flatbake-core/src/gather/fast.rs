//! The fast gather: exact visibility per pixel centre, direct light in closed
//! form per visible stretch, reflected light from the patch tree.

use std::f64::consts::TAU;

use crate::geometry::{Edge, Geometry};
use crate::level::{Cell, Level};
use crate::transport::kernel::Reach;
use crate::transport::kernel::{Falloff, GatherLine, GatherPoints};
use crate::transport::{Patches, wanted_reach};
use crate::visibility::marks::Marks;
use crate::visibility::{
    Reaches, Span, Structures, TileTree, View, VisitStats, centre, for_each_visibility_counted,
};

use super::patch_tree::node_range;
use super::*;

/// What gathering merged, summed over pixels (what it culled, the
/// visibility query counts: [`VisitStats`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GatherCounts {
    /// Pieces of reflected light gathered ([`PatchTree`] nodes) ...
    pub pieces: u64,
    /// ... and the patch pieces they stand for (equal when nothing merged).
    pub patch_pieces: u64,
    /// Pixels whose light was interpolated between exactly gathered lattice
    /// points instead of gathered ([`GatherOptions::lattice`]).
    pub interpolated: u64,
    /// Of those, the pixels interpolated in cells tested at their corners
    /// only ([`GatherOptions::coarse`]).
    pub untested: u64,
    /// Pixels gathered with a sweep over the edges that the anchors of
    /// their block see ([`super::lattice::ANCHOR`]) instead of a full
    /// visibility query.
    pub local: u64,
    /// Pixels (swept, or beside a wall with a full query) whose reflected
    /// light from beyond [`GatherOptions::far`] was interpolated between
    /// their block's corners.
    pub far: u64,
    /// Pixels swept on a level of many lights ([`super::FAR_LAMPS`]) whose
    /// light from beyond [`LAMP_FAR`], the lights' too, was interpolated
    /// between their block's corners.
    pub far_lights: u64,
    /// Anchors whose walk went past [`OUTER`] only towards the lights,
    /// and whose reflected light from beyond it was interpolated between
    /// the corners of their block of the coarser lattice.
    pub outer: u64,
}

impl std::ops::AddAssign for GatherCounts {
    fn add_assign(&mut self, o: GatherCounts) {
        self.pieces += o.pieces;
        self.patch_pieces += o.patch_pieces;
        self.interpolated += o.interpolated;
        self.untested += o.untested;
        self.local += o.local;
        self.far += o.far;
        self.far_lights += o.far_lights;
        self.outer += o.outer;
    }
}

/// Reusable buffers of [`pixel_light`] (one per thread, so that a pixel
/// allocates nothing once they have grown). A pixel's visible spans are
/// first turned into the points at which the closed forms are needed, each
/// with its own line; those are then evaluated together, in loops without
/// branches that vectorise ([`GatherPoints`]), and summed.
#[derive(Default)]
pub struct PixelScratch {
    /// Emitting spans: their starts (with their lines), their ends, their
    /// edges, and the integrals between.
    pub(super) em: GatherPoints,
    pub(super) em_end: Vec<f64>,
    pub(super) em_edge: Vec<u32>,
    em_g: Vec<f64>,
    /// Reflected light: for every reflecting span its start, then the end
    /// of each of its pieces; the three antiderivatives there.
    pub(super) pts: GatherPoints,
    f: Vec<f64>,
    l: Vec<f64>,
    q: Vec<f64>,
    /// The pieces, in the order of their end points.
    pieces: Vec<PieceAt>,
    /// The patch trees as cut for the current tile.
    cuts: TileCuts,
    /// After [`pixel_light_part`] with a distance: the angle (radians) that
    /// the spans' points within it cover, as seen from the pixel.
    pub(super) near_angle: f64,
}

impl PixelScratch {
    /// Empty scratch; it grows to what the pixels need.
    pub fn new() -> Self {
        Self::default()
    }

    /// The reflected pieces of the last pixel, in order: tree node, index
    /// of the end point in `pts`, node centre relative to the foot.
    pub(super) fn pieces_at(&self) -> impl Iterator<Item = (u32, u32, f64)> + '_ {
        self.pieces.iter().map(|p| (p.node, p.end, p.off))
    }
}

/// A piece of reflected light queued for a pixel: its tree node, the index
/// of its end point (it starts at the point before), and the node's centre
/// relative to the foot of the pixel on the edge (`foot - mid`).
#[derive(Clone, Copy, Debug)]
struct PieceAt {
    node: u32,
    end: u32,
    off: f64,
}

/// What every pixel of one gather reads: the edges and their patches, the
/// solved radiosity, the patch tree built from it, and how light travels.
#[derive(Clone, Copy)]
pub struct Lighting<'a> {
    /// The level's edges.
    pub edges: &'a [Edge],
    /// The edges' patches.
    pub patches: &'a Patches,
    /// The solved radiosity on them.
    pub rad: &'a Radiosity,
    /// The reflected light, merged within the gather's tolerance.
    pub tree: &'a PatchTree,
    /// How light falls off with distance, if it does.
    pub falloff: Option<Falloff>,
    /// Which kernel turns radiosity into pixel light.
    pub kernel: Kernel,
}

/// How a [`gather`] turns radiosity into pixel light, and how much it may
/// merge and leave out.
#[derive(Clone, Debug)]
pub struct GatherOptions<'a> {
    /// How light falls off with distance, if it does.
    pub falloff: Option<Falloff>,
    /// Which kernel turns radiosity into pixel light.
    pub kernel: Kernel,
    /// Per edge: beyond this distance its light is left out.
    pub reach: &'a Reach,
    /// Per-pixel error bound of merged reflected light (0: only exactly
    /// quadratic runs merge).
    pub tolerance: f64,
    /// The components whose deviations decide what merges.
    pub decide: std::ops::Range<usize>,
    /// Told the fraction of `pixels` gathered so far, if given.
    pub progress: Option<OnProgress<'a>>,
    /// Interpolate between exactly gathered lattice points where that is
    /// smooth to within this relative tolerance ([`super::lattice`]; the
    /// flatland kernel only). `None`: gather every pixel exactly.
    pub lattice: Option<f64>,
    /// Block sweeps (docs/transport.md, Block sweeps; the flatland kernel
    /// only): a pixel whose full visibility query would walk the level's
    /// blocks is swept over what the anchor pixels this many pixels apart
    /// around it see, where it can. `None`: a full query at every pixel
    /// (the lattice, if any, then uses [`super::lattice::ANCHOR`]).
    pub anchors: Option<i32>,
    /// Which pixels block sweeps take: every pixel the gather (the
    /// lattice) asks for that is not an anchor, over its block's corners'
    /// lists (`draft`); or only those whose full query would walk, over the
    /// lists of the corners and of the ring of anchors around them.
    pub sweep_every: bool,
    /// After the lattice's tested cells, cells of [`super::lattice::COARSE`]
    /// px gathered at their corners and interpolated where those agree
    /// within [`super::lattice::SPREAD`] (`draft`: about one pixel in four
    /// gathered where the larger cells fail). Only with a lattice.
    pub coarse: bool,
    /// Also compute the first circular moments of every pixel's light
    /// (`gather/directional.rs`; the flatland kernel only). Default off.
    pub directional: bool,
    /// Block sweeps' far reflected light (docs/transport.md, Far reflected
    /// light): a swept pixel takes the light that walls reflect to it from
    /// beyond this many pixels from the anchors at its block's corners,
    /// interpolated, and sweeps only the edges within this distance of its
    /// block, the lights, and the edges that may hide a light from some
    /// pixel of the block, where that leaves out enough of its list (else
    /// the whole list). Direct light stays exact, but on a level that is
    /// not dense where the list holds more than [`super::FAR_LAMPS`]
    /// lights: then all the light from beyond [`LAMP_FAR`], the lights'
    /// too, comes from the corners where it is at most
    /// [`super::LAMP_SHARE`] of each corner's light (docs/transport.md, Far
    /// light of many lights). A pixel with no block of
    /// floor around it (on a dense level, no block of [`Self::anchors`]
    /// px) takes its far reflected light from the corners of its
    /// [`Self::anchors`] block the same way, where they are floor of its
    /// region, and its full query wants the light of edges that do not
    /// emit only within this distance (`Exact::run_near`). `None` (and
    /// with moments): the whole list, and full queries that want all the
    /// light.
    pub far: Option<f64>,
}

/// What [`gather_with_moments`] returns.
pub struct Gather {
    /// `values[i * components + k]`: component `k` at pixel `i`.
    pub values: Vec<f64>,
    /// With [`GatherOptions::directional`], `moments[i * 2 * components + k]`
    /// the cosine and `moments[i * 2 * components + components + k]` the
    /// sine moment of component `k` at pixel `i` (else empty).
    pub moments: Vec<f64>,
    /// The visibility queries' counts.
    pub stats: VisitStats,
    /// What was merged and interpolated.
    pub counts: GatherCounts,
}

/// A callback told the fraction (0 to 1) of a gather that is done; called
/// from worker threads, once per tile at most, and only when the fraction
/// has grown by at least a thousandth since the last call.
#[derive(Clone, Copy)]
pub struct OnProgress<'a>(pub &'a (dyn Fn(f64) + Sync));

impl std::fmt::Debug for OnProgress<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("OnProgress")
    }
}

/// Counts gathered points for an [`OnProgress`]: an atomic add per tile,
/// and a call only when the thousandths go up.
struct Tally<'a> {
    hook: Option<OnProgress<'a>>,
    total: u64,
    done: std::sync::atomic::AtomicU64,
    shown: std::sync::atomic::AtomicU64,
}

impl<'a> Tally<'a> {
    fn new(hook: Option<OnProgress<'a>>, total: usize) -> Self {
        Tally {
            hook,
            total: total.max(1) as u64,
            done: Default::default(),
            shown: Default::default(),
        }
    }

    fn add(&self, n: usize) {
        use std::sync::atomic::Ordering::Relaxed;
        let Some(OnProgress(hook)) = self.hook else {
            return;
        };
        let done = self.done.fetch_add(n as u64, Relaxed) + n as u64;
        let permille = done * 1000 / self.total;
        if self.shown.fetch_max(permille, Relaxed) < permille {
            // (At most 1: a lattice whose trial fails gathers its probes
            // again.)
            hook((done as f64 / self.total as f64).min(1.0));
        }
    }
}

/// Adds to `acc` the light that pixel centre `p` receives from its visible
/// spans (all of them: the falloff reach is applied by the visibility
/// query, [`for_each_visibility`](crate::visibility::for_each_visibility),
/// which passes on only the spans within reach).
/// Reflected light is gathered from `tree`'s nodes ([`PatchTree`]), as cut
/// for `p`'s tile: `p` must be the centre of a pixel, since the cut's bound
/// is taken at the tile's pixel centres.
pub fn pixel_light(
    light: &Lighting,
    p: [f64; 2],
    spans: &[Span],
    acc: &mut [f64],
    scratch: &mut PixelScratch,
) -> GatherCounts {
    pixel_light_part(light, p, spans, acc, scratch, Part::All)
}

/// Which of a pixel's light [`pixel_light_part`] adds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Part {
    /// All of it.
    All,
    /// The direct light, and the light reflected from points of edges
    /// within this distance of the pixel.
    Near(f64),
    /// The light reflected from points of edges beyond this distance.
    Far(f64),
    /// All the light, emitted and reflected, from points of edges within
    /// this distance of the pixel.
    Inside(f64),
    /// All the light, emitted and reflected, from points of edges beyond
    /// this distance.
    Outside(f64),
    /// The light reflected from points of edges at least the first
    /// distance away and within the second.
    Band(f64, f64),
}

/// Where along an edge seen from `p` (axis coordinate, with `p`'s foot at
/// `foot` and `p` at `d` in front of its line) the points within `r` of `p`
/// lie: `foot - w` to `foot + w`, or none (`None`) if the line is as far.
fn within(r: f64, d: f64, foot: f64) -> Option<(f64, f64)> {
    let d = d.abs();
    (d < r).then(|| {
        let w = (r * r - d * d).sqrt();
        (foot - w, foot + w)
    })
}

/// The part of `[s0, s1]` along that edge within `r` of `p` ([`within`]),
/// if it is not empty.
fn part_within(r: f64, d: f64, foot: f64, s0: f64, s1: f64) -> Option<(f64, f64)> {
    let (a, b) = within(r, d, foot)?;
    let (s0, s1) = (s0.max(a), s1.min(b));
    (s0 < s1).then_some((s0, s1))
}

/// The parts of `[s0, s1]` along that edge beyond `r` of `p` (before and
/// after the part within it), those that are not empty.
fn parts_beyond(r: f64, d: f64, foot: f64, s0: f64, s1: f64) -> impl Iterator<Item = (f64, f64)> {
    let (a, b) = within(r, d, foot).unwrap_or((s1, s1));
    [(s0, s1.min(a)), (s0.max(b), s1)]
        .into_iter()
        .filter(|&(s0, s1)| s0 < s1)
}

/// [`pixel_light`], of the part of the light that `part` says.
pub(super) fn pixel_light_part(
    light: &Lighting,
    p: [f64; 2],
    spans: &[Span],
    acc: &mut [f64],
    scratch: &mut PixelScratch,
    part: Part,
) -> GatherCounts {
    let Lighting {
        edges,
        patches,
        rad,
        tree,
        falloff,
        kernel,
    } = *light;
    let k = rad.components;
    let mut counts = GatherCounts::default();
    let sc = scratch;
    sc.em.clear();
    sc.em_end.clear();
    sc.em_edge.clear();
    sc.pts.clear();
    sc.pieces.clear();
    sc.cuts.enter(tree, p, edges.len());
    sc.near_angle = 0.0;
    for span in spans {
        let ei = span.edge as usize;
        let e = &edges[ei];
        if let Part::Near(r)
        | Part::Far(r)
        | Part::Band(r, _)
        | Part::Inside(r)
        | Part::Outside(r) = part
        {
            // What the span's points within `r` hide of the farther light.
            let d = e.front_distance(p);
            let foot = if e.normal.is_vertical_edge() {
                p[1]
            } else {
                p[0]
            };
            if let Some((s0, s1)) = part_within(r, d, foot, span.s0, span.s1)
                && d > 0.0
            {
                sc.near_angle += ((s1 - foot) / d).atan() - ((s0 - foot) / d).atan();
            }
        }
        if !(rad.edge_emits[ei] || rad.edge_reflects[ei]) {
            continue;
        }
        if kernel == Kernel::Paper {
            paper_span(edges, patches, rad, falloff, p, span, acc);
            continue;
        }
        let d = e.front_distance(p);
        let foot = if e.normal.is_vertical_edge() {
            p[1]
        } else {
            p[0]
        };
        let line = GatherLine::new(d, falloff);
        if rad.edge_emits[ei] {
            let mut emit = |s0: f64, s1: f64| {
                sc.em.line(&line);
                sc.em.push(s0 - foot);
                sc.em_end.push(s1 - foot);
                sc.em_edge.push(span.edge);
            };
            match part {
                Part::All | Part::Near(_) => emit(span.s0, span.s1),
                // One integral per emitting span, empty if none of it is
                // within `r`: a pixel's [`signature`] reads them in the
                // spans' order.
                Part::Inside(r) => match part_within(r, d, foot, span.s0, span.s1) {
                    Some((s0, s1)) => emit(s0, s1),
                    None => emit(span.s0, span.s0),
                },
                Part::Outside(r) => {
                    for (s0, s1) in parts_beyond(r, d, foot, span.s0, span.s1) {
                        emit(s0, s1);
                    }
                }
                Part::Far(_) | Part::Band(..) => {}
            }
        }
        if rad.edge_reflects[ei] {
            match part {
                Part::All => reflected_pieces(light, span, &line, foot, sc, &mut counts),
                Part::Near(r) | Part::Inside(r) => {
                    if let Some((s0, s1)) = part_within(r, d, foot, span.s0, span.s1) {
                        let near = Span { s0, s1, ..*span };
                        reflected_pieces(light, &near, &line, foot, sc, &mut counts);
                    }
                }
                Part::Far(r) | Part::Outside(r) => {
                    for (s0, s1) in parts_beyond(r, d, foot, span.s0, span.s1) {
                        let far = Span { s0, s1, ..*span };
                        reflected_pieces(light, &far, &line, foot, sc, &mut counts);
                    }
                }
                Part::Band(r0, r1) => {
                    // Within `r1`, less the part within `r0` (as `Far`).
                    if let Some((lo, hi)) = part_within(r1, d, foot, span.s0, span.s1) {
                        for (s0, s1) in parts_beyond(r0, d, foot, lo, hi) {
                            let band = Span { s0, s1, ..*span };
                            reflected_pieces(light, &band, &line, foot, sc, &mut counts);
                        }
                    }
                }
            }
        }
    }
    let fall = falloff.is_some();
    // Uniform emission: one integral per emitting span (with `Outside`,
    // one per part beyond the distance; none with `Far` and `Band`).
    sc.em.between(&sc.em_end, fall, &mut sc.em_g);
    for (&ei, &g) in sc.em_edge.iter().zip(&sc.em_g) {
        let g = g / TAU;
        for c in 0..k {
            acc[c] += rad.edge_emission[ei as usize * k + c] * g;
        }
    }
    // Reflected light, quadratic along each piece.
    sc.pts
        .antiderivatives(fall, &mut sc.f, &mut sc.l, &mut sc.q);
    let (f, l, q) = (&sc.f, &sc.l, &sc.q);
    let k = tree.k;
    for pc in &sc.pieces {
        let (nd, i) = (pc.node as usize, pc.end as usize);
        let g0 = (f[i] - f[i - 1]) / TAU;
        let g1 = (l[i] - l[i - 1]) / TAU;
        let g2 = (q[i] - q[i - 1]) / TAU;
        // Express B = c0 + c1 u + c2 u^2, u = s - mid = t + off, in t = s - foot.
        let off = pc.off;
        for c in 0..k {
            let j = nd * k + c;
            let (c0, c1, c2) = (tree.c0[j], tree.c1[j], tree.c2[j]);
            let a1 = c1 + 2.0 * c2 * off;
            let a0 = c0 + (c1 + c2 * off) * off;
            acc[c] += a0 * g0 + a1 * g1 + c2 * g2;
        }
    }
    counts
}

/// Side of the square tiles of pixels that share their cuts of the patch
/// trees ([`TileCuts`]): that of the visibility tiles, whose pixels a thread
/// visits one after the other.
const CUT_TILE: i32 = TileTree::LEAF;

/// A node of a tile's cut of an edge's patch tree: the node, where its axis
/// range ends, and the patches under it.
#[derive(Clone, Copy, Debug)]
struct CutPiece {
    node: u32,
    b: f64,
    first: u32,
    last: u32,
}

/// The patch trees ([`PatchTree`]) cut into the nodes that may stand in for
/// their patches as seen from every pixel centre of one tile: a node is
/// taken whole when the tile's nearest pixel centre is far enough for it
/// (then so is every pixel's nearest visible point of it, so each pixel's
/// bound holds), else split. An edge is cut once per tile, when a pixel of
/// the tile first sees its reflected light; the pixels then read the pieces
/// under their spans off the cut instead of each walking the tree.
#[derive(Default)]
struct TileCuts {
    /// The tree and the tile the cached cuts are for.
    tree: Option<u64>,
    tile: Option<[i32; 2]>,
    /// Per edge whose cut is made: where it lies in `pieces`.
    made: Marks<(u32, u32)>,
    pieces: Vec<CutPiece>,
    /// Tree nodes still to visit: (level, index in the level).
    stack: Vec<(u32, u32)>,
}

impl TileCuts {
    /// Starts serving pixel centre `p` with `tree`: cuts made for another
    /// tile or another tree (the scratch outlives a gather) are dropped.
    fn enter(&mut self, tree: &PatchTree, p: [f64; 2], edges: usize) {
        let side = CUT_TILE as f64;
        let tile = [(p[0] / side).floor() as i32, (p[1] / side).floor() as i32];
        if self.tile == Some(tile) && self.tree == Some(tree.id) && self.made.len() == edges {
            return;
        }
        self.tile = Some(tile);
        self.tree = Some(tree.id);
        self.pieces.clear();
        self.made.clear(edges);
    }

    /// The cut of edge `ei` for the current tile.
    fn of(
        &mut self,
        tree: &PatchTree,
        edges: &[Edge],
        patches: &Patches,
        ei: usize,
    ) -> &[CutPiece] {
        if let Some((from, to)) = self.made.get(ei) {
            return &self.pieces[from as usize..to as usize];
        }
        let tile = self.tile.expect("enter() comes first");
        let from = self.pieces.len();
        self.cut(tree, &edges[ei], patches, ei, tile);
        self.made.set(ei, (from as u32, self.pieces.len() as u32));
        &self.pieces[from..]
    }

    fn cut(&mut self, tree: &PatchTree, e: &Edge, patches: &Patches, ei: usize, tile: [i32; 2]) {
        let (lo, hi) = e.extent();
        let h = patches.step[ei];
        let n = patches.of_edge(ei).len();
        let levels = &tree.levels[tree.edge_levels[ei] as usize..tree.edge_levels[ei + 1] as usize];
        // The tile's pixel centres: their nearest distance in front of the
        // edge's line, and their range along its axis.
        let side = CUT_TILE as f64;
        let (x0, y0) = (tile[0] as f64 * side + 0.5, tile[1] as f64 * side + 0.5);
        let (x1, y1) = (x0 + side - 1.0, y0 + side - 1.0);
        let front = e
            .front_distance([x0, y0])
            .min(e.front_distance([x1, y1]))
            .max(0.0);
        let (ta, tb) = if e.normal.is_vertical_edge() {
            (y0, y1)
        } else {
            (x0, x1)
        };
        let d2 = front * front;
        self.stack.clear();
        self.stack.push((levels.len() as u32 - 2, 0));
        while let Some((lv, i)) = self.stack.pop() {
            let (a, b) = node_range(lo, hi, h, n, lv, i as usize);
            let nd = levels[lv as usize] as usize + i as usize;
            let gap = (a - tb).max(ta - b).max(0.0);
            if lv > 0 && d2 + gap * gap < tree.need[nd] {
                // The right child pushed first, so that the left one comes first.
                let below = levels[lv as usize] - levels[lv as usize - 1];
                if 2 * i + 1 < below {
                    self.stack.push((lv - 1, 2 * i + 1));
                }
                self.stack.push((lv - 1, 2 * i));
                continue;
            }
            let first = (i as usize) << lv;
            let last = (((i as usize + 1) << lv) - 1).min(n - 1);
            self.pieces.push(CutPiece {
                node: nd as u32,
                b,
                first: first as u32,
                last: last as u32,
            });
        }
    }
}

/// Queues the reflected light (`B - E`, quadratic along each piece) under
/// `span` for pixel centre `p` at `foot` on the edge: the pieces of the
/// tile's cut of the edge's tree that overlap the span, clipped to it, in
/// order along the edge. The span's start point goes into `sc.pts`, then
/// each piece's end point; each piece goes into `sc.pieces`.
fn reflected_pieces(
    light: &Lighting,
    span: &Span,
    line: &GatherLine,
    foot: f64,
    sc: &mut PixelScratch,
    counts: &mut GatherCounts,
) {
    let (patches, tree, edges) = (light.patches, light.tree, light.edges);
    let ei = span.edge as usize;
    let (lo, _) = edges[ei].extent();
    let h = patches.step[ei];
    let n = patches.of_edge(ei).len();
    // (`as` truncates towards 0 and saturates: the floor, clamped at 0.)
    let patch_of = |s: f64| (((s - lo) / h) as usize).min(n - 1);
    let (j0, j1) = (patch_of(span.s0), patch_of(span.s1));
    let PixelScratch {
        pts, pieces, cuts, ..
    } = sc;
    let cut = cuts.of(tree, edges, patches, ei);
    pts.line(line);
    pts.push(span.s0 - foot);
    // The first piece that ends after the span starts.
    let from = cut.partition_point(|c| c.b <= span.s0);
    for c in &cut[from.min(cut.len() - 1)..] {
        // The last piece ends the span.
        let end = if c.last as usize >= j1 { span.s1 } else { c.b };
        pts.push(end - foot);
        pieces.push(PieceAt {
            node: c.node,
            end: pts.len() as u32 - 1,
            off: foot - tree.mid[c.node as usize],
        });
        counts.pieces += 1;
        counts.patch_pieces +=
            ((c.last as usize).min(j1) + 1).saturating_sub((c.first as usize).max(j0)) as u64;
        if c.last as usize >= j1 {
            break;
        }
    }
}

/// Equation 5 of the paper for the patches of one visible span: each patch
/// adds `B * A cos(theta) / (A + r^2) * (visible fraction)`, with `theta` and
/// `r` taken at the patch centre and `A` infinite without falloff.
fn paper_span(
    edges: &[Edge],
    patches: &Patches,
    rad: &Radiosity,
    falloff: Option<Falloff>,
    p: [f64; 2],
    span: &Span,
    acc: &mut [f64],
) {
    let e = &edges[span.edge as usize];
    let d = e.front_distance(p);
    patches.for_each_piece(edges, span, |pt, a, b| {
        let (s0, s1) = patches.bounds(edges, pt);
        let centre = e.point_at(0.5 * (s0 + s1));
        let r = (p[0] - centre[0]).hypot(p[1] - centre[1]);
        let w = falloff.map_or(1.0, |f| f.weight(r));
        let vis = (b - a) / (s1 - s0);
        for c in 0..rad.components {
            acc[c] += rad.patch(patches, pt, c) * (d / r) * w * vis;
        }
    });
}

thread_local! {
    static SCRATCH: std::cell::RefCell<PixelScratch> = std::cell::RefCell::new(PixelScratch::new());
}

/// The floor pixels of a level, as query points.
pub fn floor_pixels(level: &Level) -> Vec<[i32; 2]> {
    // Sized once: it lives through the bake.
    let n = level.cells.iter().filter(|&&c| c == Cell::Floor).count();
    let mut v = Vec::with_capacity(n);
    for y in 0..level.height {
        for x in 0..level.width {
            if level.cell(x, y) == Cell::Floor {
                v.push([x as i32, y as i32]);
            }
        }
    }
    v
}

/// Fast gather: light at each of `pixels`, `components` values per pixel,
/// and what was left out (beyond reach, or in regions no lit edge reaches).
/// Distant reflected light is gathered in merged pieces whose total error
/// per pixel is at most the options' tolerance ([`PatchTree`]); how much was
/// merged is counted. With a lattice tolerance, pixels between lattice
/// points are interpolated where that is smooth ([`super::lattice`]).
pub fn gather(
    geometry: &Geometry,
    patches: &Patches,
    rad: &Radiosity,
    pixels: &[[i32; 2]],
    options: &GatherOptions,
) -> (Vec<f64>, VisitStats, GatherCounts) {
    let g = gather_with_moments(geometry, patches, rad, pixels, options);
    (g.values, g.stats, g.counts)
}

/// [`gather`], with the pixels' first circular moments when the options
/// ask for them ([`GatherOptions::directional`]): gathered with the same
/// spans and interpolated with the same weights as the light.
pub fn gather_with_moments(
    geometry: &Geometry,
    patches: &Patches,
    rad: &Radiosity,
    pixels: &[[i32; 2]],
    options: &GatherOptions,
) -> Gather {
    let GatherOptions {
        falloff,
        kernel,
        reach,
        tolerance,
        ref decide,
        progress,
        lattice,
        anchors,
        sweep_every,
        coarse,
        directional,
        far,
    } = *options;
    // Edges with light, each within its reach.
    let reach2 = wanted_reach(reach, |e| rad.edge_emits[e] || rad.edge_reflects[e]);
    let reaches = Reaches::new(&reach2);
    // With the far split, the reaches of a walk that wants reflected light
    // only within that distance (lights as far as they reach).
    let far = far.filter(|_| !directional && kernel == Kernel::Flatland);
    let near_reach2: Option<Vec<f64>> = far.map(|r| {
        reach2
            .iter()
            .enumerate()
            .map(|(e, &r2)| {
                if rad.edge_emits[e] || r2 < 0.0 {
                    r2
                } else {
                    r2.min(r * r)
                }
            })
            .collect()
    });
    // Past that distance such a walk needs only the lights' directions:
    // an edge that does not emit is wanted only within it, and its spans
    // there depend on nothing farther. (Listing the edges that straddle
    // the distance too, as `FarWanted::new` does for a full query's
    // walk, cost the pillar field 0.9 s of its 10.7 s for the same
    // lightmap: docs/performance.md.)
    let near_reaches = near_reach2.as_deref().zip(far).map(|(r2, r)| {
        let radius = (r / geometry.unit.max(1) as f64).ceil() as i32;
        Reaches::listing(r2, &rad.edge_emits, radius)
    });
    // With the far split nearer than [`OUTER`], for the anchors' walks on
    // dense levels: the lights, whose directions alone an anchor
    // walks past [`OUTER`] ([`super::local`]), widened by the angle that a
    // pixel of its blocks (within a diagonal of the spacing) subtends there.
    let spacing = anchors.unwrap_or(super::local::ANCHOR);
    let outer_radius = (OUTER * geometry.unit.max(1) as i32) as f64;
    let outer = far.filter(|&r| r < outer_radius).map(|_| {
        let angle = (spacing as f64 * std::f64::consts::SQRT_2 / outer_radius)
            .min(1.0)
            .asin();
        let lights = Reaches::closing(&reach2, &rad.edge_emits, OUTER, angle);
        (outer_radius, lights)
    });
    // The patches' tree, the visibility's structures and the far
    // directions side by side.
    let structures = Structures::new(geometry);
    let (tree, ((), ())) = rayon::join(
        || {
            PatchTree::new(
                &geometry.edges,
                patches,
                rad,
                decide.clone(),
                falloff,
                tolerance,
            )
        },
        || {
            rayon::join(
                || structures.prepare(true),
                || {
                    reaches.prepare(geometry);
                    if let Some(n) = &near_reaches {
                        n.prepare(geometry);
                    }
                    if let Some((_, o)) = &outer {
                        o.prepare(geometry);
                    }
                },
            )
        },
    );
    // Where a block's sweep takes its lights' far light from its corners
    // too: with a far split nearer than [`LAMP_FAR`] (a split at an
    // infinite distance gathers everything as without one), on a level of
    // many lights that is not dense (on a dense one a far light's beams
    // through the gaps between pillars are a pixel wide: measured on a
    // grove of pillars, interpolated, whole beams went missing).
    let lamp_far_px = (LAMP_FAR * geometry.unit.max(1) as i32) as f64;
    let lamp_far = far
        .filter(|&r| r < lamp_far_px)
        .filter(|_| !super::local::is_dense(geometry, pixels.len()))
        .filter(|_| {
            let every = 0..geometry.edges.len() as u32;
            super::local::sees_lights(geometry, rad, every, super::local::FAR_LAMPS)
        })
        .map(|_| lamp_far_px);
    let light = Lighting {
        edges: &geometry.edges,
        patches,
        rad,
        tree: &tree,
        falloff,
        kernel,
    };
    let tally = Tally::new(progress, pixels.len());
    let exact = Exact {
        geometry,
        structures: &structures,
        light: &light,
        reach_max: reach.max,
        reaches,
        near_reaches,
        outer,
        tally: &tally,
        directional: directional && kernel == Kernel::Flatland,
        far,
        lamp_far,
    };
    match (lattice, anchors) {
        (Some(relative), _) if kernel == Kernel::Flatland => super::lattice::gather(
            &exact,
            pixels,
            relative,
            tolerance,
            spacing,
            sweep_every,
            coarse,
        ),
        (None, Some(spacing)) if kernel == Kernel::Flatland => {
            super::local::gather_all(&exact, pixels, spacing)
        }
        _ => {
            let pass = exact.run(pixels, None);
            Gather {
                values: pass.values,
                moments: pass.moments,
                stats: pass.stats,
                counts: pass.counts,
            }
        }
    }
}

/// The exact gather of a list of pixels, as [`gather`] sets it up: what
/// every pass of the lattice gather shares.
pub(super) struct Exact<'a> {
    pub geometry: &'a Geometry,
    /// The level's visibility structures, built once for every pass.
    pub structures: &'a Structures<'a>,
    pub light: &'a Lighting<'a>,
    pub reach_max: f64,
    /// Per edge, its squared reach (see [`crate::visibility::Wanted`]),
    /// shared by every pass.
    pub reaches: Reaches<'a>,
    /// With [`Exact::far`]: [`Exact::reaches`] with every edge that does
    /// not emit cut to that distance, for the walks that want only the
    /// light within it and the lights ([`Exact::run_near`]).
    pub near_reaches: Option<Reaches<'a>>,
    /// With [`Exact::far`]: [`OUTER`] in pixels of the level, and the
    /// reaches with which an anchor walks past it only towards the
    /// lights ([`Reaches::closing`]; [`super::local`]).
    pub outer: Option<(f64, Reaches<'a>)>,
    tally: &'a Tally<'a>,
    /// Also the moments ([`Pass::moments`]).
    pub directional: bool,
    /// [`GatherOptions::far`] (never with moments).
    pub far: Option<f64>,
    /// With [`Exact::far`] on a level of many lights: [`LAMP_FAR`] in
    /// pixels of the level.
    pub lamp_far: Option<f64>,
}

/// Painted pixels beyond which a swept pixel whose block's list holds more
/// than [`super::FAR_LAMPS`] lights takes all its light, the lights' too,
/// from its block's corners, on a level that is not dense and where that
/// is at most [`super::LAMP_SHARE`] of each corner's light (transport.md,
/// Far light of many lights).
/// Measured on the light field (200 lights, falloff 43; docs/performance.md):
/// 32, 64, 96, 128 and 192 px took its gather from 3.6 s to 1.16, 1.33,
/// 1.51, 1.79 and 2.44 s, at 1.50, 0.59, 0.32, 0.23 and 0.18 % from
/// `high` (0.20 % before).
pub const LAMP_FAR: i32 = 128;

/// Painted pixels within which a dense level's anchors walk everywhere,
/// with [`GatherOptions::far`] nearer: past it an anchor walks only
/// towards the lights, and takes the light reflected to it from farther
/// from the anchors of a lattice four times as coarse (the block sweeps
/// of `gather/local.rs`; transport.md, Far reflected light). Measured
/// on the pillar field (docs/performance.md): 48, 64, 96 and 128 px took
/// its bake from 11.45 s to 10.83, 10.69, 11.04 and 11.02 s, at 1.381,
/// 1.355, 1.343 and 1.341 % from `high` (1.341 % before); nearer, the
/// lights' directions widen, and walking them costs what it saves.
pub const OUTER: i32 = 64;

/// What one exact pass over a list of pixels returned.
pub(super) struct Pass {
    /// `values[i * components + k]` for the pass's pixel `i`.
    pub values: Vec<f64>,
    /// With [`Exact::directional`], `moments[i * 2 * components + ..]`:
    /// the cosine moments of the components, then the sine moments.
    pub moments: Vec<f64>,
    /// Per pixel (when asked for): its [`signature`].
    pub signature: Vec<u64>,
    pub stats: VisitStats,
    pub counts: GatherCounts,
}

impl Exact<'_> {
    /// Components per pixel.
    pub fn components(&self) -> usize {
        self.light.rad.components
    }

    /// Counts `n` pixels as done for the progress report.
    pub fn done(&self, n: usize) {
        self.tally.add(n);
    }

    /// Gathers `pixels` exactly, with their [`signature`]s for the given
    /// relative tolerance if asked for.
    pub fn run(&self, pixels: &[[i32; 2]], signatures: Option<f64>) -> Pass {
        self.run_deferring(pixels, signatures, None)
    }

    /// [`Exact::run`]; with `defer`, a pixel whose query would walk the
    /// level's blocks is passed to it instead and its values are left 0
    /// ([`crate::visibility::for_each_visibility_counted`]).
    pub fn run_deferring(
        &self,
        pixels: &[[i32; 2]],
        signatures: Option<f64>,
        defer: Option<&(dyn Fn(usize) + Sync)>,
    ) -> Pass {
        self.run_with(pixels, signatures, defer, None)
    }

    /// [`Exact::run`] of the direct light and the light reflected from
    /// within [`Exact::far`] only, with [`Exact::near_reaches`] (a walk goes
    /// on past that distance only where a light may be left to find), and
    /// `far(i, open, acc)` adding to pixel `i`'s values the light reflected
    /// to it from beyond, given the angle it has open beyond that distance.
    /// `None` without [`Exact::far`].
    pub fn run_near(
        &self,
        pixels: &[[i32; 2]],
        signatures: Option<f64>,
        far: &(dyn Fn(usize, f64, &mut [f64]) + Sync),
    ) -> Option<Pass> {
        let r = self.far?;
        let reaches = self.near_reaches.as_ref()?;
        Some(self.run_with(pixels, signatures, None, Some((r, reaches, far))))
    }

    /// [`Exact::run_deferring`], or with `near` [`Exact::run_near`].
    #[allow(clippy::type_complexity)]
    fn run_with(
        &self,
        pixels: &[[i32; 2]],
        signatures: Option<f64>,
        defer: Option<&(dyn Fn(usize) + Sync)>,
        near: Option<(f64, &Reaches, &(dyn Fn(usize, f64, &mut [f64]) + Sync))>,
    ) -> Pass {
        let (light, rad) = (self.light, self.light.rad);
        let (part, reaches) = match near {
            Some((r, reaches, _)) => (Part::Near(r), reaches),
            None => (Part::All, &self.reaches),
        };
        let k = rad.components;
        let mut out = vec![0.0; pixels.len() * k];
        let mut sigs = vec![
            0u64;
            if signatures.is_some() {
                pixels.len()
            } else {
                0
            }
        ];
        let shared = Disjoint::new(&mut out);
        let shared_sig = Disjoint::new(&mut sigs);
        let directional = self.directional;
        let mut moments = vec![0.0; if directional { pixels.len() * 2 * k } else { 0 }];
        let shared_moments = Disjoint::new(&mut moments);
        // What the pixels merged, summed per thread (a lock or an atomic
        // shared by every pixel costs more than the pixel's own bookkeeping,
        // and a pair per pixel is 8 bytes of the gather's peak).
        let merged = PerThread::<2>::new();
        let stats = for_each_visibility_counted(
            self.structures,
            None,
            pixels,
            &|_| View::Full,
            self.reach_max,
            Some(reaches),
            &|n| self.tally.add(n),
            defer,
            &|i, spans| {
                // Bakes have at most three channels: no allocation per pixel.
                let mut small = [0.0; 3];
                let mut big = Vec::new();
                let acc = if k <= 3 {
                    &mut small[..k]
                } else {
                    big.resize(k, 0.0);
                    &mut big[..]
                };
                let (c, sig) = SCRATCH.with(|sc| {
                    let sc = &mut *sc.borrow_mut();
                    let c = pixel_light_part(light, centre(pixels[i]), spans, acc, sc, part);
                    if let Some((_, _, far)) = near {
                        far(i, TAU - sc.near_angle, acc);
                    }
                    if directional {
                        let (mut small, mut big) = ([0.0; 6], Vec::new());
                        let m = if k <= 3 {
                            &mut small[..2 * k]
                        } else {
                            big.resize(2 * k, 0.0);
                            &mut big[..]
                        };
                        super::directional::pixel_moments(light, centre(pixels[i]), spans, sc, m);
                        for (j, &v) in m.iter().enumerate() {
                            // SAFETY: each pixel index is visited exactly once.
                            unsafe { shared_moments.write(i * 2 * k + j, v) };
                        }
                    }
                    (
                        c,
                        signatures.map(|rel| signature(light, spans, sc, acc, rel)),
                    )
                });
                merged.add([c.pieces, c.patch_pieces]);
                for (c, &v) in acc.iter().enumerate() {
                    // SAFETY: each pixel index is visited exactly once.
                    unsafe { shared.write(i * k + c, v) };
                }
                if let Some(h) = sig {
                    // SAFETY: as above.
                    unsafe { shared_sig.write(i, h) };
                }
            },
        );
        let [pieces, patch_pieces] = merged.sum();
        let counts = GatherCounts {
            pieces,
            patch_pieces,
            ..GatherCounts::default()
        };
        Pass {
            values: out,
            moments,
            signature: sigs,
            stats,
            counts,
        }
    }
}

/// What a pixel's direct light is made of, as a hash (read after
/// [`pixel_light_part`] with [`Part::All`], [`Part::Near`] or
/// [`Part::Inside`], which queue one integral per emitting span, in the
/// spans' order): the emitting solids
/// (loops) it sees, and which ends of their visible stretches are cut off
/// by something in front, counting only stretches that add at least
/// `relative` of the pixel's light. Two pixels with the same signature see
/// the same lights whole or cut by the same shadow lines; a hard shadow
/// line between them, or a light that appears, changes it. A face of a
/// light turning edge-on does not (its light goes smoothly to 0).
pub(super) fn signature(
    light: &Lighting,
    spans: &[Span],
    sc: &PixelScratch,
    acc: &[f64],
    relative: f64,
) -> u64 {
    let (edges, rad) = (light.edges, light.rad);
    let k = rad.components;
    let least = relative * acc.iter().copied().fold(0.0, f64::max);
    let mut loops: Vec<u32> = Vec::new();
    let mut h = 0u64;
    // In the order `pixel_light` queued their integrals.
    let emitting = spans.iter().filter(|s| rad.edge_emits[s.edge as usize]);
    for (s, &g) in emitting.zip(&sc.em_g) {
        let ei = s.edge as usize;
        let e = &edges[ei];
        let brightest = (0..k)
            .map(|c| rad.edge_emission[ei * k + c])
            .fold(0.0, f64::max);
        if brightest * g / TAU < least {
            continue;
        }
        loops.push(e.loop_id);
        let (lo, hi) = e.extent();
        if s.s0 > lo + 1e-9 {
            h = h.wrapping_add(mix(2 * s.edge as u64));
        }
        if s.s1 < hi - 1e-9 {
            h = h.wrapping_add(mix(2 * s.edge as u64 + 1));
        }
    }
    loops.sort_unstable();
    loops.dedup();
    loops
        .iter()
        .fold(h, |h, &l| h.wrapping_add(mix((1 << 40) + l as u64)))
}

/// A 64-bit mix (SplitMix64's finaliser): summed over a pixel's emitting
/// spans, it tells apart different sets of them.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::visibility::{Sweeper, View, Viewpoint};
    use crate::{Material, MaterialKind};

    /// The parts of a pixel's light add up to the whole: `Near(r0)` (the
    /// direct light and what is reflected from within `r0`), `Band(r0,
    /// r1)` and `Far(r1)` sum to `All` at every floor pixel of a room of
    /// scattered pillars and two lamps (each part's reflected light is its
    /// spans' points at those distances, cut where the circles cross
    /// them), with falloff and without; `Band` and `Far` at `r0` report the
    /// same angle within `r0`, and neither holds direct light; `Inside`
    /// and `Outside` at either distance sum to `All` too, and split the
    /// direct light that `Near` holds whole; `Inside` queues one integral
    /// per emitting span, as [`signature`] reads them.
    #[test]
    fn near_band_and_far_add_up_to_the_whole() {
        let side = 40;
        let cells = (0..side * side)
            .map(|i| {
                let (x, y) = (i % side, i / side);
                let h = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 58;
                if x == 0 || y == 0 || x == side - 1 || y == side - 1 {
                    Cell::Solid(0)
                } else if (x, y) == (9, 9) || (x, y) == (30, 25) {
                    Cell::Solid(1)
                } else if x % 3 == 1 && y % 3 == 1 && h < 20 {
                    Cell::Solid(0)
                } else {
                    Cell::Floor
                }
            })
            .collect();
        let material = |kind, reflectance: f64, emission: f64| Material {
            color: [128; 3],
            kind,
            reflectance: [reflectance; 3],
            emission: [emission; 3],
            group: None,
            line: None,
        };
        let level = Level {
            name: "parts".into(),
            width: side,
            height: side,
            cells,
            albedo: vec![[0.5; 3]; side * side],
            materials: vec![
                material(MaterialKind::Wall, 0.5, 0.0),
                material(MaterialKind::Emitter, 0.3, 4.0),
            ],
            warnings: vec![],
            lossy_format: None,
            origin: Default::default(),
            floor_fraction: None,
        };
        let g = crate::geometry::trace(&level);
        let patches = Patches::new(&g, 1.0);
        let n = patches.len();
        let b = vec![
            (0..n)
                .map(|p| 0.2 + 0.01 * (p % 17) as f64)
                .collect::<Vec<_>>(),
        ];
        let slope = vec![(0..n).map(|p| 0.003 * (p % 5) as f64 - 0.006).collect()];
        let e = vec![
            g.edges
                .iter()
                .map(|ed| level.materials[ed.material as usize].emission[0])
                .collect(),
        ];
        let rad = Radiosity::new(&patches, &b, &slope, &e);
        let all_edges: Vec<u32> = (0..g.edges.len() as u32).collect();
        let (r0, r1) = (5.0, 13.0);
        for falloff in [None, Some(Falloff::new(8.0))] {
            let tree = PatchTree::new(&g.edges, &patches, &rad, 0..1, falloff, 0.0);
            let light = Lighting {
                edges: &g.edges,
                patches: &patches,
                rad: &rad,
                tree: &tree,
                falloff,
                kernel: Kernel::Flatland,
            };
            let (mut sw, mut spans, mut sc) = (Sweeper::new(), Vec::new(), PixelScratch::new());
            let (mut checked, mut split_lamps) = (0, 0);
            for y in 0..side {
                for x in 0..side {
                    let Some(comp) = g.component_at(x as i64, y as i64) else {
                        continue;
                    };
                    let p = [x as f64 + 0.5, y as f64 + 0.5];
                    spans.clear();
                    sw.sweep(
                        &g.edges,
                        &all_edges,
                        Viewpoint::new(p, View::Full, comp),
                        &mut spans,
                    );
                    let part = |part: Part, sc: &mut PixelScratch| {
                        let mut acc = [0.0];
                        pixel_light_part(&light, p, &spans, &mut acc, sc, part);
                        (acc[0], sc.near_angle)
                    };
                    let (whole, _) = part(Part::All, &mut sc);
                    let (near, _) = part(Part::Near(r0), &mut sc);
                    let (band, band_angle) = part(Part::Band(r0, r1), &mut sc);
                    let (far, _) = part(Part::Far(r1), &mut sc);
                    let (beyond_r0, far_angle) = part(Part::Far(r0), &mut sc);
                    let sum = near + band + far;
                    assert!(
                        (sum - whole).abs() <= 1e-9 * whole.abs().max(1e-6),
                        "{falloff:?} at {p:?}: {near} + {band} + {far} = {sum}, all {whole}"
                    );
                    assert!(
                        (band + far - beyond_r0).abs() <= 1e-9 * whole.abs().max(1e-6),
                        "{falloff:?} at {p:?}: band and far {} against far of r0 {beyond_r0}",
                        band + far
                    );
                    assert_eq!(band_angle, far_angle, "{falloff:?} at {p:?}");
                    checked += usize::from(band > 0.0 && far > 0.0);
                    // `Inside` and `Outside` split the direct light too.
                    let emitting = spans.iter().filter(|s| rad.edge_emits[s.edge as usize]);
                    let emitting = emitting.count();
                    for r in [r0, r1] {
                        let (inside, inside_angle) = part(Part::Inside(r), &mut sc);
                        // One integral per emitting span, as `signature`
                        // reads them.
                        assert_eq!(sc.em_edge.len(), emitting, "{falloff:?} at {p:?}, {r}");
                        let (outside, outside_angle) = part(Part::Outside(r), &mut sc);
                        let (near, _) = part(Part::Near(r), &mut sc);
                        let (far, _) = part(Part::Far(r), &mut sc);
                        let tol = 1e-9 * whole.abs().max(1e-6);
                        assert!(
                            (inside + outside - whole).abs() <= tol,
                            "{falloff:?} at {p:?}, {r}: {inside} + {outside}, all {whole}"
                        );
                        assert_eq!(inside_angle, outside_angle, "{falloff:?} at {p:?}");
                        // What `Near` holds beyond `Inside` is direct
                        // light from beyond `r`, which `Outside` holds
                        // beyond `Far`.
                        assert!(near - inside >= -tol, "{falloff:?} at {p:?}, {r}");
                        assert!(
                            ((near - inside) - (outside - far)).abs() <= tol,
                            "{falloff:?} at {p:?}, {r}"
                        );
                        split_lamps += usize::from(near - inside > 1e-3 * whole);
                    }
                }
            }
            assert!(
                checked > 500,
                "only {checked} pixels with light in both parts"
            );
            assert!(
                split_lamps > 500,
                "only {split_lamps} pixels with direct light beyond a split"
            );
        }
    }
}
