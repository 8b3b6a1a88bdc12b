//! Hard cases (the tables of docs/robustness.md): reflectance near and at 1, geometry extremes,
//! extreme values, the paper's kernel, determinism, and random levels.
//!
//! Every bake here goes through [`checked`], which asserts what must hold for
//! any level: light is finite and non-negative (and the baker did not have to
//! clamp it), and emitted = absorbed + escaped within the solver tolerance.
//! Where a closed form exists the test compares against it.

mod common;
use common::*;

use std::f64::consts::{PI, TAU};

use flatbake_core::bake::{BakeError, Baked, Settings, bake};
use flatbake_core::gather::Kernel;
use flatbake_core::geometry::trace;
use flatbake_core::level::{Cell, Level};
use flatbake_core::quality::Quality;
use flatbake_core::transport::kernel::Reach;
use flatbake_core::transport::solve::{SolveError, SolveSettings, solve_channel};
use flatbake_core::transport::{Patches, form_factors};
use flatbake_core::visibility::Structures;
use proptest::prelude::*;

fn quiet(_: &str) {}

fn settings(q: Quality) -> Settings {
    Settings::new(q)
}

/// Relative energy mismatch `|emitted - absorbed - escaped| / emitted`.
fn energy_gap(b: &Baked) -> f64 {
    let e = &b.report.energy;
    let gap = (e.emitted - e.absorbed - e.escaped).abs();
    if e.emitted == 0.0 {
        gap
    } else {
        gap / e.emitted
    }
}

/// The properties every baked level must have.
#[track_caller]
fn check(level: &Level, baked: &Baked, energy_tol: f64) {
    assert_eq!(baked.lightmap.rgb.len(), level.width * level.height);
    for (i, px) in baked.lightmap.rgb.iter().enumerate() {
        for v in px {
            assert!(
                v.is_finite() && *v >= 0.0,
                "pixel ({}, {}) holds {v}",
                i % level.width,
                i / level.width
            );
        }
    }
    for c in 0..3 {
        for (p, b) in baked.radiosity[c].iter().enumerate() {
            assert!(b.is_finite() && *b >= 0.0, "patch {p} channel {c}: {b}");
        }
    }
    assert!(
        !baked.report.warnings.iter().any(|w| w.contains("clamped")),
        "the baker had to clamp bad light: {:?}",
        baked.report.warnings
    );
    let e = &baked.report.energy;
    for v in [e.emitted, e.absorbed, e.escaped] {
        assert!(v.is_finite() && v >= -1e-9 * e.emitted.max(1.0), "{e:?}");
    }
    assert!(
        energy_gap(baked) <= energy_tol,
        "energy does not balance: {e:?} (gap {:e})",
        energy_gap(baked)
    );
    assert!(baked.report.residual.is_finite());
}

/// Bakes and checks at `q`; energy must balance to `tol`.
#[track_caller]
fn bake_checked(level: &Level, s: &Settings, tol: f64) -> Baked {
    let baked = bake(level, s, &quiet).unwrap_or_else(|e| panic!("bake failed: {e}"));
    check(level, &baked, tol);
    baked
}

fn floor_values(level: &Level, b: &Baked) -> Vec<(usize, usize, f64)> {
    let mut out = Vec::new();
    for y in 0..level.height {
        for x in 0..level.width {
            if level.cell(x, y) == Cell::Floor {
                out.push((x, y, b.lightmap.rgb[y * level.width + x][0] as f64));
            }
        }
    }
    out
}

/// A room `w x h` whose border is `#`, with the `L` pixels given.
fn room_with(w: usize, h: usize, lights: &[(usize, usize)]) -> Vec<String> {
    let mut rows = room(w, h);
    for &(x, y) in lights {
        rows[y].replace_range(x..x + 1, "L");
    }
    rows
}

// ---------------------------------------------------------------------------
// Reflectance near and at 1

/// A closed room of walls of reflectance r lit by one emitter pixel: nothing
/// escapes, so everything emitted is absorbed; r = 0.98 and 0.999 amplify
/// the light many times and must still balance, and more reflective walls
/// make a brighter room.
#[test]
fn closed_room_near_mirror_walls_absorb_everything_emitted() {
    for q in [Quality::Draft, Quality::Normal, Quality::High] {
        let mut means = Vec::new();
        for r in [0.5, 0.98, 0.999] {
            let rows = room_with(17, 11, &[(8, 0)]);
            let lvl = ascii(&refs(&rows), &[('#', wall(r)), ('L', light(1.0, 0.0))]);
            let b = bake_checked(&lvl, &settings(q), 1e-6);
            let e = &b.report.energy;
            assert!(e.emitted > 0.0);
            assert!(
                e.escaped.abs() <= 1e-9 * e.emitted,
                "{q} r={r}: a closed room lets {e:?} escape"
            );
            let v = floor_values(&lvl, &b);
            means.push(v.iter().map(|v| v.2).sum::<f64>() / v.len() as f64);
        }
        assert!(
            means.windows(2).all(|m| m[1] > m[0]),
            "{q}: mean floor light {means:?} does not grow with reflectance"
        );
    }
}

/// r = 0.999 everywhere including the emitter: B = e / (1 - r) = 1000 e.
#[test]
fn closed_room_r_0999_everywhere_is_a_thousand_times_e() {
    let rows = room(9, 7);
    let lvl = ascii(&refs(&rows), &[('#', light(0.25, 0.999))]);
    let b = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
    let want = 0.25 / (1.0 - 0.999);
    for (x, y, v) in floor_values(&lvl, &b) {
        assert!((v / want - 1.0).abs() < 1e-4, "({x},{y}): {v} vs {want}");
    }
}

