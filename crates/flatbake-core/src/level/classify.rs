//! Classifying pixels: each distinct colour resolved once against the
//! palette (wall, emitter, floor albedo, or a near miss worth a warning).

use std::collections::{BTreeMap, HashMap};
use std::hash::{BuildHasherDefault, Hasher};

use crate::level::material::{MaterialKind, srgb_to_linear};
use crate::level::palette::{ColorClass, Palette, PaletteOrigin};
use crate::level::{Cell, Level, NEAR_MISS_DISTANCE};

/// How one distinct colour resolves; computed once per colour and cached.
#[derive(Clone, Copy, Debug)]
enum Resolved {
    /// Index into `palette.solids`.
    Solid(usize),
    Floor([f32; 3]),
    /// Floor, but within [`NEAR_MISS_DISTANCE`] of `palette.solids[solid]`.
    NearMiss {
        solid: usize,
        diff: u8,
        albedo: [f32; 3],
    },
}

fn resolve(palette: &Palette, rgb: [u8; 3], lut: &[f32; 256]) -> Resolved {
    let floor_albedo = |i: usize| match palette.floors.get(i) {
        Some(f) => f.albedo.map(|a| a as f32),
        None => rgb.map(|c| lut[c as usize]),
    };
    let class = palette.classify(rgb).or_else(|| {
        // A tolerance snaps near-misses to the nearest palette colour of any
        // kind: an anti-aliased pixel closest to a listed floor is that floor.
        let t = palette.settings.tolerance.filter(|&t| t > 0)?;
        palette.nearest(rgb, t).map(|(class, _)| class)
    });
    match class {
        Some(ColorClass::Solid(i)) => Resolved::Solid(i),
        Some(ColorClass::Floor(i)) => Resolved::Floor(floor_albedo(i)),
        None => {
            let albedo = rgb.map(|c| lut[c as usize]);
            match palette.nearest(rgb, NEAR_MISS_DISTANCE) {
                Some((ColorClass::Solid(solid), diff)) => Resolved::NearMiss {
                    solid,
                    diff,
                    albedo,
                },
                _ => Resolved::Floor(albedo),
            }
        }
    }
}

/// Near-miss pixels of one palette colour, gathered for a single warning.
struct NearMisses {
    pixels: u64,
    colors: u64,
    example: (usize, usize, [u8; 3]),
    min: (usize, usize),
    max: (usize, usize),
    max_diff: u8,
}

/// Hashes a packed `0x00bbggrr` colour with one multiply: the keys are
/// small integers, so SipHash's flood resistance buys nothing here and its
/// cost shows on 2048 x 2048 levels with many colours.
#[derive(Default)]
struct ColorHasher(u64);

impl Hasher for ColorHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ b as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }
    fn write_u32(&mut self, n: u32) {
        self.0 = (n as u64)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .rotate_right(29);
    }
}

