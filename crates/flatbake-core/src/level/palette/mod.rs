//! Palettes: which painted colour is which material (docs/transport.md#palette-and-materials).
//!
//! A palette is TOML text with an optional `[bake]` table and `[[wall]]`,
//! `[[emitter]]` and `[[floor]]` entries, which are added to the built-in
//! palette (an entry overrides the built-in entry of its colour) unless the
//! file starts with `builtin = false`. [`Palette::parse`] checks it
//! completely — unknown keys, wrong types, out-of-range numbers, duplicate
//! colours — and every error names the file and the 1-based line, because a
//! level designer fixes palettes by hand. [`Palette::resolve_for_level`]
//! applies the lookup order (docs/transport.md#palette-and-materials) and [`Palette::builtin`] is the default
//! palette. The level loader asks a palette what a colour is through
//! [`Palette::classify`] and [`Palette::nearest`]; nothing after loading looks
//! at palette text again.

use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use toml::Spanned;
use toml::de::{DeArray, DeTable, DeValue};

use crate::level::material::{Material, MaterialKind, Rgb, hex_color};
use parse::Parser;

mod parse;
mod text;

/// Where a palette came from.
#[derive(Clone, Debug, PartialEq)]
pub enum PaletteOrigin {
    /// flatbake's own palette.
    BuiltIn,
    /// A palette file.
    File(PathBuf),
}

impl std::fmt::Display for PaletteOrigin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PaletteOrigin::BuiltIn => f.write_str("built-in palette"),
            PaletteOrigin::File(p) => write!(f, "{}", p.display()),
        }
    }
}

/// A floor colour with an explicit albedo.
#[derive(Clone, Debug, PartialEq)]
pub struct FloorColor {
    /// The exact sRGB colour.
    pub color: [u8; 3],
    /// Linear albedo per channel, each in `0..=1`.
    pub albedo: Rgb,
    /// Line of the entry's `color` key, for messages (`None` when built in).
    pub line: Option<usize>,
    /// The entry's optional `name`, shown in the legend and in messages.
    pub name: Option<String>,
}

/// The optional `[bake]` table; command-line flags override each field.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PaletteSettings {
    /// Half-energy distance in pixels.
    pub falloff: Option<f64>,
    /// Truncate the bounce series after this many bounces (0 = direct light only).
    pub bounces: Option<u32>,
    /// Snap pixels within this many 8-bit steps (per channel) to a palette colour.
    pub tolerance: Option<u8>,
    /// Lightmap exposure.
    pub exposure: Option<f64>,
}

impl PaletteSettings {
    /// These settings where they are given, `base`'s elsewhere.
    pub fn over(&self, base: &PaletteSettings) -> PaletteSettings {
        PaletteSettings {
            falloff: self.falloff.or(base.falloff),
            bounces: self.bounces.or(base.bounces),
            tolerance: self.tolerance.or(base.tolerance),
            exposure: self.exposure.or(base.exposure),
        }
    }
}

/// A resolved palette.
#[derive(Clone, Debug, PartialEq)]
pub struct Palette {
    /// Where it came from, for messages.
    pub origin: PaletteOrigin,
    /// Walls and emitters, in palette order.
    pub solids: Vec<Material>,
    /// Floor colours with explicit albedo.
    pub floors: Vec<FloorColor>,
    /// The `[bake]` table's settings.
    pub settings: PaletteSettings,
    /// Optional `name` of each entry of `solids`, by index. May be shorter
    /// than `solids` (palettes built in code need not name anything); use
    /// [`Palette::solid_name`] to read it.
    pub solid_names: Vec<Option<String>>,
    /// The built-in entries whose colours the file does not list are part of
    /// this palette (after the file's own entries): true for the built-in
    /// palette and for a file without `builtin = false`. Built-in entries
    /// have no `line`.
    pub includes_builtin: bool,
}

/// A palette problem, located in its file.
#[derive(Debug, thiserror::Error)]
#[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct PaletteError {
    /// The palette file (or the built-in palette's name).
    pub path: PathBuf,
    /// The line of the problem, when it has one.
    pub line: Option<usize>,
    /// What is wrong, in words.
    pub message: String,
}

