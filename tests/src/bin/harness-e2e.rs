//! The `harness` command line, built inside this package so that end-to-end tests can run it
//! as a real process (cargo hands integration tests the paths of their own package's binaries).

fn main() -> anyhow::Result<()> {
    harness::cli::main()
}
