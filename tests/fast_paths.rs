//! The speed-ups recorded in docs/performance.md change no answer: the batched reflected-light
//! kernel against the plain per-patch sum with the library's `atan`, and the
//! sweep's reuse of the previous query's event order against fresh sweeps.
//! The one that trades exactness for speed, gathering distant reflected
//! light in merged pieces, stays within the error bound it promises.

#![allow(clippy::needless_range_loop)]

mod common;
use common::*;

use std::f64::consts::TAU;

use flatbake_core::gather::{Kernel, Lighting, PatchTree, PixelScratch, Radiosity, pixel_light};
use flatbake_core::geometry::trace;
use flatbake_core::level::Level;
use flatbake_core::transport::Patches;
use flatbake_core::transport::kernel::Falloff;
use flatbake_core::visibility::{Span, Sweeper, View, Viewpoint};
use proptest::prelude::*;

/// The flatland lighting of one solved level.
fn lighting<'a>(
    edges: &'a [flatbake_core::geometry::Edge],
    patches: &'a Patches,
    rad: &'a Radiosity,
    tree: &'a PatchTree,
    falloff: Option<Falloff>,
) -> Lighting<'a> {
    Lighting {
        edges,
        patches,
        rad,
        tree,
        falloff,
        kernel: Kernel::Flatland,
    }
}

/// Walls at a random density, a few lights, all floor otherwise.
fn level_strategy() -> impl Strategy<Value = Level> {
    grid_level(
        4..28,
        4..28,
        |v, density| match v % 32 {
            0 => '*',
            v if v < 2 + density * 2 => '#',
            _ => '.',
        },
        || vec![('#', wall(0.5)), ('*', light(4.0, 0.3))],
    )
}

/// `0..n` in an order shuffled by `seed` (Fisher-Yates, xorshift).
fn shuffled(n: usize, seed: u64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    let mut s = seed | 1;
    for i in (1..n).rev() {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        order.swap(i, (s % (i as u64 + 1)) as usize);
    }
    order
}

/// The gather kernel as it was before batching: per piece, library `atan`.
fn reference_light(
    edges: &[flatbake_core::geometry::Edge],
    patches: &Patches,
    rad: &Radiosity,
    falloff: Option<Falloff>,
    p: [f64; 2],
    spans: &[Span],
) -> Vec<f64> {
    let k = rad.components;
    let mut acc = vec![0.0; k];
    for span in spans {
        let ei = span.edge as usize;
        let e = &edges[ei];
        let d = e.front_distance(p);
        let foot = if e.normal.is_vertical_edge() {
            p[1]
        } else {
            p[0]
        };
        let (kf, c) = match falloff {
            Some(f) => {
                let a = f.radius_for_weight(0.5).powi(2);
                let c = (a + d * d).sqrt();
                (d / c, c)
            }
            None => (0.0, 1.0),
        };
        let big_f = |t: f64| (t / d).atan() - kf * (t / c).atan();
        let big_t = |t: f64| {
            let r2 = d * d + t * t;
            if falloff.is_some() {
                0.5 * d * (r2 / (c * c + t * t)).ln()
            } else {
                0.5 * d * r2.ln()
            }
        };
        if rad.edge_emits[ei] {
            let g = (big_f(span.s1 - foot) - big_f(span.s0 - foot)) / TAU;
            for ch in 0..k {
                acc[ch] += rad.edge_emission[ei * k + ch] * g;
            }
        }
        if rad.edge_reflects[ei] {
            let (lo, _) = e.extent();
            let h = patches.step[ei];
            let first = patches.first[ei] as usize;
            patches.for_each_piece(edges, span, |pt, a, b| {
                let g0 = (big_f(b - foot) - big_f(a - foot)) / TAU;
                let g1 = (big_t(b - foot) - big_t(a - foot)) / TAU;
                let mid = lo + ((pt - first) as f64 + 0.5) * h;
                for ch in 0..k {
                    let g = rad.slope[pt * k + ch];
                    acc[ch] += (rad.reflected[pt * k + ch] + g * (foot - mid)) * g0 + g * g1;
                }
            });
        }
    }
    acc
}

