//! Parsing palette TOML: one pass over the document that checks every key,
//! type and range, and names the 1-based line of every problem.

use super::*;

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
            EntryKind::Wall => &["color (or colour)", "reflectance", "name"],
            EntryKind::Emitter => &[
                "color (or colour)",
                "emission",
                "reflectance",
                "group",
                "name",
            ],
            EntryKind::Floor => &["color (or colour)", "albedo", "name"],
        }
    }
}

const BAKE_KEYS: &[&str] = &["falloff", "bounces", "tolerance", "exposure"];

/// One pass over a parsed document; holds the text for line numbers.
pub(super) struct Parser<'a> {
    pub(super) text: &'a str,
    pub(super) path: &'a Path,
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

    pub(super) fn parse(&self) -> Fail<Palette> {
        let doc = DeTable::parse(self.text).map_err(|e| self.syntax_error(&e))?;
        let mut palette = Palette::empty(PaletteOrigin::File(self.path.to_path_buf()));
        // `builtin = false` starts from an empty palette; by default the
        // file's entries are added to the built-in ones.
        let mut builtin: Option<Range<usize>> = None;
        palette.includes_builtin = true;

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
                "builtin" => {
                    let DeValue::Boolean(b) = value.get_ref() else {
                        return Err(self.err(
                            &value.span(),
                            format!(
                                "builtin must be true or false, found {} (false: only this file's colours; \
                                 true, the default: this file's colours added to the built-in palette)",
                                self.src(&value.span())
                            ),
                        ));
                    };
                    palette.includes_builtin = *b;
                    builtin = Some(key.span());
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
                             (expected builtin, [bake], [[wall]], [[emitter]], [[floor]])"
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
        if palette.includes_builtin {
            self.add_builtin(&mut palette, builtin)?;
        }
        Ok(palette)
    }

    /// Adds the built-in entries whose colours the file does not list (a
    /// file's entry of any kind overrides the built-in entry of its colour).
    fn add_builtin(&self, palette: &mut Palette, key: Option<Range<usize>>) -> Fail<()> {
        let builtin = Palette::builtin();
        let listed: std::collections::HashSet<[u8; 3]> = palette
            .solids
            .iter()
            .map(|m| m.color)
            .chain(palette.floors.iter().map(|f| f.color))
            .collect();
        palette.solid_names.resize(palette.solids.len(), None);
        for (i, m) in builtin.solids.iter().enumerate() {
            if listed.contains(&m.color) {
                continue;
            }
            if palette.solids.len() >= MAX_SOLIDS {
                let message = format!(
                    "too many walls and emitters with the built-in ones (at most {MAX_SOLIDS}); \
                     `builtin = false` at the top of the file leaves the built-in palette out"
                );
                return Err(match key {
                    Some(span) => self.err(&span, message),
                    None => PaletteError {
                        path: self.path.to_path_buf(),
                        line: None,
                        message,
                    },
                });
            }
            palette.solids.push(m.clone());
            palette
                .solid_names
                .push(builtin.solid_name(i).map(str::to_string));
        }
        for f in &builtin.floors {
            if !listed.contains(&f.color) {
                palette.floors.push(f.clone());
            }
        }
        Ok(())
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
                    if n > crate::bake::MAX_BOUNCES {
                        return Err(self.err(
                            &span,
                            format!(
                                "bounces {} is more than {}; leave bounces out for the full solve",
                                self.src(&span),
                                crate::bake::MAX_BOUNCES
                            ),
                        ));
                    }
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
                "builtin" => {
                    return Err(self.err(
                        &k.span(),
                        "`builtin` belongs at the top of the file, before [bake] and every entry \
                         (a key below a [table] header is part of that table)",
                    ));
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
        let mut color: Option<([u8; 3], Range<usize>, &str)> = None;
        let mut out = ParsedEntry::default();
        for (k, v) in sorted(table) {
            match k.get_ref().as_ref() {
                // Both spellings: the messages say "colour", the TOML
                // convention says "color".
                spelling @ ("color" | "colour") => {
                    if let Some((_, first, first_spelling)) = &color {
                        return Err(self.err(
                            &k.span(),
                            format!(
                                "{header} entry has both `{first_spelling}` (line {}) and `{spelling}`; \
                                 give its colour once",
                                self.line_of(first)
                            ),
                        ));
                    }
                    let spelling = if spelling == "color" {
                        "color"
                    } else {
                        "colour"
                    };
                    color = Some((self.color(spelling, v)?, v.span(), spelling));
                }
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
        let Some((rgb, color_span, _)) = color else {
            return Err(self.err(
                &entry.span(),
                format!("{header} entry has no `color` (or `colour`)"),
            ));
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

    fn color(&self, key: &str, v: &Spanned<DeValue>) -> Fail<[u8; 3]> {
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
                    format!("{key} {} is not a colour (expected \"#rrggbb\", \"#rgb\" or [r, g, b]){hint}", self.src(&span)),
                )
            }),
            DeValue::Array(a) => {
                let bad = || {
                    self.err(
                        &span,
                        format!(
                            "{key} {} is not a colour (expected [r, g, b] with whole numbers 0..=255, or \"#rrggbb\")",
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
                format!("{key} must be \"#rrggbb\", \"#rgb\" or [r, g, b], found {}", other.type_str()),
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
