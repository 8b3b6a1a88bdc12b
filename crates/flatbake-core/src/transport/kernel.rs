//! Closed-form flatland integrals over a straight stretch of edge.
//!
//! Seen from a point at perpendicular distance `d > 0` from an edge's line,
//! a point of the line at signed offset `t` from the foot of the
//! perpendicular is at angle `psi = atan(t / d)` and distance
//! `r = sqrt(d^2 + t^2)`, and `cos(theta_y) dy / r = d psi`. The falloff
//! weight is `w = A / (A + r^2) = A cos^2 psi / (A cos^2 psi + d^2)`.
//!
//! * Floor gather (docs/transport.md#floor-gather): `1/(2 pi) * integral of w d psi`, with
//!   `integral w d psi = psi - (d / c) atan(t / c)`, `c = sqrt(A + d^2)`.
//! * Point-to-edge form factor: `1/2 * integral of cos(theta_x) w d psi`, where
//!   `cos(theta_x) = alpha cos psi + beta sin psi` for the receiving point's
//!   normal; `integral cos psi w = s - d^2/(c sqrt A) artanh(sqrt A s / c)`
//!   with `s = sin psi`, and `integral sin psi w = -(u - d/sqrt A atan(sqrt A u / d))`
//!   with `u = cos psi`. Without falloff these reduce to `sin psi` and `-cos psi`.
//!
//! So visible stretches contribute exactly, with no sampling noise; only the
//! patch size and the quadrature over the receiving patch remain.

/// Falloff as the constant `A = falloff^2`, or none.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Falloff {
    a: f64,
    sqrt_a: f64,
}

/// Falloff distances are capped here. At this distance the weight is 1 to
/// double precision for any level that fits in memory, while squaring a
/// distance above about 1.3e154 overflows `A` to infinity and turns the
/// weight into `inf / inf` = NaN (light that was then clamped to black).
pub const MAX_FALLOFF: f64 = 1e100;

impl Falloff {
    /// `distance` is the half-energy distance in pixels; distances above
    /// [`MAX_FALLOFF`] (including infinity) act as [`MAX_FALLOFF`].
    pub fn new(distance: f64) -> Falloff {
        let d = distance.min(MAX_FALLOFF);
        Falloff {
            a: d * d,
            sqrt_a: d,
        }
    }

    /// The constant `A = falloff^2`.
    pub fn a(&self) -> f64 {
        self.a
    }

    /// The weight `A / (A + r^2)` at distance `r`.
    pub fn weight(&self, r: f64) -> f64 {
        self.a / (self.a + r * r)
    }

    /// Distance beyond which the weight is below `w` (`0 < w < 1`).
    pub fn radius_for_weight(&self, w: f64) -> f64 {
        (self.a * (1.0 / w - 1.0)).sqrt()
    }
}

/// How far each edge's light matters under falloff.
///
/// An edge of length `L` whose radiosity is at most `B` adds at most
/// `B * w(r) * min(pi, L / r) / (2 pi)` to a pixel at distance `r` (the
/// weight is largest at the nearest point and the edge subtends at most
/// `min(pi, L / r)`). Beyond the distance where that bound falls below a
/// threshold the pair is not computed. An edge is dropped from a tile
/// altogether only beyond [`Reach::max`], the largest radius of any edge:
/// nearer than that it may still hide a brighter edge behind it.
#[derive(Clone, Debug)]
pub struct Reach {
    /// Per edge: beyond this distance its contribution is below the threshold.
    pub radius: Vec<f64>,
    /// Largest radius over all edges.
    pub max: f64,
}

impl Reach {
    /// Edges per chunk of [`Reach::new`]'s parallel bisection.
    const CHUNK: usize = 4096;

    /// No culling at all.
    pub fn unlimited(edges: usize) -> Reach {
        Reach {
            radius: vec![f64::INFINITY; edges],
            max: f64::INFINITY,
        }
    }