pub(super) fn classify_pixels(
    name: &str,
    width: usize,
    height: usize,
    rgba: &[u8],
    palette: &Palette,
) -> Level {
    let mut warnings = Vec::new();
    let (width, height) = match width.checked_mul(height) {
        Some(_) => (width, height),
        None => {
            warnings.push(format!(
                "level size {width} x {height} overflows; treated as empty"
            ));
            (0, 0)
        }
    };
    let n = width * height;
    let available = rgba.len() / 4;
    if available < n {
        warnings.push(format!(
            "pixel data holds {available} pixels but the level is {width} x {height} = {n}; the rest is void"
        ));
    }

    let lut: [f32; 256] = std::array::from_fn(|c| srgb_to_linear(c as u8) as f32);
    let mut cache: HashMap<u32, Resolved, BuildHasherDefault<ColorHasher>> = HashMap::default();
    // Material slot of each palette solid in first-use order; remapped to
    // palette order at the end so indices do not depend on where in the
    // image a material first appears.
    let mut slot_of: Vec<Option<u16>> = vec![None; palette.solids.len()];
    let mut used: Vec<usize> = Vec::new();
    let mut overflowed = false;
    let mut near: BTreeMap<usize, NearMisses> = BTreeMap::new();

    let mut cells = Vec::with_capacity(n);
    let mut albedo = Vec::with_capacity(n);
    // Levels are painted in flat areas, so most pixels repeat their left
    // neighbour: remember the last answer and skip the hash lookup.
    let mut last: Option<(u32, Resolved)> = None;

    for (i, px) in rgba.chunks_exact(4).take(n).enumerate() {
        if px[3] == 0 {
            cells.push(Cell::Void);
            albedo.push([0.0; 3]);
            continue;
        }
        let key = u32::from_le_bytes([px[0], px[1], px[2], 0]);
        let (resolved, first_time) = match last {
            Some((k, r)) if k == key => (r, false),
            _ => {
                let mut first_time = false;
                let r = *cache.entry(key).or_insert_with(|| {
                    first_time = true;
                    resolve(palette, [px[0], px[1], px[2]], &lut)
                });
                last = Some((key, r));
                (r, first_time)
            }
        };
        match resolved {
            Resolved::Solid(p) => {
                let slot = match slot_of.get(p).copied().flatten() {
                    Some(s) => Some(s),
                    None if used.len() <= u16::MAX as usize && p < slot_of.len() => {
                        let s = used.len() as u16;
                        slot_of[p] = Some(s);
                        used.push(p);
                        Some(s)
                    }
                    None => {
                        overflowed = true;
                        None
                    }
                };
                match slot {
                    Some(s) => {
                        cells.push(Cell::Solid(s));
                        albedo.push([0.0; 3]);
                    }
                    None => {
                        cells.push(Cell::Floor);
                        albedo.push([0.0; 3]);
                    }
                }
            }
            Resolved::Floor(a) => {
                cells.push(Cell::Floor);
                albedo.push(a);
            }
            Resolved::NearMiss {
                solid,
                diff,
                albedo: a,
            } => {
                cells.push(Cell::Floor);
                albedo.push(a);
                let (x, y) = (i % width, i / width);
                let e = near.entry(solid).or_insert(NearMisses {
                    pixels: 0,
                    colors: 0,
                    example: (x, y, [px[0], px[1], px[2]]),
                    min: (x, y),
                    max: (x, y),
                    max_diff: 0,
                });
                e.pixels += 1;
                e.colors += first_time as u64;
                e.min = (e.min.0.min(x), e.min.1.min(y));
                e.max = (e.max.0.max(x), e.max.1.max(y));
                e.max_diff = e.max_diff.max(diff);
            }
        }
    }
    cells.resize(n, Cell::Void);
    albedo.resize(n, [0.0; 3]);

    if overflowed {
        warnings.push(format!(
            "the level uses more than {} wall and emitter colours; the rest are floor",
            u16::MAX as usize + 1
        ));
    }

    // Palette order for the materials actually used.
    let mut order: Vec<usize> = (0..used.len()).collect();
    order.sort_by_key(|&s| used[s]);
    let mut new_slot = vec![0u16; used.len()];
    for (new, &old) in order.iter().enumerate() {
        new_slot[old] = new as u16;
    }
    if order.iter().enumerate().any(|(new, &old)| new != old) {
        for c in &mut cells {
            if let Cell::Solid(s) = c {
                *s = new_slot[*s as usize];
            }
        }
    }
    let materials = order
        .iter()
        .map(|&s| palette.solids[used[s]].clone())
        .collect();

    for (&solid, m) in &near {
        warnings.push(near_miss_warning(palette, name, solid, m));
    }

    Level {
        name: name.to_string(),
        width,
        height,
        cells,
        albedo,
        materials,
        warnings,
    }
}

fn near_miss_warning(palette: &Palette, level: &str, solid: usize, m: &NearMisses) -> String {
    let what = palette.describe(ColorClass::Solid(solid));
    let kind = match palette.solids.get(solid).map(|s| s.kind) {
        Some(MaterialKind::Emitter) => "emitter",
        _ => "wall",
    };
    let plural = |n: u64, word: &str| {
        if n == 1 {
            format!("1 {word}")
        } else {
            format!("{n} {word}s")
        }
    };
    let (x, y, c) = m.example;
    let fix = match palette.settings.tolerance {
        Some(t) if t > 0 => format!("raise `[bake] tolerance` from {t} to {}", m.max_diff),
        _ => format!("set `[bake] tolerance = {}`", m.max_diff),
    };
    let where_ = match palette.origin {
        PaletteOrigin::BuiltIn => format!(" in a palette file (e.g. {level}.palette.toml)"),
        PaletteOrigin::File(_) => " in the palette".to_string(),
    };
    format!(
        "{} in {} are close to {what} but not exactly that colour, probably anti-aliasing \
         (e.g. {} at ({x}, {y}); all within x {}..={}, y {}..={}; up to {} steps off per channel); \
         they are treated as floor, not {kind}. Paint with hard edges (no anti-aliasing), or {fix}{where_} \
         to snap them to the nearest palette colour",
        plural(m.pixels, "pixel"),
        plural(m.colors, "colour"),
        crate::level::material::hex_color(c),
        m.min.0,
        m.max.0,
        m.min.1,
        m.max.1,
        m.max_diff,
    )
}
