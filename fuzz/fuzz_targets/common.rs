//! Checks shared by the fuzz targets: what must hold for any baked level.

use flatbake_core::bake::{BakeError, Settings, bake};
use flatbake_core::level::Level;
use flatbake_core::quality::Quality;

/// Traces and bakes `level` (draft quality) and panics on anything that
/// must never happen: NaN, negative light, energy that does not balance.
pub fn bake_and_check(level: &Level, falloff: Option<f64>, paper: bool) {
    let g = flatbake_core::geometry::trace(level);
    for e in &g.edges {
        assert!(e.len() > 0.0, "empty edge {e:?}");
    }
    let mut s = Settings::new(Quality::Draft);
    s.falloff = falloff;
    if paper {
        s.kernel = flatbake_core::gather::Kernel::Paper;
    }
    let baked = match bake(level, &s, &|_| {}) {
        Ok(b) => b,
        Err(e @ BakeError::Unbounded { .. }) => {
            assert!(e.to_string().contains("reflectance 1"), "{e}");
            return;
        }
        Err(e) => panic!("bake failed: {e}"),
    };
    for px in &baked.lightmap.rgb {
        for v in px {
            assert!(v.is_finite() && *v >= 0.0, "light {v}");
        }
    }
    assert!(
        !baked.report.warnings.iter().any(|w| w.contains("clamped")),
        "{:?}",
        baked.report.warnings
    );
    for ch in &baked.radiosity {
        for b in ch {
            assert!(b.is_finite() && *b >= 0.0, "radiosity {b}");
        }
    }
    if !paper {
        let e = &baked.report.energy;
        let gap = (e.emitted - e.absorbed - e.escaped).abs();
        // Within the preset's solver tolerance: falloff culling (pairs below
        // the preset's reach bound) may break exact balance by about that much.
        let tol = s.knobs.tolerance;
        assert!(
            gap <= tol * e.emitted.max(1e-300) || gap < 1e-250,
            "energy {e:?}, gap {:e} above the tolerance {tol:e}",
            gap / e.emitted
        );
    }
}