    /// Radii for edges of lengths `len` with largest radiosity `bmax`, for the
    /// bound `scale * B * w(r) * min(pi, L / r) <= threshold` (`scale` is
    /// `1 / (2 pi)` for the gather, `1 / 2` for form factors). No falloff or a
    /// zero threshold means unlimited.
    pub fn new(
        len: &[f64],
        bmax: &[f64],
        falloff: Option<Falloff>,
        scale: f64,
        threshold: f64,
    ) -> Reach {
        let Some(f) = falloff.filter(|_| threshold > 0.0) else {
            return Reach::unlimited(len.len());
        };
        let bound =
            |b: f64, l: f64, r: f64| scale * b * f.weight(r) * std::f64::consts::PI.min(l / r);
        let radius_of = |l: f64, b: f64| {
            // The bound decreases with r: bracket, then bisect.
            let mut hi = f.sqrt_a.max(l).max(1.0);
            while bound(b, l, hi) > threshold {
                hi *= 2.0;
                if hi > 1e12 {
                    return f64::INFINITY;
                }
            }
            let mut lo = 0.0;
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if bound(b, l, mid) > threshold {
                    lo = mid
                } else {
                    hi = mid
                }
            }
            hi
        };
        // Edges of a pixel level share few distinct lengths (and, for the
        // form factors, one unit radiosity): each distinct pair is bisected
        // once per chunk of edges (a level of millions of one-pixel edges
        // spent seconds here), and the chunks are shared out between the
        // threads (the gather's radiosities are mostly distinct: wall noise
        // at 30 % spent 66 ms here on one thread).
        use rayon::prelude::*;
        let radius: Vec<f64> = len
            .par_chunks(Self::CHUNK)
            .zip(bmax.par_chunks(Self::CHUNK))
            .flat_map_iter(|(len, bmax)| {
                let mut known: std::collections::HashMap<(u64, u64), f64> = Default::default();
                len.iter()
                    .zip(bmax)
                    .map(|(&l, &b)| {
                        if b <= 0.0 {
                            return 0.0;
                        }
                        *known
                            .entry((l.to_bits(), b.to_bits()))
                            .or_insert_with(|| radius_of(l, b))
                    })
                    .collect::<Vec<f64>>()
            })
            .collect();
        let max = radius.iter().copied().fold(0.0, f64::max);
        Reach { radius, max }
    }
}

/// `atan(x)`, within a few ulps of `f64::atan`, at a fraction of the cost
/// of the C library's (which the gather called hundreds of millions of times
/// on big levels: a quarter of the bake). Cephes' `atan`: the argument is
/// reduced to `|x| <= 0.66` with `atan(x) = pi/2 - atan(1/x)` or
/// `pi/4 + atan((x - 1) / (x + 1))`, then a degree 4/5 rational function in
/// `x^2`. No table and no slow path.
#[inline(always)]
pub fn atan(x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};
    // tan(3 pi / 8), and the low bits of pi/2 that FRAC_PI_2 drops.
    const T3P8: f64 = 2.414_213_562_373_095;
    const MOREBITS: f64 = 6.123_233_995_736_766e-17;
    const P: [f64; 5] = [
        -8.750_608_600_031_904e-1,
        -1.615_753_718_733_365e1,
        -7.500_855_792_314_705e1,
        -1.228_866_684_490_136_2e2,
        -6.485_021_904_942_025e1,
    ];
    const Q: [f64; 5] = [
        2.485_846_490_142_306_3e1,
        1.650_270_098_316_988_6e2,
        4.328_810_604_912_903e2,
        4.853_903_996_359_137e2,
        1.945_506_571_482_614e2,
    ];
    let a = x.abs();
    // One division for all three cases, selects instead of branches (so a
    // loop of these vectorises).
    let (big, mid) = (a > T3P8, a > 0.66);
    let num = if big {
        -1.0
    } else if mid {
        a - 1.0
    } else {
        a
    };
    let den = if big {
        a
    } else if mid {
        a + 1.0
    } else {
        1.0
    };
    let base = if big {
        FRAC_PI_2
    } else if mid {
        FRAC_PI_4
    } else {
        0.0
    };
    let low = if big {
        MOREBITS
    } else if mid {
        0.5 * MOREBITS
    } else {
        0.0
    };
    let r = num / den;
    let z = r * r;
    let p = (((P[0] * z + P[1]) * z + P[2]) * z + P[3]) * z + P[4];
    let q = ((((z + Q[0]) * z + Q[1]) * z + Q[2]) * z + Q[3]) * z + Q[4];
    let y = base + ((r * (z * p / q) + r) + low);
    y.copysign(x)
}

