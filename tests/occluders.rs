//! Occluder polygons for live lights: the simplified wall loops stay within
//! their tolerance, keep every corner where loops touch, never cross each
//! other, and land in the output files `bake --occluders` writes.

mod common;
use common::*;

use std::collections::HashMap;
use std::path::Path;

use flatbake_core::geometry::{Geometry, trace};
use flatbake_core::level::Level;
use flatbake_core::output::occluders::{DEFAULT_TOLERANCE, Occluders, simplify_loops};
use proptest::prelude::*;

fn level_strategy() -> impl Strategy<Value = Level> {
    grid_level(
        1..16,
        1..16,
        |v, density| {
            if v % 8 < 3 + density {
                '#'
            } else if v % 8 == 7 {
                'L'
            } else {
                '.'
            }
        },
        || vec![('#', wall(0.5)), ('L', light(1.0, 0.2))],
    )
}

fn seg_dist(p: [f64; 2], a: [i32; 2], b: [i32; 2]) -> f64 {
    let (ax, ay) = (a[0] as f64, a[1] as f64);
    let (dx, dy) = (b[0] as f64 - ax, b[1] as f64 - ay);
    let (px, py) = (p[0] - ax, p[1] - ay);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        ((px * dx + py * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((px - t * dx).powi(2) + (py - t * dy).powi(2)).sqrt()
}

fn ring_dist(p: [f64; 2], ring: &[[i32; 2]]) -> f64 {
    (0..ring.len())
        .map(|i| seg_dist(p, ring[i], ring[(i + 1) % ring.len()]))
        .fold(f64::MAX, f64::min)
}

fn cross(a: [i32; 2], b: [i32; 2], c: [i32; 2]) -> i64 {
    (b[0] - a[0]) as i64 * (c[1] - a[1]) as i64 - (b[1] - a[1]) as i64 * (c[0] - a[0]) as i64
}

/// True when two closed segments meet anywhere but at end points of both
/// (exact integer orientation tests).
fn meet_badly(s: ([i32; 2], [i32; 2]), t: ([i32; 2], [i32; 2])) -> bool {
    let ((a, b), (c, d)) = (s, t);
    let (d1, d2, d3, d4) = (
        cross(a, b, c),
        cross(a, b, d),
        cross(c, d, a),
        cross(c, d, b),
    );
    let within = |p: [i32; 2], q: [i32; 2], r: [i32; 2]| {
        r[0] >= p[0].min(q[0])
            && r[0] <= p[0].max(q[0])
            && r[1] >= p[1].min(q[1])
            && r[1] <= p[1].max(q[1])
    };
    if d1 == 0 && d2 == 0 {
        // Collinear: overlapping in more than one point?
        let key = |p: [i32; 2]| p[0] as i64 * 1_000_003 + p[1] as i64;
        let (lo1, hi1) = (key(a).min(key(b)), key(a).max(key(b)));
        let (lo2, hi2) = (key(c).min(key(d)), key(c).max(key(d)));
        return lo1.max(lo2) < hi1.min(hi2);
    }
    if (d1 > 0) != (d2 > 0) && d1 != 0 && d2 != 0 && (d3 > 0) != (d4 > 0) && d3 != 0 && d4 != 0 {
        return true;
    }
    let end_s = |p: [i32; 2]| p == a || p == b;
    let end_t = |p: [i32; 2]| p == c || p == d;
    (d1 == 0 && within(a, b, c) && !(end_s(c)))
        || (d2 == 0 && within(a, b, d) && !end_s(d))
        || (d3 == 0 && within(c, d, a) && !end_t(a))
        || (d4 == 0 && within(c, d, b) && !end_t(b))
}

/// The traced loops that face into the image, as the occluders keep them.
fn traced(g: &Geometry) -> Vec<Vec<[i32; 2]>> {
    g.loops
        .iter()
        .filter(|l| l.edges.iter().any(|e| e.transport.is_some()))
        .map(|l| l.vertices.clone())
        .collect()
}

fn check(g: &Geometry, occ: &Occluders, tol: f64) -> Result<(), TestCaseError> {
    let loops = traced(g);
    prop_assert_eq!(loops.len(), occ.polygons.len());
    let mut seen: HashMap<[i32; 2], u32> = HashMap::new();
    for l in &g.loops {
        for &v in &l.vertices {
            *seen.entry(v).or_insert(0) += 1;
        }
    }
    let eps = 1e-9;
    for (l, p) in loops.iter().zip(&occ.polygons) {
        prop_assert!(p.points.len() >= 3);
        prop_assert!(p.points.len() <= l.len());
        // Within tolerance both ways: traced vertices of the polygon,
        // polygon points (sampled along every segment) of the traced loop.
        for &v in l {
            let d = ring_dist([v[0] as f64, v[1] as f64], &p.points);
            prop_assert!(d <= tol + eps, "traced {:?} is {} px off", v, d);
        }
        for i in 0..p.points.len() {
            let (a, b) = (p.points[i], p.points[(i + 1) % p.points.len()]);
            for k in 0..=16 {
                let t = k as f64 / 16.0;
                let q = [
                    a[0] as f64 + t * (b[0] - a[0]) as f64,
                    a[1] as f64 + t * (b[1] - a[1]) as f64,
                ];
                let d = ring_dist(q, l);
                prop_assert!(d <= tol + eps, "{:?} is {} px off the traced loop", q, d);
            }
        }
        // Corners where loops touch are kept.
        for &v in l {
            if seen[&v] > 1 {
                prop_assert!(p.points.contains(&v), "touching corner {:?} dropped", v);
            }
        }
    }
    // No segment crosses or overlaps another, except at shared end points.
    let segs: Vec<_> = occ
        .polygons
        .iter()
        .flat_map(|p| {
            (0..p.points.len()).map(|i| (p.points[i], p.points[(i + 1) % p.points.len()]))
        })
        .collect();
    for i in 0..segs.len() {
        for j in i + 1..segs.len() {
            prop_assert!(
                !meet_badly(segs[i], segs[j]),
                "{:?} and {:?} cross",
                segs[i],
                segs[j]
            );
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(160))]

    #[test]
    fn simplified_loops_stay_close_keep_touching_corners_and_never_cross(
        level in level_strategy(),
        tol in prop_oneof![Just(0.0), Just(0.5), Just(DEFAULT_TOLERANCE), Just(1.5), Just(4.0)],
    ) {
        let g = trace(&level);
        let occ = simplify_loops(&g, tol);
        check(&g, &occ, tol)?;
    }
}

#[test]
fn a_rectangular_room_gives_four_vertices_with_the_solid_outside() {
    let rows = room(20, 12);
    let g = trace(&ascii(&refs(&rows), &[('#', wall(0.5))]));
    for tol in [0.0, DEFAULT_TOLERANCE, 3.0] {
        let occ = simplify_loops(&g, tol);
        // The image border's loop faces only out of the image: left out.
        assert_eq!(occ.polygons.len(), 1);
        let p = &occ.polygons[0];
        assert!(!p.solid_inside);
        let mut pts = p.points.clone();
        pts.sort();
        assert_eq!(pts, vec![[1, 1], [1, 11], [19, 1], [19, 11]]);
    }
}

#[test]
fn a_pillar_has_the_solid_inside() {
    let rows = ["......", "..##..", "..##..", "......"];
    let g = trace(&ascii(&rows, &[('#', wall(0.5))]));
    let occ = simplify_loops(&g, DEFAULT_TOLERANCE);
    assert_eq!(occ.polygons.len(), 1);
    assert!(occ.polygons[0].solid_inside);
    assert_eq!(occ.polygons[0].points.len(), 4);
}

#[test]
fn a_diagonal_checkerboard_keeps_every_corner() {
    let rows: Vec<String> = (0..10)
        .map(|y| {
            (0..10)
                .map(|x| if (x + y) % 2 == 0 { '#' } else { '.' })
                .collect()
        })
        .collect();
    let g = trace(&ascii(&refs(&rows), &[('#', wall(0.5))]));
    for tol in [DEFAULT_TOLERANCE, 2.0, 10.0] {
        let occ = simplify_loops(&g, tol);
        let traced = traced(&g);
        for (l, p) in traced.iter().zip(&occ.polygons) {
            // Every corner of a checkerboard square touches a neighbour's,
            // except on the image border.
            let inner = l
                .iter()
                .filter(|v| v[0] > 0 && v[1] > 0 && v[0] < 10 && v[1] < 10)
                .count();
            assert!(p.points.len() >= inner, "{l:?} -> {:?}", p.points);
        }
        check(&g, &occ, tol).expect("invariants");
    }
}

#[test]
fn a_diagonal_staircase_becomes_a_straight_line() {
    // A wall whose lower edge steps one pixel per pixel.
    let rows: Vec<String> = (0..12)
        .map(|y| (0..12).map(|x| if x >= y { '#' } else { '.' }).collect())
        .collect();
    let g = trace(&ascii(&refs(&rows), &[('#', wall(0.5))]));
    let traced = traced(&g);
    assert_eq!(traced.len(), 1);
    let occ = simplify_loops(&g, DEFAULT_TOLERANCE);
    assert!(
        occ.polygons[0].points.len() <= 5 && traced[0].len() > 20,
        "{} traced -> {:?}",
        traced[0].len(),
        occ.polygons[0].points
    );
    assert!(occ.polygons[0].solid_inside);
    // Below 0.45 px (a vertex off a chord that skips it: 0.45 or 0.71) every step stays.
    let tight = simplify_loops(&g, 0.4);
    assert_eq!(tight.polygons[0].points.len(), traced[0].len());
}

fn stamp_outputs(out: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(out.join("room.stamp.json")).expect("stamp");
    let v: serde_json::Value = serde_json::from_str(&text).expect("stamp JSON");
    v["outputs"]
        .as_array()
        .expect("outputs")
        .iter()
        .map(|o| o.as_str().expect("name").to_string())
        .collect()
}

#[test]
fn bake_with_occluders_writes_json_svg_and_a_godot_resource() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_room(dir.path(), "room", true);
    let args = ["bake", "room.png", "-o", "out", "--quality", "draft"];
    let o = flatbake_in(&[&args[..], &["--occluders"]].concat(), dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    let text = std::fs::read_to_string(out.join("room.occluders.json")).expect("json");
    let v: serde_json::Value = serde_json::from_str(&text).expect("occluders JSON");
    assert_eq!(v["width"], 24);
    assert_eq!(v["height"], 16);
    assert_eq!(v["tolerance"].as_f64(), Some(DEFAULT_TOLERANCE));
    let polys = v["polygons"].as_array().expect("polygons");
    // The room's walls (with the stub) and the pillar; the image border is left out.
    assert_eq!(polys.len(), 2, "{text}");
    let inside: Vec<bool> = polys
        .iter()
        .map(|p| p["solid_inside"].as_bool().expect("bool"))
        .collect();
    assert_eq!(inside.iter().filter(|b| **b).count(), 1, "one pillar");
    for p in polys {
        let pts = p["points"].as_array().expect("points");
        assert!(pts.len() >= 4);
        for q in pts {
            let (x, y) = (q[0].as_i64().expect("x"), q[1].as_i64().expect("y"));
            assert!((1..=23).contains(&x) && (1..=15).contains(&y), "{q}");
        }
    }
    let tres = std::fs::read_to_string(out.join("room.occluders.tres")).expect("tres");
    assert!(tres.starts_with("[gd_resource "), "{tres}");
    assert_eq!(
        tres.matches("[sub_resource type=\"OccluderPolygon2D\"")
            .count(),
        polys.len()
    );
    assert_eq!(tres.matches("closed = true").count(), polys.len());
    assert_eq!(tres.matches("PackedVector2Array(").count(), polys.len());
    let parsed = godot4_tres(&tres);
    assert_eq!(parsed.len(), polys.len(), "{tres}");
    for (p, (closed, cull, pts)) in polys.iter().zip(&parsed) {
        let want: Vec<f64> = p["points"]
            .as_array()
            .expect("points")
            .iter()
            .flat_map(|q| [q[0].as_f64().expect("x"), q[1].as_f64().expect("y")])
            .collect();
        assert_eq!(pts, &want, "the .tres polygon is the JSON one");
        assert!(*closed, "closed polygons occlude from every side");
        assert_eq!(*cull, 0, "culling off, as documented");
    }
    let svg = std::fs::read_to_string(out.join("room.occluders.svg")).expect("svg");
    assert!(svg.contains("viewBox=\"0 0 24 16\""));
    assert_eq!(svg.matches("<polygon ").count(), polys.len());
    let listed = stamp_outputs(&out);
    for s in ["json", "svg", "tres"] {
        assert!(
            listed.contains(&format!("room.occluders.{s}")),
            "{listed:?}"
        );
    }

    // Without the flag the level is not up to date: re-baked, and the stamp
    // no longer lists the occluders.
    let o = flatbake_in(&args, dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        !stamp_outputs(&out).iter().any(|n| n.contains("occluders")),
        "{}",
        stderr(&o)
    );
    // A different tolerance is a different recipe too.
    let o = flatbake_in(
        &[&args[..], &["--occluders", "--occluder-tolerance", "0"]].concat(),
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("room.occluders.json")).expect("json"),
    )
    .expect("JSON");
    assert_eq!(v["tolerance"].as_f64(), Some(0.0));
}

#[test]
fn a_negative_tolerance_is_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_room(dir.path(), "room", true);
    let o = flatbake_in(
        &[
            "bake",
            "room.png",
            "--occluders",
            "--occluder-tolerance",
            "-1",
        ],
        dir.path(),
    );
    assert_exit(&o, 2);
    assert_says(&o, &["--occluder-tolerance"]);
}

