//! The option values' parsers, each refusing what is out of its range in words: whole numbers,
//! sizes with binary units (`64KiB`, `32MiB`), durations with units (`500ms`, `5s`, `1m`).

use std::{str::FromStr, time::Duration};

/// A whole number in `MIN..=MAX`.
pub fn count<const MIN: usize, const MAX: usize>(text: &str) -> Result<usize, String> {
    let value = usize::from_str(text.trim())
        .map_err(|_| format!("expected a whole number from {MIN} to {MAX}"))?;
    if (MIN..=MAX).contains(&value) {
        Ok(value)
    } else {
        Err(format!("must be from {MIN} to {MAX}"))
    }
}

/// A part of a run, `I/N`: the I-th (from 0) of N.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Part {
    pub index: usize,
    pub count: usize,
}

/// `I/N` with 0 ≤ I < N ≤ 100000.
pub fn part(text: &str) -> Result<Part, String> {
    let expected = || "expected I/N, the I-th (from 0) of N parts, such as 0/4".to_owned();
    let (i, n) = text.trim().split_once('/').ok_or_else(expected)?;
    let index = usize::from_str(i.trim()).map_err(|_| expected())?;
    let count = usize::from_str(n.trim()).map_err(|_| expected())?;
    if count == 0 || count > 100_000 || index >= count {
        return Err(format!(
            "{index}/{count}: I must be from 0 to N − 1, N from 1 to 100000"
        ));
    }
    Ok(Part { index, count })
}

/// A size in bytes from `MIN` to `MAX`: a whole number, or one with a binary unit such as
/// `64KiB`, `32MiB` or `1GiB`.
pub fn size<const MIN: usize, const MAX: usize>(text: &str) -> Result<usize, String> {
    let text = text.trim();
    let expected = || "expected a size such as 1048576, 512KiB, 32MiB or 1GiB".to_owned();
    let digits = text
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(digits);
    let scale: usize = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "kib" | "k" => 1 << 10,
        "mib" | "m" => 1 << 20,
        "gib" | "g" => 1 << 30,
        _ => return Err(expected()),
    };
    let value = usize::from_str(number)
        .ok()
        .and_then(|n| n.checked_mul(scale))
        .ok_or_else(expected)?;
    if (MIN..=MAX).contains(&value) {
        Ok(value)
    } else {
        Err(format!("must be from {MIN} to {MAX} bytes"))
    }
}

/// A duration with a unit, such as `500ms`, `5s` or `1m`.
pub fn duration(text: &str) -> Result<Duration, String> {
    humantime::parse_duration(text.trim())
        .map_err(|error| format!("expected a duration such as 500ms, 5s or 1m ({error})"))
}

/// A timeout: a duration from 1 ms to 1 hour.
pub fn timeout(text: &str) -> Result<Duration, String> {
    let value = duration(text)?;
    if value < Duration::from_millis(1) || value > Duration::from_secs(3600) {
        return Err("must be from 1ms to 1h".to_owned());
    }
    Ok(value)
}

/// A delay: a duration from 0 to 5 minutes.
pub fn delay(text: &str) -> Result<Duration, String> {
    let value = duration(text)?;
    if value > Duration::from_secs(300) {
        return Err("must be at most 5m".to_owned());
    }
    Ok(value)
}
