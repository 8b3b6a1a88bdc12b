//! The classes of level that cost a bake the most, as generators: the
//! yardsticks of the speed targets in docs/performance.md.
//!
//! The 512 px benchmark ([`bench_obstacles`](crate::bench_obstacles)) is one
//! open room with a few hundred edges. Real levels and adversarial ones are
//! different: a shooter map has thousands of edges in many small rooms, a
//! courtyard without falloff lets every pixel see far, and pixel-scale
//! clutter (pillars, noise, checkerboards, dots) multiplies edges and free
//! regions by the hundred thousand. Each generator here stands for one such
//! class, is deterministic (seeded [`Rng`]), takes its size as parameters,
//! and paints pixels plus palette the way the sample generators do (floors
//! kept clear of wall and emitter colours by [`Painted::new`]).
//!
//! [`hard_classes`] lists every class at the size it was first timed at,
//! [`small_classes`] the same scenes small enough for `flatbake sweep`.

use crate::{
    CORRIDOR_FLOOR, Canvas, Floor, Painted, PaletteBuilder, ROOM_FLOORS, Rect, Rng, VOID,
    bench_obstacles, scatter, split_vertically,
};

// ---------------------------------------------------------------------------
// Shared building blocks

/// Rooms, corridors and the walls between them, before painting.
#[derive(Default)]
struct Plan {
    rooms: Vec<Rect>,
    corridors: Vec<Rect>,
    walls: Vec<Rect>,
}

/// Splits the floor rectangle `area` into rooms separated by shared walls
/// 2-4 px thick (binary space partition, leaves at least `min_leaf` wide).
/// With `corridor = Some((p, lo, hi))`, a split of a node at least four
/// leaves long is, with probability `p`, a corridor `lo..=hi` px wide with a
/// wall on each side, running the whole length of the node.
fn partition(
    area: Rect,
    min_leaf: i32,
    corridor: Option<(f64, i32, i32)>,
    rng: &mut Rng,
    plan: &mut Plan,
) {
    let t = *rng.pick(&[2, 3, 3, 4]);
    let can_v = area.w >= 2 * min_leaf + t;
    let can_h = area.h >= 2 * min_leaf + t;
    let small = area.w < 3 * min_leaf && area.h < 3 * min_leaf;
    if !(can_v || can_h) || (small && rng.chance(0.35)) {
        plan.rooms.push(area);
        return;
    }
    let vertical = split_vertically(area, can_v, can_h, rng);
    let len = if vertical { area.w } else { area.h };
    // A stretch `[a, a + n)` across the split axis as a rectangle.
    let band = |a: i32, n: i32| {
        if vertical {
            Rect::new(area.x + a, area.y, n, area.h)
        } else {
            Rect::new(area.x, area.y + a, area.w, n)
        }
    };
    let (first, second) = match corridor {
        Some((p, lo, hi)) if len >= 4 * min_leaf + 2 * t + hi && rng.chance(p) => {
            let cw = rng.range(lo, hi + 1);
            let cut = rng.range(min_leaf, len - min_leaf - 2 * t - cw + 1);
            plan.walls.push(band(cut, t));
            plan.corridors.push(band(cut + t, cw));
            plan.walls.push(band(cut + t + cw, t));
            (band(0, cut), band(cut + 2 * t + cw, len - cut - 2 * t - cw))
        }
        _ => {
            let cut = rng.range(min_leaf, len - min_leaf - t + 1);
            plan.walls.push(band(cut, t));
            (band(0, cut), band(cut + t, len - cut - t))
        }
    };
    partition(first, min_leaf, corridor, rng, plan);
    partition(second, min_leaf, corridor, rng, plan);
}

/// Cuts doorways `lo..=hi` px wide out of the walls around the floor
/// rectangle `r`: each side gets one with probability `p`, and at least one
/// side always does. A doorway goes straight through pixels of colour
/// `wall` to floor beyond (at most 6 px); it is painted with `floor`.
/// Returns the doorways (the carved wall pixels).
fn doors(
    c: &mut Canvas,
    r: Rect,
    wall: [u8; 4],
    floor: Floor,
    p: f64,
    (lo, hi): (i32, i32),
    rng: &mut Rng,
) -> Vec<Rect> {
    // Sides as (outward step, along step, start corner, side length).
    let sides = [
        ((0, -1), (1, 0), (r.x, r.y), r.w),
        ((0, 1), (1, 0), (r.x, r.y1() - 1), r.w),
        ((-1, 0), (0, 1), (r.x, r.y), r.h),
        ((1, 0), (0, 1), (r.x1() - 1, r.y), r.h),
    ];
    let mut order = [0usize, 1, 2, 3];
    for i in (1..4).rev() {
        order.swap(i, rng.below(i as u64 + 1) as usize);
    }
    let mut out = Vec::new();
    for pass in 0..2 {
        for &s in &order {
            if !out.is_empty() && pass == 1 {
                break;
            }
            if pass == 0 && !rng.chance(p) {
                continue;
            }
            let ((ox, oy), (ax, ay), (sx, sy), len) = sides[s];
            let margin = 3;
            let dw = rng.range(lo, hi + 1).min(len - 2 * margin);
            if dw < 1 {
                continue;
            }
            for _ in 0..8 {
                let at = rng.range(margin, len - margin - dw + 1);
                // The wall depth behind every column of the doorway.
                let depth = |k: i32| {
                    let (x, y) = (sx + ax * (at + k), sy + ay * (at + k));
                    for d in 1..=7 {
                        match c.get(x + ox * d, y + oy * d) {
                            Some(px) if px == wall => continue,
                            Some(px) if px[3] != 0 && d > 1 => return Some(d),
                            _ => return None,
                        }
                    }
                    None
                };
                let d0 = depth(0);
                if d0.is_none() || (1..dw).any(|k| depth(k) != d0) {
                    continue;
                }
                let d = d0.expect("checked");
                let seed = c.seed;
                let mut lo_x = i32::MAX;
                let mut lo_y = i32::MAX;
                let mut hi_x = i32::MIN;
                let mut hi_y = i32::MIN;
                for k in 0..dw {
                    for j in 1..d {
                        let (x, y) = (sx + ax * (at + k) + ox * j, sy + ay * (at + k) + oy * j);
                        c.set(x, y, floor.color(x, y, seed));
                        lo_x = lo_x.min(x);
                        lo_y = lo_y.min(y);
                        hi_x = hi_x.max(x);
                        hi_y = hi_y.max(y);
                    }
                }
                out.push(Rect::new(lo_x, lo_y, hi_x - lo_x + 1, hi_y - lo_y + 1));
                break;
            }
        }
    }
    out
}

