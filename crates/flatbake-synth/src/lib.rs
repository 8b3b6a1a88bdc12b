//! Procedural levels for samples, benchmarks and tests.
//!
//! Every generator paints a level the way a designer would in an image
//! editor — walls, emitters and floor as plain pixels — and writes the palette
//! TOML (docs/transport.md#palette-and-materials) that gives those colours their meaning. Output is a
//! [`Painted`] level: RGBA pixels plus palette text, so the same levels feed
//! the sample folder (`examples/make_levels.rs`), the benchmarks and the
//! property tests through exactly the loading path a user's files take.
//!
//! Everything is deterministic: randomness comes from a hand-written
//! SplitMix64 ([`Rng`]) seeded explicitly, and floor texture noise is a pure
//! hash of `(seed, x, y)`, so a generator called twice with the same arguments
//! returns identical pixels on every platform.
//!
//! Floors are painted in mid and light tones (the lit view multiplies floor
//! albedo by light, so dark floors would hide the lighting) and are kept more
//! than [`NEAR`] away, in some channel, from every wall and emitter colour:
//! the loader treats floor pixels that almost match a palette colour as
//! probable anti-aliasing and warns about them.

use std::path::Path;

mod classes;
pub use classes::{
    Class, checkerboard, corridors, courtyard_map, dots, hard_classes, light_field, noise,
    pillar_field, shooter_map, small_classes,
};

/// A floor colour is "near" a palette colour when every channel is within
/// this many 8-bit steps of it; generated floors never are.
pub const NEAR: u8 = 40;

/// A fully transparent pixel: void (light passes, nothing is lit).
pub const VOID: [u8; 4] = [0, 0, 0, 0];

// ---------------------------------------------------------------------------
// Randomness

/// SplitMix64: tiny, fast, good enough for level layout, and identical on
/// every platform (unlike a seeded library RNG whose stream may change).
#[derive(Clone, Debug)]
pub struct Rng(u64);

/// The SplitMix64 output function; also used as a hash for texture noise.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A hash of a seed and a lattice point, uniform over `u64`.
pub fn hash2(seed: u64, x: i32, y: i32) -> u64 {
    let k = ((x as u32 as u64) << 32) | (y as u32 as u64);
    mix(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ mix(k ^ 0x632b_e59b_d9b4_e019))
}

/// [`hash2`] mapped to `-1.0..1.0`.
fn signed_noise(seed: u64, x: i32, y: i32) -> f64 {
    (hash2(seed, x, y) >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// Smooth value noise in `-1.0..1.0` with features about `scale` pixels wide:
/// blotches for grass and dirt that per-pixel noise alone cannot give.
fn value_noise(seed: u64, x: i32, y: i32, scale: i32) -> f64 {
    let scale = scale.max(1);
    let (gx, gy) = (x.div_euclid(scale), y.div_euclid(scale));
    let fx = x.rem_euclid(scale) as f64 / scale as f64;
    let fy = y.rem_euclid(scale) as f64 / scale as f64;
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (s(fx), s(fy));
    let n = |dx, dy| signed_noise(seed, gx + dx, gy + dy);
    let top = n(0, 0) * (1.0 - sx) + n(1, 0) * sx;
    let bottom = n(0, 1) * (1.0 - sx) + n(1, 1) * sx;
    top * (1.0 - sy) + bottom * sy
}

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x5851_f42d_4c95_7f2d)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix(self.0)
    }

    /// Uniform in `0..n` (`n > 0`), by multiply-shift: no modulo bias worth
    /// caring about at level sizes.
    pub fn below(&mut self, n: u64) -> u64 {
        ((self.next_u64() as u128 * n as u128) >> 64) as u64
    }

    /// Uniform in `lo..hi`; `lo` when the range is empty.
    pub fn range(&mut self, lo: i32, hi: i32) -> i32 {
        if hi <= lo {
            lo
        } else {
            lo + self.below((hi - lo) as u64) as i32
        }
    }

    /// Uniform in `0.0..1.0`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }

    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len() as u64) as usize]
    }
}

// ---------------------------------------------------------------------------
// Geometry helpers

/// An axis-aligned pixel rectangle `[x, x + w) x [y, y + h)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    pub x: i32,
    pub y: i32,
    pub w: i32,
    pub h: i32,
}

impl Rect {
    pub const fn new(x: i32, y: i32, w: i32, h: i32) -> Rect {
        Rect { x, y, w, h }
    }
    pub fn x1(&self) -> i32 {
        self.x + self.w
    }
    pub fn y1(&self) -> i32 {
        self.y + self.h
    }
    pub fn center(&self) -> (i32, i32) {
        (self.x + self.w / 2, self.y + self.h / 2)
    }
    pub fn area(&self) -> i64 {
        self.w.max(0) as i64 * self.h.max(0) as i64
    }
    /// Grown by `d` on every side (shrunk for negative `d`).
    pub fn grow(&self, d: i32) -> Rect {
        Rect::new(self.x - d, self.y - d, self.w + 2 * d, self.h + 2 * d)
    }
    pub fn contains(&self, x: i32, y: i32) -> bool {
        x >= self.x && x < self.x1() && y >= self.y && y < self.y1()
    }
    pub fn intersects(&self, o: &Rect) -> bool {
        self.x < o.x1() && o.x < self.x1() && self.y < o.y1() && o.y < self.y1()
    }
}

// ---------------------------------------------------------------------------
// Colours and palettes

/// An opaque pixel from `0xrrggbb`.
pub const fn rgb(hex: u32) -> [u8; 4] {
    [(hex >> 16) as u8, (hex >> 8) as u8, hex as u8, 255]
}

/// True when every channel of `a` is within [`NEAR`] of `b`.
pub fn is_near(a: [u8; 3], b: [u8; 3]) -> bool {
    (0..3).all(|k| a[k].abs_diff(b[k]) <= NEAR)
}

/// Adds `d` to every channel, clamped.
fn shade(c: [u8; 4], d: i32) -> [u8; 4] {
    tint(c, [d, d, d])
}

/// Adds a per-channel offset, clamped.
fn tint(c: [u8; 4], d: [i32; 3]) -> [u8; 4] {
    let f = |k: usize| (c[k] as i32 + d[k]).clamp(0, 255) as u8;
    [f(0), f(1), f(2), c[3]]
}

/// A reflectance, emission or albedo: one number for grey, or per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    Grey(f64),
    Rgb([f64; 3]),
}

impl From<f64> for Value {
    fn from(v: f64) -> Value {
        Value::Grey(v)
    }
}

impl From<[f64; 3]> for Value {
    fn from(v: [f64; 3]) -> Value {
        Value::Rgb(v)
    }
}

/// A TOML float: always with a decimal point, never an exponent, at most 4
/// decimals so the files stay readable.
fn toml_num(v: f64) -> String {
    let r = (v * 1e4).round() / 1e4;
    if r.fract() == 0.0 {
        format!("{r:.1}")
    } else {
        format!("{r}")
    }
}

impl Value {
    fn toml(&self) -> String {
        match self {
            Value::Grey(v) => toml_num(*v),
            Value::Rgb(v) => format!(
                "[{}, {}, {}]",
                toml_num(v[0]),
                toml_num(v[1]),
                toml_num(v[2])
            ),
        }
    }
}

#[derive(Clone, Debug)]
enum Entry {
    Wall {
        color: [u8; 4],
        reflectance: Value,
    },
    Emitter {
        color: [u8; 4],
        emission: Value,
        reflectance: Option<Value>,
    },
    Floor {
        color: [u8; 4],
        albedo: Value,
    },
}

/// Builds palette TOML while painting: each material call returns the colour
/// to paint it with, so a level's pixels and palette cannot disagree.
#[derive(Clone, Debug, Default)]
pub struct PaletteBuilder {
    title: String,
    falloff: Option<f64>,
    entries: Vec<(String, Entry)>,
}

impl PaletteBuilder {
    /// `title` becomes the file's opening comment.
    pub fn new(title: &str) -> PaletteBuilder {
        PaletteBuilder {
            title: title.to_string(),
            ..PaletteBuilder::default()
        }
    }

    pub fn falloff(&mut self, d: f64) -> &mut Self {
        self.falloff = Some(d);
        self
    }

    /// A wall material; `note` is written as a comment above the entry.
    pub fn wall(&mut self, note: &str, hex: u32, reflectance: impl Into<Value>) -> [u8; 4] {
        let color = rgb(hex);
        self.push(
            note,
            Entry::Wall {
                color,
                reflectance: reflectance.into(),
            },
        );
        color
    }

    /// An emitter; `reflectance` `None` leaves the palette default (0).
    pub fn emitter(
        &mut self,
        note: &str,
        hex: u32,
        emission: impl Into<Value>,
        reflectance: Option<Value>,
    ) -> [u8; 4] {
        let color = rgb(hex);
        self.push(
            note,
            Entry::Emitter {
                color,
                emission: emission.into(),
                reflectance,
            },
        );
        color
    }

    /// A floor colour with an explicit albedo.
    pub fn floor(&mut self, note: &str, hex: u32, albedo: impl Into<Value>) -> [u8; 4] {
        let color = rgb(hex);
        self.push(
            note,
            Entry::Floor {
                color,
                albedo: albedo.into(),
            },
        );
        color
    }

    fn push(&mut self, note: &str, e: Entry) {
        let c = match &e {
            Entry::Wall { color, .. }
            | Entry::Emitter { color, .. }
            | Entry::Floor { color, .. } => *color,
        };
        // Two entries with one colour would make the palette ambiguous: a
        // generator bug, not a level property.
        assert!(
            !self.colors().any(|(k, _)| k == c),
            "palette colour #{:02x}{:02x}{:02x} used twice",
            c[0],
            c[1],
            c[2]
        );
        self.entries.push((note.to_string(), e));
    }

    /// Every palette colour, with `true` for walls and emitters.
    fn colors(&self) -> impl Iterator<Item = ([u8; 4], bool)> + '_ {
        self.entries.iter().map(|(_, e)| match e {
            Entry::Wall { color, .. } | Entry::Emitter { color, .. } => (*color, true),
            Entry::Floor { color, .. } => (*color, false),
        })
    }

    /// The palette as TOML text (docs/transport.md#palette-and-materials).
    pub fn to_toml(&self) -> String {
        let hex = |c: [u8; 4]| format!("\"#{:02x}{:02x}{:02x}\"", c[0], c[1], c[2]);
        let mut s = String::new();
        for line in self.title.lines() {
            s += &format!("# {line}\n");
        }
        s += "# Generated by `cargo run --release --example make_levels`.\n";
        if let Some(f) = self.falloff {
            s += &format!("\n[bake]\nfalloff = {}\n", toml_num(f));
        }
        for (note, e) in &self.entries {
            s += "\n";
            if !note.is_empty() {
                s += &format!("# {note}\n");
            }
            match e {
                Entry::Wall { color, reflectance } => {
                    s += &format!(
                        "[[wall]]\ncolor = {}\nreflectance = {}\n",
                        hex(*color),
                        reflectance.toml()
                    );
                }
                Entry::Emitter {
                    color,
                    emission,
                    reflectance,
                } => {
                    s += &format!(
                        "[[emitter]]\ncolor = {}\nemission = {}\n",
                        hex(*color),
                        emission.toml()
                    );
                    if let Some(r) = reflectance {
                        s += &format!("reflectance = {}\n", r.toml());
                    }
                }
                Entry::Floor { color, albedo } => {
                    s += &format!(
                        "[[floor]]\ncolor = {}\nalbedo = {}\n",
                        hex(*color),
                        albedo.toml()
                    );
                }
            }
        }
        s
    }
}

