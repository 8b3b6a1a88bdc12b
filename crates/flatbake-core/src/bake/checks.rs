//! Results that look like success but are probably not what was meant: a
//! level with no floor, nothing that gives light, or a black lightmap. Each
//! becomes a [`Problem`](super::Problem) in the report, with the likely
//! cause found in the level itself (white is light; no colour matched the
//! palette; a lossy image whose colours drifted). How bright the written
//! images are (clipping, exposure) is checked where they are encoded:
//! [`crate::output::exposure`].

use super::{Log, Scene};
use crate::level::material::MaterialKind;
use crate::level::{Cell, Level, Origin};

/// The kind of a level without floor.
pub const NO_FLOOR: &str = "no floor";
/// The kind of a level where nothing gives light to free space.
pub const NO_LIGHT: &str = "no light";
/// The kind of a lightmap without light on the floor.
pub const BLACK: &str = "black";
/// The kind of a lightmap whose floor is mostly at full scale.
pub const CLIPPED: &str = "clipped";

/// Checks the level before anything is simulated: is there floor to light,
/// and does anything give light to it? Records a problem with the likely
/// cause for the first answer that is no (without floor, no lamp can face
/// any, so the second question would only repeat the first).
pub fn level(level: &Level, scene: &Scene, log: &mut Log) {
    if scene.floor_pixels.is_empty() {
        log.problem(NO_FLOOR, no_floor(level));
    } else if !scene.has_emitters(level) {
        log.problem(NO_LIGHT, no_light(level));
    }
}

/// Checks the gathered lightmap of a level that has floor and light: a
/// floor without any light is a problem.
pub fn lightmap(level: &Level, rgb: &[[f32; 3]], log: &mut Log) {
    if !log.problems.is_empty() {
        return;
    }
    let lit = level
        .cells
        .iter()
        .zip(rgb)
        .any(|(c, p)| *c == Cell::Floor && p.iter().any(|&v| v > 0.0));
    if !lit && level.cells.contains(&Cell::Floor) {
        log.problem(
            BLACK,
            "the lightmap is black: no floor pixel receives any light (every lamp faces only \
             void, or floor that its light cannot reach); check that the lamps touch the floor \
             of the rooms they should light",
        );
    }
}

/// How many pixels of each material, and of void.
fn census(level: &Level) -> (Vec<usize>, usize) {
    let mut per = vec![0usize; level.materials.len()];
    let mut void = 0;
    for c in &level.cells {
        match c {
            Cell::Solid(m) => {
                if let Some(n) = per.get_mut(*m as usize) {
                    *n += 1;
                }
            }
            Cell::Void => void += 1,
            Cell::Floor => {}
        }
    }
    (per, void)
}

fn percent(part: usize, whole: usize) -> String {
    let p = 100.0 * part as f64 / whole.max(1) as f64;
    if p >= 99.95 || p == 0.0 {
        format!("{p:.0}%")
    } else {
        format!("{p:.1}%")
    }
}

