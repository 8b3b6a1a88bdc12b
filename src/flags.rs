//! Flag values that clap's own parsers get wrong for people, and the
//! examples at the end of each subcommand's `--help`.
//!
//! Numeric flags accept negative numbers as values (clap's
//! `allow_negative_numbers`), so that `--bounces -1` reaches these parsers
//! and is refused with the flag's range, instead of clap's advice to write
//! `-- -1` (which would make `-1` a level path). Every message names the
//! flag, what it takes and what it got.

use flatbake_core::batch::Shard;

/// `--falloff`: a half-energy distance, or falloff switched off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FalloffArg {
    /// `none` or `off`: no falloff, whatever the palette says.
    Off,
    /// A half-energy distance in pixels (finite, positive).
    Pixels(f64),
}

impl FalloffArg {
    /// The library's falloff override: `None` for off, else the distance.
    pub fn distance(self) -> Option<f64> {
        match self {
            FalloffArg::Off => None,
            FalloffArg::Pixels(d) => Some(d),
        }
    }
}

/// `--falloff PIXELS|none`.
pub fn parse_falloff(s: &str) -> Result<FalloffArg, String> {
    let t = s.trim();
    if t.eq_ignore_ascii_case("none") || t.eq_ignore_ascii_case("off") {
        return Ok(FalloffArg::Off);
    }
    match t.parse::<f64>() {
        Ok(d) if d.is_finite() && d > 0.0 => Ok(FalloffArg::Pixels(d)),
        _ => Err(format!(
            "--falloff must be a positive number of pixels (the half-energy distance, such as 40), not {s}; `--falloff none` switches falloff off"
        )),
    }
}

/// `--occluder-tolerance PX`: 0 or more pixels.
pub fn parse_occluder_tolerance(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(d) if d.is_finite() && d >= 0.0 => Ok(d),
        _ => Err(format!(
            "--occluder-tolerance takes a number of pixels, 0 or more (such as 0.75), not {s}"
        )),
    }
}

/// A whole number from `lo` to `hi` for `flag`; `what` says what it counts.
fn whole_number(flag: &str, what: &str, lo: u64, hi: u64, s: &str) -> Result<u64, String> {
    match s.trim().parse::<u64>() {
        Ok(n) if (lo..=hi).contains(&n) => Ok(n),
        _ if hi == u64::MAX => Err(format!("{flag} takes {what}, {lo} or more, not {s}")),
        _ => Err(format!("{flag} takes {lo} to {hi} {what}, not {s}")),
    }
}

/// `--bounces N`: 0 to [`flatbake_core::bake::MAX_BOUNCES`].
pub fn parse_bounces(s: &str) -> Result<u32, String> {
    let max = u64::from(flatbake_core::bake::MAX_BOUNCES);
    let n = whole_number(
        "--bounces",
        "bounces of light (0 = direct light only)",
        0,
        max,
        s,
    )?;
    u32::try_from(n).map_err(|e| e.to_string())
}

/// `--jobs N`: 1 to [`crate::cli::MAX_JOBS`] worker threads.
pub fn parse_jobs(s: &str) -> Result<u16, String> {
    let n = whole_number(
        "--jobs",
        "worker threads",
        1,
        crate::cli::MAX_JOBS as u64,
        s,
    )?;
    u16::try_from(n).map_err(|e| e.to_string())
}

/// `--max-pixels N`: at least 1.
pub fn parse_max_pixels(s: &str) -> Result<u64, String> {
    whole_number(
        "--max-pixels",
        "a number of pixels per image",
        1,
        u64::MAX,
        s,
    )
}

/// The longest `--debounce`: an hour.
pub const MAX_DEBOUNCE_MS: u64 = 3_600_000;

/// `--debounce MS`: 0 to an hour, in milliseconds.
pub fn parse_debounce(s: &str) -> Result<u64, String> {
    whole_number("--debounce", "milliseconds", 0, MAX_DEBOUNCE_MS, s)
}

/// `--depth 8|16`.
pub fn parse_depth(s: &str) -> Result<u8, String> {
    match s.trim() {
        "8" => Ok(8),
        "16" => Ok(16),
        _ => Err(format!("the PNG depth is 8 or 16 bits, not {s}")),
    }
}

/// Largest `--padding`: wider than any mip chain an engine filters over.
pub const MAX_PADDING: u32 = 256;

/// `--padding N`: texels, 0 to [`MAX_PADDING`].
pub fn parse_padding(s: &str) -> Result<u32, String> {
    match s.trim().parse::<i64>() {
        Ok(n) if (0..=MAX_PADDING as i64).contains(&n) => Ok(n as u32),
        _ => Err(format!(
            "the padding is a whole number of texels from 0 to {MAX_PADDING} (8 covers bilinear filtering and 3 mip levels), not {s}"
        )),
    }
}

