//! Between planning and the form factors: an estimate of the bake's peak
//! memory, so that a level that would exhaust the machine is refused up
//! front with the estimate and the flag that overrides it, instead of
//! growing until the system kills the whole batch.
//!
//! What grows with a level (docs/robustness.md#memory):
//! - per pixel: the level, the lightmap and the gather's per-pixel arrays,
//!   measured at about 80 bytes per pixel on the 2048 px benchmark and 75
//!   on the 8192 px one (a few large rooms, where the gather arrays
//!   dominate); counted as [`PER_PIXEL`];
//! - per edge: the traced edges, their tiles and blocks and the candidate
//!   lists that name them, measured at about 205 bytes per edge on a
//!   2048 px checkerboard of one-pixel walls (8.25 million edges, 1.95 GB);
//!   counted as [`PER_EDGE`];
//! - per patch: materials, radiosity, solver vectors, slopes and the patch
//!   tree; counted as [`PER_PATCH`];
//! - per entry of the patches' merged form-factor rows (a patch and a patch
//!   that some quadrature point of it sees, less its slivers): 16 bytes in
//!   the merged rows (patch, `F0`, the slope rows' `G` in single
//!   precision), which become the symmetric matrix's pattern: a pair that
//!   only one row holds is added to the other row (8 bytes each while they
//!   are found, then 16; at most one per merged entry, 0.4 per merged
//!   entry on a level of one-pixel dots). The rows are then split into one
//!   table, 16 bytes per entry of the matrix (column, `S` built in place
//!   in `F0`'s values, `G`), the merged rows freed as they are copied and
//!   handed back to the system; the solver reads the matrix in place. The
//!   points' own rows are merged as soon as each patch's last point is
//!   visited, so they are never all kept. At most 32 bytes per merged
//!   entry; counted at 36 for a margin as [`PER_FACTOR_ENTRY`], and
//!   estimated from the exact visibility of a sample of patches, slivers
//!   left out as the form factors leave them out
//!   ([`transport::estimate_entries`]);
//! - the dense fallback solve of systems up to the solver's fallback size,
//!   8 bytes per matrix entry;
//! - per-emitter responses (light layers, relight caches): 12 bytes per
//!   pixel per emitter material and reflectance class;
//! - directional moments ([`super::Settings::directional`]): per pixel 32
//!   bytes per gathered component (two f64 moments, and draft's copy) and
//!   24 for the moments kept, and 8 more per response.

use super::{Ctx, Plan, Scene, factors};
use crate::gather::Kernel;
use crate::transport::kernel::Reach;
use crate::transport::{self, solve::SolveSettings};
use crate::visibility::Structures;

/// Bytes per level pixel outside the form factors (see the module docs).
pub const PER_PIXEL: u64 = 100;
/// Bytes per patch outside the form factors (see the module docs).
pub const PER_PATCH: u64 = 200;
/// Bytes per entry of the patches' merged form-factor rows, with the slope
/// rows and the matrix built from them.
pub const PER_FACTOR_ENTRY: u64 = 36;
/// Bytes per traced edge (see the module docs).
pub const PER_EDGE: u64 = 220;
/// What every bake needs whatever its size: threads, tables, buffers.
pub const BASE: u64 = 64 << 20;
/// Patches whose visibility is sampled for the estimate.
pub const SAMPLED_PATCHES: usize = 256;

/// A bake's estimated peak memory, and what it is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// The estimate, in bytes.
    pub bytes: u64,
    /// Level pixels.
    pub pixels: u64,
    /// Estimated entries of the patches' merged form-factor rows (0 when
    /// no bounce is solved).
    pub factor_entries: u64,
}

