//! The `graftal` binary: everything lives in the library; see `cli`.

fn main() -> std::process::ExitCode {
    graftal::cli::main()
}
