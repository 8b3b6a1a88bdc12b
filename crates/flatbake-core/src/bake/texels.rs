//! Texel density and wall faces: the lightmap at `N` texels per painted
//! pixel (along each axis), each texel the light averaged over its area,
//! and what solid texels carry ([`Walls`]).
//!
//! The exact core is not touched. For `N >= 1` the level is baked
//! *upscaled*: every painted pixel becomes `k x k` pixels, `k = N * s` with
//! `s` quadrature points per texel side ([`TexelOptions::samples`]), and
//! every length setting (patch length, falloff) is scaled by `k`, so the
//! patches, their quadrature points and the solve are the same scene in
//! other units (the flatland kernel is scale invariant: light depends on
//! angles only). The pixel centres of the upscaled level are then the
//! midpoints of an `s x s` grid on each texel, and a texel's value is their
//! mean: the composite midpoint rule of its area average, whose error
//! docs/transport.md bounds. For `N = 1/m < 1` a texel is a block of
//! `m x m` painted pixels (baked upscaled by `s`), and its value is the mean
//! over the block's floor points: the light averaged over the texel's floor
//! area. Density 1 with one sample and lit walls is the plain bake, byte for
//! byte.
//!
//! The outputs encode the [`TexelBake::level`], the level at texel
//! resolution (cells replicated for `N >= 1`; for `N < 1` a texel is floor
//! when it holds any floor pixel, and its [`Level::floor_fraction`] is the
//! share of its painted pixels that are floor, the coverage the outputs
//! write), so padding, the lit image, layers and the relight cache all work
//! on texels. The directional moments
//! ([`Settings::directional`]) are integrals of the light like the mean, and
//! are averaged over each texel's floor points the same way.

use std::borrow::Cow;

use super::{BakeError, Baked, Directional, Responses, Settings, bake_with_progress};
use crate::geometry::{self, Geometry};
use crate::level::{Cell, Level};

/// Largest `N` and largest `m` of `1/m` texels per pixel.
pub const MAX_DENSITY: u32 = 16;

/// Most quadrature points per texel side.
pub const MAX_SAMPLES: u32 = 8;

/// Texels per painted pixel, along each axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Density {
    /// `N` texels per pixel (1 to [`MAX_DENSITY`]): each pixel is `N x N` texels.
    Up(u32),
    /// One texel per `m` pixels (2 to [`MAX_DENSITY`]): each texel is `m x m` pixels.
    Down(u32),
}

impl Default for Density {
    fn default() -> Self {
        Density::Up(1)
    }
}

/// A texel density that is not one flatbake bakes.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "texels per pixel is a whole number from 1 to {MAX_DENSITY} or a fraction from 1/2 to 1/{MAX_DENSITY} (such as 1/4, 0.25, 1, 2, 8), not {0}"
)]
pub struct DensityError(pub String);

impl Density {
    /// Parses "2", "1/4", "0.25" (a whole number or the inverse of one).
    pub fn parse(s: &str) -> Result<Density, DensityError> {
        let err = || DensityError(s.to_string());
        let t = s.trim();
        let whole = |v: f64| (v.round() - v).abs() < 1e-9 && v >= 1.0;
        let value = if let Some((a, b)) = t.split_once('/') {
            let a: f64 = a.trim().parse().map_err(|_| err())?;
            let b: f64 = b.trim().parse().map_err(|_| err())?;
            if !(a.is_finite() && b.is_finite() && b != 0.0) {
                return Err(err());
            }
            a / b
        } else {
            t.parse::<f64>().map_err(|_| err())?
        };
        if !value.is_finite() || value <= 0.0 {
            return Err(err());
        }
        let n = value.round();
        if value >= 1.0 && whole(value) && n <= MAX_DENSITY as f64 {
            return Ok(Density::Up(n as u32));
        }
        let inv = 1.0 / value;
        let m = inv.round();
        if value < 1.0 && (m - inv).abs() < 1e-6 * inv && m <= MAX_DENSITY as f64 {
            return Ok(Density::Down(m as u32));
        }
        Err(err())
    }