/// `ln(x)` for positive, finite, normal `x`, within an ulp or so of
/// `f64::ln`, written without branches or calls so that a loop of these
/// vectorises (the C library's `log` is a call per value). fdlibm's
/// `__ieee754_log`: `x = 2^k m` with `m` in `[sqrt(2)/2, sqrt(2))`, then
/// `ln(m) = 2 atanh(f / (2 + f))` with `f = m - 1`, as a degree 14
/// polynomial in `s = f / (2 + f)`; `k ln 2` is added in two parts.
#[inline(always)]
pub fn ln_pos(x: f64) -> f64 {
    // ln 2 in two parts, the high one with its low 32 bits zero.
    const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
    const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
    const LG: [f64; 7] = [
        6.666_666_666_666_735e-1,
        3.999_999_999_940_942e-1,
        2.857_142_874_366_239e-1,
        2.222_219_843_214_978_4e-1,
        1.818_357_216_161_805e-1,
        1.531_383_769_920_937_3e-1,
        1.479_819_860_511_658_6e-1,
    ];
    let bits = x.to_bits();
    let high = bits >> 32;
    let frac = high & 0x000f_ffff;
    // 0x0010_0000 when the mantissa is at least sqrt(2): then m is halved
    // (exponent 0x3fe instead of 0x3ff) and k goes up by one.
    let up = (frac + 0x95f64) & 0x0010_0000;
    let m = f64::from_bits(((frac | (up ^ 0x3ff0_0000)) << 32) | (bits & 0xffff_ffff));
    // k as a float without an integer conversion (none vectorises in AVX2):
    // the biased exponent placed in the mantissa of 2^52.
    let biased = (bits >> 52) + (up >> 20);
    let k = f64::from_bits(0x4330_0000_0000_0000 | biased) - (4_503_599_627_370_496.0 + 1023.0);
    let f = m - 1.0;
    let s = f / (2.0 + f);
    let z = s * s;
    let w = z * z;
    let t1 = w * (LG[1] + w * (LG[3] + w * LG[5]));
    let t2 = z * (LG[0] + w * (LG[2] + w * (LG[4] + w * LG[6])));
    let r = t2 + t1;
    let hfsq = 0.5 * f * f;
    k * LN2_HI - ((hfsq - (s * (hfsq + r) + k * LN2_LO)) - f)
}

/// `atanh(x)` for `-1 < x < 1`, within a few ulps of `f64::atanh`, without
/// the C library's `log1p` call (the form factors' closed form under
/// falloff asks for one per piece end: 4 % of wall noise's bake). The
/// library's `0.5 log1p(2x / (1 - x))`, with `log1p(y)` as
/// `ln(u) y / (u - 1)` for `u = 1 + y` (Goldberg: the rounding of `u` is
/// divided out) and [`ln_pos`] for `ln`.
#[inline(always)]
pub fn atanh(x: f64) -> f64 {
    let y = 2.0 * x / (1.0 - x);
    let u = 1.0 + y;
    let log1p = if u == 1.0 {
        y
    } else {
        ln_pos(u) * y / (u - 1.0)
    };
    0.5 * log1p
}

/// The antiderivatives of the gather integrands along a line at distance `d`:
/// `F(t)` of `w d psi` (uniform radiosity) and `T(t)` of `t w d psi` (the
/// linear part of a patch's radiosity; `integral t w d psi = d/2 ln(r^2 / (A + r^2))`,
/// and `d ln r` without falloff). A stretch `[t0, t1]` of radiosity `a + b t`
/// contributes `(a (F(t1) - F(t0)) + b (T(t1) - T(t0))) / (2 pi)`.
#[derive(Clone, Copy, Debug)]
pub struct GatherLine {
    d: f64,
    /// `(d / c, c)` with falloff.
    fall: Option<(f64, f64)>,
}

impl GatherLine {
    #[inline]
    /// The line at distance `d` from the pixel, with `falloff`.
    pub fn new(d: f64, falloff: Option<Falloff>) -> Self {
        GatherLine {
            d,
            fall: falloff.map(|f| {
                let c = (f.a + d * d).sqrt();
                (d / c, c)
            }),
        }
    }

    /// Antiderivative at offset `t` from the foot.
    #[inline]
    pub fn at(&self, t: f64) -> f64 {
        let psi = atan(t / self.d);
        match self.fall {
            None => psi,
            Some((k, c)) => psi - k * atan(t / c),
        }
    }

    /// Antiderivative of `t w d psi` at offset `t`.
    #[inline]
    pub fn at_linear(&self, t: f64) -> f64 {
        let r2 = self.d * self.d + t * t;
        match self.fall {
            None => 0.5 * self.d * ln_pos(r2),
            // A + r^2 = c^2 + t^2, with c^2 = A + d^2.
            Some((_, c)) => 0.5 * self.d * ln_pos(r2 / (c * c + t * t)),
        }
    }