/// Gathers arbitrary radiosity (two channels, with slopes) over every free
/// pixel of `l` and compares it with [`reference_light`]: within `tolerance`
/// (plus rounding) when patches may merge, to 1e-12 relative when not.
fn check_gather(
    l: &Level,
    patch_len: f64,
    fall: Option<f64>,
    seed: u64,
    tolerance: f64,
) -> Result<(), TestCaseError> {
    let g = trace(l);
    let patches = Patches::new(&g, patch_len);
    let n = patches.len();
    let mut s = seed | 1;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s % 10_000) as f64 / 10_000.0
    };
    // Smooth along each edge with some noise, so that runs do merge.
    let b: Vec<Vec<f64>> = (0..2)
        .map(|_| {
            let base = 5.0 * next();
            (0..n)
                .map(|p| base + 0.01 * p as f64 + next() * next() * next())
                .collect()
        })
        .collect();
    let sl: Vec<Vec<f64>> = (0..2)
        .map(|_| (0..n).map(|_| next() - 0.5).collect())
        .collect();
    let e: Vec<Vec<f64>> = (0..2)
        .map(|_| {
            g.edges
                .iter()
                .map(|ed| l.materials[ed.material as usize].emission[0])
                .collect()
        })
        .collect();
    let rad = Radiosity::new(&patches, &b, &sl, &e);
    let falloff = fall.map(Falloff::new);
    let tree = PatchTree::new(&g.edges, &patches, &rad, 0..2, falloff, tolerance);
    let all: Vec<u32> = (0..g.edges.len() as u32).collect();
    let mut sw = Sweeper::new();
    let mut spans = Vec::new();
    // One scratch for every pixel, as a gather thread uses it.
    let mut scratch = PixelScratch::new();
    for y in 0..l.height {
        for x in 0..l.width {
            let Some(comp) = g.component_at(x as i64, y as i64) else {
                continue;
            };
            let p = [x as f64 + 0.5, y as f64 + 0.5];
            spans.clear();
            sw.sweep(
                &g.edges,
                &all,
                Viewpoint::new(p, View::Full, comp),
                &mut spans,
            );
            let mut acc = vec![0.0; 2];
            pixel_light(
                &lighting(&g.edges, &patches, &rad, &tree, falloff),
                p,
                &spans,
                &mut acc,
                &mut scratch,
            );
            let want = reference_light(&g.edges, &patches, &rad, falloff, p, &spans);
            for ch in 0..2 {
                let allowed = tolerance + 1e-12 * (1.0 + want[ch].abs());
                prop_assert!(
                    (acc[ch] - want[ch]).abs() <= allowed,
                    "pixel ({}, {}) channel {}: {} vs {} (tolerance {})",
                    x,
                    y,
                    ch,
                    acc[ch],
                    want[ch],
                    tolerance
                );
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(60))]

    #[test]
    fn batched_kernel_matches_the_per_patch_sum(
        l in level_strategy(),
        patch_len in prop_oneof![Just(0.25), Just(1.0), Just(4.0)],
        fall in prop_oneof![Just(None), Just(Some(3.0)), Just(Some(40.0))],
        seed in any::<u64>(),
    ) {
        check_gather(&l, patch_len, fall, seed, 0.0)?;
    }

    /// With a tolerance, every pixel stays within it of the exact sum (the
    /// bound holds for the total, whatever the number of merged pieces).
    #[test]
    fn merged_patches_stay_within_the_tolerance(
        l in level_strategy(),
        patch_len in prop_oneof![Just(0.25), Just(1.0)],
        fall in prop_oneof![Just(None), Just(Some(3.0)), Just(Some(10.0))],
        tolerance in prop_oneof![Just(1e-4), Just(1e-2), Just(0.3)],
        seed in any::<u64>(),
    ) {
        check_gather(&l, patch_len, fall, seed, tolerance)?;
    }

    /// A pixel's light does not depend on the pixels its scratch served
    /// before (the patch trees are cut per tile and cached): scan order and
    /// a shuffled order give the same bits.
    #[test]
    fn pixel_light_does_not_depend_on_the_previous_pixel(
        l in level_strategy(),
        fall in prop_oneof![Just(None), Just(Some(6.0))],
        seed in any::<u64>(),
    ) {
        let g = trace(&l);
        let patches = Patches::new(&g, 1.0);
        let n = patches.len();
        let b: Vec<Vec<f64>> = vec![(0..n).map(|p| 1.0 + 0.01 * p as f64).collect()];
        let sl: Vec<Vec<f64>> = vec![(0..n).map(|p| 0.001 * (p % 7) as f64).collect()];
        let e: Vec<Vec<f64>> = vec![g.edges.iter().map(|ed| l.materials[ed.material as usize].emission[0]).collect()];
        let rad = Radiosity::new(&patches, &b, &sl, &e);
        let falloff = fall.map(Falloff::new);
        let tree = PatchTree::new(&g.edges, &patches, &rad, 0..1, falloff, 1e-3);
        let all: Vec<u32> = (0..g.edges.len() as u32).collect();
        let mut sw = Sweeper::new();
        let mut points = Vec::new();
        for y in 0..l.height {
            for x in 0..l.width {
                if let Some(comp) = g.component_at(x as i64, y as i64) {
                    let p = [x as f64 + 0.5, y as f64 + 0.5];
                    let mut spans = Vec::new();
                    sw.sweep(&g.edges, &all, Viewpoint::new(p, View::Full, comp), &mut spans);
                    points.push((p, spans));
                }
            }
        }
        let light = |order: &[usize]| {
            let mut scratch = PixelScratch::new();
            let mut out = vec![0.0; points.len()];
            for &i in order {
                let mut acc = [0.0];
                pixel_light(&lighting(&g.edges, &patches, &rad, &tree, falloff), points[i].0, &points[i].1, &mut acc, &mut scratch);
                out[i] = acc[0];
            }
            out
        };
        let scan: Vec<usize> = (0..points.len()).collect();
        let (a, b) = (light(&scan), light(&shuffled(points.len(), seed)));
        for i in 0..a.len() {
            prop_assert_eq!(a[i].to_bits(), b[i].to_bits(), "point {:?}", points[i].0);
        }
        // A scratch that served another tree (the same edges, other light:
        // a later bake on the same thread) cuts this one afresh.
        let b2: Vec<Vec<f64>> = vec![(0..n).map(|p| 3.0 - 0.02 * (p % 11) as f64).collect()];
        let rad2 = Radiosity::new(&patches, &b2, &sl, &e);
        let tree2 = PatchTree::new(&g.edges, &patches, &rad2, 0..1, falloff, 1e-3);
        let mut used = PixelScratch::new();
        for (p, spans) in &points {
            let (mut first, mut second, mut fresh) = ([0.0], [0.0], [0.0]);
            pixel_light(&lighting(&g.edges, &patches, &rad, &tree, falloff), *p, spans, &mut first, &mut used);
            pixel_light(&lighting(&g.edges, &patches, &rad2, &tree2, falloff), *p, spans, &mut second, &mut used);
            pixel_light(&lighting(&g.edges, &patches, &rad2, &tree2, falloff), *p, spans, &mut fresh, &mut PixelScratch::new());
            prop_assert_eq!(second[0].to_bits(), fresh[0].to_bits(), "point {:?}", p);
        }
    }

    #[test]
    fn sweeps_do_not_depend_on_the_previous_query(l in level_strategy(), seed in any::<u64>()) {
        let g = trace(&l);
        let all: Vec<u32> = (0..g.edges.len() as u32).collect();
        let mut points = Vec::new();
        for y in 0..l.height {
            for x in 0..l.width {
                if let Some(comp) = g.component_at(x as i64, y as i64) {
                    points.push(([x as f64 + 0.5, y as f64 + 0.5], comp));
                }
            }
        }
        // Fresh sweeper per point, in scan order.
        let fresh: Vec<Vec<Span>> = points
            .iter()
            .map(|&(p, comp)| {
                let mut out = Vec::new();
                Sweeper::new().sweep(&g.edges, &all, Viewpoint::new(p, View::Full, comp), &mut out);
                out
            })
            .collect();
        // One sweeper reused over the points in a shuffled order.
        let order = shuffled(points.len(), seed);
        let mut sw = Sweeper::new();
        for &i in &order {
            let (p, comp) = points[i];
            let mut out = Vec::new();
            sw.sweep(&g.edges, &all, Viewpoint::new(p, View::Full, comp), &mut out);
            prop_assert_eq!(&out, &fresh[i], "point {:?}", p);
        }
    }
}