    /// Texels per pixel as a number (0.25 for one texel per 4 pixels).
    pub fn value(self) -> f64 {
        match self {
            Density::Up(n) => n as f64,
            Density::Down(m) => 1.0 / m as f64,
        }
    }

    /// As the stamp and the docs spell it: "4", "1/4".
    pub fn name(self) -> String {
        match self {
            Density::Up(n) => n.to_string(),
            Density::Down(m) => format!("1/{m}"),
        }
    }

    /// The texel grid of a `width x height` painted level: `N` times its
    /// size, or `1/m` of it rounded up (the last texels of a row or column
    /// then cover the pixels that are left).
    pub fn texels(self, width: usize, height: usize) -> (usize, usize) {
        match self {
            Density::Up(n) => (
                width.saturating_mul(n as usize),
                height.saturating_mul(n as usize),
            ),
            Density::Down(m) => (width.div_ceil(m as usize), height.div_ceil(m as usize)),
        }
    }

    /// The default quadrature points per texel side: 1 up to one texel per
    /// pixel (then a texel is a pixel, or holds whole pixels each sampled at
    /// its centre), 2 above (a texel is part of a pixel, and a shadow edge
    /// crossing it is averaged, not sampled at one point).
    pub fn default_samples(self) -> u32 {
        match self {
            Density::Up(n) if n >= 2 => 2,
            _ => 1,
        }
    }
}

/// What solid texels of the lightmap carry.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum Walls {
    /// Every solid texel 0.
    Dark,
    /// Exposed faces of emitters carry their emission; other solid texels 0.
    Glow,
    /// Every exposed wall face texel carries the solved radiosity `B` of
    /// the face (emission plus reflected light); inner solid texels 0. The
    /// default, and what a bake always wrote.
    #[default]
    Lit,
}

impl Walls {
    /// The name on the command line and in the stamp.
    pub fn name(self) -> &'static str {
        match self {
            Walls::Dark => "dark",
            Walls::Glow => "glow",
            Walls::Lit => "lit",
        }
    }
}

/// How the lightmap's texels are laid out and what walls carry.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct TexelOptions {
    /// Texels per painted pixel. Default 1.
    pub density: Density,
    /// Quadrature points per texel side (1 to [`MAX_SAMPLES`]); `None`:
    /// [`Density::default_samples`].
    pub samples: Option<u32>,
    /// What solid texels carry. Default [`Walls::Lit`].
    pub walls: Walls,
}

impl TexelOptions {
    /// The quadrature points per texel side.
    pub fn samples(&self) -> u32 {
        self.samples
            .unwrap_or_else(|| self.density.default_samples())
            .clamp(1, MAX_SAMPLES)
    }

    /// Painted pixel to quadrature pixel: the level is baked upscaled by this.
    pub fn scale(&self) -> usize {
        let s = self.samples() as usize;
        match self.density {
            Density::Up(n) => n as usize * s,
            Density::Down(_) => s,
        }
    }

    /// Side of a texel in quadrature pixels.
    fn block(&self) -> usize {
        let s = self.samples() as usize;
        match self.density {
            Density::Up(_) => s,
            Density::Down(m) => m as usize * s,
        }
    }

    /// True when the plain bake is the answer, byte for byte.
    pub fn is_plain(&self) -> bool {
        self.density == Density::Up(1) && self.samples() == 1 && self.walls == Walls::Lit
    }

    /// The options as the stamp spells them: empty at the defaults, so
    /// that stamps of bakes that do not use them stay up to date.
    pub fn fingerprint(&self) -> String {
        let mut s = String::new();
        if self.density != Density::default() {
            s.push_str(&format!(" texels-per-pixel {}", self.density.name()));
        }
        if let Some(n) = self.samples
            && n != self.density.default_samples()
        {
            s.push_str(&format!(" texel-samples {n}"));
        }
        if self.walls != Walls::Lit {
            s.push_str(&format!(" walls {}", self.walls.name()));
        }
        s
    }
}