/// `n` shares of a total spread over `weights` by largest remainder, so the
/// shares sum to `n` exactly.
fn apportion(n: usize, weights: &[i64]) -> Vec<usize> {
    let total: i64 = weights.iter().sum::<i64>().max(1);
    let exact: Vec<f64> = weights
        .iter()
        .map(|&w| n as f64 * w as f64 / total as f64)
        .collect();
    let mut share: Vec<usize> = exact.iter().map(|e| e.floor() as usize).collect();
    let mut rest: Vec<usize> = (0..weights.len()).collect();
    rest.sort_by(|&a, &b| {
        let fa = exact[a] - exact[a].floor();
        let fb = exact[b] - exact[b].floor();
        fb.total_cmp(&fa).then(a.cmp(&b))
    });
    let missing = n - share.iter().sum::<usize>();
    for &i in rest.iter().take(missing) {
        share[i] += 1;
    }
    share
}

/// Marks pixels as taken, for placing thousands of pixel-sized things
/// without the quadratic cost of [`scatter`].
struct Taken {
    w: i32,
    h: i32,
    bits: Vec<bool>,
}

impl Taken {
    fn new(w: i32, h: i32) -> Taken {
        Taken {
            w,
            h,
            bits: vec![false; (w * h) as usize],
        }
    }
    /// True when `r` grown by `gap` is inside the level and free.
    fn free(&self, r: Rect, gap: i32) -> bool {
        let g = r.grow(gap);
        g.x >= 0
            && g.y >= 0
            && g.x1() <= self.w
            && g.y1() <= self.h
            && (g.y..g.y1()).all(|y| (g.x..g.x1()).all(|x| !self.bits[(y * self.w + x) as usize]))
    }
    fn take(&mut self, r: Rect) {
        for y in r.y.max(0)..r.y1().min(self.h) {
            for x in r.x.max(0)..r.x1().min(self.w) {
                self.bits[(y * self.w + x) as usize] = true;
            }
        }
    }
    /// Up to `n` squares of side `side` in `area`, each `gap` px clear of
    /// everything taken before (which they then take).
    fn place(&mut self, area: Rect, n: usize, side: i32, gap: i32, rng: &mut Rng) -> Vec<Rect> {
        let mut out = Vec::new();
        for _ in 0..n * 50 {
            if out.len() >= n || area.w < side || area.h < side {
                break;
            }
            let r = Rect::new(
                rng.range(area.x, area.x1() - side + 1),
                rng.range(area.y, area.y1() - side + 1),
                side,
                side,
            );
            if self.free(r, gap) {
                self.take(r);
                out.push(r);
            }
        }
        out
    }
}

/// The side of a "small light" at this scale: 2 px at 512 and above, 1 px
/// below.
fn light_side(k: f64) -> i32 {
    ((2.0 * k).round() as i32).clamp(1, 2)
}

// ---------------------------------------------------------------------------
// Real maps