/// What a palette says one exact colour is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ColorClass {
    /// Index into [`Palette::solids`].
    Solid(usize),
    /// Index into [`Palette::floors`].
    Floor(usize),
}

/// The most solid entries a palette may have: level cells store a `u16` index.
pub const MAX_SOLIDS: usize = u16::MAX as usize + 1;

impl Palette {
    /// An empty palette (every colour is floor) from `origin`; handy for
    /// building palettes in code.
    pub fn empty(origin: PaletteOrigin) -> Palette {
        Palette {
            origin,
            solids: Vec::new(),
            floors: Vec::new(),
            settings: PaletteSettings::default(),
            solid_names: Vec::new(),
            includes_builtin: false,
        }
    }

    /// The built-in default palette: colours that are easy to type into any
    /// editor's colour picker and unlikely to be painted as floor.
    ///
    /// | colour    | kind    | numbers                      | name          |
    /// |-----------|---------|------------------------------|---------------|
    /// | `#000000` | wall    | reflectance 0.5              | stone         |
    /// | `#202020` | wall    | reflectance 0.05             | soot          |
    /// | `#f0f0f0` | wall    | reflectance 0.85             | plaster       |
    /// | `#800000` | wall    | reflectance [0.7, 0.1, 0.1]  | red wall      |
    /// | `#008000` | wall    | reflectance [0.1, 0.7, 0.1]  | green wall    |
    /// | `#000080` | wall    | reflectance [0.1, 0.1, 0.7]  | blue wall     |
    /// | `#ffffff` | emitter | emission 4                   | white light   |
    /// | `#ffe0a0` | emitter | emission [4, 3.4, 2.4]       | warm light    |
    /// | `#c0e0ff` | emitter | emission [2.8, 3.4, 4]       | cool light    |
    /// | `#ff8000` | emitter | emission [4, 1.8, 0.4]       | torch         |
    /// | `#ff0000` | emitter | emission [4, 0, 0]           | red light     |
    /// | `#00ff00` | emitter | emission [0, 4, 0]           | green light   |
    /// | `#0000ff` | emitter | emission [0, 0, 4]           | blue light    |
    /// | `#ffff00` | emitter | emission [4, 4, 0]           | yellow light  |
    /// | `#00ffff` | emitter | emission [0, 4, 4]           | cyan light    |
    /// | `#ff00ff` | emitter | emission [4, 0, 4]           | magenta light |
    ///
    /// Black is the conventional "paint the walls" colour, so it is an
    /// ordinary mid-grey stone rather than a perfect absorber; pure white is
    /// the natural light colour, so the brightest wall is the slightly grey
    /// plaster. Emission 4 makes a room lit by a few small lamps read around
    /// mid-grey at exposure 1 (a pixel beside a long emitter of emission 1
    /// reads only 0.5, docs/transport.md#floor-gather). Every other colour is floor, albedo = the
    /// pixel's colour.
    pub fn builtin() -> Palette {
        let wall = |color: [u8; 3], r: Rgb, name: &str| {
            let m = Material {
                color,
                kind: MaterialKind::Wall,
                reflectance: r,
                emission: [0.0; 3],
                group: None,
                line: None,
            };
            (m, Some(name.to_string()))
        };
        let light = |color: [u8; 3], e: Rgb, name: &str| {
            let m = Material {
                color,
                kind: MaterialKind::Emitter,
                reflectance: [0.0; 3],
                emission: e,
                group: None,
                line: None,
            };
            (m, Some(name.to_string()))
        };
        let entries = vec![
            wall([0x00, 0x00, 0x00], [0.5; 3], "stone"),
            wall([0x20, 0x20, 0x20], [0.05; 3], "soot"),
            wall([0xf0, 0xf0, 0xf0], [0.85; 3], "plaster"),
            wall([0x80, 0x00, 0x00], [0.7, 0.1, 0.1], "red wall"),
            wall([0x00, 0x80, 0x00], [0.1, 0.7, 0.1], "green wall"),
            wall([0x00, 0x00, 0x80], [0.1, 0.1, 0.7], "blue wall"),
            light([0xff, 0xff, 0xff], [4.0; 3], "white light"),
            light([0xff, 0xe0, 0xa0], [4.0, 3.4, 2.4], "warm light"),
            light([0xc0, 0xe0, 0xff], [2.8, 3.4, 4.0], "cool light"),
            light([0xff, 0x80, 0x00], [4.0, 1.8, 0.4], "torch"),
            light([0xff, 0x00, 0x00], [4.0, 0.0, 0.0], "red light"),
            light([0x00, 0xff, 0x00], [0.0, 4.0, 0.0], "green light"),
            light([0x00, 0x00, 0xff], [0.0, 0.0, 4.0], "blue light"),
            light([0xff, 0xff, 0x00], [4.0, 4.0, 0.0], "yellow light"),
            light([0x00, 0xff, 0xff], [0.0, 4.0, 4.0], "cyan light"),
            light([0xff, 0x00, 0xff], [4.0, 0.0, 4.0], "magenta light"),
        ];
        let (solids, solid_names) = entries.into_iter().unzip();
        Palette {
            origin: PaletteOrigin::BuiltIn,
            solids,
            floors: vec![],
            settings: PaletteSettings::default(),
            solid_names,
            includes_builtin: true,
        }
    }

