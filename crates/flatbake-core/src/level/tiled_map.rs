//! Tiled maps (`.tmx`) as levels, without painting a picture first.
//!
//! One tile layer — the one named by the map property `flatbake_layer`, else
//! the one named `walls` — says what each map tile is through the custom
//! properties of its tiles: `flatbake` = `wall` | `emitter` | `floor`, with
//! optional `reflectance` (walls, default 0.5), `emission` (emitters, default
//! 4), `albedo` (floors, default 0.5) and `group` (light group for layers).
//! Numbers are one value or three (`"0.7 0.1 0.1"` or `"[0.7, 0.1, 0.1]"`),
//! linear, with the palette's ranges. Empty tiles and tiles without a
//! `flatbake` property are floor. Objects of class `light` (point, rectangle,
//! ellipse or tile object; rotation ignored) become emitter cells of that
//! shape with the same properties, and so do objects with a `flatbake`
//! property of that material; a point is a square of one tile, a tile
//! object (whose y is its bottom edge) has its tile's class and properties
//! unless it sets its own. Layers inside group layers count too. One map tile is
//! `tile width x tile height` level pixels, or `flatbake_tile_pixels` square
//! pixels when the map sets that property. Tileset images are never read.

use std::path::{Path, PathBuf};

use tiled::{LayerType, ObjectShape, PropertyValue, TileLayer};

use crate::level::map_grid::{self, Canvas, Kind, Spec, parse_rgb};
use crate::level::material::Rgb;
use crate::level::palette::PaletteSettings;
use crate::level::{Level, LevelError, LoadLimits};

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

fn err(map: &Path, place: impl Into<String>, problem: impl Into<String>) -> LevelError {
    LevelError::Tiled(TiledError {
        map: map.to_path_buf(),
        place: place.into(),
        problem: problem.into(),
    })
}

fn rgb_value(v: &PropertyValue) -> Result<Rgb, String> {
    match v {
        PropertyValue::FloatValue(f) => Ok([*f as f64; 3]),
        PropertyValue::IntValue(i) => Ok([*i as f64; 3]),
        PropertyValue::StringValue(s) => parse_rgb(s),
        other => Err(format!("{other:?} is not a number or three numbers")),
    }
}

/// Reads the flatbake properties; `None` when the tile has no `flatbake` property.
fn kind_of(props: &tiled::Properties, default_solid: bool) -> Result<Option<Kind>, String> {
    let kind = match props.get("flatbake") {
        Some(PropertyValue::StringValue(s)) => s.clone(),
        Some(other) => return Err(format!("property flatbake is {other:?}, expected a string")),
        None if default_solid => "emitter".into(),
        None => return Ok(None),
    };
    let num = |key: &str| -> Result<Option<Rgb>, String> {
        props
            .get(key)
            .map(|v| rgb_value(v).map_err(|e| format!("property {key}: {e}")))
            .transpose()
    };
    let group = match props.get("group") {
        Some(PropertyValue::StringValue(s)) => Some(s.clone()),
        Some(other) => return Err(format!("property group is {other:?}, expected a string")),
        None => None,
    };
    let spec = Spec {
        kind,
        reflectance: num("reflectance")?,
        emission: num("emission")?,
        albedo: num("albedo")?,
        group,
    };
    spec.resolve().map(Some).map_err(|e| {
        if e.starts_with("unknown") {
            e
        } else {
            format!("property {e}")
        }
    })
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

/// The `[bake]` settings the map's properties `flatbake_falloff`,
/// `flatbake_bounces` and `flatbake_exposure` give (over the palette's, under
/// the command line's).
pub fn tiled_settings(path: &Path) -> Result<PaletteSettings, LevelError> {
    let map = tiled::Loader::new()
        .load_tmx_map(path)
        .map_err(|e| err(path, "map", format!("cannot read the Tiled map: {e}")))?;
    let mut s = PaletteSettings::default();
    for key in map_grid::BAKE_KEYS {
        let value = match map.properties.get(key) {
            None => continue,
            Some(PropertyValue::FloatValue(f)) => *f as f64,
            Some(PropertyValue::IntValue(n)) => *n as f64,
            Some(other) => {
                return Err(err(
                    path,
                    format!("map property {key}"),
                    format!("{other:?} is not a number"),
                ));
            }
        };
        map_grid::bake_setting(&mut s, key, value)
            .map_err(|e| err(path, format!("map property {key}"), e))?;
    }
    Ok(s)
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
    let mut canvas = Canvas::new(w, h);
    let mut found = false;
    let mut layers = Vec::new();
    flatten(map.layers(), &mut layers);
    for &layer in &layers {
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
                canvas.fill_cell(tx as usize, ty as usize, tpx_w, tpx_h, &kind);
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
    for &layer in &layers {
        let LayerType::Objects(ol) = layer.layer_type() else {
            continue;
        };
        for obj in ol.objects() {
            // A tile object has its tile's class and properties, which
            // its own override.
            let tile = obj.get_tile();
            let tile = tile.as_ref().and_then(|t| t.get_tile());
            let light = obj.user_type.eq_ignore_ascii_case("light")
                || tile
                    .as_ref()
                    .is_some_and(|t| t.user_type.eq_ignore_ascii_case("light"));
            let mut props = tile
                .as_ref()
                .map(|t| t.properties.clone())
                .unwrap_or_default();
            props.extend(obj.properties.clone());
            if !light && !props.contains_key("flatbake") {
                continue;
            }
            let place = format!("layer {:?}, object {} {:?}", layer.name, obj.id(), obj.name);
            let kind = kind_of(&props, light).map_err(|p| err(path, place.clone(), p))?;
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
            // A point is centred on its position; rectangles and ellipses
            // start at it; a tile object stands on it (its y is the bottom).
            let (x0, y0) = if matches!(obj.shape, ObjectShape::Point(..)) {
                (x0 - ow / 2.0, y0 - oh / 2.0)
            } else if obj.get_tile().is_some() {
                (x0, y0 - oh)
            } else {
                (x0, y0)
            };
            canvas.paint(x0, y0, ow, oh, ellipse, &kind);
        }
    }
    canvas
        .into_level(name, super::Origin::Tiled)
        .map_err(|p| err(path, "map", p))
}

/// Appends `layers` and, after each group layer, the layers inside it, in
/// the map's order.
fn flatten<'m>(layers: impl Iterator<Item = tiled::Layer<'m>>, out: &mut Vec<tiled::Layer<'m>>) {
    for layer in layers {
        out.push(layer);
        if let LayerType::Group(g) = layer.layer_type() {
            flatten(g.layers(), out);
        }
    }
}

/// True for a path ending in `.tmx` (any case).
pub fn is_tiled_map(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("tmx"))
}
