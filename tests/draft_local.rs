//! The gather's shortcuts against the same preset gathered by a full query
//! at every pixel: `draft`'s interpolated lattice and the block sweeps of
//! `draft` and `normal` (gather/local.rs) must stay within a fraction of a
//! percent, and a pixel beside a wall must never see through it.

mod common;
use common::*;

use flatbake_core::Material;
use flatbake_core::bake::{Baked, Settings, bake};
use flatbake_core::level::{Cell, Level};
use flatbake_core::quality::Quality;

fn quiet(_: &str) {}

/// A room full of pillars and thin walls, lit by three small lights: most
/// lattice cells are crossed by shadow lines, so most pixels are swept.
fn pillared_room() -> Level {
    pillared_room_of(wall(0.6), light(4.0, 0.3))
}

/// [`pillared_room`] with these walls and lights.
fn pillared_room_of(walls: Material, lights: Material) -> Level {
    let (w, h) = (112, 72);
    let mut rows = room(w, h);
    let mut put = |x: usize, y: usize, c: char| rows[y].replace_range(x..x + 1, &c.to_string());
    for (i, (x, y)) in [
        (9, 7),
        (21, 30),
        (33, 12),
        (46, 27),
        (58, 9),
        (61, 34),
        (15, 20),
    ]
    .into_iter()
    .enumerate()
    {
        let side = 1 + i % 3;
        for dy in 0..side {
            for dx in 0..side {
                put(x + dx, y + dy, '#');
            }
        }
    }
    // A grove of one-pixel pillars: enough edges that a full query walks
    // the level's blocks instead of sweeping its tile's short list, which
    // is where the block sweeps take over.
    for y in (3..h - 3).step_by(7) {
        for x in (3..w - 3).step_by(6) {
            if (x + y) % 4 != 0 {
                put(x, y, '#');
            }
        }
    }
    // A thin wall with a door: pixels beside it must not see through it.
    for y in 4..h - 4 {
        if !(18..22).contains(&y) {
            put(40, y, '#');
        }
    }
    for (x, y) in [(6, 30), (28, 5), (52, 20)] {
        for dy in 0..2 {
            for dx in 0..2 {
                put(x + dx, y + dy, 'L');
            }
        }
    }
    let rows = refs(&rows);
    ascii(&rows, &[('#', walls), ('L', lights)])
}

fn red(b: &Baked, lvl: &Level) -> Vec<Option<f64>> {
    lvl.cells
        .iter()
        .zip(&b.lightmap.rgb)
        .map(|(c, v)| (*c == Cell::Floor).then_some(v[0] as f64))
        .collect()
}

/// How far floor pixels `a` are from `b`: `b`'s brightest value, the
/// relative RMS, and the largest difference as a share of that brightest
/// value, with its pixel.
fn off(a: &[Option<f64>], b: &[Option<f64>]) -> (f64, f64, (f64, usize)) {
    let top = b.iter().flatten().copied().fold(0.0, f64::max);
    assert!(top > 0.0);
    let (mut sq, mut norm, mut worst) = (0.0, 0.0, (0.0, 0));
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        let (Some(x), Some(y)) = (x, y) else { continue };
        sq += (x - y) * (x - y);
        norm += y * y;
        let d = (x - y).abs() / top;
        if d > worst.0 {
            worst = (d, i);
        }
    }
    (top, (sq / norm).sqrt(), worst)
}

#[test]
fn draft_sweeps_stay_close_to_the_exact_draft_gather() {
    close_to_exact(Quality::Draft);
}

/// `normal` sweeps the pixels whose full query would walk the level's
/// blocks over what the anchors around their block see.
#[test]
fn normal_sweeps_stay_close_to_the_exact_normal_gather() {
    close_to_exact(Quality::Normal);
}

/// `quality`'s bake of `lvl`, and the same preset gathered by a full query
/// at every pixel (no lattice, no block sweeps).
fn fast_and_exact(lvl: &Level, quality: Quality) -> (Baked, Baked) {
    let fast = bake(lvl, &Settings::new(quality), &quiet).unwrap();
    let mut s = Settings::new(quality);
    s.knobs.lattice = None;
    s.knobs.anchors = None;
    (fast, bake(lvl, &s, &quiet).unwrap())
}

