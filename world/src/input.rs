//! Reading an input file (a map, a scenario, an actions file, a store's own files) safely.
//!
//! A path may name anything: `/dev/zero` never ends, a FIFO blocks until someone writes to it,
//! and a sparse file claims gigabytes it does not hold. Every input is therefore opened only
//! if it is a regular file, and read through a capped reader up to a limit that follows from
//! its format, so a wrong path fails at once with a message naming the file and the limit.

use std::fs::{File, FileType};
use std::io::Read;
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

/// A file that was not read, and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {problem}", path.display())]
pub struct InputError {
    pub path: PathBuf,
    pub problem: InputProblem,
}

/// Why a file was not read (the path aside, for errors that name the file themselves).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InputProblem {
    #[error("cannot read: {0}")]
    Io(String),
    #[error("not a regular file ({0})")]
    NotRegular(&'static str),
    #[error("larger than {}, the limit for {what}", bytes(*limit))]
    TooLarge { limit: u64, what: &'static str },
    #[error("not UTF-8 text")]
    NotText,
}

/// The bytes of the regular file `path`, refused when it holds more than `limit` bytes;
/// `what` names the kind of file in that error ("a text map").
pub fn read_bounded(path: &Path, limit: u64, what: &'static str) -> Result<Vec<u8>, InputError> {
    read_capped(path, limit, what).map_err(|problem| InputError {
        path: path.to_owned(),
        problem,
    })
}

fn read_capped(path: &Path, limit: u64, what: &'static str) -> Result<Vec<u8>, InputProblem> {
    let too_large = InputProblem::TooLarge { limit, what };
    let file = open_regular(path)?;
    // The size on disk refuses a large (or sparse) file before any byte is read; the cap
    // refuses a file that grows while it is read.
    if file.metadata().map_err(io)?.len() > limit {
        return Err(too_large);
    }
    let mut bytes = Vec::new();
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(too_large);
    }
    Ok(bytes)
}

fn io(error: std::io::Error) -> InputProblem {
    InputProblem::Io(error.to_string())
}

/// [`read_bounded`] for a text format: the file must also be UTF-8. A leading byte-order mark
/// is dropped: editors on Windows write one, and it is no part of any format read here (a map
/// would otherwise fail on an unknown character in its first column).
pub fn read_bounded_text(
    path: &Path,
    limit: u64,
    what: &'static str,
) -> Result<String, InputError> {
    let mut bytes = read_bounded(path, limit, what)?;
    if bytes.starts_with(BOM) {
        bytes.drain(..BOM.len());
    }
    String::from_utf8(bytes).map_err(|_| InputError {
        path: path.to_owned(),
        problem: InputProblem::NotText,
    })
}

/// The UTF-8 byte-order mark.
const BOM: &[u8] = b"\xEF\xBB\xBF";

/// Opens `path` without blocking (a FIFO would wait for a writer) and keeps it only if the
/// opened file is a regular one; checking the open file, not the path, leaves no gap for the
/// path to be swapped between the check and the read.
fn open_regular(path: &Path) -> Result<File, InputProblem> {
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(io)?;
    match irregular(file.metadata().map_err(io)?.file_type()) {
        Some(kind) => Err(InputProblem::NotRegular(kind)),
        None => Ok(file),
    }
}

/// What a file that is not a regular one is, in words; `None` for a regular file.
fn irregular(kind: FileType) -> Option<&'static str> {
    if kind.is_file() {
        None
    } else if kind.is_fifo() {
        Some("a FIFO")
    } else if kind.is_char_device() {
        Some("a character device")
    } else if kind.is_block_device() {
        Some("a block device")
    } else if kind.is_dir() {
        Some("a directory")
    } else if kind.is_socket() {
        Some("a socket")
    } else {
        Some("not a file")
    }
}