/// A top-down shooter map, `w` x `h` px (first timed at 1025 x 838): one
/// building inside a 4 px outer wall, split by shared 2-4 px walls into
/// rooms and long corridors 10-18 px wide (scaled with the map), doorways
/// between neighbours, crates and low cover walls in every room, and small
/// square ceiling lights (2 x 2 px at full size, 1 px below about 600 px;
/// about 70 of them at the full size's aspect, shared out by area). The palette sets falloff 48 at full size (scaled
/// with the map), as a game would. About 4,000 edges at full size.
///
/// Class: the real game level, many rooms and thousands of short edges, the
/// case the 512 px benchmark does not show.
pub fn shooter_map(w: usize, h: usize, seed: u64) -> Painted {
    let (w, h) = (w.max(64) as i32, h.max(64) as i32);
    let k = w.min(h) as f64 / 838.0;
    let sc = |v: f64| ((v * k).round() as i32).max(1);
    let mut rng = Rng::new(seed ^ 0x5400_7e12);
    let mut pal = PaletteBuilder::new(&format!(
        "Shooter map {w}x{h}, seed {seed}: rooms, corridors, doors, crates, ceiling lights."
    ));
    pal.falloff((48.0 * k * 10.0).round() / 10.0);
    let wall = pal.wall("concrete walls", 0x3c3c46, 0.5);
    let crate_c = pal.wall("wooden crates", 0x6e4e2c, [0.5, 0.38, 0.25]);
    let cover = pal.wall("low cover walls", 0x44505e, 0.45);
    let light = pal.emitter("ceiling lights", 0xfff4e0, [16.0, 15.0, 13.0], None);

    let mut c = Canvas::new(w as usize, h as usize, VOID, seed);
    let t = 4;
    let inner = Rect::new(t, t, w - 2 * t, h - 2 * t);
    let mut plan = Plan::default();
    partition(
        inner,
        sc(70.0).max(12),
        Some((0.45, sc(10.0).max(3), sc(18.0).max(4))),
        &mut rng,
        &mut plan,
    );
    let room_floors: Vec<Floor> = plan.rooms.iter().map(|_| *rng.pick(&ROOM_FLOORS)).collect();
    for (r, f) in plan.rooms.iter().zip(&room_floors) {
        c.floor(*r, *f);
    }
    for r in &plan.corridors {
        c.floor(*r, CORRIDOR_FLOOR);
    }
    for r in &plan.walls {
        c.fill_rect(*r, wall);
    }
    c.outline_rect(Rect::new(0, 0, w, h), t, wall);
    let door_w = (sc(8.0).max(2), sc(14.0).max(3));
    let mut open = Vec::new();
    for (r, f) in plan.rooms.iter().zip(&room_floors) {
        open.extend(doors(&mut c, *r, wall, *f, 0.5, door_w, &mut rng));
    }
    for r in &plan.corridors {
        open.extend(doors(
            &mut c,
            *r,
            wall,
            CORRIDOR_FLOOR,
            0.9,
            door_w,
            &mut rng,
        ));
    }
    // Keep doorways passable: nothing stands within a door's width of one.
    let keep: Vec<Rect> = open.iter().map(|d| d.grow(sc(12.0).max(3))).collect();
    let mut stuff: Vec<Rect> = Vec::new();
    for r in &plan.rooms {
        let n = (r.area() as f64 / (1050.0 * k * k)).round() as usize;
        let big = sc(12.0).max(2);
        let placed = scatter(r.grow(-sc(4.0)), n, sc(3.0), &keep, &mut rng, |rng| {
            let u = rng.unit();
            if u < 0.65 {
                let s = rng.range(sc(5.0), big + 1);
                (s, s)
            } else {
                let long = rng.range(sc(10.0), sc(28.0) + 1);
                let thin = sc(2.0);
                if rng.chance(0.5) {
                    (thin, long)
                } else {
                    (long, thin)
                }
            }
        });
        for p in placed {
            let col = if p.w == p.h { crate_c } else { cover };
            c.fill_rect(p, col);
            stuff.push(p.grow(2));
        }
    }
    let areas: Vec<Rect> = plan.rooms.iter().chain(&plan.corridors).copied().collect();
    // 70 lights in a map of the full size's shape, whatever the scale.
    let n_lights = ((70.0 * (w * h) as f64 / (1025.0 * 838.0 * k * k)).round() as usize).max(2);
    let shares = apportion(n_lights, &areas.iter().map(Rect::area).collect::<Vec<_>>());
    let ls = light_side(k * 838.0 / 512.0);
    let avoid: Vec<Rect> = keep.iter().chain(&stuff).copied().collect();
    for (r, n) in areas.iter().zip(shares) {
        for l in scatter(r.grow(-sc(3.0)), n, sc(8.0), &avoid, &mut rng, |_| (ls, ls)) {
            c.fill_rect(l, light);
        }
    }
    Painted::new("shooter_map", c, &pal)
}

