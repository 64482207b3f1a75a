//! The `nsrm` command: a thin binary over the library, whose `cli` room holds the command line
//! (see `src/cli/`).
#![forbid(unsafe_code)]

fn main() -> std::process::ExitCode {
    nsrm::cli::main()
}