    /// Parses palette text into the palette a level gets from it: the
    /// file's entries, then (unless the file says `builtin = false`) the
    /// built-in entries of every colour the file does not list. `path` is
    /// used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Palette, PaletteError> {
        Parser { text, path }.parse()
    }

    /// Reads and parses a palette file.
    pub fn load(path: &Path) -> Result<Palette, PaletteError> {
        let text = std::fs::read_to_string(path).map_err(|e| PaletteError {
            path: path.to_path_buf(),
            line: None,
            message: match e.kind() {
                std::io::ErrorKind::NotFound => "palette file not found".to_string(),
                std::io::ErrorKind::InvalidData => "palette is not UTF-8 text".to_string(),
                _ => format!("cannot read palette: {e}"),
            },
        })?;
        Palette::parse(&text, path)
    }

    /// The files that would supply a level's palette when no `--palette` is
    /// given, in lookup order: `NAME.palette.toml` beside `NAME.png`, then
    /// `palette.toml` in the level's folder. `watch` re-bakes when one changes.
    /// The levels of an LDtk project (`world.ldtk/Cellar`) share the
    /// project's: `world.palette.toml`, then `palette.toml`.
    pub fn candidate_paths(level: &Path) -> [PathBuf; 2] {
        let level = match crate::level::ldtk::project_level(level) {
            Some((project, _)) => project,
            None => level,
        };
        let dir = match level.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let stem = level
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        [
            dir.join(format!("{stem}.palette.toml")),
            dir.join("palette.toml"),
        ]
    }

    /// The palette for a level, first match wins: `explicit`; `NAME.palette.toml`
    /// beside `NAME.png`; `palette.toml` in the level's folder; the built-in one.
    ///
    /// A palette file that exists but is broken is an error, never silently
    /// replaced by the next candidate: the designer meant to use it.
    pub fn resolve_for_level(
        level: &Path,
        explicit: Option<&Path>,
    ) -> Result<Palette, PaletteError> {
        if let Some(p) = explicit {
            return Palette::load(p);
        }
        for candidate in Palette::candidate_paths(level) {
            if candidate.is_file() {
                return Palette::load(&candidate);
            }
        }
        Ok(Palette::builtin())
    }

    /// Where the entry of `class` comes from: `built-in`, or the palette
    /// file and the line of its colour (`levels/cave.palette.toml:12`).
    pub fn source(&self, class: ColorClass) -> String {
        let line = match class {
            ColorClass::Solid(i) => self.solids.get(i).and_then(|m| m.line),
            ColorClass::Floor(i) => self.floors.get(i).and_then(|f| f.line),
        };
        match (&self.origin, line) {
            (PaletteOrigin::File(p), Some(l)) => format!("{}:{l}", shown_path(p)),
            (PaletteOrigin::File(p), None) if !self.includes_builtin => shown_path(p),
            _ => "built-in".to_string(),
        }
    }

    /// The `name` of solid entry `i`, if it has one.
    pub fn solid_name(&self, i: usize) -> Option<&str> {
        self.solid_names.get(i).and_then(|n| n.as_deref())
    }

    /// What the palette says the exact colour `rgb` is; `None` means an
    /// unlisted colour (floor, albedo = the colour). Solids win over floors,
    /// though a parsed palette never lists a colour twice.
    ///
    /// A linear scan: palettes are short and the level loader caches the
    /// answer per distinct colour.
    pub fn classify(&self, rgb: [u8; 3]) -> Option<ColorClass> {
        if let Some(i) = self.solids.iter().position(|m| m.color == rgb) {
            return Some(ColorClass::Solid(i));
        }
        self.floors
            .iter()
            .position(|f| f.color == rgb)
            .map(ColorClass::Floor)
    }

    /// The palette colour nearest to `rgb` whose largest per-channel
    /// difference is at most `max_diff`, with that difference. Ties go to the
    /// smaller total difference, then to solids, then to palette order, so
    /// the answer never depends on hashing.
    pub fn nearest(&self, rgb: [u8; 3], max_diff: u8) -> Option<(ColorClass, u8)> {
        let solids = self
            .solids
            .iter()
            .enumerate()
            .map(|(i, m)| (ColorClass::Solid(i), m.color));
        let floors = self
            .floors
            .iter()
            .enumerate()
            .map(|(i, f)| (ColorClass::Floor(i), f.color));
        let mut best: Option<((u8, u16), ColorClass)> = None;
        for (class, c) in solids.chain(floors) {
            let d = color_distance(rgb, c);
            if d.0 > max_diff {
                continue;
            }
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, class));
            }
        }
        best.map(|((d, _), class)| (class, d))
    }

    /// A short description of a class for messages, e.g. `wall #000000 (stone)`.
    pub fn describe(&self, class: ColorClass) -> String {
        let (kind, color, name) = match class {
            ColorClass::Solid(i) => match self.solids.get(i) {
                Some(m) => (kind_word(m.kind), m.color, self.solid_name(i)),
                None => return format!("solid #{i}"),
            },
            ColorClass::Floor(i) => match self.floors.get(i) {
                Some(f) => ("floor", f.color, f.name.as_deref()),
                None => return format!("floor #{i}"),
            },
        };
        match name {
            Some(n) => format!("{kind} {} ({n})", hex_color(color)),
            None => format!("{kind} {}", hex_color(color)),
        }
    }
}