/// r = 1 and emission inside a closed region has no finite answer: the bake
/// fails and the message names the region's pixel bounds and the channel.
#[test]
fn closed_room_r_1_with_emission_is_an_error_naming_the_region() {
    let (w, h) = (11, 7);
    let rows = room_with(w, h, &[(5, 0)]);
    let lvl = ascii(&refs(&rows), &[('#', wall(1.0)), ('L', light(1.0, 1.0))]);
    let err = match bake(&lvl, &settings(Quality::Normal), &quiet) {
        Ok(b) => panic!("expected an error, got radiosity {:?}", b.radiosity[0]),
        Err(e) => e,
    };
    assert!(matches!(err, BakeError::Unbounded { .. }), "{err:?}");
    let msg = err.to_string();
    // The free interior spans corners (1,1)-(w-1,h-1).
    let region = format!("(1,1)-({},{})", w - 1, h - 1);
    for words in [
        region.as_str(),
        "closed region",
        "reflectance 1",
        "red channel",
        "no finite value",
    ] {
        assert!(msg.contains(words), "{msg:?} lacks {words:?}");
    }
}

/// Only the channel whose emission is trapped is named.
#[test]
fn closed_room_r_1_names_the_channel_that_emits() {
    let rows = room_with(7, 6, &[(3, 0)]);
    let mut l = light(0.0, 1.0);
    l.emission = [0.0, 0.0, 2.0];
    let lvl = ascii(&refs(&rows), &[('#', wall(1.0)), ('L', l)]);
    let msg = bake(&lvl, &settings(Quality::Draft), &quiet)
        .err()
        .expect("unbounded")
        .to_string();
    assert!(msg.contains("blue channel"), "{msg}");
}

/// Mirror walls but an emitter that absorbs (r = 0): finite; the emitter
/// absorbs everything it emits, nothing escapes.
#[test]
fn closed_mirror_room_with_absorbing_emitter_is_finite() {
    let rows = room_with(11, 7, &[(5, 0)]);
    let lvl = ascii(&refs(&rows), &[('#', wall(1.0)), ('L', light(1.0, 0.0))]);
    let b = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
    let e = &b.report.energy;
    assert!(e.escaped.abs() <= 1e-9 * e.emitted, "{e:?}");
    assert!((e.absorbed / e.emitted - 1.0).abs() < 1e-6, "{e:?}");
}

/// A dark mirror room (r = 1, no emitter inside) beside a lit room: the
/// dark one is exactly 0, the lit one solves.
#[test]
fn dark_closed_mirror_room_is_zero_beside_a_lit_room() {
    let rows = [
        "#########MMMMMMM",
        "#.......#M.....M",
        "#...L...#M.....M",
        "#.......#M.....M",
        "#########MMMMMMM",
    ];
    let lvl = ascii(
        &rows,
        &[('#', wall(0.5)), ('M', wall(1.0)), ('L', light(1.0, 0.5))],
    );
    let b = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
    for (x, y, v) in floor_values(&lvl, &b) {
        if x >= 10 {
            assert_eq!(v, 0.0, "({x},{y}) in the dark mirror room");
        } else {
            assert!(v > 0.0, "({x},{y}) in the lit room");
        }
    }
}

/// Open scenes with r = 1 solve: energy escapes through the opening or the
/// image border. With every surface a perfect mirror nothing is absorbed.
#[test]
fn open_scenes_with_r_1_solve_and_everything_escapes() {
    for rows in [
        // A room with a gap in its wall.
        vec![
            "###########",
            "#.........#",
            "#....L.....",
            "#.........#",
            "###########",
        ],
        // Two mirror walls facing each other, open at both ends.
        vec![
            "...........",
            "###########",
            ".....L.....",
            "###########",
            "...........",
        ],
    ] {
        let lvl = ascii(&rows, &[('#', wall(1.0)), ('L', light(1.0, 1.0))]);
        for q in [Quality::Draft, Quality::Normal] {
            let b = bake_checked(&lvl, &settings(q), 1e-6);
            let e = &b.report.energy;
            assert!(e.emitted > 0.0);
            assert!(e.absorbed.abs() <= 1e-9 * e.emitted, "{q}: {e:?}");
            assert!((e.escaped / e.emitted - 1.0).abs() < 1e-6, "{q}: {e:?}");
            assert!(b.report.solves >= 1);
        }
    }
}

// ---------------------------------------------------------------------------
// The iterative solver checks its residual and falls back

/// Form factors of a near-mirror room with many patches: CG needs many
/// iterations here.
fn hard_system() -> (flatbake_core::transport::FormFactors, Vec<f64>, Vec<f64>) {
    let rows = room_with(40, 30, &[(20, 0), (0, 15)]);
    let lvl = ascii(
        &refs(&rows),
        &[('#', wall(0.999)), ('L', light(1.0, 0.999))],
    );
    let g = trace(&lvl);
    let patches = Patches::new(&g, 0.5);
    let reach = Reach::unlimited(g.edges.len());
    let (ff, _, _) = form_factors(&Structures::new(&g), &patches, 3, None, &reach, 0.0);
    let mat = |p: usize| &lvl.materials[g.edges[patches.edge[p] as usize].material as usize];
    let rho = (0..patches.len()).map(|p| mat(p).reflectance[0]).collect();
    let e = (0..patches.len()).map(|p| mat(p).emission[0]).collect();
    (ff, rho, e)
}

/// Settings that solve every system with the dense Cholesky factorisation.
fn direct_only() -> SolveSettings {
    SolveSettings {
        direct_max: usize::MAX,
        ..SolveSettings::default()
    }
}

