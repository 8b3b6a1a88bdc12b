//! Simulating only what a scene calls for (README, "What flatbake skips"): every skip is checked
//! against the full computation (`Settings::exhaustive`), identical where the
//! skip is exact and within its documented bound where it is bounded, and
//! the report says what was skipped.

mod common;
use common::*;

use flatbake_core::bake::{Baked, Settings, bake, plan_channels};
use flatbake_core::level::material::Material;
use flatbake_core::level::{Cell, Level};
use flatbake_core::quality::Quality;

fn run(level: &Level, q: Quality, falloff: Option<f64>, exhaustive: bool) -> Baked {
    let mut s = Settings::new(q);
    s.falloff = falloff;
    s.exhaustive = exhaustive;
    bake(level, &s, &|_| {}).expect("bakes")
}

fn skipped(b: &Baked, effect: &str) -> bool {
    b.report.skipped.iter().any(|s| s.effect.contains(effect))
}

/// Largest absolute difference over all pixels and channels.
fn max_diff(a: &Baked, b: &Baked) -> f64 {
    a.lightmap
        .rgb
        .iter()
        .zip(&b.lightmap.rgb)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] as f64 - q[c] as f64).abs()))
        .fold(0.0, f64::max)
}

/// A room with a block, a light strip in the top wall, and the given materials.
fn room(wall_m: Material, light_m: Material) -> Level {
    let rows = [
        "##########LLLL##########",
        "#......................#",
        "#......................#",
        "#.......###............#",
        "#.......###............#",
        "#......................#",
        "#..............#.......#",
        "#..............#.......#",
        "#......................#",
        "########################",
    ];
    ascii(&rows, &[('#', wall_m), ('L', light_m)])
}

fn coloured(r: [f64; 3]) -> Material {
    Material {
        reflectance: r,
        ..wall(0.0)
    }
}

fn emitter(e: [f64; 3]) -> Material {
    Material {
        emission: e,
        ..light(0.0, 0.0)
    }
}

/// `level` baked at `q` with one solve for three channels (asserted), and
/// exhaustively. An exhaustive bake gathers every pixel exactly: so does
/// the first, without the lattice (draft's lattice and block sweeps are
/// tested in draft_local.rs).
fn shared_and_exhaustive(level: &Level, q: Quality) -> (Baked, Baked) {
    let mut s = Settings::new(q);
    s.knobs.lattice = None;
    let fast = bake(level, &s, &|_| {}).expect("bakes");
    assert_eq!(fast.report.solves, 1, "{q}");
    (fast, run(level, q, None, true))
}

#[test]
fn grey_scene_is_solved_once_and_matches_three_solves() {
    let level = room(wall(0.6), light(2.0, 0.3));
    for q in [Quality::Draft, Quality::Normal] {
        let (fast, full) = shared_and_exhaustive(&level, q);
        assert_eq!(full.report.solves, 3, "{q}");
        assert!(skipped(&fast, "channel"), "{:?}", fast.report.skipped);
        assert!(full.report.skipped.is_empty(), "{:?}", full.report.skipped);
        assert_eq!(max_diff(&fast, &full), 0.0, "{q}: sharing a solve is exact");
    }
}

/// Largest difference over all pixels and channels, relative to the
/// brightest value of `b`.
fn rel_diff(a: &Baked, b: &Baked) -> f64 {
    let top = b
        .lightmap
        .rgb
        .iter()
        .flat_map(|p| p.iter().map(|&v| v as f64))
        .fold(0.0, f64::max);
    max_diff(a, b) / top
}

/// A room of grey walls with a lamp of emission `l` in the top wall and
/// one of emission `m` in the right wall.
fn two_lamps(l: [f64; 3], m: [f64; 3]) -> Level {
    let rows = [
        "##########LLLL##########",
        "#......................#",
        "#.......###............#",
        "#.......###............M",
        "#......................M",
        "#..............#.......#",
        "########################",
    ];
    ascii(
        &rows,
        &[('#', wall(0.6)), ('L', emitter(l)), ('M', emitter(m))],
    )
}