    /// Antiderivative of `t^2 w d psi` at offset `t`: `t^2 w d psi = d t^2 A
    /// dt / ((d^2 + t^2) (c^2 + t^2))`, which splits into `d (c^2 / (c^2 +
    /// t^2) - d^2 / (d^2 + t^2)) dt` (as `c^2 - d^2 = A`), so the integral is
    /// `d (c atan(t / c) - d atan(t / d))`, and `d (t - d atan(t / d))`
    /// without falloff: the same `atan`s as [`GatherLine::at`].
    #[inline]
    pub fn at_quadratic(&self, t: f64) -> f64 {
        let d = self.d;
        let a = atan(t / d);
        match self.fall {
            None => d * (t - d * a),
            Some((_, c)) => d * (c * atan(t / c) - d * a),
        }
    }

    /// Integral over `[t0, t1]`, computed without cancellation for short stretches.
    #[inline]
    pub fn between(&self, t0: f64, t1: f64) -> f64 {
        let d = self.d;
        let dpsi = (d * (t1 - t0)).atan2(d * d + t0 * t1);
        match self.fall {
            None => dpsi,
            Some((k, c)) => dpsi - k * (c * (t1 - t0)).atan2(c * c + t0 * t1),
        }
    }
}

/// Points at which a pixel needs the gather's closed forms, each on its own
/// line (structure of arrays, so that the loops over them vectorise): point
/// `i` is at offset `t[i]` from the foot of a line at distance `d[i]`, with
/// the falloff constants `c = sqrt(A + d^2)` and `k = d / c` of that line
/// (`1` and `0` without falloff, where they are not used). Points are
/// pushed line by line ([`GatherPoints::line`], then [`GatherPoints::push`]);
/// the per-point line constants are spread out once, before evaluating.
#[derive(Clone, Debug, Default)]
pub struct GatherPoints {
    /// Offset of each point from the foot of its line.
    pub t: Vec<f64>,
    d: Vec<f64>,
    c: Vec<f64>,
    k: Vec<f64>,
    /// Each line and the number of points pushed before it.
    lines: Vec<(usize, GatherLine)>,
}

impl GatherPoints {
    /// Forgets every point and line.
    pub fn clear(&mut self) {
        self.t.clear();
        self.lines.clear();
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// No points.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The points pushed from now on lie on `line`.
    #[inline]
    pub fn line(&mut self, line: &GatherLine) {
        self.lines.push((self.t.len(), *line));
    }

    /// Adds offset `t` on the current line.
    #[inline]
    pub fn push(&mut self, t: f64) {
        self.t.push(t);
    }

    /// Fills the per-point line constants from the lines.
    fn spread(&mut self) {
        let n = self.t.len();
        for v in [&mut self.d, &mut self.c, &mut self.k] {
            v.resize(n, 0.0);
        }
        for (j, (from, line)) in self.lines.iter().enumerate() {
            let to = self.lines.get(j + 1).map_or(n, |l| l.0);
            let (k, c) = line.fall.unwrap_or((0.0, 1.0));
            self.d[*from..to].fill(line.d);
            self.c[*from..to].fill(c);
            self.k[*from..to].fill(k);
        }
    }

    /// [`GatherLine::at`], [`GatherLine::at_linear`] and
    /// [`GatherLine::at_quadratic`] at every point, into `f`, `l` and `q`
    /// (resized to fit). The same numbers as the scalar calls; `falloff`
    /// says which forms the points' lines use.
    pub fn antiderivatives(
        &mut self,
        falloff: bool,
        f: &mut Vec<f64>,
        l: &mut Vec<f64>,
        q: &mut Vec<f64>,
    ) {
        self.spread();
        for v in [&mut *f, &mut *l, &mut *q] {
            v.resize(self.len(), 0.0);
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { self.antiderivatives_avx2(falloff, f, l, q) };
        }
        self.antiderivatives_plain(falloff, f, l, q)
    }

    /// [`GatherPoints::antiderivatives`] compiled for AVX2: four lanes
    /// instead of two. The same operations in the same order (no fused
    /// multiply-add), so the same bits as the plain version.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn antiderivatives_avx2(
        &self,
        falloff: bool,
        f: &mut [f64],
        l: &mut [f64],
        q: &mut [f64],
    ) {
        self.antiderivatives_plain(falloff, f, l, q)
    }

