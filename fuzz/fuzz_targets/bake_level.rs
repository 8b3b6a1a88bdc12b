//! Small levels and materials straight from bytes (no image decoding), so
//! the fuzzer spends its time in geometry, form factors, solve and gather.
//!
//! Input: width, height, flags, then materials (3 bytes each), then one byte
//! per pixel choosing floor, void or a material.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

use flatbake_core::level::{Cell, Level};
use flatbake_core::level::material::{Material, MaterialKind};

/// Values that stress the solver: 0, 1 and nearly 1 reflectance, tiny and huge emission.
const RHO: [f64; 8] = [0.0, 0.25, 0.5, 0.9, 0.98, 0.999, 0.9999, 1.0];
const EMIT: [f64; 8] = [0.0, 1e-6, 1e-3, 0.5, 1.0, 7.0, 1e3, 1e6];
const FALLOFF: [Option<f64>; 4] = [None, Some(0.1), Some(8.0), Some(1e6)];

fuzz_target!(|data: &[u8]| {
    if data.len() < 4 {
        return;
    }
    let w = 1 + data[0] as usize % 24;
    let h = 1 + data[1] as usize % 24;
    let flags = data[2];
    let nmat = 1 + data[3] as usize % 4;
    let rest = &data[4..];
    if rest.len() < nmat * 3 {
        return;
    }
    let mut materials = Vec::new();
    for k in 0..nmat {
        let m = &rest[k * 3..k * 3 + 3];
        let emits = m[0] & 1 == 1;
        let rho = [
            RHO[(m[1] & 7) as usize],
            RHO[((m[1] >> 3) & 7) as usize],
            RHO[(m[1] >> 5) as usize],
        ];
        let e = EMIT[(m[2] & 7) as usize];
        materials.push(Material {
            color: [k as u8, 0, 0],
            kind: if emits {
                MaterialKind::Emitter
            } else {
                MaterialKind::Wall
            },
            reflectance: rho,
            emission: if emits {
                [e, EMIT[((m[2] >> 3) & 7) as usize], e]
            } else {
                [0.0; 3]
            },
            group: None,
            line: None,
        });
    }
    let px = &rest[nmat * 3..];
    let mut cells = Vec::with_capacity(w * h);
    for i in 0..w * h {
        let b = px.get(i).copied().unwrap_or(0);
        cells.push(match b % 8 {
            0..=2 => Cell::Floor,
            3 => Cell::Void,
            k => Cell::Solid(((k as usize - 4) % nmat) as u16),
        });
    }
    let albedo = cells
        .iter()
        .map(|c| {
            if *c == Cell::Floor {
                [0.5; 3]
            } else {
                [0.0; 3]
            }
        })
        .collect();
    let level = Level {
        name: "fuzz".into(),
        width: w,
        height: h,
        cells,
        albedo,
        materials,
        warnings: vec![],
    };
    common::bake_and_check(&level, FALLOFF[(flags & 3) as usize], flags & 4 != 0);
});