/// A map around one huge open courtyard, `w` x `h` px (first timed at
/// about 610 x 641): a ring of buildings (rooms behind shared walls, with
/// doorways to each other and onto the yard) inside a 3 px outer wall, and
/// in the middle a walled courtyard over half the map wide with a round
/// fountain, trees, crates and ruined wall stubs under lamp posts. Rooms are
/// lit by small lights. No falloff: every lamp lights the whole yard, and
/// every yard pixel sees its far side. About 1,900 edges at full size.
///
/// Class: long sight lines over many edges, the case where nothing is far
/// enough away to be skipped.
pub fn courtyard_map(w: usize, h: usize, seed: u64) -> Painted {
    let (w, h) = (w.max(96) as i32, h.max(96) as i32);
    let k = w.min(h) as f64 / 610.0;
    let sc = |v: f64| ((v * k).round() as i32).max(1);
    let mut rng = Rng::new(seed ^ 0xc0_7e7a);
    let mut pal = PaletteBuilder::new(&format!(
        "Courtyard map {w}x{h}, seed {seed}: buildings around one open yard, no falloff."
    ));
    let wall = pal.wall("stone walls", 0x4a4652, 0.5);
    let tree = pal.wall("trees", 0x2e5a2a, [0.2, 0.4, 0.15]);
    let ruin = pal.wall("crates and ruins", 0x6a5038, [0.5, 0.4, 0.3]);
    let basin = pal.wall("fountain basin", 0x7c8088, 0.6);
    let lamp = pal.emitter("lamp posts", 0xe0ecff, [6.0, 6.6, 8.0], None);
    let torch = pal.emitter("room lights", 0xffb060, [8.0, 5.6, 2.8], None);

    let mut c = Canvas::new(w as usize, h as usize, VOID, seed);
    let t = 3;
    let i = Rect::new(t, t, w - 2 * t, h - 2 * t);
    // The yard's wall box B (a ring t wide) and the yard C inside it.
    let b = Rect::new(
        (w as f64 * 0.2).round() as i32,
        (h as f64 * 0.2).round() as i32,
        (w as f64 * 0.6).round() as i32,
        (h as f64 * 0.6).round() as i32,
    );
    let yard = b.grow(-t);
    let yard_floor = Floor::Ground {
        base: 0xb0a886,
        blotch: 6,
    };
    c.floor(yard, yard_floor);
    let bands = [
        Rect::new(i.x, i.y, i.w, b.y - i.y),
        Rect::new(i.x, b.y1(), i.w, i.y1() - b.y1()),
        Rect::new(i.x, b.y + t, b.x - i.x, b.h - 2 * t),
        Rect::new(b.x1(), b.y + t, i.x1() - b.x1(), b.h - 2 * t),
    ];
    let mut plan = Plan::default();
    for band in bands {
        partition(band, sc(48.0).max(10), None, &mut rng, &mut plan);
    }
    let floors: Vec<Floor> = plan.rooms.iter().map(|_| *rng.pick(&ROOM_FLOORS)).collect();
    for (r, f) in plan.rooms.iter().zip(&floors) {
        c.floor(*r, *f);
    }
    for r in &plan.walls {
        c.fill_rect(*r, wall);
    }
    c.fill_rect(Rect::new(i.x, b.y, i.w, t), wall);
    c.fill_rect(Rect::new(i.x, b.y1() - t, i.w, t), wall);
    c.fill_rect(Rect::new(b.x, b.y, t, b.h), wall);
    c.fill_rect(Rect::new(b.x1() - t, b.y, t, b.h), wall);
    c.outline_rect(Rect::new(0, 0, w, h), t, wall);
    let door_w = (sc(6.0).max(2), sc(12.0).max(3));
    let mut open = Vec::new();
    for (r, f) in plan.rooms.iter().zip(&floors) {
        open.extend(doors(&mut c, *r, wall, *f, 0.45, door_w, &mut rng));
    }
    // Archways from the yard into the buildings, a few per side.
    let n_arch = 3;
    for _ in 0..4 * n_arch {
        open.extend(doors(
            &mut c,
            yard,
            wall,
            yard_floor,
            0.0,
            (sc(10.0).max(2), sc(16.0).max(3)),
            &mut rng,
        ));
    }
    let keep_doors: Vec<Rect> = open.iter().map(|d| d.grow(sc(8.0).max(2))).collect();

    // Room lights: one or two small lights per room, away from the doors.
    let ls = light_side(k * 610.0 / 512.0);
    for r in &plan.rooms {
        let n = 1 + (r.area() > (3000.0 * k * k) as i64) as usize;
        for l in scatter(r.grow(-sc(4.0)), n, sc(10.0), &keep_doors, &mut rng, |_| {
            (ls, ls)
        }) {
            c.fill_rect(l, torch);
        }
    }

    // The yard: a fountain in the middle, lamp posts on a ring around it,
    // then trees, crates and ruined stubs wherever there is room.
    let (cx, cy) = yard.center();
    let (cx, cy) = (cx as f64, cy as f64);
    let fr = 16.0 * k;
    c.ring((cx, cy), fr - 3.0 * k.max(0.34), fr, basin);
    let mut occupied: Vec<Rect> = keep_doors.clone();
    occupied.push(Rect::new(
        (cx - fr) as i32 - 4,
        (cy - fr) as i32 - 4,
        (2.0 * fr) as i32 + 9,
        (2.0 * fr) as i32 + 9,
    ));
    let lamps: Vec<Rect> = (0..8)
        .map(|q| {
            let a = q as f64 * std::f64::consts::TAU / 8.0 + 0.3;
            let rx = yard.w as f64 * 0.33;
            let ry = yard.h as f64 * 0.33;
            Rect::new(
                (cx + rx * a.cos()) as i32,
                (cy + ry * a.sin()) as i32,
                ls,
                ls,
            )
        })
        .collect();
    for l in &lamps {
        c.fill_rect(*l, lamp);
        occupied.push(l.grow(sc(6.0).max(2)));
    }
    let trees = scatter(
        yard.grow(-sc(8.0)),
        (22.0 * k * k).round() as usize,
        sc(6.0),
        &occupied,
        &mut rng,
        |rng| {
            let d = rng.range(sc(5.0), sc(10.0) + 1);
            (d, d)
        },
    );
    for r in &trees {
        let (x, y) = (r.x as f64 + r.w as f64 / 2.0, r.y as f64 + r.h as f64 / 2.0);
        c.disc((x, y), r.w as f64 / 2.0, tree);
    }
    occupied.extend(trees.iter().map(|r| r.grow(1)));
    let clutter = scatter(
        yard.grow(-sc(6.0)),
        (110.0 * k * k).round() as usize,
        sc(4.0),
        &occupied,
        &mut rng,
        |rng| {
            if rng.chance(0.6) {
                let s = rng.range(sc(3.0), sc(9.0) + 1);
                (s, s)
            } else if rng.chance(0.5) {
                (sc(2.0), rng.range(sc(8.0), sc(24.0) + 1))
            } else {
                (rng.range(sc(8.0), sc(24.0) + 1), sc(2.0))
            }
        },
    );
    for r in clutter {
        c.fill_rect(r, ruin);
    }
    Painted::new("courtyard_map", c, &pal)
}

// ---------------------------------------------------------------------------
// Pixel-scale clutter

/// The enclosing wall of the clutter classes: `max(2, size / 256)` px.
fn enclosed_field(
    pal: &mut PaletteBuilder,
    size: i32,
    seed: u64,
    floor: Floor,
) -> (Canvas, [u8; 4], i32) {
    let wall = pal.wall("enclosing wall", 0x50505a, 0.6);
    let mut c = Canvas::new(size as usize, size as usize, VOID, seed);
    c.floor(Rect::new(0, 0, size, size), floor);
    let t = (size / 256).max(2);
    c.outline_rect(Rect::new(0, 0, size, size), t, wall);
    (c, wall, t)
}

