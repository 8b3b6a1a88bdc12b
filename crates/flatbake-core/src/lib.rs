//! flatbake: baked 2D ("flatland") radiosity lightmaps for top-down levels
//! painted as bitmaps.
//!
//! A level designer paints walls, coloured lights and floor into an image; a
//! palette says which colour is which material. flatbake traces the walls
//! into line segments, solves how light bounces between them (per RGB
//! channel), and gathers the light of every floor pixel into a lightmap.
//!
//! # Baking a level in memory
//!
//! A game editor plugin, or a game that bakes procedurally generated levels
//! at load time, needs no files: build a [`Level`] from pixels and a
//! [`Palette`], [`bake`](fn@bake) it, and read the [`Lightmap`].
//!
//! ```
//! use flatbake_core::{Level, Palette, Quality, Settings, bake};
//!
//! // A 16 x 10 room: grey walls, a white lamp in the top wall, floor inside.
//! let (w, h) = (16, 10);
//! let mut rgba = vec![[180, 170, 150, 255]; w * h];
//! for y in 0..h {
//!     for x in 0..w {
//!         if x == 0 || y == 0 || x == w - 1 || y == h - 1 {
//!             rgba[y * w + x] = [90, 90, 90, 255];
//!         }
//!     }
//! }
//! for x in 6..10 {
//!     rgba[x] = [255, 255, 255, 255];
//! }
//! let palette = Palette::parse(
//!     r##"
//!     [[wall]]
//!     color = "#5a5a5a"
//!     reflectance = 0.5
//!
//!     [[emitter]]
//!     color = "#ffffff"
//!     emission = 2.0
//!     "##,
//!     "room.palette.toml".as_ref(),
//! )?;
//! let level = Level::from_rgba("room", w, h, &rgba, &palette);
//! let baked = bake(&level, &Settings::new(Quality::Draft), &|_stage| {})?;
//!
//! // Linear light per pixel, row-major: brighter under the lamp than in the
//! // far corner, and never negative.
//! let light = |x: usize, y: usize| baked.lightmap.rgb[y * w + x][0];
//! assert!(light(8, 1) > light(1, 8) && light(1, 8) > 0.0);
//! assert_eq!(baked.report.solves, 1); // a grey scene: one solve for R, G, B
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! To bake files the way the `flatbake` command does — folders of images,
//! palettes looked up beside them, incremental stamps, every output written
//! atomically — use [`batch::run`] with [`BatchOptions`]; [`output`] encodes
//! and writes a lightmap on its own.
//!
//! # The pipeline
//!
//! One folder per stage, each with a resolved boundary (see
//! `docs/ARCHITECTURE.md` in the repository):
//! [`level`] turns an image and its palette into a resolved [`Level`];
//! [`geometry`] traces its walls into edges; [`transport`] cuts edges into
//! patches, computes the form factors with exact visibility ([`visibility`])
//! and closed-form integrals, and solves the radiosity per channel;
//! [`gather`] lights every floor pixel; [`bake`](mod@bake) runs the stages
//! for one level and decides what a scene does not need; [`output`] writes
//! the results; [`batch`] bakes folders of levels incrementally and relights
//! caches; [`accuracy`] measures the price of accuracy.

// Numeric kernels index several parallel arrays by channel or patch.
#![allow(clippy::needless_range_loop)]
#![warn(missing_docs)]

pub mod accuracy;
pub mod bake;
pub mod batch;
pub mod error;
pub mod gather;
pub mod geometry;
pub mod level;
pub mod output;
pub mod quality;
pub mod transport;
pub mod visibility;

pub use bake::{BakeError, Baked, GatherMethod, Lightmap, Report, Responses, Settings, bake};
pub use batch::{BatchOptions, LevelOutcome, Observer};
pub use error::{Error, Result};
pub use gather::Kernel;
pub use level::material::{Material, MaterialKind};
pub use level::palette::{Palette, PaletteError};
pub use level::{Cell, Level, LevelError, LoadLimits, load_level};
pub use output::{Depth, OutputError, OutputOptions};
pub use quality::{Knobs, Quality};