/// `quality`'s bake of the pillared room against the same preset gathered
/// by a full query at every pixel.
fn close_to_exact(quality: Quality) {
    let lvl = pillared_room();
    let (fast, exact) = fast_and_exact(&lvl, quality);
    // The sweeps ran, and the report says so.
    let swept = fast
        .report
        .skipped
        .iter()
        .find(|k| k.reason.contains("gathered with a sweep"))
        .expect("the report names the swept pixels");
    let n: usize = swept.reason.split(' ').next().unwrap().parse().unwrap();
    assert!(n > 500, "only {n} pixels swept: {}", swept.reason);
    // `draft` interpolates 2 px cells between their corners where the
    // larger cells fail (most of this room), and says how many.
    let cells = fast
        .report
        .skipped
        .iter()
        .find(|k| k.reason.contains("cells of 2 px"));
    if quality == Quality::Draft {
        let cells = cells.expect("the report names the 2 px cells");
        let m: usize = cells.reason.split(' ').next().unwrap().parse().unwrap();
        assert!(m > 500, "only {m} pixels in 2 px cells: {}", cells.reason);
    } else {
        assert!(cells.is_none(), "{quality} has no 2 px cells");
    }
    let (a, b) = (red(&fast, &lvl), red(&exact, &lvl));
    let (top, rms, worst) = off(&a, &b);
    eprintln!("{quality}: {n} pixels swept, relative RMS {rms}, worst {worst:?}");
    if std::env::var_os("DRAFT_DEBUG").is_some() {
        let w = lvl.width;
        let mut v: Vec<(f64, usize, f64, f64)> = a
            .iter()
            .zip(&b)
            .enumerate()
            .filter_map(|(i, (x, y))| {
                Some(((x.as_ref()? - y.as_ref()?).abs() / top, i, (*x)?, (*y)?))
            })
            .collect();
        v.sort_by(|p, q| q.0.total_cmp(&p.0));
        for (d, i, x, y) in v.iter().take(40) {
            eprintln!(
                "({}, {}) {quality} {x:.4} exact {y:.4} off {d:.4}",
                i % w,
                i / w
            );
        }
        for y in 0..lvl.height {
            let row: String = (0..w)
                .map(|x| {
                    let i = y * w + x;
                    match (a[i], b[i]) {
                        (Some(p), Some(q)) => {
                            let d = (p - q).abs() / top;
                            if d > 0.02 {
                                '@'
                            } else if d > 0.005 {
                                '+'
                            } else if d > 1e-6 {
                                '.'
                            } else {
                                ' '
                            }
                        }
                        _ => '#',
                    }
                })
                .collect();
            eprintln!("{row}");
        }
    }
    // Interpolation is within 2 % of a cell's corners (`draft`'s 2 px
    // cells: corners within 20 % of each other, so a shadow line that
    // changes them less is blurred); the sweeps are exact wherever the
    // block's list holds what the pixel sees, but for the light reflected
    // from beyond `Knobs::far`, interpolated between the block's corners.
    // A pixel seeing through a wall would be off by a good part of the
    // brightest light. Measured: `normal` (the ring of anchors on each
    // list) 0.09 % and 0.3 % of the brightest light without the far
    // interpolation, 0.51 % and 0.58 % with it in the sweeps, 0.61 % and
    // 0.75 % with it also for the pixels beside a pillar (0.71 % and 1.0 %
    // in the sweeps alone without scaling it by the angle a pixel has
    // open: the far light that a pillar beside a pixel hides from it), then
    // 0.77 % and 0.75 % where a pixel beside a pillar walks near rather than
    // sweep a 2 px block (0.71 % alone) and a block whose list is not worth
    // cutting still takes its far light from its corners (0.68 % alone);
    // `draft` (the block's corners only, 8 px blocks, 2 px cells) 1.6 % and
    // 3.9 % without the far interpolation, 2.0 % and 4.1 % with it (0.69 %
    // and 3.4 % with 4 px blocks and without the 2 px cells); with each
    // block's list cut to what one corner sees, 6.2 % and 23 %.
    let (rms_max, worst_max) = match quality {
        Quality::Draft => (0.025, 0.05),
        _ => (0.0085, 0.02),
    };
    assert!(rms < rms_max, "relative RMS {rms}");
    assert!(
        worst.0 < worst_max,
        "pixel {} off by {} of the brightest light",
        worst.1,
        worst.0
    );
}

