//! `harness`: the command line of the research harness.

fn main() -> anyhow::Result<()> {
    harness::cli::main()
}
