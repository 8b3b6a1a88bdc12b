//! Drawing the palette legend image: what each colour of a palette means.
//!
//! The legend is how a level designer learns the palette without reading
//! TOML — the README shows the built-in palette's legend, and
//! `flatbake palette --legend FILE.png` draws any palette's. One row per
//! entry: a colour swatch, the hex colour, the kind and its numbers, so the
//! image is enough to paint a level. Text uses the embedded DejaVu Sans Mono
//! so the output is the same on every machine.

use ab_glyph::{FontRef, PxScale};
use image::{ImageEncoder, Rgba, RgbaImage};
use imageproc::drawing::{draw_filled_rect_mut, draw_hollow_rect_mut, draw_text_mut, text_size};
use imageproc::rect::Rect;

use flatbake_core::level::material::{MaterialKind, Rgb, hex_color};
use flatbake_core::level::palette::{Palette, PaletteOrigin, kind_word};

static FONT_BYTES: &[u8] = include_bytes!("../assets/fonts/DejaVuSansMono.ttf");

/// Rows drawn before the legend says "and N more": a palette may list
/// thousands of colours, and the image must stay a sane size.
const MAX_ROWS: usize = 512;

const MARGIN: u32 = 16;
const ROW_HEIGHT: u32 = 30;
const SWATCH: u32 = 22;
const GAP: u32 = 18;
const TEXT_SCALE: f32 = 16.0;
const TITLE_SCALE: f32 = 20.0;

const BACKGROUND: Rgba<u8> = Rgba([250, 250, 248, 255]);
const INK: Rgba<u8> = Rgba([30, 30, 30, 255]);
const FAINT: Rgba<u8> = Rgba([110, 110, 110, 255]);
const RULE: Rgba<u8> = Rgba([215, 215, 210, 255]);
/// Swatch outline: mid grey, visible around black and white swatches alike.
const OUTLINE: Rgba<u8> = Rgba([128, 128, 128, 255]);

/// One legend row, as text columns plus its swatch colour.
struct Row {
    color: [u8; 3],
    cells: [String; 4],
}

/// Draws the legend of `palette`: a title naming where it came from, one row
/// per entry (swatch, `#rrggbb`, kind, numbers, name) and a footer for the
/// colours the palette does not list.
pub fn draw_legend(palette: &Palette) -> RgbaImage {
    // The font is compiled in; failing to parse it would be a build defect,
    // and a legend without text is still better than a crash.
    let font = FontRef::try_from_slice(FONT_BYTES).ok();

    let title = match &palette.origin {
        PaletteOrigin::BuiltIn => "flatbake palette — built-in default".to_string(),
        PaletteOrigin::File(p) => format!("flatbake palette — {}", p.display()),
    };
    let mut subtitle = Vec::new();
    let s = &palette.settings;
    if let Some(f) = s.falloff {
        subtitle.push(format!("falloff {f} px"));
    }
    if let Some(b) = s.bounces {
        subtitle.push(format!("bounces {b}"));
    }
    if let Some(t) = s.tolerance {
        subtitle.push(format!("tolerance {t}"));
    }
    if let Some(e) = s.exposure {
        subtitle.push(format!("exposure {e}"));
    }
    let subtitle = (!subtitle.is_empty()).then(|| format!("[bake] {}", subtitle.join(" · ")));

    let mut rows: Vec<Row> = Vec::new();
    for (i, m) in palette.solids.iter().enumerate() {
        let mut numbers = match m.kind {
            MaterialKind::Wall => format!("reflectance {}", rgb_text(m.reflectance)),
            MaterialKind::Emitter => format!("emission {}", rgb_text(m.emission)),
        };
        if m.kind == MaterialKind::Emitter && m.reflects() {
            numbers.push_str(&format!(" · reflectance {}", rgb_text(m.reflectance)));
        }
        let mut label = palette.solid_name(i).unwrap_or_default().to_string();
        if let Some(g) = &m.group {
            if !label.is_empty() {
                label.push(' ');
            }
            label.push_str(&format!("(group {g})"));
        }
        rows.push(Row {
            color: m.color,
            cells: [hex_color(m.color), kind_word(m.kind).into(), numbers, label],
        });
    }
    for f in &palette.floors {
        let numbers = format!("albedo {}", rgb_text(f.albedo));
        let label = f.name.clone().unwrap_or_default();
        rows.push(Row {
            color: f.color,
            cells: [hex_color(f.color), "floor".into(), numbers, label],
        });
    }
    let hidden = rows.len().saturating_sub(MAX_ROWS);
    rows.truncate(MAX_ROWS);

    let mut footer = vec![
        "any other colour: floor, albedo = the colour (sRGB-decoded)".to_string(),
        "fully transparent (alpha 0): void — light passes, nothing is lit".to_string(),
    ];
    if hidden > 0 {
        footer.insert(0, format!("… and {hidden} more entries not shown"));
    }
    if rows.is_empty() {
        footer.insert(0, "(no entries)".to_string());
    }

    let measure = |scale: f32, text: &str| match &font {
        Some(f) => text_size(PxScale::from(scale), f, text).0,
        // Without a font, fall back to a monospace guess so layout still works.
        None => (text.chars().count() as f32 * scale * 0.6) as u32,
    };
    let mut col_width = [0u32; 4];
    for row in &rows {
        for (w, text) in col_width.iter_mut().zip(&row.cells) {
            *w = (*w).max(measure(TEXT_SCALE, text));
        }
    }
    let table_width = SWATCH + GAP + col_width.iter().map(|w| w + GAP).sum::<u32>();
    let text_width = [measure(TITLE_SCALE, &title)]
        .into_iter()
        .chain(subtitle.iter().map(|t| measure(TEXT_SCALE, t)))
        .chain(footer.iter().map(|t| measure(TEXT_SCALE, t)))
        .max()
        .unwrap_or(0);
    let width = 2 * MARGIN + table_width.max(text_width);

    let header_height = 32 + if subtitle.is_some() { 24 } else { 0 };
    let footer_height = 12 + 24 * footer.len() as u32;
    let height = 2 * MARGIN + header_height + ROW_HEIGHT * rows.len() as u32 + footer_height;

    let mut img = RgbaImage::from_pixel(width, height, BACKGROUND);
    let text = |img: &mut RgbaImage, color, x: u32, y: u32, scale: f32, s: &str| {
        if let Some(f) = &font {
            draw_text_mut(img, color, x as i32, y as i32, PxScale::from(scale), f, s);
        }
    };

    let mut y = MARGIN;
    text(&mut img, INK, MARGIN, y, TITLE_SCALE, &title);
    y += 32;
    if let Some(sub) = &subtitle {
        text(&mut img, FAINT, MARGIN, y, TEXT_SCALE, sub);
        y += 24;
    }
    for row in &rows {
        draw_filled_rect_mut(
            &mut img,
            Rect::at(MARGIN as i32, (y + ROW_HEIGHT - 1) as i32).of_size(width - 2 * MARGIN, 1),
            RULE,
        );
        let sy = y + (ROW_HEIGHT - SWATCH) / 2;
        let [r, g, b] = row.color;
        draw_filled_rect_mut(
            &mut img,
            Rect::at(MARGIN as i32, sy as i32).of_size(SWATCH, SWATCH),
            Rgba([r, g, b, 255]),
        );
        draw_hollow_rect_mut(
            &mut img,
            Rect::at(MARGIN as i32, sy as i32).of_size(SWATCH, SWATCH),
            OUTLINE,
        );
        let ty = y + (ROW_HEIGHT - TEXT_SCALE as u32) / 2 - 1;
        let mut x = MARGIN + SWATCH + GAP;
        for (i, (cell, w)) in row.cells.iter().zip(col_width).enumerate() {
            // The name column is commentary; the numbers are what matter.
            let color = if i == 3 { FAINT } else { INK };
            text(&mut img, color, x, ty, TEXT_SCALE, cell);
            x += w + GAP;
        }
        y += ROW_HEIGHT;
    }
    y += 12;
    for line in &footer {
        text(&mut img, FAINT, MARGIN, y, TEXT_SCALE, line);
        y += 24;
    }
    img
}

