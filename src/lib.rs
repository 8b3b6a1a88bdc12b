//! flatbake: baked 2D ("flatland") radiosity lightmaps for top-down levels
//! painted as bitmaps.
//!
//! The pipeline, one module per stage, each with a resolved boundary:
//! [`palette`] + [`level`] turn an image into a resolved [`level::Level`];
//! [`geometry`] traces its walls into edges; [`transport`] cuts edges into
//! patches and computes the form factors with exact visibility
//! ([`visibility`]) and closed-form integrals ([`kernel`]); [`solve`] finds
//! the radiosity per channel; [`gather`] lights every floor pixel; [`output`]
//! writes the results. [`bake`] runs the stages for one level and decides
//! what a scene does not need.

// Numeric kernels index several parallel arrays by channel or patch.
#![allow(clippy::needless_range_loop)]

pub mod bake;
pub mod batch;
pub mod cache;
pub mod cli;
pub mod gather;
pub mod geometry;
pub mod kernel;
pub mod layers;
pub mod legend;
pub mod level;
pub mod marks;
pub mod material;
pub mod output;
pub mod palette;
pub mod paper;
pub mod quality;
pub mod report;
pub mod solve;
pub mod stamp;
pub mod sweep;
pub mod synth;
pub mod transport;
pub mod visibility;
pub mod watch;