    #[inline(always)]
    fn antiderivatives_plain(&self, falloff: bool, f: &mut [f64], l: &mut [f64], q: &mut [f64]) {
        let n = self.len();
        let (t, d, c, k) = (&self.t[..n], &self.d[..n], &self.c[..n], &self.k[..n]);
        let (f, l, q) = (&mut f[..n], &mut l[..n], &mut q[..n]);
        if falloff {
            for i in 0..n {
                let (a, b) = (atan(t[i] / d[i]), atan(t[i] / c[i]));
                f[i] = a - k[i] * b;
                q[i] = d[i] * (c[i] * b - d[i] * a);
            }
            for i in 0..n {
                let (t, d, c) = (t[i], d[i], c[i]);
                l[i] = 0.5 * d * ln_pos((d * d + t * t) / (c * c + t * t));
            }
        } else {
            for i in 0..n {
                let a = atan(t[i] / d[i]);
                f[i] = a;
                q[i] = d[i] * (t[i] - d[i] * a);
            }
            for i in 0..n {
                let (t, d) = (t[i], d[i]);
                l[i] = 0.5 * d * ln_pos(d * d + t * t);
            }
        }
    }

    /// [`GatherLine::between`] from each point to the point after it in
    /// `ends` (`ends.t[i] > t[i]`, same lines), into `out` (resized to fit):
    /// the integral over each stretch without cancellation, with a
    /// branch-free `atan2` ([`atan2_upper`]) instead of the library's.
    pub fn between(&mut self, ends: &[f64], falloff: bool, out: &mut Vec<f64>) {
        self.spread();
        out.resize(self.len(), 0.0);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { self.between_avx2(ends, falloff, out) };
        }
        self.between_plain(ends, falloff, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn between_avx2(&self, ends: &[f64], falloff: bool, out: &mut [f64]) {
        self.between_plain(ends, falloff, out)
    }

    #[inline(always)]
    fn between_plain(&self, ends: &[f64], falloff: bool, out: &mut [f64]) {
        let n = self.len();
        let (t0, t1, d) = (&self.t[..n], &ends[..n], &self.d[..n]);
        let (c, k, out) = (&self.c[..n], &self.k[..n], &mut out[..n]);
        for i in 0..n {
            let (t0, t1, d) = (t0[i], t1[i], d[i]);
            out[i] = atan2_upper(d * (t1 - t0), d * d + t0 * t1);
        }
        if falloff {
            for i in 0..n {
                let (t0, t1, c) = (t0[i], t1[i], c[i]);
                out[i] -= k[i] * atan2_upper(c * (t1 - t0), c * c + t0 * t1);
            }
        }
    }
}

/// `atan2(y, x)` for `y > 0` (or `y = 0 < x`), without branches: `atan(y /
/// x)` for `x > 0`, else `pi/2 + atan(-x / y)`. Within a few ulps of the
/// library's, as [`atan`] is.
#[inline(always)]
pub fn atan2_upper(y: f64, x: f64) -> f64 {
    let right = x > 0.0;
    let q = if right { y / x } else { -x / y };
    let a = atan(q);
    if right {
        a
    } else {
        std::f64::consts::FRAC_PI_2 + a
    }
}

/// The point-to-edge form factor along a line, for a receiving point with
/// `cos(theta_x) = alpha cos psi + beta sin psi`.
#[derive(Clone, Copy, Debug)]
pub struct FactorLine {
    d: f64,
    alpha: f64,
    beta: f64,
    /// `(A, sqrt A, c, d^2 / (c sqrt A), d / sqrt A)` with falloff.
    fall: Option<(f64, f64, f64, f64, f64)>,
}

impl FactorLine {
    #[inline]
    /// The line at distance `d`, with direction cosines `alpha` and `beta` of the source and target axes, and `falloff`.
    pub fn new(d: f64, alpha: f64, beta: f64, falloff: Option<Falloff>) -> Self {
        FactorLine {
            d,
            alpha,
            beta,
            fall: falloff.map(|f| {
                let c = (f.a + d * d).sqrt();
                (f.a, f.sqrt_a, c, d * d / (c * f.sqrt_a), d / f.sqrt_a)
            }),
        }
    }