/// A field of `pillars` one-pixel pillars, `size` x `size` px inside an
/// enclosing wall, lit by `lights` small square lights (2 x 2 px at 512).
/// No two pillars touch, even at a corner, so each is its own loop of four
/// unit edges. The palette sets the benchmark's falloff, `size / 12`. First
/// timed at 512 px with 5,000 pillars and 12 lights (about 20,000
/// edges).
///
/// Class: the benchmark scene with its obstacles shattered into thousands of
/// tiny occluders (foliage, rubble, columns painted pixel by pixel).
pub fn pillar_field(size: usize, pillars: usize, lights: usize, seed: u64) -> Painted {
    let s = size.max(16) as i32;
    let k = s as f64 / 512.0;
    let mut rng = Rng::new(seed ^ 0x9111a5);
    let mut pal = PaletteBuilder::new(&format!(
        "Pillar field {s}x{s}: {pillars} one-pixel pillars, {lights} lights, seed {seed}."
    ));
    pal.falloff(s as f64 / 12.0);
    let floor = Floor::Flagstones {
        base: 0xa8a498,
        tile: ((16.0 * k).round() as i32).max(3),
    };
    let (mut c, _, t) = enclosed_field(&mut pal, s, seed, floor);
    let pillar = pal.wall("one-pixel pillars", 0x5c5868, 0.55);
    let light = pal.emitter("lights", 0xfff0d0, [12.0, 11.0, 9.0], None);
    let mut taken = Taken::new(s, s);
    taken.take(Rect::new(0, 0, s, t + 1));
    taken.take(Rect::new(0, s - t - 1, s, t + 1));
    taken.take(Rect::new(0, 0, t + 1, s));
    taken.take(Rect::new(s - t - 1, 0, t + 1, s));
    let ls = light_side(k);
    let inner = Rect::new(t + 2, t + 2, s - 2 * t - 4, s - 2 * t - 4);
    let lit = taken.place(inner, lights, ls, ((16.0 * k) as i32).max(2), &mut rng);
    // Lights keep 2 px of clear floor around them.
    for l in &lit {
        c.fill_rect(*l, light);
        taken.take(l.grow(1));
    }
    for p in taken.place(inner, pillars, 1, 1, &mut rng) {
        c.fill_rect(p, pillar);
    }
    Painted::new(&format!("pillar_field_{s}_{pillars}"), c, &pal)
}

/// An open field, `size` x `size` px inside an enclosing wall, with
/// nothing in it but `lights` small square lights (2 x 2 px at 512) at least
/// 8 px apart, and the palette falloff `falloff` px. First timed at 512
/// px, 200 lights, falloff 43.
///
/// Class: many lights and few edges, where the cost is the light sources
/// themselves (each pixel sees every light within reach).
pub fn light_field(size: usize, lights: usize, falloff: f64, seed: u64) -> Painted {
    let s = size.max(16) as i32;
    let k = s as f64 / 512.0;
    let mut rng = Rng::new(seed ^ 0x119_47f1);
    let mut pal = PaletteBuilder::new(&format!(
        "Light field {s}x{s}: {lights} small lights, falloff {falloff}, seed {seed}."
    ));
    pal.falloff(falloff);
    let floor = Floor::Flagstones {
        base: 0xa6a29a,
        tile: ((16.0 * k).round() as i32).max(3),
    };
    let (mut c, _, t) = enclosed_field(&mut pal, s, seed, floor);
    let light = pal.emitter("small lights", 0xfff0d0, [6.0, 5.6, 4.6], None);
    let mut taken = Taken::new(s, s);
    let ls = light_side(k);
    let inner = Rect::new(t + 3, t + 3, s - 2 * t - 6, s - 2 * t - 6);
    for l in taken.place(inner, lights, ls, ((8.0 * k) as i32).max(2), &mut rng) {
        c.fill_rect(l, light);
    }
    Painted::new(&format!("light_field_{s}_{lights}"), c, &pal)
}

/// A checkerboard of one-pixel walls, `size` x `size` px: pixel `(x, y)` is
/// wall when `x + y` is even, so every floor pixel touches floor only at its
/// corners and is a free region of its own (docs/transport.md#corners),
/// walled in by four unit edges. `lit_rooms` square rooms (`max(8, size /
/// 32)` px) are cleared in it, each with a small light (2 x 2 px at 512) in
/// the middle; the checkerboard pixels around a room catch its light. The
/// palette sets the benchmark's falloff, `size / 12`. About `2 size^2`
/// edges. First timed at 512 px with 0 or a few rooms, and 2048 px with
/// 16.
///
/// Class: the most edges and free regions per pixel a level can have, nearly
/// all of them dark.
pub fn checkerboard(size: usize, lit_rooms: usize, seed: u64) -> Painted {
    let s = size.max(16) as i32;
    let k = s as f64 / 512.0;
    let mut rng = Rng::new(seed ^ 0xc4ec_4e25);
    let mut pal = PaletteBuilder::new(&format!(
        "Checkerboard {s}x{s} of one-pixel walls, {lit_rooms} lit rooms, seed {seed}."
    ));
    pal.falloff(s as f64 / 12.0);
    let wall = pal.wall("one-pixel walls", 0x505060, 0.6);
    let light = pal.emitter("room lights", 0xfff0d0, [12.0, 11.0, 9.0], None);
    let mut c = Canvas::new(s as usize, s as usize, VOID, seed);
    c.floor(Rect::new(0, 0, s, s), Floor::Plain { base: 0xa8a498 });
    for y in 0..s {
        for x in (y & 1..s).step_by(2) {
            c.set(x, y, wall);
        }
    }
    let side = (s / 32).max(8);
    let rooms = scatter(
        Rect::new(2, 2, s - 4, s - 4),
        lit_rooms,
        4,
        &[],
        &mut rng,
        |_| (side, side),
    );
    let ls = light_side(k);
    for r in rooms {
        c.floor(r, Floor::Plain { base: 0xb4ae9e });
        let (x, y) = r.center();
        c.fill_rect(Rect::new(x - ls / 2, y - ls / 2, ls, ls), light);
    }
    Painted::new(&format!("checkerboard_{s}_{lit_rooms}"), c, &pal)
}

