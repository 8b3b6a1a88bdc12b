//! The `flatbake` binary: the command line over the `flatbake-core` library.

mod cli;
mod flags;
mod legend;
mod plot;
mod shard;
mod watch;

fn main() -> std::process::ExitCode {
    cli::main()
}
