//! LDtk projects (`.ldtk`) as levels: every level of a project is a level of
//! its own, named `PROJECT.LEVEL` and addressed as the path
//! `PROJECT.ldtk/LEVEL` (the project file, then the level's identifier), so
//! that a batch, its stamps and its reports treat it like any level file.
//!
//! Only the few fields flatbake needs are read, with our own serde types.
//! One IntGrid layer — the one named by the level field `flatbake_layer`,
//! else the only IntGrid layer, else the one named `walls` or `collisions`
//! (any case) — says what each grid cell is, by its value's identifier:
//! `wall`/`walls` are walls (reflectance 0.5), `emitter`/`light`/`lamp`
//! emitters (emission 4), `floor` floor (albedo 0.5), and 0 (empty) is floor.
//! Any other identifier is an error naming the cell, unless the level field
//! `flatbake` (a multi-line string; give it a default in the project's level
//! field definition and it holds for every level) maps it, one entry a line
//! or separated by `;`:
//!
//! ```text
//! water = floor albedo=0.2,0.3,0.6
//! lava = emitter emission=8,2,0.5 group=lava
//! 3 = wall reflectance=0.3
//! Torch = emitter emission=6
//! ```
//!
//! A key is an IntGrid value's identifier or number, or an entity's
//! identifier; options are `reflectance`, `emission`, `albedo` (one number
//! or three, linear, or `#rrggbb`), `colour` (tints the emission) and
//! `group`. Entities become shapes of material: those with a `flatbake`
//! field (wall, emitter or floor), those the table names, and lights (an
//! entity named `Light` or `Lamp`, or tagged `light`, is an emitter). Their
//! own fields `reflectance`, `emission`, `albedo`, `colour`/`color` and
//! `group` override the table's; the shape is the entity's box (an ellipse
//! when the entity is drawn as one), or a disc of `radius` grid cells around
//! the entity's position. One grid cell is its layer's grid size in level
//! pixels, or `flatbake_tile_pixels` square pixels when the level sets that
//! field. Tilesets and background images are never read.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::level::map_grid::{self, Canvas, Kind, Spec, parse_rgb};
use crate::level::material::Rgb;
use crate::level::palette::PaletteSettings;
use crate::level::{Level, LevelError, LoadLimits};
use crate::output::names;

/// An LDtk project problem, located in the project.
#[derive(Debug, thiserror::Error)]
#[error("{}: {place}: {problem}", project.display())]
pub struct LdtkError {
    /// The project file.
    pub project: PathBuf,
    /// Where: the project, or a level and its layer, cell, entity or field.
    pub place: String,
    /// What is wrong.
    pub problem: String,
}

fn err(project: &Path, place: impl Into<String>, problem: impl Into<String>) -> LevelError {
    LevelError::Ldtk(LdtkError {
        project: project.to_path_buf(),
        place: place.into(),
        problem: problem.into(),
    })
}

#[derive(Debug, Deserialize)]
struct Project {
    defs: Defs,
    #[serde(default)]
    levels: Vec<LevelJson>,
    #[serde(default)]
    worlds: Vec<World>,
}

#[derive(Debug, Deserialize)]
struct World {
    #[serde(default)]
    levels: Vec<LevelJson>,
}

#[derive(Debug, Deserialize, Serialize)]
struct Defs {
    #[serde(default)]
    layers: Vec<LayerDef>,
    #[serde(default)]
    entities: Vec<EntityDef>,
}

#[derive(Debug, Deserialize, Serialize)]
struct LayerDef {
    identifier: String,
    uid: i64,
    #[serde(rename = "intGridValues", default)]
    int_grid_values: Vec<IntGridValue>,
}

#[derive(Debug, Deserialize, Serialize)]
struct IntGridValue {
    /// Missing in projects of LDtk before 0.9, where a value is its place in
    /// the list (1, 2, ...): [`upgrade_legacy`] fills it in as LDtk does.
    #[serde(default = "no_value")]
    value: i64,
    identifier: Option<String>,
}