/// Wall noise at `draft`: a swept pixel whose block's corners see past
/// the far split only through a few narrow gaps takes their far light
/// scaled by its open angle over theirs, at most `gather::FAR_SCALE`
/// times, not spread over its own much wider view. On this level,
/// without the cap, a pixel came out 14 % of the brightest light off the
/// exact `draft` gather (at full size, one ten times too bright); with
/// it, 1.4 %.
#[test]
fn draft_far_light_in_wall_noise_stays_near_the_exact_gather() {
    let (lvl, _) = flatbake_synth::noise(128, 0.1, 4, 2).level().unwrap();
    let (fast, exact) = fast_and_exact(&lvl, Quality::Draft);
    let (_, rms, worst) = off(&red(&fast, &lvl), &red(&exact, &lvl));
    assert!(
        worst.0 < 0.05,
        "pixel ({}, {}) off by {} of the brightest light (relative RMS {rms})",
        worst.1 % lvl.width,
        worst.1 / lvl.width,
        worst.0
    );
}

/// The far split of block sweeps (`Knobs::far`: a swept pixel's light
/// reflected from beyond a distance interpolated between its block's
/// corners, and only the edges that can hide a light swept beyond it)
/// keeps direct light exact: with black walls and lights, so that there is
/// no reflected light, a bake with it matches at every pixel a bake whose
/// split lies at an infinite distance (the same pixels walked, swept and
/// anchored, with whole lists and nothing interpolated). An edge that
/// hides a light and is wrongly left off a list shows as light where
/// there is shadow. (Without the lattice, whose interpolation would blur
/// both.)
#[test]
fn far_split_keeps_direct_light_exact() {
    let lvl = pillared_room_of(wall(0.0), light(4.0, 0.0));
    for quality in [Quality::Draft, Quality::Normal] {
        let mut s = Settings::new(quality);
        s.knobs.lattice = None;
        // Short, so that most of each list is far.
        s.knobs.far = Some(4.0);
        let split = bake(&lvl, &s, &quiet).unwrap();
        let said = split
            .report
            .skipped
            .iter()
            .find(|k| k.effect == "far reflected light")
            .expect("the report names the far split");
        let n: usize = said.reason.split(' ').next().unwrap().parse().unwrap();
        assert!(n > 300, "{quality}: only {n} pixels split: {}", said.reason);
        s.knobs.far = None;
        let whole = bake(&lvl, &s, &quiet).unwrap();
        assert!(
            !whole
                .report
                .skipped
                .iter()
                .any(|k| k.effect == "far reflected light"),
            "{quality}: no split without the knob"
        );
        s.knobs.far = Some(f64::INFINITY);
        let whole = bake(&lvl, &s, &quiet).unwrap();
        same_light(&split, &whole, &lvl, &quality.to_string());
    }
}

/// Every floor pixel of `split` reads what it reads in `whole`, up to
/// rounding (`what` names the bakes in a failure).
fn same_light(split: &Baked, whole: &Baked, lvl: &Level, what: &str) {
    same_light_where(split, whole, lvl, what, |_| true);
}

/// [`same_light`] at the floor pixels (by index) that `keep` names, up to
/// the rounding of `whole`'s brightest floor pixel; how many it compared.
fn same_light_where(
    split: &Baked,
    whole: &Baked,
    lvl: &Level,
    what: &str,
    keep: impl Fn(usize) -> bool,
) -> usize {
    let (a, b) = (red(split, lvl), red(whole, lvl));
    let top = b.iter().flatten().copied().fold(0.0, f64::max);
    assert!(top > 0.0);
    let mut compared = 0;
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        let (Some(x), Some(y)) = (x, y) else { continue };
        if !keep(i) {
            continue;
        }
        compared += 1;
        assert!(
            (x - y).abs() <= 1e-9 * top,
            "{what}: pixel ({}, {}) {x} with the split, {y} without",
            i % lvl.width,
            i / lvl.width
        );
    }
    compared
}