#[test]
fn one_light_colour_on_grey_walls_is_solved_once_and_scaled() {
    // Two lamps of one colour at two brightnesses, grey walls: every
    // channel's emission is one ratio of blue's (the brightest).
    let level = two_lamps([1.0, 2.0, 4.0], [0.25, 0.5, 1.0]);
    let used = vec![true; level.materials.len()];
    let plan = plan_channels(&level, &used);
    assert_eq!(plan.classes, vec![2], "blue, the brightest, is solved");
    assert_eq!(plan.scale, [0.25, 0.5, 1.0]);
    for q in [Quality::Draft, Quality::Normal] {
        let (fast, full) = shared_and_exhaustive(&level, q);
        assert!(
            fast.report
                .skipped
                .iter()
                .any(|s| s.effect == "channel solves" && s.reason.contains("scaled")),
            "{:?}",
            fast.report.skipped
        );
        // Two solves each within the solver's tolerance of the answer.
        let d = rel_diff(&fast, &full);
        assert!(
            d <= 1e-5,
            "{q}: scaling a solve is exact up to the solver: {d}"
        );
        let (ef, eu) = (fast.report.energy.emitted, full.report.energy.emitted);
        assert!(
            (ef - eu).abs() <= 1e-9 * eu,
            "emitted power {ef} against {eu}"
        );
    }
}

#[test]
fn lights_of_two_colours_take_a_solve_per_channel() {
    // Each lamp alone would be one colour; together no channel is a
    // multiple of another.
    let level = two_lamps([2.0, 1.0, 1.0], [1.0, 1.0, 2.0]);
    let b = run(&level, Quality::Normal, None, false);
    assert_eq!(b.report.solves, 3);
    assert_eq!(max_diff(&b, &run(&level, Quality::Normal, None, true)), 0.0);
    // And one colour on coloured walls: a solve per channel too.
    let level = room(coloured([0.7, 0.5, 0.3]), emitter([2.0, 1.0, 0.5]));
    assert_eq!(run(&level, Quality::Normal, None, false).report.solves, 3);
}

#[test]
fn coloured_scene_takes_three_solves() {
    let level = room(coloured([0.7, 0.2, 0.1]), light(2.0, 0.0));
    let b = run(&level, Quality::Normal, None, false);
    assert_eq!(b.report.solves, 3);
    assert_eq!(max_diff(&b, &run(&level, Quality::Normal, None, true)), 0.0);
}

#[test]
fn channel_without_emission_is_not_solved() {
    // Yellow light: red and green share one solve, blue is dark.
    let level = room(wall(0.5), emitter([2.0, 2.0, 0.0]));
    let b = run(&level, Quality::Normal, None, false);
    assert_eq!(b.report.solves, 1);
    assert!(skipped(&b, "blue"), "{:?}", b.report.skipped);
    assert!(b.lightmap.rgb.iter().all(|p| p[2] == 0.0));
    assert_eq!(max_diff(&b, &run(&level, Quality::Normal, None, true)), 0.0);
}

#[test]
fn no_reflecting_wall_means_no_bounce_solve() {
    let level = room(wall(0.0), emitter([1.0, 0.5, 0.2]));
    let b = run(&level, Quality::Normal, None, false);
    assert_eq!(b.report.solves, 0);
    assert_eq!(b.report.counts.form_factor_entries, 0, "no F is built");
    assert!(
        b.report
            .skipped
            .iter()
            .any(|s| s.effect == "bounce" && s.reason.contains("no wall reflects")),
        "{:?}",
        b.report.skipped
    );
    let full = run(&level, Quality::Normal, None, true);
    assert_eq!(full.report.solves, 3);
    assert!(
        max_diff(&b, &full) <= 1e-6 * 1.0,
        "radiosity is the emission: {}",
        max_diff(&b, &full)
    );
}