    /// Antiderivative of `1/2 cos(theta_x) w d psi` at offset `t`.
    #[inline]
    pub fn at(&self, t: f64) -> f64 {
        let r = (self.d * self.d + t * t).sqrt();
        let (s, u) = (t / r, self.d / r);
        let (ps, qu) = match self.fall {
            None => (s, u),
            Some((_, sa, c, k1, k2)) => {
                (s - k1 * atanh(sa * s / c), u - k2 * atan(sa * u / self.d))
            }
        };
        0.5 * (self.alpha * ps - self.beta * qu)
    }
}

/// Gauss-Legendre nodes on `[0, 1]` and weights summing to 1, for `n` in 1..=8.
pub fn gauss_legendre(n: usize) -> (&'static [f64], &'static [f64]) {
    // Nodes and weights on [-1, 1], mapped below at compile time is awkward;
    // these are the standard tables already mapped to [0, 1].
    const X1: [f64; 1] = [0.5];
    const W1: [f64; 1] = [1.0];
    const X2: [f64; 2] = [0.211_324_865_405_187_1, 0.788_675_134_594_812_9];
    const W2: [f64; 2] = [0.5, 0.5];
    const X3: [f64; 3] = [0.112_701_665_379_258_3, 0.5, 0.887_298_334_620_741_7];
    const W3: [f64; 3] = [
        0.277_777_777_777_777_8,
        0.444_444_444_444_444_4,
        0.277_777_777_777_777_8,
    ];
    const X4: [f64; 4] = [
        0.069_431_844_202_973_71,
        0.330_009_478_207_571_9,
        0.669_990_521_792_428_1,
        0.930_568_155_797_026_3,
    ];
    const W4: [f64; 4] = [
        0.173_927_422_568_727,
        0.326_072_577_431_273,
        0.326_072_577_431_273,
        0.173_927_422_568_727,
    ];
    const X6: [f64; 6] = [
        0.033_765_242_898_423_99,
        0.169_395_306_766_867_7,
        0.380_690_406_958_401_5,
        0.619_309_593_041_598_5,
        0.830_604_693_233_132_3,
        0.966_234_757_101_576,
    ];
    const W6: [f64; 6] = [
        0.085_662_246_189_585_17,
        0.180_380_786_524_069_3,
        0.233_956_967_286_345_5,
        0.233_956_967_286_345_5,
        0.180_380_786_524_069_3,
        0.085_662_246_189_585_17,
    ];
    const X8: [f64; 8] = [
        0.019_855_071_751_231_88,
        0.101_666_761_293_186_6,
        0.237_233_795_041_835_5,
        0.408_282_678_752_175_1,
        0.591_717_321_247_825,
        0.762_766_204_958_164_5,
        0.898_333_238_706_813_4,
        0.980_144_928_248_768_1,
    ];
    const W8: [f64; 8] = [
        0.050_614_268_145_188_13,
        0.111_190_517_226_687_2,
        0.156_853_322_938_943_6,
        0.181_341_891_689_181,
        0.181_341_891_689_181,
        0.156_853_322_938_943_6,
        0.111_190_517_226_687_2,
        0.050_614_268_145_188_13,
    ];
    match n {
        0 | 1 => (&X1, &W1),
        2 => (&X2, &W2),
        3 => (&X3, &W3),
        4 | 5 => (&X4, &W4),
        6 | 7 => (&X6, &W6),
        _ => (&X8, &W8),
    }
}

#[cfg(test)]
pub(in crate::transport) mod tests {
    use super::*;

    /// Midpoint-rule integral of `f` over `[t0, t1]` in `psi`, for checking.
    pub(in crate::transport) fn numeric(
        d: f64,
        t0: f64,
        t1: f64,
        f: impl Fn(f64, f64) -> f64,
    ) -> f64 {
        let (p0, p1) = ((t0 / d).atan(), (t1 / d).atan());
        let n = 200_000;
        let h = (p1 - p0) / n as f64;
        (0..n)
            .map(|i| p0 + (i as f64 + 0.5) * h)
            .map(|psi| f(psi, d / psi.cos()) * h)
            .sum()
    }

    /// No falloff, and falloffs below, near and far above the test lines'
    /// distances.
    fn falloffs() -> [Option<Falloff>; 4] {
        [
            None,
            Some(Falloff::new(0.7)),
            Some(Falloff::new(5.0)),
            Some(Falloff::new(300.0)),
        ]
    }

    #[test]
    fn fast_atan_matches_the_library_atan() {
        let mut worst: f64 = 0.0;
        let mut check = |x: f64| {
            let (a, b) = (atan(x), x.atan());
            let err = (a - b).abs() / b.abs().max(f64::MIN_POSITIVE);
            worst = worst.max(err);
            assert!(err <= 4.0 * f64::EPSILON, "atan({x}) = {a}, library {b}");
        };
        for i in 0..=200_000 {
            let t = i as f64 / 200_000.0;
            // Dense in [-4, 4] (all three reductions and their seams) ...
            check(8.0 * t - 4.0);
            // ... and log-spaced from 1e-12 to 1e12, both signs.
            let x = 10f64.powf(24.0 * t - 12.0);
            check(x);
            check(-x);
        }
        for x in [0.0, 0.66, 2.414_213_562_373_095, 1e300, f64::INFINITY] {
            check(x);
        }
        assert_eq!(atan(-0.0).to_bits(), (-0.0f64).to_bits());
        assert!(atan(f64::NAN).is_nan());
        assert_eq!(atan(f64::NEG_INFINITY), -std::f64::consts::FRAC_PI_2);
        eprintln!("worst relative error {:.2} ulp", worst / f64::EPSILON);
    }

