//! The two exact visibility queries agree with each other and with
//! brute-force ray casting, on random levels.

mod common;
use common::*;

use flatbake_core::geometry::{Edge, Geometry, trace};
use flatbake_core::level::Level;
use flatbake_core::visibility::{
    Blocks, FarWanted, Rect, Span, Structures, Sweeper, View, Viewpoint, VisitStats, Wanted,
    diamond, receiver_keeps,
};
use proptest::prelude::*;

/// Walls at a random density on floor.
fn level_strategy() -> impl Strategy<Value = Level> {
    grid_level(
        2..24,
        2..24,
        |v, density| if v % 16 < 2 + density * 2 { '#' } else { '.' },
        || vec![('#', wall(0.5))],
    )
}

/// First edge hit by the ray from `p` in direction `d` (brute force).
fn first_hit(edges: &[Edge], p: [f64; 2], d: [f64; 2]) -> Option<(u32, f64)> {
    let mut best: Option<(u32, f64)> = None;
    for (i, e) in edges.iter().enumerate() {
        let (lo, hi) = e.extent();
        let line = e.line();
        let (t, s) = if e.normal.is_vertical_edge() {
            if d[0] == 0.0 {
                continue;
            }
            let t = (line - p[0]) / d[0];
            (t, p[1] + t * d[1])
        } else {
            if d[1] == 0.0 {
                continue;
            }
            let t = (line - p[1]) / d[1];
            (t, p[0] + t * d[0])
        };
        if t > 1e-12 && s >= lo && s <= hi && best.is_none_or(|b| t < b.1) {
            best = Some((i as u32, t));
        }
    }
    best
}

/// The spans `a` and `b` (seen from `p`) are the same, up to rounding:
/// the same edges, in the same order, between the same axis coordinates
/// within 1e-9 (spans narrower than that are left out of both).
fn assert_same_spans(a: &[Span], b: &[Span], p: [f64; 2]) {
    let (a, b) = (wide(a), wide(b));
    assert_eq!(a.len(), b.len(), "point {p:?}");
    for (s, t) in a.iter().zip(&b) {
        assert_eq!(s.edge, t.edge, "point {p:?}");
        assert!(
            (s.s0 - t.s0).abs() < 1e-9 && (s.s1 - t.s1).abs() < 1e-9,
            "point {p:?}: {s:?} vs {t:?}"
        );
    }
}

