//! A palette as text for people: [`Palette::to_toml`], a commented palette
//! file that parses back to the same palette, and [`Palette::table`], the
//! listing `flatbake palette` prints (each colour with its material and where
//! it comes from, the light groups and the `[bake]` settings).

use std::fmt::Write;

use super::*;

/// A per-channel triple as a palette file writes it: one number when the
/// channels agree, else `[r, g, b]`. `{:?}` is the shortest spelling that
/// reads back as the same `f64` and is always a valid TOML number.
fn toml_rgb(v: Rgb) -> String {
    if v[0] == v[1] && v[1] == v[2] {
        format!("{:?}", v[0])
    } else {
        format!("[{:?}, {:?}, {:?}]", v[0], v[1], v[2])
    }
}

/// The same for people: `0.5`, `[4, 1.8, 0.4]`.
fn shown_rgb(v: Rgb) -> String {
    if v[0] == v[1] && v[1] == v[2] {
        format!("{}", v[0])
    } else {
        format!("[{}, {}, {}]", v[0], v[1], v[2])
    }
}

/// A TOML basic string.
fn toml_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => {
                let _ = write!(out, "\\u{:04X}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

impl Palette {
    /// The palette as a commented TOML file that [`Palette::parse`] reads
    /// back as the same entries, in the same order, with the same `[bake]`
    /// settings. It spells every entry out and starts with `builtin = false`,
    /// so the file alone is the whole palette: deleting an entry removes
    /// that colour. `flatbake palette --toml` writes it to start from.
    pub fn to_toml(&self) -> String {
        let mut out = String::new();
        let from = match &self.origin {
            PaletteOrigin::BuiltIn => "flatbake's built-in palette".to_string(),
            PaletteOrigin::File(p) if self.includes_builtin => {
                format!("{} with the built-in palette", shown_path(p))
            }
            PaletteOrigin::File(p) => shown_path(p),
        };
        let _ = write!(
            out,
            "# A flatbake palette: which painted colour is which material.\n\
             # Written by `flatbake palette --toml` from {from}.\n\
             #\n\
             # Save it as NAME.palette.toml beside NAME.png (one level), or as\n\
             # palette.toml in a folder of levels. Colours are \"#rrggbb\", \"#rgb\" or\n\
             # [r, g, b] (the key may be spelled `color` or `colour`); numbers are\n\
             # linear, one number or [r, g, b]. A colour this file does not list is\n\
             # floor, lit with its own colour as albedo.\n\
             #\n\
             # `builtin = false`: this file is the whole palette. Without that line\n\
             # the file's entries are added to flatbake's built-in palette, and an\n\
             # entry replaces the built-in entry of the same colour.\n\
             builtin = false\n\n"
        );
        let s = &self.settings;
        out.push_str("# Bake settings; command-line flags override each one.\n[bake]\n");
        let setting = |out: &mut String, key: &str, value: Option<String>, help: &str| {
            let _ = match value {
                Some(v) => writeln!(out, "{key} = {v}"),
                None => writeln!(out, "# {key} = {help}"),
            };
        };
        setting(
            &mut out,
            "falloff",
            s.falloff.map(|f| format!("{f:?}")),
            "40.0    # half-energy distance in pixels; absent = no falloff",
        );
        setting(
            &mut out,
            "bounces",
            s.bounces.map(|b| b.to_string()),
            "2       # truncate the bounce series (0 = direct light only)",
        );
        setting(
            &mut out,
            "tolerance",
            s.tolerance.map(|t| t.to_string()),
            "8     # snap pixels within 8 steps per channel (anti-aliasing)",
        );
        setting(
            &mut out,
            "exposure",
            s.exposure.map(|e| format!("{e:?}")),
            "1.0    # lightmap exposure",
        );
        for (i, m) in self.solids.iter().enumerate() {
            out.push('\n');
            match m.kind {
                MaterialKind::Wall => {
                    let _ = writeln!(
                        out,
                        "[[wall]]\ncolor = \"{}\"\nreflectance = {}",
                        m.hex(),
                        toml_rgb(m.reflectance)
                    );
                }
                MaterialKind::Emitter => {
                    let _ = writeln!(
                        out,
                        "[[emitter]]\ncolor = \"{}\"\nemission = {}\nreflectance = {}",
                        m.hex(),
                        toml_rgb(m.emission),
                        toml_rgb(m.reflectance)
                    );
                    if let Some(g) = &m.group {
                        let _ = writeln!(out, "group = {}", toml_string(g));
                    }
                }
            }
            if let Some(n) = self.solid_name(i) {
                let _ = writeln!(out, "name = {}", toml_string(n));
            }
        }
        for f in &self.floors {
            let _ = writeln!(
                out,
                "\n[[floor]]\ncolor = \"{}\"\nalbedo = {}",
                hex_color(f.color),
                toml_rgb(f.albedo)
            );
            if let Some(n) = &f.name {
                let _ = writeln!(out, "name = {}", toml_string(n));
            }
        }
        out
    }

    /// The palette as a text table: where it comes from, each colour with
    /// its kind, numbers, name and source ([`Palette::source`]), the light
    /// groups and the `[bake]` settings.
    pub fn table(&self) -> String {
        let mut out = String::new();
        let _ = match &self.origin {
            PaletteOrigin::BuiltIn => writeln!(out, "built-in palette"),
            PaletteOrigin::File(p) if self.includes_builtin => writeln!(
                out,
                "{}, added to the built-in palette (a colour it lists replaces the built-in entry)",
                shown_path(p)
            ),
            PaletteOrigin::File(p) => writeln!(
                out,
                "{} (builtin = false: only the colours it lists)",
                shown_path(p)
            ),
        };
        let builtin = Palette::builtin();
        let mut rows: Vec<[String; 5]> = vec![[
            "colour".into(),
            "kind".into(),
            "numbers".into(),
            "name".into(),
            "source".into(),
        ]];
        let source = |class: ColorClass, color: [u8; 3]| {
            let mut s = self.source(class);
            let line = match class {
                ColorClass::Solid(i) => self.solids[i].line,
                ColorClass::Floor(i) => self.floors[i].line,
            };
            if let (true, Some(_), Some(b)) = (self.includes_builtin, line, builtin.classify(color))
            {
                let what = match b {
                    ColorClass::Solid(i) => builtin.solid_name(i).map(str::to_string),
                    ColorClass::Floor(i) => builtin.floors[i].name.clone(),
                };
                let what = what.unwrap_or_else(|| builtin.describe(b));
                s.push_str(&format!(" (replaces built-in {what})"));
            }
            s
        };
        for (i, m) in self.solids.iter().enumerate() {
            let (kind, numbers) = match m.kind {
                MaterialKind::Wall => ("wall", format!("reflectance {}", shown_rgb(m.reflectance))),
                MaterialKind::Emitter => (
                    "emitter",
                    format!(
                        "emission {}, reflectance {}",
                        shown_rgb(m.emission),
                        shown_rgb(m.reflectance)
                    ),
                ),
            };
            rows.push([
                m.hex(),
                kind.into(),
                numbers,
                self.solid_name(i).unwrap_or("-").into(),
                source(ColorClass::Solid(i), m.color),
            ]);
        }
        for (i, f) in self.floors.iter().enumerate() {
            rows.push([
                hex_color(f.color),
                "floor".into(),
                format!("albedo {}", shown_rgb(f.albedo)),
                f.name.clone().unwrap_or_else(|| "-".into()),
                source(ColorClass::Floor(i), f.color),
            ]);
        }
        let width = |c: usize| rows.iter().map(|r| r[c].chars().count()).max().unwrap_or(0);
        let widths = [width(0), width(1), width(2), width(3)];
        for r in &rows {
            let _ = writeln!(
                out,
                "  {:w0$}  {:w1$}  {:w2$}  {:w3$}  {}",
                r[0],
                r[1],
                r[2],
                r[3],
                r[4],
                w0 = widths[0],
                w1 = widths[1],
                w2 = widths[2],
                w3 = widths[3],
            );
        }
        let _ = writeln!(
            out,
            "  any other colour: floor, albedo = the colour (sRGB-decoded)"
        );

        // Light groups, as light layers name them.
        let _ = writeln!(out, "light groups (one layer each with --layers):");
        let mut groups: Vec<(&str, Vec<String>)> = Vec::new();
        let mut ungrouped = 0usize;
        for m in self
            .solids
            .iter()
            .filter(|m| m.kind == MaterialKind::Emitter)
        {
            match &m.group {
                Some(g) => match groups.iter_mut().find(|(n, _)| *n == g.as_str()) {
                    Some((_, colours)) => colours.push(m.hex()),
                    None => groups.push((g.as_str(), vec![m.hex()])),
                },
                None => ungrouped += 1,
            }
        }
        for (name, colours) in &groups {
            let _ = writeln!(out, "  {name}: {}", colours.join(", "));
        }
        let _ = match (ungrouped, groups.is_empty()) {
            (0, true) => writeln!(out, "  none (no emitters)"),
            (0, false) => Ok(()),
            (n, true) => writeln!(
                out,
                "  no `group` set: each of the {n} emitter colours is a group of its own"
            ),
            (n, false) => writeln!(
                out,
                "  and {n} emitter colours without `group`, each a group of its own"
            ),
        };

        // [bake]
        let s = &self.settings;
        let set: Vec<String> = [
            ("falloff", s.falloff.map(|f| f.to_string())),
            ("bounces", s.bounces.map(|b| b.to_string())),
            ("tolerance", s.tolerance.map(|t| t.to_string())),
            ("exposure", s.exposure.map(|e| e.to_string())),
        ]
        .into_iter()
        .filter_map(|(k, v)| v.map(|v| format!("{k} = {v}")))
        .collect();
        let unset: Vec<&str> = [
            ("falloff", s.falloff.is_none()),
            ("bounces", s.bounces.is_none()),
            ("tolerance", s.tolerance.is_none()),
            ("exposure", s.exposure.is_none()),
        ]
        .into_iter()
        .filter_map(|(k, unset)| unset.then_some(k))
        .collect();
        let _ = match &self.origin {
            PaletteOrigin::File(p) if !set.is_empty() => {
                writeln!(out, "[bake] from {}: {}", shown_path(p), set.join(", "))
            }
            _ => writeln!(out, "[bake]: nothing set"),
        };
        if !unset.is_empty() {
            let _ = writeln!(
                out,
                "  not set: {} (defaults; command-line flags override every one)",
                unset.join(", ")
            );
        }
        out
    }
}
