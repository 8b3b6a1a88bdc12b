//! Engine presets: which lightmap files, encodings and padding suit a game
//! engine's importer, so that one choice (`--engine godot`) writes files the
//! engine takes as they are. A preset only turns outputs on; options given
//! beside it add to it.

use super::{Depth, ExrCompression};

/// A game engine whose importer the outputs are chosen for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    /// Godot 4: the linear ZIP EXR (imported as an HDR texture), padded.
    Godot,
    /// Unity: Unity-convention RGBM (range 5, gamma) and the ZIP EXR, padded.
    Unity,
    /// Bevy: the RGBA16F KTX2 (Bevy's `ktx2` feature) and the ZIP EXR, padded.
    Bevy,
    /// Any engine: 16-bit sRGB PNGs and the uncompressed linear EXR, padded.
    Generic,
}

/// What a preset writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EngineOutputs {
    /// `NAME.lightmap.exr`.
    pub hdr: bool,
    /// `NAME.lightmap.rgbm.png` (linear, range 6).
    pub rgbm: bool,
    /// `NAME.lightmap.rgbm-unity.png` (range 5, gamma).
    pub rgbm_unity: bool,
    /// Bits per channel of the PNGs.
    pub depth: Depth,
    /// Padding in texels (see [`super::padding`]).
    pub padding: u32,
    /// `NAME.lightmap.ktx2` (RGBA 16-bit float).
    pub ktx2: bool,
    /// Compression of the EXR outputs.
    pub exr_compression: ExrCompression,
}

impl Engine {
    /// Every preset, in the order the help lists them.
    pub const ALL: [Engine; 4] = [Engine::Godot, Engine::Unity, Engine::Bevy, Engine::Generic];

    /// The preset's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Engine::Godot => "godot",
            Engine::Unity => "unity",
            Engine::Bevy => "bevy",
            Engine::Generic => "generic",
        }
    }

    /// The outputs this preset turns on. Every preset pads by
    /// [`super::padding::SUGGESTED_PADDING`] texels; the engine presets
    /// compress the EXR with ZIP (which Godot, Unity and Bevy import),
    /// `generic` leaves it uncompressed for the simplest readers.
    pub fn outputs(self) -> EngineOutputs {
        let base = EngineOutputs {
            hdr: true,
            rgbm: false,
            rgbm_unity: false,
            depth: Depth::Eight,
            padding: super::padding::SUGGESTED_PADDING,
            ktx2: false,
            exr_compression: ExrCompression::Zip,
        };
        match self {
            Engine::Godot => base,
            Engine::Bevy => EngineOutputs { ktx2: true, ..base },
            Engine::Unity => EngineOutputs {
                rgbm_unity: true,
                ..base
            },
            Engine::Generic => EngineOutputs {
                depth: Depth::Sixteen,
                exr_compression: ExrCompression::None,
                ..base
            },
        }
    }
}
