//! Palettes: which painted colour is which material (SPEC section 2).
//!
//! A palette is TOML text with an optional `[bake]` table and `[[wall]]`,
//! `[[emitter]]` and `[[floor]]` entries. [`Palette::parse`] checks it
//! completely — unknown keys, wrong types, out-of-range numbers, duplicate
//! colours — and every error names the file and the 1-based line, because a
//! level designer fixes palettes by hand. [`Palette::resolve_for_level`]
//! applies the lookup order of SPEC 2 and [`Palette::builtin`] is the default
//! palette. The level loader asks a palette what a colour is through
//! [`Palette::classify`] and [`Palette::nearest`]; nothing after loading looks
//! at palette text again.

use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use toml::Spanned;
use toml::de::{DeArray, DeTable, DeValue};

use crate::level::material::{Material, MaterialKind, Rgb, hex_color};

/// Where a palette came from.
#[derive(Clone, Debug, PartialEq)]
pub enum PaletteOrigin {
    BuiltIn,
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
    pub color: [u8; 3],
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

/// A resolved palette.
#[derive(Clone, Debug, PartialEq)]
pub struct Palette {
    pub origin: PaletteOrigin,
    /// Walls and emitters, in palette order.
    pub solids: Vec<Material>,
    /// Floor colours with explicit albedo.
    pub floors: Vec<FloorColor>,
    pub settings: PaletteSettings,
    /// Optional `name` of each entry of `solids`, by index. May be shorter
    /// than `solids` (palettes built in code need not name anything); use
    /// [`Palette::solid_name`] to read it.
    pub solid_names: Vec<Option<String>>,
}

/// A palette problem, located in its file.
#[derive(Debug, thiserror::Error)]
#[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct PaletteError {
    pub path: PathBuf,
    pub line: Option<usize>,
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
    /// reads only 0.5, SPEC 4). Every other colour is floor, albedo = the
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
        }
    }

    /// Parses palette text; `path` is used in messages.
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
    pub fn candidate_paths(level: &Path) -> [PathBuf; 2] {
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

/// Which array of tables an entry came from.
#[derive(Clone, Copy, Debug, PartialEq)]
enum EntryKind {
    Wall,
    Emitter,
    Floor,
}

impl EntryKind {
    fn header(self) -> &'static str {
        match self {
            EntryKind::Wall => "[[wall]]",
            EntryKind::Emitter => "[[emitter]]",
            EntryKind::Floor => "[[floor]]",
        }
    }
    fn keys(self) -> &'static [&'static str] {
        match self {
            EntryKind::Wall => &["color", "reflectance", "name"],
            EntryKind::Emitter => &["color", "emission", "reflectance", "group", "name"],
            EntryKind::Floor => &["color", "albedo", "name"],
        }
    }
}

const BAKE_KEYS: &[&str] = &["falloff", "bounces", "tolerance", "exposure"];

/// One pass over a parsed document; holds the text for line numbers.
struct Parser<'a> {
    text: &'a str,
    path: &'a Path,
}

type Fail<T> = Result<T, PaletteError>;

impl<'a> Parser<'a> {
    fn line_of(&self, span: &Range<usize>) -> usize {
        let end = span.start.min(self.text.len());
        // Spans are byte offsets; counting bytes is safe even mid-character.
        1 + self.text.as_bytes()[..end]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    }

    fn err(&self, span: &Range<usize>, message: impl Into<String>) -> PaletteError {
        PaletteError {
            path: self.path.to_path_buf(),
            line: Some(self.line_of(span)),
            message: message.into(),
        }
    }