/// A grove of one-pixel pillars standing on the anchors' grid (every
/// eighth pixel, offset by four), three lamps: a dense level whose pixels
/// beside a pillar have a corner of their 4 px block in it, so they walk
/// near and take their far reflected light from the other three corners.
fn grove_on_the_grid(walls: Material, lights: Material) -> Level {
    grove_of(96, 64, walls, lights)
}

/// [`grove_on_the_grid`], `w` by `h` pixels (its lamps where they are).
fn grove_of(w: usize, h: usize, walls: Material, lights: Material) -> Level {
    let mut rows = room(w, h);
    let mut put = |x: usize, y: usize, c: char| rows[y].replace_range(x..x + 1, &c.to_string());
    for y in (4..h - 2).step_by(8) {
        for x in (4..w - 2).step_by(8) {
            put(x, y, '#');
        }
    }
    for (x, y) in [(21, 13), (61, 41), (45, 25)] {
        for dy in 0..2 {
            for dx in 0..2 {
                put(x + dx, y + dy, 'L');
            }
        }
    }
    let rows = refs(&rows);
    ascii(&rows, &[('#', walls), ('L', lights)])
}

/// On [`grove_on_the_grid`], `normal` stays within a fraction of a
/// percent of its exact gather, and its far split keeps direct light
/// exact (black walls: a bake with the split at 4 px matches one with it
/// at an infinite distance at every pixel).
#[test]
fn pillars_on_block_corners_take_far_light_from_the_other_three() {
    let lvl = grove_on_the_grid(wall(0.6), light(4.0, 0.3));
    let fast = bake(&lvl, &Settings::new(Quality::Normal), &quiet).unwrap();
    let mut s = Settings::new(Quality::Normal);
    s.knobs.lattice = None;
    s.knobs.anchors = None;
    let exact = bake(&lvl, &s, &quiet).unwrap();
    let (_, rms, (worst, _)) = off(&red(&fast, &lvl), &red(&exact, &lvl));
    eprintln!("grove: relative RMS {rms}, worst {worst} of the brightest");
    // Measured: 0.63 % and 0.63 % of the brightest light; 0.28 % and
    // 0.47 % where such pixels took a full query or swept a 2 px block,
    // whose corners each needed a full walk. The far light that the
    // pillar beside a pixel hides from it, not from its corners, is most
    // of the difference (the open angle scales it as if it came evenly
    // from every direction).
    assert!(rms < 0.007, "relative RMS {rms}");
    assert!(
        worst < 0.008,
        "a pixel off by {worst} of the brightest light"
    );

    let lvl = grove_on_the_grid(wall(0.0), light(4.0, 0.0));
    let mut s = Settings::new(Quality::Normal);
    s.knobs.lattice = None;
    s.knobs.far = Some(4.0);
    let split = bake(&lvl, &s, &quiet).unwrap();
    s.knobs.far = Some(f64::INFINITY);
    let whole = bake(&lvl, &s, &quiet).unwrap();
    same_light(&split, &whole, &lvl, "grove");
}

/// On a dense level, with the far split, the anchors off the lattice four
/// times as coarse walk everywhere within 64 px only, and past it towards
/// the lights alone, widened for the pixels of their blocks (a split at an
/// infinite distance has no such anchors). A long grove with its lamps at
/// one end: most of its pixels see them past 64 px, through the pillars.
/// An edge that hides a lamp from a pixel, left off its block's list,
/// shows as light where there is shadow; with black walls a bake with the
/// split matches one without at every pixel.
#[test]
fn anchors_walking_near_keep_what_hides_a_light() {
    let lvl = grove_of(240, 64, wall(0.0), light(4.0, 0.0));
    let mut s = Settings::new(Quality::Normal);
    s.knobs.lattice = None;
    s.knobs.far = Some(4.0);
    let split = bake(&lvl, &s, &quiet).unwrap();
    let outer = counted(&split, "anchors' far light").expect("the report names the anchors' split");
    assert!(outer > 200, "only {outer} anchors walked near");
    s.knobs.far = Some(f64::INFINITY);
    let whole = bake(&lvl, &s, &quiet).unwrap();
    assert_eq!(counted(&whole, "anchors' far light"), None);
    same_light(&split, &whole, &lvl, "long grove");
}

