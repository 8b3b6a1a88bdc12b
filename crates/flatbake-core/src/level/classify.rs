//! Classifying pixels: each distinct colour resolved once against the
//! palette (wall, emitter, floor albedo, or a near miss worth a warning).

use std::collections::{BTreeMap, HashMap};
use std::hash::{BuildHasherDefault, Hasher};
use std::path::Path;

use crate::level::material::{Material, MaterialKind, srgb_to_linear};
use crate::level::palette::{ColorClass, Palette, PaletteOrigin};
use crate::level::{Cell, FRINGE_REACH, Level, NEAR_MISS_DISTANCE};

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
/// `palette_file` is the file the near-miss advice names when the palette
/// is the built-in one (the level's `NAME.palette.toml`).
pub(super) fn classify_pixels(
    name: &str,
    width: usize,
    height: usize,
    rgba: &[u8],
    palette: &Palette,
    palette_file: Option<&Path>,
) -> Level {
    let mut warnings = Vec::new();
    let (width, height) = checked_size(width, height, rgba.len() / 4, &mut warnings);
    let n = width * height;

    let lut: [f32; 256] = std::array::from_fn(|c| srgb_to_linear(c as u8) as f32);
    let mut cache: HashMap<u32, Resolved, BuildHasherDefault<ColorHasher>> = HashMap::default();
    let mut slots = Slots::new(palette.solids.len());
    // Pixels (indices) of colours near a wall or emitter colour, in raster
    // order; whether they are an anti-aliased fringe is decided below.
    let mut near_px: Vec<usize> = Vec::new();

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
        let resolved = match last {
            Some((k, r)) if k == key => r,
            _ => {
                let r = *cache
                    .entry(key)
                    .or_insert_with(|| resolve(palette, [px[0], px[1], px[2]], &lut));
                last = Some((key, r));
                r
            }
        };
        let (cell, a) = match resolved {
            // A solid beyond the slots a cell can index is floor.
            Resolved::Solid(p) => (slots.of(p).map_or(Cell::Floor, Cell::Solid), [0.0; 3]),
            Resolved::Floor(a) => (Cell::Floor, a),
            Resolved::NearMiss { albedo: a, .. } => {
                near_px.push(i);
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

    if !near_px.is_empty() {
        let image = Image {
            width,
            height,
            rgba,
            cells: &cells,
            materials: &materials,
        };
        let near = fringes(&image, palette, &cache, &near_px);
        let advice = Advice::new(name, palette, palette_file);
        for (&solid, m) in &near.by_solid {
            warnings.push(near_miss_warning(palette, &advice, &near, solid, m));
        }
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
        origin: Default::default(),
        floor_fraction: None,
    }
}

/// What the fringe analysis reads.
struct Image<'a> {
    width: usize,
    height: usize,
    rgba: &'a [u8],
    cells: &'a [Cell],
    materials: &'a [Material],
}

impl Image<'_> {
    /// The opaque colour of pixel `i` as a cache key; `None` for void.
    fn key(&self, i: usize) -> Option<u32> {
        let p = self.rgba.get(4 * i..4 * i + 4)?;
        (p[3] != 0).then(|| u32::from_le_bytes([p[0], p[1], p[2], 0]))
    }

    /// Pixel `i`'s four neighbours all exist and have its colour.
    fn interior(&self, i: usize, key: u32) -> bool {
        let (x, y) = (i % self.width, i / self.width);
        x > 0
            && y > 0
            && x + 1 < self.width
            && y + 1 < self.height
            && [i - 1, i + 1, i - self.width, i + self.width]
                .iter()
                .all(|&j| self.key(j) == Some(key))
    }

    /// Some pixel within [`FRINGE_REACH`] of pixel `i` is solid of `color`.
    fn touches(&self, i: usize, color: [u8; 3]) -> bool {
        let (x, y) = (i % self.width, i / self.width);
        let r = FRINGE_REACH;
        (y.saturating_sub(r)..(y + r + 1).min(self.height)).any(|yy| {
            (x.saturating_sub(r)..(x + r + 1).min(self.width)).any(|xx| {
                matches!(self.cells[yy * self.width + xx],
                    Cell::Solid(s) if self.materials.get(s as usize).is_some_and(|m| m.color == color))
            })
        })
    }
}

