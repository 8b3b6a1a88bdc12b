//! The price of accuracy, pinned: on varied small levels the error against
//! the `reference` preset falls from draft to normal to high, `normal` stays
//! within 2% relative RMS error, `high` within 0.5%, and `reference` itself is
//! converged (refining it changes the result by less than 0.05%).

mod common;
use common::*;

use flatbake_core::accuracy::{REFERENCE_TOLERANCE, compare};
use flatbake_core::bake::{Settings, bake};
use flatbake_core::level::Level;
use flatbake_core::level::material::Material;
use flatbake_core::quality::{Knobs, Quality};

/// A level from a per-pixel rule: `Some(k)` is material `k`, `None` floor.
fn level_from(
    w: usize,
    h: usize,
    mats: &[Material],
    f: impl Fn(usize, usize) -> Option<usize>,
) -> Level {
    const KEYS: &[char] = &['#', 'L', 'R', 'G'];
    let rows: Vec<String> = (0..h)
        .map(|y| (0..w).map(|x| f(x, y).map_or('.', |k| KEYS[k])).collect())
        .collect();
    let legend: Vec<(char, Material)> = mats
        .iter()
        .cloned()
        .enumerate()
        .map(|(i, m)| (KEYS[i], m))
        .collect();
    ascii(&refs(&rows), &legend)
}

/// A closed room of near-mirror walls (r = 0.98) lit by one emitter pixel,
/// with a block casting a shadow.
fn mirror_room() -> Level {
    level_from(40, 30, &[wall(0.98), light(1.0, 0.0)], |x, y| {
        if x == 0 && y == 15 {
            Some(1)
        } else if x == 0
            || y == 0
            || x == 39
            || y == 29
            || ((10..14).contains(&x) && (10..20).contains(&y))
        {
            Some(0)
        } else {
            None
        }
    })
}

/// A maze of one-pixel walls with single-pixel lights set into them, open
/// to the outside at two gaps.
fn maze() -> Level {
    level_from(64, 64, &[wall(0.6), light(6.0, 0.0)], |x, y| {
        let border = x == 0 || y == 0 || x == 63 || y == 63;
        if border {
            return if (x == 0 && y == 31) || (x == 63 && y == 40) {
                None
            } else {
                Some(0)
            };
        }
        if x % 9 == 0 && (y / 9 + x / 9) % 3 != 0 && y % 9 != 4 {
            return Some(if y % 17 == 3 { 1 } else { 0 });
        }
        if y % 9 == 0 && (x / 9 * 7 + y / 9) % 4 != 0 && x % 9 != 5 {
            return Some(0);
        }
        None
    })
}

/// An open field with pillars of several sizes and two small lights; light
/// escapes through the image border.
fn field() -> Level {
    let red = Material {
        reflectance: [0.8, 0.1, 0.1],
        ..wall(0.0)
    };
    level_from(80, 60, &[wall(0.5), light(12.0, 0.0), red], |x, y| {
        if y == 10 && (10..12).contains(&x) || y == 45 && (60..62).contains(&x) {
            return Some(1);
        }
        let pillars = [
            (20, 20, 3, 3, 0),
            (40, 30, 1, 1, 0),
            (50, 12, 6, 2, 2),
            (30, 45, 2, 8, 0),
            (65, 25, 1, 6, 2),
        ];
        pillars
            .iter()
            .find(|&&(a, b, w, h, _)| x >= a && x < a + w && y >= b && y < b + h)
            .map(|p| p.4)
    })
}

/// A hall with lamps in both long walls and columns between them, baked
/// with falloff.
fn falloff_hall() -> Level {
    level_from(96, 32, &[wall(0.7), light(4.0, 0.2)], |x, y| {
        if y == 0 || y == 31 || x == 0 || x == 95 {
            return Some(if (y == 0 || y == 31) && x % 24 == 12 {
                1
            } else {
                0
            });
        }
        if (y == 10 || y == 21) && x % 24 == 0 && x > 0 {
            return Some(0);
        }
        None
    })
}

fn bake_knobs(level: &Level, q: Quality, knobs: Knobs, falloff: Option<f64>) -> Vec<[f32; 3]> {
    let mut s = Settings::new(q);
    s.knobs = knobs;
    s.falloff = falloff;
    bake(level, &s, &|_| {}).expect("bakes").lightmap.rgb
}

fn check_ladder(name: &str, level: &Level, falloff: Option<f64>) {
    let reference = bake_knobs(
        level,
        Quality::Reference,
        Quality::Reference.knobs(),
        falloff,
    );
    let err = |q: Quality| compare(level, &bake_knobs(level, q, q.knobs(), falloff), &reference).0;
    let (d, n, h) = (
        err(Quality::Draft),
        err(Quality::Normal),
        err(Quality::High),
    );
    eprintln!(
        "{name}: draft {:.3}%  normal {:.3}%  high {:.4}%",
        100.0 * d,
        100.0 * n,
        100.0 * h
    );
    assert!(
        n < 0.02,
        "{name}: normal is {:.3}% from reference",
        100.0 * n
    );
    assert!(
        h < 0.005,
        "{name}: high is {:.3}% from reference",
        100.0 * h
    );
    assert!(
        d > n && n > h,
        "{name}: error must fall draft {d:.2e} > normal {n:.2e} > high {h:.2e}"
    );
}

