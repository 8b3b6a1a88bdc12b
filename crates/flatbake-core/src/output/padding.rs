//! Padding for engines: texels inside walls and void near the floor are
//! filled from the nearest floor texels, so that bilinear filtering and the
//! first mip levels never pull black (or an emitter's glow) into the floor,
//! and a coverage channel tells floor (1) from padding and wall (0).
//!
//! The fill is an iterated dilation: pass `k` (1 to `texels`) gives every
//! non-floor texel that is still empty and has a filled 8-neighbour the
//! mean of those neighbours as they stood after pass `k - 1` (floor texels
//! are filled from the start). A texel at Chebyshev distance `d <= texels`
//! from the floor is filled in pass `d`, from texels one step nearer, so
//! every padded value is a mean of floor values within `d` texels: it lies
//! in their `[min, max]`. Each value depends only on the previous pass,
//! summed in a fixed neighbour order, so the result does not depend on
//! threads or on the order texels are visited. Texels further than
//! `texels` from the floor are 0 ([`pad`]) or keep their values
//! ([`pad_over`], what the lightmap outputs do: wall faces there hold what
//! `--walls` says).

/// Padding width when none is asked for: 0, so the default lightmaps keep
/// today's bytes (solid pixels showing their own radiosity, no coverage
/// channel in the EXR). [`SUGGESTED_PADDING`] is what an engine wants.
pub const DEFAULT_PADDING: u32 = 0;

/// A padding width that covers bilinear filtering (1 texel) and three mip
/// levels (a texel of mip 3 is 8 texels wide).
pub const SUGGESTED_PADDING: u32 = 8;

/// The eight neighbours, in the fixed order their values are summed in.
const NEIGHBOURS: [(isize, isize); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// Pads `values` (row-major, `width * height`) in place: texels where
/// `floor` is false and that lie within `texels` (Chebyshev distance) of a
/// floor texel get the dilated floor values described in the module
/// documentation; every other non-floor texel becomes 0. Floor texels are
/// left as they are. Inputs of mismatched lengths are left untouched.
pub fn pad(width: usize, height: usize, values: &mut [[f32; 3]], floor: &[bool], texels: u32) {
    pad_with(width, height, values, floor, texels, true);
}

/// As [`pad`], but the non-floor texels further than `texels` from the
/// floor keep their values instead of becoming 0: the lightmap outputs'
/// rule, where those texels hold what `--walls` put on wall faces.
pub fn pad_over(width: usize, height: usize, values: &mut [[f32; 3]], floor: &[bool], texels: u32) {
    pad_with(width, height, values, floor, texels, false);
}

fn pad_with(
    width: usize,
    height: usize,
    values: &mut [[f32; 3]],
    floor: &[bool],
    texels: u32,
    clear: bool,
) {
    let n = width * height;
    if values.len() != n || floor.len() != n {
        return;
    }
    let mut filled = floor.to_vec();
    if clear {
        for (v, &f) in values.iter_mut().zip(floor) {
            if !f {
                *v = [0.0; 3];
            }
        }
    }
    let neighbours = |i: usize| {
        let (x, y) = ((i % width) as isize, (i / width) as isize);
        NEIGHBOURS.iter().filter_map(move |&(dx, dy)| {
            let (nx, ny) = (x + dx, y + dy);
            (nx >= 0 && ny >= 0 && (nx as usize) < width && (ny as usize) < height)
                .then(|| ny as usize * width + nx as usize)
        })
    };
    // The texels filled in the last pass (the floor before the first), in
    // increasing index order: the next pass looks only at their neighbours.
    let mut front: Vec<usize> = (0..n).filter(|&i| floor[i]).collect();
    let mut seen = vec![false; n];
    for _ in 0..texels {
        let mut next: Vec<usize> = Vec::new();
        for &i in &front {
            for j in neighbours(i) {
                if !filled[j] && !seen[j] {
                    seen[j] = true;
                    next.push(j);
                }
            }
        }
        if next.is_empty() {
            break;
        }
        next.sort_unstable();
        let new: Vec<[f32; 3]> = next
            .iter()
            .map(|&j| {
                let mut sum = [0f64; 3];
                let mut count = 0u32;
                for k in neighbours(j) {
                    if filled[k] {
                        for c in 0..3 {
                            sum[c] += values[k][c] as f64;
                        }
                        count += 1;
                    }
                }
                sum.map(|s| (s / count.max(1) as f64) as f32)
            })
            .collect();
        for (&j, v) in next.iter().zip(new) {
            values[j] = v;
            filled[j] = true;
        }
        front = next;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fills_within_the_width_and_zeroes_beyond() {
        // One row: floor at 0 (value 1) and 1 (value 3), then 4 wall texels.
        let mut v = vec![[1.0; 3], [3.0; 3], [9.0; 3], [9.0; 3], [9.0; 3], [9.0; 3]];
        let floor = [true, true, false, false, false, false];
        pad(6, 1, &mut v, &floor, 2);
        assert_eq!(v[0], [1.0; 3]);
        assert_eq!(v[1], [3.0; 3]);
        assert_eq!(v[2], [3.0; 3]);
        assert_eq!(v[3], [3.0; 3]);
        assert_eq!(v[4], [0.0; 3]);
        assert_eq!(v[5], [0.0; 3]);
    }

    #[test]
    fn a_texel_between_two_floors_takes_their_mean() {
        let mut v = vec![[2.0; 3], [7.0; 3], [4.0; 3]];
        pad(3, 1, &mut v, &[true, false, true], 1);
        assert_eq!(v[1], [3.0; 3]);
    }

    #[test]
    fn pad_over_keeps_what_lies_beyond_the_width() {
        let mut v = vec![[1.0; 3], [9.0; 3], [9.0; 3], [5.0; 3]];
        pad_over(4, 1, &mut v, &[true, false, false, false], 2);
        assert_eq!(v, vec![[1.0; 3], [1.0; 3], [1.0; 3], [5.0; 3]]);
    }

    #[test]
    fn zero_width_only_clears_non_floor() {
        let mut v = vec![[2.0; 3], [7.0; 3]];
        pad(2, 1, &mut v, &[true, false], 0);
        assert_eq!(v, vec![[2.0; 3], [0.0; 3]]);
    }
}