/// A byte count as people read it: `300 bytes`, `1.5 KiB (1536 bytes)`.
fn bytes(count: u64) -> String {
    let mut value = count as f64;
    let mut unit = "bytes";
    for larger in ["KiB", "MiB", "GiB", "TiB"] {
        if value < 1024.0 {
            break;
        }
        value /= 1024.0;
        unit = larger;
    }
    if unit == "bytes" {
        format!("{count} bytes")
    } else {
        let rounded = (value * 100.0).round() / 100.0;
        format!("{rounded} {unit} ({count} bytes)")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("world-input-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_regular_file_within_the_limit_is_read_whole() {
        let dir = scratch("within");
        let path = dir.join("map.txt");
        std::fs::write(&path, "..#\n...\n").unwrap();
        assert_eq!(read_bounded(&path, 8, "a text map").unwrap(), b"..#\n...\n");
        assert_eq!(
            read_bounded_text(&path, 8, "a text map").unwrap(),
            "..#\n...\n"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_leading_byte_order_mark_is_dropped_once() {
        let dir = scratch("bom");
        let path = dir.join("map.txt");
        std::fs::write(&path, b"\xEF\xBB\xBF..#\n").unwrap();
        assert_eq!(read_bounded_text(&path, 8, "a text map").unwrap(), "..#\n");
        std::fs::write(&path, b"\xEF\xBB\xBF\xEF\xBB\xBF.\n").unwrap();
        assert_eq!(
            read_bounded_text(&path, 8, "a text map").unwrap(),
            "\u{feff}.\n"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_file_over_the_limit_is_refused_naming_the_file_and_the_limit() {
        let dir = scratch("over");
        let path = dir.join("map.txt");
        std::fs::write(&path, "..#\n...\n.").unwrap();
        let error = read_bounded(&path, 8, "a text map").unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "{}: larger than 8 bytes, the limit for a text map",
                path.display()
            )
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_sparse_file_is_refused_by_its_size_without_reading_it() {
        let dir = scratch("sparse");
        let path = dir.join("huge.txt");
        File::create(&path).unwrap().set_len(1 << 30).unwrap();
        let error = read_bounded(&path, 1 << 20, "a scenario").unwrap_err();
        assert!(
            error
                .to_string()
                .ends_with("larger than 1 MiB (1048576 bytes), the limit for a scenario"),
            "{error}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_fifo_is_refused_at_once_without_waiting_for_a_writer() {
        let dir = scratch("fifo");
        let path = dir.join("map.txt");
        let name = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: `name` is a valid NUL-terminated path that outlives the call.
        assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
        let error = read_bounded(&path, 1 << 20, "a text map").unwrap_err();
        assert_eq!(error.problem, InputProblem::NotRegular("a FIFO"));
        assert_eq!(
            error.to_string(),
            format!("{}: not a regular file (a FIFO)", path.display())
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_device_and_a_directory_are_refused() {
        let zero = read_bounded(Path::new("/dev/zero"), 1 << 20, "a text map").unwrap_err();
        assert_eq!(
            zero.to_string(),
            "/dev/zero: not a regular file (a character device)"
        );
        let dir = read_bounded(Path::new("/"), 1 << 20, "a text map").unwrap_err();
        assert_eq!(dir.problem, InputProblem::NotRegular("a directory"));
    }

    #[test]
    fn a_missing_file_is_an_io_error_naming_it() {
        let error = read_bounded(Path::new("/no/such/map.txt"), 8, "a text map").unwrap_err();
        assert!(
            error
                .to_string()
                .starts_with("/no/such/map.txt: cannot read: "),
            "{error}"
        );
    }

    #[test]
    fn limits_are_written_in_the_largest_unit_that_fits() {
        assert_eq!(bytes(300).to_string(), "300 bytes");
        assert_eq!(bytes(1536).to_string(), "1.5 KiB (1536 bytes)");
        assert_eq!(bytes(16 << 30).to_string(), "16 GiB (17179869184 bytes)");
    }
}