#[test]
fn mirror_room_error_falls_with_quality() {
    check_ladder("mirror room r=0.98", &mirror_room(), None);
}

#[test]
fn one_pixel_maze_error_falls_with_quality() {
    check_ladder("one-pixel maze", &maze(), None);
}

#[test]
fn open_field_error_falls_with_quality() {
    check_ladder("open field", &field(), None);
}

#[test]
fn falloff_hall_error_falls_with_quality() {
    check_ladder("falloff hall", &falloff_hall(), Some(12.0));
}

/// An edge's clearance counts the free pixels in front of it up to a solid
/// pixel, the border or the cap, and takes the lower quartile along the
/// edge; the patches of the normal preset follow it.
#[test]
fn patches_are_no_longer_than_a_multiple_of_their_clearance() {
    use flatbake_core::geometry::{Normal, trace};
    use flatbake_core::transport::Patches;
    use flatbake_core::transport::clearance;
    // A room 16 px wide; the wall across its top has a 2-px pocket above
    // columns 1..5 of the room and is solid above the rest.
    let mut rows = vec!["#".repeat(18); 3];
    rows[1].replace_range(2..6, "....");
    rows[2].replace_range(2..6, "....");
    for _ in 0..12 {
        rows.push(format!("#{}#", ".".repeat(16)));
    }
    rows.push("#".repeat(18));
    let level = ascii(&refs(&rows), &[('#', wall(0.5))]);
    let g = trace(&level);
    let find = |normal: Normal, line: f64, len: f64| find_edge(&g, normal, line, len);
    // The pocket's roof sees down through the pocket and the room (14 px);
    // its left side sees across the pocket (4 px); the room's left wall
    // across the room (16 px); the stub of top wall left of the pocket down
    // the room (12 px).
    let pocket_roof = find(Normal::Down, 1.0, 4.0);
    let pocket_side = find(Normal::Right, 2.0, 2.0);
    let room_left = find(Normal::Right, 1.0, 12.0);
    let top = find(Normal::Down, 3.0, 1.0);
    assert_eq!(clearance(&g, &g.edges[pocket_roof], 99), 14);
    assert_eq!(clearance(&g, &g.edges[pocket_side], 99), 4);
    assert_eq!(clearance(&g, &g.edges[room_left], 99), 16);
    assert_eq!(clearance(&g, &g.edges[room_left], 3), 3, "the cap");
    assert_eq!(clearance(&g, &g.edges[top], 99), 12);
    // Normal: 4 px patches, and no longer than 1.5x the clearance.
    let knobs = Quality::Normal.knobs();
    let k = knobs.per_clearance.expect("normal follows clearance");
    let p = Patches::new_where(&g, 4.0, Some(k), |_| true);
    let longest = |e: usize| p.of_edge(e).map(|q| p.length(q)).fold(0.0, f64::max);
    for (e, c) in [(pocket_roof, 14.0), (pocket_side, 4.0), (room_left, 16.0)] {
        assert!(
            longest(e) <= (4.0f64).min(k * c),
            "edge {e}: {}",
            longest(e)
        );
    }
    let narrow = ascii(&["######", "#....#", "######"], &[('#', wall(0.5))]);
    let g = trace(&narrow);
    let corridor = find_in(&g, Normal::Down, 1.0);
    assert_eq!(clearance(&g, &g.edges[corridor], 99), 1);
    let p = Patches::new_where(&g, 4.0, Some(k), |_| true);
    assert_eq!(p.of_edge(corridor).len(), (4.0 / k).ceil() as usize);
    assert_eq!(Patches::new(&g, 4.0).of_edge(corridor).len(), 1);
}

