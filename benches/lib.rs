//! Nothing here: the benchmarks are `bake.rs` (`cargo bench -p flatbake-benches`).