#[derive(Debug, Deserialize, Serialize)]
struct EntityDef {
    uid: i64,
    #[serde(rename = "renderMode", default)]
    render_mode: String,
    /// The definition's tags; instances carry a copy (`__tags`) that a
    /// hand edit of the definition may leave behind, so both count.
    #[serde(default)]
    tags: Vec<String>,
    /// The size an instance has when it does not say (LDtk before 0.8).
    #[serde(default)]
    width: f64,
    #[serde(default)]
    height: f64,
}

#[derive(Debug, Deserialize, Serialize)]
struct LevelJson {
    identifier: String,
    #[serde(rename = "externalRelPath", default, skip_serializing)]
    external_rel_path: Option<String>,
    #[serde(rename = "fieldInstances", default)]
    field_instances: Vec<Field>,
    #[serde(rename = "layerInstances", default)]
    layer_instances: Option<Vec<LayerInstance>>,
}

#[derive(Debug, Deserialize, Serialize)]
struct Field {
    #[serde(rename = "__identifier")]
    identifier: String,
    #[serde(rename = "__value", default)]
    value: Value,
}

#[derive(Debug, Deserialize, Serialize)]
struct LayerInstance {
    #[serde(rename = "__identifier")]
    identifier: String,
    #[serde(rename = "__type")]
    kind: String,
    #[serde(rename = "__cWid")]
    c_wid: i64,
    #[serde(rename = "__cHei")]
    c_hei: i64,
    #[serde(rename = "__gridSize")]
    grid_size: i64,
    #[serde(rename = "__pxTotalOffsetX", default)]
    offset_x: f64,
    #[serde(rename = "__pxTotalOffsetY", default)]
    offset_y: f64,
    #[serde(rename = "layerDefUid")]
    layer_def_uid: i64,
    #[serde(rename = "intGridCsv", default)]
    int_grid_csv: Vec<i64>,
    /// LDtk before 0.8: the set cells, each a cell index and a value index
    /// (value - 1); [`upgrade_legacy`] turns it into `int_grid_csv`.
    #[serde(rename = "intGrid", default, skip_serializing)]
    int_grid: Option<Vec<LegacyIntGridCell>>,
    #[serde(rename = "entityInstances", default)]
    entity_instances: Vec<EntityInstance>,
}

#[derive(Debug, Deserialize)]
struct LegacyIntGridCell {
    #[serde(rename = "coordId")]
    coord_id: i64,
    v: i64,
}

fn no_value() -> i64 {
    i64::MIN
}

fn no_size() -> f64 {
    f64::NAN
}

/// Reads projects of older LDtk versions the way LDtk itself upgrades them:
/// an IntGrid value without a `value` is its place in the list (from 1),
/// and a layer with the pre-0.8 `intGrid` list instead of `intGridCsv` has
/// value `v + 1` at cell `coordId`; an `intGridCsv` with negative entries is
/// the zero-based form that development builds of LDtk 0.8 wrote (-1 empty,
/// else the value's index), shifted up by one. Released versions never
/// write a negative entry (0 is empty), and those builds already said
/// `jsonVersion` 0.8.0, so the entries are the only sign; a level of such a
/// build without one empty cell reads one value too low (its first value
/// as empty). An entity instance without a size has its
/// definition's. A cell outside the layer is an error.
fn upgrade_legacy(
    project: &Path,
    defs: &mut Defs,
    level: &mut LevelJson,
) -> Result<(), LevelError> {
    for layer in &mut defs.layers {
        for (k, v) in layer.int_grid_values.iter_mut().enumerate() {
            if v.value == no_value() {
                v.value = k as i64 + 1;
            }
        }
    }
    for layer in level.layer_instances.iter_mut().flatten() {
        for e in &mut layer.entity_instances {
            let def = defs.entities.iter().find(|d| d.uid == e.def_uid);
            if e.width.is_nan() {
                e.width = def.map_or(0.0, |d| d.width);
            }
            if e.height.is_nan() {
                e.height = def.map_or(0.0, |d| d.height);
            }
        }
        if layer.int_grid_csv.iter().any(|&v| v < 0) {
            layer
                .int_grid_csv
                .iter_mut()
                .for_each(|v| *v = v.saturating_add(1));
        }
        let Some(cells) = layer.int_grid.take() else {
            continue;
        };
        if !layer.int_grid_csv.is_empty() {
            continue;
        }
        let n = (layer.c_wid.max(0) as usize).saturating_mul(layer.c_hei.max(0) as usize);
        let mut csv = vec![0; n];
        for c in cells {
            let slot = usize::try_from(c.coord_id)
                .ok()
                .and_then(|i| csv.get_mut(i));
            let Some(slot) = slot else {
                return Err(err(
                    project,
                    format!("level {:?}, layer {:?}", level.identifier, layer.identifier),
                    format!(
                        "intGrid cell {} is outside the layer's {} x {} cells",
                        c.coord_id, layer.c_wid, layer.c_hei
                    ),
                ));
            };
            *slot = c.v.saturating_add(1);
        }
        layer.int_grid_csv = csv;
    }
    Ok(())
}