    /// The source spelling of a value, for messages ("1.5", not "1.5000").
    fn src(&self, span: &Range<usize>) -> &'a str {
        self.text.get(span.clone()).map(str::trim).unwrap_or("?")
    }

    fn parse(&self) -> Fail<Palette> {
        let doc = DeTable::parse(self.text).map_err(|e| self.syntax_error(&e))?;
        let mut palette = Palette::empty(PaletteOrigin::File(self.path.to_path_buf()));

        // Entries of all three kinds in file order, so the first problem
        // reported is the first one in the file and duplicates name the
        // earlier entry.
        let mut entries: Vec<(EntryKind, &Spanned<DeValue>)> = Vec::new();
        let mut top: Vec<(&Spanned<_>, &Spanned<DeValue>)> = doc.get_ref().iter().collect();
        top.sort_by_key(|(k, _)| k.span().start);
        for (key, value) in top {
            let kind = match key.get_ref().as_ref() {
                "bake" => {
                    palette.settings = self.bake(key, value)?;
                    continue;
                }
                "wall" => EntryKind::Wall,
                "emitter" => EntryKind::Emitter,
                "floor" => EntryKind::Floor,
                other => {
                    return Err(self.err(
                        &key.span(),
                        format!(
                            "unknown key `{other}` at the top level \
                             (expected [bake], [[wall]], [[emitter]], [[floor]])"
                        ),
                    ));
                }
            };
            let array = self.array_of_tables(kind, key, value)?;
            entries.extend(array.iter().map(|e| (kind, e)));
        }
        entries.sort_by_key(|(_, e)| e.span().start);

        // colour -> (line, spelling, header) of the entry that first used it.
        let mut seen: HashMap<[u8; 3], (usize, String, &'static str)> = HashMap::new();
        for (kind, entry) in entries {
            let parsed = self.entry(kind, entry)?;
            let line = self.line_of(&parsed.color_span);
            if let Some((first_line, first_spelling, first_header)) = seen.get(&parsed.color) {
                return Err(self.err(
                    &parsed.color_span,
                    format!(
                        "duplicate colour: {} in {} here (line {line}) is the same colour as \
                         {first_spelling} in {first_header} on line {first_line}",
                        self.src(&parsed.color_span),
                        kind.header(),
                    ),
                ));
            }
            seen.insert(
                parsed.color,
                (
                    line,
                    self.src(&parsed.color_span).to_string(),
                    kind.header(),
                ),
            );
            match kind {
                EntryKind::Wall | EntryKind::Emitter => {
                    if palette.solids.len() >= MAX_SOLIDS {
                        return Err(self.err(
                            &parsed.color_span,
                            format!("too many walls and emitters (at most {MAX_SOLIDS})"),
                        ));
                    }
                    let wall = kind == EntryKind::Wall;
                    palette.solids.push(Material {
                        color: parsed.color,
                        kind: if wall {
                            MaterialKind::Wall
                        } else {
                            MaterialKind::Emitter
                        },
                        reflectance: parsed.reflectance.unwrap_or([0.0; 3]),
                        emission: parsed.emission.unwrap_or([0.0; 3]),
                        group: parsed.group,
                        line: Some(line),
                    });
                    palette.solid_names.push(parsed.name);
                }
                EntryKind::Floor => palette.floors.push(FloorColor {
                    color: parsed.color,
                    albedo: parsed.albedo.unwrap_or([0.0; 3]),
                    line: Some(line),
                    name: parsed.name,
                }),
            }
        }
        Ok(palette)
    }

    fn syntax_error(&self, e: &toml::de::Error) -> PaletteError {
        let message = e.message().trim_end();
        match e.span() {
            Some(span) => {
                // Bytes, not str slices: a span inside a multi-byte
                // character must not turn an error message into a panic.
                let bytes = self.text.as_bytes();
                let start = span.start.min(bytes.len());
                let line_start = bytes[..start]
                    .iter()
                    .rposition(|&b| b == b'\n')
                    .map_or(0, |i| i + 1);
                let column = String::from_utf8_lossy(&bytes[line_start..start])
                    .chars()
                    .count()
                    + 1;
                self.err(&span, format!("invalid TOML (column {column}): {message}"))
            }
            None => PaletteError {
                path: self.path.to_path_buf(),
                line: None,
                message: format!("invalid TOML: {message}"),
            },
        }
    }

    fn bake(
        &self,
        key: &Spanned<std::borrow::Cow<str>>,
        value: &Spanned<DeValue>,
    ) -> Fail<PaletteSettings> {
        let DeValue::Table(table) = value.get_ref() else {
            return Err(self.err(
                &key.span(),
                format!(
                    "`bake` must be a table ([bake]), found {}",
                    value.get_ref().type_str()
                ),
            ));
        };
        let mut s = PaletteSettings::default();
        for (k, v) in sorted(table) {
            let span = v.span();
            match k.get_ref().as_ref() {
                "falloff" => {
                    let f = self.number("falloff", v)?;
                    if !f.is_finite() || f <= 0.0 {
                        return Err(self.err(
                            &span,
                            format!(
                                "falloff {} must be a finite number of pixels > 0",
                                self.src(&span)
                            ),
                        ));
                    }
                    s.falloff = Some(f);
                }
                "exposure" => {
                    let f = self.number("exposure", v)?;
                    if !f.is_finite() || f <= 0.0 {
                        return Err(self.err(
                            &span,
                            format!("exposure {} must be a finite number > 0", self.src(&span)),
                        ));
                    }
                    s.exposure = Some(f);
                }
                "bounces" => {
                    let n = self.integer("bounces", v)?;
                    let n = u32::try_from(n).map_err(|_| {
                        self.err(
                            &span,
                            format!("bounces {} must be a whole number >= 0", self.src(&span)),
                        )
                    })?;
                    s.bounces = Some(n);
                }
                "tolerance" => {
                    let n = self.integer("tolerance", v)?;
                    let n = u8::try_from(n).map_err(|_| {
                        self.err(
                            &span,
                            format!(
                                "tolerance {} is outside 0..=255 (largest per-channel difference in 8-bit steps)",
                                self.src(&span)
                            ),
                        )
                    })?;
                    s.tolerance = Some(n);
                }
                other => return Err(self.unknown_key(k, other, "[bake]", BAKE_KEYS)),
            }
        }
        Ok(s)
    }

    fn unknown_key(
        &self,
        key: &Spanned<std::borrow::Cow<str>>,
        name: &str,
        header: &str,
        expected: &[&str],
    ) -> PaletteError {
        self.err(
            &key.span(),
            format!(
                "unknown key `{name}` in {header} (expected {})",
                expected.join(", ")
            ),
        )
    }

    fn array_of_tables<'d>(
        &self,
        kind: EntryKind,
        key: &Spanned<std::borrow::Cow<str>>,
        value: &'d Spanned<DeValue<'d>>,
    ) -> Fail<&'d DeArray<'d>> {
        let name = kind.header().trim_matches(|c| c == '[' || c == ']');
        match value.get_ref() {
            DeValue::Array(a) => Ok(a),
            DeValue::Table(_) => Err(self.err(
                &key.span(),
                format!(
                    "`{name}` must be an array of tables: write {} (double brackets), not [{name}]",
                    kind.header()
                ),
            )),
            other => Err(self.err(
                &key.span(),
                format!(
                    "`{name}` must be an array of tables ({}), found {}",
                    kind.header(),
                    other.type_str()
                ),
            )),
        }
    }

    fn entry(&self, kind: EntryKind, entry: &Spanned<DeValue>) -> Fail<ParsedEntry> {
        let header = kind.header();
        let DeValue::Table(table) = entry.get_ref() else {
            return Err(self.err(
                &entry.span(),
                format!(
                    "each {header} entry must be a table, found {}",
                    entry.get_ref().type_str()
                ),
            ));
        };
        let mut color: Option<([u8; 3], Range<usize>)> = None;
        let mut out = ParsedEntry::default();
        for (k, v) in sorted(table) {
            match k.get_ref().as_ref() {
                "color" => color = Some((self.color(v)?, v.span())),
                "reflectance" if kind != EntryKind::Floor => {
                    out.reflectance = Some(self.rgb("reflectance", v, Bounds::Unit)?)
                }
                "emission" if kind == EntryKind::Emitter => {
                    out.emission = Some(self.rgb("emission", v, Bounds::NonNegative)?)
                }
                "albedo" if kind == EntryKind::Floor => {
                    out.albedo = Some(self.rgb("albedo", v, Bounds::Unit)?)
                }
                "group" if kind == EntryKind::Emitter => {
                    let g = self.string("group", v)?;
                    if g.trim().is_empty() {
                        return Err(self.err(
                            &v.span(),
                            "group name is empty (leave `group` out for no group)",
                        ));
                    }
                    out.group = Some(g);
                }
                "name" => out.name = Some(self.string("name", v)?),
                other => return Err(self.unknown_key(k, other, header, kind.keys())),
            }
        }
        let Some((rgb, color_span)) = color else {
            return Err(self.err(&entry.span(), format!("{header} entry has no `color`")));
        };
        let missing = match kind {
            EntryKind::Wall if out.reflectance.is_none() => Some("reflectance"),
            EntryKind::Emitter if out.emission.is_none() => Some("emission"),
            EntryKind::Floor if out.albedo.is_none() => Some("albedo"),
            _ => None,
        };
        if let Some(key) = missing {
            return Err(self.err(
                &color_span,
                format!("{header} {} has no `{key}`", self.src(&color_span)),
            ));
        }
        out.color = rgb;
        out.color_span = color_span;
        Ok(out)
    }

    fn color(&self, v: &Spanned<DeValue>) -> Fail<[u8; 3]> {
        let span = v.span();
        match v.get_ref() {
            DeValue::String(s) => parse_hex(s).ok_or_else(|| {
                let hint = if !s.starts_with('#') && parse_hex(&format!("#{s}")).is_some() {
                    format!(" — did you mean \"#{s}\"?")
                } else {
                    String::new()
                };
                self.err(
                    &span,
                    format!("color {} is not a colour (expected \"#rrggbb\", \"#rgb\" or [r, g, b]){hint}", self.src(&span)),
                )
            }),
            DeValue::Array(a) => {
                let bad = || {
                    self.err(
                        &span,
                        format!(
                            "color {} is not a colour (expected [r, g, b] with whole numbers 0..=255, or \"#rrggbb\")",
                            self.src(&span)
                        ),
                    )
                };
                if a.len() != 3 {
                    return Err(bad());
                }
                let mut rgb = [0u8; 3];
                for (c, item) in rgb.iter_mut().zip(a.iter()) {
                    let DeValue::Integer(i) = item.get_ref() else { return Err(bad()) };
                    *c = i64::from_str_radix(i.as_str(), i.radix())
                        .ok()
                        .and_then(|n| u8::try_from(n).ok())
                        .ok_or_else(bad)?;
                }
                Ok(rgb)
            }
            other => Err(self.err(
                &span,
                format!("color must be \"#rrggbb\", \"#rgb\" or [r, g, b], found {}", other.type_str()),
            )),
        }
    }

    /// A TOML integer or float as f64 (TOML spells inf and nan too; callers
    /// check finiteness themselves so the message can name the key).
    fn number(&self, key: &str, v: &Spanned<DeValue>) -> Fail<f64> {
        let span = v.span();
        let parsed = match v.get_ref() {
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
                .ok()
                .map(|n| n as f64),
            DeValue::Float(f) => f.as_str().replace('_', "").parse::<f64>().ok(),
            other => {
                return Err(self.err(
                    &span,
                    format!("{key} must be a number, found {}", other.type_str()),
                ));
            }
        };
        parsed.ok_or_else(|| self.err(&span, format!("{key} {} is not a number", self.src(&span))))
    }

    fn integer(&self, key: &str, v: &Spanned<DeValue>) -> Fail<i64> {
        let span = v.span();
        match v.get_ref() {
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
                .map_err(|_| self.err(&span, format!("{key} {} is too large", self.src(&span)))),
            DeValue::Float(_) => Err(self.err(
                &span,
                format!("{key} {} must be a whole number", self.src(&span)),
            )),
            other => Err(self.err(
                &span,
                format!("{key} must be a whole number, found {}", other.type_str()),
            )),
        }
    }

    fn string(&self, key: &str, v: &Spanned<DeValue>) -> Fail<String> {
        match v.get_ref() {
            DeValue::String(s) => Ok(s.to_string()),
            other => Err(self.err(
                &v.span(),
                format!("{key} must be a string, found {}", other.type_str()),
            )),
        }
    }

    /// A number or an `[r, g, b]` array, each channel checked against `range`.
    fn rgb(&self, key: &str, v: &Spanned<DeValue>, bounds: Bounds) -> Fail<Rgb> {
        let channels: Vec<&Spanned<DeValue>> = match v.get_ref() {
            DeValue::Integer(_) | DeValue::Float(_) => vec![v; 3],
            DeValue::Array(a) if a.len() == 3 => a.iter().collect(),
            DeValue::Array(_) => {
                return Err(self.err(
                    &v.span(),
                    format!(
                        "{key} {} must be a number or [r, g, b] (three numbers)",
                        self.src(&v.span())
                    ),
                ));
            }
            other => {
                return Err(self.err(
                    &v.span(),
                    format!(
                        "{key} must be a number or [r, g, b], found {}",
                        other.type_str()
                    ),
                ));
            }
        };
        let mut out = [0.0; 3];
        for (o, c) in out.iter_mut().zip(channels) {
            let span = c.span();
            let x = match c.get_ref() {
                DeValue::Integer(_) | DeValue::Float(_) => self.number(key, c)?,
                other => {
                    return Err(self.err(
                        &span,
                        format!(
                            "{key} must be a number or [r, g, b] of numbers, found {} in the array",
                            other.type_str()
                        ),
                    ));
                }
            };
            let s = self.src(&span);
            match bounds {
                Bounds::Unit if !(0.0..=1.0).contains(&x) => {
                    return Err(self.err(&span, format!("{key} {s} is outside 0..=1")));
                }
                Bounds::NonNegative if !x.is_finite() => {
                    return Err(self.err(&span, format!("{key} {s} is not a finite number")));
                }
                Bounds::NonNegative if x < 0.0 => {
                    return Err(self.err(
                        &span,
                        format!("{key} {s} is negative (light cannot be removed)"),
                    ));
                }
                Bounds::NonNegative if x > MAX_EMISSION => {
                    return Err(self.err(
                        &span,
                        format!(
                            "{key} {s} is too large: at most {MAX_EMISSION:e} (a lightmap saturates at 1; light beyond the 32-bit float range of the outputs cannot be stored)"
                        ),
                    ));
                }
                _ => {}
            }
            *o = x;
        }
        Ok(out)
    }
}

/// Largest emission a palette may give. Radiosity is emission amplified by
/// up to `1 / (1 - reflectance)`; this keeps it well inside the f32 range of
/// the lightmap even for reflectance within 1e-15 of 1.
pub const MAX_EMISSION: f64 = 1e15;

/// The allowed values of a per-channel number.
#[derive(Clone, Copy)]
enum Bounds {
    /// `0..=1` (reflectance, albedo); NaN fails the check too.
    Unit,
    /// Finite, `>= 0` and at most [`MAX_EMISSION`] (emission).
    NonNegative,
}

#[derive(Default)]
struct ParsedEntry {
    color: [u8; 3],
    color_span: std::ops::Range<usize>,
    reflectance: Option<Rgb>,
    emission: Option<Rgb>,
    albedo: Option<Rgb>,
    group: Option<String>,
    name: Option<String>,
}

/// A table's entries in file order (the map itself is sorted by key).
fn sorted<'t, 'i>(
    table: &'t DeTable<'i>,
) -> Vec<(
    &'t Spanned<std::borrow::Cow<'i, str>>,
    &'t Spanned<DeValue<'i>>,
)> {
    let mut v: Vec<_> = table.iter().collect();
    v.sort_by_key(|(k, _)| k.span().start);
    v
}

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
