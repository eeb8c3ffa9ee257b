//! When a frame is sent again: on a connection refused, reset or cut off, and on 502, 503 or
//! 504 (a fleet restarting, a proxy with no replica behind it, a busy service), after an
//! exponential backoff with jitter, or after the service's own `Retry-After` when it gives
//! one; `--retries` bounds how many times.

use std::time::{Duration, SystemTime};

/// The default of `--retries`: 10 tries after the first, waiting 0.5 s, 1 s, 2 s, 4 s, 8 s
/// and then 10 s each (less the jitter): about 50 s in all, through a pod's restart (a few
/// seconds for this binary to start and pass its readiness probe) and a rolling update's
/// gap with room to spare.
pub const DEFAULT_RETRIES: u32 = 10;
/// The first wait.
const FIRST: Duration = Duration::from_millis(500);
/// The longest backoff between two tries.
const LONGEST: Duration = Duration::from_secs(10);
/// The longest a `Retry-After` is followed.
const LONGEST_ASKED: Duration = Duration::from_secs(60);

/// How the sending of one frame goes on after a try that failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Policy {
    /// Tries after the first.
    pub retries: u32,
}

/// Whether an answer's status is worth another try: the gateway's 502 and 504 (no replica
/// answered) and the service's 503 (busy or stopping).
pub fn retried_status(status: u16) -> bool {
    matches!(status, 502..=504)
}

impl Policy {
    /// The wait before try `retry` (1 for the first retry), or `None` when the tries are
    /// spent. `asked` is the answer's `Retry-After`; `unit` a number in [0, 1) that spreads
    /// the waits of the frames in flight so that they do not all come back at once (equal
    /// jitter: half the backoff fixed, half random).
    pub fn wait(self, retry: u32, asked: Option<Duration>, unit: f64) -> Option<Duration> {
        if retry > self.retries {
            return None;
        }
        if let Some(asked) = asked {
            return Some(asked.min(LONGEST_ASKED));
        }
        let backoff = FIRST
            .saturating_mul(1 << retry.saturating_sub(1).min(16))
            .min(LONGEST);
        Some(backoff.mul_f64(0.5 + 0.5 * unit.clamp(0.0, 1.0)))
    }
}

/// A `Retry-After` value: delay-seconds, or an HTTP date (RFC 9110) from `now`.
pub fn retry_after(value: &str, now: SystemTime) -> Option<Duration> {
    let value = value.trim();
    if let Ok(seconds) = value.parse::<u64>() {
        return Some(Duration::from_secs(seconds));
    }
    let when = httpdate(value)?;
    Some(when.duration_since(now).unwrap_or_default())
}

/// An IMF-fixdate (`Sun, 06 Nov 1994 08:49:37 GMT`), the form RFC 9110 has senders use.
fn httpdate(text: &str) -> Option<SystemTime> {
    let mut words = text.split_whitespace();
    let _weekday = words.next()?;
    let day: u64 = words.next()?.parse().ok()?;
    const MONTHS: [&str; 12] = [
        "Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec",
    ];
    let month = words.next()?;
    let month = MONTHS.iter().position(|m| *m == month)? as u64 + 1;
    let year: u64 = words.next()?.parse().ok()?;
    let mut clock = words.next()?.split(':').map(|p| p.parse::<u64>().ok());
    let (h, m, s) = (clock.next()??, clock.next()??, clock.next()??);
    if words.next()? != "GMT" || !(1..=31).contains(&day) || h > 23 || m > 59 || s > 60 {
        return None;
    }
    // Days since 1970-01-01 of a proleptic Gregorian date (Howard Hinnant's days_from_civil).
    let (y, mo) = if month <= 2 {
        (year - 1, month + 9)
    } else {
        (year, month - 3)
    };
    let era = y / 400;
    let yoe = y - era * 400;
    let doy = (153 * mo + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = (era * 146_097 + doe).checked_sub(719_468)?;
    Some(SystemTime::UNIX_EPOCH + Duration::from_secs(days * 86_400 + h * 3600 + m * 60 + s))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The backoff doubles from 0.5 s to its 10 s cap, each wait between half and all of
    /// it; the tries end after `retries`; a `Retry-After` is followed up to a minute.
    #[test]
    fn waits_back_off_with_jitter_and_end() {
        let policy = Policy { retries: 7 };
        let full: Vec<f64> = (1..=7)
            .map(|k| policy.wait(k, None, 1.0).unwrap().as_secs_f64())
            .collect();
        assert_eq!(full, [0.5, 1.0, 2.0, 4.0, 8.0, 10.0, 10.0]);
        let least = policy.wait(3, None, 0.0).unwrap().as_secs_f64();
        assert_eq!(least, 1.0);
        assert_eq!(policy.wait(8, None, 0.5), None);
        assert_eq!(
            policy.wait(2, Some(Duration::from_secs(3)), 0.9),
            Some(Duration::from_secs(3))
        );
        assert_eq!(
            policy.wait(2, Some(Duration::from_secs(3600)), 0.9),
            Some(LONGEST_ASKED)
        );
        assert_eq!(Policy { retries: 0 }.wait(1, None, 0.5), None);
        let default: f64 = (1..=DEFAULT_RETRIES)
            .map(|k| policy_default().wait(k, None, 1.0).unwrap().as_secs_f64())
            .sum();
        assert_eq!(default, 65.5);
    }

    fn policy_default() -> Policy {
        Policy {
            retries: DEFAULT_RETRIES,
        }
    }

    /// `Retry-After` in seconds and as an HTTP date (RFC 9110's example), a date past
    /// meaning now; nonsense is none.
    #[test]
    fn retry_after_reads_seconds_and_dates() {
        let now = SystemTime::UNIX_EPOCH + Duration::from_secs(784_111_777 - 30);
        assert_eq!(retry_after(" 7 ", now), Some(Duration::from_secs(7)));
        assert_eq!(
            retry_after("Sun, 06 Nov 1994 08:49:37 GMT", now),
            Some(Duration::from_secs(30))
        );
        let later = now + Duration::from_secs(100);
        assert_eq!(
            retry_after("Sun, 06 Nov 1994 08:49:37 GMT", later),
            Some(Duration::ZERO)
        );
        assert_eq!(retry_after("soon", now), None);
        assert_eq!(retry_after("Sun, 36 Nov 1994 08:49:37 GMT", now), None);
        assert!(retried_status(503) && retried_status(502) && retried_status(504));
        assert!(!retried_status(500) && !retried_status(422));
    }
}