#[derive(Debug, Deserialize, Serialize)]
struct EntityInstance {
    #[serde(rename = "__identifier")]
    identifier: String,
    #[serde(rename = "__pivot", default)]
    pivot: [f64; 2],
    #[serde(rename = "__tags", default)]
    tags: Vec<String>,
    /// Missing before LDtk 0.8: the definition's ([`upgrade_legacy`]).
    #[serde(default = "no_size")]
    width: f64,
    #[serde(default = "no_size")]
    height: f64,
    #[serde(rename = "defUid")]
    def_uid: i64,
    px: [f64; 2],
    #[serde(rename = "fieldInstances", default)]
    field_instances: Vec<Field>,
}

/// True for a path ending in `.ldtk` (any case).
pub fn is_ldtk_project(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("ldtk"))
}

/// The project and level identifier of a level path `PROJECT.ldtk/LEVEL`;
/// `None` for any other path. Looks only at the path's spelling (an LDtk
/// identifier has no dot) and that the project is not a folder.
pub fn project_level(path: &Path) -> Option<(&Path, &str)> {
    let project = path.parent()?;
    let level = path.file_name()?.to_str()?;
    (is_ldtk_project(project) && !level.is_empty() && !level.contains('.') && !project.is_dir())
        .then_some((project, level))
}

/// The level paths (`PROJECT.ldtk/LEVEL`) of every level of a project, in
/// the project's order.
pub fn project_levels(project: &Path) -> Result<Vec<PathBuf>, LevelError> {
    let p = read_project(project)?;
    Ok(all_levels(&p)
        .map(|l| project.join(&l.identifier))
        .collect())
}

fn all_levels(p: &Project) -> impl Iterator<Item = &LevelJson> {
    p.levels
        .iter()
        .chain(p.worlds.iter().flat_map(|w| &w.levels))
}

fn read_project(project: &Path) -> Result<Project, LevelError> {
    let bytes = std::fs::read(project).map_err(|e| {
        let problem = match e.kind() {
            std::io::ErrorKind::NotFound => "file not found".to_string(),
            _ => format!("cannot read the file: {e}"),
        };
        err(project, "project", problem)
    })?;
    serde_json::from_slice(&bytes).map_err(|e| {
        // Name the version that wrote it: projects older than the ones
        // read here need a round trip through a current LDtk.
        #[derive(Deserialize)]
        struct Version {
            #[serde(rename = "jsonVersion")]
            json_version: String,
        }
        let hint = match serde_json::from_slice::<Version>(&bytes) {
            Ok(v) if is_before(&v.json_version, (0, 4)) => format!(
                " (saved by LDtk {}: flatbake reads projects of LDtk 0.4 and later; open it \
                 in a current LDtk and save it again)",
                v.json_version
            ),
            Ok(v) => format!(" (saved by LDtk {})", v.json_version),
            Err(_) => String::new(),
        };
        err(
            project,
            "project",
            format!("not an LDtk project: {e}{hint}"),
        )
    })
}