/// A bake at a texel density.
pub struct TexelBake {
    /// The bake of the level upscaled by [`TexelBake::scale`]: its geometry,
    /// patches and radiosity are in quadrature pixels; its lightmap and
    /// responses are at texel resolution (those of [`TexelBake::level`]).
    pub baked: Baked,
    /// The level at texel resolution: what the outputs encode.
    pub level: Level,
    /// Painted pixels to the baked level's pixels.
    pub scale: usize,
}

impl TexelBake {
    /// The walls traced in painted pixels (for occluder polygons).
    pub fn painted_geometry(&self, painted: &Level) -> Cow<'_, Geometry> {
        if self.scale == 1 {
            Cow::Borrowed(&self.baked.geometry)
        } else {
            Cow::Owned(geometry::trace(painted))
        }
    }
}

/// `level` upscaled by `k`: every pixel becomes `k x k` pixels of the same
/// cell and albedo.
pub fn upscale(level: &Level, k: usize) -> Level {
    if k == 1 {
        return level.clone();
    }
    let (w, h) = (level.width * k, level.height * k);
    let mut cells = Vec::with_capacity(w * h);
    let mut albedo = Vec::with_capacity(w * h);
    for y in 0..h {
        let row = (y / k) * level.width;
        for x in 0..w {
            cells.push(level.cells[row + x / k]);
            albedo.push(level.albedo[row + x / k]);
        }
    }
    Level {
        width: w,
        height: h,
        cells,
        albedo,
        ..level.clone()
    }
}

/// The settings of the bake upscaled by `k`: every length times `k`.
pub fn scaled_settings(settings: &Settings, k: usize) -> Settings {
    let mut s = settings.clone();
    s.knobs.patch_len *= k as f64;
    s.falloff = settings.falloff.map(|f| f * k as f64);
    s.unit = settings.unit.max(1) * k;
    s
}

