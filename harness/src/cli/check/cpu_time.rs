//! CPU time as a reader takes it in: seconds, minutes, hours or days, whichever reads best,
//! for the estimates of `check`, its pilot and `slurm`.

/// A rough duration, in the unit that reads best.
pub(crate) fn duration(seconds: f64) -> String {
    match seconds {
        s if s < 120.0 => format!("{s:.0} s"),
        s if s < 7200.0 => format!("{:.0} min", s / 60.0),
        s if s < 172_800.0 => format!("{:.1} h", s / 3600.0),
        s => format!("{:.1} days", s / 86_400.0),
    }
}
