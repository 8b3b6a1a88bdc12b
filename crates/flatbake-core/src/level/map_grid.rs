//! What map editors' levels (Tiled maps, LDtk projects) have in common on
//! their way to a [`Level`]: a grid of map cells that are each a material or
//! floor, shapes (lights, blocks) painted over it, and the materials' numbers
//! with their defaults and ranges. The editors' loaders only say which cell
//! or shape is what.

use std::collections::HashMap;

use crate::level::material::{Material, MaterialKind, Rgb, linear_to_srgb, srgb_to_linear};
use crate::level::palette::{MAX_EMISSION, PaletteSettings};
use crate::level::{Cell, Level};

/// What one map cell or shape is.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Kind {
    /// Floor of this linear albedo.
    Floor(Rgb),
    /// A wall or an emitter.
    Solid(Material),
}

/// A material as a map's custom properties or fields spell it: the kind
/// (`wall`, `emitter` or `floor`) and the optional numbers, linear.
#[derive(Clone, Debug, Default)]
pub(crate) struct Spec {
    /// `wall`, `emitter` or `floor`.
    pub kind: String,
    /// Walls' and emitters' reflectance (defaults 0.5 and 0).
    pub reflectance: Option<Rgb>,
    /// Emitters' emission (default 4).
    pub emission: Option<Rgb>,
    /// Floors' albedo (default 0.5).
    pub albedo: Option<Rgb>,
    /// Light group, for layers.
    pub group: Option<String>,
}

/// The map properties (Tiled) and level fields (LDtk) that carry a
/// palette's `[bake]` settings.
pub(crate) const BAKE_KEYS: [&str; 3] =
    ["flatbake_falloff", "flatbake_bounces", "flatbake_exposure"];

/// Sets the `[bake]` setting that map property or level field `key` names
/// to `value`, checked as the palette file checks it.
pub(crate) fn bake_setting(s: &mut PaletteSettings, key: &str, value: f64) -> Result<(), String> {
    match key {
        "flatbake_falloff" => {
            if !value.is_finite() || value <= 0.0 {
                return Err(format!(
                    "falloff {value} must be a finite number of pixels > 0"
                ));
            }
            s.falloff = Some(value);
        }
        "flatbake_exposure" => {
            if !value.is_finite() || value <= 0.0 {
                return Err(format!("exposure {value} must be a finite number > 0"));
            }
            s.exposure = Some(value);
        }
        "flatbake_bounces" => {
            let max = crate::bake::MAX_BOUNCES;
            if value.fract() != 0.0 || !(0.0..=max as f64).contains(&value) {
                return Err(format!(
                    "bounces {value} must be a whole number from 0 to {max} (leave it out for the full solve)"
                ));
            }
            s.bounces = Some(value as u32);
        }
        _ => return Err(format!("{key} is not a bake setting")),
    }
    Ok(())
}

/// Parses one number or three (`"0.7"`, `"0.7 0.1 0.1"`, `"[0.7, 0.1, 0.1]"`,
/// `"0.7,0.1,0.1"`), or an sRGB colour `#rrggbb` (made linear).
pub(crate) fn parse_rgb(s: &str) -> Result<Rgb, String> {
    let s = s.trim();
    if let Some(hex) = s.strip_prefix('#') {
        return hex_colour(hex).ok_or_else(|| format!("{s:?} is not a colour #rrggbb"));
    }
    let list: Vec<f64> = s
        .trim_start_matches('[')
        .trim_end_matches(']')
        .split([',', ' '])
        .filter(|p| !p.is_empty())
        .map(|p| {
            p.parse::<f64>()
                .map_err(|_| format!("{p:?} is not a number"))
        })
        .collect::<Result<_, _>>()?;
    match list[..] {
        [a] => Ok([a; 3]),
        [a, b, c] => Ok([a, b, c]),
        _ => Err(format!("{} numbers given, expected 1 or 3", list.len())),
    }
}

/// `rrggbb` (sRGB, 8 bits a channel) as linear values.
pub(crate) fn hex_colour(hex: &str) -> Option<Rgb> {
    if hex.len() != 6 || !hex.is_ascii() {
        return None;
    }
    let mut out = [0.0; 3];
    for (i, o) in out.iter_mut().enumerate() {
        let v = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).ok()?;
        *o = srgb_to_linear(v);
    }
    Some(out)
}