/// True when a version string `major.minor...` is before `(major, minor)`.
fn is_before(version: &str, (major, minor): (u32, u32)) -> bool {
    let mut parts = version
        .split('.')
        .map(|p| p.trim().parse::<u32>().unwrap_or(0));
    let v = (parts.next().unwrap_or(0), parts.next().unwrap_or(0));
    v < (major, minor)
}

/// The project and its level `id`, with the level's layers read from its
/// own `.ldtkl` file when the project keeps levels in separate files.
fn read_level(project: &Path, id: &str) -> Result<(Defs, LevelJson), LevelError> {
    let p = read_project(project)?;
    let names: Vec<&str> = all_levels(&p).map(|l| l.identifier.as_str()).collect();
    let Some(i) = names.iter().position(|n| *n == id) else {
        return Err(err(
            project,
            format!("level {id:?}"),
            format!(
                "the project has no level of this identifier (its levels: {})",
                names.join(", ")
            ),
        ));
    };
    let Project {
        mut defs,
        levels,
        worlds,
    } = p;
    let Some(mut level) = levels
        .into_iter()
        .chain(worlds.into_iter().flat_map(|w| w.levels))
        .nth(i)
    else {
        return Err(err(project, format!("level {id:?}"), "the level vanished"));
    };
    if level.layer_instances.is_none()
        && let Some(rel) = &level.external_rel_path
    {
        let file = project.parent().unwrap_or(Path::new("")).join(rel);
        let place = format!("level {id:?}");
        let bytes = std::fs::read(&file).map_err(|e| {
            err(
                project,
                place.clone(),
                format!("cannot read its level file {}: {e}", file.display()),
            )
        })?;
        let ext: LevelJson = serde_json::from_slice(&bytes).map_err(|e| {
            err(
                project,
                place.clone(),
                format!(
                    "its level file {} is not an LDtk level: {e}",
                    file.display()
                ),
            )
        })?;
        level.layer_instances = ext.layer_instances;
        level.field_instances = ext.field_instances;
    }
    upgrade_legacy(project, &mut defs, &mut level)?;
    Ok((defs, level))
}

/// What the level at `path` (`PROJECT.ldtk/LEVEL`) is made from, as bytes
/// to hash: the project's layer and entity definitions that loading reads,
/// and the level itself (from its `.ldtkl` file if it has one). Edits
/// elsewhere in the project (another level, a tileset, the world layout)
/// leave it unchanged.
pub fn level_inputs(path: &Path) -> Result<Vec<u8>, LevelError> {
    let Some((project, id)) = project_level(path) else {
        return Err(err(path, "project", "not a level path PROJECT.ldtk/LEVEL"));
    };
    let (defs, level) = read_level(project, id)?;
    serde_json::to_vec(&(&defs, &level))
        .map_err(|e| err(project, format!("level {id:?}"), e.to_string()))
}

/// The level file (`.ldtkl`) that holds the layers of `path`'s level, when
/// its project keeps levels in separate files.
pub fn level_file(path: &Path) -> Option<PathBuf> {
    let (project, id) = project_level(path)?;
    let p = read_project(project).ok()?;
    let level = all_levels(&p).find(|l| l.identifier == id)?;
    let rel = level.external_rel_path.as_ref()?;
    Some(project.parent().unwrap_or(Path::new("")).join(rel))
}

fn field<'a>(fields: &'a [Field], name: &str) -> Option<&'a Value> {
    fields
        .iter()
        .find(|f| f.identifier.eq_ignore_ascii_case(name))
        .map(|f| &f.value)
        .filter(|v| !v.is_null())
}