/// One near-miss colour: how many pixels, how many of them inside a flat
/// area of that colour, and which palette solid it is near.
struct NearColour {
    rgb: [u8; 3],
    pixels: u64,
    interior: u64,
    solid: usize,
    diff: u8,
    /// How many of its pixels are part of a fringe.
    fringe: u64,
}

impl NearColour {
    /// Painted on purpose as an area of its own: at least a quarter of its
    /// pixels have all four neighbours of the same colour. An anti-aliased
    /// edge changes shade from one pixel to the next across the edge, so
    /// its pixels (almost) never do.
    fn flat(&self) -> bool {
        self.interior > 0 && self.interior * 4 >= self.pixels
    }
}

/// The near-miss analysis of a level.
struct Fringes {
    /// Near-miss colours by cache key.
    colours: HashMap<u32, NearColour, BuildHasherDefault<ColorHasher>>,
    /// Fringe pixels per palette solid.
    by_solid: BTreeMap<usize, NearMisses>,
    /// Floor pixels of the level as classified.
    floor_pixels: u64,
}

/// Finds the anti-aliased fringes among the near-miss pixels `near_px`: a
/// near-miss pixel is a fringe pixel when its colour is not a flat area of
/// its own ([`NearColour::flat`]) and a pixel of the wall or emitter colour
/// it is near lies within [`FRINGE_REACH`]. Flat areas (a floor painted a
/// shade close to a wall, on purpose) and stray pixels far from that colour
/// are plain floor and say nothing.
fn fringes(
    image: &Image,
    palette: &Palette,
    cache: &HashMap<u32, Resolved, BuildHasherDefault<ColorHasher>>,
    near_px: &[usize],
) -> Fringes {
    let mut colours: HashMap<u32, NearColour, BuildHasherDefault<ColorHasher>> = HashMap::default();
    for &i in near_px {
        let Some(key) = image.key(i) else { continue };
        let Some(&Resolved::NearMiss { solid, diff, .. }) = cache.get(&key) else {
            continue;
        };
        let c = colours.entry(key).or_insert_with(|| NearColour {
            rgb: key.to_le_bytes()[..3].try_into().unwrap_or([0; 3]),
            pixels: 0,
            interior: 0,
            solid,
            diff,
            fringe: 0,
        });
        c.pixels += 1;
        c.interior += image.interior(i, key) as u64;
    }
    let mut by_solid: BTreeMap<usize, NearMisses> = BTreeMap::new();
    for &i in near_px {
        let Some(key) = image.key(i) else { continue };
        let Some(c) = colours.get_mut(&key) else {
            continue;
        };
        let Some(solid_color) = palette.solids.get(c.solid).map(|m| m.color) else {
            continue;
        };
        if c.flat() || !image.touches(i, solid_color) {
            continue;
        }
        let (x, y) = (i % image.width, i / image.width);
        let first_time = c.fringe == 0;
        c.fringe += 1;
        by_solid
            .entry(c.solid)
            .or_insert_with(|| NearMisses::at(x, y, c.rgb))
            .record((x, y), c.diff, first_time);
    }
    let floor_pixels = image.cells.iter().filter(|&&c| c == Cell::Floor).count() as u64;
    Fringes {
        colours,
        by_solid,
        floor_pixels,
    }
}

