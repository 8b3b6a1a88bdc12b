//! Proptest strategies for random levels.

use std::ops::Range;

use flatbake_core::level::Level;
use flatbake_core::level::material::Material;
use proptest::prelude::*;

use super::levels::{ascii, refs};

/// Random levels of `w x h` pixels, sizes drawn from the ranges: pixel
/// `(x, y)` is `cell(byte, density)` for a byte drawn per pixel and one
/// density `0..4` per level (`.` floor, ` ` void, else a `legend` character).
pub fn grid_level(
    w: Range<usize>,
    h: Range<usize>,
    cell: fn(u8, u8) -> char,
    legend: fn() -> Vec<(char, Material)>,
) -> impl Strategy<Value = Level> {
    (w, h, 0u8..4).prop_flat_map(move |(w, h, density)| {
        proptest::collection::vec(any::<u8>(), w * h).prop_map(move |v| {
            let rows: Vec<String> = (0..h)
                .map(|y| (0..w).map(|x| cell(v[y * w + x], density)).collect())
                .collect();
            ascii(&refs(&rows), &legend())
        })
    })
}