/// Random one-pixel wall noise, `size` x `size` px inside an enclosing
/// wall: each pixel is wall with probability `density` (0.1 to 0.3 in the
/// timed classes), and `lights` small lights (2 x 2 px at 512) sit in cleared spots
/// (a pixel of floor around each). The palette sets the benchmark's
/// falloff, `size / 12`.
///
/// Class: unstructured pixel clutter (noise brushes, eroded terrain): many
/// short edges, short and ragged sight lines.
pub fn noise(size: usize, density: f64, lights: usize, seed: u64) -> Painted {
    let s = size.max(16) as i32;
    let k = s as f64 / 512.0;
    let mut rng = Rng::new(seed ^ 0x4015e);
    let pct = (density * 100.0).round() as i32;
    let mut pal = PaletteBuilder::new(&format!(
        "Wall noise {s}x{s}, density {density}, {lights} lights, seed {seed}."
    ));
    pal.falloff(s as f64 / 12.0);
    let floor = Floor::Ground {
        base: 0xaaa888,
        blotch: 5,
    };
    let (mut c, _, t) = enclosed_field(&mut pal, s, seed, floor);
    let speck = pal.wall("wall noise", 0x5a5048, 0.5);
    let light = pal.emitter("lights", 0xfff0d0, [12.0, 11.0, 9.0], None);
    let ls = light_side(k);
    let inner = Rect::new(t + 2, t + 2, s - 2 * t - 4, s - 2 * t - 4);
    let lit = Taken::new(s, s).place(inner, lights, ls, ((16.0 * k) as i32).max(2), &mut rng);
    let clear: Vec<Rect> = lit.iter().map(|l| l.grow(1)).collect();
    for y in t..s - t {
        for x in t..s - t {
            if rng.chance(density) && !clear.iter().any(|r| r.contains(x, y)) {
                c.set(x, y, speck);
            }
        }
    }
    for l in lit {
        c.fill_rect(l, light);
    }
    Painted::new(&format!("noise_{s}_{pct}"), c, &pal)
}

/// A network of long straight corridors 1-3 px wide cut into solid rock,
/// `size` x `size` px: each corridor starts on an earlier one and runs a
/// quarter to three quarters of the level across it, so they cross and
/// branch like a maze of long halls; lights (one pixel, about `size / 16`
/// of them) are set into the corridor walls. The palette sets the
/// benchmark's falloff, `size / 12`.
///
/// Class: long thin free regions, where every pixel sees far along its
/// corridor but almost nothing across it.
pub fn corridors(size: usize, seed: u64) -> Painted {
    let s = size.max(32) as i32;
    let k = s as f64 / 512.0;
    let mut rng = Rng::new(seed ^ 0xc0_441d);
    let mut pal = PaletteBuilder::new(&format!(
        "Corridors {s}x{s}: long 1-3 px corridors in rock, seed {seed}."
    ));
    pal.falloff(s as f64 / 12.0);
    let rock = pal.wall("rock", 0x46424c, 0.5);
    let light = pal.emitter("wall lights", 0xffe0a0, [12.0, 10.2, 7.2], None);
    let mut c = Canvas::new(s as usize, s as usize, rock, seed);
    let seed_f = c.seed;
    // Corridors as (horizontal, fixed coordinate, from, to, width).
    let mut segs: Vec<(bool, i32, i32, i32, i32)> = vec![(true, s / 2, 2, s - 2, 2)];
    let n = (70.0 * k).round() as usize;
    for _ in 0..n * 10 {
        if segs.len() >= n {
            break;
        }
        let &(hz, fixed, a, b, _) = rng.pick(&segs);
        let at = rng.range(a, b);
        let width = *rng.pick(&[1, 1, 2, 2, 3]);
        let len = rng.range(s / 4, 3 * s / 4 + 1);
        let dir = if rng.chance(0.5) { 1 } else { -1 };
        let (from, to) = if dir > 0 {
            (fixed, (fixed + len).min(s - 2))
        } else {
            ((fixed - len).max(2), fixed + 1)
        };
        // Perpendicular to its parent, starting on it.
        if to - from < s / 8 || at < 2 || at + width > s - 2 {
            continue;
        }
        // Keep parallel corridors at least 4 px apart.
        if segs.iter().any(|&(h2, f2, a2, b2, w2)| {
            h2 != hz && (f2 - at).abs() < 4 + w2.max(width) && a2 < to && from < b2
        }) {
            continue;
        }
        segs.push((!hz, at, from, to, width));
    }
    let floor = Floor::Flagstones {
        base: 0x9a9286,
        tile: 5,
    };
    for &(hz, fixed, a, b, width) in &segs {
        let r = if hz {
            Rect::new(a, fixed, b - a, width)
        } else {
            Rect::new(fixed, a, width, b - a)
        };
        c.fill_rect_with(r, |x, y| floor.color(x, y, seed_f));
    }
    // Lights: rock pixels beside a corridor whose other neighbours are rock.
    let is_rock = |c: &Canvas, x: i32, y: i32| c.get(x, y).is_none_or(|p| p == rock);
    let mut cands = Vec::new();
    for y in 1..s - 1 {
        for x in 1..s - 1 {
            if !is_rock(&c, x, y) {
                continue;
            }
            let open = [(1, 0), (-1, 0), (0, 1), (0, -1)]
                .iter()
                .filter(|(dx, dy)| !is_rock(&c, x + dx, y + dy))
                .count();
            if open == 1 {
                cands.push((x, y));
            }
        }
    }
    let want = ((s / 16) as usize).max(2);
    let mut placed: Vec<(i32, i32)> = Vec::new();
    for _ in 0..want * 40 {
        if placed.len() >= want || cands.is_empty() {
            break;
        }
        let &(x, y) = rng.pick(&cands);
        if placed
            .iter()
            .all(|&(a, b)| (a - x).abs() + (b - y).abs() >= 16)
        {
            placed.push((x, y));
        }
    }
    for (x, y) in placed {
        c.set(x, y, light);
    }
    Painted::new(&format!("corridors_{s}"), c, &pal)
}