/// Why a level has no floor: the colour that covers most of it, and what
/// the palette makes of it.
fn no_floor(level: &Level) -> String {
    let head = "the level has no floor pixels: nothing to light";
    let n = level.cells.len();
    let (per, void) = census(level);
    let kind_share = |kind: MaterialKind| {
        let c: usize = level
            .materials
            .iter()
            .zip(&per)
            .filter(|(m, _)| m.kind == kind)
            .map(|(_, n)| n)
            .sum();
        percent(c, n)
    };
    match level.origin {
        Origin::Image => {}
        Origin::Tiled => {
            return format!(
                "{head}: {} of the map is wall and {} emitter. Leave floor tiles empty, or give \
                 their tiles the custom property `flatbake` = `floor`; check which layer is the \
                 wall layer (the map property `flatbake_layer`, else the layer `walls`)",
                kind_share(MaterialKind::Wall),
                kind_share(MaterialKind::Emitter)
            );
        }
        Origin::Ldtk => {
            return format!(
                "{head}: {} of the level is wall and {} emitter. Leave floor cells empty in the \
                 IntGrid layer, or name their value `floor`; check which IntGrid layer is read \
                 (the level field `flatbake_layer`) and that no entity covers the level",
                kind_share(MaterialKind::Wall),
                kind_share(MaterialKind::Emitter)
            );
        }
    }
    let top = per
        .iter()
        .enumerate()
        .max_by_key(|&(i, &c)| (c, usize::MAX - i));
    match top {
        Some((m, &count)) if count >= void && count > 0 => {
            let mat = &level.materials[m];
            let share = percent(count, n);
            let hex = mat.hex();
            if mat.kind == MaterialKind::Emitter {
                if mat.color == [255, 255, 255] {
                    format!(
                        "{head}. {share} of the image is white ({hex}), and white is light: the \
                         palette makes it an emitter, so a sketch on a white background has no \
                         floor. Paint the floor in a colour the palette does not list (any such \
                         colour is floor, e.g. #c8c8c8), or make the background transparent"
                    )
                } else {
                    format!(
                        "{head}. {share} of the image is {hex}, which the palette makes an \
                         emitter (a lamp). Paint the floor in a colour the palette does not list \
                         (any such colour is floor)"
                    )
                }
            } else {
                format!(
                    "{head}. {share} of the image is {hex}, which the palette makes a wall. \
                     Paint the floor in a colour the palette does not list (any such colour is \
                     floor)"
                )
            }
        }
        _ if void > 0 => format!(
            "{head}. {} of the image is transparent (void); paint the floor opaque",
            percent(void, n)
        ),
        _ => format!("{head}."),
    }
}

/// Why nothing gives light: no colour matched the palette, no lamp colour
/// was painted, or the lamps face no free space.
fn no_light(level: &Level) -> String {
    let head = "the level has no emitter pixels facing free space: the lightmap is black";
    let lossy = level.lossy_format.map(|f| {
        format!(
            " The image is {f}, a lossy format: compression shifts colours, so walls and lamps \
             no longer match the palette exactly; save the level as PNG"
        )
    });
    let list = " (`flatbake palette` lists them)";
    let (per, _) = census(level);
    let solid = per.iter().any(|&n| n > 0);
    let emitters = level
        .materials
        .iter()
        .zip(&per)
        .filter(|(m, n)| m.kind == MaterialKind::Emitter && **n > 0)
        .count();
    match level.origin {
        Origin::Tiled if emitters == 0 => {
            return format!(
                "{head}. No tile or object of the map is an emitter{}. Add an object of class \
                 `light` (a point, rectangle or ellipse), or give a tile of the wall layer the \
                 custom property `flatbake` = `emitter`",
                if solid { "" } else { ", and none is a wall" }
            );
        }
        Origin::Ldtk if emitters == 0 => {
            return format!(
                "{head}. No IntGrid value or entity of the level is an emitter{}. Add an entity \
                 named `Light` or tagged `light`, name an IntGrid value `light`, or map an \
                 identifier to `emitter` in the level field `flatbake` (`Torch = emitter`)",
                if solid { "" } else { ", and none is a wall" }
            );
        }
        _ => {}
    }
    if !solid {
        format!(
            "{head}. No colour matched the palette: every pixel is floor or void, with no wall \
             and no lamp.{}",
            lossy.unwrap_or_else(|| format!(
                " Paint walls and lamps in the palette's exact colours{list}"
            ))
        )
    } else if emitters == 0 {
        format!(
            "{head}. No pixel has an emitter colour of the palette.{}",
            lossy.unwrap_or_else(|| format!(" Paint lamps in an emitter colour{list}"))
        )
    } else if level
        .materials
        .iter()
        .any(|m| m.kind == MaterialKind::Emitter && m.emits())
    {
        format!(
            "{head}. Every lamp is enclosed by walls or lies only on the image's border: no \
             emitter pixel touches floor or void"
        )
    } else {
        format!("{head}. The palette gives the level's emitter colours no emission")
    }
}