#[test]
fn cg_that_stalls_falls_back_to_a_direct_solve() {
    let (ff, rho, e) = hard_system();
    let direct = solve_channel(&ff, &rho, &e, &direct_only()).expect("direct");
    assert_eq!(direct.method, "cholesky");
    // CG forced (direct_max 0) with a tolerance it cannot reach in its
    // iteration budget: it must not return its unconverged answer.
    let forced = SolveSettings {
        tolerance: 1e-15,
        direct_max: 0,
        fallback_max: 100_000,
    };
    let s = solve_channel(&ff, &rho, &e, &forced).expect("fallback solves");
    assert_eq!(s.method, "cg-then-cholesky");
    assert!(s.iterations > 0);
    for (a, b) in s.radiosity.iter().zip(&direct.radiosity) {
        assert!((a - b).abs() <= 1e-9 * b.abs().max(1.0), "{a} vs {b}");
    }
    assert!(s.residual < 1e-9, "residual {}", s.residual);
}

#[test]
fn cg_that_cannot_converge_and_may_not_fall_back_is_an_error() {
    let (ff, rho, e) = hard_system();
    let s = SolveSettings {
        tolerance: 0.0,
        direct_max: 0,
        fallback_max: 0,
    };
    match solve_channel(&ff, &rho, &e, &s) {
        Err(SolveError::NotConverged { residual, .. }) => assert!(residual > 0.0),
        Ok(sol) => assert!(
            sol.residual <= 1e-6,
            "an unconverged answer was returned: {} via {}",
            sol.residual,
            sol.method
        ),
        Err(other) => panic!("{other}"),
    }
}

#[test]
fn cg_that_converges_matches_the_direct_solve() {
    let (ff, rho, e) = hard_system();
    let direct = solve_channel(&ff, &rho, &e, &direct_only()).expect("direct");
    let cg = SolveSettings {
        tolerance: 1e-10,
        direct_max: 0,
        fallback_max: 100_000,
    };
    let s = solve_channel(&ff, &rho, &e, &cg).expect("cg");
    assert!(s.method.starts_with("cg"), "{}", s.method);
    for (a, b) in s.radiosity.iter().zip(&direct.radiosity) {
        assert!((a - b).abs() <= 1e-6 * b.abs().max(1.0), "{a} vs {b}");
    }
}

// ---------------------------------------------------------------------------
// Geometry extremes

/// Angle subtended at `p` by the axis-aligned box `[x0, x1] x [y0, y1]`.
fn box_angle(p: [f64; 2], b: [f64; 4]) -> f64 {
    let corners = [[b[0], b[1]], [b[2], b[1]], [b[2], b[3]], [b[0], b[3]]];
    let ang: Vec<f64> = corners
        .iter()
        .map(|c| (c[1] - p[1]).atan2(c[0] - p[0]))
        .collect();
    let mut best: f64 = 0.0;
    for a in &ang {
        for c in &ang {
            let mut d = (a - c).abs();
            if d > PI {
                d = TAU - d;
            }
            best = best.max(d);
        }
    }
    best
}

/// One emitter pixel alone on a floor: every floor pixel reads e times the
/// angle the pixel subtends over 2 pi.
#[test]
fn one_pixel_light_reads_its_subtended_angle() {
    let mut rows = vec![".............".to_string(); 9];
    rows[4].replace_range(6..7, "L");
    let lvl = ascii(&refs(&rows), &[('L', light(2.0, 0.0))]);
    for q in [Quality::Draft, Quality::High] {
        let b = bake_checked(&lvl, &settings(q), 1e-9);
        for (x, y, v) in floor_values(&lvl, &b) {
            let want =
                2.0 * box_angle([x as f64 + 0.5, y as f64 + 0.5], [6.0, 4.0, 7.0, 5.0]) / TAU;
            assert!((v - want).abs() < 1e-5 * want, "({x},{y}) {v} vs {want}");
        }
    }
}

/// A one-pixel wall in front of a one-pixel light casts a shadow and the
/// scene balances.
#[test]
fn one_pixel_wall_and_light() {
    let rows = [
        "...........",
        "...........",
        "..L...#....",
        "...........",
        "...........",
    ];
    let lvl = ascii(&rows, &[('#', wall(0.7)), ('L', light(1.0, 0.3))]);
    let b = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
    let at = |x: usize, y: usize| b.lightmap.rgb[y * 11 + x][0];
    // The wall hides the whole light from the pixels right behind it, and
    // its own back faces see no light: exactly 0 there.
    assert_eq!(at(8, 2), 0.0);
    assert_eq!(at(7, 2), 0.0);
    // Off the axis the light is seen directly.
    assert!(at(8, 0) > 0.0 && at(8, 4) > 0.0);
}

/// A checkerboard: each interior floor pixel is a closed 1x1 cell whose two
/// opposite sides emit and the other two reflect. Flatland factors of a unit
/// square: opposite side sqrt(2) - 1, adjacent side 1 - sqrt(2)/2. The pixel
/// centre sees each side under 90 degrees, so it reads (B_e + B_w) / 2.
#[test]
fn checkerboard_cells_match_the_unit_square_closed_form() {
    let (w, h) = (12, 10);
    let rows: Vec<String> = (0..h)
        .map(|y| {
            (0..w)
                .map(|x| {
                    if (x + y) % 2 == 0 {
                        if x % 2 == 0 { 'L' } else { '#' }
                    } else {
                        '.'
                    }
                })
                .collect()
        })
        .collect();
    let (e, re, rw) = (1.0, 0.4, 0.8);
    let lvl = ascii(&refs(&rows), &[('#', wall(rw)), ('L', light(e, re))]);
    let fo = 2f64.sqrt() - 1.0;
    let fa = 1.0 - 2f64.sqrt() / 2.0;
    // B_e = e + re (fo B_e + 2 fa B_w);  B_w = rw (fo B_w + 2 fa B_e)
    let (a11, a12, a21, a22) = (1.0 - re * fo, -re * 2.0 * fa, -rw * 2.0 * fa, 1.0 - rw * fo);
    let det = a11 * a22 - a12 * a21;
    let be = e * a22 / det;
    let bw = -a21 * e / det;
    let want = 0.5 * (be + bw);
    for q in [Quality::Draft, Quality::Normal, Quality::High] {
        let b = bake_checked(&lvl, &settings(q), 1e-6);
        let e = &b.report.energy;
        assert!(e.escaped > 0.0, "border cells are open: {e:?}");
        let mut checked = 0;
        for (x, y, v) in floor_values(&lvl, &b) {
            if x == 0 || y == 0 || x == w - 1 || y == h - 1 {
                continue;
            }
            assert!(
                (v / want - 1.0).abs() < 1e-3,
                "{q} ({x},{y}): {v} vs {want}"
            );
            checked += 1;
        }
        assert!(checked > 20);
    }
}

