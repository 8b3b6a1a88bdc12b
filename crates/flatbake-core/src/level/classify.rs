//! Classifying pixels: each distinct colour resolved once against the
//! palette (wall, emitter, floor albedo, or a near miss worth a warning).

use std::collections::{BTreeMap, HashMap};
use std::hash::{BuildHasherDefault, Hasher};

use crate::level::material::{Material, MaterialKind, srgb_to_linear};
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

/// Material slots of the palette's solids in first-use order; remapped to
/// palette order at the end so indices do not depend on where in the image
/// a material first appears.
struct Slots {
    slot_of: Vec<Option<u16>>,
    /// The palette solid of each slot.
    used: Vec<usize>,
    /// More solids were used than a cell can index.
    overflowed: bool,
}

impl Slots {
    fn new(solids: usize) -> Slots {
        Slots {
            slot_of: vec![None; solids],
            used: Vec::new(),
            overflowed: false,
        }
    }

    /// The slot of palette solid `p`, taken now if it is new; `None` when
    /// every slot is taken.
    fn of(&mut self, p: usize) -> Option<u16> {
        match self.slot_of.get(p).copied().flatten() {
            Some(s) => Some(s),
            None if self.used.len() <= u16::MAX as usize && p < self.slot_of.len() => {
                let s = self.used.len() as u16;
                self.slot_of[p] = Some(s);
                self.used.push(p);
                Some(s)
            }
            None => {
                self.overflowed = true;
                None
            }
        }
    }

    /// Renumbers the solid `cells` into palette order and returns the
    /// materials used, in that order.
    fn into_palette_order(self, cells: &mut [Cell], palette: &Palette) -> Vec<Material> {
        let used = self.used;
        let mut order: Vec<usize> = (0..used.len()).collect();
        order.sort_by_key(|&s| used[s]);
        let mut new_slot = vec![0u16; used.len()];
        for (new, &old) in order.iter().enumerate() {
            new_slot[old] = new as u16;
        }
        if order.iter().enumerate().any(|(new, &old)| new != old) {
            for c in cells.iter_mut() {
                if let Cell::Solid(s) = c {
                    *s = new_slot[*s as usize];
                }
            }
        }
        order
            .iter()
            .map(|&s| palette.solids[used[s]].clone())
            .collect()
    }
}

impl NearMisses {
    /// None yet; the first will be at `(x, y)`, of colour `rgb`.
    fn at(x: usize, y: usize, rgb: [u8; 3]) -> NearMisses {
        NearMisses {
            pixels: 0,
            colors: 0,
            example: (x, y, rgb),
            min: (x, y),
            max: (x, y),
            max_diff: 0,
        }
    }

    /// Counts one more near-miss pixel at `(x, y)`, `diff` steps from its
    /// palette colour, of a colour seen for the first time or not.
    fn record(&mut self, (x, y): (usize, usize), diff: u8, first_time: bool) {
        self.pixels += 1;
        self.colors += first_time as u64;
        self.min = (self.min.0.min(x), self.min.1.min(y));
        self.max = (self.max.0.max(x), self.max.1.max(y));
        self.max_diff = self.max_diff.max(diff);
    }
}

/// The level's size, or `0 x 0` when it overflows; says so, and says when
/// the `available` pixels are fewer than the size needs.
fn checked_size(
    width: usize,
    height: usize,
    available: usize,
    warnings: &mut Vec<String>,
) -> (usize, usize) {
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
    if available < n {
        warnings.push(format!(
            "pixel data holds {available} pixels but the level is {width} x {height} = {n}; the rest is void"
        ));
    }
    (width, height)
}

/// Classifies `rgba` (row-major, 4 bytes per pixel) with `palette`.
pub(super) fn classify_pixels(
    name: &str,
    width: usize,
    height: usize,
    rgba: &[u8],
    palette: &Palette,
) -> Level {
    let mut warnings = Vec::new();
    let (width, height) = checked_size(width, height, rgba.len() / 4, &mut warnings);
    let n = width * height;

    let lut: [f32; 256] = std::array::from_fn(|c| srgb_to_linear(c as u8) as f32);
    let mut cache: HashMap<u32, Resolved, BuildHasherDefault<ColorHasher>> = HashMap::default();
    let mut slots = Slots::new(palette.solids.len());
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
        let (cell, a) = match resolved {
            // A solid beyond the slots a cell can index is floor.
            Resolved::Solid(p) => (slots.of(p).map_or(Cell::Floor, Cell::Solid), [0.0; 3]),
            Resolved::Floor(a) => (Cell::Floor, a),
            Resolved::NearMiss {
                solid,
                diff,
                albedo: a,
            } => {
                let (x, y) = (i % width, i / width);
                near.entry(solid)
                    .or_insert_with(|| NearMisses::at(x, y, [px[0], px[1], px[2]]))
                    .record((x, y), diff, first_time);
                (Cell::Floor, a)
            }
        };
        cells.push(cell);
        albedo.push(a);
    }
    cells.resize(n, Cell::Void);
    albedo.resize(n, [0.0; 3]);

    if slots.overflowed {
        warnings.push(format!(
            "the level uses more than {} wall and emitter colours; the rest are floor",
            u16::MAX as usize + 1
        ));
    }
    let materials = slots.into_palette_order(&mut cells, palette);

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
        lossy_format: None,
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
