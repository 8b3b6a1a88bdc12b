//! The `flatbake` binary: everything lives in the library; see `flatbake::cli`.

fn main() -> std::process::ExitCode {
    flatbake::cli::main()
}