#[test]
fn reflecting_walls_that_see_no_emitter_mean_no_bounce_solve() {
    // Left room: black walls and a light. Right room: white walls, no light.
    let rows = [
        "BBBBBBBBB#########",
        "B.......B#.......#",
        "B.......B#.......#",
        "LLL.....B#.......#",
        "B.......B#.......#",
        "BBBBBBBBB#########",
    ];
    let level = ascii(
        &rows,
        &[('B', wall(0.0)), ('#', wall(0.8)), ('L', light(3.0, 0.0))],
    );
    let b = run(&level, Quality::Normal, None, false);
    assert_eq!(b.report.solves, 0, "{:?}", b.report.skipped);
    assert!(skipped(&b, "bounce"));
    let full = run(&level, Quality::Normal, None, true);
    assert!(max_diff(&b, &full) <= 1e-6, "{}", max_diff(&b, &full));
    // The right room is not lit, and not gathered.
    assert!(
        b.report.counts.unreached_pixels >= 7 * 4,
        "{:?}",
        b.report.counts
    );
}

#[test]
fn unreached_regions_are_zero_and_counted() {
    // A sealed dark room beside a lit one: identical to gathering it.
    let rows = [
        "####LL#############",
        "#.........#.......#",
        "#.........#.......#",
        "#.........#.......#",
        "###################",
    ];
    let level = ascii(&rows, &[('#', wall(0.5)), ('L', light(2.0, 0.0))]);
    let b = run(&level, Quality::Normal, None, false);
    let full = run(&level, Quality::Normal, None, true);
    assert_eq!(max_diff(&b, &full), 0.0);
    assert_eq!(b.report.counts.unreached_pixels, 3 * 7);
    assert!(skipped(&b, "gather"), "{:?}", b.report.skipped);
    for y in 1..4 {
        for x in 11..18 {
            assert_eq!(b.lightmap.rgb[y * level.width + x], [0.0; 3]);
        }
    }
}

#[test]
fn a_level_without_emitters_is_black_at_once() {
    let level = ascii(&refs(&common::room(12, 8)), &[('#', wall(0.7))]);
    let b = run(&level, Quality::Normal, None, false);
    assert_eq!(b.report.solves, 0);
    assert_eq!(b.report.counts.form_factor_entries, 0);
    assert!(b.lightmap.rgb.iter().all(|p| *p == [0.0; 3]));
    assert!(
        b.report.warnings.iter().any(|w| w.contains("no emitter")),
        "{:?}",
        b.report.warnings
    );
}

/// With falloff, each skipped edge-pixel pair would have contributed less
/// than `reach_bound` times the brightest emission, so (direct light only)
/// the summed error over all pixels is at most `culled pairs * bound`.
#[test]
fn falloff_reach_skip_stays_within_its_bound() {
    let mut rows: Vec<String> = common::room(400, 12);
    for x in [10usize, 200, 388] {
        rows[0].replace_range(x..x + 2, "LL");
    }
    let level = ascii(&refs(&rows), &[('#', wall(0.0)), ('L', light(5.0, 0.0))]);
    for q in [Quality::Draft, Quality::Normal, Quality::High] {
        let b = run(&level, q, Some(3.0), false);
        let full = run(&level, q, Some(3.0), true);
        let pairs = b.report.counts.culled_pairs;
        assert!(pairs > 0, "{q}: the far pixels are culled");
        assert!(skipped(&b, "falloff reach"), "{:?}", b.report.skipped);
        let bound = q.knobs().reach_bound * 5.0;
        let total: f64 = level
            .cells
            .iter()
            .enumerate()
            .filter(|(_, c)| **c == Cell::Floor)
            .map(|(i, _)| (b.lightmap.rgb[i][0] as f64 - full.lightmap.rgb[i][0] as f64).abs())
            .sum();
        assert!(
            total <= pairs as f64 * bound * (1.0 + 1e-6) + 1e-5,
            "{q}: summed error {total:.3e} over {pairs} culled pairs x {bound:.1e}"
        );
        assert_eq!(full.report.counts.culled_pairs, 0);
    }
}