/// Diagonal one-pixel walls (touching only at corners) inside a lit room:
/// closed at the corners, balanced, the far side dark.
#[test]
fn diagonal_one_pixel_walls() {
    let n = 14;
    let mut rows = room(n, n);
    for (i, row) in rows.iter_mut().enumerate().take(n - 1).skip(1) {
        let x = n - 1 - i;
        row.replace_range(x..x + 1, "D");
    }
    rows[3].replace_range(3..4, "L");
    let lvl = ascii(
        &refs(&rows),
        &[('#', wall(0.9)), ('D', wall(0.9)), ('L', light(1.0, 0.9))],
    );
    let b = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
    let e = &b.report.energy;
    assert!(e.escaped.abs() <= 1e-9 * e.emitted, "closed: {e:?}");
    for (x, y, v) in floor_values(&lvl, &b) {
        if x + y > n - 1 {
            assert_eq!(v, 0.0, "({x},{y}) behind the diagonal");
        } else {
            assert!(v > 0.0, "({x},{y}) in front of the diagonal");
        }
    }
}

/// Walls touching the image border on every side and an emitter in the
/// border: the room is closed by its own walls; edges facing out of the
/// image are dropped without disturbing the balance.
#[test]
fn walls_touching_the_image_border() {
    let rows = room_with(10, 8, &[(0, 3), (9, 5), (4, 0), (5, 7)]);
    let lvl = ascii(&refs(&rows), &[('#', wall(0.5)), ('L', light(1.0, 0.5))]);
    let b = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
    assert!(b.report.energy.escaped.abs() <= 1e-9 * b.report.energy.emitted);
    // A wall strip along one border only: an open scene.
    let rows = ["L.......", "#.......", "#.......", "L......."];
    let lvl = ascii(&rows, &[('#', wall(0.5)), ('L', light(1.0, 0.5))]);
    let b = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
    assert!(b.report.energy.escaped > 0.0);
    assert!(floor_values(&lvl, &b).iter().all(|v| v.2 > 0.0));
}

#[test]
fn all_wall_level_bakes_to_black_with_a_warning() {
    let rows = ["#L#", "###", "L#L"];
    let lvl = ascii(&rows, &[('#', wall(0.5)), ('L', light(1.0, 0.5))]);
    let b = bake_checked(&lvl, &settings(Quality::Normal), 0.0);
    assert!(b.lightmap.rgb.iter().all(|p| *p == [0.0; 3]));
    assert!(
        b.report
            .warnings
            .iter()
            .any(|w| w.contains("no floor pixels")),
        "{:?}",
        b.report.warnings
    );
    assert_eq!(b.report.counts.edges, 0, "all edges face out of the image");
}

#[test]
fn all_floor_level_bakes_to_black_with_a_warning() {
    let rows = vec!["........".to_string(); 6];
    let lvl = ascii(&refs(&rows), &[]);
    let b = bake_checked(&lvl, &settings(Quality::Normal), 0.0);
    assert!(b.lightmap.rgb.iter().all(|p| *p == [0.0; 3]));
    assert_eq!(b.report.solves, 0);
    assert!(b.report.warnings.iter().any(|w| w.contains("no emitter")));
}

#[test]
fn no_emitters_is_black_and_solves_nothing() {
    let rows = [
        "##########",
        "#........#",
        "#..##....#",
        "#........#",
        "##########",
    ];
    let lvl = ascii(&rows, &[('#', wall(0.999))]);
    let b = bake_checked(&lvl, &settings(Quality::Normal), 0.0);
    assert!(b.lightmap.rgb.iter().all(|p| *p == [0.0; 3]));
    assert_eq!(b.report.solves, 0);
    assert_eq!(b.report.energy.emitted, 0.0);
}

/// One floor pixel walled in by emitters: it reads e / (1 - r).
#[test]
fn one_floor_pixel_walled_in_reads_e_over_one_minus_r() {
    let rows = ["LLL", "L.L", "LLL"];
    for r in [0.0, 0.5, 0.98] {
        let lvl = ascii(&rows, &[('L', light(0.3, r))]);
        let b = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
        let want = 0.3 / (1.0 - r);
        let v = b.lightmap.rgb[4][0] as f64;
        assert!((v / want - 1.0).abs() < 1e-5, "r={r}: {v} vs {want}");
    }
    // One floor pixel in an otherwise solid image, open to nothing else but
    // at the border: it still bakes.
    let lvl = ascii(&["L.L"], &[('L', light(1.0, 0.5))]);
    bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
}

#[test]
fn one_by_one_images() {
    for (ch, legend) in [
        ('.', vec![]),
        (' ', vec![]),
        ('#', vec![('#', wall(0.5))]),
        ('L', vec![('L', light(1.0, 0.5))]),
    ] {
        let lvl = ascii(&[&ch.to_string()], &legend);
        let b = bake_checked(&lvl, &settings(Quality::Normal), 0.0);
        assert_eq!(b.lightmap.rgb, vec![[0.0; 3]], "{ch:?}");
    }
}