/// Reads a Godot 4 text resource as `to_tres` should write it and as Godot
/// 4's text resource format and `OccluderPolygon2D` class define it (the
/// file was never loaded in Godot; Godot 3 cannot read `format=3`):
///
/// - the first line is the descriptor `[gd_resource type="Resource"
///   load_steps=N format=3]`, `N` the number of sub-resources plus one;
/// - then one `[sub_resource type="OccluderPolygon2D" id="..."]` section per
///   polygon, with unique string ids, holding only `OccluderPolygon2D`'s
///   properties: `closed` (bool, default `true`), `cull_mode` (0, 1 or 2,
///   default 0: disabled) and `polygon` (a `PackedVector2Array` of an even
///   number of plain numbers, at least three points);
/// - last the `[resource]` section, whose only property `metadata/occluders`
///   is an array that lists every sub-resource as `SubResource("id")`, once
///   each, in the order of the sections;
/// - every property line is `key = value`, sections are separated by one
///   blank line, and the file ends with a newline.
///
/// Returns `(closed, cull_mode, polygon)` per sub-resource, in order.
fn godot4_tres(text: &str) -> Vec<(bool, i64, Vec<f64>)> {
    assert!(text.ends_with("]\n"), "ends with the metadata line: {text}");
    let mut sections = text.trim_end_matches('\n').split("\n\n");
    let head = sections.next().expect("descriptor");
    let mut ids = Vec::new();
    let mut out = Vec::new();
    let mut listed = None;
    for section in sections {
        let mut lines = section.lines();
        let header = lines.next().expect("section header");
        let props: Vec<(&str, &str)> = lines
            .map(|l| {
                l.split_once(" = ")
                    .unwrap_or_else(|| panic!("not `key = value`: {l:?}"))
            })
            .collect();
        if header == "[resource]" {
            assert!(listed.is_none(), "one [resource] section");
            assert_eq!(props.len(), 1, "{section}");
            assert_eq!(props[0].0, "metadata/occluders");
            let list = props[0].1;
            let inner = list
                .strip_prefix('[')
                .and_then(|l| l.strip_suffix(']'))
                .unwrap_or_else(|| panic!("an array: {list}"));
            let refs: Vec<String> = inner
                .split(", ")
                .filter(|r| !inner.is_empty() || !r.is_empty())
                .map(|r| {
                    r.strip_prefix("SubResource(\"")
                        .and_then(|r| r.strip_suffix("\")"))
                        .unwrap_or_else(|| panic!("a SubResource: {r}"))
                        .to_string()
                })
                .collect();
            listed = Some(refs);
            continue;
        }
        assert!(listed.is_none(), "sub-resources come before [resource]");
        let id = header
            .strip_prefix("[sub_resource type=\"OccluderPolygon2D\" id=\"")
            .and_then(|h| h.strip_suffix("\"]"))
            .unwrap_or_else(|| panic!("an OccluderPolygon2D sub-resource: {header}"));
        assert!(!id.is_empty() && !id.contains('"'), "{header}");
        assert!(!ids.contains(&id.to_string()), "id {id} twice");
        ids.push(id.to_string());
        let (mut closed, mut cull, mut polygon) = (true, 0, None);
        for (key, value) in props {
            match key {
                "closed" => {
                    closed = match value {
                        "true" => true,
                        "false" => false,
                        v => panic!("closed = {v}"),
                    }
                }
                "cull_mode" => {
                    cull = value.parse().expect("cull_mode an integer");
                    assert!((0..=2).contains(&cull), "cull_mode = {cull}");
                }
                "polygon" => {
                    let inner = value
                        .strip_prefix("PackedVector2Array(")
                        .and_then(|v| v.strip_suffix(')'))
                        .unwrap_or_else(|| panic!("polygon = {value}"));
                    let nums: Vec<f64> = inner
                        .split(", ")
                        .map(|n| n.parse().unwrap_or_else(|_| panic!("a number: {n:?}")))
                        .collect();
                    assert!(nums.len().is_multiple_of(2) && nums.len() >= 6, "{value}");
                    assert!(polygon.is_none(), "polygon twice");
                    polygon = Some(nums);
                }
                k => panic!("OccluderPolygon2D has no property {k:?}"),
            }
        }
        out.push((closed, cull, polygon.expect("a polygon")));
    }
    assert_eq!(
        head,
        format!(
            "[gd_resource type=\"Resource\" load_steps={} format=3]",
            ids.len() + 1
        )
    );
    assert_eq!(listed.expect("a [resource] section"), ids);
    out
}