/// A palette path as messages show it: without the `./` that the lookup
/// beside a level in the current folder puts in front.
pub fn shown_path(p: &Path) -> String {
    p.strip_prefix(".").unwrap_or(p).display().to_string()
}

/// `wall` / `emitter`, as written in palette files.
pub fn kind_word(kind: MaterialKind) -> &'static str {
    match kind {
        MaterialKind::Wall => "wall",
        MaterialKind::Emitter => "emitter",
    }
}

/// (largest per-channel difference, sum of differences) between two colours.
fn color_distance(a: [u8; 3], b: [u8; 3]) -> (u8, u16) {
    let d = [0, 1, 2].map(|c| a[c].abs_diff(b[c]));
    (d[0].max(d[1]).max(d[2]), d.iter().map(|&x| x as u16).sum())
}

/// Largest emission a palette may give. Radiosity is emission amplified by
/// up to `1 / (1 - reflectance)`; this keeps it well inside the f32 range of
/// the lightmap even for reflectance within 1e-15 of 1.
pub const MAX_EMISSION: f64 = 1e15;

/// `#rrggbb` or `#rgb`, any case.
pub fn parse_hex(s: &str) -> Option<[u8; 3]> {
    let hex = s.strip_prefix('#')?;
    if !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    let digit = |i: usize| u8::from_str_radix(&hex[i..i + 1], 16).ok();
    match hex.len() {
        // "#abc" is "#aabbcc": each digit doubled, as in CSS.
        3 => Some([digit(0)? * 17, digit(1)? * 17, digit(2)? * 17]),
        6 => {
            let pair = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).ok();
            Some([pair(0)?, pair(2)?, pair(4)?])
        }
        _ => None,
    }
}