/// A patch takes a preset's quadrature points spread over its edge's
/// longest patch: a one-pixel face of a pillar in the open takes one
/// point, a wall as long as the patch length every point, and patches that
/// their clearance shortened, or that meet a concave corner, every point.
#[test]
fn patches_take_quadrature_points_by_length() {
    use flatbake_core::geometry::{Normal, trace};
    use flatbake_core::transport::Patches;
    // A room 16 x 12 with a one-pixel pillar in the open, a 5-px block
    // (whose faces meet no concave corner), and an L-shaped notch in the
    // right wall.
    let mut rows = vec!["#".repeat(18)];
    for y in 0..12 {
        let mut r: Vec<char> = format!("#{}#", ".".repeat(16)).chars().collect();
        if y == 3 {
            r[4] = '#';
        }
        if (7..9).contains(&y) {
            for c in &mut r[3..8] {
                *c = '#';
            }
        }
        if y < 2 {
            r[16] = '#';
        }
        rows.push(r.into_iter().collect());
    }
    rows.push("#".repeat(18));
    let level = ascii(&refs(&rows), &[('#', wall(0.5))]);
    let g = trace(&level);
    let find = |normal: Normal, line: f64, len: f64| find_edge(&g, normal, line, len);
    let knobs = Quality::Normal.knobs();
    let (h, q) = (knobs.patch_len, knobs.quad);
    let p = Patches::new_where(&g, h, knobs.per_clearance, |_| true);
    let points = |e: usize| p.of_edge(e).map(|i| p.points(i, q)).collect::<Vec<usize>>();
    // The pillar's four faces, one point each.
    for (n, line) in [
        (Normal::Up, 4.0),
        (Normal::Down, 5.0),
        (Normal::Left, 4.0),
        (Normal::Right, 5.0),
    ] {
        assert_eq!(points(find(n, line, 1.0)), [1], "pillar face {n:?}");
    }
    // The block's top, 5 px: two patches of 2.5 px, two points each (no
    // farther apart than three on a 4 px patch); its 2-px side towards the
    // room, two; its side 2 px from the left wall, whose clearance
    // shortens its patches, every point.
    assert_eq!(points(find(Normal::Up, 8.0, 5.0)), [2, 2]);
    assert_eq!(points(find(Normal::Right, 8.0, 2.0)), [2]);
    assert_eq!(points(find(Normal::Left, 3.0, 2.0)), [q]);
    // The notch's floor meets the right wall in a concave corner: every
    // point, though it is one pixel long and open in front.
    assert_eq!(points(find(Normal::Down, 3.0, 1.0)), [q]);
    // The top wall, 15 px: patches of 3.75 px (and concave corners at both
    // ends): every point.
    assert!(
        points(find(Normal::Down, 1.0, 15.0))
            .iter()
            .all(|&k| k == q)
    );
    // A patch shortened by its clearance (a one-pixel corridor): every point.
    let narrow = ascii(&["######", "#....#", "######"], &[('#', wall(0.5))]);
    let g = trace(&narrow);
    let corridor = find_in(&g, Normal::Down, 1.0);
    let p = Patches::new_where(&g, h, knobs.per_clearance, |_| true);
    assert!(p.of_edge(corridor).all(|i| p.points(i, q) == q));
    // Without the clearance rule, a 4 px corridor wall is one full patch.
    let p = Patches::new(&g, h);
    assert!(p.of_edge(corridor).all(|i| p.points(i, q) == q));
}

/// The edge of `g` with this normal, line and length.
fn find_edge(
    g: &flatbake_core::geometry::Geometry,
    normal: flatbake_core::geometry::Normal,
    line: f64,
    len: f64,
) -> usize {
    g.edges
        .iter()
        .position(|e| e.normal == normal && e.line() == line && e.len() == len)
        .unwrap_or_else(|| panic!("an edge {normal:?} at {line}, {len} long"))
}

fn find_in(
    g: &flatbake_core::geometry::Geometry,
    normal: flatbake_core::geometry::Normal,
    line: f64,
) -> usize {
    g.edges
        .iter()
        .position(|e| e.normal == normal && e.line() == line)
        .expect("the edge")
}

/// Corridors one to three pixels wide in rock, lit from lamps in their
/// walls, with the generator's falloff: light crosses a corridor over a
/// pixel or two, so patches as long as the preset's patch length would
/// average away the light along the walls; patches no longer than a
/// multiple of the corridor's width keep the ladder.
#[test]
fn corridors_error_falls_with_quality() {
    let (level, palette) = flatbake_synth::corridors(128, 7)
        .level()
        .expect("the generator's palette parses");
    check_ladder("corridors", &level, palette.settings.falloff);
}

/// `reference` is converged: halving its patch length (and keeping the
/// largest quadrature) changes the lightmap by less than 0.05%.
#[test]
fn reference_is_converged() {
    for (name, level, falloff) in [
        ("mirror room", mirror_room(), None),
        ("maze", maze(), None),
        ("falloff hall", falloff_hall(), Some(12.0)),
    ] {
        let r = Quality::Reference.knobs();
        let finer = Knobs {
            patch_len: r.patch_len / 2.0,
            ..r
        };
        let a = bake_knobs(&level, Quality::Reference, r, falloff);
        let b = bake_knobs(&level, Quality::Reference, finer, falloff);
        let (change, _) = compare(&level, &a, &b);
        eprintln!(
            "{name}: reference refined changes by {:.4}%",
            100.0 * change
        );
        assert!(
            change < REFERENCE_TOLERANCE,
            "{name}: reference changes by {:.4}% when refined",
            100.0 * change
        );
    }
}
