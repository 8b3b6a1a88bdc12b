//! Arbitrary bytes as a relight cache (`NAME.flatbake`), relit.
//!
//! Input: one flag byte, then the bytes. Flag bit 0 set: the bytes are the
//! payload, wrapped in a valid header and checksum (so the fuzzer reaches
//! the decoder and the cross-checks instead of stopping at the checksum);
//! clear: the bytes are the whole file. Bit 1: write the light layers too.
//! The EXR lightmap is always written, and read back to check its values.
//!
//! Every input must be refused with a message naming the cache or an output
//! file, or relit into lightmaps whose values are finite and >= 0.
#![no_main]

use libfuzzer_sys::fuzz_target;

use flatbake_core::batch::relight::{RelightOptions, relight};
use flatbake_core::output::cache::{FORMAT, MAGIC, VERSION};
use flatbake_core::output::read_lightmap_exr;

fuzz_target!(|data: &[u8]| {
    let Some((&flags, bytes)) = data.split_first() else {
        return;
    };
    let file = if flags & 1 == 1 {
        let mut f = Vec::with_capacity(bytes.len() + 64);
        f.extend_from_slice(MAGIC);
        f.extend_from_slice(&FORMAT.to_le_bytes());
        f.extend_from_slice(&(VERSION.len() as u32).to_le_bytes());
        f.extend_from_slice(VERSION.as_bytes());
        f.extend_from_slice(blake3::hash(bytes).as_bytes());
        f.extend_from_slice(bytes);
        f
    } else {
        bytes.to_vec()
    };
    let dir = std::env::temp_dir().join(format!("flatbake-fuzz-relight-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    if std::fs::create_dir_all(&dir).is_err() {
        return;
    }
    let cache = dir.join("fuzz.flatbake");
    if std::fs::write(&cache, &file).is_err() {
        return;
    }
    let out = dir.join("relit");
    let opts = RelightOptions {
        out_dir: out.clone(),
        layers: flags & 2 != 0,
        hdr: true,
        ..RelightOptions::default()
    };
    match relight(&cache, &opts) {
        Ok(report) => {
            // The files are named after the cache's level name, which a
            // damaged cache need not share with its report.
            let exr = report
                .outputs
                .iter()
                .find(|f| f.ends_with(".lightmap.exr"))
                .map(|f| out.join(f))
                .expect("the relight lists its EXR lightmap");
            let (_, _, px) = read_lightmap_exr(&exr).expect("the relit EXR reads back");
            for p in &px {
                for v in p {
                    assert!(v.is_finite() && *v >= 0.0, "light {v}");
                }
            }
            // Nothing is written outside the output folder.
            for f in &report.outputs {
                let p = out.join(f);
                assert!(
                    p.parent() == Some(out.as_path()) && p.is_file(),
                    "output {f:?} outside {}",
                    out.display()
                );
            }
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.contains(&cache.display().to_string()) || msg.contains(&out.display().to_string()),
                "{msg}"
            );
        }
    }
});