    #[test]
    fn fast_atanh_matches_the_library_atanh() {
        let mut worst: f64 = 0.0;
        let mut check = |x: f64| {
            let (a, b) = (atanh(x), x.atanh());
            let err = (a - b).abs() / b.abs().max(f64::MIN_POSITIVE);
            worst = worst.max(err);
            assert!(err <= 4.0 * f64::EPSILON, "atanh({x}) = {a}, library {b}");
        };
        for i in 0..=400_000 {
            let t = i as f64 / 400_000.0;
            // Evenly over (-1, 1) ...
            check(-0.999_999 + 1.999_998 * t);
            // ... and log-spaced towards 0 and towards 1, on both sides.
            let tiny = 10f64.powf(-1.0 - 299.0 * t);
            check(tiny);
            check(-tiny);
            check(1.0 - 10f64.powf(-1.0 - 14.0 * t));
            check(-(1.0 - 10f64.powf(-1.0 - 14.0 * t)));
        }
        for x in [0.0, 0.5, -0.5, f64::EPSILON, 1.0 - f64::EPSILON / 2.0] {
            check(x);
        }
        assert_eq!(atanh(0.0), 0.0);
        eprintln!("worst relative error {:.2} ulp", worst / f64::EPSILON);
    }

    #[test]
    fn fast_ln_matches_the_library_ln() {
        let mut worst: f64 = 0.0;
        let mut check = |x: f64| {
            let (a, b) = (ln_pos(x), x.ln());
            // Absolute near x = 1, where ln crosses zero; relative elsewhere.
            let err = (a - b).abs() / b.abs().max(1.0);
            worst = worst.max(err);
            assert!(err <= 2.0 * f64::EPSILON, "ln({x}) = {a}, library {b}");
        };
        for i in 0..=400_000 {
            let t = i as f64 / 400_000.0;
            // Dense around 1 (both halvings of the mantissa and their seam) ...
            check(0.5 + 1.5 * t);
            // ... and log-spaced from 1e-300 to 1e300.
            check(10f64.powf(600.0 * t - 300.0));
        }
        for x in [
            1.0,
            2.0,
            0.5,
            std::f64::consts::SQRT_2,
            std::f64::consts::FRAC_1_SQRT_2,
            f64::MIN_POSITIVE,
            f64::MAX,
            1.0 + f64::EPSILON,
            1.0 - f64::EPSILON / 2.0,
        ] {
            check(x);
        }
        assert_eq!(ln_pos(1.0), 0.0);
        eprintln!("worst error {:.2} ulp", worst / f64::EPSILON);
    }

    #[test]
    fn reach_radius_is_where_the_bound_meets_the_threshold() {
        let f = Falloff::new(20.0);
        let reach = Reach::new(
            &[4.0, 40.0, 4.0],
            &[10.0, 10.0, 0.0],
            Some(f),
            0.5 / std::f64::consts::PI,
            1e-3,
        );
        for (i, (l, b)) in [(4.0, 10.0), (40.0, 10.0)].into_iter().enumerate() {
            let r = reach.radius[i];
            let bound = |r: f64| {
                10.0 * f.weight(r) * std::f64::consts::PI.min(l / r) / std::f64::consts::TAU
            };
            assert!((bound(r) - 1e-3).abs() < 1e-9, "{r}");
            assert!(b > 0.0);
        }
        assert!(
            reach.radius[1] > reach.radius[0],
            "longer edges reach farther"
        );
        assert_eq!(reach.radius[2], 0.0, "dark edges reach nowhere");
        assert_eq!(reach.max, reach.radius[1]);
        assert!(
            Reach::new(&[4.0], &[1.0], None, 1.0, 1e-3)
                .max
                .is_infinite()
        );
    }

    #[test]
    fn gauss_weights_sum_to_one_and_integrate_cubics() {
        for n in 1..=8 {
            let (x, w) = gauss_legendre(n);
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-14, "n = {n}");
            let exact = 0.25; // integral of t^3 on [0, 1]
            let got: f64 = x.iter().zip(w).map(|(x, w)| w * x * x * x).sum();
            if x.len() >= 2 {
                assert!((got - exact).abs() < 1e-14, "n = {n}");
            }
        }
    }

