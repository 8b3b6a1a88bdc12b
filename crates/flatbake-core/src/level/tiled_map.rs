//! Tiled maps (`.tmx`) as levels, without painting a picture first.
//!
//! One tile layer — the one named by the map property `flatbake_layer`, else
//! the one named `walls` — says what each map tile is through the custom
//! properties of its tiles: `flatbake` = `wall` | `emitter` | `floor`, with
//! optional `reflectance` (walls, default 0.5), `emission` (emitters, default
//! 4), `albedo` (floors, default 0.5) and `group` (light group for layers).
//! Numbers are one value or three (`"0.7 0.1 0.1"` or `"[0.7, 0.1, 0.1]"`),
//! linear, with the palette's ranges. Empty tiles and tiles without a
//! `flatbake` property are floor. Objects of class `light` (point, rectangle
//! or ellipse; rotation ignored) become emitter cells of that shape with the
//! same properties; a point is a square of one tile. One map tile is
//! `tile width x tile height` level pixels, or `flatbake_tile_pixels` square
//! pixels when the map sets that property. Tileset images are never read.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use tiled::{LayerType, ObjectShape, PropertyValue, TileLayer};

use crate::level::material::{Material, MaterialKind, Rgb, linear_to_srgb};
use crate::level::palette::MAX_EMISSION;
use crate::level::{Cell, Level, LevelError, LoadLimits};

/// A Tiled map problem, located in the map.
#[derive(Debug, thiserror::Error)]
#[error("{}: {place}: {problem}", map.display())]
pub struct TiledError {
    /// The map file.
    pub map: PathBuf,
    /// Where in the map: layer and tile, object, or the map itself.
    pub place: String,
    /// What is wrong.
    pub problem: String,
}

/// What one map tile or light object is.
#[derive(Clone, Debug, PartialEq)]
enum Kind {
    Floor(Rgb),
    Solid(Material),
}

fn err(map: &Path, place: impl Into<String>, problem: impl Into<String>) -> LevelError {
    LevelError::Tiled(TiledError {
        map: map.to_path_buf(),
        place: place.into(),
        problem: problem.into(),
    })
}

fn rgb_value(v: &PropertyValue) -> Result<Rgb, String> {
    let list: Vec<f64> = match v {
        PropertyValue::FloatValue(f) => vec![*f as f64],
        PropertyValue::IntValue(i) => vec![*i as f64],
        PropertyValue::StringValue(s) => s
            .trim()
            .trim_start_matches('[')
            .trim_end_matches(']')
            .split([',', ' '])
            .filter(|p| !p.is_empty())
            .map(|p| {
                p.parse::<f64>()
                    .map_err(|_| format!("{p:?} is not a number"))
            })
            .collect::<Result<_, _>>()?,
        other => return Err(format!("{other:?} is not a number or three numbers")),
    };
    match list[..] {
        [a] => Ok([a; 3]),
        [a, b, c] => Ok([a, b, c]),
        _ => Err(format!("{} numbers given, expected 1 or 3", list.len())),
    }
}

/// Reads the flatbake properties; `None` when the tile has no `flatbake` property.
fn kind_of(props: &tiled::Properties, default_solid: bool) -> Result<Option<Kind>, String> {
    let kind = match props.get("flatbake") {
        Some(PropertyValue::StringValue(s)) => s.as_str(),
        Some(other) => return Err(format!("property flatbake is {other:?}, expected a string")),
        None if default_solid => "emitter",
        None => return Ok(None),
    };
    let num = |key: &str, default: f64, max: f64| -> Result<Rgb, String> {
        let v = match props.get(key) {
            Some(v) => rgb_value(v).map_err(|e| format!("property {key}: {e}"))?,
            None => [default; 3],
        };
        if v.iter().any(|x| !x.is_finite() || *x < 0.0 || *x > max) {
            return Err(format!("property {key} = {v:?} is outside 0..={max}"));
        }
        Ok(v)
    };
    let group = match props.get("group") {
        Some(PropertyValue::StringValue(s)) => Some(s.clone()),
        Some(other) => return Err(format!("property group is {other:?}, expected a string")),
        None => None,
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
            group: group.clone(),
            line: None,
        }
    };
    match kind {
        "floor" => Ok(Some(Kind::Floor(num("albedo", 0.5, 1.0)?))),
        "wall" => Ok(Some(Kind::Solid(material(
            MaterialKind::Wall,
            num("reflectance", 0.5, 1.0)?,
            [0.0; 3],
        )))),
        "emitter" => Ok(Some(Kind::Solid(material(
            MaterialKind::Emitter,
            num("reflectance", 0.0, 1.0)?,
            num("emission", 4.0, MAX_EMISSION)?,
        )))),
        other => Err(format!(
            "unknown flatbake value {other:?} (expected wall, emitter or floor)"
        )),
    }
}

/// The external tileset files (`.tsx`) a map uses, which its level depends on.
pub fn tiled_dependencies(path: &Path) -> Vec<PathBuf> {
    let Ok(map) = tiled::Loader::new().load_tmx_map(path) else {
        return Vec::new();
    };
    let mut out: Vec<PathBuf> = map
        .tilesets()
        .iter()
        .map(|t| t.source.clone())
        .filter(|s| s != path)
        .collect();
    out.sort();
    out.dedup();
    out
}

