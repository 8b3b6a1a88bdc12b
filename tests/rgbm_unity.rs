//! Unity-convention RGBM (`NAME.lightmap.rgbm-unity.png`): range 5 in gamma
//! space, decoded here with Unity's formula written out independently, and
//! held to the documented error bound.

mod common;
use common::*;

use flatbake_core::bake::{Settings, bake};
use flatbake_core::output::{
    OutputKind, OutputOptions, encode_images, lightmap_pixels, rgbm_unity_decode, rgbm_unity_encode,
};
use flatbake_core::quality::Quality;

/// Unity's decode in gamma space, then to linear: `(rgb * a * 5)^2.2`.
fn unity_decode(p: [u8; 4]) -> [f64; 3] {
    let a = p[3] as f64 / 255.0;
    [0, 1, 2].map(|k| (p[k] as f64 / 255.0 * a * 5.0).powf(2.2))
}

/// The documented bound for channel value `v` of a pixel stored with
/// alpha `a`: `(g + 5 a / 510)^2.2 - g^2.2`, `g` the clamped gamma value.
fn bound(v: f64, a: u8) -> f64 {
    let cap = 5f64.powf(2.2);
    let g = v.clamp(0.0, cap).powf(1.0 / 2.2);
    let step = 5.0 * a as f64 / 255.0 / 510.0;
    (g + step).powf(2.2) - g.powf(2.2) + 1e-6 * (1.0 + v.min(cap))
}

/// Deterministic colours over 1e-4..40 (past the range), in all mixes.
fn colours() -> Vec<[f32; 3]> {
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out: Vec<[f32; 3]> = (0..=200)
        .map(|i| [10f64.powf(-4.0 + 5.6 * i as f64 / 200.0) as f32; 3])
        .collect();
    for _ in 0..20_000 {
        let scale = 10f64.powf(-4.0 + 5.6 * next());
        out.push([0; 3].map(|_| (scale * next()) as f32));
    }
    out.extend([[0.0; 3], [f32::NAN, -1.0, f32::INFINITY], [34.0, 0.0, 1.0]]);
    out
}

#[test]
fn round_trip_within_the_documented_bound() {
    let cap = 5f64.powf(2.2);
    let mut worst_rel = 0f64;
    for c in colours() {
        let p = rgbm_unity_encode(c);
        let got = unity_decode(p);
        let lib = rgbm_unity_decode(p);
        let want = c.map(|v| {
            if v.is_finite() && v > 0.0 {
                (v as f64).min(cap)
            } else {
                0.0
            }
        });
        for k in 0..3 {
            assert!((lib[k] as f64 - got[k]).abs() <= 1e-5 * (1.0 + got[k]));
            let err = (got[k] - want[k]).abs();
            assert!(
                err <= bound(want[k], p[3]),
                "{c:?} channel {k}: decoded {} for {}, error {err} above {}",
                got[k],
                want[k],
                bound(want[k], p[3])
            );
        }
        let max = want[0].max(want[1]).max(want[2]);
        if max >= 0.01 {
            for k in 0..3 {
                worst_rel = worst_rel.max((got[k] - want[k]).abs() / max);
            }
        }
    }
    // At most 0.5 % of the brightest channel from 0.01 up, as documented.
    assert!(worst_rel <= 0.005, "worst relative error {worst_rel}");
    eprintln!("worst error relative to the brightest channel (>= 0.01): {worst_rel:.5}");
}

#[test]
fn the_linear_rgbm_is_not_unity_rgbm() {
    // Decoding today's linear RGBM (range 6) the Unity way is far off, so
    // the test above would catch the wrong convention.
    let p = flatbake_core::output::rgbm_encode([0.5; 3]);
    assert!((unity_decode(p)[0] - 0.5).abs() > 0.1);
}

#[test]
fn the_output_file_holds_the_lightmap() {
    let rows = room(12, 9);
    let lvl = ascii(&refs(&rows), &[('#', light(1.5, 0.5))]);
    let map = bake(&lvl, &Settings::new(Quality::Draft), &|_| {})
        .expect("bake")
        .lightmap;
    let opts = OutputOptions {
        rgbm_unity: true,
        ..OutputOptions::default()
    };
    let files = encode_images(&lvl, &map, &opts).expect("encode");
    let f = files
        .iter()
        .find(|f| f.kind == OutputKind::RgbmUnity)
        .expect("written");
    assert_eq!(f.kind.file_name("room"), "room.lightmap.rgbm-unity.png");
    let img = image::load_from_memory(&f.bytes).expect("png").into_rgba8();
    let hdr = lightmap_pixels(&lvl, &map).expect("hdr");
    for (p, want) in img.pixels().zip(&hdr) {
        let got = unity_decode(p.0);
        for k in 0..3 {
            assert!((got[k] - want[k] as f64).abs() <= bound(want[k] as f64, p.0[3]));
        }
    }
    let without = encode_images(&lvl, &map, &OutputOptions::default()).expect("encode");
    assert!(without.iter().all(|f| f.kind != OutputKind::RgbmUnity));
}