impl Fringes {
    /// The largest tolerance up to `wanted` that is safe to suggest: it
    /// snaps no flat area's colour to a wall or emitter and leaves floor
    /// pixels. Returns it with the flat colour that limited it, if one did.
    fn safe_tolerance(&self, wanted: u8) -> (u8, Option<[u8; 3]>) {
        let mut t = wanted;
        let mut limit = None;
        for c in self.colours.values().filter(|c| c.flat()) {
            if c.diff <= t {
                t = c.diff.saturating_sub(1);
                limit = Some(c.rgb);
            }
        }
        // Whatever else snaps, some floor must stay floor.
        while t > 0 && self.snapped(t) >= self.floor_pixels {
            t -= 1;
        }
        (t, limit)
    }

    /// Floor pixels that `tolerance` turns into walls or emitters: every
    /// near-miss colour at most `tolerance` steps from its solid (the
    /// nearest palette colour within the tolerance is the one within
    /// the near-miss distance, when it is that close).
    fn snapped(&self, tolerance: u8) -> u64 {
        self.colours
            .values()
            .filter(|c| c.diff <= tolerance)
            .map(|c| c.pixels)
            .sum()
    }

    /// Fringe pixels of `solid` within `tolerance` steps.
    fn fringe_within(&self, solid: usize, tolerance: u8) -> u64 {
        self.colours
            .values()
            .filter(|c| c.solid == solid && c.diff <= tolerance)
            .map(|c| c.fringe)
            .sum()
    }
}

/// Where the near-miss advice tells the designer to set the tolerance.
struct Advice {
    /// The palette file, as the designer would name it.
    file: String,
    /// The file serves other levels too (a folder's `palette.toml`, or
    /// `--palette`).
    shared: bool,
}

impl Advice {
    fn new(level: &str, palette: &Palette, palette_file: Option<&Path>) -> Advice {
        let shown = crate::level::palette::shown_path;
        match &palette.origin {
            PaletteOrigin::File(p) => Advice {
                file: shown(p),
                shared: p.file_name().and_then(|f| f.to_str())
                    != Some(&format!("{level}.palette.toml")),
            },
            PaletteOrigin::BuiltIn => Advice {
                file: palette_file.map_or_else(|| format!("{level}.palette.toml"), shown),
                shared: false,
            },
        }
    }
}

fn near_miss_warning(
    palette: &Palette,
    advice: &Advice,
    near: &Fringes,
    solid: usize,
    m: &NearMisses,
) -> String {
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
    let current = palette.settings.tolerance.unwrap_or(0);
    let (t, limit) = near.safe_tolerance(m.max_diff);
    let set = if current > 0 {
        format!("raise `[bake] tolerance` from {current} to {t}")
    } else {
        format!("set `[bake] tolerance = {t}`")
    };
    let file = &advice.file;
    let shared = if advice.shared {
        " (every level that uses that palette gets it)"
    } else {
        ""
    };
    let fix = if t <= current {
        match limit {
            Some(c) => format!(
                ". A larger tolerance cannot snap them: it would also snap {}, painted as an \
                 area of its own, to a wall or light",
                crate::level::material::hex_color(c)
            ),
            None => ". A larger tolerance cannot snap them without leaving the level no floor"
                .to_string(),
        }
    } else if t >= m.max_diff {
        format!(", or {set} in {file}{shared} to snap them to the nearest palette colour")
    } else {
        let why = match limit {
            Some(c) => format!(
                "would also snap {}, painted as an area of its own",
                crate::level::material::hex_color(c)
            ),
            None => "would leave the level no floor".to_string(),
        };
        format!(
            ", or {set} in {file}{shared} to snap the {} of them within {t} steps (a larger \
             tolerance {why})",
            near.fringe_within(solid, t)
        )
    };
    format!(
        "{} in {} along the edges of {what} are close to that colour but not exactly it, \
         probably anti-aliasing (e.g. {} at ({x}, {y}); all within x {}..={}, y {}..={}; up to {} \
         steps off per channel); they are treated as floor, not {kind}. Paint with hard edges \
         (no anti-aliasing){fix}",
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
