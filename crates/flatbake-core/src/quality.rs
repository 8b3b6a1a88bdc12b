//! Quality presets: how much accuracy a bake pays for.
//!
//! Every preset computes direct light exactly (closed-form visible angles)
//! at the pixels it gathers; the presets differ in how finely the
//! reflected light is resolved, and `draft` and `normal` also in which
//! pixels they gather (interpolating where the light is smooth) and over
//! which edges (block sweeps): see docs/transport.md, Quality knobs.

use serde::{Deserialize, Serialize};

/// A named quality preset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Quality {
    /// Preview while painting.
    Draft,
    /// Daily bakes.
    Normal,
    /// Shipping.
    High,
    /// Converged: the yardstick the others are measured against.
    Reference,
}

/// The discretisation knobs a preset sets.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Knobs {
    /// Longest patch, in pixels.
    pub patch_len: f64,
    /// Longest patch as a multiple of its edge's clearance, the free
    /// distance in front of the edge ([`crate::transport::clearance`]):
    /// in a corridor one or two pixels wide, light crosses from wall to wall
    /// over a distance far shorter than `patch_len`, and a patch as long as
    /// `patch_len` averages away the light along it. `None`: `patch_len`
    /// alone.
    #[serde(default)]
    pub per_clearance: Option<f64>,
    /// Gauss-Legendre points for the form factors per patch of the full
    /// length; shorter patches may take fewer
    /// ([`Patches::points`](crate::transport::Patches::points)).
    pub quad: usize,
    /// Relative residual the solver must reach.
    pub tolerance: f64,
    /// With falloff: pixels and patches whose distance to an emitting or
    /// reflecting edge makes its largest possible contribution smaller than
    /// this fraction of the level's brightest emission are not gathered.
    /// With or without: the share of a patch's form-factor row that the
    /// smallest entries left out of it may carry, their part shared by the
    /// rest ([`crate::transport::form_factors`]).
    pub reach_bound: f64,
    /// Relative tolerance of the interpolated gather ([`crate::gather::lattice`]):
    /// floor light is gathered exactly at probe pixels of 8 and 4 px cells and
    /// interpolated in between where the probes show it is smooth to within
    /// this fraction. `None`: every floor pixel is gathered exactly.
    pub lattice: Option<f64>,
    /// Block sweeps: a pixel whose full visibility query would walk the
    /// level's blocks is swept over what the anchor pixels this many pixels
    /// apart around it see ([`crate::gather::GatherOptions::anchors`]; the
    /// lattice's pixels too). `None`: a full query at every pixel.
    #[serde(default)]
    pub anchors: Option<i32>,
    /// Which pixels block sweeps take: `true` (`draft`), every pixel the
    /// gather asks for that is not an anchor, over the lists of its block's
    /// corners; `false`, only the pixels whose full query would walk the
    /// level, over the lists of the block's corners and of the ring of
    /// anchors around it ([`crate::gather::GatherOptions::sweep_every`]).
    #[serde(default)]
    pub sweep_every: bool,
    /// `draft`: after the lattice's tested cells, every 2 px cell of floor
    /// in one free region that they left is gathered at its corners and
    /// interpolated where those agree within
    /// [`crate::gather::lattice::SPREAD`] ([`crate::gather::GatherOptions::coarse`]):
    /// about one pixel in four is gathered there, and a shadow line between
    /// two gathered pixels that changes neither by more than that is
    /// blurred over the two pixels.
    #[serde(default)]
    pub coarse: bool,
    /// Block sweeps' far reflected light: a swept pixel takes the light
    /// that walls reflect to it from beyond this many pixels from the
    /// anchors at its block's corners, interpolated, and sweeps only the
    /// edges that can matter otherwise (those within this distance of its
    /// block, the lights, and what may hide a light from it), where that
    /// leaves out enough of its list, else its whole list
    /// ([`crate::gather::GatherOptions::far`]);
    /// a pixel beside a wall takes it from the corners of its block too,
    /// and its full query goes past this distance only towards lights.
    /// Direct light stays exact, but on a level of many lights that is not
    /// dense, where a swept pixel's list holds more than
    /// [`crate::gather::FAR_LAMPS`] of them: there it takes all its light
    /// from beyond [`crate::gather::LAMP_FAR`] px from its block's
    /// corners, the lights' too, where that is at most
    /// [`crate::gather::LAMP_SHARE`] of each corner's light. `None`: every swept pixel sweeps its
    /// whole list, and every full query wants all the light.
    #[serde(default)]
    pub far: Option<f64>,
}

