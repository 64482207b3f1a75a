//! The `nsrm` command: a thin binary over the command-line crate `nsrm_cli` (`src/lib.rs`), which
//! stands on the `nsrm` corrector's public API.
#![forbid(unsafe_code)]

fn main() -> std::process::ExitCode {
    nsrm_cli::main()
}
