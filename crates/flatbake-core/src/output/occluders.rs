//! Occluders for live lights: the traced wall loops ([`Geometry::loops`]) as
//! simplified polygons, so that a game can add live lights and shadows that
//! match the baked walls — `NAME.occluders.json`, `NAME.occluders.svg` and a
//! Godot 4 resource `NAME.occluders.tres` (one `OccluderPolygon2D` per
//! polygon).
//!
//! Coordinates are level pixels: the origin is the top-left corner of the
//! image, x to the right, **y down** (Godot's 2D convention), every vertex a
//! pixel corner (integers).
//!
//! Each loop is simplified by Douglas-Peucker with a tolerance in pixels
//! ([`DEFAULT_TOLERANCE`]), with two rules that keep the outlines from
//! opening a gap the bake does not have:
//!
//! - every vertex where loops touch (a corner saddle, where two diagonal
//!   solids share a corner point, or a loop touching itself there) stays
//!   fixed, so diagonal solids still meet at their corner;
//! - no simplified segment may cross or overlap another simplified segment
//!   (of any polygon, its own included) except at a shared end point: a
//!   segment that would is split again at its farthest traced vertex, until
//!   none does. The traced loops themselves never cross, so this ends, at
//!   worst with the traced loop.
//!
//! Every traced vertex is within the tolerance of its polygon and every
//! point of a polygon within the tolerance of its traced loop. Loops that
//! face only out of the image (the image border of a wall ring) cast no
//! shadow inside the level and are left out.

use std::collections::HashMap;
use std::fmt::Write as _;

use serde::Serialize;

use crate::geometry::{Geometry, Loop};

/// The default tolerance in pixels: one-pixel diagonal staircases (whose
/// corners are 0.71 px off the diagonal) become straight lines, a wall one
/// pixel thick keeps its four corners.
pub const DEFAULT_TOLERANCE: f64 = 0.75;

/// One simplified loop.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Occluder {
    /// Vertices in the traced loop's order, `[x, y]` in level pixels (y
    /// down); the polygon closes from the last back to the first.
    pub points: Vec<[i32; 2]>,
    /// True when the solid is inside the polygon (a pillar, a wall blob;
    /// counter-clockwise on screen), false when it is outside (the walls
    /// around a room; clockwise on screen).
    pub solid_inside: bool,
    /// How many vertices the traced loop had.
    pub traced_vertices: usize,
}

/// The occluders of one level.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Occluders {
    /// Level width in pixels.
    pub width: usize,
    /// Level height in pixels.
    pub height: usize,
    /// The simplification tolerance used, in pixels.
    pub tolerance: f64,
    /// One polygon per traced loop that faces into the image.
    pub polygons: Vec<Occluder>,
}

/// Simplifies every loop of `geometry` that faces into the image, within
/// `tolerance` pixels (a negative or NaN tolerance is 0: the traced loops).
pub fn simplify_loops(geometry: &Geometry, tolerance: f64) -> Occluders {
    let tolerance = if tolerance.is_finite() {
        tolerance.max(0.0)
    } else if tolerance > 0.0 {
        f64::MAX
    } else {
        0.0
    };
    let loops: Vec<&Loop> = geometry
        .loops
        .iter()
        .filter(|l| l.edges.iter().any(|e| e.transport.is_some()))
        .collect();
    let mut seen: HashMap<[i32; 2], u32> = HashMap::new();
    for l in &geometry.loops {
        for &v in &l.vertices {
            *seen.entry(v).or_insert(0) += 1;
        }
    }
    let mut keep: Vec<Vec<bool>> = loops
        .iter()
        .map(|l| {
            let fixed: Vec<bool> = l.vertices.iter().map(|v| seen[v] > 1).collect();
            first_pass(&l.vertices, fixed, tolerance)
        })
        .collect();
    resolve_crossings(&loops, &mut keep, tolerance);
    let polygons = loops
        .iter()
        .zip(&keep)
        .map(|(l, k)| Occluder {
            points: l
                .vertices
                .iter()
                .zip(k)
                .filter(|(_, k)| **k)
                .map(|(v, _)| *v)
                .collect(),
            solid_inside: twice_area(&l.vertices) < 0,
            traced_vertices: l.vertices.len(),
        })
        .collect();
    Occluders {
        width: geometry.width,
        height: geometry.height,
        tolerance,
        polygons,
    }
}