// ---------------------------------------------------------------------------
// Floors

/// A floor texture, painted in absolute coordinates so tiles line up across
/// rooms the way a tiled brush would.
#[derive(Clone, Copy, Debug)]
pub enum Floor {
    /// Flat colour with faint per-pixel noise.
    Plain { base: u32 },
    /// Square flagstones `tile` px wide with slightly darker grout; every
    /// stone has its own tint.
    Flagstones { base: u32, tile: i32 },
    /// Horizontal planks `width` px wide and about `length` px long with
    /// staggered joints and a faint grain.
    Planks { base: u32, width: i32, length: i32 },
    /// A checkerboard of two tile colours.
    Checker { a: u32, b: u32, tile: i32 },
    /// Organic ground (grass, sand, gravel): blotches about `blotch` px wide.
    Ground { base: u32, blotch: i32 },
}

impl Floor {
    /// The colour of floor pixel `(x, y)`.
    pub fn color(&self, x: i32, y: i32, seed: u64) -> [u8; 4] {
        let grain =
            |amp: f64, sx: i32, sy: i32| (signed_noise(seed ^ 0x11, sx, sy) * amp).round() as i32;
        match *self {
            Floor::Plain { base } => shade(rgb(base), grain(3.0, x, y)),
            Floor::Flagstones { base, tile } => {
                let (tx, ty) = (x.div_euclid(tile), y.div_euclid(tile));
                let stone = hash2(seed ^ 0x22, tx, ty);
                let d = (stone % 17) as i32 - 8;
                let warm = ((stone >> 8) % 5) as i32 - 2;
                let grout = x.rem_euclid(tile) == 0 || y.rem_euclid(tile) == 0;
                let c = tint(rgb(base), [d + warm, d, d - warm]);
                shade(c, grain(3.0, x, y) - if grout { 14 } else { 0 })
            }
            Floor::Planks {
                base,
                width,
                length,
            } => {
                let row = y.div_euclid(width);
                let offset = (hash2(seed ^ 0x33, 0, row) % length as u64) as i32;
                let along = x + offset;
                let plank = hash2(seed ^ 0x44, along.div_euclid(length), row);
                let d = (plank % 21) as i32 - 10;
                let seam = y.rem_euclid(width) == 0 || along.rem_euclid(length) == 0;
                // Grain: streaks along the plank, so noise varies slowly in x.
                let streak = (value_noise(seed ^ 0x55, x, y * 7, 5) * 6.0).round() as i32;
                shade(
                    rgb(base),
                    d + streak + grain(2.0, x, y) - if seam { 20 } else { 0 },
                )
            }
            Floor::Checker { a, b, tile } => {
                let odd = (x.div_euclid(tile) + y.div_euclid(tile)).rem_euclid(2) == 1;
                shade(rgb(if odd { b } else { a }), grain(3.0, x, y))
            }
            Floor::Ground { base, blotch } => {
                let big = value_noise(seed ^ 0x66, x, y, blotch * 3) * 8.0;
                let small = value_noise(seed ^ 0x77, x, y, blotch) * 7.0;
                let d = (big + small).round() as i32;
                // Blotches shift hue a little too: greener and browner patches.
                tint(
                    rgb(base),
                    [
                        d + grain(4.0, x, y),
                        d + (small * 0.6) as i32 + grain(4.0, x, y),
                        d - 2,
                    ],
                )
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Canvas

/// An RGBA canvas with clipped drawing primitives. Coordinates are `i32` so
/// shapes may hang over the border; whatever falls outside is dropped.
#[derive(Clone, Debug)]
pub struct Canvas {
    pub width: usize,
    pub height: usize,
    pub px: Vec<[u8; 4]>,
    /// Seed for floor texture noise.
    pub seed: u64,
}

/// The pixels of the Bresenham line from `a` to `b`, both included.
pub fn line_points((mut x0, mut y0): (i32, i32), (x1, y1): (i32, i32)) -> Vec<(i32, i32)> {
    let dx = (x1 - x0).abs();
    let dy = -(y1 - y0).abs();
    let (sx, sy) = ((x1 - x0).signum(), (y1 - y0).signum());
    let mut err = dx + dy;
    let mut out = Vec::with_capacity((dx - dy + 1) as usize);
    loop {
        out.push((x0, y0));
        if x0 == x1 && y0 == y1 {
            return out;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x0 += sx;
        }
        if e2 <= dx {
            err += dx;
            y0 += sy;
        }
    }
}

impl Canvas {
    pub fn new(width: usize, height: usize, fill: [u8; 4], seed: u64) -> Canvas {
        Canvas {
            width,
            height,
            px: vec![fill; width * height],
            seed,
        }
    }

    pub fn in_bounds(&self, x: i32, y: i32) -> bool {
        x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height
    }

    /// The pixel at `(x, y)`, `None` outside the canvas.
    pub fn get(&self, x: i32, y: i32) -> Option<[u8; 4]> {
        self.in_bounds(x, y)
            .then(|| self.px[y as usize * self.width + x as usize])
    }

    pub fn set(&mut self, x: i32, y: i32, c: [u8; 4]) {
        if self.in_bounds(x, y) {
            self.px[y as usize * self.width + x as usize] = c;
        }
    }

    pub fn fill_rect(&mut self, r: Rect, c: [u8; 4]) {
        self.fill_rect_with(r, |_, _| c);
    }

    /// Fills `r` with `f(x, y)`.
    pub fn fill_rect_with(&mut self, r: Rect, mut f: impl FnMut(i32, i32) -> [u8; 4]) {
        let x0 = r.x.max(0);
        let y0 = r.y.max(0);
        let x1 = r.x1().min(self.width as i32);
        let y1 = r.y1().min(self.height as i32);
        for y in y0..y1 {
            for x in x0..x1 {
                self.px[y as usize * self.width + x as usize] = f(x, y);
            }
        }
    }

    /// Paints floor texture over `r`.
    pub fn floor(&mut self, r: Rect, floor: Floor) {
        let seed = self.seed;
        self.fill_rect_with(r, |x, y| floor.color(x, y, seed));
    }

    /// A frame `t` px thick just inside `r`.
    pub fn outline_rect(&mut self, r: Rect, t: i32, c: [u8; 4]) {
        self.fill_rect(Rect::new(r.x, r.y, r.w, t), c);
        self.fill_rect(Rect::new(r.x, r.y1() - t, r.w, t), c);
        self.fill_rect(Rect::new(r.x, r.y, t, r.h), c);
        self.fill_rect(Rect::new(r.x1() - t, r.y, t, r.h), c);
    }

    /// A Bresenham line, 8-connected: diagonal steps touch only at corners,
    /// which are closed (docs/transport.md#corners), so the line is still a wall.
    pub fn line(&mut self, a: (i32, i32), b: (i32, i32), c: [u8; 4]) {
        for (x, y) in line_points(a, b) {
            self.set(x, y, c);
        }
    }

    /// A filled disc of pixels whose centres are within `r` of `(cx, cy)`.
    pub fn disc(&mut self, (cx, cy): (f64, f64), r: f64, c: [u8; 4]) {
        self.ring((cx, cy), 0.0, r, c);
    }

    /// Pixels whose centres are between `r0` and `r1` from `(cx, cy)`.
    pub fn ring(&mut self, (cx, cy): (f64, f64), r0: f64, r1: f64, c: [u8; 4]) {
        let b = Rect::new(
            (cx - r1).floor() as i32 - 1,
            (cy - r1).floor() as i32 - 1,
            0,
            0,
        );
        let n = (2.0 * r1).ceil() as i32 + 3;
        for y in b.y..b.y + n {
            for x in b.x..b.x + n {
                let d = ((x as f64 + 0.5 - cx).powi(2) + (y as f64 + 0.5 - cy).powi(2)).sqrt();
                if d >= r0 && d <= r1 {
                    self.set(x, y, c);
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Output

/// A generated level: pixels plus the palette that gives them meaning.
#[derive(Clone, Debug, PartialEq)]
pub struct Painted {
    /// File stem: the level is saved as `NAME.png` + `NAME.palette.toml`.
    pub name: String,
    pub width: usize,
    pub height: usize,
    /// Row-major RGBA, `width * height`.
    pub rgba: Vec<[u8; 4]>,
    /// Palette TOML; empty means "use whatever palette the loader finds".
    pub palette_toml: String,
}

impl Painted {
    /// The level as the loader resolves it, with its palette (parsed as
    /// `NAME.palette.toml`, the name the palette is saved under): what a
    /// bake of the saved files would see, without touching the disk.
    pub fn level(
        &self,
    ) -> Result<
        (
            flatbake_core::level::Level,
            flatbake_core::level::palette::Palette,
        ),
        flatbake_core::level::palette::PaletteError,
    > {
        let path = format!("{}.palette.toml", self.name);
        let palette =
            flatbake_core::level::palette::Palette::parse(&self.palette_toml, Path::new(&path))?;
        let level = flatbake_core::level::Level::from_rgba(
            &self.name,
            self.width,
            self.height,
            &self.rgba,
            &palette,
        );
        Ok((level, palette))
    }

    /// Finishes a level: floors that came out near a wall or emitter colour
    /// are pushed away from it (so texture noise can never turn into a
    /// near-miss warning), then the palette is rendered.
    pub fn new(name: &str, mut canvas: Canvas, palette: &PaletteBuilder) -> Painted {
        let colors: Vec<([u8; 4], bool)> = palette.colors().collect();
        let solid: Vec<[u8; 3]> = colors
            .iter()
            .filter(|c| c.1)
            .map(|c| [c.0[0], c.0[1], c.0[2]])
            .collect();
        for p in &mut canvas.px {
            if p[3] == 0 || colors.iter().any(|(c, _)| c[..3] == p[..3]) {
                continue;
            }
            *p = keep_clear(*p, &solid);
        }
        // Void pixels carry no colour: a fixed value keeps files comparable.
        for p in &mut canvas.px {
            if p[3] == 0 {
                *p = VOID;
            }
        }
        Painted {
            name: name.to_string(),
            width: canvas.width,
            height: canvas.height,
            rgba: canvas.px,
            palette_toml: palette.to_toml(),
        }
    }

    pub fn to_image(&self) -> image::RgbaImage {
        let bytes: Vec<u8> = self.rgba.iter().flatten().copied().collect();
        image::RgbaImage::from_raw(self.width as u32, self.height as u32, bytes)
            .expect("rgba holds width * height pixels")
    }

    /// Writes `NAME.png` and, with a palette, `NAME.palette.toml` into `dir`
    /// (created if missing).
    pub fn save(&self, dir: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(dir)?;
        self.to_image()
            .save(dir.join(format!("{}.png", self.name)))
            .map_err(std::io::Error::other)?;
        if !self.palette_toml.is_empty() {
            std::fs::write(
                dir.join(format!("{}.palette.toml", self.name)),
                &self.palette_toml,
            )?;
        }
        Ok(())
    }
}

/// Moves a floor colour the least distance (one channel) so that it is no
/// longer near any of `solid`; gives up after a few rounds, which only a
/// palette crowding the whole colour cube could need.
fn keep_clear(mut p: [u8; 4], solid: &[[u8; 3]]) -> [u8; 4] {
    for _ in 0..8 {
        let Some(s) = solid.iter().find(|s| is_near([p[0], p[1], p[2]], **s)) else {
            return p;
        };
        let mut best: Option<(i32, usize, u8)> = None;
        for k in 0..3 {
            let (v, sv) = (p[k] as i32, s[k] as i32);
            for target in [sv + NEAR as i32 + 1, sv - NEAR as i32 - 1] {
                if (0..=255).contains(&target) {
                    let cost = (target - v).abs();
                    if best.is_none_or(|b| cost < b.0) {
                        best = Some((cost, k, target as u8));
                    }
                }
            }
        }
        let (_, k, t) = best.expect("some channel can always move 41 steps");
        p[k] = t;
    }
    p
}

// ---------------------------------------------------------------------------
// Sample levels

/// A flatland Cornell box, about `size` px square: a closed room with a red
/// left wall and a green right wall, off-white walls elsewhere, a warm light
/// strip set into the top wall and two grey blocks. Shows colour bleeding
/// (the floor turns pink and green near the side walls), soft shadows behind
/// the blocks, and interreflection filling the shadows.
pub fn cornell(size: usize) -> Painted {
    let s = size.max(24) as i32;
    let f = |v: f64| (v * s as f64).round() as i32;
    let t = (s / 32).max(2);
    let mut pal = PaletteBuilder::new(&format!("Flatland Cornell box, {s}x{s}."));
    let white = pal.wall("off-white walls", 0xe8e4da, 0.75);
    let red = pal.wall("red left wall", 0xc0282a, [0.75, 0.1, 0.1]);
    let green = pal.wall("green right wall", 0x2a9a3c, [0.1, 0.7, 0.1]);
    let grey = pal.wall("grey blocks", 0x62626c, 0.6);
    let light = pal.emitter(
        "warm light strip in the top wall",
        0xfff0c8,
        [5.0, 4.4, 3.4],
        None,
    );

    let mut c = Canvas::new(s as usize, s as usize, VOID, 1);
    c.floor(
        Rect::new(0, 0, s, s),
        Floor::Flagstones {
            base: 0xb0a898,
            tile: (s / 8).max(3),
        },
    );
    c.fill_rect(Rect::new(0, 0, s, t), white);
    c.fill_rect(Rect::new(0, s - t, s, t), white);
    c.fill_rect(Rect::new(0, t, t, s - 2 * t), red);
    c.fill_rect(Rect::new(s - t, t, t, s - 2 * t), green);
    // The strip is the inner row of the top wall: it lights the room only.
    c.fill_rect(Rect::new(f(0.375), t - 1, f(0.25), 1), light);
    // A tall block at the back left, a short one at the front right, as in
    // the original box seen from above.
    c.fill_rect(Rect::new(f(0.24), f(0.40), f(0.2), f(0.3)), grey);
    c.fill_rect(Rect::new(f(0.58), f(0.62), f(0.18), f(0.16)), grey);
    Painted::new("cornell", c, &pal)
}

/// Coloured light and coloured walls, `size` x `3/4 size` px: three alcoves
/// with red, green and blue emitters open onto one hall where their light
/// mixes (white where all three overlap, cyan, yellow and magenta where one
/// is shadowed); below, a white lamp bar between a thick orange wall and a
/// blue wall (white light, coloured bounce: the floor warms towards the
/// orange side and cools towards the blue) and a room lit by a magenta
/// strip with a yellow wall and a green pillar (coloured shadows).
pub fn colour_bleed(size: usize) -> Painted {
    let w = size.max(48) as i32;
    let h = w * 3 / 4;
    let fx = |v: f64| (v * w as f64).round() as i32;
    let fy = |v: f64| (v * h as f64).round() as i32;
    let t = 2;
    let mut pal = PaletteBuilder::new(&format!(
        "Colour bleeding: coloured lights and walls, {w}x{h}."
    ));
    let white = pal.wall("white plaster", 0xeeeeea, 0.7);
    let orange = pal.wall("orange wall", 0xe07818, [0.9, 0.45, 0.08]);
    let blue = pal.wall("blue wall", 0x2040c0, [0.08, 0.25, 0.85]);
    let yellow = pal.wall("yellow wall", 0xe8d020, [0.8, 0.75, 0.15]);
    let jade = pal.wall("green pillar", 0x208a40, [0.15, 0.6, 0.2]);
    let red_l = pal.emitter("red light", 0xff2020, [4.0, 0.15, 0.15], None);
    let green_l = pal.emitter("green light", 0x20ff20, [0.15, 4.0, 0.15], None);
    let blue_l = pal.emitter("blue light", 0x2020ff, [0.2, 0.2, 5.0], None);
    let white_l = pal.emitter("white lamp bar", 0xfffff0, 2.5, None);
    let magenta_l = pal.emitter("magenta strip", 0xff20ff, [3.0, 0.1, 3.0], None);

    // Neutral floors: colour on them is the light's, not the paint's.
    let hall_floor = Floor::Flagstones {
        base: 0xaeaca4,
        tile: 8,
    };
    let room_floor = Floor::Flagstones {
        base: 0xbab8b0,
        tile: 4,
    };
    let mut c = Canvas::new(w as usize, h as usize, VOID, 2);
    c.floor(Rect::new(0, 0, w, h), hall_floor);
    let divider = fy(0.57);
    c.floor(Rect::new(0, divider, w, h - divider), room_floor);
    c.outline_rect(Rect::new(0, 0, w, h), t, white);

    // Three alcoves across the top, each with its light in the back wall.
    let bay_depth = fy(0.3);
    for (i, light) in [red_l, green_l, blue_l].into_iter().enumerate() {
        let x0 = t + (w - 2 * t) * i as i32 / 3;
        let x1 = t + (w - 2 * t) * (i as i32 + 1) / 3;
        if i > 0 {
            c.fill_rect(Rect::new(x0 - 1, t, 2, bay_depth), white);
        }
        let len = (x1 - x0) / 3;
        c.fill_rect(Rect::new((x0 + x1) / 2 - len / 2, t - 1, len, 1), light);
    }

    // Divider between the hall and the two rooms below, with two doorways.
    c.fill_rect(Rect::new(0, divider - t, w, t), white);
    c.floor(Rect::new(fx(0.16), divider - t, fx(0.08), t), room_floor);
    c.floor(Rect::new(fx(0.76), divider - t, fx(0.08), t), room_floor);

    // Bottom left: a vertical white lamp bar facing a thick orange wall on
    // the left and a blue wall on the right.
    let mid = w / 2;
    let room_h = h - divider - t;
    c.fill_rect(Rect::new(0, divider, fx(0.05), room_h), orange);
    c.fill_rect(Rect::new(mid - 2, divider, 3, room_h), blue);
    c.fill_rect(
        Rect::new(fx(0.27) - 1, divider + room_h / 4, 2, room_h / 2),
        white_l,
    );

    // Bottom right: a magenta strip in the bottom wall, a yellow right wall
    // and a green pillar casting a coloured shadow.
    c.fill_rect(Rect::new(w - fx(0.05), divider, fx(0.05), room_h), yellow);
    c.fill_rect(Rect::new(fx(0.6), h - t, fx(0.22), 1), magenta_l);
    c.fill_rect(Rect::new(fx(0.68), fy(0.7), fx(0.05), fx(0.05)), jade);
    Painted::new("colour_bleed", c, &pal)
}

// ---------------------------------------------------------------------------
// Dungeon layouts (shared by `dungeon` and `big_level`)

/// The outline of a room's floor inside its rectangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Shape {
    Rect,
    /// Corners cut at 45 degrees, `c` px deep: staircase walls.
    Octagon(i32),
    /// The ellipse inscribed in the rectangle.
    Round,
}

#[derive(Clone, Copy, Debug)]
struct Room {
    r: Rect,
    /// Wall thickness, 1-3 px.
    t: i32,
    shape: Shape,
}

impl Room {
    fn inside(&self, x: i32, y: i32) -> bool {
        let r = self.r;
        if !r.contains(x, y) {
            return false;
        }
        match self.shape {
            Shape::Rect => true,
            Shape::Octagon(c) => {
                let ex = (x - r.x).min(r.x1() - 1 - x);
                let ey = (y - r.y).min(r.y1() - 1 - y);
                ex + ey >= c
            }
            Shape::Round => {
                let u = (x as f64 + 0.5 - r.x as f64) / r.w as f64 * 2.0 - 1.0;
                let v = (y as f64 + 0.5 - r.y as f64) / r.h as f64 * 2.0 - 1.0;
                u * u + v * v <= 1.0
            }
        }
    }
}

/// Rooms and corridors before painting. Room floors are kept at least their
/// wall thickness inside their BSP leaf, so walls of neighbouring rooms meet
/// (a shared 2-6 px wall) or leave void between them, never cover a floor.
struct Layout {
    rooms: Vec<Room>,
    corridors: Vec<Rect>,
}

/// What a pixel of a painted layout is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Owner {
    Void,
    Wall,
    Corridor,
    Room(usize),
}

impl Owner {
    fn is_floor(self) -> bool {
        matches!(self, Owner::Corridor | Owner::Room(_))
    }
}

/// Which way a binary space partition splits `area` (a vertical cut when
/// true): across its longer side when one side is over 5/4 of the other,
/// else at random; `can_v` / `can_h` say which cuts leave both halves big
/// enough. Draws from `rng` only when both cuts fit and neither side is
/// much longer.
pub(crate) fn split_vertically(area: Rect, can_v: bool, can_h: bool, rng: &mut Rng) -> bool {
    if can_v && can_h {
        if area.w * 4 > area.h * 5 {
            true
        } else if area.h * 4 > area.w * 5 {
            false
        } else {
            rng.chance(0.5)
        }
    } else {
        can_v
    }
}

/// Binary space partition of `area` into leaves at least `min_leaf` wide;
/// returns the leaves under this node and records, per split, the two leaf
/// sets a corridor must join.
fn bsp(
    area: Rect,
    min_leaf: i32,
    rng: &mut Rng,
    leaves: &mut Vec<Rect>,
    links: &mut Vec<(Vec<usize>, Vec<usize>)>,
) -> Vec<usize> {
    let can_v = area.w >= 2 * min_leaf;
    let can_h = area.h >= 2 * min_leaf;
    // Stop early now and then so room sizes vary, but never leave a leaf
    // so big that one room would dominate the level.
    let small = area.w < 3 * min_leaf && area.h < 3 * min_leaf;
    if !(can_v || can_h) || (small && rng.chance(0.3)) {
        leaves.push(area);
        return vec![leaves.len() - 1];
    }
    let vertical = split_vertically(area, can_v, can_h, rng);
    let (a, b) = if vertical {
        let cut = rng.range(min_leaf, area.w - min_leaf + 1);
        (
            Rect::new(area.x, area.y, cut, area.h),
            Rect::new(area.x + cut, area.y, area.w - cut, area.h),
        )
    } else {
        let cut = rng.range(min_leaf, area.h - min_leaf + 1);
        (
            Rect::new(area.x, area.y, area.w, cut),
            Rect::new(area.x, area.y + cut, area.w, area.h - cut),
        )
    };
    let left = bsp(a, min_leaf, rng, leaves, links);
    let right = bsp(b, min_leaf, rng, leaves, links);
    links.push((left.clone(), right.clone()));
    left.into_iter().chain(right).collect()
}

fn layout(area: Rect, min_leaf: i32, rng: &mut Rng) -> Layout {
    let mut leaves = Vec::new();
    let mut links = Vec::new();
    bsp(area, min_leaf, rng, &mut leaves, &mut links);
    let rooms: Vec<Room> = leaves
        .iter()
        .map(|leaf| {
            let t = *rng.pick(&[1, 2, 2, 2, 3]);
            let inner = leaf.grow(-t);
            // Most rooms fill their leaf (thin shared walls); some are smaller
            // and leave void around them.
            let (w, h) = if rng.chance(0.7) {
                (inner.w, inner.h)
            } else {
                (
                    rng.range((inner.w * 3 / 4).max(4), inner.w + 1),
                    rng.range((inner.h * 3 / 4).max(4), inner.h + 1),
                )
            };
            let x = rng.range(inner.x, inner.x1() - w + 1);
            let y = rng.range(inner.y, inner.y1() - h + 1);
            let u = rng.unit();
            let shape = if w.min(h) < 16 || u < 0.65 {
                Shape::Rect
            } else if u < 0.85 {
                Shape::Octagon(w.min(h) / 4)
            } else {
                Shape::Round
            };
            Room {
                r: Rect::new(x, y, w, h),
                t,
                shape,
            }
        })
        .collect();
    let mut corridors = Vec::new();
    for (a, b) in links {
        // Join the closest pair across the split: short corridors, like a
        // designer would draw.
        let mut best = (i64::MAX, 0, 0);
        for &i in &a {
            for &j in &b {
                let (ax, ay) = rooms[i].r.center();
                let (bx, by) = rooms[j].r.center();
                let d = ((ax - bx) as i64).pow(2) + ((ay - by) as i64).pow(2);
                if d < best.0 {
                    best = (d, i, j);
                }
            }
        }
        let cw = *rng.pick(&[2, 3, 3, 4]);
        // Aim at a random point in the middle half of each room (inside any
        // shape) rather than the centre, so doors are not all mid-wall.
        let mut target = |r: Rect| {
            let q = Rect::new(r.x + r.w / 4, r.y + r.h / 4, r.w / 2, r.h / 2);
            (
                rng.range(q.x, q.x1() - cw + 1),
                rng.range(q.y, q.y1() - cw + 1),
            )
        };
        let pa = target(rooms[best.1].r);
        let pb = target(rooms[best.2].r);
        let (p, q) = if rng.chance(0.5) { (pa, pb) } else { (pb, pa) };
        // L-shape: horizontal from p, then vertical into q.
        corridors.push(Rect::new(p.0.min(q.0), p.1, (p.0 - q.0).abs() + cw, cw));
        corridors.push(Rect::new(q.0, p.1.min(q.1), cw, (p.1 - q.1).abs() + cw));
    }
    Layout { rooms, corridors }
}

/// Paints a layout: carved floors (a room's floor wins over a corridor
/// crossing it), walls by growing each room's floor by its thickness and
/// each corridor's by one pixel (so every floor pixel is enclosed, corners
/// included), void everywhere else. Returns what each pixel became.
fn paint_layout(
    c: &mut Canvas,
    l: &Layout,
    room_wall: &dyn Fn(usize) -> [u8; 4],
    room_floor: &dyn Fn(usize) -> Floor,
    corridor_wall: [u8; 4],
    corridor_floor: Floor,
) -> Vec<Owner> {
    let (w, h) = (c.width as i32, c.height as i32);
    let mut owner = vec![Owner::Void; c.px.len()];
    let at = |x: i32, y: i32| (y * w + x) as usize;
    for r in &l.corridors {
        for y in r.y.max(0)..r.y1().min(h) {
            for x in r.x.max(0)..r.x1().min(w) {
                owner[at(x, y)] = Owner::Corridor;
            }
        }
    }
    for (i, room) in l.rooms.iter().enumerate() {
        let r = room.r;
        for y in r.y.max(0)..r.y1().min(h) {
            for x in r.x.max(0)..r.x1().min(w) {
                if room.inside(x, y) {
                    owner[at(x, y)] = Owner::Room(i);
                }
            }
        }
    }
    // Walls claim only void: a corridor through a room's wall is a door.
    let grow = |c: &mut Canvas, owner: &mut Vec<Owner>, x: i32, y: i32, t: i32, col: [u8; 4]| {
        for ny in (y - t).max(0)..=(y + t).min(h - 1) {
            for nx in (x - t).max(0)..=(x + t).min(w - 1) {
                if owner[at(nx, ny)] == Owner::Void {
                    owner[at(nx, ny)] = Owner::Wall;
                    c.px[at(nx, ny)] = col;
                }
            }
        }
    };
    for y in 0..h {
        for x in 0..w {
            if let Owner::Room(i) = owner[at(x, y)] {
                grow(c, &mut owner, x, y, l.rooms[i].t, room_wall(i));
            }
        }
    }
    for y in 0..h {
        for x in 0..w {
            if owner[at(x, y)] == Owner::Corridor {
                grow(c, &mut owner, x, y, 1, corridor_wall);
            }
        }
    }
    let floors: Vec<Floor> = (0..l.rooms.len()).map(room_floor).collect();
    for y in 0..h {
        for x in 0..w {
            let f = match owner[at(x, y)] {
                Owner::Room(i) => floors[i],
                Owner::Corridor => corridor_floor,
                _ => continue,
            };
            c.px[at(x, y)] = f.color(x, y, c.seed);
        }
    }
    owner
}

/// Sets up to `n` torches into the walls around room `room`: wall pixels on
/// a straight stretch of wall facing the room, whose far side is not floor
/// (a torch in a thin wall would light the next room too) and that are not
/// beside a doorway. Returns how many were set.
fn torches(
    c: &mut Canvas,
    owner: &[Owner],
    l: &Layout,
    room: usize,
    n: usize,
    torch: [u8; 4],
    rng: &mut Rng,
) -> usize {
    let w = c.width as i32;
    let at = |x: i32, y: i32| {
        if c.in_bounds(x, y) {
            owner[(y * w + x) as usize]
        } else {
            Owner::Void
        }
    };
    let r = l.rooms[room].r.grow(1);
    let mut cands = Vec::new();
    for y in r.y..r.y1() {
        for x in r.x..r.x1() {
            if at(x, y) != Owner::Wall {
                continue;
            }
            for (dx, dy) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                if at(x - dx, y - dy) == Owner::Room(room)
                    && !at(x + dx, y + dy).is_floor()
                    && !at(x + dy, y + dx).is_floor()
                    && !at(x - dy, y - dx).is_floor()
                    // The wall runs on both sides: not the tip of a staircase.
                    && at(x + dy, y + dx) == Owner::Wall
                    && at(x - dy, y - dx) == Owner::Wall
                {
                    cands.push((x, y));
                }
            }
        }
    }
    let mut placed: Vec<(i32, i32)> = Vec::new();
    let room_r = l.rooms[room].r;
    let spacing = ((room_r.w + room_r.h) / (2 * n.max(1) as i32)).clamp(4, 24);
    for _ in 0..n * 20 {
        if placed.len() >= n || cands.is_empty() {
            break;
        }
        let &(x, y) = rng.pick(&cands);
        if placed
            .iter()
            .all(|&(px, py)| (px - x).abs().max((py - y).abs()) >= spacing)
        {
            c.set(x, y, torch);
            placed.push((x, y));
        }
    }
    placed.len()
}

/// Paints `r` with `col`, but only over room `room`'s own floor: furniture
/// never blocks a corridor that happens to cross the room.
fn paint_on_room(c: &mut Canvas, owner: &[Owner], r: Rect, room: usize, col: [u8; 4]) {
    let w = c.width as i32;
    for y in r.y.max(0)..r.y1().min(c.height as i32) {
        for x in r.x.max(0)..r.x1().min(w) {
            if owner[(y * w + x) as usize] == Owner::Room(room) {
                c.set(x, y, col);
            }
        }
    }
}

/// True when all of `r` is room `room`'s own floor.
fn on_room(c: &Canvas, owner: &[Owner], r: Rect, room: usize) -> bool {
    let w = c.width as i32;
    (r.y..r.y1()).all(|y| {
        (r.x..r.x1()).all(|x| c.in_bounds(x, y) && owner[(y * w + x) as usize] == Owner::Room(room))
    })
}

/// Two rows of `size` px columns along the long axis of room `room`, every
/// `step` px, a quarter of the way in from each long wall: a colonnade, the
/// way halls are really furnished (a dense grid reads as a pegboard).
fn colonnade(
    c: &mut Canvas,
    owner: &[Owner],
    l: &Layout,
    room: usize,
    step: i32,
    size: i32,
    col: [u8; 4],
) {
    let r = l.rooms[room].r;
    let along = r.w >= r.h;
    let (len, across) = if along { (r.w, r.h) } else { (r.h, r.w) };
    let n = (len - 2 * step) / step;
    if n < 1 || across < 10 {
        return;
    }
    let first = (len - n * step) / 2;
    for row in [across / 4, across - across / 4 - size] {
        for k in 0..=n {
            let a = first + k * step - size / 2;
            let p = if along {
                Rect::new(r.x + a, r.y + row, size, size)
            } else {
                Rect::new(r.x + row, r.y + a, size, size)
            };
            // Only on this room's own floor, with a pixel of floor around it.
            if on_room(c, owner, p.grow(1), room) {
                c.fill_rect(p, col);
            }
        }
    }
}

/// A dungeon, `w` x `h` px: BSP rooms (some octagonal or round) joined by
/// L-shaped corridors, walls 1-3 px thick with void beyond, warm torches set
/// into the walls, colonnades of one-pixel pillars in the larger rooms and a
/// blue crystal standing in one room. Shows many small lights, thin and
/// staircase walls, light spilling through doorways and pillar shadows;
/// every floor pixel is enclosed.
pub fn dungeon(w: usize, h: usize, seed: u64) -> Painted {
    let (w, h) = (w.max(32) as i32, h.max(32) as i32);
    let mut rng = Rng::new(seed);
    let mut pal = PaletteBuilder::new(&format!(
        "Dungeon {w}x{h}, seed {seed}: rooms, corridors, torches."
    ));
    let stone = pal.wall("rough stone walls", 0x4a4652, 0.5);
    let brick = pal.wall("red brick walls", 0x7a3428, [0.6, 0.32, 0.25]);
    let pillar = pal.wall("pillars", 0x4e5868, 0.6);
    let torch = pal.emitter("torches", 0xff9a2a, [12.0, 6.4, 2.0], None);
    let crystal = pal.emitter(
        "blue crystal",
        0x60d8ff,
        [3.0, 9.0, 18.0],
        Some(Value::Grey(0.3)),
    );

    let l = layout(
        Rect::new(2, 2, w - 4, h - 4),
        (w.min(h) / 5).clamp(12, 40),
        &mut rng,
    );
    let styles: Vec<(bool, Floor)> = (0..l.rooms.len())
        .map(|_| (rng.chance(0.25), *rng.pick(&ROOM_FLOORS)))
        .collect();
    let mut c = Canvas::new(w as usize, h as usize, VOID, seed);
    let owner = paint_layout(
        &mut c,
        &l,
        &|i| if styles[i].0 { brick } else { stone },
        &|i| styles[i].1,
        stone,
        CORRIDOR_FLOOR,
    );
    let mut crystal_room = None;
    for (i, room) in l.rooms.iter().enumerate() {
        let r = room.r;
        if r.area() >= 20 * 20 && rng.chance(0.5) {
            colonnade(&mut c, &owner, &l, i, *rng.pick(&[5, 6, 7]), 1, pillar);
        } else if crystal_room.is_none() && r.w.min(r.h) >= 12 {
            crystal_room = Some(i);
            continue;
        }
        let n = (1 + r.area() / 200).min(5) as usize;
        torches(&mut c, &owner, &l, i, n, torch, &mut rng);
    }
    // The crystal is the one coloured light among the torches: it stands
    // alone in its room so its blue is not washed out.
    if let Some(i) = crystal_room {
        let (cx, cy) = l.rooms[i].r.center();
        c.set(cx, cy, crystal);
    }
    Painted::new("dungeon", c, &pal)
}

/// Floors for ordinary rooms.
const ROOM_FLOORS: [Floor; 5] = [
    Floor::Flagstones {
        base: 0xa29a8c,
        tile: 6,
    },
    Floor::Planks {
        base: 0xae8256,
        width: 3,
        length: 14,
    },
    Floor::Checker {
        a: 0xc4b496,
        b: 0xa8785a,
        tile: 4,
    },
    Floor::Flagstones {
        base: 0x9aa0aa,
        tile: 8,
    },
    Floor::Flagstones {
        base: 0xb0a488,
        tile: 4,
    },
];

const CORRIDOR_FLOOR: Floor = Floor::Flagstones {
    base: 0x9a9286,
    tile: 5,
};

/// A perfect maze (exactly one path between any two cells) of one-pixel
/// hedge walls and `cell`-px corridors, centred in `w` x `h` (void margin),
/// with an entrance at the top left and an exit at the bottom right, and
/// lanterns set into the hedges. One-pixel walls lit from both sides are the
/// hardest case for wall tracing and visibility; light leaks out of the
/// entrance and exit into the void.
pub fn maze(w: usize, h: usize, cell: usize, seed: u64) -> Painted {
    let p = cell.max(1) as i32 + 1;
    let (w, h) = ((w as i32).max(2 * p + 1), (h as i32).max(2 * p + 1));
    let (cols, rows) = ((w - 1) / p, (h - 1) / p);
    let (mw, mh) = (cols * p + 1, rows * p + 1);
    let (ox, oy) = ((w - mw) / 2, (h - mh) / 2);
    let mut rng = Rng::new(seed);
    let mut pal = PaletteBuilder::new(&format!(
        "Hedge maze {w}x{h}, {cell}-px paths, seed {seed}."
    ));
    let hedge = pal.wall("clipped hedges", 0x2e5e2a, [0.25, 0.5, 0.2]);
    let lantern = pal.emitter(
        "lanterns hung in the hedges",
        0xffe27a,
        [10.0, 8.2, 4.6],
        None,
    );

    let mut c = Canvas::new(w as usize, h as usize, VOID, seed);
    c.floor(
        Rect::new(ox, oy, mw, mh),
        Floor::Ground {
            base: 0xc2b69a,
            blotch: 4,
        },
    );
    for i in 0..=cols {
        c.fill_rect(Rect::new(ox + i * p, oy, 1, mh), hedge);
    }
    for j in 0..=rows {
        c.fill_rect(Rect::new(ox, oy + j * p, mw, 1), hedge);
    }
    // Recursive backtracker: long winding corridors, few short dead ends.
    let idx = |i: i32, j: i32| (j * cols + i) as usize;
    let mut seen = vec![false; (cols * rows) as usize];
    let mut stack = vec![(0, 0)];
    seen[0] = true;
    let seed_f = c.seed;
    let path = |x, y| {
        Floor::Ground {
            base: 0xc2b69a,
            blotch: 4,
        }
        .color(x, y, seed_f)
    };
    while let Some(&(i, j)) = stack.last() {
        let next: Vec<(i32, i32)> = [(1, 0), (-1, 0), (0, 1), (0, -1)]
            .into_iter()
            .map(|(di, dj)| (i + di, j + dj))
            .filter(|&(a, b)| a >= 0 && b >= 0 && a < cols && b < rows && !seen[idx(a, b)])
            .collect();
        if next.is_empty() {
            stack.pop();
            continue;
        }
        let (a, b) = *rng.pick(&next);
        seen[idx(a, b)] = true;
        // Knock out the wall between the two cells.
        let wall = if a != i {
            Rect::new(ox + i.max(a) * p, oy + j * p + 1, 1, p - 1)
        } else {
            Rect::new(ox + i * p + 1, oy + j.max(b) * p, p - 1, 1)
        };
        c.fill_rect_with(wall, path);
        stack.push((a, b));
    }
    c.fill_rect_with(Rect::new(ox + 1, oy, p - 1, 1), path);
    c.fill_rect_with(Rect::new(ox + mw - p, oy + mh - 1, p - 1, 1), path);

    // Lanterns: inside wall runs (not at lattice junctions), off the border.
    let mut cands = Vec::new();
    for y in oy + 1..oy + mh - 1 {
        for x in ox + 1..ox + mw - 1 {
            let junction = (x - ox) % p == 0 && (y - oy) % p == 0;
            if !junction && c.get(x, y) == Some(hedge) {
                cands.push((x, y));
            }
        }
    }
    let n = ((cols * rows) / 8).max(2) as usize;
    let mut placed: Vec<(i32, i32)> = Vec::new();
    for _ in 0..n * 30 {
        if placed.len() >= n || cands.is_empty() {
            break;
        }
        let &(x, y) = rng.pick(&cands);
        if placed
            .iter()
            .all(|&(a, b)| (a - x).abs() + (b - y).abs() >= 2 * p)
        {
            c.set(x, y, lantern);
            placed.push((x, y));
        }
    }
    Painted::new("maze", c, &pal)
}

/// Places up to `n` rectangles from `size()` inside `area`, each kept `gap`
/// px clear of the others and of `keep_out`.
fn scatter(
    area: Rect,
    n: usize,
    gap: i32,
    keep_out: &[Rect],
    rng: &mut Rng,
    mut size: impl FnMut(&mut Rng) -> (i32, i32),
) -> Vec<Rect> {
    let mut out: Vec<Rect> = Vec::new();
    for _ in 0..n {
        for _ in 0..40 {
            let (w, h) = size(rng);
            if w > area.w || h > area.h {
                continue;
            }
            let r = Rect::new(
                rng.range(area.x, area.x1() - w + 1),
                rng.range(area.y, area.y1() - h + 1),
                w,
                h,
            );
            let g = r.grow(gap);
            if keep_out.iter().chain(&out).all(|o| !g.intersects(o)) {
                out.push(r);
                break;
            }
        }
    }
    out
}

/// An open courtyard, `size` x `3/4 size` px: `n` scattered rectangular
/// pillars (many one or two pixels, some large blocks) lit by two area
/// lights, with a ruined wall along the top and left edges and nothing on
/// the right and bottom, where light escapes off the image. Shows soft
/// shadows with penumbrae that widen with distance from the pillar.
pub fn pillars(size: usize, n: usize, seed: u64) -> Painted {
    let w = size.max(32) as i32;
    let h = w * 3 / 4;
    let k = w as f64 / 160.0;
    let sc = |v: f64| ((v * k).round() as i32).max(1);
    let mut rng = Rng::new(seed);
    let mut pal = PaletteBuilder::new(&format!(
        "Pillared courtyard {w}x{h}, {n} pillars, seed {seed}: soft shadows."
    ));
    let column = pal.wall("stone pillars", 0x5c5868, 0.55);
    let ruin = pal.wall("ruined wall", 0x4c463c, 0.45);
    let light = pal.emitter("light panels", 0xfff4d8, [7.0, 6.6, 5.7], None);

    let mut c = Canvas::new(w as usize, h as usize, VOID, seed);
    c.floor(
        Rect::new(0, 0, w, h),
        Floor::Ground {
            base: 0xa6ae80,
            blotch: 5,
        },
    );
    // A flagstone path across the yard.
    c.floor(
        Rect::new(0, h * 11 / 20, w, sc(10.0)),
        Floor::Flagstones {
            base: 0xb4aa98,
            tile: 5,
        },
    );
    // Ruined wall: runs of wall with gaps, top and left edges only.
    for horizontal in [true, false] {
        let len = if horizontal { w } else { h };
        let mut pos = 0;
        while pos < len {
            let run = rng.range(sc(8.0), sc(30.0));
            let r = if horizontal {
                Rect::new(pos, 0, run, 2)
            } else {
                Rect::new(0, pos, 2, run)
            };
            c.fill_rect(r, ruin);
            pos += run + rng.range(sc(3.0), sc(10.0));
        }
    }
    let lights = [
        Rect::new(
            (w as f64 * 0.28) as i32,
            (h as f64 * 0.3) as i32,
            sc(10.0),
            2,
        ),
        Rect::new(
            (w as f64 * 0.68) as i32,
            (h as f64 * 0.6) as i32,
            2,
            sc(10.0),
        ),
    ];
    for r in lights {
        c.fill_rect(r, light);
    }
    let big = sc(10.0).max(4);
    let keep: Vec<Rect> = lights.iter().map(|r| r.grow(2)).collect();
    for r in scatter(
        Rect::new(5, 5, w - 8, h - 8),
        n,
        1,
        &keep,
        &mut rng,
        |rng| {
            let u = rng.unit();
            if u < 0.35 {
                (1, 1)
            } else if u < 0.6 {
                *rng.pick(&[(2, 2), (1, 2), (2, 1)])
            } else {
                (rng.range(3, big + 1), rng.range(3, big + 1))
            }
        },
    ) {
        c.fill_rect(r, column);
    }
    Painted::new("pillars", c, &pal)
}

/// A long hall, `w` x `h` px, with lamps set into both long walls every 32
/// px (staggered) and columns between them; the palette sets `falloff = 24`,
/// so each lamp lights a pool of floor that fades before the next one. Shows
/// falloff (`[bake] falloff`) against the unattenuated flatland kernel.
pub fn falloff_hall(w: usize, h: usize) -> Painted {
    let (w, h) = (w.max(48) as i32, h.max(24) as i32);
    let t = 2;
    let mut pal = PaletteBuilder::new(&format!(
        "Long hall {w}x{h} with a row of lamps and falloff 24."
    ));
    pal.falloff(24.0);
    let stone = pal.wall("hall walls", 0x474350, 0.5);
    let column = pal.wall("columns", 0x58506a, 0.55);
    let lamp = pal.emitter("wall lamps", 0xffe6a8, [10.0, 8.4, 6.0], None);

    let mut c = Canvas::new(w as usize, h as usize, VOID, 7);
    c.floor(
        Rect::new(0, 0, w, h),
        Floor::Flagstones {
            base: 0xa09a8e,
            tile: 8,
        },
    );
    // A red runner with gold edges down the middle of the hall.
    let runner = (h / 5).max(3);
    let ry = h / 2 - runner / 2;
    c.floor(
        Rect::new(t + 6, ry, w - 2 * t - 12, runner),
        Floor::Plain { base: 0x9c3a34 },
    );
    c.floor(
        Rect::new(t + 6, ry, w - 2 * t - 12, 1),
        Floor::Plain { base: 0xc4a050 },
    );
    c.floor(
        Rect::new(t + 6, ry + runner - 1, w - 2 * t - 12, 1),
        Floor::Plain { base: 0xc4a050 },
    );
    c.outline_rect(Rect::new(0, 0, w, h), t, stone);
    // Lamps every 32 px in each long wall, the two rows offset by half a
    // step; a column stands in front of each wall between its lamps, so it
    // shades the floor without hiding a lamp.
    let step = 32;
    let mut x = step / 2;
    while x + 2 < w - t {
        c.fill_rect(Rect::new(x - 1, t - 1, 3, 1), lamp);
        c.fill_rect(Rect::new(x - 1, h - t - 8, 3, 3), column);
        x += step;
    }
    let mut x = step;
    while x + 2 < w - t {
        c.fill_rect(Rect::new(x - 1, h - t, 3, 1), lamp);
        c.fill_rect(Rect::new(x - 1, t + 5, 3, 3), column);
        x += step;
    }
    Painted::new("falloff_hall", c, &pal)
}

/// A game-sized level, `size` x `size` px (512 or more intended): a BSP
/// dungeon of rooms and corridors with a colonnaded great hall lit by
/// braziers, an open courtyard of ruins under cool lamp posts, a round
/// cavern split by a glowing lava river with a crossing, a library of
/// wooden shelves with reading candles, and torch-lit rooms elsewhere. The
/// palette sets a falloff of `size / 10.7` (48 at 512) so distant lights
/// fade as in a game. Shows everything at once, at the scale where bake
/// speed matters.
pub fn big_level(size: usize, seed: u64) -> Painted {
    let s = size.max(128) as i32;
    let k = s as f64 / 512.0;
    let mut rng = Rng::new(seed);
    let mut pal = PaletteBuilder::new(&format!(
        "Big level {s}x{s}, seed {seed}: halls, courtyard, lava, library."
    ));
    pal.falloff((48.0 * k).round());
    let stone = pal.wall("rough stone walls", 0x4a4652, 0.5);
    let brick = pal.wall("red brick walls", 0x7a3428, [0.6, 0.32, 0.25]);
    let pillar = pal.wall("pillars and columns", 0x4e5868, 0.6);
    let shelf = pal.wall("bookshelves", 0x5a381c, [0.45, 0.3, 0.18]);
    let ruin = pal.wall("ruins", 0x56503e, 0.45);
    // Brighter than the dungeon's: the falloff dims everything beyond a room.
    let torch = pal.emitter("torches", 0xff9a2a, [15.0, 8.0, 2.5], None);
    let brazier = pal.emitter("braziers", 0xffc840, [12.0, 8.4, 3.1], None);
    let moon = pal.emitter("lamp posts", 0xd8e8ff, [7.0, 8.4, 11.0], None);
    let lava = pal.emitter("lava", 0xff4a10, [2.4, 0.6, 0.1], None);
    let candle = pal.emitter("reading candles", 0xfff0a0, [8.0, 6.6, 3.4], None);

    let mut l = layout(Rect::new(2, 2, s - 4, s - 4), (s / 8).max(24), &mut rng);
    let mut order: Vec<usize> = (0..l.rooms.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(l.rooms[i].r.area()));
    // The four largest rooms get a purpose; the cavern is round, the others
    // need straight walls for their furniture.
    for (rank, &i) in order.iter().take(4).enumerate() {
        l.rooms[i].shape = if rank == 2 { Shape::Round } else { Shape::Rect };
    }
    let role = |i: usize| order.iter().position(|&o| o == i).unwrap_or(usize::MAX);
    let styles: Vec<(bool, Floor)> = (0..l.rooms.len())
        .map(|i| {
            let f = match role(i) {
                0 => Floor::Checker {
                    a: 0xd0c6b0,
                    b: 0x8e96a4,
                    tile: 6,
                },
                1 => Floor::Ground {
                    base: 0xa0ac78,
                    blotch: 6,
                },
                2 => Floor::Ground {
                    base: 0x9c8c7a,
                    blotch: 5,
                },
                3 => Floor::Planks {
                    base: 0xae8256,
                    width: 3,
                    length: 16,
                },
                _ => *rng.pick(&ROOM_FLOORS),
            };
            (role(i) > 3 && rng.chance(0.25), f)
        })
        .collect();
    let mut c = Canvas::new(s as usize, s as usize, VOID, seed);
    let owner = paint_layout(
        &mut c,
        &l,
        &|i| if styles[i].0 { brick } else { stone },
        &|i| styles[i].1,
        stone,
        CORRIDOR_FLOOR,
    );
    for i in 0..l.rooms.len() {
        let r = l.rooms[i].r;
        let (cx, cy) = r.center();
        match role(i) {
            0 => {
                // Great hall: a colonnade and braziers down the middle.
                colonnade(&mut c, &owner, &l, i, 10, 2, pillar);
                for f in [1, 2, 3] {
                    let (bx, by) = if r.w >= r.h {
                        (r.x + r.w * f / 4, cy)
                    } else {
                        (cx, r.y + r.h * f / 4)
                    };
                    paint_on_room(&mut c, &owner, Rect::new(bx - 1, by - 1, 2, 2), i, brazier);
                }
                torches(&mut c, &owner, &l, i, 6, torch, &mut rng);
            }
            1 => {
                // Courtyard: scattered ruins under four cool lamp posts.
                let posts: Vec<Rect> = (0..4)
                    .map(|q| {
                        Rect::new(
                            r.x + r.w * (1 + 2 * (q % 2)) / 4,
                            r.y + r.h * (1 + 2 * (q / 2)) / 4,
                            1,
                            1,
                        )
                    })
                    .collect();
                let keep: Vec<Rect> = posts.iter().map(|p| p.grow(3)).collect();
                let big = (r.w.min(r.h) / 8).max(3);
                for p in scatter(
                    r.grow(-3),
                    (r.area() / 400) as usize,
                    2,
                    &keep,
                    &mut rng,
                    |rng| {
                        if rng.chance(0.4) {
                            (1, 1)
                        } else {
                            (rng.range(1, big), rng.range(1, big))
                        }
                    },
                ) {
                    paint_on_room(&mut c, &owner, p, i, ruin);
                }
                for p in posts {
                    paint_on_room(&mut c, &owner, p, i, moon);
                }
            }
            2 => {
                // Cavern: a lava river, 2 px wide so every lava pixel shows
                // its glow, meandering across the long axis; a gap is the
                // crossing. The lava is the only light.
                let along = r.w >= r.h;
                let (len, across) = if along { (r.w, r.h) } else { (r.h, r.w) };
                let amp = across as f64 / 6.0;
                let gap = len / 2 + rng.range(-len / 6, len / 6 + 1);
                let mut prev: Option<(i32, i32)> = None;
                for a in 0..len {
                    let b = (across as f64 / 2.0
                        + amp * (a as f64 * std::f64::consts::TAU / (len as f64 * 0.6)).sin())
                        as i32;
                    let p = if along {
                        (r.x + a, r.y + b)
                    } else {
                        (r.x + b, r.y + a)
                    };
                    if (a - gap).abs() <= 2 {
                        prev = None;
                        continue;
                    }
                    let q = prev.unwrap_or(p);
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        draw_line_on_room(
                            &mut c,
                            &owner,
                            (q.0 + dx, q.1 + dy),
                            (p.0 + dx, p.1 + dy),
                            i,
                            lava,
                        );
                    }
                    prev = Some(p);
                }
            }
            3 => {
                // Library: rows of shelves with aisles at both ends and a
                // candle at one end of each shelf, alternating sides.
                let mut y = r.y + 3;
                let mut n = 0;
                while y + 2 < r.y1() - 2 {
                    paint_on_room(&mut c, &owner, Rect::new(r.x + 4, y, r.w - 8, 2), i, shelf);
                    let end = if n % 2 == 0 { r.x + 2 } else { r.x1() - 3 };
                    paint_on_room(&mut c, &owner, Rect::new(end, y, 1, 1), i, candle);
                    y += 6;
                    n += 1;
                }
                torches(&mut c, &owner, &l, i, 2, torch, &mut rng);
            }
            _ => {
                let big = r.area() >= 30 * 30;
                if big && rng.chance(0.4) {
                    colonnade(
                        &mut c,
                        &owner,
                        &l,
                        i,
                        *rng.pick(&[6, 8, 10]),
                        *rng.pick(&[1, 2]),
                        pillar,
                    );
                }
                if big && rng.chance(0.6) && on_room(&c, &owner, Rect::new(cx - 2, cy - 2, 4, 4), i)
                {
                    c.fill_rect(Rect::new(cx - 1, cy - 1, 2, 2), brazier);
                }
                let n = (1 + r.area() / 300).min(6) as usize;
                torches(&mut c, &owner, &l, i, n, torch, &mut rng);
            }
        }
    }
    Painted::new("big_level", c, &pal)
}

/// An 8-connected line painted only over room `room`'s own floor.
fn draw_line_on_room(
    c: &mut Canvas,
    owner: &[Owner],
    a: (i32, i32),
    b: (i32, i32),
    room: usize,
    col: [u8; 4],
) {
    let w = c.width as i32;
    for (x, y) in line_points(a, b) {
        if c.in_bounds(x, y) && owner[(y * w + x) as usize] == Owner::Room(room) {
            c.set(x, y, col);
        }
    }
}

// ---------------------------------------------------------------------------
// Benchmark and test levels

/// Benchmark level, `size` x `size` px inside an enclosing wall: about
/// `obstacles` rectangular obstacles (thin walls and blocks, sides from
/// `size/128` to `size/13` px) and `lights` small square emitters
/// (`size/256` px). Every length scales with `size`, so 512 with 60
/// obstacles and 12 lights and 2048 with the same counts are the same scene
/// at two resolutions. Palette falloff is `size / 12`.
pub fn bench_obstacles(size: usize, obstacles: usize, lights: usize, seed: u64) -> Painted {
    let s = size.max(16) as i32;
    let k = s as f64 / 512.0;
    let sc = |v: f64| ((v * k).round() as i32).max(1);
    let mut rng = Rng::new(seed);
    let mut pal = PaletteBuilder::new(&format!(
        "Benchmark: {s}x{s}, about {obstacles} obstacles, {lights} lights, seed {seed}."
    ));
    pal.falloff(s as f64 / 12.0);
    let wall = pal.wall("enclosing wall", 0x50505a, 0.6);
    let block = pal.wall("obstacles", 0x6a4e3a, [0.55, 0.45, 0.35]);
    let light = pal.emitter("lights", 0xfff0d0, [12.0, 11.0, 9.0], None);

    let mut c = Canvas::new(s as usize, s as usize, VOID, seed);
    c.floor(
        Rect::new(0, 0, s, s),
        Floor::Flagstones {
            base: 0xa8a498,
            tile: sc(16.0).max(3),
        },
    );
    let t = sc(2.0).max(2);
    c.outline_rect(Rect::new(0, 0, s, s), t, wall);
    let inner = Rect::new(t + 1, t + 1, s - 2 * t - 2, s - 2 * t - 2);
    let placed = scatter(inner, obstacles, 1, &[], &mut rng, |rng| {
        // Sides log-uniform between 4 and 40 px at 512; a quarter are thin
        // wall segments, which produce long edges with little area.
        let side = |rng: &mut Rng| ((4.0 * 10f64.powf(rng.unit())) * k).round().max(1.0) as i32;
        if rng.chance(0.25) {
            let thin = sc(2.0);
            let long = side(rng) * 2;
            if rng.chance(0.5) {
                (thin, long)
            } else {
                (long, thin)
            }
        } else {
            (side(rng), side(rng))
        }
    });
    for &r in &placed {
        c.fill_rect(r, block);
    }
    let ls = sc(2.0);
    let keep: Vec<Rect> = placed.iter().map(|r| r.grow(sc(2.0))).collect();
    for r in scatter(
        inner.grow(-sc(4.0)),
        lights,
        sc(16.0),
        &keep,
        &mut rng,
        |_| (ls, ls),
    ) {
        c.fill_rect(r, light);
    }
    Painted::new(&format!("bench_obstacles_{s}"), c, &pal)
}

/// Benchmark level, `size` x `size` px with no enclosing wall: `walls`
/// scattered one-pixel walls and `lights` one-pixel lights (e.g. 64 px, 40
/// walls, 3 lights). Many tiny loops and much light escaping off the image:
/// the worst case per pixel of wall for tracing and visibility. No falloff.
pub fn bench_scattered(size: usize, walls: usize, lights: usize, seed: u64) -> Painted {
    let s = size.max(4) as i32;
    let mut rng = Rng::new(seed);
    let mut pal = PaletteBuilder::new(&format!(
        "Benchmark: {s}x{s}, {walls} one-pixel walls, {lights} one-pixel lights, seed {seed}."
    ));
    let wall = pal.wall("one-pixel walls", 0x505060, 0.6);
    let light = pal.emitter("one-pixel lights", 0xfff0d0, [10.0, 9.2, 7.6], None);
    let mut c = Canvas::new(s as usize, s as usize, VOID, seed);
    c.floor(Rect::new(0, 0, s, s), Floor::Plain { base: 0xa8a498 });
    let area = Rect::new(0, 0, s, s);
    let placed = scatter(area, walls, 0, &[], &mut rng, |_| (1, 1));
    for &r in &placed {
        c.fill_rect(r, wall);
    }
    for r in scatter(area, lights, 0, &placed, &mut rng, |_| (1, 1)) {
        c.fill_rect(r, light);
    }
    Painted::new(&format!("bench_scattered_{s}"), c, &pal)
}

/// A colour at least [`NEAR`] + 1 away (in some channel) from all of `taken`.
fn distinct_color(rng: &mut Rng, taken: &[[u8; 3]]) -> [u8; 3] {
    loop {
        let c = [
            rng.below(256) as u8,
            rng.below(256) as u8,
            rng.below(256) as u8,
        ];
        if taken.iter().all(|t| !is_near(c, *t)) {
            return c;
        }
    }
}

fn hex_of(c: [u8; 3]) -> u32 {
    (c[0] as u32) << 16 | (c[1] as u32) << 8 | c[2] as u32
}

/// A reflectance-like number in `0..=1`, exactly 0 or 1 a fifth of the time:
/// the edges of the range are where solvers and skips misbehave.
fn random_unit(rng: &mut Rng) -> f64 {
    match rng.below(10) {
        0 => 0.0,
        1 => 1.0,
        _ => (rng.unit() * 1000.0).round() / 1000.0,
    }
}

fn random_value(rng: &mut Rng, f: &mut dyn FnMut(&mut Rng) -> f64) -> Value {
    if rng.chance(0.5) {
        Value::Grey(f(rng))
    } else {
        Value::Rgb([f(rng), f(rng), f(rng)])
    }
}

/// A tiny random level for property tests: 3-24 px per side; floor, void
/// (alpha 0, sometimes none) and a few partly transparent floor pixels;
/// 1-4 wall materials with random reflectance in `0..=1` (grey or per
/// channel, sometimes exactly 0 or 1); 0-3 emitters with random, often
/// coloured emission (sometimes with reflectance); sometimes an explicit
/// `[[floor]]` albedo; falloff or none. Sometimes the level is a walled room.
/// The palette is always valid (docs/transport.md#palette-and-materials) and floor colours are never near a
/// wall or emitter colour.
pub fn random_small(seed: u64) -> Painted {
    let mut rng = Rng::new(seed ^ 0x7a11_5ca1_ab1e);
    let (w, h) = (rng.range(3, 25), rng.range(3, 25));
    let mut pal = PaletteBuilder::new(&format!("Random small level, seed {seed}."));
    if rng.chance(0.5) {
        pal.falloff(((0.5 + rng.unit() * 63.5) * 100.0).round() / 100.0);
    }
    let mut taken: Vec<[u8; 3]> = Vec::new();
    let mut walls = Vec::new();
    for i in 0..rng.range(1, 5) {
        let col = distinct_color(&mut rng, &taken);
        taken.push(col);
        let r = random_value(&mut rng, &mut random_unit);
        walls.push(pal.wall(&format!("wall {i}"), hex_of(col), r));
    }
    let mut emitters = Vec::new();
    for i in 0..rng.range(0, 4) {
        let col = distinct_color(&mut rng, &taken);
        taken.push(col);
        // Coloured more often than not: some channels dark.
        let e = random_value(&mut rng, &mut |rng: &mut Rng| {
            if rng.chance(0.3) {
                0.0
            } else {
                (rng.unit() * 2000.0).round() / 100.0
            }
        });
        let r = rng
            .chance(0.5)
            .then(|| random_value(&mut rng, &mut random_unit));
        emitters.push(pal.emitter(&format!("emitter {i}"), hex_of(col), e, r));
    }
    let mut floors = Vec::new();
    for _ in 0..rng.range(1, 4) {
        let col = distinct_color(&mut rng, &taken);
        taken.push(col);
        floors.push(rgb(hex_of(col)));
    }
    if rng.chance(0.25) {
        let a = random_value(&mut rng, &mut random_unit);
        let f = floors[0];
        pal.floor("floor with explicit albedo", hex_of([f[0], f[1], f[2]]), a);
    }

    let p_void = *rng.pick(&[0.0, 0.0, 0.1, 0.4]);
    let p_solid = rng.unit() * 0.5;
    let p_emit = if emitters.is_empty() { 0.0 } else { 0.25 };
    let translucent = rng.chance(0.1);
    let room = rng.chance(0.3);
    let mut c = Canvas::new(w as usize, h as usize, VOID, seed);
    for y in 0..h {
        for x in 0..w {
            let border = x == 0 || y == 0 || x == w - 1 || y == h - 1;
            let px = if room && border {
                if rng.chance(p_emit) {
                    *rng.pick(&emitters)
                } else {
                    *rng.pick(&walls)
                }
            } else if rng.chance(p_void) {
                VOID
            } else if rng.chance(p_solid) {
                if rng.chance(p_emit) {
                    *rng.pick(&emitters)
                } else {
                    *rng.pick(&walls)
                }
            } else {
                let mut f = *rng.pick(&floors);
                if translucent && rng.chance(0.3) {
                    f[3] = rng.range(1, 255) as u8;
                }
                f
            };
            c.set(x, y, px);
        }
    }
    Painted::new(&format!("random_{seed}"), c, &pal)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every generator at a small size, plus the sample sizes of the
    /// cheap ones.
    fn all() -> Vec<Painted> {
        vec![
            cornell(96),
            cornell(30),
            colour_bleed(128),
            colour_bleed(64),
            dungeon(192, 160, 7),
            dungeon(64, 48, 3),
            maze(128, 128, 3, 11),
            maze(41, 23, 1, 2),
            pillars(160, 70, 5),
            pillars(64, 20, 9),
            falloff_hall(256, 64),
            big_level(256, 1),
            bench_obstacles(256, 60, 12, 1),
            bench_scattered(64, 40, 3, 1),
            random_small(0),
            random_small(1),
        ]
    }

    /// `(colour, is_solid)` of every palette entry, read back from the TOML.
    fn palette_colors(p: &Painted) -> Vec<([u8; 3], bool)> {
        let table = p
            .palette_toml
            .parse::<toml::Table>()
            .unwrap_or_else(|e| panic!("{}: {e}", p.name));
        let mut out = Vec::new();
        for (key, solid) in [("wall", true), ("emitter", true), ("floor", false)] {
            for e in table
                .get(key)
                .and_then(|v| v.as_array())
                .into_iter()
                .flatten()
            {
                let hex = e["color"].as_str().expect("color is a string");
                assert!(
                    hex.len() == 7 && hex.starts_with('#'),
                    "{}: colour {hex}",
                    p.name
                );
                let c = u32::from_str_radix(&hex[1..], 16).expect("hex colour");
                out.push(([(c >> 16) as u8, (c >> 8) as u8, c as u8], solid));
            }
        }
        out
    }

    #[test]
    fn generators_are_deterministic() {
        for (a, b) in all().into_iter().zip(all()) {
            assert_eq!(a, b, "{} differs between two runs", a.name);
        }
        assert_ne!(
            dungeon(96, 96, 1).rgba,
            dungeon(96, 96, 2).rgba,
            "the seed matters"
        );
        assert_ne!(random_small(5), random_small(6));
    }

    #[test]
    fn sizes_are_as_asked() {
        let sized = [
            (cornell(96), 96, 96),
            (colour_bleed(128), 128, 96),
            (dungeon(192, 160, 7), 192, 160),
            (maze(128, 128, 3, 11), 128, 128),
            (pillars(160, 70, 5), 160, 120),
            (falloff_hall(256, 64), 256, 64),
            (big_level(512, 2014), 512, 512),
            (bench_obstacles(512, 60, 12, 1), 512, 512),
            (bench_scattered(64, 40, 3, 1), 64, 64),
        ];
        for (p, w, h) in sized {
            assert_eq!((p.width, p.height), (w, h), "{}", p.name);
            assert_eq!(p.rgba.len(), w * h, "{}", p.name);
            assert_eq!(p.to_image().dimensions(), (w as u32, h as u32));
        }
        for seed in 0..200 {
            let p = random_small(seed);
            assert!(
                (3..=24).contains(&p.width) && (3..=24).contains(&p.height),
                "{}",
                p.name
            );
            assert_eq!(p.rgba.len(), p.width * p.height);
        }
    }

    #[test]
    fn palettes_parse_and_floors_stay_clear_of_solid_colours() {
        let randoms = (0..300).map(random_small);
        for p in all().into_iter().chain(randoms) {
            let colors = palette_colors(&p);
            assert!(colors.iter().any(|c| c.1), "{}: no wall or emitter", p.name);
            for (i, a) in colors.iter().enumerate() {
                assert!(
                    colors[..i].iter().all(|b| b.0 != a.0),
                    "{}: colour listed twice",
                    p.name
                );
            }
            for px in &p.rgba {
                let c = [px[0], px[1], px[2]];
                if px[3] == 0 || colors.iter().any(|k| k.0 == c) {
                    continue;
                }
                for (s, _) in colors.iter().filter(|k| k.1) {
                    assert!(
                        !is_near(c, *s),
                        "{}: floor {c:?} is near palette colour {s:?}",
                        p.name
                    );
                }
            }
        }
    }

    #[test]
    fn the_real_parser_accepts_every_palette_and_sees_no_near_misses() {
        let randoms = (0..300).map(random_small);
        for p in all().into_iter().chain(randoms) {
            let (level, _) = p
                .level()
                .unwrap_or_else(|e| panic!("{e}\n{}", p.palette_toml));
            assert!(
                level.warnings.is_empty(),
                "{}: {:?}",
                p.name,
                level.warnings
            );
        }
    }

    #[test]
    fn random_palettes_cover_the_spec_ranges() {
        let (mut falloff, mut none, mut floors, mut coloured, mut edge) = (0, 0, 0, 0, 0);
        for seed in 0..300 {
            let p = random_small(seed);
            let t = p.palette_toml.parse::<toml::Table>().expect("toml");
            match t.get("bake").and_then(|b| b.get("falloff")) {
                Some(f) => {
                    assert!(f.as_float().expect("float") > 0.0);
                    falloff += 1;
                }
                None => none += 1,
            }
            floors += t.contains_key("floor") as usize;
            let nums = |v: &toml::Value| -> Vec<f64> {
                match v {
                    toml::Value::Array(a) => {
                        a.iter().map(|x| x.as_float().expect("float")).collect()
                    }
                    x => vec![x.as_float().expect("float")],
                }
            };
            let walls = t["wall"].as_array().expect("walls");
            assert!((1..=4).contains(&walls.len()));
            for w in walls {
                for r in nums(&w["reflectance"]) {
                    assert!((0.0..=1.0).contains(&r));
                    edge += (r == 0.0 || r == 1.0) as usize;
                }
            }
            for e in t
                .get("emitter")
                .and_then(|e| e.as_array())
                .into_iter()
                .flatten()
            {
                let em = nums(&e["emission"]);
                assert!(em.iter().all(|&x| x >= 0.0 && x.is_finite()));
                coloured += (em.len() == 3 && em.iter().any(|&x| x != em[0])) as usize;
                if let Some(r) = e.get("reflectance") {
                    assert!(nums(r).iter().all(|r| (0.0..=1.0).contains(r)));
                }
            }
        }
        // The generator really does exercise every branch.
        assert!(falloff > 50 && none > 50 && floors > 20 && coloured > 50 && edge > 20);
    }

    /// 8-neighbours of every floor pixel are in the image and not void.
    fn enclosed(p: &Painted) -> bool {
        let colors = palette_colors(p);
        let (w, h) = (p.width as i32, p.height as i32);
        let at = |x: i32, y: i32| p.rgba[(y * w + x) as usize];
        let floor =
            |c: [u8; 4]| c[3] != 0 && !colors.iter().any(|k| k.1 && k.0 == [c[0], c[1], c[2]]);
        (0..h).all(|y| {
            (0..w).all(|x| {
                !floor(at(x, y))
                    || (-1..=1).all(|dy| {
                        (-1..=1).all(|dx| {
                            let (nx, ny) = (x + dx, y + dy);
                            nx >= 0 && ny >= 0 && nx < w && ny < h && at(nx, ny)[3] != 0
                        })
                    })
            })
        })
    }

    #[test]
    fn dungeons_and_rooms_are_enclosed() {
        for seed in 0..8 {
            assert!(enclosed(&dungeon(160, 128, seed)), "dungeon seed {seed}");
        }
        assert!(enclosed(&big_level(256, 3)));
        assert!(enclosed(&cornell(64)));
        assert!(enclosed(&falloff_hall(100, 40)));
        assert!(enclosed(&bench_obstacles(128, 20, 4, 2)));
        // The courtyard is open on purpose.
        assert!(!enclosed(&pillars(96, 10, 1)));
    }

    #[test]
    fn the_maze_is_connected() {
        let p = maze(64, 48, 2, 4);
        let colors = palette_colors(&p);
        let (w, h) = (p.width as i32, p.height as i32);
        let free = |x: i32, y: i32| {
            let c = p.rgba[(y * w + x) as usize];
            c[3] != 0 && !colors.iter().any(|k| k.0 == [c[0], c[1], c[2]])
        };
        let cells: Vec<(i32, i32)> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| free(x, y))
            .collect();
        let mut seen = vec![false; (w * h) as usize];
        let mut stack = vec![cells[0]];
        seen[(cells[0].1 * w + cells[0].0) as usize] = true;
        let mut n = 0;
        while let Some((x, y)) = stack.pop() {
            n += 1;
            for (nx, ny) in [(x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)] {
                if nx >= 0
                    && ny >= 0
                    && nx < w
                    && ny < h
                    && free(nx, ny)
                    && !seen[(ny * w + nx) as usize]
                {
                    seen[(ny * w + nx) as usize] = true;
                    stack.push((nx, ny));
                }
            }
        }
        assert_eq!(n, cells.len(), "every path pixel is reachable");
    }

    #[test]
    fn benchmark_levels_have_what_they_promise() {
        for (size, lights) in [(512, 12), (2048, 12)] {
            let p = bench_obstacles(size, 60, lights, 1);
            let t = p.palette_toml.parse::<toml::Table>().expect("toml");
            let falloff = t["bake"]["falloff"].as_float().expect("falloff");
            assert!((falloff - size as f64 / 12.0).abs() < 0.01);
            let light = rgb(0xfff0d0);
            let lit = p.rgba.iter().filter(|&&c| c == light).count();
            let side = (2 * size / 512).max(1);
            assert_eq!(lit, lights * side * side, "{size}: every light placed");
        }
        let p = bench_scattered(64, 40, 3, 1);
        assert_eq!(p.rgba.iter().filter(|&&c| c == rgb(0x505060)).count(), 40);
        assert_eq!(p.rgba.iter().filter(|&&c| c == rgb(0xfff0d0)).count(), 3);
    }

    #[test]
    fn save_writes_the_image_and_palette() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = cornell(32);
        p.save(dir.path()).expect("save");
        let img = image::open(dir.path().join("cornell.png"))
            .expect("png")
            .to_rgba8();
        assert_eq!(img, p.to_image());
        let toml = std::fs::read_to_string(dir.path().join("cornell.palette.toml")).expect("toml");
        assert_eq!(toml, p.palette_toml);
    }

    #[test]
    fn near_floors_are_pushed_clear() {
        let solid = [[100, 100, 100], [141, 100, 100]];
        for c in [
            [100u8, 100, 100, 255],
            [120, 90, 110, 255],
            [0, 0, 0, 255],
            [255, 255, 255, 255],
        ] {
            let p = keep_clear(c, &solid);
            assert!(
                solid.iter().all(|s| !is_near([p[0], p[1], p[2]], *s)),
                "{c:?} -> {p:?}"
            );
        }
    }
}
