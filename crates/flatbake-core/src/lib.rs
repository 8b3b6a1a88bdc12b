//! flatbake: baked 2D ("flatland") radiosity lightmaps for top-down levels
//! painted as bitmaps.
//!
//! The pipeline, one module per stage, each with a resolved boundary:
//! [`level`] turns an image and its palette into a resolved [`level::Level`];
//! [`geometry`] traces its walls into edges; [`transport`] cuts edges into
//! patches and computes the form factors with exact visibility
//! ([`visibility`]) and closed-form integrals ([`transport::kernel`]), and
//! solves the radiosity per channel ([`transport::solve`]); [`gather`] lights
//! every floor pixel; [`output`] writes the results. [`bake`] runs the stages
//! for one level and decides what a scene does not need; [`batch`] bakes
//! folders of levels incrementally.

// Numeric kernels index several parallel arrays by channel or patch.
#![allow(clippy::needless_range_loop)]

pub mod accuracy;
pub mod bake;
pub mod batch;
pub mod gather;
pub mod geometry;
pub mod level;
pub mod output;
pub mod quality;
pub mod transport;
pub mod visibility;
