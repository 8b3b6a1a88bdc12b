//! Checks that light layers add up to a lightmap: reads a lightmap EXR and
//! any number of layer EXRs, and prints the largest absolute and relative
//! difference between the lightmap and the sum of the layers.
//!
//! `cargo run --release --example layer_sum_check -- out/L.lightmap.exr out/L.layer-*.exr`

use flatbake_core::output::read_lightmap_exr;

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let full = args
        .next()
        .ok_or("usage: layer_sum_check LIGHTMAP.exr LAYER.exr...")?;
    let (_, _, f) = read_lightmap_exr(full.as_ref()).map_err(|e| e.to_string())?;
    let mut sum = vec![[0f32; 3]; f.len()];
    for layer in args {
        let (_, _, v) = read_lightmap_exr(layer.as_ref()).map_err(|e| e.to_string())?;
        if v.len() != f.len() {
            return Err(format!("{layer} has another size than {full}"));
        }
        for (s, x) in sum.iter_mut().zip(&v) {
            for c in 0..3 {
                s[c] += x[c];
            }
        }
    }
    let max = f.iter().flatten().fold(0f64, |m, &v| m.max(v as f64));
    let (mut abs, mut rel) = (0f64, 0f64);
    for (x, s) in f.iter().zip(&sum) {
        for c in 0..3 {
            let e = (x[c] as f64 - s[c] as f64).abs();
            abs = abs.max(e);
            // Relative error only where there is light worth speaking of:
            // at least 1% of the brightest value.
            if x[c] as f64 > 0.01 * max {
                rel = rel.max(e / x[c] as f64);
            }
        }
    }
    println!(
        "max abs difference {abs:e} (brightest value {max}); max relative difference where above 1% of it: {rel:e}"
    );
    Ok(())
}