/// Isolated one-pixel dots, `size` x `size` px with no enclosing wall: a
/// wall dot at every pixel whose `x` and `y` are both odd (about `size^2 /
/// 4` dots, four unit edges each: about 400,000 edges at 640 px), a few of
/// them lights instead (`max(2, size^2 / 51200)`, 8 at 640). Every floor
/// pixel is connected; light escapes off the image. The palette sets the
/// benchmark's falloff, `size / 12`.
///
/// Class: the most separate loops per pixel, each a tiny occluder, with
/// short sight lines in every direction.
pub fn dots(size: usize, seed: u64) -> Painted {
    let s = size.max(8) as i32;
    let mut rng = Rng::new(seed ^ 0xd075);
    let mut pal = PaletteBuilder::new(&format!(
        "Dots {s}x{s}: a one-pixel dot at every odd/odd pixel, seed {seed}."
    ));
    pal.falloff(s as f64 / 12.0);
    let dot = pal.wall("dots", 0x505060, 0.6);
    let light = pal.emitter("light dots", 0xfff0d0, [12.0, 11.0, 9.0], None);
    let mut c = Canvas::new(s as usize, s as usize, VOID, seed);
    c.floor(Rect::new(0, 0, s, s), Floor::Plain { base: 0xa8a498 });
    for y in (1..s).step_by(2) {
        for x in (1..s).step_by(2) {
            c.set(x, y, dot);
        }
    }
    let n = ((s as i64 * s as i64 / 51200) as usize).max(2);
    let half = s / 2;
    let mut placed: Vec<(i32, i32)> = Vec::new();
    for _ in 0..n * 40 {
        if placed.len() >= n {
            break;
        }
        let (x, y) = (
            2 * rng.range(1, half - 1) + 1,
            2 * rng.range(1, half - 1) + 1,
        );
        if placed
            .iter()
            .all(|&(a, b)| (a - x).abs().max((b - y).abs()) >= 8)
        {
            placed.push((x, y));
        }
    }
    for (x, y) in placed {
        c.set(x, y, light);
    }
    Painted::new(&format!("dots_{s}"), c, &pal)
}

// ---------------------------------------------------------------------------
// The sets the tools use

/// One level class: a short label, whether it stands for a real map (the
/// tools also time those at `draft`), and the level.
#[derive(Clone, Debug)]
pub struct Class {
    /// What the class is, for tables ("shooter map", "dots").
    pub label: String,
    /// A real map (rather than an adversarial pattern).
    pub real_map: bool,
    /// The level.
    pub level: Painted,
}

fn class(label: &str, real_map: bool, level: Painted) -> Class {
    Class {
        label: label.to_string(),
        real_map,
        level,
    }
}

/// Every class at the size it was first timed at, cheapest first within
/// each kind; the last is the 8192 px benchmark (the pixel limit).
pub fn hard_classes() -> Vec<Class> {
    vec![
        class("shooter map", true, shooter_map(1025, 838, 1)),
        class("courtyard map", true, courtyard_map(610, 641, 1)),
        class("pillar field", false, pillar_field(512, 5000, 12, 1)),
        class("light field", false, light_field(512, 200, 43.0, 1)),
        class("checkerboard", false, checkerboard(512, 0, 1)),
        class("checkerboard, 4 rooms", false, checkerboard(512, 4, 1)),
        class("noise 0.1", false, noise(512, 0.1, 12, 1)),
        class("noise 0.3", false, noise(512, 0.3, 12, 1)),
        class("corridors", false, corridors(1024, 1)),
        class("dots", false, dots(640, 1)),
        class("checkerboard, 16 rooms", false, checkerboard(2048, 16, 1)),
        class("benchmark 8192", false, bench_obstacles(8192, 60, 12, 7)),
    ]
}

