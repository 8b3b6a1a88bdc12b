//! Invariants of marching-squares tracing on random masks.

mod common;
use common::*;

use std::collections::HashMap;

use flatbake_core::geometry::{Geometry, Normal, trace};
use flatbake_core::level::{Cell, Level};
use proptest::prelude::*;

/// A random level: each pixel floor, void, or one of two wall materials.
fn level_strategy() -> impl Strategy<Value = Level> {
    grid_level(
        1..14,
        1..14,
        |v, _| match v % 10 {
            0..=3 => '.',
            4 => ' ',
            5..=7 => '#',
            _ => 'L',
        },
        || vec![('#', wall(0.5)), ('L', light(1.0, 0.2))],
    )
}

fn solid(l: &Level, x: i32, y: i32) -> bool {
    x >= 0
        && y >= 0
        && (x as usize) < l.width
        && (y as usize) < l.height
        && l.cell(x as usize, y as usize).is_solid()
}

/// Every exposed side of every solid pixel, as (pixel, normal).
fn exposed_sides(l: &Level) -> Vec<([i32; 2], Normal)> {
    let mut v = Vec::new();
    for y in 0..l.height as i32 {
        for x in 0..l.width as i32 {
            if !solid(l, x, y) {
                continue;
            }
            for n in Normal::ALL {
                let d = n.vec();
                if !solid(l, x + d[0], y + d[1]) {
                    v.push(([x, y], n));
                }
            }
        }
    }
    v
}

/// Unit sides covered by the loops' edges, counted.
fn covered_sides(g: &Geometry) -> HashMap<([i32; 2], Normal), usize> {
    let mut m = HashMap::new();
    for lp in &g.loops {
        for e in &lp.edges {
            let d = e.normal.travel();
            let len = (e.b[0] - e.a[0]).abs() + (e.b[1] - e.a[1]).abs();
            for k in 0..len {
                let from = [e.a[0] + d[0] * k, e.a[1] + d[1] * k];
                // The solid pixel behind the side owns it.
                let px = match e.normal {
                    Normal::Up => [from[0] - 1, from[1]],
                    Normal::Left => [from[0], from[1]],
                    Normal::Down => [from[0], from[1] - 1],
                    Normal::Right => [from[0] - 1, from[1] - 1],
                };
                *m.entry((px, e.normal)).or_insert(0) += 1;
            }
        }
    }
    m
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn loops_close_and_turn_at_every_vertex(l in level_strategy()) {
        let g = trace(&l);
        for lp in &g.loops {
            prop_assert!(lp.edges.len() >= 4, "a loop has at least four edges");
            for (i, e) in lp.edges.iter().enumerate() {
                let next = &lp.edges[(i + 1) % lp.edges.len()];
                prop_assert_eq!(e.b, next.a, "consecutive edges meet");
                // The edge runs along its travel direction.
                let d = e.normal.travel();
                let len = (e.b[0] - e.a[0]).abs() + (e.b[1] - e.a[1]).abs();
                prop_assert!(len > 0);
                prop_assert_eq!([e.a[0] + d[0] * len, e.a[1] + d[1] * len], e.b);
                // Merged runs are maximal: a straight continuation changes material.
                if next.normal == e.normal {
                    prop_assert!(next.material != e.material || next.transport.is_some() != e.transport.is_some());
                }
            }
        }
    }

    #[test]
    fn every_exposed_side_is_covered_exactly_once(l in level_strategy()) {
        let g = trace(&l);
        let want = exposed_sides(&l);
        let got = covered_sides(&g);
        prop_assert_eq!(got.len(), want.len());
        for s in &want {
            prop_assert_eq!(got.get(s).copied(), Some(1), "side {:?}", s);
        }
    }

    #[test]
    fn normals_face_free_space_and_material_matches(l in level_strategy()) {
        let g = trace(&l);
        for e in &g.edges {
            let (lo, hi) = e.extent();
            for s in lo as i32..hi as i32 {
                let p = e.solid_pixel_at(s);
                let f = e.free_pixel_at(s);
                prop_assert!(solid(&l, p[0], p[1]));
                prop_assert!(!solid(&l, f[0], f[1]));
                prop_assert!(f[0] >= 0 && f[1] >= 0 && (f[0] as usize) < l.width && (f[1] as usize) < l.height,
                    "transport edges face into the image");
                prop_assert_eq!(l.cell(p[0] as usize, p[1] as usize), Cell::Solid(e.material));
                prop_assert_eq!(Some(e.component), g.component_at(f[0] as i64, f[1] as i64));
                // A point in front of the edge is in front; behind is behind.
                let m = e.point_at(s as f64 + 0.5);
                let n = e.normal.vec();
                prop_assert!(e.front_distance([m[0] + n[0] as f64 * 0.5, m[1] + n[1] as f64 * 0.5]) > 0.0);
            }
        }
    }

    #[test]
    fn components_are_four_connected_free_regions(l in level_strategy()) {
        let g = trace(&l);
        for y in 0..l.height as i64 {
            for x in 0..l.width as i64 {
                let c = g.component_at(x, y);
                prop_assert_eq!(c.is_none(), l.cell(x as usize, y as usize).is_solid());
                if let (Some(a), Some(b)) = (c, g.component_at(x + 1, y)) {
                    prop_assert_eq!(a, b);
                }
                if let (Some(a), Some(b)) = (c, g.component_at(x, y + 1)) {
                    prop_assert_eq!(a, b);
                }
            }
        }
    }
}

/// A rectangle of wall pixels is one loop of four edges.
#[test]
fn a_rectangle_is_one_loop_of_four_edges() {
    let lvl = ascii(
        &["......", ".####.", ".####.", "......"],
        &[('#', wall(0.5))],
    );
    let g = trace(&lvl);
    assert_eq!(g.loops.len(), 1);
    assert_eq!(g.loops[0].edges.len(), 4);
    assert_eq!(g.edges.len(), 4);
}

/// Two wall pixels touching at a corner stay two loops that share the point.
#[test]
fn diagonal_pixels_are_separate_loops_meeting_at_the_corner() {
    let lvl = ascii(&["....", ".#..", "..#.", "...."], &[('#', wall(0.5))]);
    let g = trace(&lvl);
    assert_eq!(g.loops.len(), 2);
    let shared = [2, 2];
    for lp in &g.loops {
        assert!(
            lp.vertices.contains(&shared),
            "each loop has the shared corner"
        );
    }
    // The free pixels on either side of the diagonal touch only at corners,
    // but they are connected around the ends: one component.
    assert_eq!(g.component_count, 1);
}

/// A material change splits a straight run.
#[test]
fn material_change_splits_a_run() {
    let lvl = ascii(
        &["......", ".##LL.", "......"],
        &[('#', wall(0.5)), ('L', light(1.0, 0.0))],
    );
    let g = trace(&lvl);
    assert_eq!(g.loops.len(), 1);
    // Top and bottom each split in two: 2 + 2 + left + right = 6.
    assert_eq!(g.edges.len(), 6);
}

/// Edges facing out of the image are dropped from transport but kept in loops.
#[test]
fn border_facing_edges_are_not_transport_edges() {
    let lvl = ascii(&["###", "#.#", "###"], &[('#', wall(0.5))]);
    let g = trace(&lvl);
    let outer: usize = g
        .loops
        .iter()
        .map(|l| l.edges.iter().filter(|e| e.transport.is_none()).count())
        .sum();
    assert_eq!(outer, 4);
    assert_eq!(g.edges.len(), 4, "only the four inner walls face the floor");
}
