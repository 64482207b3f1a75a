//! Progress of a batch as log lines, for a run whose standard error is not a terminal (a farm
//! task's log, a pipe, a file): one line per finished frame, at most one a second (the last
//! frame's always), with counts, rate and the time left.

use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Counts a batch's finished frames and says when a line is due.
#[derive(Debug)]
pub(crate) struct ProgressLog {
    total: usize,
    every: Duration,
    state: Mutex<State>,
}

#[derive(Debug)]
struct State {
    done: usize,
    failed: usize,
    pixels: u64,
    started: Instant,
    last: Option<Instant>,
}

/// A file name for a log line: as it is, or quoted with escapes when it holds a control
/// character (a line break would forge a log line).
fn shown(name: &str) -> String {
    if name.chars().any(char::is_control) {
        format!("{name:?}")
    } else {
        name.to_string()
    }
}

/// Seconds as `12 s`, `3 min 05 s` or `2 h 07 min`.
pub(crate) fn duration_text(s: f64) -> String {
    let s = s.max(0.0).round() as u64;
    if s < 60 {
        format!("{s} s")
    } else if s < 3600 {
        format!("{} min {:02} s", s / 60, s % 60)
    } else {
        format!("{} h {:02} min", s / 3600, s % 3600 / 60)
    }
}

impl ProgressLog {
    /// A log of `total` frames, a line at most every `every`.
    pub(crate) fn new(total: usize, every: Duration) -> ProgressLog {
        ProgressLog {
            total,
            every,
            state: Mutex::new(State {
                done: 0,
                failed: 0,
                pixels: 0,
                started: Instant::now(),
                last: None,
            }),
        }
    }

    /// Records a finished frame (`ok`: written; else failed) of `pixels` named `name`, and
    /// returns the line to print when one is due.
    pub(crate) fn frame(&self, ok: bool, pixels: u64, name: &str) -> Option<String> {
        self.frame_at(ok, pixels, name, Instant::now())
    }

    fn frame_at(&self, ok: bool, pixels: u64, name: &str, now: Instant) -> Option<String> {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        s.done += 1;
        s.pixels += pixels;
        if !ok {
            s.failed += 1;
        }
        let last = s.done >= self.total;
        if !last && s.last.is_some_and(|t| now.duration_since(t) < self.every) {
            return None;
        }
        s.last = Some(now);
        let secs = now.duration_since(s.started).as_secs_f64().max(1e-6);
        let rate = s.done as f64 / secs;
        let left = self.total.saturating_sub(s.done);
        let eta = if last {
            "done".to_string()
        } else {
            format!("ETA {}", duration_text(left as f64 / rate))
        };
        Some(format!(
            "nsrm apply: {}/{} frames ({:.0}%), {} failed; {:.2} frames/s, {:.1} Mpixel/s; {} elapsed, {eta}; {} {}",
            s.done,
            self.total,
            100.0 * s.done as f64 / self.total.max(1) as f64,
            s.failed,
            rate,
            s.pixels as f64 / secs / 1e6,
            duration_text(secs),
            if ok { "wrote" } else { "failed" },
            shown(name)
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_per_frame_at_most_once_a_second_and_always_the_last() {
        let log = ProgressLog::new(4, Duration::from_secs(1));
        let t0 = log.state.lock().unwrap().started;
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        let first = log.frame_at(true, 2_000_000, "a.exr", at(2000)).unwrap();
        assert!(
            first.starts_with("nsrm apply: 1/4 frames (25%), 0 failed; 0.50 frames/s, 1.0 Mpixel/s; 2 s elapsed, ETA 6 s; wrote a.exr"),
            "{first}"
        );
        assert_eq!(log.frame_at(false, 0, "b\nforged.exr", at(2500)), None);
        let third = log.frame_at(true, 0, "c.exr", at(3000)).unwrap();
        assert!(third.contains("3/4 frames (75%), 1 failed"), "{third}");
        let last = log.frame_at(false, 0, "d\nx.exr", at(3100)).unwrap();
        assert!(last.contains("4/4 frames (100%), 2 failed"), "{last}");
        assert!(last.contains("done; failed \"d\\nx.exr\""), "{last}");
        assert_eq!(last.lines().count(), 1);
    }

    #[test]
    fn durations_read_as_a_person_would() {
        assert_eq!(duration_text(4.4), "4 s");
        assert_eq!(duration_text(185.0), "3 min 05 s");
        assert_eq!(duration_text(7620.0), "2 h 07 min");
    }
}
