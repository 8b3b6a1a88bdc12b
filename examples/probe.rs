//! Accuracy probe: bakes a few scenes at every preset against reference.
use flatbake::bake::{Settings, bake};
use flatbake::level::{Cell, Level};
use flatbake::material::{Material, MaterialKind};
use flatbake::quality::Quality;
use std::time::Instant;

fn mat(kind: MaterialKind, r: [f64; 3], e: [f64; 3]) -> Material {
    Material {
        color: [0, 0, 0],
        kind,
        reflectance: r,
        emission: e,
        group: None,
        line: None,
    }
}

fn level(
    name: &str,
    w: usize,
    h: usize,
    f: impl Fn(usize, usize) -> Option<u16>,
    mats: Vec<Material>,
) -> Level {
    let mut cells = vec![];
    for y in 0..h {
        for x in 0..w {
            cells.push(match f(x, y) {
                Some(m) => Cell::Solid(m),
                None => Cell::Floor,
            });
        }
    }
    Level {
        name: name.into(),
        width: w,
        height: h,
        albedo: vec![[0.5; 3]; w * h],
        cells,
        materials: mats,
        warnings: vec![],
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let falloff: Option<f64> = args.get(1).and_then(|s| s.parse().ok());
    let wall = |r| mat(MaterialKind::Wall, [r; 3], [0.0; 3]);
    let light = |e| mat(MaterialKind::Emitter, [0.0; 3], [e; 3]);
    let red = mat(MaterialKind::Wall, [0.8, 0.1, 0.1], [0.0; 3]);
    let scenes = vec![
        level(
            "room",
            64,
            48,
            |x, y| {
                if y == 0 && (28..36).contains(&x) {
                    Some(1)
                } else if x == 0 || y == 0 || x == 63 || y == 47 {
                    Some(0)
                } else if (20..28).contains(&x) && (20..30).contains(&y) {
                    Some(0)
                } else if x == 63 - 1 && y > 10 && y < 30 {
                    Some(2)
                } else {
                    None
                }
            },
            vec![wall(0.7), light(4.0), red.clone()],
        ),
        level(
            "mirror98",
            40,
            30,
            |x, y| {
                if x == 0 && y == 15 {
                    Some(1)
                } else if x == 0 || y == 0 || x == 39 || y == 29 {
                    Some(0)
                } else if (10..14).contains(&x) && (10..20).contains(&y) {
                    Some(0)
                } else {
                    None
                }
            },
            vec![wall(0.98), light(1.0)],
        ),
        level(
            "maze",
            64,
            64,
            |x, y| {
                if x == 0 || y == 0 || x == 63 || y == 63 {
                    return Some(0);
                }
                if x % 9 == 0 && (y / 9 + x / 9) % 3 != 0 && y % 9 != 4 {
                    return Some(if y % 17 == 3 { 1 } else { 0 });
                }
                if y % 9 == 0 && (x / 9 * 7 + y / 9) % 4 != 0 && x % 9 != 5 {
                    return Some(0);
                }
                None
            },
            vec![wall(0.6), light(6.0)],
        ),
        level(
            "field",
            80,
            60,
            |x, y| {
                if (x == 10 || x == 11) && (y == 10) {
                    return Some(1);
                }
                if (60..62).contains(&x) && y == 45 {
                    return Some(1);
                }
                let px = [
                    (20, 20, 3, 3),
                    (40, 30, 1, 1),
                    (50, 12, 6, 2),
                    (30, 45, 2, 8),
                    (65, 25, 1, 6),
                ];
                for (a, b, w, h) in px {
                    if x >= a && x < a + w && y >= b && y < b + h {
                        return Some(0);
                    }
                }
                None
            },
            vec![wall(0.5), light(12.0)],
        ),
    ];
    if args.get(2).map(String::as_str) == Some("knobs") {
        let lvl = &scenes[2];
        let mut rs = Settings::new(Quality::Reference);
        rs.falloff = falloff;
        let reference = bake(lvl, &rs, &|_| {}).unwrap();
        for (h, q) in [
            (4.0, 3),
            (4.0, 8),
            (1.0, 3),
            (1.0, 8),
            (0.5, 3),
            (0.25, 8),
            (2.0, 8),
            (4.0, 2),
        ] {
            let mut s = Settings::new(Quality::Normal);
            s.knobs.patch_len = h;
            s.knobs.quad = q;
            s.falloff = falloff;
            let b = bake(lvl, &s, &|_| {}).unwrap();
            let (mut num, mut den) = (0.0, 0.0);
            for (i, c) in lvl.cells.iter().enumerate() {
                if *c != Cell::Floor {
                    continue;
                }
                let (a, r) = (
                    b.lightmap.rgb[i][0] as f64,
                    reference.lightmap.rgb[i][0] as f64,
                );
                num += (a - r) * (a - r);
                den += r * r;
            }
            println!("h {h} q {q}: rel_rmse {:.3e}", (num / den).sqrt());
        }
        return;
    }
    for lvl in &scenes {
        let mut results = vec![];
        for q in Quality::ALL {
            let mut s = Settings::new(q);
            s.falloff = falloff;
            let t = Instant::now();
            let b = bake(lvl, &s, &|_| {}).unwrap();
            results.push((q, t.elapsed().as_secs_f64(), b));
        }
        let reference = &results[3].2;
        for (q, secs, b) in &results {
            let (mut num, mut den, mut maxe) = (0.0, 0.0, 0.0f64);
            for (i, c) in lvl.cells.iter().enumerate() {
                if *c != Cell::Floor {
                    continue;
                }
                for k in 0..3 {
                    let (a, r) = (
                        b.lightmap.rgb[i][k] as f64,
                        reference.lightmap.rgb[i][k] as f64,
                    );
                    num += (a - r) * (a - r);
                    den += r * r;
                    maxe = maxe.max((a - r).abs());
                }
            }
            eprintln!("  {}", timings(b));
            println!(
                "{:9} {:9} patches {:6} nnz {:9} {:7.3}s  rel_rmse {:.3e}  max {:.3e}  solver {} res {:.1e}",
                lvl.name,
                q.name(),
                b.report.counts.patches,
                b.report.counts.form_factor_entries,
                secs,
                (num / den).sqrt(),
                maxe,
                b.report.solver,
                b.report.residual
            );
        }
    }
}
#[allow(dead_code)]
fn timings(b: &flatbake::bake::Baked) -> String {
    format!("{:?}", b.report.timings)
}