    #[test]
    fn gather_closed_forms_match_quadrature() {
        for fall in falloffs() {
            let (d, t0, t1) = (2.3, -4.0, 7.5);
            let line = GatherLine::new(d, fall);
            let want = numeric(d, t0, t1, |_, r| fall.map_or(1.0, |f| f.weight(r)));
            assert!((line.at(t1) - line.at(t0) - want).abs() < 1e-8, "{fall:?}");
            assert!((line.between(t0, t1) - want).abs() < 1e-8, "{fall:?}");
        }
    }

    #[test]
    fn linear_gather_closed_form_matches_quadrature() {
        for fall in falloffs() {
            let (d, t0, t1) = (2.3, -4.0, 7.5);
            let line = GatherLine::new(d, fall);
            let want = numeric(d, t0, t1, |psi, r| {
                d * psi.tan() * fall.map_or(1.0, |f| f.weight(r))
            });
            assert!(
                (line.at_linear(t1) - line.at_linear(t0) - want).abs() < 1e-7,
                "{fall:?}"
            );
        }
    }

    #[test]
    fn quadratic_gather_closed_form_matches_quadrature() {
        for fall in falloffs() {
            let (d, t0, t1) = (2.3, -4.0, 7.5);
            let line = GatherLine::new(d, fall);
            let want = numeric(d, t0, t1, |psi, r| {
                let t = d * psi.tan();
                t * t * fall.map_or(1.0, |f| f.weight(r))
            });
            let got = line.at_quadratic(t1) - line.at_quadratic(t0);
            assert!(
                (got - want).abs() < 1e-6 * want.abs(),
                "{fall:?}: {got} vs {want}"
            );
        }
    }

    /// The batched antiderivatives are the scalar ones, bit for bit, on
    /// lines with and without falloff.
    #[test]
    fn batched_antiderivatives_are_the_scalar_ones() {
        for fall in [None, Some(Falloff::new(3.0)), Some(Falloff::new(40.0))] {
            let mut pts = GatherPoints::default();
            let lines: Vec<GatherLine> = [0.5, 2.0, 17.25, 300.0]
                .iter()
                .map(|&d| GatherLine::new(d, fall))
                .collect();
            let ts = [-50.0, -3.5, -0.25, 0.0, 0.75, 4.0, 123.0];
            for line in &lines {
                pts.line(line);
                for &t in &ts {
                    pts.push(t);
                }
            }
            let (mut f, mut l, mut q) = (Vec::new(), Vec::new(), Vec::new());
            pts.antiderivatives(fall.is_some(), &mut f, &mut l, &mut q);
            let mut i = 0;
            for line in &lines {
                for &t in &ts {
                    assert_eq!(f[i].to_bits(), line.at(t).to_bits(), "{fall:?} at {t}");
                    assert_eq!(
                        l[i].to_bits(),
                        line.at_linear(t).to_bits(),
                        "{fall:?} at {t}"
                    );
                    assert_eq!(
                        q[i].to_bits(),
                        line.at_quadratic(t).to_bits(),
                        "{fall:?} at {t}"
                    );
                    i += 1;
                }
            }
            // Stretches between consecutive offsets, against the scalar form.
            let mut em = GatherPoints::default();
            let mut ends = Vec::new();
            for line in &lines {
                for w in ts.windows(2) {
                    em.line(line);
                    em.push(w[0]);
                    ends.push(w[1]);
                }
            }
            let mut g = Vec::new();
            em.between(&ends, fall.is_some(), &mut g);
            let mut i = 0;
            for line in &lines {
                for w in ts.windows(2) {
                    let want = line.between(w[0], w[1]);
                    // Angles: a few ulps of 1 absolute (the fast atan is within 4 ulps).
                    assert!(
                        (g[i] - want).abs() <= 1e-15 + 1e-13 * want.abs(),
                        "{fall:?} {w:?}: {} vs {want}",
                        g[i]
                    );
                    i += 1;
                }
            }
        }
    }

    #[test]
    fn factor_closed_forms_match_quadrature() {
        for fall in falloffs() {
            for (alpha, beta) in [(1.0, 0.0), (0.0, 1.0), (0.0, -1.0), (0.6, 0.8)] {
                let (d, t0, t1) = (1.7, -3.0, 9.0);
                let line = FactorLine::new(d, alpha, beta, fall);
                let want = numeric(d, t0, t1, |psi, r| {
                    0.5 * (alpha * psi.cos() + beta * psi.sin()) * fall.map_or(1.0, |f| f.weight(r))
                });
                assert!(
                    (line.at(t1) - line.at(t0) - want).abs() < 1e-8,
                    "{fall:?} {alpha} {beta}"
                );
            }
        }
    }
}
