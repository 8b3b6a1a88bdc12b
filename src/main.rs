//! The `flatbake` binary: the command line over the `flatbake-core` library.

mod cli;
mod legend;
mod plot;
mod watch;

fn main() -> std::process::ExitCode {
    cli::main()
}
