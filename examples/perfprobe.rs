//! Profiling probe: one bigger maze-like level at normal quality.
use flatbake::bake::{Settings, bake};
use flatbake::level::{Cell, Level};
use flatbake::material::{Material, MaterialKind};
use flatbake::quality::Quality;
fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(256);
    let mat = |r: f64, e: f64| Material {
        color: [0, 0, 0],
        kind: if e > 0.0 {
            MaterialKind::Emitter
        } else {
            MaterialKind::Wall
        },
        reflectance: [r; 3],
        emission: [e; 3],
        group: None,
        line: None,
    };
    let f = |x: usize, y: usize| -> Option<u16> {
        if x == 0 || y == 0 || x == n - 1 || y == n - 1 {
            return Some(0);
        }
        if x % 9 == 0 && (y / 9 + x / 9) % 3 != 0 && y % 9 != 4 {
            return Some(if y % 17 == 3 { 1 } else { 0 });
        }
        if y % 9 == 0 && (x / 9 * 7 + y / 9) % 4 != 0 && x % 9 != 5 {
            return Some(0);
        }
        None
    };
    let mut cells = vec![];
    for y in 0..n {
        for x in 0..n {
            cells.push(f(x, y).map_or(Cell::Floor, Cell::Solid));
        }
    }
    let lvl = Level {
        name: "m".into(),
        width: n,
        height: n,
        albedo: vec![[0.5; 3]; n * n],
        cells,
        materials: vec![mat(0.6, 0.0), mat(0.0, 6.0)],
        warnings: vec![],
    };
    let b = bake(&lvl, &Settings::new(Quality::Normal), &|_| {}).unwrap();
    println!(
        "{:?} edges {} patches {}",
        b.report.timings, b.report.counts.edges, b.report.counts.patches
    );
}