/// The spans wider than rounding. Where two vertices are collinear with
/// the query point, their pseudo-angles may differ by an ulp, and the sweep
/// and the walk may then disagree on a sliver between them (an axis length
/// of about 1e-15, found by this test): that is rounding, not a difference.
fn wide(spans: &[Span]) -> Vec<Span> {
    spans
        .iter()
        .copied()
        .filter(|s| s.s1 - s.s0 > 1e-9)
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(150))]

    #[test]
    fn sweep_walk_and_ray_casting_agree(l in level_strategy()) {
        let g = trace(&l);
        let all: Vec<u32> = (0..g.edges.len() as u32).collect();
        let blocks = Blocks::new(&g);
        let mut sw = Sweeper::new();
        for y in 0..l.height {
            for x in 0..l.width {
                let Some(comp) = g.component_at(x as i64, y as i64) else { continue };
                let p = [x as f64 + 0.5, y as f64 + 0.5];
                let (mut a, mut b): (Vec<Span>, Vec<Span>) = (vec![], vec![]);
                sw.sweep(&g.edges, &all, Viewpoint::new(p, View::Full, comp), &mut a);
                sw.walk(&blocks, Viewpoint::new(p, View::Full, comp), f64::INFINITY, &mut b);
                let (a, b) = (wide(&a), wide(&b));
                prop_assert_eq!(a.len(), b.len(), "pixel ({}, {})", x, y);
                for (s, t) in a.iter().zip(&b) {
                    prop_assert_eq!(s.edge, t.edge);
                    prop_assert!((s.s0 - t.s0).abs() < 1e-9 && (s.s1 - t.s1).abs() < 1e-9, "{:?} vs {:?}", s, t);
                }
                // Rays between span boundaries hit the span's edge first.
                for k in 0..720 {
                    let ang = (k as f64 + 0.37) / 720.0 * std::f64::consts::TAU;
                    let d = [ang.cos(), ang.sin()];
                    let key = diamond(d[0], d[1]);
                    let hit = first_hit(&g.edges, p, d);
                    let span = a.iter().find(|s| s.k0 < key && key < s.k1);
                    match (hit, span) {
                        (Some((e, _)), Some(s)) => prop_assert_eq!(e, s.edge, "pixel ({}, {}) angle {}", x, y, ang),
                        (None, None) => {}
                        (h, s) => {
                            // Allowed only within rounding of a span boundary.
                            let near = a.iter().any(|s| (s.k0 - key).abs() < 1e-9 || (s.k1 - key).abs() < 1e-9);
                            prop_assert!(near, "pixel ({}, {}) angle {}: ray {:?} span {:?}", x, y, ang, h, s);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn half_views_agree_between_sweep_and_walk(l in level_strategy()) {
        let g = trace(&l);
        let all: Vec<u32> = (0..g.edges.len() as u32).collect();
        let blocks = Blocks::new(&g);
        let mut sw = Sweeper::new();
        for e in &g.edges {
            let (lo, hi) = e.extent();
            let s = lo + 0.3 * (hi - lo);
            let p = e.point_at(s);
            let (mut a, mut b): (Vec<Span>, Vec<Span>) = (vec![], vec![]);
            sw.sweep(&g.edges, &all, Viewpoint::new(p, View::Half(e.normal), e.component), &mut a);
            sw.walk(&blocks, Viewpoint::new(p, View::Half(e.normal), e.component), f64::INFINITY, &mut b);
            let (a, b) = (wide(&a), wide(&b));
            prop_assert_eq!(a.len(), b.len());
            for (s, t) in a.iter().zip(&b) {
                prop_assert_eq!(s.edge, t.edge);
                prop_assert!((s.s0 - t.s0).abs() < 1e-9 && (s.s1 - t.s1).abs() < 1e-9, "{:?} vs {:?}", s, t);
            }
        }
    }
}

/// Larger levels with rooms and thin walls, so the tile tree has depth;
/// `n` strokes on up to `size` pixels a side (dense enough, the regions get
/// long candidate lists and use the occlusion walk).
fn structured_strategy(size: usize, n: usize) -> impl Strategy<Value = Level> {
    (
        20usize..size,
        20usize..size,
        proptest::collection::vec((0usize..size, 0usize..size, 1usize..30, 0u8..3), 1..n),
    )
        .prop_map(|(w, h, rects)| {
            let mut grid = vec![vec!['.'; w]; h];
            for (x, y, len, kind) in rects {
                for k in 0..len {
                    let (px, py) = match kind {
                        0 => (x + k, y),
                        1 => (x, y + k),
                        _ => (x + k % 3, y + k / 3),
                    };
                    if px < w && py < h {
                        grid[py][px] = '#';
                    }
                }
            }
            let rows: Vec<String> = grid.into_iter().map(|r| r.into_iter().collect()).collect();
            ascii(&refs(&rows), &[('#', wall(0.5))])
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    /// Culled candidate lists never change what a point sees.
    #[test]
    fn tile_tree_culling_is_conservative(l in structured_strategy(70, 25)) {
        same_as_full_sweep(&l)?;
    }

    /// The same on dense clutter, where regions walk the blocks.
    #[test]
    fn tile_tree_walk_is_exact_on_dense_clutter(l in structured_strategy(130, 220)) {
        same_as_full_sweep(&l)?;
    }
}

fn same_as_full_sweep(l: &Level) -> Result<(), TestCaseError> {
    let g = trace(l);
    let (pixels, pos) = free_pixel_centres(&g, l);
    let comp = |i: usize| {
        g.component_at(pixels[i][0] as i64, pixels[i][1] as i64)
            .unwrap()
    };
    culled_same_as_all(&g, &pos, &pixels, &|_| View::Full, &comp, &|s| s.to_vec())
}

/// Every free pixel of `l` and its centre.
fn free_pixel_centres(
    g: &flatbake_core::geometry::Geometry,
    l: &Level,
) -> (Vec<[i32; 2]>, Vec<[f64; 2]>) {
    let mut pixels = Vec::new();
    let mut pos = Vec::new();
    for y in 0..l.height {
        for x in 0..l.width {
            if g.component_at(x as i64, y as i64).is_some() {
                pixels.push([x as i32, y as i32]);
                pos.push([x as f64 + 0.5, y as f64 + 0.5]);
            }
        }
    }
    (pixels, pos)
}

/// Fields of rectangular obstacles (1 to 9 px a side, some touching), the
/// case the box test of the tile tree culls.
fn obstacle_strategy() -> impl Strategy<Value = Level> {
    (
        16usize..56,
        16usize..56,
        proptest::collection::vec((0usize..56, 0usize..56, 1usize..10, 1usize..10), 1..30),
    )
        .prop_map(|(w, h, rects)| {
            let mut grid = vec![vec!['.'; w]; h];
            for (x, y, rw, rh) in rects {
                for row in grid.iter_mut().skip(y).take(rh) {
                    for c in row.iter_mut().skip(x).take(rw) {
                        *c = '#';
                    }
                }
            }
            let rows: Vec<String> = grid.into_iter().map(|r| r.into_iter().collect()).collect();
            ascii(&refs(&rows), &[('#', wall(0.5))])
        })
}

/// Spans seen through `for_each_visibility` (culled candidate lists) at
/// `pos`, against a sweep over every edge; `view` and `comp` per point.
/// Both sides are compared after `kept` (all spans, or [`wide`] ones).
fn culled_same_as_all(
    g: &flatbake_core::geometry::Geometry,
    pos: &[[f64; 2]],
    pixels: &[[i32; 2]],
    view: &(dyn Fn(usize) -> View + Sync),
    comp: &dyn Fn(usize) -> u32,
    kept: &dyn Fn(&[Span]) -> Vec<Span>,
) -> Result<(), TestCaseError> {
    let all: Vec<u32> = (0..g.edges.len() as u32).collect();
    let got: Vec<std::sync::Mutex<Vec<Span>>> =
        (0..pos.len()).map(|_| Default::default()).collect();
    flatbake_core::visibility::for_each_visibility(
        g,
        pos,
        pixels,
        view,
        f64::INFINITY,
        None,
        &|i, spans: &[Span]| {
            *got[i].lock().unwrap() = spans.to_vec();
        },
    );
    let mut sw = Sweeper::new();
    for i in 0..pos.len() {
        let mut want = Vec::new();
        sw.sweep(
            &g.edges,
            &all,
            Viewpoint::new(pos[i], view(i), comp(i)),
            &mut want,
        );
        let (got, want) = (kept(&got[i].lock().unwrap()), kept(&want));
        prop_assert_eq!(got.len(), want.len(), "point {:?}", pos[i]);
        for (s, t) in got.iter().zip(&want) {
            prop_assert_eq!(s.edge, t.edge, "point {:?}", pos[i]);
            prop_assert!((s.s0 - t.s0).abs() < 1e-9 && (s.s1 - t.s1).abs() < 1e-9);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    /// Among solid boxes the tile tree culls edges that a box hides from a
    /// whole region: never one that a pixel centre, or a point on an edge
    /// looking out of it, can see.
    #[test]
    fn box_culling_is_conservative(l in obstacle_strategy()) {
        let g = trace(&l);
        let (pixels, pos) = free_pixel_centres(&g, &l);
        let comp = |i: usize| g.component_at(pixels[i][0] as i64, pixels[i][1] as i64).unwrap();
        // Spans wider than rounding: an edge that a box hides but for a
        // grazing direction can leave a sliver of ~1e-15 in the full sweep.
        culled_same_as_all(&g, &pos, &pixels, &|_| View::Full, &comp, &wide)?;
        // Points on edges (as form factors ask), on pixel sides, down to a
        // hair from a corner. Not on the corner itself: there the face that
        // starts at the point is at distance 0, so the plain sweep sees
        // through the solid pixel behind it, which a box rightly hides (no
        // form factor or sample point sits on an edge's end).
        let (mut epos, mut epix, mut eview, mut ecomp) = (vec![], vec![], vec![], vec![]);
        for e in &g.edges {
            let (lo, hi) = e.extent();
            for s in [lo + 1e-6, lo + 0.3 * (hi - lo), 0.5 * (lo + hi), hi - 1e-6] {
                epos.push(e.point_at(s));
                epix.push(e.free_pixel_at((s.floor() as i32).min(hi as i32 - 1)));
                eview.push(View::Half(e.normal));
                ecomp.push(e.component);
            }
        }
        culled_same_as_all(&g, &epos, &epix, &|i| eview[i], &|i| ecomp[i], &wide)?;
    }

    /// The exact box test claims a box hides an edge only when every
    /// segment from the zone to the edge meets the box (checked on a grid
    /// of segments, corners and inside points).
    #[test]
    fn box_hides_only_when_every_segment_meets_the_box(
        (zx, zy, zw, zh) in (0i32..20, 0i32..20, 1i32..6, 1i32..6),
        (bx, by, bw, bh) in (0i32..30, 0i32..30, 1i32..10, 1i32..10),
        (ex, ey, el, vertical) in (0i32..30, 0i32..30, 1i32..12, proptest::bool::ANY),
        centres in proptest::bool::ANY,
    ) {
        use flatbake_core::geometry::Normal;
        use flatbake_core::visibility::{Rect, Zone, box_hides};
        let r = Rect { x0: zx, y0: zy, x1: zx + zw, y1: zy + zh };
        let b = Rect { x0: bx, y0: by, x1: bx + bw, y1: by + bh };
        let (a, e_end, normal) = if vertical {
            ([ex, ey], [ex, ey + el], Normal::Left)
        } else {
            ([ex + el, ey], [ex, ey], Normal::Up)
        };
        let e = Edge { a, b: e_end, normal, material: 0, loop_id: 0, run: 0, component: 0, rectangle: false };
        let z = Zone::of(r, centres);
        if box_hides(&z, &e, &b) {
            let (zx0, zy0) = (z.x0 as f64 / 2.0, z.y0 as f64 / 2.0);
            let (zx1, zy1) = (z.x1 as f64 / 2.0, z.y1 as f64 / 2.0);
            let meets = |p: [f64; 2], q: [f64; 2]| {
                // Liang-Barsky clip of the segment against the closed box.
                let (mut t0, mut t1) = (0.0f64, 1.0f64);
                let d = [q[0] - p[0], q[1] - p[1]];
                for (dd, lo, hi, pp) in [
                    (d[0], b.x0 as f64, b.x1 as f64, p[0]),
                    (d[1], b.y0 as f64, b.y1 as f64, p[1]),
                ] {
                    if dd == 0.0 {
                        if pp < lo - 1e-9 || pp > hi + 1e-9 { return false; }
                    } else {
                        let (mut ta, mut tb) = ((lo - pp) / dd, (hi - pp) / dd);
                        if ta > tb { std::mem::swap(&mut ta, &mut tb); }
                        t0 = t0.max(ta);
                        t1 = t1.min(tb);
                    }
                }
                t0 <= t1 + 1e-9
            };
            let n = 6;
            for i in 0..=n {
                for j in 0..=n {
                    let p = [
                        zx0 + (zx1 - zx0) * i as f64 / n as f64,
                        zy0 + (zy1 - zy0) * j as f64 / n as f64,
                    ];
                    for k in 0..=n {
                        let t = k as f64 / n as f64;
                        let y = [
                            a[0] as f64 + (e_end[0] - a[0]) as f64 * t,
                            a[1] as f64 + (e_end[1] - a[1]) as f64 * t,
                        ];
                        prop_assert!(meets(p, y), "{:?} -> {:?} misses {:?}", p, y, b);
                    }
                }
            }
        }
    }
}

/// The box test does cull: a wall behind a block, seen from a room on the
/// other side, is not among that room's candidates (no single straight run
/// hides it, since the block is thicker than the room is tall).
#[test]
fn a_box_between_a_region_and_an_edge_culls_it() {
    use flatbake_core::visibility::{LeafRegions, TileTree};
    // A block at x 10..20, y 10..20; a one-pixel post at (26, 24..26).
    // From the leaf 0..8 x 0..8, segments to the post's left face enter
    // the block through its top face or its left face: no one straight run
    // hides the post, the block does.
    let mut rows = vec![String::from("................................"); 32];
    for (y, row) in rows.iter_mut().enumerate() {
        let mut r: Vec<char> = row.chars().collect();
        if (10..20).contains(&y) {
            r[10..20].fill('#');
        }
        if (24..26).contains(&y) {
            r[26] = '#';
        }
        *row = r.into_iter().collect();
    }
    let l = ascii(&refs(&rows), &[('#', wall(0.5))]);
    let g = trace(&l);
    let post = g
        .edges
        .iter()
        .position(|e| e.line() == 26.0 && e.normal == flatbake_core::geometry::Normal::Left)
        .expect("the post's left face") as u32;
    let inside = |r: &Rect| r.x0 <= 3 && 3 < r.x1 && r.y0 <= 3 && 3 < r.y1;
    for centres in [true, false] {
        let tree = TileTree::new(&g, centres);
        let found = std::sync::Mutex::new(None);
        tree.for_each_leaf(
            // A full leaf of 64 points (culling pays only for many).
            &|r: Rect| if inside(&r) { 64 } else { 0 },
            f64::INFINITY,
            &|leaf: &LeafRegions| {
                if inside(&leaf.rect) {
                    let c = leaf.candidates_at([3, 3]).map(|c| c.to_vec());
                    *found.lock().unwrap() = Some(c);
                }
            },
        );
        let cands = found.into_inner().unwrap().expect("the leaf was visited");
        let cands = cands.expect("a short list: swept");
        assert!(
            !cands.contains(&post),
            "centres {centres}: the post behind the block is culled: {cands:?}"
        );
    }
}

/// A plain room beside a field of pillars behind a wall: its room's points
/// have short candidate lists, its pillar field's points walk the blocks.
fn room_and_pillar_field() -> Level {
    walled(120, 64, |x, y| {
        let pillar = x > 34 && (x % 4 == 1) && (y % 5 == 2) && (x + y) % 3 != 0;
        x == 30 || pillar
    })
}

/// A room `w` x `h` px inside a one-pixel wall, with the pixels `solid`
/// picks painted as wall too.
fn walled(w: usize, h: usize, solid: impl Fn(usize, usize) -> bool) -> Level {
    let rows: Vec<String> = (0..h)
        .map(|y| {
            (0..w)
                .map(|x| {
                    let border = x == 0 || y == 0 || x == w - 1 || y == h - 1;
                    if border || solid(x, y) { '#' } else { '.' }
                })
                .collect()
        })
        .collect();
    ascii(&refs(&rows), &[('#', wall(0.5))])
}

/// Every point's spans from one call of `for_each_visibility_counted`
/// (`None` for a point handed back to `defer`).
fn spans_of(
    structures: &Structures,
    pos: Option<&[[f64; 2]]>,
    pixels: &[[i32; 2]],
    defer: Option<&(dyn Fn(usize) + Sync)>,
) -> Vec<Option<Vec<Span>>> {
    visit(structures, pos, pixels, defer).0
}

/// [`spans_of`], and what the call counted.
fn visit(
    structures: &Structures,
    pos: Option<&[[f64; 2]]>,
    pixels: &[[i32; 2]],
    defer: Option<&(dyn Fn(usize) + Sync)>,
) -> (Vec<Option<Vec<Span>>>, VisitStats) {
    let got: Vec<std::sync::Mutex<Option<Vec<Span>>>> =
        (0..pixels.len()).map(|_| Default::default()).collect();
    let stats = flatbake_core::visibility::for_each_visibility_counted(
        structures,
        pos,
        pixels,
        &|_| View::Full,
        f64::INFINITY,
        None,
        &|_| {},
        defer,
        &|i, spans: &[Span]| {
            let mut slot = got[i].lock().unwrap();
            assert!(slot.is_none(), "point {i} visited twice");
            *slot = Some(spans.to_vec());
        },
    );
    let spans = got.into_iter().map(|m| m.into_inner().unwrap()).collect();
    (spans, stats)
}

/// On open ground no point walks: in a room of 1 px pillars scattered as
/// sparsely as lamps in a field of lights, an 8 px tile's region lists
/// more than `TileTree::SWEEP_SHORT` edges, which culling leaves almost
/// whole and each point away from the walls mostly sees (the region is
/// open, `Region::open`). So the region's first point sweeps its list (at
/// most `TileTree::SWEEP_FIRST` edges) rather than walking every block to
/// find that out, and the rest follow. With the first point walking (a
/// `SWEEP_FIRST` of 0, checked by hand) the count is one walk per region.
/// The spans are those of a plain sweep over every edge.
#[test]
fn open_ground_is_swept_from_each_regions_first_point() {
    let level = walled(200, 200, |x, y| {
        // One pillar per 20 px cell, at an offset that a hash of the cell
        // picks.
        let (cx, cy) = (x / 20, y / 20);
        let h = (cx as u64 * 0x9e37_79b9 + cy as u64 * 0x85eb_ca6b) % 1009;
        (x % 20, y % 20) == (2 + h as usize % 16, 2 + (h as usize / 16) % 16)
    });
    let g = trace(&level);
    // Away from the room's walls, where a point sees less than half of
    // its list and the region rightly walks.
    let (pixels, _) = free_pixel_centres(&g, &level);
    let pixels: Vec<[i32; 2]> = pixels
        .into_iter()
        .filter(|p| p.iter().all(|&c| (40..160).contains(&c)))
        .collect();
    let (got, stats) = visit(&Structures::new(&g), None, &pixels, None);
    let n = pixels.len();
    assert_eq!(stats.walks, 0, "{} points of {n} walked", stats.walks);
    let all: Vec<u32> = (0..g.edges.len() as u32).collect();
    let mut sw = Sweeper::new();
    for (&[x, y], spans) in pixels.iter().zip(&got).step_by(5) {
        let comp = g.component_at(x as i64, y as i64).unwrap();
        let p = [x as f64 + 0.5, y as f64 + 0.5];
        let mut want = Vec::new();
        sw.sweep(
            &g.edges,
            &all,
            Viewpoint::new(p, View::Full, comp),
            &mut want,
        );
        let spans = spans.as_ref().expect("every point visited");
        assert_same_spans(spans, &want, p);
    }
}

/// With `defer`, every point is either queried (with the spans it gets
/// without `defer`) or handed back, exactly once: in a level of a plain
/// room beside a field of pillars behind a wall, the pillar field's points
/// (long candidate lists) are handed back and the room's are not.
#[test]
fn deferring_hands_back_walking_points_and_keeps_the_rest() {
    let level = room_and_pillar_field();
    let g = trace(&level);
    let (pixels, _) = free_pixel_centres(&g, &level);
    let all = spans_of(&Structures::new(&g), None, &pixels, None);
    let handed: Vec<std::sync::atomic::AtomicU32> =
        (0..pixels.len()).map(|_| Default::default()).collect();
    let defer = |i: usize| {
        handed[i].fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    };
    let some = spans_of(&Structures::new(&g), None, &pixels, Some(&defer));
    let mut deferred = 0;
    for i in 0..pixels.len() {
        let n = handed[i].load(std::sync::atomic::Ordering::Relaxed);
        match &some[i] {
            Some(spans) => {
                assert_eq!(n, 0, "point {i} queried and handed back");
                assert_eq!(Some(spans), all[i].as_ref(), "point {i}");
            }
            None => {
                assert_eq!(n, 1, "point {i} neither queried nor handed back once");
                deferred += 1;
            }
        }
    }
    assert!(
        deferred > 0 && deferred < pixels.len(),
        "{deferred} of {} points handed back",
        pixels.len()
    );
}

/// The structures a call builds are kept for the next: calls that share
/// one [`Structures`] (points off the pixel centres and at them, in either
/// order, a part of the pixels and all of them) give every point the spans
/// that a call with structures of its own gives, so sharing them between
/// the passes of a gather changes nothing.
#[test]
fn kept_structures_give_the_same_spans() {
    let level = room_and_pillar_field();
    let g = trace(&level);
    let (pixels, _) = free_pixel_centres(&g, &level);
    let off: Vec<[f64; 2]> = pixels
        .iter()
        .map(|p| [p[0] as f64 + 0.25, p[1] as f64 + 0.75])
        .collect();
    let fresh_off = spans_of(&Structures::new(&g), Some(&off), &pixels, None);
    let fresh = spans_of(&Structures::new(&g), None, &pixels, None);
    let half = &pixels[..pixels.len() / 2];
    // Off the centres first, then centres first.
    let kept = Structures::new(&g);
    assert_eq!(spans_of(&kept, Some(&off), &pixels, None), fresh_off);
    assert_eq!(spans_of(&kept, None, half, None)[..], fresh[..half.len()]);
    assert_eq!(spans_of(&kept, None, &pixels, None), fresh);
    let kept = Structures::new(&g);
    assert_eq!(spans_of(&kept, None, half, None)[..], fresh[..half.len()]);
    assert_eq!(spans_of(&kept, Some(&off), &pixels, None), fresh_off);
    assert_eq!(spans_of(&kept, None, &pixels, None), fresh);
    // No points: nothing to build or visit.
    assert!(spans_of(&Structures::new(&g), None, &[], None).is_empty());
}

/// A room `side` px square holding one-pixel dots scattered at about one
/// pixel in `sparse`.
fn dot_field(side: usize, sparse: u64, seed: u64) -> Level {
    walled(side, side, |x, y| {
        let h = ((x * side + y) as u64 ^ seed).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 40;
        x % 2 == 1 && y % 2 == 1 && h.is_multiple_of(sparse)
    })
}

/// Every free pixel centre of a `side` x `side` level (full view) and a
/// point on every edge (half view).
fn free_centres_and_edge_points(g: &Geometry, side: usize) -> Vec<Viewpoint> {
    let mut points: Vec<Viewpoint> = Vec::new();
    for y in 0..side {
        for x in 0..side {
            if let Some(comp) = g.component_at(x as i64, y as i64) {
                let p = [x as f64 + 0.5, y as f64 + 0.5];
                points.push(Viewpoint::new(p, View::Full, comp));
            }
        }
    }
    for e in &g.edges {
        let (lo, hi) = e.extent();
        let p = e.point_at(lo + 0.3 * (hi - lo));
        points.push(Viewpoint::new(p, View::Half(e.normal), e.component));
    }
    points
}

/// On a level dense enough for small blocks (a field of one-pixel dots,
/// where far dots are seen through narrow gaps), the walk gives the
/// sweep's spans, from every free pixel centre and from a point on every
/// edge.
#[test]
fn walk_over_small_blocks_agrees_with_the_sweep() {
    let g = trace(&dot_field(48, 1, 7));
    let blocks = Blocks::new(&g);
    assert_eq!(blocks.side(), Blocks::DENSE_SIZE, "{} edges", g.edges.len());
    let all: Vec<u32> = (0..g.edges.len() as u32).collect();
    let mut sw = Sweeper::new();
    let mut far_seen = 0;
    for at in free_centres_and_edge_points(&g, 48) {
        let (mut a, mut b): (Vec<Span>, Vec<Span>) = (vec![], vec![]);
        sw.sweep(&g.edges, &all, at, &mut a);
        sw.walk(&blocks, at, f64::INFINITY, &mut b);
        assert_same_spans(&a, &b, at.p);
        let a = wide(&a);
        far_seen += a
            .iter()
            .filter(|s| {
                let e = &g.edges[s.edge as usize];
                e.distance_sq(at.p) > 16.0 * 16.0
            })
            .count();
    }
    // Far dots are seen through the gaps (else the test walks nothing far).
    assert!(far_seen > 1000, "{far_seen} spans of dots past 16 px");
}

/// With [`FarWanted`], a walk leaves the blocks past its radius unwalked
/// except in the directions of the edges wanted there (and tests the
/// blocks there only in those directions), and no wanted span changes: on
/// fields of dots whose reaches are mostly short, with a few edges of long
/// reach and some with no light, every free pixel centre (full view) and a
/// point on every edge (half view) gets the spans of the walk that goes
/// everywhere, at each radius `FarWanted::new` may choose, with and
/// without the receiving cosine ([`Wanted::cosine`], which also closes
/// directions). Fewer dim spans are counted with it: blocks were left
/// unwalked.
#[test]
fn far_wanted_changes_no_wanted_span() {
    let cells = FarWanted::NARROW.into_iter().chain([FarWanted::CELL]);
    let levels = [
        (150, 3, 1u64, None),
        (130, 6, 2, None),
        (150, 3, 1, Some(30.0 * 30.0)),
    ];
    for ((side, sparse, seed, cosine), cell) in levels
        .into_iter()
        .flat_map(|level| cells.clone().map(move |c| (level, c)))
    {
        let level = dot_field(side, sparse, seed);
        let g = trace(&level);
        let reach2: Vec<f64> = (0..g.edges.len() as u64)
            .map(|i| {
                let h = (i ^ seed).wrapping_mul(0x2545_f491_4f6c_dd1d) >> 32;
                match h % 100 {
                    0..=9 => -1.0,
                    10..=12 => 200.0 * 200.0,
                    r => ((r % 13) as f64).powi(2),
                }
            })
            .collect();
        let far =
            FarWanted::with_cell(&g, &reach2, cell).expect("short reaches: the lists are kept");
        assert_eq!(far.radius(), cell as f64);
        let blocks = Blocks::new(&g);
        let wanted = Some(Wanted {
            reach2: &reach2,
            class: None,
            cosine,
        });
        let mut sw = Sweeper::new();
        let (mut dim_all, mut dim_far) = (0, 0);
        for at in free_centres_and_edge_points(&g, side) {
            let (mut a, mut b): (Vec<Span>, Vec<Span>) = (vec![], vec![]);
            dim_all += sw.walk_wanted(&blocks, at, f64::INFINITY, wanted, None, &mut a);
            dim_far += sw.walk_wanted(&blocks, at, f64::INFINITY, wanted, Some(&far), &mut b);
            assert_eq!(
                a, b,
                "dots {side} px, one in {sparse}, radius {cell}, cosine {cosine:?}: point {:?}",
                at.p
            );
        }
        assert!(
            dim_far < dim_all,
            "dots {side} px, radius {cell}: no block left unwalked ({dim_far} dim spans, {dim_all} without)"
        );
    }
}

/// A walk that filters no span but closes its directions past a radius
/// except towards a few lights ([`FarWanted`] over the lights' reaches
/// alone, widened: how a dense level's anchors walk) sees the lights as
/// the walk that goes everywhere does, and every edge that lies within
/// the radius too: on a field of dots, from every free pixel centre and a
/// point on every edge, the spans of the lights and of the edges whose
/// farther end is within the radius are the same. It returns fewer spans:
/// blocks past the radius in the other directions are not walked.
#[test]
fn a_walk_closed_but_towards_the_lights_sees_them_and_what_is_near() {
    let g = trace(&dot_field(150, 3, 1));
    let lamp = |e: u32| e.is_multiple_of(97);
    let reach2: Vec<f64> = (0..g.edges.len() as u32)
        .map(|e| if lamp(e) { 400.0 * 400.0 } else { -1.0 })
        .collect();
    let radius = 32;
    let far = FarWanted::with_cell(&g, &reach2, radius)
        .expect("few lights: the lists are kept")
        .widened(0.1);
    let blocks = Blocks::new(&g);
    let mut sw = Sweeper::new();
    let (mut everywhere, mut closed) = (0, 0);
    for at in free_centres_and_edge_points(&g, 150) {
        let (mut a, mut b): (Vec<Span>, Vec<Span>) = (vec![], vec![]);
        sw.walk_wanted(&blocks, at, f64::INFINITY, None, None, &mut a);
        sw.walk_wanted(&blocks, at, f64::INFINITY, None, Some(&far), &mut b);
        let kept = |spans: &[Span]| -> Vec<Span> {
            spans
                .iter()
                .filter(|s| {
                    let e = &g.edges[s.edge as usize];
                    let d = |v: [i32; 2]| (v[0] as f64 - at.p[0]).hypot(v[1] as f64 - at.p[1]);
                    lamp(s.edge) || d(e.a).max(d(e.b)) < radius as f64
                })
                .copied()
                .collect()
        };
        assert_same_spans(&kept(&a), &kept(&b), at.p);
        everywhere += a.len();
        closed += b.len();
    }
    assert!(
        closed < everywhere,
        "nothing left unwalked: {closed} spans against {everywhere}"
    );
}

/// `FarWanted::new` takes the narrowest radius for which few edges with
/// light are listed: 8 px when every reach is 2 px, 16 px when reaches of
/// 12 px list every edge at 8 px, and 32 px when every edge reaches 20 px
/// (edges without light are never listed).
#[test]
fn far_wanted_radius_follows_the_reaches() {
    let g = trace(&dot_field(150, 3, 1));
    for (reach, want) in [(2.0, 8.0), (12.0, 16.0), (20.0, 32.0)] {
        let reach2: Vec<f64> = (0..g.edges.len())
            .map(|i| if i % 3 == 0 { -1.0 } else { reach * reach })
            .collect();
        let far = FarWanted::new(&g, &reach2).expect("short reaches: the lists are kept");
        assert_eq!(far.radius(), want, "every reach {reach} px");
    }
}

/// The receiving cosine ([`Wanted::cosine`]) leaves out only spans whose
/// light is below the bound the reach stands for: from a point on every
/// edge of a field of dots (half views), the sweep over every edge with
/// the cosine returns the spans it returns without, less some far ones;
/// for each of those, the edge's largest cosine (sampled along it) times
/// the bound at its distance is at most the bound at its reach. The walk
/// with [`FarWanted`] gives the same spans as the sweep.
#[test]
fn receiving_cosine_leaves_out_only_light_below_the_bound() {
    let g = trace(&dot_field(150, 3, 1));
    let a = 30.0f64 * 30.0;
    let w = |r: f64| a / (a + r * r);
    let reach2: Vec<f64> = (0..g.edges.len())
        .map(|i| {
            if i % 29 == 0 {
                200.0 * 200.0
            } else {
                3.0 * 3.0
            }
        })
        .collect();
    let all: Vec<u32> = (0..g.edges.len() as u32).collect();
    let far = FarWanted::new(&g, &reach2).expect("short reaches: the lists are kept");
    let blocks = Blocks::new(&g);
    let with = |cosine| {
        Some(Wanted {
            reach2: &reach2,
            class: None,
            cosine,
        })
    };
    let mut sw = Sweeper::new();
    let mut dropped = 0;
    for at in free_centres_and_edge_points(&g, 150)
        .into_iter()
        .filter(|at| at.view != View::Full)
    {
        let (mut plain, mut cut, mut walked): (Vec<Span>, Vec<Span>, Vec<Span>) =
            (vec![], vec![], vec![]);
        sw.sweep_wanted(&g.edges, &all, at, with(None), &mut plain);
        sw.sweep_wanted(&g.edges, &all, at, with(Some(a)), &mut cut);
        sw.walk_wanted(
            &blocks,
            at,
            f64::INFINITY,
            with(Some(a)),
            Some(&far),
            &mut walked,
        );
        assert_same_spans(&cut, &walked, at.p);
        let mut rest = cut.iter().peekable();
        for s in &plain {
            if rest.peek() == Some(&s) {
                rest.next();
                continue;
            }
            dropped += 1;
            let e = &g.edges[s.edge as usize];
            let (d, r) = (e.distance_sq(at.p).sqrt(), reach2[s.edge as usize].sqrt());
            let View::Half(n) = at.view else {
                unreachable!()
            };
            let nv = n.vec();
            let (lo, hi) = e.extent();
            let c = (0..=1000)
                .map(|k| {
                    let q = e.point_at(lo + (hi - lo) * k as f64 / 1000.0);
                    let (dx, dy) = (q[0] - at.p[0], q[1] - at.p[1]);
                    (dx * nv[0] as f64 + dy * nv[1] as f64) / dx.hypot(dy)
                })
                .fold(0.0f64, f64::max);
            let l = e.len();
            let bound = |r: f64| w(r) * std::f64::consts::PI.min(l / r);
            assert!(
                c * bound(d) <= bound(r) * (1.0 + 1e-9),
                "point {:?}: edge {} at {d:.2} px (reach {r}) left out with cosine {c:.4}",
                at.p,
                s.edge
            );
        }
        assert!(
            rest.next().is_none(),
            "point {:?}: a span only with the cosine",
            at.p
        );
    }
    assert!(dropped > 100, "{dropped} spans left out by the cosine");
}

proptest! {
    /// [`receiver_keeps`] keeps every pair whose bound, times the cosine,
    /// is above the bound at the reach (`w(r) min(pi, L / r)`, the
    /// reaches' own bound up to a constant factor).
    #[test]
    fn receiver_keeps_what_the_bound_keeps(
        f in 1.0f64..300.0,
        l in 0.5f64..600.0,
        r in 0.5f64..3000.0,
        t in 0.0f64..1.0,
        c in 0.0f64..1.0,
    ) {
        let a = f * f;
        let d = (t * r).max(1e-3);
        let bound = |x: f64| a / (a + x * x) * std::f64::consts::PI.min(l / x);
        if c * bound(d) > bound(r) * (1.0 + 1e-12) {
            prop_assert!(receiver_keeps(c * c, a, d * d, r * r), "c {c} d {d} r {r} L {l} A {a}");
        }
    }
}

/// Squared reaches for `edges` edges that leave some without light, some
/// with a reach of a few pixels and some unlimited, from `seed`.
fn mixed_reaches(edges: usize, seed: u64) -> Vec<f64> {
    (0..edges as u64)
        .map(|i| {
            let h = (i ^ seed).wrapping_mul(0x2545_f491_4f6c_dd1d) >> 32;
            match h % 10 {
                0..=3 => -1.0,
                4..=7 => ((h / 10 % 6) as f64).powi(2),
                _ => f64::INFINITY,
            }
        })
        .collect()
}

/// A sweep gives the same spans, and counts the same spans of edges with
/// light as left out, whether it takes two unwanted pieces that meet at a
/// pillar's corner as one silhouette or not: from `points`, over every
/// edge of `g`, with reaches `reach2`; and so does a walk, which takes two
/// such pieces as one whether wanted or not and reads the silhouette's
/// spans off as its two pieces'. Returns how many silhouettes they took.
///
/// The same up to rounding ([`assert_same_spans`]): where several vertices
/// lie on one ray from the point, a span that ends on that ray is cut
/// through whichever of them comes first in the sweep's order, and the
/// corner inside a silhouette is no longer one of them (found by this
/// test: 13.4 against 13.399999999999999).
fn silhouettes_change_nothing(g: &Geometry, points: &[Viewpoint], reach2: &[f64]) -> u64 {
    let all: Vec<u32> = (0..g.edges.len() as u32).collect();
    let wanted = Some(Wanted {
        reach2,
        class: None,
        cosine: None,
    });
    let blocks = Blocks::new(g);
    let (mut with, mut without) = (Sweeper::new(), Sweeper::new());
    without.set_silhouettes(false);
    for &at in points {
        let (mut a, mut b): (Vec<Span>, Vec<Span>) = (vec![], vec![]);
        let dim_a = with.sweep_wanted(&g.edges, &all, at, wanted, &mut a);
        let dim_b = without.sweep_wanted(&g.edges, &all, at, wanted, &mut b);
        assert_same_spans(&a, &b, at.p);
        assert_eq!(dim_a, dim_b, "left out, point {:?}", at.p);
        let (mut a, mut b): (Vec<Span>, Vec<Span>) = (vec![], vec![]);
        let inf = f64::INFINITY;
        let dim_a = with.walk_wanted(&blocks, at, inf, wanted, None, &mut a);
        let dim_b = without.walk_wanted(&blocks, at, inf, wanted, None, &mut b);
        assert_same_spans(&a, &b, at.p);
        assert_eq!(dim_a, dim_b, "left out by the walk, point {:?}", at.p);
    }
    assert_eq!(without.silhouettes(), 0);
    with.silhouettes()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// [`silhouettes_change_nothing`] on random walls (pillars, bars,
    /// corners of every kind), from every free pixel centre, points off
    /// the centres and a point on every edge.
    #[test]
    fn silhouettes_change_no_span(l in level_strategy(), seed in any::<u64>()) {
        let g = trace(&l);
        let side = l.width.max(l.height);
        let mut points = free_centres_and_edge_points(&g, side);
        points.extend(points.clone().into_iter().filter(|v| v.view == View::Full).map(|v| {
            Viewpoint::new([v.p[0] + 0.31, v.p[1] - 0.17], View::Full, v.comp)
        }));
        silhouettes_change_nothing(&g, &points, &mixed_reaches(g.edges.len(), seed));
    }
}

/// [`silhouettes_change_nothing`] on fields of one-pixel dots, where most
/// pieces a point sees are a dot's two faces: silhouettes are taken there.
#[test]
fn silhouettes_change_no_span_among_dots() {
    for (side, sparse, seed) in [(40, 1, 3u64), (60, 3, 5)] {
        let g = trace(&dot_field(side, sparse, seed));
        let points = free_centres_and_edge_points(&g, side);
        let taken = silhouettes_change_nothing(&g, &points, &mixed_reaches(g.edges.len(), seed));
        assert!(
            taken > 10 * points.len() as u64,
            "dots {side} px: {taken} silhouettes from {} points",
            points.len()
        );
    }
}

/// [`silhouettes_change_nothing`] on fields of rectangles of every shape
/// from 1 x 1 to 4 x 3 (lamps, bars, blocks), with every edge wanted (a
/// field of lamps: the sweep takes their two faces as one and cuts its
/// spans at the corner) and with mixed reaches: silhouettes of sides
/// longer than a pixel are taken there, and they are only rectangles'.
#[test]
fn silhouettes_change_no_span_among_rectangles() {
    let sizes = [(2, 2), (3, 1), (1, 3), (4, 2), (2, 4), (4, 3), (1, 1)];
    let l = walled(44, 44, |x, y| {
        let (cx, cy) = ((x - 2) / 7, (y - 2) / 7);
        let (w, h) = sizes[(cx + 3 * cy) % sizes.len()];
        let (dx, dy) = ((x - 2) % 7, (y - 2) % 7);
        x >= 2 && y >= 2 && x < 42 && y < 42 && dx < w && dy < h
    });
    let g = trace(&l);
    assert!(g.edges.iter().any(|e| e.rectangle && e.len() > 1.0));
    let points = free_centres_and_edge_points(&g, 44);
    for reach2 in [
        vec![f64::INFINITY; g.edges.len()],
        mixed_reaches(g.edges.len(), 7),
    ] {
        let taken = silhouettes_change_nothing(&g, &points, &reach2);
        assert!(
            taken > 4 * points.len() as u64,
            "{taken} silhouettes from {} points",
            points.len()
        );
    }
    // The rectangles are the only loops of four edges: the walls' inner
    // side is one too, but its corners are concave seen from inside.
    for e in &g.edges {
        assert_eq!(e.rectangle, g.loops[e.loop_id as usize].edges.len() == 4);
    }
}

/// Only a corner with an edge at most a pixel long makes a silhouette:
/// behind the outer corner of an L of 6 px arms, a pillar stands in the
/// notch, hidden from the points beyond the corner, and in front of the
/// segment across the arms' far ends. Seen from there, only the pillar
/// has light: the sweep finds none of it, as without silhouettes.
#[test]
fn silhouettes_keep_what_long_arms_hide() {
    let l = walled(16, 16, |x, y| {
        ((3..9).contains(&x) && y == 3) || (x == 3 && (3..9).contains(&y)) || (x, y) == (5, 5)
    });
    let g = trace(&l);
    let pillar = |e: &Edge| {
        [e.a, e.b]
            .iter()
            .all(|v| (5..=6).contains(&v[0]) && (5..=6).contains(&v[1]))
    };
    let reach2: Vec<f64> = g
        .edges
        .iter()
        .map(|e| if pillar(e) { f64::INFINITY } else { -1.0 })
        .collect();
    let points: Vec<Viewpoint> = (1..3)
        .flat_map(|y| (1..3).map(move |x| (x, y)))
        .map(|(x, y)| {
            let comp = g.component_at(x, y).expect("free");
            Viewpoint::new([x as f64 + 0.5, y as f64 + 0.5], View::Full, comp)
        })
        .collect();
    silhouettes_change_nothing(&g, &points, &reach2);
}