/// The legend of `palette` encoded as a PNG file's bytes.
pub fn legend_png(palette: &Palette) -> Result<Vec<u8>, image::ImageError> {
    let img = draw_legend(palette);
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out).write_image(
        img.as_raw(),
        img.width(),
        img.height(),
        image::ExtendedColorType::Rgba8,
    )?;
    Ok(out)
}

/// `0.5` when all channels agree, `[0.7, 0.1, 0.1]` otherwise.
fn rgb_text(v: Rgb) -> String {
    if v[0] == v[1] && v[1] == v[2] {
        format!("{}", v[0])
    } else {
        format!("[{}, {}, {}]", v[0], v[1], v[2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;
    use std::path::Path;

    fn parse(text: &str) -> Palette {
        Palette::parse(text, Path::new("levels/x.palette.toml")).expect("palette parses")
    }

    const GOOD: &str = r##"
builtin = false

[[wall]]
color = "#5a5a5a"
reflectance = 0.6
name = "stone"

[[emitter]]
color = "#FFFADC"
emission = [2.0, 2, 2.5]
reflectance = 0.5
group = "hall"

[[emitter]]
color = [255, 0, 0]
emission = 1

[[floor]]
color = "#b4aa96"
albedo = [0.5, 0.5, 0.5]
name = "sand"
"##;

    #[test]
    fn legend_grows_with_entries_and_is_not_blank() {
        let small = parse("builtin = false\n[[wall]]\ncolor = \"#000\"\nreflectance = 0.5\n");
        let big = parse(GOOD);
        let a = draw_legend(&small);
        let b = draw_legend(&big);
        assert!(b.height() > a.height(), "{} vs {}", b.height(), a.height());
        let builtin = draw_legend(&Palette::builtin());
        assert!(builtin.height() > b.height());
        // A file without `builtin = false` adds to the built-in palette.
        let extended = draw_legend(&parse("[[wall]]\ncolor = \"#123456\"\nreflectance = 0.5\n"));
        assert!(extended.height() > builtin.height());
        for img in [&a, &b, &builtin] {
            let distinct: HashSet<[u8; 4]> = img.pixels().map(|p| p.0).collect();
            // Background, text anti-aliasing shades and swatches: far from blank.
            assert!(distinct.len() > 10, "only {} colours", distinct.len());
        }
        // The swatch colours themselves appear in the image.
        let has = |img: &image::RgbaImage, c: [u8; 3]| {
            img.pixels().any(|p| p.0 == [c[0], c[1], c[2], 255])
        };
        assert!(has(&b, [0xff, 0xfa, 0xdc]) && has(&b, [0xb4, 0xaa, 0x96]) && has(&b, [255, 0, 0]));
        for m in &Palette::builtin().solids {
            assert!(has(&builtin, m.color), "swatch {} missing", m.hex());
        }
        let png = legend_png(&big).unwrap();
        let back = image::load_from_memory(&png).unwrap().to_rgba8();
        assert_eq!(back.dimensions(), b.dimensions());
        assert!(back.pixels().zip(b.pixels()).all(|(x, y)| x == y));
    }

    #[test]
    fn legend_of_empty_palette_still_draws() {
        let img = draw_legend(&parse("builtin = false\n"));
        assert!(img.width() > 50 && img.height() > 20);
    }
}