/// The count that opens the reason the report of `b` gives for skipping
/// `effect` ("anchors' far light": the anchors that walked everywhere only
/// within the outer distance; "far light of many lights": the pixels that
/// took it from their block's corners), if it names that effect.
fn counted(b: &Baked, effect: &str) -> Option<usize> {
    let said = b.report.skipped.iter().find(|k| k.effect == effect)?;
    said.reason.split(' ').next()?.parse().ok()
}

/// On a level of many lights (a block's list holding more than
/// `gather::FAR_LAMPS`), a swept pixel sweeps only the edges within
/// `gather::LAMP_FAR` of its block and takes all the light from beyond,
/// the lights' too, from its block's corners, scaled by the angle it has
/// open past that distance. Against the same preset without the far split
/// (every light gathered exactly at every pixel), on an open field of 100
/// small lights with the generator's falloff: within 0.4 % RMS and 2.5 %
/// of the brightest pixel anywhere. Measured: 0.19 % and 1.75 % (the
/// worst pixel, beside a light, reads the same without the lights' split,
/// which gives 0.23 % RMS); with none of the far light added, 3.3 % RMS.
#[test]
fn many_lights_take_their_far_light_from_the_corners() {
    let (lvl, palette) = flatbake_synth::light_field(256, 100, 43.0, 5)
        .level()
        .expect("the generator's palette parses");
    let mut s = Settings::new(Quality::Normal);
    s.falloff = palette.settings.falloff;
    s.knobs.lattice = None;
    let split = bake(&lvl, &s, &quiet).unwrap();
    let n = counted(&split, "far light of many lights")
        .expect("the report names the lights' far light");
    // And so does its line in a level designer's words.
    let plain = split.report.plain_skips();
    assert!(
        plain.iter().any(|p| p.contains("lamps far away")),
        "{plain:?}"
    );
    let floor = lvl.cells.iter().filter(|c| **c == Cell::Floor).count();
    assert!(2 * n > floor, "only {n} of {floor} pixels");
    s.knobs.far = None;
    let whole = bake(&lvl, &s, &quiet).unwrap();
    assert_eq!(counted(&whole, "far light of many lights"), None);
    let (_, rms, worst) = off(&red(&split, &lvl), &red(&whole, &lvl));
    eprintln!("many lights: relative RMS {rms}, worst {worst:?} of the brightest");
    assert!(rms < 0.004, "relative RMS {rms}");
    assert!(
        worst.0 < 0.025,
        "pixel {} off by {} of the brightest light",
        worst.1,
        worst.0
    );
}

/// A block takes its lights' far light from its corners only where that is
/// at most `gather::LAMP_SHARE` of each corner's light: in a long hall with
/// black walls whose 144 lights stand at one end, the pixels far from all
/// of them (lit only from beyond `gather::LAMP_FAR`) read exactly what they
/// read without the far split, while pixels among the lights take it
/// (without the share's test, those far pixels are interpolated too, and
/// the test fails: checked).
#[test]
fn far_light_of_many_lights_only_where_it_is_a_small_share() {
    let (w, h) = (700, 64);
    let mut rows = room(w, h);
    for x in (4..64).step_by(5) {
        for y in (4..60).step_by(5) {
            rows[y].replace_range(x..x + 1, "L");
        }
    }
    let rows = refs(&rows);
    let lvl = ascii(&rows, &[('#', wall(0.0)), ('L', light(4.0, 0.0))]);
    let mut s = Settings::new(Quality::Normal);
    s.knobs.lattice = None;
    let split = bake(&lvl, &s, &quiet).unwrap();
    let n = counted(&split, "far light of many lights")
        .expect("the report names the lights' far light");
    assert!(n > 1000, "only {n} pixels");
    s.knobs.far = Some(f64::INFINITY);
    let whole = bake(&lvl, &s, &quiet).unwrap();
    let far = same_light_where(&split, &whole, &lvl, "hall", |i| i % w >= 220);
    assert!(far > 5000);
}
