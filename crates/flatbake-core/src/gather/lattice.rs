//! The interpolated gather (`draft` and `normal`): light gathered exactly
//! on a lattice of every eighth pixel, and in between only where the
//! lattice says it is needed (docs/transport.md#interpolated-gather).
//!
//! Floor light is smooth except across the shadow lines of walls and near
//! lit edges. A cell of the lattice (8 x 8 pixels between four lattice
//! points, all of them floor of one free region) is gathered at its four
//! corners, its centre and the middles of its sides. Where each of those
//! probes' exact light is within the tolerance of the mean of the corners
//! it lies between, and all nine have the same
//! signature (the same lights that add at least [`SHADOWS`] times the
//! tolerance, cut by the same shadow lines: no hard shadow
//! edge of their direct light between them), the cell's other pixels are interpolated
//! bilinearly from the corners. Every other cell is split into four cells
//! of 4 x 4 pixels, tested the same way, and those that fail are gathered
//! pixel by pixel (`draft` first tries cells of 2 px tested at their
//! corners only, [`COARSE`]). So a smooth open floor costs two exact pixels
//! in 64, and a level of one-pixel walls costs what an exact gather does. What it misses is
//! detail smaller than the cell that neither the centre nor the corners
//! touch, such as a shadow line no wider than a pixel running between them:
//! the error is measured per class of level in docs/performance.md. At
//! `normal` a trial on a sparse grid of cells first decides whether the
//! lattice pays at all ([`TRIAL`]).

use crate::visibility::VisitStats;

use super::fast::{Exact, Gather, GatherCounts};
use super::local;
pub use super::local::{ANCHOR, NEAR};

/// Lattice spacings, coarsest first, in pixels: a cell that fails its test
/// is split into cells of the next spacing, and after the last one gathered
/// pixel by pixel.
pub const STEPS: [i32; 2] = [8, 4];

/// With [`GatherOptions::coarse`](super::GatherOptions::coarse) (`draft`),
/// a last spacing whose cells are tested only at their corners: a cell of
/// this side (3 x 3 pixels, and the ring of pixels around them, floor of
/// one free region) that no coarser cell interpolated is gathered at its
/// four corners, and interpolated in between where they agree within
/// [`SPREAD`]. So about one pixel in four is gathered where the coarser
/// cells failed; a shadow line that passes between the corners without
/// changing them by more than that is blurred over the cell. Walls are
/// never crossed, and no interpolated pixel is beside one.
pub const COARSE: i32 = 2;

/// See [`COARSE`]: the largest difference between a cell's corners, as a
/// fraction of the largest, in every component. A hard shadow line or the
/// steep light near a lamp fails it, and the cell is gathered.
pub const SPREAD: f64 = 0.2;

/// At `normal`, a trial comes first: the 8 px cells on a grid of every
/// `TRIAL`th cell along each axis are gathered and tested; where fewer than
/// [`MIN_PASSED`] of them pass, the level is gathered as without the
/// lattice.
pub const TRIAL: i32 = 4;

/// See [`TRIAL`]. Measured share of 8 px cells passing: 2048 px benchmark
/// 71 %, shooter map and courtyard 7 %, light field 0.3 %. Where few pass,
/// the lattice's passes over scattered probes cost more per pixel than one
/// pass over every pixel (courtyard and light field 8 % slower, same run),
/// and its 4 px cells save too little to make up for it.
pub const MIN_PASSED: f64 = 0.25;

/// The share of a pixel's light, as a multiple of the lattice tolerance,
/// below which a light's shadow lines do not stop a cell from being
/// interpolated (the signature in `gather/fast.rs`): a hard shadow line of a light
/// that adds more than twice the tolerance across it already fails the
/// probes' test where it passes between them, so the signature only has to
/// catch the shadow lines of brighter lights that slip past the probes
/// (where the light's other changes across the cell cancel the jump).
pub const SHADOWS: f64 = 5.0;