fn value_rgb(v: &Value) -> Result<Rgb, String> {
    match v {
        Value::Number(n) => n
            .as_f64()
            .map(|x| [x; 3])
            .ok_or_else(|| format!("{n} is not a number")),
        Value::String(s) => parse_rgb(s),
        Value::Array(a) => {
            let nums: Vec<f64> = a
                .iter()
                .map(|x| x.as_f64().ok_or_else(|| format!("{x} is not a number")))
                .collect::<Result<_, _>>()?;
            match nums[..] {
                [x] => Ok([x; 3]),
                [r, g, b] => Ok([r, g, b]),
                _ => Err(format!("{} numbers given, expected 1 or 3", nums.len())),
            }
        }
        other => Err(format!(
            "{other} is not a number, three numbers or a colour"
        )),
    }
}

fn value_text(v: &Value) -> Result<String, String> {
    match v {
        Value::String(s) => Ok(s.clone()),
        other => Err(format!("{other} is not text")),
    }
}

/// Applies option `key` = `v` to `spec`; `tint` collects the colour.
fn set_option(spec: &mut Spec, tint: &mut Option<Rgb>, key: &str, v: &Value) -> Result<(), String> {
    let k = key.to_ascii_lowercase();
    let rgb = || value_rgb(v).map_err(|e| format!("{key}: {e}"));
    match k.as_str() {
        "reflectance" => spec.reflectance = Some(rgb()?),
        "emission" => spec.emission = Some(rgb()?),
        "albedo" => spec.albedo = Some(rgb()?),
        "colour" | "color" => *tint = Some(rgb()?),
        "group" => spec.group = Some(value_text(v).map_err(|e| format!("{key}: {e}"))?),
        _ => {
            return Err(format!(
                "unknown option {key:?} (expected reflectance, emission, albedo, colour or group)"
            ));
        }
    }
    Ok(())
}

/// The spec with its tint applied to the emission (default 4).
fn tinted(mut spec: Spec, tint: Option<Rgb>) -> Spec {
    if let Some(c) = tint {
        let e = spec.emission.unwrap_or([4.0; 3]);
        spec.emission = Some([e[0] * c[0], e[1] * c[1], e[2] * c[2]]);
    }
    spec
}

/// One entry of the `flatbake` level field: a kind and its options.
#[derive(Clone, Debug)]
struct Entry {
    spec: Spec,
    tint: Option<Rgb>,
}

/// Parses the `flatbake` level field's table, keyed by lower-case key.
fn parse_table(text: &str) -> Result<HashMap<String, Entry>, String> {
    let mut table = HashMap::new();
    for raw in text.split(['\n', ';']) {
        // A comment starts with `#` at the start or after a space (a
        // colour `=#rrggbb` is not one).
        let cut = raw
            .char_indices()
            .find(|&(i, c)| c == '#' && raw[..i].chars().last().is_none_or(char::is_whitespace))
            .map_or(raw.len(), |(i, _)| i);
        let line = raw[..cut].trim();
        if line.is_empty() {
            continue;
        }
        let Some((key, rest)) = line.split_once('=') else {
            return Err(format!(
                "entry {line:?} is not KEY = KIND [OPTION=VALUE ...]"
            ));
        };
        let key = key.trim();
        let mut words = rest.split_whitespace();
        let kind = words.next().unwrap_or("").to_ascii_lowercase();
        if !["wall", "emitter", "floor"].contains(&kind.as_str()) {
            return Err(format!(
                "entry {key}: kind {kind:?} is not wall, emitter or floor"
            ));
        }
        let mut spec = Spec {
            kind,
            ..Spec::default()
        };
        let mut tint = None;
        for w in words {
            let Some((k, v)) = w.split_once('=') else {
                return Err(format!("entry {key}: option {w:?} is not OPTION=VALUE"));
            };
            set_option(&mut spec, &mut tint, k, &Value::String(v.into()))
                .map_err(|e| format!("entry {key}: {e}"))?;
        }
        // Checked here, so that a bad number is reported where it is written.
        tinted(spec.clone(), tint)
            .resolve()
            .map_err(|e| format!("entry {key}: {e}"))?;
        if table
            .insert(key.to_ascii_lowercase(), Entry { spec, tint })
            .is_some()
        {
            return Err(format!("entry {key} is given twice"));
        }
    }
    Ok(table)
}