/// A 1 x N image: a one-pixel corridor open above and below. A pixel at
/// distance d from the emitter's face sees it under 2 atan(1 / (2 d)).
#[test]
fn one_by_n_images_read_the_subtended_angle() {
    let n = 24;
    let horizontal = format!("L{}", ".".repeat(n - 1));
    let lvl = ascii(&[&horizontal], &[('L', light(1.0, 0.0))]);
    let vertical: Vec<String> = horizontal.chars().map(String::from).collect();
    let lvl_v = ascii(&refs(&vertical), &[('L', light(1.0, 0.0))]);
    for (lvl, q) in [(&lvl, Quality::Normal), (&lvl_v, Quality::High)] {
        let b = bake_checked(lvl, &settings(q), 1e-9);
        for i in 1..n {
            let d = i as f64 - 0.5;
            let want = 2.0 * (0.5 / d).atan() / TAU;
            let v = b.lightmap.rgb[i][0] as f64;
            assert!(
                (v / want - 1.0).abs() < 1e-5,
                "{q} pixel {i}: {v} vs {want}"
            );
        }
    }
}

/// Non-square rooms and very long thin corridors (interior one pixel high,
/// 600 long): the closed form e / (1 - r) holds everywhere.
#[test]
fn non_square_rooms_and_long_thin_corridors() {
    for (w, h) in [(31, 5), (5, 31), (600, 3), (3, 400)] {
        let rows = room(w, h);
        let lvl = ascii(&refs(&rows), &[('#', light(0.5, 0.9))]);
        let b = bake_checked(&lvl, &settings(Quality::Draft), 1e-6);
        for (x, y, v) in floor_values(&lvl, &b) {
            assert!((v / 5.0 - 1.0).abs() < 1e-4, "{w}x{h} ({x},{y}): {v}");
        }
    }
}

/// A long corridor lit at one end: light decays along it and balances.
#[test]
fn long_corridor_lit_at_one_end() {
    let w = 300;
    let mut rows = room(w, 4);
    rows[1].replace_range(0..1, "L");
    rows[2].replace_range(0..1, "L");
    let lvl = ascii(&refs(&rows), &[('#', wall(0.8)), ('L', light(1.0, 0.0))]);
    let b = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
    let e = &b.report.energy;
    assert!(e.escaped.abs() <= 1e-9 * e.emitted);
    let at = |x: usize| b.lightmap.rgb[w + x][0];
    assert!(
        at(1) > at(50) && at(50) > at(250),
        "{} {} {}",
        at(1),
        at(50),
        at(250)
    );
    assert!(at(w - 2) >= 0.0);
}

/// Patches far longer than every edge (one patch per edge) and far shorter
/// (200 patches on a 10-pixel edge): the closed room is e / (1 - r) either way.
#[test]
fn edges_far_shorter_and_far_longer_than_the_patch_length() {
    let rows = room(12, 8);
    let lvl = ascii(&refs(&rows), &[('#', light(1.0, 0.6))]);
    for patch_len in [1000.0, 0.05] {
        let mut s = settings(Quality::Normal);
        s.knobs.patch_len = patch_len;
        let b = bake_checked(&lvl, &s, 1e-6);
        for (x, y, v) in floor_values(&lvl, &b) {
            assert!(
                (v / 2.5 - 1.0).abs() < 1e-4,
                "patch {patch_len} ({x},{y}): {v}"
            );
        }
    }
    // Mixed: a long room with one-pixel bumps, patches of 16.
    let mut rows = room(60, 12);
    rows[6].replace_range(20..21, "#");
    rows[3].replace_range(40..41, "L");
    let lvl = ascii(&refs(&rows), &[('#', wall(0.7)), ('L', light(1.0, 0.2))]);
    let mut s = settings(Quality::Normal);
    s.knobs.patch_len = 16.0;
    bake_checked(&lvl, &s, 1e-6);
}

// ---------------------------------------------------------------------------
// Extreme values

fn scene_for_scaling(e: f64) -> Level {
    let rows = [
        "##############",
        "#............#",
        "#..L.....##..#",
        "#........##..#",
        "#............ ",
        "##############",
    ];
    ascii(&rows, &[('#', wall(0.6)), ('L', light(e, 0.3))])
}

/// Radiosity is linear in emission: e = 1e-6 and 1e6 give exactly the
/// e = 1 result scaled, with and without falloff.
#[test]
fn emission_1e_minus_6_and_1e6_scale_linearly() {
    for falloff in [None, Some(6.0)] {
        let mut s = settings(Quality::Normal);
        s.falloff = falloff;
        let base = scene_for_scaling(1.0);
        let b1 = bake_checked(&base, &s, 1e-6);
        let max1 = b1.lightmap.rgb.iter().map(|p| p[0]).fold(0f32, f32::max) as f64;
        assert!(max1 > 0.0);
        for scale in [1e-6, 1e6] {
            let lvl = scene_for_scaling(scale);
            let b = bake_checked(&lvl, &s, 1e-6);
            for (i, (p, q)) in b.lightmap.rgb.iter().zip(&b1.lightmap.rgb).enumerate() {
                let want = q[0] as f64 * scale;
                let got = p[0] as f64;
                assert!(
                    (got - want).abs() <= 1e-5 * max1 * scale,
                    "falloff {falloff:?} scale {scale:e} pixel {i}: {got} vs {want}"
                );
            }
            let e = &b.report.energy;
            assert!((e.emitted / (b1.report.energy.emitted * scale) - 1.0).abs() < 1e-9);
        }
    }
}

