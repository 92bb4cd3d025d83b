//! The results fingerprint keys every cached cell: this is the check that keeps a key only while
//! the code gives the same bits. A failure means the code computes other results; pin the new
//! value if that is intended (every cached cell is then recomputed).

mod common;

use common::{harness, repo_file};

#[test]
fn the_code_gives_the_pinned_results_fingerprint() {
    let output = harness(&["fingerprint"]);
    let printed = String::from_utf8_lossy(&output.stdout);
    let errors = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{printed}{errors}");
    let pinned = std::fs::read_to_string(repo_file("engine/fingerprint/pinned.txt")).unwrap();
    assert!(
        printed.contains(&format!("fingerprint {}", pinned.trim())),
        "{printed}"
    );
}
