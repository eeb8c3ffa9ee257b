//! The progress of a recording's run: a bar on a terminal (frames done, frames per second,
//! time left), redrawn in place at most ten times a second, and nothing but the messages and
//! the closing line when the output is a file or a pipe.

use std::io::Write;
use std::time::{Duration, Instant};

/// What has been done so far, and where it is drawn.
pub struct Progress<W: Write> {
    out: W,
    bar: bool,
    total: usize,
    done: usize,
    failed: usize,
    started: Instant,
    drawn: Option<Instant>,
    /// Why the run is waiting to send a frame again, while it is.
    waiting: Option<String>,
}

impl<W: Write> Progress<W> {
    /// A run of `total` pairs, drawing a bar into `out` when `bar` (a terminal).
    pub fn new(out: W, bar: bool, total: usize) -> Self {
        Progress {
            out,
            bar,
            total,
            done: 0,
            failed: 0,
            started: Instant::now(),
            drawn: None,
            waiting: None,
        }
    }

    /// A line above the bar (a file skipped, a pair that failed).
    pub fn say(&mut self, line: &str) {
        if self.bar {
            let _ = write!(self.out, "\r\x1b[2K");
        }
        let _ = writeln!(self.out, "{line}");
        self.draw(true);
    }

    /// The run waits to send a frame again, and why (shown on the bar until a pair finishes).
    pub fn waiting(&mut self, why: String) {
        self.waiting = Some(why);
        self.draw(true);
    }

    /// One pair finished, written or not.
    pub fn finished(&mut self, ok: bool) {
        self.waiting = None;
        self.done += 1;
        if !ok {
            self.failed += 1;
        }
        self.draw(self.done == self.total);
    }

    /// Frames per second so far, and the time the rest will take at that rate.
    fn rate(&self) -> (f64, Option<Duration>) {
        let seconds = self.started.elapsed().as_secs_f64();
        let fps = if seconds > 0.0 {
            self.done as f64 / seconds
        } else {
            0.0
        };
        let left =
            (fps > 0.0).then(|| Duration::from_secs_f64((self.total - self.done) as f64 / fps));
        (fps, left)
    }

    fn draw(&mut self, now: bool) {
        if !self.bar || self.total == 0 {
            return;
        }
        if !now
            && self
                .drawn
                .is_some_and(|t| t.elapsed() < Duration::from_millis(100))
        {
            return;
        }
        self.drawn = Some(Instant::now());
        let _ = write!(self.out, "\r\x1b[2K{}", self.line());
        let _ = self.out.flush();
    }

    /// The bar's text: `[=====>    ] 42/100 frames  12.3 frames/s  0:05 left`.
    pub fn line(&self) -> String {
        const WIDTH: usize = 24;
        let filled = WIDTH * self.done / self.total.max(1);
        let mut bar = "=".repeat(filled);
        if filled < WIDTH {
            bar.push('>');
            bar.push_str(&" ".repeat(WIDTH - filled - 1));
        }
        let (fps, left) = self.rate();
        let left = left.map_or_else(|| "--:--".to_owned(), clock);
        let failed = if self.failed > 0 {
            format!("  {} failed", self.failed)
        } else {
            String::new()
        };
        let waiting = self
            .waiting
            .as_ref()
            .map_or_else(String::new, |why| format!("  waiting: {why}"));
        format!(
            "[{bar}] {}/{} frames  {fps:.1} frames/s  {left} left{failed}{waiting}",
            self.done, self.total
        )
    }

    /// Ends the bar's line, so that what follows starts on its own, and draws no more.
    pub fn close(&mut self) {
        if self.bar && self.total > 0 {
            let _ = writeln!(self.out);
        }
        self.bar = false;
    }
}

/// `m:ss`, or `h:mm:ss` past an hour.
pub fn clock(d: Duration) -> String {
    let s = d.as_secs();
    if s >= 3600 {
        format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
    } else {
        format!("{}:{:02}", s / 60, s % 60)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Off a terminal only the messages are written; on one, the bar redraws in place.
    #[test]
    fn the_bar_shows_only_on_a_terminal() {
        let mut plain = Progress::new(Vec::new(), false, 4);
        plain.say("skipped a.png");
        plain.finished(true);
        plain.finished(false);
        plain.close();
        assert_eq!(String::from_utf8(plain.out).unwrap(), "skipped a.png\n");
        let mut bar = Progress::new(Vec::new(), true, 4);
        bar.finished(true);
        bar.finished(true);
        bar.finished(false);
        bar.finished(true);
        let text = String::from_utf8(bar.out.clone()).unwrap();
        assert!(
            text.contains("\r\x1b[2K[========================] 4/4 frames"),
            "{text:?}"
        );
        assert!(bar.line().contains("1 failed"));
        bar.waiting("cannot connect to host:80; again in 2.0 s (retry 1 of 10)".to_owned());
        assert!(bar.line().ends_with(
            "1 failed  waiting: cannot connect to host:80; again in 2.0 s (retry 1 of 10)"
        ));
        let drawn = String::from_utf8(bar.out.clone()).unwrap();
        assert!(drawn.ends_with("(retry 1 of 10)"), "{drawn:?}");
    }

    #[test]
    fn clocks_read_as_minutes_and_hours() {
        assert_eq!(clock(Duration::from_secs(65)), "1:05");
        assert_eq!(clock(Duration::from_secs(3725)), "1:02:05");
    }
}