/// Loads a Tiled map as a level (named after the file stem).
pub fn load_tiled(path: &Path, limits: LoadLimits) -> Result<Level, LevelError> {
    let map = tiled::Loader::new()
        .load_tmx_map(path)
        .map_err(|e| err(path, "map", format!("cannot read the Tiled map: {e}")))?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let layer_name = match map.properties.get("flatbake_layer") {
        Some(PropertyValue::StringValue(s)) => s.clone(),
        Some(other) => {
            return Err(err(
                path,
                "map property flatbake_layer",
                format!("{other:?} is not a layer name"),
            ));
        }
        None => "walls".to_string(),
    };
    let (tpx_w, tpx_h) = match map.properties.get("flatbake_tile_pixels") {
        Some(PropertyValue::IntValue(n)) if (1..=4096).contains(n) => (*n as usize, *n as usize),
        Some(other) => {
            return Err(err(
                path,
                "map property flatbake_tile_pixels",
                format!("{other:?} is not an int in 1..=4096"),
            ));
        }
        None => (map.tile_width as usize, map.tile_height as usize),
    };
    if tpx_w == 0 || tpx_h == 0 || map.width == 0 || map.height == 0 {
        return Err(err(path, "map", "the map has no tiles or zero tile size"));
    }
    let (w, h) = (map.width as usize * tpx_w, map.height as usize * tpx_h);
    if (w as u64) * (h as u64) > limits.max_pixels {
        return Err(err(
            path,
            "map",
            format!(
                "the level would be {w} x {h} pixels, more than the limit of {} pixels; raise --max-pixels",
                limits.max_pixels
            ),
        ));
    }
    let mut tiles: Vec<Option<Kind>> = vec![None; w * h];
    let mut found = false;
    for layer in map.layers() {
        if layer.name != layer_name {
            continue;
        }
        let place =
            |x: u32, y: u32, id: u32| format!("layer {:?}, tile id {id} at ({x}, {y})", layer.name);
        let LayerType::Tiles(tl) = layer.layer_type() else {
            return Err(err(
                path,
                format!("layer {:?}", layer.name),
                "is not a tile layer",
            ));
        };
        let TileLayer::Finite(fl) = tl else {
            return Err(err(
                path,
                format!("layer {:?}", layer.name),
                "infinite maps are not supported; turn off Map > Infinite",
            ));
        };
        found = true;
        for ty in 0..map.height {
            for tx in 0..map.width {
                let Some(lt) = fl.get_tile(tx as i32, ty as i32) else {
                    continue;
                };
                let kind = match lt.get_tile() {
                    Some(tile) => kind_of(&tile.properties, false)
                        .map_err(|p| err(path, place(tx, ty, lt.id()), p))?,
                    None => None,
                };
                for py in 0..tpx_h {
                    let row = (ty as usize * tpx_h + py) * w + tx as usize * tpx_w;
                    tiles[row..row + tpx_w].fill(kind.clone());
                }
            }
        }
    }
    if !found {
        return Err(err(
            path,
            format!("layer {layer_name:?}"),
            "the map has no tile layer of this name (set the map property flatbake_layer to choose another)",
        ));
    }
    let (sx, sy) = (
        tpx_w as f64 / map.tile_width.max(1) as f64,
        tpx_h as f64 / map.tile_height.max(1) as f64,
    );
    for layer in map.layers() {
        let LayerType::Objects(ol) = layer.layer_type() else {
            continue;
        };
        for obj in ol.objects() {
            if !obj.user_type.eq_ignore_ascii_case("light") {
                continue;
            }
            let place = format!("layer {:?}, object {} {:?}", layer.name, obj.id(), obj.name);
            let kind = kind_of(&obj.properties, true).map_err(|p| err(path, place.clone(), p))?;
            let (x0, y0) = (obj.x as f64 * sx, obj.y as f64 * sy);
            let (ow, oh, ellipse) = match obj.shape {
                ObjectShape::Rect { width, height } => {
                    (width as f64 * sx, height as f64 * sy, false)
                }
                ObjectShape::Ellipse { width, height } => {
                    (width as f64 * sx, height as f64 * sy, true)
                }
                ObjectShape::Point(..) => (tpx_w as f64, tpx_h as f64, false),
                _ => {
                    return Err(err(
                        path,
                        place,
                        "a light must be a point, rectangle or ellipse",
                    ));
                }
            };
            // A point is centred on its position; rectangles and ellipses start at it.
            let (x0, y0) = if matches!(obj.shape, ObjectShape::Point(..)) {
                (x0 - ow / 2.0, y0 - oh / 2.0)
            } else {
                (x0, y0)
            };
            let xs =
                (x0.max(0.0).floor() as usize).min(w)..((x0 + ow).ceil().max(0.0) as usize).min(w);
            let ys =
                (y0.max(0.0).floor() as usize).min(h)..((y0 + oh).ceil().max(0.0) as usize).min(h);
            for py in ys {
                for px in xs.clone() {
                    let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
                    let inside = if ellipse {
                        let (dx, dy) = (
                            (cx - x0 - ow / 2.0) / (ow / 2.0),
                            (cy - y0 - oh / 2.0) / (oh / 2.0),
                        );
                        dx * dx + dy * dy <= 1.0
                    } else {
                        cx >= x0 && cx <= x0 + ow && cy >= y0 && cy <= y0 + oh
                    };
                    if inside {
                        tiles[py * w + px] = kind.clone();
                    }
                }
            }
        }
    }
    let mut materials: Vec<Material> = Vec::new();
    let mut index: HashMap<String, u16> = HashMap::new();
    let mut cells = Vec::with_capacity(w * h);
    let mut albedo = Vec::with_capacity(w * h);
    for k in &tiles {
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
                            return Err(err(path, "map", "more than 65536 distinct materials"));
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
        width: w,
        height: h,
        cells,
        albedo,
        materials,
        warnings: Vec::new(),
        lossy_format: None,
    })
}

/// True for a path ending in `.tmx` (any case).
pub fn is_tiled_map(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("tmx"))
}
