//! Criterion benchmarks of the bake stages (the levels and targets of docs/performance.md). Sample counts are the
//! minimum so `cargo bench` finishes in a few minutes on two cores; the
//! 1024 and 2048 px sizes run only with `FLATBAKE_BENCH_BIG=1` (or use
//! `examples/perf_table.rs`, which prints the README tables for them).
//!
//! * `size/*`: geometry, form factors and the whole bake over level size.
//! * `edges/*`: whole bake at 256 px over the obstacle (edge) count.
//! * `patches/*`: whole bake at 256 px at draft, normal and high quality.
//! * `gather_64/*`: the naive and the fast gather in the same run, on the
//!   64 px level with 40 scattered one-pixel walls and 3 one-pixel lights.

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use flatbake_core::bake::{GatherMethod, Settings, bake};
use flatbake_core::geometry;
use flatbake_core::level::Level;
use flatbake_core::quality::Quality;
use flatbake_core::transport::kernel::{Falloff, Reach};
use flatbake_core::transport::{self, Patches};
use flatbake_core::visibility::Structures;
use flatbake_synth::{self as synth, Painted};

fn level(p: &Painted) -> (Level, Option<f64>) {
    let (level, palette) = p.level().expect("synth palettes parse");
    (level, palette.settings.falloff)
}

fn settings(q: Quality, falloff: Option<f64>) -> Settings {
    let mut s = Settings::new(q);
    s.falloff = falloff;
    s
}

fn sizes(c: &mut Criterion) {
    let mut list = vec![128usize, 256, 512];
    if std::env::var_os("FLATBAKE_BENCH_BIG").is_some() {
        list.extend([1024, 2048]);
    }
    let mut g = c.benchmark_group("size");
    g.sample_size(10).warm_up_time(Duration::from_millis(200));
    for size in list {
        let (lv, falloff) = level(&synth::bench_obstacles(size, 60, 12, 7));
        let s = settings(Quality::Normal, falloff);
        g.bench_with_input(BenchmarkId::new("geometry", size), &lv, |b, lv| {
            b.iter(|| geometry::trace(lv))
        });
        let geo = geometry::trace(&lv);
        let patches = Patches::new(&geo, s.knobs.patch_len);
        let f = falloff.map(Falloff::new);
        let lens: Vec<f64> = geo.edges.iter().map(|e| e.len()).collect();
        let reach = Reach::new(&lens, &vec![1.0; lens.len()], f, 0.5, s.knobs.reach_bound);
        g.bench_with_input(BenchmarkId::new("form_factors", size), &geo, |b, geo| {
            b.iter(|| {
                transport::form_factors(
                    &Structures::new(geo),
                    &patches,
                    s.knobs.quad,
                    f,
                    &reach,
                    s.knobs.reach_bound,
                )
            })
        });
        g.bench_with_input(BenchmarkId::new("bake", size), &lv, |b, lv| {
            b.iter(|| bake(lv, &s, &|_| {}).expect("bench levels bake"))
        });
    }
    g.finish();
}

fn edges(c: &mut Criterion) {
    let mut g = c.benchmark_group("edges");
    g.sample_size(10).warm_up_time(Duration::from_millis(200));
    for obstacles in [15usize, 60, 240] {
        let (lv, falloff) = level(&synth::bench_obstacles(256, obstacles, 12, 7));
        let s = settings(Quality::Normal, falloff);
        let n = geometry::trace(&lv).edges.len();
        g.bench_with_input(BenchmarkId::new("bake_256", n), &lv, |b, lv| {
            b.iter(|| bake(lv, &s, &|_| {}).expect("bench levels bake"))
        });
    }
    g.finish();
}

fn patches(c: &mut Criterion) {
    let mut g = c.benchmark_group("patches");
    g.sample_size(10).warm_up_time(Duration::from_millis(200));
    let (lv, falloff) = level(&synth::bench_obstacles(256, 60, 12, 7));
    for q in [Quality::Draft, Quality::Normal, Quality::High] {
        let s = settings(q, falloff);
        let geo = geometry::trace(&lv);
        let n = Patches::new(&geo, s.knobs.patch_len).len();
        g.bench_with_input(
            BenchmarkId::new(format!("bake_256_{}", q.name()), n),
            &lv,
            |b, lv| b.iter(|| bake(lv, &s, &|_| {}).expect("bench levels bake")),
        );
    }
    g.finish();
}

fn naive_vs_fast(c: &mut Criterion) {
    let mut g = c.benchmark_group("gather_64");
    g.sample_size(10).warm_up_time(Duration::from_millis(200));
    let (lv, _) = level(&synth::bench_scattered(64, 40, 3, 7));
    for (name, method) in [("fast", GatherMethod::Fast), ("naive", GatherMethod::Naive)] {
        let mut s = settings(Quality::Normal, None);
        s.gather = method;
        g.bench_function(name, |b| {
            b.iter(|| bake(&lv, &s, &|_| {}).expect("bench levels bake"))
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    // No plots: plotters needs system fonts, which build machines may lack.
    config = Criterion::default().without_plots();
    targets = naive_vs_fast, sizes, edges, patches
}
criterion_main!(benches);