/// Far from a pixel, runs of patches whose reflected light is nearly quadratic
/// are gathered as one parabola; the merged pieces' errors are bounded by the
/// tolerance times the angle they cover, so every pixel stays within
/// `reach_bound` times the brightest emission of the exact gather.
#[test]
fn distant_patches_merge_within_their_bound() {
    let e = 5.0;
    let mut rows: Vec<String> = common::room(300, 24);
    rows[0].replace_range(20..24, "LLLL");
    rows[12].replace_range(150..160, "##########");
    let level = ascii(&refs(&rows), &[('#', wall(0.7)), ('L', light(e, 0.0))]);
    for falloff in [None, Some(60.0)] {
        for q in [Quality::Draft, Quality::Normal, Quality::High] {
            // Merging alone: draft's interpolation is checked on its own.
            let mut s = Settings::new(q);
            s.falloff = falloff;
            s.knobs.lattice = None;
            let b = bake(&level, &s, &|_| {}).expect("bakes");
            let full = run(&level, q, falloff, true);
            assert!(
                skipped(&b, "distant patches"),
                "{q}: {:?}",
                b.report.skipped
            );
            assert!(!skipped(&full, "distant patches"));
            let bound = q.knobs().reach_bound * e;
            let brightest = full
                .lightmap
                .rgb
                .iter()
                .flatten()
                .fold(0f32, |m, &v| m.max(v)) as f64;
            // Without falloff nothing else is left out; with it, the reach
            // culling may add its own (bounded) share on the far pixels.
            let culled = b.report.counts.culled_pairs as f64 * bound;
            let d = max_diff(&b, &full);
            assert!(
                d <= bound + culled + 1e-6 * brightest,
                "{q} falloff {falloff:?}: largest difference {d:.3e}, bound {bound:.1e}"
            );
        }
    }
}

/// `bounces = N` truncates the series: a closed room of emission e and
/// reflectance r reads e (1 - r^(N+1)) / (1 - r).
#[test]
fn bounces_truncate_the_series_exactly() {
    let (e, r) = (0.8, 0.6);
    let level = ascii(&refs(&common::room(11, 9)), &[('#', light(e, r))]);
    for n in [0u32, 1, 2, 5] {
        let mut s = Settings::new(Quality::Normal);
        s.bounces = Some(n);
        let b = bake(&level, &s, &|_| {}).expect("bakes");
        let want = e * (1.0 - r.powi(n as i32 + 1)) / (1.0 - r);
        for (i, c) in level.cells.iter().enumerate() {
            if *c == Cell::Floor {
                let v = b.lightmap.rgb[i][0] as f64;
                assert!((v / want - 1.0).abs() < 1e-5, "bounces {n}: {v} vs {want}");
            }
        }
        if n == 0 {
            assert_eq!(b.report.solves, 0);
            assert!(skipped(&b, "bounce"));
        }
    }
}

#[test]
fn sealed_dark_cells_get_no_patches_and_change_nothing() {
    // A lit room beside a strip of sealed one-pixel cells (a checkerboard):
    // the cells' walls get no patches, and the bake is the exhaustive one.
    let rows = [
        "####LL##########",
        "#.......#.#.#.##",
        "#.......##.#.#.#",
        "#.......#.#.#.##",
        "#.......##.#.#.#",
        "################",
    ];
    let level = ascii(&rows, &[('#', wall(0.5)), ('L', light(2.0, 0.0))]);
    let b = run(&level, Quality::Normal, None, false);
    let full = run(&level, Quality::Normal, None, true);
    assert!(
        b.report.counts.patches < full.report.counts.patches,
        "{} patches against {}",
        b.report.counts.patches,
        full.report.counts.patches
    );
    assert!(skipped(&b, "patches"), "{:?}", b.report.skipped);
    assert!(!skipped(&full, "patches"));
    assert_eq!(max_diff(&b, &full), 0.0);
}