/// Bakes `level` at the texel layout `texels` ([`bake_with_progress`]
/// otherwise).
pub fn bake_texels(
    level: &Level,
    settings: &Settings,
    texels: &TexelOptions,
    progress: &dyn Fn(&str),
    gathered: &(dyn Fn(f64) + Sync),
) -> Result<TexelBake, BakeError> {
    if texels.is_plain() {
        let baked = bake_with_progress(level, settings, progress, gathered)?;
        return Ok(TexelBake {
            baked,
            level: level.clone(),
            scale: 1,
        });
    }
    let k = texels.scale();
    // The upscaled level is allocated before the bake's own memory check:
    // refused here, from its pixels alone, when that is already too much.
    let pixels = (level.width as u64 * k as u64).saturating_mul(level.height as u64 * k as u64);
    let floor = super::memory::BASE.saturating_add(pixels.saturating_mul(super::memory::PER_PIXEL));
    if let Some(limit) = settings.max_memory
        && floor > limit
    {
        return Err(BakeError::TooMuchMemory {
            estimate: super::MemoryEstimate {
                bytes: floor,
                pixels,
                factor_entries: 0,
            },
            limit,
        });
    }
    let fine = upscale(level, k);
    let mut baked = bake_with_progress(&fine, &scaled_settings(settings, k), progress, gathered)?;
    let layout = Layout::new(level, &fine, texels);
    let texel_level = layout.texel_level(level, &fine);
    if let Some(r) = &baked.responses {
        let images = r
            .images
            .iter()
            .enumerate()
            .map(|(i, img)| {
                let m = r.emitters[i / r.rho_classes];
                layout.filter(img, |cell| glow_unit(cell, m))
            })
            .collect();
        // The moments are integrals of the light like the mean: a texel's
        // are their average over its floor points.
        let moments = r
            .moments
            .iter()
            .map(|img| {
                let [c, s] = [0, 1].map(|k| {
                    let v: Vec<f32> = img.iter().map(|m| m[k]).collect();
                    layout.floor_mean(&v)
                });
                c.into_iter().zip(s).map(|(c, s)| [c, s]).collect()
            })
            .collect();
        let resp = Responses {
            width: layout.tw,
            height: layout.th,
            images,
            moments,
            ..r.clone()
        };
        // As in the plain bake: the lightmap is the responses' sum, so that
        // layers and a relight add up to it exactly.
        let e: Vec<[f64; 3]> = resp
            .emitters
            .iter()
            .map(|&m| level.materials[m].emission)
            .collect();
        baked.lightmap.rgb = resp.combine(&e);
        if baked.directional.is_some() {
            baked.directional = resp.combine_moments(&e);
        }
        baked.responses = Some(resp);
    } else {
        let rgb = &baked.lightmap.rgb;
        let ch = |c: usize| {
            let img: Vec<f32> = rgb.iter().map(|p| p[c]).collect();
            layout.filter(&img, |cell| glow_emission(level, cell, c))
        };
        let [r, g, b] = [ch(0), ch(1), ch(2)];
        baked.lightmap.rgb = (0..r.len()).map(|i| [r[i], g[i], b[i]]).collect();
        if let Some(d) = &mut baked.directional {
            *d = layout.floor_moments(d);
        }
    }
    baked.lightmap.width = layout.tw;
    baked.lightmap.height = layout.th;
    // The report speaks of the level as painted: its painted and texel
    // sizes, the points per texel, the falloff as given, the power per
    // painted pixel of wall (the floor counts stay the points gathered).
    let report = &mut baked.report;
    report.size = [layout.tw, layout.th];
    report.painted_size = [level.width, level.height];
    report.texels_per_pixel = texels.density.value();
    report.points_per_texel = u32::try_from(layout.block * layout.block).unwrap_or(u32::MAX);
    report.counts.floor_texels = texel_level
        .cells
        .iter()
        .filter(|&&c| c == Cell::Floor)
        .count();
    report.falloff = settings.falloff;
    let kf = k as f64;
    report.energy.emitted /= kf;
    report.energy.absorbed /= kf;
    report.energy.escaped /= kf;
    Ok(TexelBake {
        baked,
        level: texel_level,
        scale: k,
    })
}

/// What [`Walls::Glow`] writes on an emitter's own unit response.
fn glow_unit(cell: Cell, emitter: usize) -> f32 {
    match cell {
        Cell::Solid(m) if m as usize == emitter => 1.0,
        _ => 0.0,
    }
}

/// What [`Walls::Glow`] writes in channel `c` of a solid cell.
fn glow_emission(level: &Level, cell: Cell, c: usize) -> f32 {
    match cell {
        Cell::Solid(m) => level.materials[m as usize].emission[c] as f32,
        _ => 0.0,
    }
}

/// How the baked (quadrature) pixels map onto texels.
struct Layout {
    /// Quadrature level width and height.
    fw: usize,
    fh: usize,
    /// Texel grid.
    tw: usize,
    th: usize,
    /// Texel side in quadrature pixels.
    block: usize,
    walls: Walls,
    cells: Vec<Cell>,
    /// Painted pixels to quadrature pixels.
    k: usize,
    /// The painted level's size and cells.
    pw: usize,
    ph: usize,
    painted: Vec<Cell>,
    /// `m` of density `1/m`: a texel's side in painted pixels.
    down: Option<usize>,
}

