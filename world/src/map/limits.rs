//! The size limits of any map: a leaf, so that the grid that enforces them and the errors
//! that name them both read them from below.

/// The largest side a map may have: keeps cell indices in `u32` and per-map tables in memory.
pub const MAX_SIDE: usize = 1024;

/// The largest text map file read: every row of a map at its widest with a CRLF ending
/// (1 MiB + 2 KiB), and 4 KiB more for a byte-order mark and blank lines. A longer file cannot
/// be a valid map, and refusing it before reading keeps a wrong path (a device, a huge file)
/// from filling memory.
pub const MAX_TEXT_MAP_BYTES: u64 = (MAX_SIDE * (MAX_SIDE + 2) + 4096) as u64;
