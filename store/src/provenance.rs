//! Where, when and from which code a result was computed, for the `cells` table: provenance
//! only, never part of a key (`plan::code_version` is). The code comes from the binary
//! (`BuiltFrom`); the host, the CPU and the time are read here.

use std::time::{SystemTime, UNIX_EPOCH};

/// The machine's host name, from the kernel or the environment; empty if neither says.
pub fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .map(|name| name.trim().to_owned())
        .unwrap_or_default()
}

/// The CPU's model name and the vector extensions it has that matter to numeric code, e.g.
/// `AMD EPYC 9R14 (avx512f avx2 fma)`: the record of where a result was made, so that an
/// audit elsewhere says what it compared.
pub fn cpu_description() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .find_map(|l| l.strip_prefix("model name")?.split_once(':'))
                .map(|(_, name)| name.trim().to_owned())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_owned());
    format!("{model} ({})", vector_extensions().join(" "))
}

/// The vector extensions of the running CPU, of those our kernels could use.
fn vector_extensions() -> Vec<&'static str> {
    #[cfg(target_arch = "x86_64")]
    {
        [
            ("avx512f", std::arch::is_x86_feature_detected!("avx512f")),
            ("avx2", std::arch::is_x86_feature_detected!("avx2")),
            ("fma", std::arch::is_x86_feature_detected!("fma")),
        ]
        .into_iter()
        .filter_map(|(name, present)| present.then_some(name))
        .collect()
    }
    #[cfg(not(target_arch = "x86_64"))]
    Vec::new()
}

/// `time` as UTC ISO 8601 with milliseconds, e.g. `2026-05-09T07:29:33.186Z`.
pub fn utc_timestamp(time: SystemTime) -> String {
    let since_epoch = time.duration_since(UNIX_EPOCH).unwrap_or_default();
    let seconds = since_epoch.as_secs();
    let (year, month, day) = civil_from_days((seconds / 86_400) as i64);
    let of_day = seconds % 86_400;
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}.{:03}Z",
        of_day / 3600,
        of_day / 60 % 60,
        of_day % 60,
        since_epoch.subsec_millis()
    )
}

/// Howard Hinnant's days-to-civil-date algorithm (proleptic Gregorian calendar).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let day_of_era = z.rem_euclid(146_097);
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let mp = (5 * day_of_year + 2) / 153;
    let day = (day_of_year - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = year_of_era + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

/// The code a binary was built from, recorded beside what it computes: facts of the build that
/// the binary's own build script finds (the commit, the hash of the numeric sources) and hands
/// down at run time, so that no library's build depends on the repository's HEAD and a commit
/// rebuilds only the binary. Empty fields: built outside a checkout (or outside git).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BuiltFrom {
    /// `git describe --always --dirty` of the checkout.
    pub git_commit: String,
    /// The hash of the sources that can change a cell's numbers and of their locked crates.
    pub sources: String,
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    #[test]
    fn formats_known_instants() {
        assert_eq!(utc_timestamp(UNIX_EPOCH), "1970-01-01T00:00:00.000Z");
        let leap_day = UNIX_EPOCH + Duration::from_millis(951_827_696_789);
        assert_eq!(utc_timestamp(leap_day), "2000-02-29T12:34:56.789Z");
    }
}