/// The kind an IntGrid value identifier names by flatbake's convention.
fn conventional(identifier: &str) -> Option<&'static str> {
    match identifier.to_ascii_lowercase().as_str() {
        "wall" | "walls" => Some("wall"),
        "emitter" | "emitters" | "light" | "lights" | "lamp" | "lamps" => Some("emitter"),
        "floor" => Some("floor"),
        _ => None,
    }
}

/// The `[bake]` settings the level's fields `flatbake_falloff`,
/// `flatbake_bounces` and `flatbake_exposure` give (over the palette's, under
/// the command line's); none for a path that is not one level of a project.
pub fn ldtk_settings(path: &Path) -> Result<PaletteSettings, LevelError> {
    let mut s = PaletteSettings::default();
    let Some((project, id)) = project_level(path) else {
        return Ok(s);
    };
    let (_, level) = read_level(project, id)?;
    for key in map_grid::BAKE_KEYS {
        let Some(v) = field(&level.field_instances, key) else {
            continue;
        };
        let place = format!("level {id:?}, field {key}");
        let value = v
            .as_f64()
            .ok_or_else(|| err(project, place.clone(), format!("{v} is not a number")))?;
        map_grid::bake_setting(&mut s, key, value).map_err(|e| err(project, place, e))?;
    }
    Ok(s)
}

