//! Prints every texel of a lightmap EXR and PNG as the `image` crate reads
//! them, in the line format of docs/engine-check/dump.gd ("KIND x y r g b
//! a"), so that what Godot reads can be compared with flatbake's values:
//!
//! ```text
//! cargo run --release --example engine_check -- exr FILE.exr png FILE.png
//! ```
//!
//! Used by docs/engine-check/check.sh.

use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        let [kind, path] = pair else {
            eprintln!("engine_check: arguments come in pairs: exr FILE png FILE");
            return ExitCode::from(2);
        };
        let img = match image::open(path) {
            Ok(img) => img,
            Err(e) => {
                eprintln!("engine_check: cannot read {path}: {e}");
                return ExitCode::FAILURE;
            }
        };
        match kind.as_str() {
            "exr" => {
                for (x, y, p) in img.into_rgba32f().enumerate_pixels() {
                    let [r, g, b, a] = p.0;
                    println!("exr {x} {y} {r:.9} {g:.9} {b:.9} {a:.9}");
                }
            }
            "png" => {
                for (x, y, p) in img.into_rgba8().enumerate_pixels() {
                    let [r, g, b, a] = p.0;
                    println!("png {x} {y} {r} {g} {b} {a}");
                }
            }
            other => {
                eprintln!("engine_check: {other} is not exr or png");
                return ExitCode::from(2);
            }
        }
    }
    ExitCode::SUCCESS
}