/// Falloff of 1e6 pixels is no falloff for a level this size; 0.1 pixel
/// leaves almost nothing but stays finite, non-negative and balanced, and
/// never brighter than without falloff.
#[test]
fn falloff_0_1_and_1e6_pixels() {
    let lvl = scene_for_scaling(1.0);
    let none = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
    let mut s = settings(Quality::Normal);
    s.falloff = Some(1e6);
    let far = bake_checked(&lvl, &s, 1e-6);
    for (p, q) in far.lightmap.rgb.iter().zip(&none.lightmap.rgb) {
        assert!(
            (p[0] - q[0]).abs() <= 1e-6 * q[0].max(1e-3),
            "{p:?} vs {q:?}"
        );
    }
    s.falloff = Some(0.1);
    let near = bake_checked(&lvl, &s, 1e-6);
    let mut any = false;
    for (p, q) in near.lightmap.rgb.iter().zip(&none.lightmap.rgb) {
        assert!(p[0] <= q[0] * (1.0 + 1e-5), "{p:?} vs {q:?}");
        any |= p[0] > 0.0;
    }
    assert!(any, "pixels next to the light still see some");
    let e = &near.report.energy;
    assert!(
        e.escaped > 0.9 * e.emitted,
        "most light is lost to falloff: {e:?}"
    );
}

/// Regression: a falloff distance whose square overflows (above about
/// 1.3e154 pixels, accepted by `--falloff` and the palette as a finite
/// number) made every weight `inf / inf` = NaN, and the whole lightmap was
/// clamped to black. It must act as no falloff.
#[test]
fn falloff_beyond_1e154_pixels_is_no_falloff_not_nan() {
    let lvl = scene_for_scaling(1.0);
    let none = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
    for f in [1e154, 1e200, 1e300, f64::MAX, f64::INFINITY] {
        let mut s = settings(Quality::Normal);
        s.falloff = Some(f);
        let b = bake_checked(&lvl, &s, 1e-6);
        for (p, q) in b.lightmap.rgb.iter().zip(&none.lightmap.rgb) {
            assert!(
                (p[0] - q[0]).abs() <= 1e-6 * q[0].max(1e-3),
                "falloff {f:e}: {p:?} vs {q:?}"
            );
        }
    }
}

/// Regression: light above the f32 range (emission 1e39 from code, or a
/// huge amplification) became +inf in the lightmap and was then "clamped"
/// to black. It saturates at the largest f32 instead.
#[test]
fn light_beyond_the_f32_range_saturates_instead_of_going_black() {
    let rows = room(9, 7);
    let lvl = ascii(&refs(&rows), &[('#', light(1e39, 0.5))]);
    let b = bake_checked(&lvl, &settings(Quality::Normal), 1e-6);
    for (x, y, v) in floor_values(&lvl, &b) {
        assert_eq!(v, f32::MAX as f64, "({x},{y})");
    }
    // Solid pixels (the emitters' mean radiosity) saturate too.
    assert_eq!(b.lightmap.rgb[1][0], f32::MAX);
}

/// Regression (found by fuzzing `bake_level`): with a short falloff the
/// reach culling can empty a patch's own row of form factors while other
/// patches still see it. Its coverage was left at 0, so its light counted as
/// escaped and also as received: emitted != absorbed + escaped by up to
/// 1.2e-4 at the draft preset, above its solver tolerance. The balance is
/// now exact up to rounding at every preset.
#[test]
fn energy_balances_when_falloff_culls_a_patch_s_whole_row() {
    let mut a = light(1.0, 0.0);
    a.reflectance = [0.9, 1.0, 0.9];
    let mut first = vec![".".repeat(9); 17];
    first[0] = "..AAAAAAA".into();
    first[1] = "A........".into();
    let mut b0 = light(0.0, 0.0);
    b0.reflectance = [0.25, 0.5, 0.98];
    b0.emission = [1e-6, 1e-3, 1e-6];
    let mut b1 = b0.clone();
    b1.reflectance[2] = 0.0;
    let mut second = vec!["....".to_string(); 18];
    for (y, row) in ["..11", "1111", "1111", "....", "....", ".010", "0..."]
        .iter()
        .enumerate()
    {
        second[y] = row.to_string();
    }
    let cases = [
        ascii(&refs(&first), &[('A', a)]),
        ascii(&refs(&second), &[('0', b0), ('1', b1)]),
    ];
    for lvl in &cases {
        for q in [Quality::Draft, Quality::Normal, Quality::High] {
            let mut s = settings(q);
            s.falloff = Some(0.1);
            // The presets' own bounds may be too small to cull here; the
            // regression needs culling at every discretisation.
            s.knobs.reach_bound = s.knobs.reach_bound.max(1e-5);
            let b = bake_checked(lvl, &s, 1e-12);
            assert!(
                b.report.counts.culled_pairs > 0,
                "{q}: the case needs culling"
            );
        }
    }
}

// ---------------------------------------------------------------------------
// The paper's kernel

#[test]
fn paper_kernel_on_a_near_mirror_closed_room_is_finite_with_a_warning() {
    for r in [0.999, 1.0] {
        let rows = room_with(15, 11, &[(7, 0), (0, 5)]);
        let lvl = ascii(&refs(&rows), &[('#', wall(r)), ('L', light(1.0, r))]);
        let mut s = settings(Quality::Normal);
        s.kernel = Kernel::Paper;
        let b = bake(&lvl, &s, &quiet).unwrap_or_else(|e| panic!("r={r}: {e}"));
        // The paper's kernel does not conserve energy: no balance check.
        check(&lvl, &b, f64::INFINITY);
        assert!(
            b.report
                .warnings
                .iter()
                .any(|w| w.contains("paper kernel") && w.contains("rescaled")),
            "r={r}: {:?}",
            b.report.warnings
        );
        assert!(floor_values(&lvl, &b).iter().all(|v| v.2 > 0.0));
        // Rescaled rows keep rho F below 1: B is bounded by e / (1 - MAX_ROW).
        let bound = 1.0 / (1.0 - flatbake_core::transport::paper::MAX_ROW);
        for v in &b.radiosity[0] {
            assert!(*v <= bound * (1.0 + 1e-9), "r={r}: {v} > {bound}");
        }
    }
}

