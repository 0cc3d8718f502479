//! Humane durations for the soak's flags: `90s`, `2m`, `1h`, `1h30m`, `1.5h`, `7d`, `500ms`, or
//! a bare number of seconds.

use std::time::Duration;

/// The longest soak `--soak` accepts: a week.
pub const MAX_SOAK: Duration = Duration::from_secs(7 * 24 * 3600);

/// Parses a duration: one or more `<number><unit>` parts (units `ms`, `s`, `m`, `h`, `d`), or a
/// bare number of seconds. The result must be positive and finite.
pub fn parse_duration(text: &str) -> Result<Duration, String> {
    let s = text.trim();
    let bad = || format!("{text:?} is not a duration: use e.g. 90s, 2m, 1h, 1h30m, 1.5h or 7d");
    if s.is_empty() {
        return Err(bad());
    }
    if let Ok(secs) = s.parse::<f64>() {
        return positive(secs).ok_or_else(bad);
    }
    let mut total = 0.0f64;
    let mut rest = s;
    while !rest.is_empty() {
        let num_end = rest
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .ok_or_else(bad)?;
        if num_end == 0 {
            return Err(bad());
        }
        let value: f64 = rest[..num_end].parse().map_err(|_| bad())?;
        let after = &rest[num_end..];
        let unit_end = after
            .find(|c: char| c.is_ascii_digit() || c == '.')
            .unwrap_or(after.len());
        let scale = match after[..unit_end].trim() {
            "ms" => 1e-3,
            "s" | "sec" => 1.0,
            "m" | "min" => 60.0,
            "h" => 3600.0,
            "d" => 86400.0,
            _ => return Err(bad()),
        };
        total += value * scale;
        rest = &after[unit_end..];
    }
    positive(total).ok_or_else(bad)
}

/// `secs` as a duration if it is positive and finite (and below 30 years).
fn positive(secs: f64) -> Option<Duration> {
    (secs.is_finite() && secs > 0.0 && secs < 1e9).then(|| Duration::from_secs_f64(secs))
}

/// A duration in words: `45 s`, `2 min`, `1 h 30 min`, `7 d`.
pub fn humane(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s < 60.0 {
        return format!("{} s", (s * 10.0).round() / 10.0);
    }
    let total = d.as_secs();
    let (days, hours, mins, secs) = (
        total / 86400,
        total / 3600 % 24,
        total / 60 % 60,
        total % 60,
    );
    let parts: Vec<String> = [(days, "d"), (hours, "h"), (mins, "min"), (secs, "s")]
        .into_iter()
        .filter(|(v, _)| *v > 0)
        .map(|(v, u)| format!("{v} {u}"))
        .collect();
    parts.join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn humane_durations_parse() {
        let secs = |t: &str| parse_duration(t).unwrap().as_secs_f64();
        assert_eq!(secs("90s"), 90.0);
        assert_eq!(secs("2m"), 120.0);
        assert_eq!(secs("1h"), 3600.0);
        assert_eq!(secs("1h30m"), 5400.0);
        assert_eq!(secs("1.5h"), 5400.0);
        assert_eq!(secs("7d"), 7.0 * 86400.0);
        assert_eq!(secs("500ms"), 0.5);
        assert_eq!(secs("45"), 45.0);
        assert_eq!(secs(" 5 s "), 5.0);
        for bad in ["", "h", "1x", "-5m", "0s", "1h-2m", "nan", "m5", "1..5s"] {
            assert!(parse_duration(bad).is_err(), "{bad:?} parsed");
        }
    }

    #[test]
    fn durations_print_in_words() {
        assert_eq!(humane(Duration::from_secs(45)), "45 s");
        assert_eq!(humane(Duration::from_secs(120)), "2 min");
        assert_eq!(humane(Duration::from_secs(5400)), "1 h 30 min");
        assert_eq!(humane(MAX_SOAK), "7 d");
    }
}