/// The lattice tolerance of `draft` (see [`Knobs::lattice`]).
pub const DRAFT_LATTICE: f64 = 0.02;

/// The lattice tolerance of `normal` (see [`Knobs::lattice`]).
pub const NORMAL_LATTICE: f64 = 0.01;

/// The anchor spacing of `draft` (see [`Knobs::anchors`]): twice
/// `normal`'s [`crate::gather::lattice::ANCHOR`]. With `draft`'s 2 px cells
/// ([`Knobs::coarse`]), anchors 4 px apart cost its real maps 5-10 % more
/// time at the same error.
pub const DRAFT_ANCHORS: i32 = 8;

/// The distance beyond which `normal` takes a swept pixel's reflected
/// light from its block's corners (see [`Knobs::far`]). On the pillar
/// field at 512 px: 32.0 -> 17.3 s, 0.39 % relative RMS over the floor
/// from the exact `normal` gather. 16 px saved 3 % more time for twice
/// the error (measured before the scaling by the open angle).
pub const NORMAL_FAR: f64 = 32.0;

/// `draft`'s [`Knobs::far`]: on the shooter map 4 % less time than 32 px,
/// for twice the error (0.95 % from the exact `draft` gather against
/// 0.44 %, over all pixels, before the scaling by the open angle).
pub const DRAFT_FAR: f64 = 16.0;

impl Quality {
    /// Every preset, cheapest first.
    pub const ALL: [Quality; 4] = [
        Quality::Draft,
        Quality::Normal,
        Quality::High,
        Quality::Reference,
    ];

    /// The numeric knobs behind the preset.
    pub fn knobs(self) -> Knobs {
        match self {
            Quality::Draft => Knobs {
                patch_len: 8.0,
                per_clearance: Some(3.0),
                quad: 2,
                tolerance: 1e-4,
                reach_bound: 1e-4,
                lattice: Some(DRAFT_LATTICE),
                anchors: Some(DRAFT_ANCHORS),
                sweep_every: true,
                coarse: true,
                far: Some(DRAFT_FAR),
            },
            Quality::Normal => Knobs {
                patch_len: 4.0,
                per_clearance: Some(1.5),
                quad: 3,
                tolerance: 1e-6,
                reach_bound: 1e-5,
                lattice: Some(NORMAL_LATTICE),
                anchors: Some(crate::gather::lattice::ANCHOR),
                sweep_every: false,
                coarse: false,
                far: Some(NORMAL_FAR),
            },
            Quality::High => Knobs {
                patch_len: 2.0,
                per_clearance: Some(1.0),
                quad: 4,
                tolerance: 1e-8,
                reach_bound: 1e-6,
                lattice: None,
                anchors: None,
                sweep_every: false,
                coarse: false,
                far: None,
            },
            Quality::Reference => Knobs {
                patch_len: 0.5,
                per_clearance: None,
                quad: 8,
                tolerance: 1e-10,
                reach_bound: 0.0,
                lattice: None,
                anchors: None,
                sweep_every: false,
                coarse: false,
                far: None,
            },
        }
    }

    /// The preset's name, as on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Quality::Draft => "draft",
            Quality::Normal => "normal",
            Quality::High => "high",
            Quality::Reference => "reference",
        }
    }
}

impl std::fmt::Display for Quality {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