/// Regression: rows of rho F just below 1 (say 0.99999) were not rescaled;
/// above 2500 patches the paper kernel's Jacobi iteration then stopped at
/// its sweep limit far from the answer (about 63% of it), and below 2500 the
/// direct solve gave a different answer for the same rows. Every row is now
/// capped at MAX_ROW, and both paths agree on the capped system.
#[test]
fn paper_rows_just_below_1_converge_on_large_systems() {
    let max_row = flatbake_core::transport::paper::MAX_ROW;
    for n in [100, 3000] {
        let rows: Vec<Vec<(u32, f64)>> = (0..n).map(|i| vec![(i as u32, 1.0)]).collect();
        let rho = vec![0.99999; n];
        let e = vec![1.0; n];
        let (b, _) = flatbake_core::transport::paper::solve(&rows, &rho, &e, 1e-10);
        let want = 1.0 / (1.0 - max_row);
        for v in &b {
            assert!((v / want - 1.0).abs() < 1e-6, "n={n}: {v} vs {want}");
        }
    }
}

/// Every class of generated level, small, bakes at `draft` and `normal`
/// (and exhaustively) with its palette's falloff: finite, non-negative,
/// balanced light and no clamped-light warning. The merged pieces and the
/// falloff reach may take a far, nearly dark pixel a little below 0 (within
/// the preset's bound of the brightest emission); that is set to 0 without
/// a word, and only light further below 0 is a fault worth a warning.
#[test]
fn every_level_class_bakes_clean() {
    for class in flatbake_synth::small_classes(128) {
        let (lvl, pal) = class
            .level
            .level()
            .unwrap_or_else(|e| panic!("{}: {e}", class.label));
        for (q, exhaustive) in [
            (Quality::Draft, false),
            (Quality::Normal, false),
            (Quality::Normal, true),
        ] {
            let mut s = settings(q);
            s.falloff = pal.settings.falloff;
            s.exhaustive = exhaustive;
            let baked =
                bake(&lvl, &s, &quiet).unwrap_or_else(|e| panic!("{} at {q}: {e}", class.label));
            eprintln!(
                "{} at {q}{}: ok",
                class.label,
                if exhaustive { " (exhaustive)" } else { "" }
            );
            check(&lvl, &baked, s.knobs.tolerance.max(1e-5));
        }
    }
}

// ---------------------------------------------------------------------------
// Random levels

/// A random small level and palette from the synthetic generator.
fn random_level(seed: u64) -> (Level, Option<f64>) {
    let p = flatbake_synth::random_small(seed);
    let (lvl, pal) = p.level().unwrap_or_else(|e| panic!("seed {seed}: {e}"));
    (lvl, pal.settings.falloff)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn random_levels_are_finite_non_negative_and_balanced(
        seed in any::<u64>(),
        q in prop::sample::select(vec![Quality::Draft, Quality::Normal]),
    ) {
        let (lvl, falloff) = random_level(seed);
        let mut s = settings(q);
        s.falloff = falloff;
        // Energy balances to the solver's tolerance (1e-4 at draft: CG stops
        // there; a direct solve would balance to rounding).
        let energy_tol = s.knobs.tolerance.max(1e-5);
        match bake(&lvl, &s, &quiet) {
            Ok(b) => check(&lvl, &b, energy_tol),
            // r = 1 rooms with light are the only refusal allowed.
            Err(e @ BakeError::Unbounded { .. }) => {
                prop_assert!(e.to_string().contains("reflectance 1"), "{}", e)
            }
            Err(e) => prop_assert!(false, "seed {seed}: {e}"),
        }
    }

    #[test]
    fn random_levels_with_the_paper_kernel_are_finite_and_non_negative(seed in any::<u64>()) {
        let (lvl, falloff) = random_level(seed);
        let mut s = settings(Quality::Draft);
        s.falloff = falloff;
        s.kernel = Kernel::Paper;
        let b = bake(&lvl, &s, &quiet).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        check(&lvl, &b, f64::INFINITY);
    }

    /// Random rooms with reflectance drawn near 1 and random extreme values.
    #[test]
    fn random_near_mirror_rooms(
        w in 3usize..30,
        h in 3usize..30,
        r in prop::sample::select(vec![0.0, 0.5, 0.98, 0.999, 0.9999]),
        e in prop::sample::select(vec![1e-6, 1.0, 1e6]),
        light_at in 0usize..1000,
        pillar in prop::option::of((1usize..28, 1usize..28)),
    ) {
        let mut rows = room(w, h);
        let border: Vec<(usize, usize)> = (0..w)
            .flat_map(|x| [(x, 0), (x, h - 1)])
            .chain((0..h).flat_map(|y| [(0, y), (w - 1, y)]))
            .collect();
        let (lx, ly) = border[light_at % border.len()];
        rows[ly].replace_range(lx..lx + 1, "L");
        if let Some((px, py)) = pillar
            && px < w - 1 && py < h - 1
        {
            rows[py].replace_range(px..px + 1, "#");
        }
        let lvl = ascii(&refs(&rows), &[('#', wall(r)), ('L', light(e, 0.2))]);
        let b = bake(&lvl, &settings(Quality::Draft), &quiet).expect("bakes");
        check(&lvl, &b, 1e-5);
        let en = &b.report.energy;
        prop_assert!(en.escaped.abs() <= 1e-8 * en.emitted.max(1e-300), "{:?}", en);
    }
}

// ---------------------------------------------------------------------------
// Determinism

fn run_bake(args: &[&std::ffi::OsStr]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_flatbake"))
        .arg("bake")
        .args(args)
        .output()
        .expect("flatbake runs")
}