/// The same classes small enough to sweep against `reference`: every level
/// about `size` px on its long side (the real maps keep their aspect), with
/// counts scaled to keep the density of the full-size scene.
pub fn small_classes(size: usize) -> Vec<Class> {
    let s = size.max(32);
    let area = (s * s) as f64 / (512.0 * 512.0);
    vec![
        class("shooter map", true, shooter_map(s, s * 838 / 1025, 1)),
        class("courtyard map", true, courtyard_map(s * 610 / 641, s, 1)),
        class(
            "pillar field",
            false,
            pillar_field(s, (5000.0 * area).round() as usize, 12, 1),
        ),
        class(
            "light field",
            false,
            light_field(
                s,
                ((200.0 * area).round() as usize).max(2),
                43.0 * s as f64 / 512.0,
                1,
            ),
        ),
        class("checkerboard, 2 rooms", false, checkerboard(s, 2, 1)),
        class("noise 0.1", false, noise(s, 0.1, 6, 1)),
        class("noise 0.3", false, noise(s, 0.3, 6, 1)),
        class("corridors", false, corridors(s, 1)),
        class("dots", false, dots(s, 1)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use flatbake_core::geometry::trace;

    /// True when pixel `(x, y)` of `p` is painted `c`.
    fn is(p: &Painted, x: i32, y: i32, c: [u8; 4]) -> bool {
        x >= 0
            && y >= 0
            && (x as usize) < p.width
            && (y as usize) < p.height
            && p.rgba[y as usize * p.width + x as usize] == c
    }

    fn small() -> Vec<Painted> {
        vec![
            shooter_map(300, 245, 3),
            courtyard_map(180, 190, 3),
            pillar_field(96, 150, 3, 3),
            light_field(96, 10, 12.0, 3),
            checkerboard(64, 2, 3),
            noise(64, 0.2, 3, 3),
            corridors(96, 3),
            dots(40, 3),
        ]
    }

    #[test]
    fn classes_are_deterministic_and_seeded() {
        for (a, b) in small().into_iter().zip(small()) {
            assert_eq!(a, b, "{} differs between two runs", a.name);
        }
        assert_ne!(shooter_map(300, 245, 1).rgba, shooter_map(300, 245, 2).rgba);
        assert_ne!(noise(64, 0.2, 3, 1).rgba, noise(64, 0.2, 3, 2).rgba);
        assert_ne!(corridors(96, 1).rgba, corridors(96, 2).rgba);
    }

    #[test]
    fn classes_load_without_warnings_and_have_light() {
        for p in small() {
            let (level, _) = p.level().unwrap_or_else(|e| panic!("{}: {e}", p.name));
            assert_eq!((level.width, level.height), (p.width, p.height));
            assert!(
                level.warnings.is_empty(),
                "{}: {:?}",
                p.name,
                level.warnings
            );
            assert!(
                level.materials.iter().any(|m| m.emits()),
                "{}: no light",
                p.name
            );
        }
    }

    #[test]
    fn checkerboard_floor_cells_are_isolated() {
        let p = checkerboard(48, 0, 1);
        let wall = crate::rgb(0x505060);
        for y in 0..48 {
            for x in 0..48 {
                let floor = (x + y) % 2 == 1;
                assert_eq!(!is(&p, x, y, wall), floor, "({x}, {y})");
                if floor {
                    for (dx, dy) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                        let (nx, ny) = (x + dx, y + dy);
                        let outside = nx < 0 || ny < 0 || nx >= 48 || ny >= 48;
                        assert!(outside || is(&p, nx, ny, wall), "({x}, {y})");
                    }
                }
            }
        }
        // Every wall pixel's sides are separate unit edges (none merge),
        // except those facing out of the image.
        let (level, _) = p.level().expect("level");
        let g = trace(&level);
        assert!(g.edges.iter().all(|e| e.len() == 1.0));
        assert_eq!(g.component_count, 48 * 48 / 2);
    }

    #[test]
    fn dots_are_every_odd_odd_pixel() {
        let p = dots(40, 1);
        let dot = crate::rgb(0x505060);
        let light = crate::rgb(0xfff0d0);
        let mut n = 0;
        for y in 0..40 {
            for x in 0..40 {
                let odd = x % 2 == 1 && y % 2 == 1;
                let solid = is(&p, x, y, dot) || is(&p, x, y, light);
                assert_eq!(solid, odd, "({x}, {y})");
                n += solid as usize;
            }
        }
        assert_eq!(n, 20 * 20);
        assert_eq!(p.rgba.iter().filter(|&&c| c == light).count(), 2);
        let (level, _) = p.level().expect("level");
        let g = trace(&level);
        assert_eq!(g.component_count, 1, "the floor is one region");
        // Four unit edges per dot, but the last row and column of dots sit on
        // the image border, where the sides facing out are not edges.
        assert_eq!(g.edges.len(), 4 * 400 - 2 * 20);
    }

    #[test]
    fn pillars_and_lights_are_as_many_as_asked() {
        let p = pillar_field(128, 300, 4, 1);
        let pillar = crate::rgb(0x5c5868);
        assert_eq!(p.rgba.iter().filter(|&&c| c == pillar).count(), 300);
        let (level, _) = p.level().expect("level");
        // 300 pillars of 4 edges and 4 lights of 4, plus the wall's inside.
        assert_eq!(trace(&level).edges.len(), 300 * 4 + 4 * 4 + 4);
        let l = light_field(128, 20, 11.0, 1);
        let lit = l
            .rgba
            .iter()
            .filter(|&&c| c == crate::rgb(0xfff0d0))
            .count();
        assert_eq!(lit, 20);
    }

    #[test]
    fn corridors_are_thin_and_lit() {
        let p = corridors(128, 1);
        let rock = crate::rgb(0x46424c);
        let free = p.rgba.iter().filter(|&&c| c != rock).count();
        assert!(free > 128 * 6 && free < 128 * 128 / 3, "{free}");
        let (level, _) = p.level().expect("level");
        let g = trace(&level);
        assert!(g.edges.len() > 40, "{}", g.edges.len());
    }

    #[test]
    fn rooms_have_doors() {
        // One free region: every room is reachable through some doorway.
        for p in [shooter_map(300, 245, 1), courtyard_map(180, 190, 1)] {
            let (level, _) = p.level().expect("level");
            let g = trace(&level);
            let big = {
                let mut n = vec![0usize; g.component_count as usize];
                for &c in &g.components {
                    if c != u32::MAX {
                        n[c as usize] += 1;
                    }
                }
                *n.iter().max().expect("regions")
            };
            let floor = level.cells.iter().filter(|c| c.is_free()).count();
            assert!(
                big as f64 > 0.8 * floor as f64,
                "{}: the largest region holds {big} of {floor} free pixels",
                p.name
            );
        }
    }
}
