//! Closed-form first circular moments of the floor gather over a straight
//! stretch of edge (docs/transport.md#directional-lightmaps).
//!
//! As in [`super::kernel`]: a point of the edge's line at offset `t` from the
//! foot of the perpendicular from the pixel is at angle `psi = atan(t / d)`
//! and distance `r = sqrt(d^2 + t^2)`, `d psi = d dt / r^2`, and the falloff
//! weight is `w = A / (A + r^2)`. The unit direction from the pixel to that
//! point has the component `cos psi = d / r` towards the line (along minus
//! the edge's normal) and `sin psi = t / r` along the edge's axis. The
//! moments of radiosity `t^j` are then
//!
//! * `N_j = integral of t^j w cos psi d psi = d^2 integral of t^j w / r^3 dt`,
//! * `T_j = integral of t^j w sin psi d psi = d integral of t^(j+1) w / r^3 dt`,
//!
//! so `N_j = d T_(j-1)`. Without falloff the antiderivatives are
//! `N_0 = t / r`, `T_0 = -d / r`, `T_1 = d (asinh(t / d) - t / r)` and
//! `T_2 = d (r + d^2 / r)`. With falloff, `w / r^3 = 1 / r^3 - 1 / (r (A +
//! r^2))` and `A + r^2 = c^2 + t^2` with `c^2 = A + d^2`, so each one loses
//! an integral of `t^m / (r (c^2 + t^2))`:
//! `J_0 = artanh(sqrt A t / (c r)) / (c sqrt A)` and
//! `J_1 = atan(r / sqrt A) / sqrt A` (the `m = 2, 3` ones are `asinh(t / d)
//! - c^2 J_0` and `r - c^2 J_1`), which gives `N_0 = t / r - d^2 J_0`,
//! `T_0 = -d / r - d J_1`, `T_1 = d (c^2 J_0 - t / r)` and
//! `T_2 = d (d^2 / r + c^2 J_1)`. Every one is exact; no quadrature.

use super::kernel::{Falloff, atan, ln_pos};

/// The antiderivatives of the first moments along one line at distance `d`
/// from the pixel (see the module docs).
#[derive(Clone, Copy, Debug)]
pub struct MomentLine {
    d: f64,
    /// `(sqrt A, c = sqrt(A + d^2))` with falloff.
    fall: Option<(f64, f64)>,
}

/// The antiderivatives at one offset: `n0 = N_0`, and `t0, t1, t2 = T_0,
/// T_1, T_2` (then `N_1 = d T_0` and `N_2 = d T_1`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MomentsAt {
    /// `N_0`: uniform radiosity, towards the line.
    pub n0: f64,
    /// `T_0`: uniform radiosity, along the axis.
    pub t0: f64,
    /// `T_1`: radiosity `t`, along the axis.
    pub t1: f64,
    /// `T_2`: radiosity `t^2`, along the axis.
    pub t2: f64,
}

impl MomentLine {
    /// The line at distance `d > 0` from the pixel, with `falloff`.
    #[inline]
    pub fn new(d: f64, falloff: Option<Falloff>) -> Self {
        MomentLine {
            d,
            fall: falloff.map(|f| {
                let a = f.a();
                (a.sqrt(), (a + d * d).sqrt())
            }),
        }
    }

    /// The line's distance from the pixel.
    pub fn d(&self) -> f64 {
        self.d
    }

    /// The antiderivatives at offset `t` from the foot.
    #[inline]
    pub fn at(&self, t: f64) -> MomentsAt {
        let d = self.d;
        let r = (d * d + t * t).sqrt();
        let (inv_r, at) = (1.0 / r, t.abs());
        match self.fall {
            None => {
                // asinh(t / d), odd, without the cancellation of ln(t + r) for t < 0.
                let asinh = ln_pos((at + r) / d).copysign(t);
                MomentsAt {
                    n0: t * inv_r,
                    t0: -d * inv_r,
                    t1: d * (asinh - t * inv_r),
                    t2: d * (r + d * d * inv_r),
                }
            }
            Some((sa, c)) => {
                // artanh(x) for x = sqrt A t / (c r) is ln((c r + sqrt A |t|)
                // / (d sqrt(c^2 + t^2))) with the sign of t, since
                // (c r)^2 - A t^2 = d^2 (c^2 + t^2): no cancellation near x = 1.
                let q = (c * c + t * t).sqrt();
                let artanh = ln_pos((c * r + sa * at) / (d * q)).copysign(t);
                let c2j0 = c * artanh / sa;
                let j1 = atan(r / sa) / sa;
                MomentsAt {
                    n0: t * inv_r - d * d * c2j0 / (c * c),
                    t0: -d * inv_r - d * j1,
                    t1: d * (c2j0 - t * inv_r),
                    t2: d * (d * d * inv_r + c * c * j1),
                }
            }
        }
    }
}

/// The moment of a stretch, in the edge's frame, turned into the level's:
/// `along_n` towards the edge's line (minus its normal), `along_axis` along
/// `+x` for a horizontal edge or `+y` (image rows, downwards) for a vertical
/// one. Returns `(cos, sin)` with the angle counter-clockwise from `+x` as
/// seen on screen, `+y` up (so `sin` is minus the image-row component).
#[inline]
pub fn to_level(normal: crate::geometry::Normal, along_n: f64, along_axis: f64) -> (f64, f64) {
    let sign = normal.sign();
    if normal.is_vertical_edge() {
        // -n = (-sign, 0), axis = (0, +1 image) = (0, -1 up).
        (-sign * along_n, -along_axis)
    } else {
        // -n = (0, -sign image) = (0, +sign up), axis = (1, 0).
        (along_axis, sign * along_n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::transport::kernel::tests::numeric;

    #[test]
    fn moment_closed_forms_match_quadrature() {
        for fall in [
            None,
            Some(Falloff::new(0.7)),
            Some(Falloff::new(5.0)),
            Some(Falloff::new(300.0)),
            Some(Falloff::new(1e100)),
        ] {
            for (d, t0, t1) in [(2.3, -4.0, 7.5), (0.5, 0.25, 40.0), (17.0, -60.0, -3.0)] {
                let line = MomentLine::new(d, fall);
                let (a, b) = (line.at(t0), line.at(t1));
                let w = |r: f64| fall.map_or(1.0, |f| f.weight(r));
                for j in 0..3 {
                    let tj = |psi: f64| (d * psi.tan()).powi(j);
                    let n = numeric(d, t0, t1, |psi, r| tj(psi) * w(r) * psi.cos());
                    let t = numeric(d, t0, t1, |psi, r| tj(psi) * w(r) * psi.sin());
                    let (gn, gt) = match j {
                        0 => (b.n0 - a.n0, b.t0 - a.t0),
                        1 => (d * (b.t0 - a.t0), b.t1 - a.t1),
                        _ => (d * (b.t1 - a.t1), b.t2 - a.t2),
                    };
                    let scale = 1e-7 * (1.0 + n.abs() + t.abs());
                    assert!(
                        (gn - n).abs() < scale,
                        "{fall:?} d {d} j {j}: N {gn} vs {n}"
                    );
                    assert!(
                        (gt - t).abs() < scale,
                        "{fall:?} d {d} j {j}: T {gt} vs {t}"
                    );
                }
            }
        }
    }
}
