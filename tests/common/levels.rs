//! Levels from ASCII art.

use flatbake_core::level::material::{Material, MaterialKind};
use flatbake_core::level::{Cell, Level};

/// A wall material.
pub fn wall(r: f64) -> Material {
    Material {
        color: [0, 0, 0],
        kind: MaterialKind::Wall,
        reflectance: [r; 3],
        emission: [0.0; 3],
        group: None,
        line: None,
    }
}

/// An emitter material.
pub fn light(e: f64, r: f64) -> Material {
    Material {
        color: [255, 255, 255],
        kind: MaterialKind::Emitter,
        reflectance: [r; 3],
        emission: [e; 3],
        group: None,
        line: None,
    }
}

/// Builds a level from rows of characters: `.` floor, ` ` void, and any
/// character listed in `legend` is that solid material.
pub fn ascii(rows: &[&str], legend: &[(char, Material)]) -> Level {
    let h = rows.len();
    let w = rows.iter().map(|r| r.chars().count()).max().unwrap_or(0);
    let mut cells = Vec::with_capacity(w * h);
    let mut albedo = Vec::with_capacity(w * h);
    for r in rows {
        let chars: Vec<char> = r.chars().collect();
        for x in 0..w {
            let ch = chars.get(x).copied().unwrap_or('.');
            let cell = match ch {
                '.' => Cell::Floor,
                ' ' => Cell::Void,
                c => {
                    let i = legend
                        .iter()
                        .position(|(k, _)| *k == c)
                        .unwrap_or_else(|| panic!("no material for {c:?}"));
                    Cell::Solid(i as u16)
                }
            };
            albedo.push(if cell == Cell::Floor {
                [0.5; 3]
            } else {
                [0.0; 3]
            });
            cells.push(cell);
        }
    }
    Level {
        name: "ascii".into(),
        width: w,
        height: h,
        cells,
        albedo,
        materials: legend.iter().map(|(_, m)| m.clone()).collect(),
        warnings: vec![],
        lossy_format: None,
        origin: Default::default(),
        floor_fraction: None,
    }
}

/// A closed rectangular room `w x h` (walls included) of one material.
pub fn room(w: usize, h: usize) -> Vec<String> {
    (0..h)
        .map(|y| {
            (0..w)
                .map(|x| {
                    if x == 0 || y == 0 || x == w - 1 || y == h - 1 {
                        '#'
                    } else {
                        '.'
                    }
                })
                .collect()
        })
        .collect()
}

/// The rows as string slices, for [`ascii`].
pub fn refs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}