/// Relative RMS difference of two lightmaps over floor pixels.
fn rel_rms(level: &Level, a: &Baked, b: &Baked) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (i, cell) in level.cells.iter().enumerate() {
        if *cell == Cell::Floor {
            for c in 0..3 {
                let (x, y) = (a.lightmap.rgb[i][c] as f64, b.lightmap.rgb[i][c] as f64);
                num += (x - y) * (x - y);
                den += y * y;
            }
        }
    }
    (num / den).sqrt()
}

#[test]
fn draft_interpolates_smooth_floor_and_stays_near_its_exact_gather() {
    // An open hall with a long light and a pillar: most cells are smooth.
    let mut rows = vec![format!("#{}#", "L".repeat(62))];
    for y in 0..46 {
        let pillar = (20..24).contains(&y);
        rows.push(format!(
            "#{}{}{}#",
            ".".repeat(30),
            if pillar { "##" } else { ".." },
            ".".repeat(30)
        ));
    }
    rows.push("#".repeat(64));
    let level = ascii(&refs(&rows), &[('#', wall(0.5)), ('L', light(2.0, 0.0))]);
    let b = run(&level, Quality::Draft, Some(40.0), false);
    let mut s = Settings::new(Quality::Draft);
    s.falloff = Some(40.0);
    s.knobs.lattice = None;
    let each = bake(&level, &s, &|_| {}).expect("bakes");
    assert!(skipped(&b, "pixels"), "{:?}", b.report.skipped);
    assert!(!skipped(&each, "pixels"));
    let err = rel_rms(&level, &b, &each);
    assert!(err > 0.0 && err < 0.01, "interpolation error {err}");
    // Exhaustive bakes gather every pixel.
    assert!(!skipped(
        &run(&level, Quality::Draft, Some(40.0), true),
        "pixels"
    ));
}

/// Slivers (docs/transport.md, Slivers): on a field of one-pixel dots each
/// patch's smallest form factors are left out, the row of `F` keeps the sum
/// of the whole raw row, `D F` stays symmetric, and the light moves by far
/// less than the bound allows; an exhaustive bake leaves none out.
#[test]
fn slivers_keep_row_sums_and_reciprocity_and_move_little_light() {
    use flatbake_core::bake::Scene;
    use flatbake_core::transport::{form_factors, kernel::Reach};
    use flatbake_core::visibility::Structures;
    let (level, _) = flatbake_synth::dots(96, 5).level().expect("palette");
    let knobs = Quality::Normal.knobs();
    let scene = Scene::new(&level, &knobs, false);
    let (g, p) = (&scene.geometry, &scene.patches);
    let reach = Reach::unlimited(g.edges.len());
    let structures = Structures::new(g);
    let (whole, _, _) = form_factors(&structures, p, knobs.quad, None, &reach, 0.0);
    let (thin, _, _) = form_factors(&structures, p, knobs.quad, None, &reach, knobs.reach_bound);
    assert_eq!(whole.dropped, 0);
    assert!(thin.dropped > 0, "a dots field has slivers");
    assert!(thin.nnz() < whole.nnz());
    let mut worst: f64 = 0.0;
    for i in 0..p.len() {
        let sum = |f: &flatbake_core::transport::FormFactors| f.row(i).map(|e| e.1).sum::<f64>();
        let (a, b) = (sum(&whole), sum(&thin));
        assert!((a - b).abs() <= 1e-12 * a.max(1.0), "row {i}: {a} vs {b}");
        for (j, f) in thin.row(i) {
            let (x, y) = (thin.dlen[i] * f, thin.dlen[j] * thin.get(j, i));
            assert!(
                (x - y).abs() <= 1e-12 * x.max(y),
                "D F at ({i}, {j}): {x} vs {y}"
            );
        }
        // How far the row moved, as a share of its sum: what it left out,
        // what the rows it lost transposes to left out, and the share both
        // give the rest.
        let moved: f64 = whole.row(i).map(|(j, f)| (f - thin.get(i, j)).abs()).sum();
        worst = worst.max(moved / sum(&whole).max(1e-300));
    }
    eprintln!(
        "slivers: {} of {} entries left out, rows moved by at most {worst:e} of their sums",
        thin.dropped,
        whole.nnz()
    );
    assert!(
        worst < 100.0 * knobs.reach_bound,
        "a row moved by {worst:e} of its sum"
    );
    let s = Settings::new(Quality::Normal);
    let b = bake(&level, &s, &|_| {}).expect("bakes");
    assert!(skipped(&b, "slivers"), "{:?}", b.report.skipped);
    let mut none = s.clone();
    none.knobs.reach_bound = 0.0;
    let full = bake(&level, &none, &|_| {}).expect("bakes");
    assert!(!skipped(&full, "slivers"));
    let d = rel_rms(&level, &b, &full);
    assert!(d < 1e-4, "slivers moved the light by {d:e} relative RMS");
}