/// Loads the level at `path` (`PROJECT.ldtk/LEVEL`), named `PROJECT.LEVEL`.
/// A bare project path is an error: its project's problem if it has one,
/// else that it must be baked level by level.
pub fn load_ldtk(path: &Path, limits: LoadLimits) -> Result<Level, LevelError> {
    let Some((project, id)) = project_level(path) else {
        let p = read_project(path)?;
        let problem = if all_levels(&p).next().is_none() {
            "the project has no levels"
        } else {
            "a project is baked level by level: give the folder or the project, or PROJECT.ldtk/LEVEL"
        };
        return Err(err(path, "project", problem));
    };
    let (defs, level) = read_level(project, id)?;
    let here = format!("level {id:?}");
    let place = |what: String| format!("{here}, {what}");
    let table = match field(&level.field_instances, "flatbake") {
        Some(v) => {
            let text =
                value_text(v).map_err(|e| err(project, place("field flatbake".into()), e))?;
            parse_table(&text).map_err(|e| err(project, place("field flatbake".into()), e))?
        }
        None => HashMap::new(),
    };
    let layers = level.layer_instances.as_deref().unwrap_or(&[]);
    let wanted = match field(&level.field_instances, "flatbake_layer") {
        Some(v) => {
            Some(value_text(v).map_err(|e| err(project, place("field flatbake_layer".into()), e))?)
        }
        None => None,
    };
    let grids: Vec<&LayerInstance> = layers.iter().filter(|l| l.kind == "IntGrid").collect();
    let grid = match &wanted {
        Some(name) => match layers.iter().find(|l| &l.identifier == name) {
            Some(l) if l.kind == "IntGrid" => l,
            Some(l) => {
                return Err(err(
                    project,
                    place(format!("layer {name:?}")),
                    format!("is an {} layer, not an IntGrid layer", l.kind),
                ));
            }
            None => {
                return Err(err(
                    project,
                    place(format!("field flatbake_layer = {name:?}")),
                    "the level has no layer of this identifier",
                ));
            }
        },
        None => match grids[..] {
            [one] => one,
            [] => {
                return Err(err(
                    project,
                    here,
                    "the level has no IntGrid layer to take walls from",
                ));
            }
            _ => match grids.iter().find(|l| {
                ["walls", "wall", "collisions"]
                    .contains(&l.identifier.to_ascii_lowercase().as_str())
            }) {
                Some(l) => *l,
                None => {
                    let names: Vec<&str> = grids.iter().map(|l| l.identifier.as_str()).collect();
                    return Err(err(
                        project,
                        here,
                        format!(
                            "the level has several IntGrid layers ({}); say which holds the walls with the level field flatbake_layer",
                            names.join(", ")
                        ),
                    ));
                }
            },
        },
    };
    let layer_place = format!("layer {:?}", grid.identifier);
    let tile_pixels = match field(&level.field_instances, "flatbake_tile_pixels") {
        Some(v) => match v.as_i64() {
            Some(n) if (1..=4096).contains(&n) => n,
            _ => {
                return Err(err(
                    project,
                    place("field flatbake_tile_pixels".into()),
                    format!("{v} is not an integer in 1..=4096"),
                ));
            }
        },
        None => grid.grid_size,
    };
    let (cw, ch) = (grid.c_wid, grid.c_hei);
    if !(1..=65536).contains(&cw)
        || !(1..=65536).contains(&ch)
        || !(1..=4096).contains(&tile_pixels)
    {
        return Err(err(
            project,
            place(layer_place),
            format!("a grid of {cw} x {ch} cells of {tile_pixels} px is not a level"),
        ));
    }
    let (cw, ch, tp) = (cw as usize, ch as usize, tile_pixels as usize);
    let (w, h) = (cw * tp, ch * tp);
    if (w as u64) * (h as u64) > limits.max_pixels {
        return Err(err(
            project,
            here,
            format!(
                "the level would be {w} x {h} pixels, more than the limit of {} pixels; raise --max-pixels",
                limits.max_pixels
            ),
        ));
    }
    if grid.int_grid_csv.len() != cw * ch {
        return Err(err(
            project,
            place(layer_place),
            format!(
                "intGridCsv holds {} values for {cw} x {ch} cells ",
                grid.int_grid_csv.len()
            ),
        ));
    }
    let values = defs
        .layers
        .iter()
        .find(|d| d.uid == grid.layer_def_uid)
        .map(|d| &d.int_grid_values[..])
        .unwrap_or(&[]);
    let mut kinds: HashMap<i64, Option<Kind>> = HashMap::from([(0, None)]);
    let mut canvas = Canvas::new(w, h);
    for (i, &v) in grid.int_grid_csv.iter().enumerate() {
        let (cx, cy) = (i % cw, i / cw);
        let kind = match kinds.get(&v) {
            Some(k) => k.clone(),
            None => {
                let cell = || place(format!("{layer_place}, cell ({cx}, {cy})"));
                let Some(def) = values.iter().find(|d| d.value == v) else {
                    return Err(err(
                        project,
                        cell(),
                        format!("IntGrid value {v} is not defined by the layer"),
                    ));
                };
                let ident = def.identifier.as_deref().unwrap_or("");
                let shown = if ident.is_empty() {
                    format!("IntGrid value {v} (no identifier)")
                } else {
                    format!("IntGrid value {v} {ident:?}")
                };
                let listed = table
                    .get(&ident.to_ascii_lowercase())
                    .filter(|_| !ident.is_empty())
                    .or_else(|| table.get(&v.to_string()))
                    .cloned();
                let from = if listed.is_some() {
                    " (as the level field flatbake maps it)"
                } else {
                    ""
                };
                let entry = listed.or_else(|| {
                    conventional(ident).map(|k| Entry {
                        spec: Spec {
                            kind: k.into(),
                            ..Spec::default()
                        },
                        tint: None,
                    })
                });
                let Some(entry) = entry else {
                    return Err(err(
                        project,
                        cell(),
                        format!(
                            "{shown} has no flatbake meaning: name it wall, emitter or floor, or map it in the level field flatbake (\"{} = floor\")",
                            if ident.is_empty() {
                                v.to_string()
                            } else {
                                ident.to_string()
                            }
                        ),
                    ));
                };
                let k = tinted(entry.spec, entry.tint)
                    .resolve()
                    .map_err(|e| err(project, cell(), format!("{shown}{from}: {e}")))?;
                kinds.insert(v, Some(k.clone()));
                Some(k)
            }
        };
        if kind.is_some() {
            canvas.fill_cell(cx, cy, tp, tp, &kind);
        }
    }
    let scale = tp as f64 / grid.grid_size.max(1) as f64;
    // Bottom layers first, so that what a higher layer places wins.
    for layer in layers.iter().rev().filter(|l| l.kind == "Entities") {
        for e in &layer.entity_instances {
            let at = place(format!(
                "layer {:?}, entity {:?} at ({}, {}) px",
                layer.identifier, e.identifier, e.px[0], e.px[1]
            ));
            let fail = |p: String| err(project, at.clone(), p);
            let own = match field(&e.field_instances, "flatbake") {
                Some(v) => Some(value_text(v).map_err(|p| fail(format!("field flatbake: {p}")))?),
                None => None,
            };
            let listed = table.get(&e.identifier.to_ascii_lowercase()).cloned();
            let def = defs.entities.iter().find(|d| d.uid == e.def_uid);
            let is_light = ["light", "lamp"].contains(&e.identifier.to_ascii_lowercase().as_str())
                || e.tags
                    .iter()
                    .chain(def.into_iter().flat_map(|d| &d.tags))
                    .any(|t| t.eq_ignore_ascii_case("light"));
            let (mut spec, mut tint) = match (own, listed) {
                (Some(k), Some(entry)) => (
                    Spec {
                        kind: k.to_ascii_lowercase(),
                        ..entry.spec
                    },
                    entry.tint,
                ),
                (Some(k), None) => (
                    Spec {
                        kind: k.to_ascii_lowercase(),
                        ..Spec::default()
                    },
                    None,
                ),
                (None, Some(entry)) => (entry.spec, entry.tint),
                (None, None) if is_light => (
                    Spec {
                        kind: "emitter".into(),
                        ..Spec::default()
                    },
                    None,
                ),
                (None, None) => continue,
            };
            for f in &e.field_instances {
                let k = f.identifier.to_ascii_lowercase();
                if [
                    "reflectance",
                    "emission",
                    "albedo",
                    "colour",
                    "color",
                    "group",
                ]
                .contains(&k.as_str())
                    && !f.value.is_null()
                {
                    set_option(&mut spec, &mut tint, &f.identifier, &f.value)
                        .map_err(|p| fail(format!("field {p}")))?;
                }
            }
            let kind = Some(
                tinted(spec, tint)
                    .resolve()
                    .map_err(|p| fail(format!("field {p}")))?,
            );
            // The entity's position in the level image's pixels.
            let x = (e.px[0] + layer.offset_x - grid.offset_x) * scale;
            let y = (e.px[1] + layer.offset_y - grid.offset_y) * scale;
            if let Some(r) = field(&e.field_instances, "radius") {
                let r = r
                    .as_f64()
                    .filter(|r| r.is_finite() && *r > 0.0)
                    .ok_or_else(|| {
                        fail(format!(
                            "field radius = {r} is not a positive number of cells"
                        ))
                    })?;
                let r = r * tp as f64;
                canvas.paint(x - r, y - r, 2.0 * r, 2.0 * r, true, &kind);
            } else {
                let (ew, eh) = (e.width * scale, e.height * scale);
                let ellipse = def.is_some_and(|d| d.render_mode == "Ellipse");
                canvas.paint(
                    x - e.pivot[0] * ew,
                    y - e.pivot[1] * eh,
                    ew,
                    eh,
                    ellipse,
                    &kind,
                );
            }
        }
    }
    canvas
        .into_level(names::project_level_name(project, id), super::Origin::Ldtk)
        .map_err(|p| err(project, here, p))
}
