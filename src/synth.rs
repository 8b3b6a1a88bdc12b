//! Procedural levels for samples, benchmarks and tests.