impl Layout {
    fn new(level: &Level, fine: &Level, texels: &TexelOptions) -> Layout {
        let block = texels.block();
        let (tw, th) = texel_size(texels, level);
        Layout {
            fw: fine.width,
            fh: fine.height,
            tw,
            th,
            block,
            walls: texels.walls,
            cells: fine.cells.clone(),
            k: texels.scale(),
            pw: level.width,
            ph: level.height,
            painted: level.cells.clone(),
            down: match texels.density {
                Density::Down(m) => Some(m as usize),
                Density::Up(_) => None,
            },
        }
    }

    /// Below one texel per pixel: for each texel, the fraction of the
    /// painted pixels it holds that are floor (the last texels of a row or
    /// column hold fewer pixels). `None` above, where a texel lies in one
    /// painted pixel and is all floor or none.
    fn floor_fraction(&self) -> Option<Vec<f32>> {
        let m = self.down?;
        let mut out = vec![0f32; self.tw * self.th];
        for ty in 0..self.th {
            for tx in 0..self.tw {
                let (x0, y0) = (tx * m, ty * m);
                let (x1, y1) = ((x0 + m).min(self.pw), (y0 + m).min(self.ph));
                let mut floor = 0usize;
                for y in y0..y1 {
                    for x in x0..x1 {
                        floor += usize::from(self.painted[y * self.pw + x] == Cell::Floor);
                    }
                }
                let all = (x1 - x0) * (y1 - y0);
                out[ty * self.tw + tx] = (floor as f64 / all.max(1) as f64) as f32;
            }
        }
        Some(out)
    }

    /// For quadrature pixel `i` of a solid painted pixel: the quadrature
    /// pixels on the pixel's exposed sides (those whose neighbour across is
    /// free, inside the image) in the same row or column as `i`.
    fn face_sources(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        let (x, y, k) = (i % self.fw, i / self.fw, self.k);
        let (px, py) = (x / k, y / k);
        let free = move |dx: isize, dy: isize| {
            let (qx, qy) = (px as isize + dx, py as isize + dy);
            qx >= 0
                && qy >= 0
                && (qx as usize) < self.pw
                && (qy as usize) < self.ph
                && self.painted[qy as usize * self.pw + qx as usize].is_free()
        };
        [
            (free(-1, 0), px * k, y),
            (free(1, 0), px * k + k - 1, y),
            (free(0, -1), x, py * k),
            (free(0, 1), x, py * k + k - 1),
        ]
        .into_iter()
        .filter(|s| s.0)
        .map(move |(_, sx, sy)| sy * self.fw + sx)
    }

    /// The mean of `img` over [`Layout::face_sources`]: the light of the
    /// face(s) at this point's position along them. So every point of a
    /// wall pixel with an exposed face carries its face's light, as the
    /// whole pixel does at density 1. `None` inside walls.
    fn face_value(&self, i: usize, img: &[f32]) -> Option<f64> {
        let (mut sum, mut n) = (0f64, 0u32);
        for j in self.face_sources(i) {
            sum += img[j] as f64;
            n += 1;
        }
        (n > 0).then(|| sum / n as f64)
    }