/// Form-factor reach in passes (docs/transport.md, Reach and culling): on
/// a field of one-pixel dots with falloff, whose light fades within a few
/// dots of the lamps, the form factors follow each edge's solved light.
/// The report says how many passes were run. The factors are far fewer
/// than at a unit of radiosity, and the light moves by far less than
/// `normal`'s error budget. The energy still balances, and nothing is NaN.
/// Without falloff, no passes are run.
#[test]
fn form_factor_reach_follows_the_solved_light() {
    let (level, palette) = flatbake_synth::dots(96, 5).level().expect("palette");
    let mut s = Settings::new(Quality::Normal);
    s.falloff = palette.settings.falloff;
    assert!(s.falloff.is_some(), "the dots have falloff");
    s.reach_passes_from = 0;
    let passes = bake(&level, &s, &|_| {}).expect("bakes");
    let mut unit = s.clone();
    unit.reach_passes_from = u64::MAX;
    let whole = bake(&level, &unit, &|_| {}).expect("bakes");
    assert!(
        skipped(&passes, "form-factor reach"),
        "{:?}",
        passes.report.skipped
    );
    assert!(!skipped(&whole, "form-factor reach"));
    assert!(
        passes
            .report
            .skipped
            .iter()
            .any(|s| s.effect == "form-factor reach" && s.reason.contains("calls for")),
        "the passes did not fall back to a unit of radiosity: {:?}",
        passes.report.skipped
    );
    let (few, all) = (
        passes.report.counts.form_factor_entries,
        whole.report.counts.form_factor_entries,
    );
    eprintln!("form-factor entries: {few} with passes, {all} at a unit of radiosity");
    assert!(5 * few < all, "{few} entries vs {all}");
    assert!(
        passes
            .lightmap
            .rgb
            .iter()
            .all(|p| p.iter().all(|v| v.is_finite()))
    );
    let d = rel_rms(&level, &passes, &whole);
    eprintln!("passes moved the light by {d:e} relative RMS");
    assert!(d > 0.0 && d < 2e-3, "passes moved the light by {d:e}");
    let e = &passes.report.energy;
    assert!(
        (e.emitted - e.absorbed - e.escaped).abs() <= 1e-6 * e.emitted,
        "{e:?}"
    );
    // No falloff: every factor is computed, as without passes.
    let mut none = s.clone();
    none.falloff = None;
    let flat = bake(&level, &none, &|_| {}).expect("bakes");
    assert!(!skipped(&flat, "form-factor reach"));
}