impl MemoryEstimate {
    /// The estimate for baking `scene` as planned.
    pub fn new(ctx: &Ctx, scene: &Scene, plan: &Plan, structures: &Structures) -> MemoryEstimate {
        let level = ctx.level;
        let pixels = (level.width as u64) * (level.height as u64);
        let n = scene.patch_count() as u64;
        let edges = scene.geometry.edges.len() as u64;
        let factor_entries = if plan.needs_form_factors() {
            // The paper kernel stores one entry per visible patch pair, with
            // no reach bound: the same count at one point per patch.
            let (quad, bound, reach) = match ctx.settings.kernel {
                Kernel::Flatland => (
                    ctx.settings.knobs.quad,
                    ctx.reach_bound,
                    factors::unit_reach(ctx, &scene.geometry),
                ),
                Kernel::Paper => (1, 0.0, Reach::unlimited(scene.geometry.edges.len())),
            };
            transport::estimate_entries(
                structures,
                &scene.patches,
                quad,
                ctx.falloff,
                &reach,
                bound,
                SAMPLED_PATCHES,
            )
        } else {
            0
        };
        let dense =
            if plan.needs_form_factors() && n as usize <= SolveSettings::default().fallback_max {
                n * n * 8
            } else {
                0
            };
        let responses = plan.responses.as_ref().map_or(0, |rp| {
            (rp.emitters.len() as u64) * (rp.rho_reps.len() as u64) * pixels * 12
        });
        let directional = if ctx.settings.directional {
            let traced = plan
                .responses
                .as_ref()
                .map_or(0, |rp| (rp.emitters.len() * rp.rho_reps.len()) as u64);
            let components = plan.channels.classes.len() as u64 + traced;
            pixels.saturating_mul(32 * components + 24 + 8 * traced)
        } else {
            0
        };
        let bytes = BASE
            .saturating_add(pixels.saturating_mul(PER_PIXEL))
            .saturating_add(directional)
            .saturating_add(edges.saturating_mul(PER_EDGE))
            .saturating_add(n.saturating_mul(PER_PATCH))
            .saturating_add(factor_entries.saturating_mul(PER_FACTOR_ENTRY))
            .saturating_add(dense)
            .saturating_add(responses);
        MemoryEstimate {
            bytes,
            pixels,
            factor_entries,
        }
    }
}

/// `bytes` for people: "812 MB", "24.1 GB" (powers of 1000, as `--max-memory`
/// reads them).
pub fn human_bytes(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.0} MB", b / 1e6)
    } else {
        format!("{:.0} kB", b / 1e3)
    }
}

/// The `--max-memory` value that would admit `bytes`: whole gigabytes,
/// rounded up ("25G").
pub fn flag_value_for(bytes: u64) -> String {
    format!("{}G", bytes.div_ceil(1_000_000_000).max(1))
}

/// The memory this machine has free for a bake: `MemAvailable` of
/// `/proc/meminfo` (Linux), or `None` where that cannot be read.
pub fn available() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_meminfo_available(&info)
}

/// `MemAvailable` of a `/proc/meminfo` text, in bytes.
fn parse_meminfo_available(info: &str) -> Option<u64> {
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kb.checked_mul(1024)
}

/// Reads a memory size as `--max-memory` spells it: bytes, or a number with
/// `K`, `M`, `G` or `T` (powers of 1000) or `KiB`, `MiB`, `GiB`, `TiB`
/// (powers of 1024), with an optional `B`: "24G", "1.5GB", "512MiB".
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let not_a_size = || format!("`{s}` is not a memory size (e.g. 16G, 512M, 2000000000)");
    let x: f64 = num.parse().map_err(|_| not_a_size())?;
    let unit = unit.trim().to_ascii_lowercase();
    let scale: f64 = match unit.trim_end_matches('b') {
        "" => 1.0,
        "k" => 1e3,
        "m" => 1e6,
        "g" => 1e9,
        "t" => 1e12,
        "ki" => 1024.0,
        "mi" => 1024.0 * 1024.0,
        "gi" => 1024.0 * 1024.0 * 1024.0,
        "ti" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        _ => {
            return Err(format!(
                "unknown unit in `{s}`: use a number of bytes or K, M, G, T (e.g. 16G)"
            ));
        }
    };
    let bytes = x * scale;
    if !(1.0..1.8e19).contains(&bytes) {
        return Err(format!(
            "`{s}` is not a usable memory size: give at least 1 byte (e.g. 16G)"
        ));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_in_both_unit_systems() {
        assert_eq!(parse_size("24G"), Ok(24_000_000_000));
        assert_eq!(parse_size("1.5GB"), Ok(1_500_000_000));
        assert_eq!(parse_size("512MiB"), Ok(512 << 20));
        assert_eq!(parse_size("2000"), Ok(2000));
        assert!(parse_size("12X").unwrap_err().contains("unknown unit"));
        assert!(parse_size("G").is_err());
        assert!(parse_size("0").is_err());
        assert!(parse_size("-1G").is_err());
    }

    #[test]
    fn meminfo_available_is_read_in_bytes() {
        let info = "MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   20000000 kB\n";
        assert_eq!(parse_meminfo_available(info), Some(20_000_000 * 1024));
        assert_eq!(parse_meminfo_available("MemTotal: 1 kB\n"), None);
    }

    #[test]
    fn flag_values_round_up_to_whole_gigabytes() {
        assert_eq!(flag_value_for(24_100_000_000), "25G");
        assert_eq!(flag_value_for(1), "1G");
        assert_eq!(human_bytes(24_100_000_000), "24.1 GB");
        assert_eq!(human_bytes(812_000_000), "812 MB");
    }
}