/// Twice the signed (shoelace) area in image coordinates: negative when the
/// loop runs counter-clockwise on screen (y down).
fn twice_area(v: &[[i32; 2]]) -> i64 {
    let n = v.len();
    (0..n)
        .map(|i| {
            let (p, q) = (v[i], v[(i + 1) % n]);
            p[0] as i64 * q[1] as i64 - q[0] as i64 * p[1] as i64
        })
        .sum()
}

fn dist_sq(a: [i32; 2], b: [i32; 2]) -> f64 {
    let (dx, dy) = ((a[0] - b[0]) as f64, (a[1] - b[1]) as f64);
    dx * dx + dy * dy
}

/// Distance from `p` to the closed segment `a b`.
fn seg_dist(p: [i32; 2], a: [i32; 2], b: [i32; 2]) -> f64 {
    let (ax, ay) = (a[0] as f64, a[1] as f64);
    let (dx, dy) = ((b[0] - a[0]) as f64, (b[1] - a[1]) as f64);
    let (px, py) = (p[0] as f64 - ax, p[1] as f64 - ay);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        ((px * dx + py * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((px - t * dx).powi(2) + (py - t * dy).powi(2)).sqrt()
}

/// The interior vertex of the cyclic range `i..j` (indices mod `v.len()`,
/// `j > i + 1`) farthest from the chord `v[i] v[j]`, and its distance.
fn farthest(v: &[[i32; 2]], i: usize, j: usize) -> (usize, f64) {
    let n = v.len();
    let (a, b) = (v[i % n], v[j % n]);
    let mut best = (i + 1, -1.0);
    for k in i + 1..j {
        let d = seg_dist(v[k % n], a, b);
        if d > best.1 {
            best = (k, d);
        }
    }
    best
}

/// Douglas-Peucker between the fixed vertices of one loop: which vertices
/// are kept. A loop with fewer than two fixed vertices fixes its first one
/// and the one farthest from it; at least three are kept.
fn first_pass(v: &[[i32; 2]], mut keep: Vec<bool>, tolerance: f64) -> Vec<bool> {
    let n = v.len();
    if n <= 3 {
        return vec![true; n];
    }
    let mut fixed: Vec<usize> = (0..n).filter(|&i| keep[i]).collect();
    if fixed.is_empty() {
        keep[0] = true;
        fixed.push(0);
    }
    if fixed.len() == 1 {
        let f = fixed[0];
        let far = (0..n)
            .max_by(|&a, &b| dist_sq(v[a], v[f]).total_cmp(&dist_sq(v[b], v[f])))
            .unwrap_or(f);
        keep[far] = true;
        fixed = (0..n).filter(|&i| keep[i]).collect();
    }
    let stack: Vec<(usize, usize)> = (0..fixed.len())
        .map(|k| {
            let i = fixed[k];
            let j = if k + 1 < fixed.len() {
                fixed[k + 1]
            } else {
                fixed[0] + n
            };
            (i, j)
        })
        .collect();
    refine(v, &mut keep, stack, tolerance);
    while keep.iter().filter(|k| **k).count() < 3 {
        let kept: Vec<usize> = (0..n).filter(|&i| keep[i]).collect();
        let far = (0..n)
            .filter(|&i| !keep[i])
            .max_by(|&a, &b| {
                let da = kept
                    .iter()
                    .map(|&k| dist_sq(v[a], v[k]))
                    .fold(f64::MAX, f64::min);
                let db = kept
                    .iter()
                    .map(|&k| dist_sq(v[b], v[k]))
                    .fold(f64::MAX, f64::min);
                da.total_cmp(&db)
            })
            .expect("a loop of more than three vertices has one not kept");
        keep[far] = true;
        let ranges = ranges_around(&keep, far);
        refine(v, &mut keep, ranges, tolerance);
    }
    keep
}

/// Douglas-Peucker on the cyclic vertex ranges `i..j` of `stack` (kept end
/// points, `j` possibly past `v.len()`): keeps the farthest interior vertex
/// of a range while it is more than `tolerance` off its chord, so that every
/// vertex ends within `tolerance` of the segment that replaces it.
fn refine(v: &[[i32; 2]], keep: &mut [bool], mut stack: Vec<(usize, usize)>, tolerance: f64) {
    let n = v.len();
    while let Some((i, j)) = stack.pop() {
        if j <= i + 1 {
            continue;
        }
        let (k, d) = farthest(v, i, j);
        // A chord between two visits of one point always splits.
        if d > tolerance || v[i % n] == v[j % n] {
            keep[k % n] = true;
            stack.push((i, k));
            stack.push((k, j));
        }
    }
}

/// The two cyclic ranges from the kept vertex before `k` to `k` and from
/// `k` to the kept vertex after it, as [`refine`] takes them (`k` is kept).
fn ranges_around(keep: &[bool], k: usize) -> Vec<(usize, usize)> {
    let n = keep.len();
    let ahead = (1..=n).find(|&d| keep[(k + d) % n]).unwrap_or(n);
    let back = (1..=n).find(|&d| keep[(k + n - d) % n]).unwrap_or(n);
    // Indices may run past n but not below 0: shift k up by n if need be.
    let k = if back > k { k + n } else { k };
    vec![(k - back, k), (k, k + ahead)]
}

/// A simplified segment: loop, and the cyclic vertex range `i..=j` it replaces.
#[derive(Clone, Copy)]
struct Seg {
    lp: usize,
    i: usize,
    j: usize,
    a: [i32; 2],
    b: [i32; 2],
}

fn orient(a: [i32; 2], b: [i32; 2], c: [i32; 2]) -> i64 {
    let (ax, ay) = (a[0] as i64, a[1] as i64);
    ((b[0] as i64 - ax) * (c[1] as i64 - ay) - (b[1] as i64 - ay) * (c[0] as i64 - ax)).signum()
}

/// `c` lies on the closed segment `a b`, given that the three are collinear.
fn on_segment(a: [i32; 2], b: [i32; 2], c: [i32; 2]) -> bool {
    c[0] >= a[0].min(b[0])
        && c[0] <= a[0].max(b[0])
        && c[1] >= a[1].min(b[1])
        && c[1] <= a[1].max(b[1])
}

/// True when segments `s` and `t` meet anywhere but at an end point of both
/// (exact: integer coordinates).
pub(crate) fn segments_conflict(s: ([i32; 2], [i32; 2]), t: ([i32; 2], [i32; 2])) -> bool {
    let ((p1, p2), (q1, q2)) = (s, t);
    let (o1, o2) = (orient(p1, p2, q1), orient(p1, p2, q2));
    let (o3, o4) = (orient(q1, q2, p1), orient(q1, q2, p2));
    if o1 == 0 && o2 == 0 {
        // Collinear: they conflict when they overlap in more than a point.
        let axis = if p1[0] != p2[0] { 0 } else { 1 };
        let (slo, shi) = (p1[axis].min(p2[axis]), p1[axis].max(p2[axis]));
        let (tlo, thi) = (q1[axis].min(q2[axis]), q1[axis].max(q2[axis]));
        return slo.max(tlo) < shi.min(thi);
    }
    if o1 * o2 < 0 && o3 * o4 < 0 {
        return true;
    }
    let shared = |c: [i32; 2]| c == p1 || c == p2;
    let shared_t = |c: [i32; 2]| c == q1 || c == q2;
    (o1 == 0 && on_segment(p1, p2, q1) && !shared(q1))
        || (o2 == 0 && on_segment(p1, p2, q2) && !shared(q2))
        || (o3 == 0 && on_segment(q1, q2, p1) && !shared_t(p1))
        || (o4 == 0 && on_segment(q1, q2, p2) && !shared_t(p2))
}

/// Splits segments that cross or overlap another one at their farthest
/// traced vertex (simplifying its two halves again within `tolerance`),
/// until none does.
fn resolve_crossings(loops: &[&Loop], keep: &mut [Vec<bool>], tolerance: f64) {
    const CELL: i32 = 16;
    loop {
        let mut segs: Vec<Seg> = Vec::new();
        for (lp, (l, k)) in loops.iter().zip(keep.iter()).enumerate() {
            let n = l.vertices.len();
            let kept: Vec<usize> = (0..n).filter(|&i| k[i]).collect();
            for (m, &i) in kept.iter().enumerate() {
                let j = if m + 1 < kept.len() {
                    kept[m + 1]
                } else {
                    kept[0] + n
                };
                segs.push(Seg {
                    lp,
                    i,
                    j,
                    a: l.vertices[i],
                    b: l.vertices[j % n],
                });
            }
        }
        let mut grid: HashMap<(i32, i32), Vec<u32>> = HashMap::new();
        for (id, s) in segs.iter().enumerate() {
            let (x0, x1) = (s.a[0].min(s.b[0]), s.a[0].max(s.b[0]));
            let (y0, y1) = (s.a[1].min(s.b[1]), s.a[1].max(s.b[1]));
            for cy in y0.div_euclid(CELL)..=y1.div_euclid(CELL) {
                for cx in x0.div_euclid(CELL)..=x1.div_euclid(CELL) {
                    grid.entry((cx, cy)).or_default().push(id as u32);
                }
            }
        }
        let mut bad = vec![false; segs.len()];
        let mut cells: Vec<_> = grid.into_values().collect();
        cells.sort_unstable();
        for ids in &cells {
            for (x, &s) in ids.iter().enumerate() {
                for &t in &ids[x + 1..] {
                    let (s, t) = (s as usize, t as usize);
                    if (!bad[s] || !bad[t])
                        && segments_conflict((segs[s].a, segs[s].b), (segs[t].a, segs[t].b))
                    {
                        bad[s] = true;
                        bad[t] = true;
                    }
                }
            }
        }
        let mut changed = false;
        for (s, _) in segs.iter().zip(&bad).filter(|(_, b)| **b) {
            if s.j > s.i + 1 {
                let n = loops[s.lp].vertices.len();
                let v = &loops[s.lp].vertices;
                let (k, _) = farthest(v, s.i, s.j);
                keep[s.lp][k % n] = true;
                // The split's two halves need not be within the tolerance
                // of the vertices they replace: simplify them again.
                refine(v, &mut keep[s.lp], vec![(s.i, k), (k, s.j)], tolerance);
                changed = true;
            }
        }
        if !changed {
            // Only traced segments conflict, which tracing rules out; keep
            // the traced loops of any still involved rather than loop forever.
            for (s, _) in segs.iter().zip(&bad).filter(|(_, b)| **b) {
                keep[s.lp].iter_mut().for_each(|k| *k = true);
            }
            return;
        }
    }
}

/// `NAME.occluders.json`: pretty JSON and a final newline.
pub fn to_json(occ: &Occluders) -> Result<Vec<u8>, String> {
    #[derive(Serialize)]
    struct File<'a> {
        format: &'static str,
        version: u32,
        coordinates: &'static str,
        winding: &'static str,
        #[serde(flatten)]
        occluders: &'a Occluders,
    }
    let mut bytes = serde_json::to_vec_pretty(&File {
        format: "flatbake-occluders",
        version: 1,
        coordinates: "level pixels, origin at the top-left corner of the image, x right, y down",
        winding: "solid_inside polygons run counter-clockwise on screen (negative shoelace area \
                  with y down), the others (walls around a room) clockwise; the free side is on \
                  the right of travel",
        occluders: occ,
    })
    .map_err(|e| e.to_string())?;
    bytes.push(b'\n');
    Ok(bytes)
}

fn point_list(points: &[[i32; 2]], sep: &str) -> String {
    let mut s = String::new();
    for (k, p) in points.iter().enumerate() {
        if k > 0 {
            s.push_str(sep);
        }
        let _ = write!(s, "{}, {}", p[0], p[1]);
    }
    s
}

/// `NAME.occluders.svg`: the level's size as view box, solid-inside
/// polygons filled, every outline drawn.
pub fn to_svg(occ: &Occluders) -> Vec<u8> {
    let (w, h) = (occ.width, occ.height);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"0 0 {w} {h}\" width=\"{}\" height=\"{}\">",
        w.max(1) * 4,
        h.max(1) * 4
    );
    let _ = writeln!(s, "<rect width=\"{w}\" height=\"{h}\" fill=\"#f4f1ea\"/>");
    for p in &occ.polygons {
        let fill = if p.solid_inside { "#44444480" } else { "none" };
        let _ = writeln!(
            s,
            "<polygon points=\"{}\" fill=\"{fill}\" stroke=\"#d03020\" stroke-width=\"0.25\" stroke-linejoin=\"round\"/>",
            point_list(&p.points, " ").replace(", ", ",")
        );
    }
    s.push_str("</svg>\n");
    s.into_bytes()
}