/// Gathers `pixels` through the lattice: see the module docs. A cell is
/// interpolated when, in every component, each probe's light differs from
/// the mean of the corners it lies between by at most `relative` of the
/// larger of the two plus `absolute`. The pixels it gathers go through
/// the block sweeps ([`local::Lists`]): every one (`sweep_every`, `draft`),
/// or those whose full query would walk the level.
pub(super) fn gather(
    exact: &Exact,
    pixels: &[[i32; 2]],
    relative: f64,
    absolute: f64,
    spacing: i32,
    sweep_every: bool,
    coarse: bool,
) -> Gather {
    let g = exact.geometry;
    let (w, h) = (g.width as i32, g.height as i32);
    let k = exact.components();
    // Index of each pixel in `pixels`, by position.
    let at = local::PixelIndex::new(g, pixels);
    let index = |x: i32, y: i32| at.get(x, y);
    let comp = |x: i32, y: i32| g.components[(y * w + x) as usize];
    // A cell of side `step` whose every pixel is one of `pixels`, in one
    // free region.
    let whole = |step: i32, x0: i32, y0: i32| {
        let c = comp(x0, y0);
        (y0..=y0 + step).all(|y| (x0..=x0 + step).all(|x| index(x, y).is_some() && comp(x, y) == c))
    };
    // No cell to interpolate (a level of one-pixel walls): `normal` gathers
    // as it would without the lattice, and without its arrays.
    let fine = STEPS[STEPS.len() - 1];
    let no_cell = !(0..h - fine).step_by(fine as usize).any(|y0| {
        (0..w - fine)
            .step_by(fine as usize)
            .any(|x0| whole(fine, x0, y0))
    });
    if no_cell && !sweep_every {
        drop(at);
        return local::gather_all(exact, pixels, spacing);
    }
    let mut values = vec![0.0; pixels.len() * k];
    // The moments, if asked for, follow the light: copied where it is
    // gathered, interpolated with its weights where it is interpolated.
    let km = if exact.directional { 2 * k } else { 0 };
    let mut moments = vec![0.0; pixels.len() * km];
    let mut signature = vec![0u64; pixels.len()];
    // 0: to gather, 1: gathered, 2: interpolated, 3: interpolated in a
    // cell of the last spacing ([`COARSE`]).
    let mut state = vec![0u8; pixels.len()];
    // Pixels of a cell that failed at the last spacing: gathered at the end
    // even if a neighbouring cell interpolated them.
    let mut exact_too = vec![false; pixels.len()];
    // What the anchors see, for the sweeps of the pixels between them; and
    // how the pixels asked for are gathered: every one through the lists,
    // or only those whose full query would walk the level.
    let mut lists = local::Lists::new(spacing, !sweep_every);
    let (mut stats, mut counts) = (VisitStats::default(), GatherCounts::default());
    let mut take =
        |lists: &mut local::Lists, want: &[usize], sigs: Option<f64>, out: local::Out| {
            let (s, c) = if sweep_every {
                lists.gather(exact, pixels, &index, want, sigs, out)
            } else {
                lists.gather_walking(exact, pixels, &index, want, sigs, out)
            };
            stats += s;
            counts += c;
        };
    // A cell passes when its probes share a signature and each is within
    // the tolerance of the mean of the corners it lies between: the centre
    // (all four) and the middle of each side (two).
    let test = |probe: &[usize; 9], values: &[f64], signature: &[u64]| {
        let between: [&[usize]; 5] = [&[0, 1, 2, 3], &[0, 1], &[2, 3], &[0, 2], &[1, 3]];
        probe.iter().all(|&i| signature[i] == signature[probe[0]])
            && between.iter().enumerate().all(|(j, of)| {
                let at = probe[4 + j];
                (0..k).all(|c| {
                    let mean =
                        of.iter().map(|&n| values[probe[n] * k + c]).sum::<f64>() / of.len() as f64;
                    let v = values[at * k + c];
                    (v - mean).abs() <= relative * v.max(mean) + absolute
                })
            })
    };
    let rejected = !sweep_every && {
        // The trial ([`TRIAL`]): its probes are gathered as any probe.
        let step = STEPS[0];
        let mut trial = Vec::new();
        for y0 in (0..h - step).step_by((step * TRIAL) as usize) {
            for x0 in (0..w - step).step_by((step * TRIAL) as usize) {
                if whole(step, x0, y0) {
                    trial.push(probes(x0, y0, step).map(|(x, y)| index(x, y).expect("whole")));
                }
            }
        }
        let want: Vec<usize> = trial.iter().flatten().copied().collect();
        want.iter().for_each(|&i| state[i] = 1);
        take(
            &mut lists,
            &want,
            Some(SHADOWS * relative),
            (&mut values, &mut moments, &mut signature, &mut state),
        );
        let pass = trial
            .iter()
            .filter(|p| test(p, &values, &signature))
            .count();
        (pass as f64) < MIN_PASSED * trial.len() as f64
    };
    // Where the trial rejects the lattice, no cell is tested: the last pass
    // gathers every other pixel as without the lattice, the trial's probes
    // keeping their light and its anchors their lists.
    let mut steps: Vec<i32> = if rejected { Vec::new() } else { STEPS.to_vec() };
    if coarse && !rejected {
        steps.push(COARSE);
    }
    // Per spacing so far, the top-left corners of the cells that passed.
    let mut passed: Vec<(i32, std::collections::HashSet<[i32; 2]>)> = Vec::new();
    for (level, &step) in steps.iter().enumerate() {
        // The last spacing of `coarse`: gathered and tested at the corners.
        let corners_only = coarse && step == COARSE;
        let mut cells = Vec::new();
        for y0 in (0..h - step).step_by(step as usize) {
            for x0 in (0..w - step).step_by(step as usize) {
                let inside_passed = passed.iter().any(|(ps, cells)| {
                    cells.contains(&[x0 - x0.rem_euclid(*ps), y0 - y0.rem_euclid(*ps)])
                });
                // A cell tested at its corners only needs floor of its
                // region around it too: a pixel of its side beside a wall
                // or a pillar sees much less than the corners it lies
                // between (one beside a one-pixel pillar was off by 5 % of
                // the brightest light).
                let whole = if corners_only {
                    x0 >= 1 && y0 >= 1 && whole(step + 2, x0 - 1, y0 - 1)
                } else {
                    whole(step, x0, y0)
                };
                if !inside_passed && whole {
                    cells.push([x0, y0]);
                }
            }
        }
        // Probes not gathered yet (an interpolated one is gathered now: the
        // cells that use it need its exact light).
        let mut want: Vec<usize> = Vec::new();
        let gathered_at = if corners_only { 4 } else { 9 };
        for &[x0, y0] in &cells {
            for (x, y) in probes(x0, y0, step).into_iter().take(gathered_at) {
                let i = index(x, y).expect("a whole cell is floor");
                if state[i] != 1 {
                    state[i] = 1;
                    want.push(i);
                }
            }
        }
        take(
            &mut lists,
            &want,
            (!corners_only).then_some(SHADOWS * relative),
            (&mut values, &mut moments, &mut signature, &mut state),
        );
        let last = level + 1 == steps.len();
        let mut now_passed = std::collections::HashSet::new();
        for &[x0, y0] in &cells {
            let probe =
                probes(x0, y0, step).map(|(x, y)| index(x, y).expect("a whole cell is floor"));
            let corner = [probe[0], probe[1], probe[2], probe[3]];
            let smooth = if corners_only {
                corners_agree(&corner, &values, k)
            } else {
                test(&probe, &values, &signature)
            };
            if smooth {
                now_passed.insert([x0, y0]);
            }
            if !smooth && !last {
                continue;
            }
            for y in y0..=y0 + step {
                for x in x0..=x0 + step {
                    let i = index(x, y).expect("a whole cell is floor");
                    if state[i] == 1 {
                        continue;
                    }
                    if !smooth {
                        exact_too[i] = true;
                        continue;
                    }
                    let u = (x - x0) as f64 / step as f64;
                    let v = (y - y0) as f64 / step as f64;
                    let wts = [(1.0 - u) * (1.0 - v), u * (1.0 - v), (1.0 - u) * v, u * v];
                    for c in 0..k {
                        values[i * k + c] = corner
                            .iter()
                            .zip(wts)
                            .map(|(&j, wt)| wt * values[j * k + c])
                            .sum();
                    }
                    for c in 0..km {
                        moments[i * km + c] = corner
                            .iter()
                            .zip(wts)
                            .map(|(&j, wt)| wt * moments[j * km + c])
                            .sum();
                    }
                    state[i] = if corners_only { 3 } else { 2 };
                }
            }
        }
        passed.push((step, now_passed));
    }
    // Last pass: pixels of rough cells, and those in no whole cell.
    let rest: Vec<usize> = (0..pixels.len())
        .filter(|&i| state[i] == 0 || (state[i] >= 2 && exact_too[i]))
        .collect();
    let interpolated = (0..pixels.len())
        .filter(|&i| state[i] >= 2 && !exact_too[i])
        .count();
    exact.done(interpolated);
    // (The last pass asks for no signatures: their memory goes first.)
    drop((signature, exact_too, passed));
    take(
        &mut lists,
        &rest,
        None,
        (&mut values, &mut moments, &mut [], &mut state),
    );
    drop(rest);
    // Every pixel of `rest` is gathered now; less the anchors that the last
    // pass gathered exactly too.
    counts.interpolated = state.iter().filter(|&&s| s >= 2).count() as u64;
    counts.untested = state.iter().filter(|&&s| s == 3).count() as u64;
    Gather {
        values,
        moments,
        stats,
        counts,
    }
}

/// Whether the light at the pixels `corner` agrees within [`SPREAD`] in
/// each of its `k` components (see [`COARSE`]).
fn corners_agree(corner: &[usize; 4], values: &[f64], k: usize) -> bool {
    (0..k).all(|c| {
        let (lo, hi) = corner.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &j| {
            (lo.min(values[j * k + c]), hi.max(values[j * k + c]))
        });
        hi - lo <= SPREAD * hi
    })
}

/// The pixels at which a cell of side `step` at `(x0, y0)` is gathered
/// exactly: its four corners, then its centre and the middles of its top,
/// bottom, left and right sides. (A saddle, curved one way and the other
/// way across, can leave the centre on the interpolation; a side's middle
/// is not.)
fn probes(x0: i32, y0: i32, step: i32) -> [(i32, i32); 9] {
    let (h, s) = (step / 2, step);
    [
        (x0, y0),
        (x0 + s, y0),
        (x0, y0 + s),
        (x0 + s, y0 + s),
        (x0 + h, y0 + h),
        (x0 + h, y0),
        (x0 + h, y0 + s),
        (x0, y0 + h),
        (x0 + s, y0 + h),
    ]
}