    /// The quadrature pixels of texel `(tx, ty)`, clipped to the level.
    fn pixels(&self, tx: usize, ty: usize) -> impl Iterator<Item = usize> + '_ {
        let b = self.block;
        let (x0, y0) = (tx * b, ty * b);
        let (x1, y1) = ((x0 + b).min(self.fw), (y0 + b).min(self.fh));
        (y0..y1).flat_map(move |y| (x0..x1).map(move |x| y * self.fw + x))
    }

    /// One image of the baked level at texel resolution: floor texels the
    /// mean over their floor points; solid texels (no floor point) the mean
    /// over their exposed wall points of what [`Walls`] writes there (the
    /// baked image for lit walls, `glow(cell)` for glowing ones); the rest 0.
    fn filter(&self, img: &[f32], glow: impl Fn(Cell) -> f32) -> Vec<f32> {
        let mut out = vec![0f32; self.tw * self.th];
        for ty in 0..self.th {
            for tx in 0..self.tw {
                let (mut floor, mut nf) = (0f64, 0u32);
                let (mut wall, mut nw) = (0f64, 0u32);
                for i in self.pixels(tx, ty) {
                    match self.cells[i] {
                        Cell::Floor => {
                            floor += img[i] as f64;
                            nf += 1;
                        }
                        c @ Cell::Solid(_) => {
                            if let Some(v) = self.face_value(i, img) {
                                wall += match self.walls {
                                    Walls::Lit => v,
                                    Walls::Glow => glow(c) as f64,
                                    Walls::Dark => 0.0,
                                };
                                nw += 1;
                            }
                        }
                        _ => {}
                    }
                }
                out[ty * self.tw + tx] = if nf > 0 {
                    (floor / nf as f64) as f32
                } else if nw > 0 {
                    (wall / nw as f64) as f32
                } else {
                    0.0
                };
            }
        }
        out
    }

    /// The mean of `img` over each texel's floor points; 0 on texels
    /// without floor.
    fn floor_mean(&self, img: &[f32]) -> Vec<f32> {
        let mut out = vec![0f32; self.tw * self.th];
        for ty in 0..self.th {
            for tx in 0..self.tw {
                let (mut sum, mut n) = (0f64, 0u32);
                for i in self.pixels(tx, ty) {
                    if self.cells[i] == Cell::Floor {
                        sum += img[i] as f64;
                        n += 1;
                    }
                }
                if n > 0 {
                    out[ty * self.tw + tx] = (sum / n as f64) as f32;
                }
            }
        }
        out
    }

    /// The moments of the baked level at texel resolution: per texel their
    /// mean over its floor points (the area average of the light's
    /// moments, as the lightmap's texel is of its mean).
    fn floor_moments(&self, d: &Directional) -> Directional {
        let mut out = Directional::zero(self.tw, self.th);
        for (src, dst) in [(&d.cos, &mut out.cos), (&d.sin, &mut out.sin)] {
            for c in 0..3 {
                let img: Vec<f32> = src.iter().map(|v| v[c]).collect();
                for (t, v) in self.floor_mean(&img).into_iter().enumerate() {
                    dst[t][c] = v;
                }
            }
        }
        out
    }

    /// The level at texel resolution: for each texel, floor if any of its
    /// points is floor, else the material of its first exposed (or else
    /// first) solid point, else void; albedo the mean over its floor points.
    fn texel_level(&self, level: &Level, fine: &Level) -> Level {
        let n = self.tw * self.th;
        let mut cells = vec![Cell::Void; n];
        let mut albedo = vec![[0f32; 3]; n];
        for ty in 0..self.th {
            for tx in 0..self.tw {
                let t = ty * self.tw + tx;
                let (mut sum, mut nf) = ([0f64; 3], 0u32);
                let (mut exposed, mut solid) = (None, None);
                for i in self.pixels(tx, ty) {
                    match fine.cells[i] {
                        Cell::Floor => {
                            for c in 0..3 {
                                sum[c] += fine.albedo[i][c] as f64;
                            }
                            nf += 1;
                        }
                        c @ Cell::Solid(_) => {
                            solid = solid.or(Some(c));
                            if self.face_sources(i).next().is_some() {
                                exposed = exposed.or(Some(c));
                            }
                        }
                        Cell::Void => {}
                    }
                }
                if nf > 0 {
                    cells[t] = Cell::Floor;
                    albedo[t] = sum.map(|v| (v / nf as f64) as f32);
                } else if let Some(c) = exposed.or(solid) {
                    cells[t] = c;
                }
            }
        }
        Level {
            width: self.tw,
            height: self.th,
            cells,
            albedo,
            floor_fraction: self.floor_fraction(),
            ..level.clone()
        }
    }
}

/// The texel grid of `level` at `texels`' density ([`Density::texels`]).
pub fn texel_size(texels: &TexelOptions, level: &Level) -> (usize, usize) {
    texels.density.texels(level.width, level.height)
}