impl Spec {
    /// The material this spec describes, with defaults filled in and every
    /// number checked against its range (the palette's).
    pub fn resolve(&self) -> Result<Kind, String> {
        let num = |key: &str, v: Option<Rgb>, default: f64, max: f64| -> Result<Rgb, String> {
            let v = v.unwrap_or([default; 3]);
            if v.iter().any(|x| !x.is_finite() || *x < 0.0 || *x > max) {
                return Err(format!("{key} = {v:?} is outside 0..={max}"));
            }
            Ok(v)
        };
        let material = |kind, reflectance: Rgb, emission: Rgb| {
            // A colour for messages and default group names, from the values.
            let peak = emission.iter().cloned().fold(0.0, f64::max).max(1e-30);
            let shown = if kind == MaterialKind::Emitter {
                emission.map(|e| e / peak)
            } else {
                reflectance
            };
            Material {
                color: shown.map(|c| (linear_to_srgb(c) * 255.0).round() as u8),
                kind,
                reflectance,
                emission,
                group: self.group.clone(),
                line: None,
            }
        };
        match self.kind.as_str() {
            "floor" => Ok(Kind::Floor(num("albedo", self.albedo, 0.5, 1.0)?)),
            "wall" => Ok(Kind::Solid(material(
                MaterialKind::Wall,
                num("reflectance", self.reflectance, 0.5, 1.0)?,
                [0.0; 3],
            ))),
            "emitter" => Ok(Kind::Solid(material(
                MaterialKind::Emitter,
                num("reflectance", self.reflectance, 0.0, 1.0)?,
                num("emission", self.emission, 4.0, MAX_EMISSION)?,
            ))),
            other => Err(format!(
                "unknown flatbake value {other:?} (expected wall, emitter or floor)"
            )),
        }
    }
}

/// The level's cells while a map is painted into it: `None` is plain floor.
pub(crate) struct Canvas {
    /// Width in level pixels.
    pub width: usize,
    /// Height in level pixels.
    pub height: usize,
    /// Row-major.
    pub cells: Vec<Option<Kind>>,
}

impl Canvas {
    /// An all-floor canvas.
    pub fn new(width: usize, height: usize) -> Canvas {
        Canvas {
            width,
            height,
            cells: vec![None; width * height],
        }
    }

    /// Fills the `tw x th` pixel block of map cell `(tx, ty)`.
    pub fn fill_cell(&mut self, tx: usize, ty: usize, tw: usize, th: usize, kind: &Option<Kind>) {
        for py in 0..th {
            let y = ty * th + py;
            if y >= self.height {
                break;
            }
            let row = y * self.width;
            let x0 = (tx * tw).min(self.width);
            let x1 = (tx * tw + tw).min(self.width);
            self.cells[row + x0..row + x1].fill(kind.clone());
        }
    }

    /// Paints the pixels whose centres lie in the rectangle (or the ellipse
    /// inscribed in it) at `(x0, y0)` of size `w x h`, in level pixels;
    /// what lies outside the level is cut off.
    pub fn paint(&mut self, x0: f64, y0: f64, w: f64, h: f64, ellipse: bool, kind: &Option<Kind>) {
        if ![x0, y0, w, h].iter().all(|v| v.is_finite()) || w <= 0.0 || h <= 0.0 {
            return;
        }
        let range = |a: f64, len: f64, n: usize| {
            (a.max(0.0).floor().min(n as f64) as usize)
                ..((a + len).ceil().clamp(0.0, n as f64) as usize)
        };
        for py in range(y0, h, self.height) {
            for px in range(x0, w, self.width) {
                let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
                let inside = if ellipse {
                    let dx = (cx - x0 - w / 2.0) / (w / 2.0);
                    let dy = (cy - y0 - h / 2.0) / (h / 2.0);
                    dx * dx + dy * dy <= 1.0
                } else {
                    cx >= x0 && cx <= x0 + w && cy >= y0 && cy <= y0 + h
                };
                if inside {
                    self.cells[py * self.width + px] = kind.clone();
                }
            }
        }
    }

    /// The resolved level: floor (albedo 0.5 where nothing is painted) and
    /// one material per distinct solid. Fails only past 65536 materials.
    pub fn into_level(self, name: String, origin: super::Origin) -> Result<Level, String> {
        let mut materials: Vec<Material> = Vec::new();
        let mut index: HashMap<String, u16> = HashMap::new();
        let mut cells = Vec::with_capacity(self.cells.len());
        let mut albedo = Vec::with_capacity(self.cells.len());
        for k in &self.cells {
            match k {
                None => {
                    cells.push(Cell::Floor);
                    albedo.push([0.5; 3]);
                }
                Some(Kind::Floor(a)) => {
                    cells.push(Cell::Floor);
                    albedo.push(a.map(|v| v as f32));
                }
                Some(Kind::Solid(m)) => {
                    let key = format!("{m:?}");
                    let i = match index.get(&key) {
                        Some(&i) => i,
                        None => {
                            if materials.len() > u16::MAX as usize {
                                return Err("more than 65536 distinct materials".into());
                            }
                            let i = materials.len() as u16;
                            materials.push(m.clone());
                            index.insert(key, i);
                            i
                        }
                    };
                    cells.push(Cell::Solid(i));
                    albedo.push([0.0; 3]);
                }
            }
        }
        Ok(Level {
            name,
            width: self.width,
            height: self.height,
            cells,
            albedo,
            materials,
            warnings: Vec::new(),
            lossy_format: None,
            origin,
            floor_fraction: None,
        })
    }
}