/// `--texels-per-pixel N`: a whole number or the inverse of one
/// ([`Density::parse`](flatbake_core::bake::Density::parse)).
pub fn parse_texels_per_pixel(s: &str) -> Result<flatbake_core::bake::Density, String> {
    flatbake_core::bake::Density::parse(s).map_err(|e| e.to_string())
}

/// `--texel-samples S`: 1 to [`MAX_SAMPLES`](flatbake_core::bake::texels::MAX_SAMPLES).
pub fn parse_texel_samples(s: &str) -> Result<u32, String> {
    let max = flatbake_core::bake::texels::MAX_SAMPLES;
    match s.trim().parse::<i64>() {
        Ok(n) if (1..=max as i64).contains(&n) => Ok(n as u32),
        _ => Err(format!(
            "the texel samples are a whole number of quadrature points per texel side from 1 to {max}, not {s}"
        )),
    }
}

/// `--shard K/N`.
pub fn parse_shard(s: &str) -> Result<Shard, String> {
    s.parse::<Shard>().map_err(|e| e.to_string())
}

/// The end of `flatbake bake --help`.
pub const BAKE_EXAMPLES: &str = "\
Examples:
  flatbake bake levels/                            # every level of the folder, into out/
  flatbake bake levels/dungeon.png --quality draft # one level, quickly
  flatbake bake levels/ --falloff none             # no falloff, whatever the palettes say
  flatbake bake levels/ -o game/ --quality high --layers --cache
  flatbake bake levels/ -o out/ --shard 2/3        # machine 2 of 3 bakes its third

Writes NAME.lightmap.png, NAME.lit.png, NAME.report.json and NAME.stamp.json per level,
and batch.json (batch-K-of-N.json with --shard) for the whole run.";

/// The end of `flatbake relight --help`.
pub const RELIGHT_EXAMPLES: &str = "\
Examples:
  flatbake bake levels/ -o game/ --cache           # first a bake that writes NAME.flatbake
  flatbake relight game/dungeon.flatbake --emission \"#ff9a2a=10,6,2\" -o game/night/
  flatbake relight game/dungeon.flatbake --emission \"#60d8ff=0\" --layers -o game/dark/";

/// The end of `flatbake watch --help`.
pub const WATCH_EXAMPLES: &str = "\
Examples:
  flatbake watch levels/ -o preview/ --quality draft  # re-bake on every save, until Ctrl-C";

/// The end of `flatbake palette --help`.
pub const PALETTE_EXAMPLES: &str = "\
Examples:
  flatbake palette                                  # the built-in palette as a table
  flatbake palette levels/dungeon.png               # the palette dungeon gets: each colour's source, groups, [bake]
  flatbake palette --palette levels/dungeon.palette.toml
  flatbake palette --toml start.palette.toml        # the built-in palette as a commented file to start from
  flatbake palette --legend legend.png              # the built-in palette drawn as an image";

/// The end of `flatbake sweep --help`.
pub const SWEEP_EXAMPLES: &str = "\
Examples:
  flatbake sweep levels/ -o sweep/                  # accuracy.csv, accuracy.md, accuracy.png";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn falloff_none_and_off_switch_it_off_and_bad_numbers_say_how() {
        assert_eq!(parse_falloff("none"), Ok(FalloffArg::Off));
        assert_eq!(parse_falloff("OFF"), Ok(FalloffArg::Off));
        assert_eq!(parse_falloff("40"), Ok(FalloffArg::Pixels(40.0)));
        for bad in ["0", "-3", "nan", "inf", "forty", ""] {
            let e = parse_falloff(bad).unwrap_err();
            assert!(e.contains("--falloff none"), "{bad}: {e}");
        }
    }

    #[test]
    fn whole_numbers_outside_their_range_name_the_range() {
        assert_eq!(parse_bounces("0"), Ok(0));
        assert_eq!(parse_bounces("1000"), Ok(1000));
        for bad in ["-1", "1001", "4294967296", "two", "1.5"] {
            let e = parse_bounces(bad).unwrap_err();
            assert!(e.starts_with("--bounces takes 0 to 1000"), "{e}");
        }
        assert!(parse_jobs("0").is_err() && parse_jobs("513").is_err());
        assert_eq!(parse_jobs("512"), Ok(512));
        assert!(parse_max_pixels("0").is_err());
        assert_eq!(parse_debounce("0"), Ok(0));
        assert!(parse_debounce("-5").unwrap_err().contains("milliseconds"));
    }
}