/// The same bytes for `--jobs 1` and `--jobs 2`: every image, the report
/// apart from its timings, the stamp apart from the report's hash, and the
/// batch summary apart from its seconds.
#[test]
fn jobs_1_and_jobs_2_write_identical_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let levels = dir.path().join("levels");
    flatbake_synth::cornell(64).save(&levels).unwrap();
    flatbake_synth::random_small(3).save(&levels).unwrap();
    flatbake_synth::random_small(11).save(&levels).unwrap();
    let mut outs = Vec::new();
    for jobs in ["1", "2"] {
        let out = dir.path().join(format!("out{jobs}"));
        let o = run_bake(&[
            levels.as_os_str(),
            "-o".as_ref(),
            out.as_os_str(),
            "--jobs".as_ref(),
            jobs.as_ref(),
            "--hdr".as_ref(),
            "--rgbm".as_ref(),
            "--quiet".as_ref(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        outs.push(out);
    }
    let mut names: Vec<_> = std::fs::read_dir(&outs[0])
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert!(names.len() >= 12, "{names:?}");
    for name in names {
        let a = std::fs::read(outs[0].join(&name)).unwrap();
        let b = std::fs::read(outs[1].join(&name))
            .unwrap_or_else(|e| panic!("{name:?} missing with --jobs 2: {e}"));
        if name.to_string_lossy().ends_with(".report.json") {
            let strip = |bytes: &[u8]| {
                let mut v: serde_json::Value = serde_json::from_slice(bytes).unwrap();
                v.as_object_mut().unwrap().remove("timings");
                v
            };
            assert_eq!(strip(&a), strip(&b), "{name:?}");
        } else if name == "batch.json" {
            // The batch summary: equal apart from the run's and each
            // level's seconds.
            let strip = |bytes: &[u8]| {
                let mut v: serde_json::Value = serde_json::from_slice(bytes).unwrap();
                v.as_object_mut().unwrap().remove("seconds");
                for l in v["levels"].as_array_mut().unwrap() {
                    l.as_object_mut().unwrap().remove("seconds");
                }
                v
            };
            assert_eq!(strip(&a), strip(&b), "{name:?}");
        } else if name.to_string_lossy().ends_with(".stamp.json") {
            // The stamp hashes every output, the report (and so its
            // timings) included: equal apart from the report's hash.
            let strip = |bytes: &[u8]| {
                let v: serde_json::Value = serde_json::from_slice(bytes).unwrap();
                let outputs = v["outputs"].as_array().unwrap().clone();
                let hashes: Vec<_> = v["hashes"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .zip(&outputs)
                    .filter(|(_, o)| !o.as_str().unwrap().ends_with(".report.json"))
                    .map(|(h, _)| h.clone())
                    .collect();
                (v["flatbake"].clone(), v["inputs"].clone(), outputs, hashes)
            };
            assert_eq!(strip(&a), strip(&b), "{name:?}");
        } else {
            assert!(a == b, "{name:?} differs between --jobs 1 and --jobs 2");
        }
    }
}

/// A system that neither Cholesky nor LU can factor (two perfect mirrors
/// that see only each other, with effective lengths that make `D / rho - S`
/// singular) is an error, not an answer of zeros.
#[test]
fn a_singular_system_is_an_error_not_zeros() {
    let ff = flatbake_core::transport::FormFactors {
        row_ptr: vec![0, 1, 2],
        col: vec![1, 0].into(),
        val: vec![1.0, 1.0],
        dlen: vec![1.0, 1.0],
        coverage: vec![0.5, 0.5],
        dropped: 0,
        one_sided: 0,
    };
    let (rho, e) = (vec![1.0, 1.0], vec![1.0, 0.0]);
    match solve_channel(&ff, &rho, &e, &SolveSettings::default()) {
        Err(SolveError::Singular { unknowns }) => assert_eq!(unknowns, 2),
        Ok(sol) => panic!(
            "a singular system was solved: {:?} via {}",
            sol.radiosity, sol.method
        ),
        Err(other) => panic!("{other}"),
    }
}

/// The last-resort clamp never fires on a valid level: the reported level
/// (a tiny falloff at draft, where the fast gather's sums of moments nearly
/// cancel) at every preset, with and without its falloff, and a level of
/// 25 % random one-pixel walls.
#[test]
fn the_last_resort_clamp_does_not_fire_on_valid_levels() {
    use flatbake_core::level::palette::Palette;
    use flatbake_core::level::{LoadLimits, load_level};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/input/clamp_draft_falloff.png");
    let palette = Palette::resolve_for_level(&path, None).expect("palette");
    let reported = load_level(&path, &palette, LoadLimits::default()).expect("level");
    // 25 % random one-pixel walls in a closed room with a light strip.
    let mut s = 7u64;
    let rows: Vec<String> = (0..96)
        .map(|y| {
            (0..96)
                .map(|x| {
                    s ^= s << 13;
                    s ^= s >> 7;
                    s ^= s << 17;
                    if y == 0 && (30..60).contains(&x) {
                        '*'
                    } else if x == 0 || y == 0 || x == 95 || y == 95 || s.is_multiple_of(4) {
                        '#'
                    } else {
                        '.'
                    }
                })
                .collect()
        })
        .collect();
    let noise = ascii(&refs(&rows), &[('#', wall(0.6)), ('*', light(2.0, 0.0))]);
    for q in [Quality::Draft, Quality::Normal, Quality::High] {
        for falloff in [None, Some(0.1), Some(8.0)] {
            for level in [&reported, &noise] {
                let mut s = settings(q);
                s.falloff = falloff;
                let b = bake(level, &s, &quiet).unwrap_or_else(|e| panic!("{e}"));
                check(level, &b, s.knobs.tolerance.max(1e-5));
            }
        }
    }
}
