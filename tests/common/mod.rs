//! Helpers shared by the integration tests: levels from ASCII art, the
//! command-line runner and its fixtures, and proptest strategies. Each test
//! file is its own crate and uses only some of them.
#![allow(dead_code, unused_imports)]

mod cli;
mod levels;
mod strategies;

pub use cli::*;
pub use levels::*;
pub use strategies::*;
