//! Names that the tables' writers (the engine) and their readers (the report, the tests) share
//! beyond a table's own columns, so that renaming one is a compile error on both sides.

/// The columns a test curve adds to an episodes table's (`test_curve` table).
pub mod test_curve {
    pub const TRAINING_EPISODE: &str = "training_episode";
    pub const CPU_SECONDS: &str = "cpu_seconds";
    pub const WALL_SECONDS: &str = "wall_seconds";
}

/// Layer names of the `snapshots` table.
pub mod layer {
    /// The whole map: a free cell's penalty (<= 0), obstacles 150.
    pub const PENALTY: &str = "penalty";
    /// Agent 0's local map, in the paper's codes (obstacle 150, agent 200).
    pub const LOCAL: &str = "local";
    /// Agent 0's mini-map, in the paper's codes.
    pub const MINI: &str = "mini";
}