/// `NAME.occluders.tres`: a Godot 4 text resource holding one
/// `OccluderPolygon2D` sub-resource per polygon (`closed = true`, culling
/// off), listed in the resource's `metadata/occluders` array.
pub fn to_tres(occ: &Occluders) -> Vec<u8> {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "[gd_resource type=\"Resource\" load_steps={} format=3]\n",
        occ.polygons.len() + 1
    );
    for (k, p) in occ.polygons.iter().enumerate() {
        let _ = writeln!(
            s,
            "[sub_resource type=\"OccluderPolygon2D\" id=\"OccluderPolygon2D_{k}\"]\nclosed = true\npolygon = PackedVector2Array({})\n",
            point_list(&p.points, ", ")
        );
    }
    s.push_str("[resource]\nmetadata/occluders = [");
    for k in 0..occ.polygons.len() {
        if k > 0 {
            s.push_str(", ");
        }
        let _ = write!(s, "SubResource(\"OccluderPolygon2D_{k}\")");
    }
    s.push_str("]\n");
    s.into_bytes()
}

/// The three occluder files of level `name`, in writing order: JSON, SVG,
/// Godot resource.
pub fn encode_occluders(
    name: &str,
    geometry: &Geometry,
    tolerance: f64,
) -> Result<Vec<super::Encoded>, super::OutputError> {
    use super::{Encoded, OutputKind};
    let occ = simplify_loops(geometry, tolerance);
    let json = to_json(&occ).map_err(|message| super::OutputError::Encode {
        path: OutputKind::OccludersJson.file_name(name).into(),
        message,
    })?;
    Ok(vec![
        Encoded {
            kind: OutputKind::OccludersJson,
            bytes: json,
        },
        Encoded {
            kind: OutputKind::OccludersSvg,
            bytes: to_svg(&occ),
        },
        Encoded {
            kind: OutputKind::OccludersTres,
            bytes: to_tres(&occ),
        },
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_meet_only_at_shared_end_points() {
        let s = ([0, 0], [4, 0]);
        // Crossing, touching inside, overlapping, identical: conflicts.
        assert!(segments_conflict(s, ([2, -1], [2, 1])));
        assert!(segments_conflict(s, ([2, 0], [2, 3])));
        assert!(segments_conflict(s, ([3, 0], [6, 0])));
        assert!(segments_conflict(s, ([4, 0], [0, 0])));
        // Sharing an end point, collinear end to end, apart: fine.
        assert!(!segments_conflict(s, ([4, 0], [5, 3])));
        assert!(!segments_conflict(s, ([4, 0], [7, 0])));
        assert!(!segments_conflict(s, ([0, 1], [4, 1])));
    }

    #[test]
    fn the_godot_resource_lists_one_polygon_per_loop() {
        let occ = Occluders {
            width: 4,
            height: 3,
            tolerance: 0.75,
            polygons: vec![
                Occluder {
                    points: vec![[1, 1], [1, 2], [3, 2], [3, 1]],
                    solid_inside: false,
                    traced_vertices: 4,
                },
                Occluder {
                    points: vec![[0, 0], [0, 1], [1, 0]],
                    solid_inside: true,
                    traced_vertices: 6,
                },
            ],
        };
        let tres = String::from_utf8(to_tres(&occ)).expect("utf-8");
        assert!(tres.starts_with("[gd_resource type=\"Resource\" load_steps=3 format=3]\n"));
        assert!(tres.contains("polygon = PackedVector2Array(1, 1, 1, 2, 3, 2, 3, 1)\n"));
        assert!(tres.contains(
            "metadata/occluders = [SubResource(\"OccluderPolygon2D_0\"), SubResource(\"OccluderPolygon2D_1\")]"
        ));
        let json: serde_json::Value =
            serde_json::from_slice(&to_json(&occ).expect("json")).expect("parses");
        assert_eq!(
            json["polygons"][1]["points"],
            serde_json::json!([[0, 0], [0, 1], [1, 0]])
        );
        assert_eq!(json["format"], "flatbake-occluders");
    }

    #[test]
    fn a_nan_or_negative_tolerance_writes_the_traced_loops() {
        let level = crate::level::Level {
            name: "t".into(),
            width: 5,
            height: 5,
            cells: (0..25)
                .map(|i| {
                    let (x, y) = (i % 5, i / 5);
                    if (1..4).contains(&x) && (1..4).contains(&y) && (x, y) != (3, 3) {
                        crate::level::Cell::Solid(0)
                    } else {
                        crate::level::Cell::Floor
                    }
                })
                .collect(),
            albedo: vec![[0.5; 3]; 25],
            materials: vec![],
            warnings: vec![],
            lossy_format: None,
            origin: Default::default(),
            floor_fraction: None,
        };
        let g = crate::geometry::trace(&level);
        for tol in [f64::NAN, -1.0, 0.0] {
            let occ = simplify_loops(&g, tol);
            assert_eq!(occ.tolerance, 0.0);
            assert_eq!(occ.polygons[0].points, g.loops[0].vertices);
        }
        // An L of 6 vertices: at 10 px, still a triangle at least.
        assert!(simplify_loops(&g, 10.0).polygons[0].points.len() >= 3);
    }
}
