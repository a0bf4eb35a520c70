//! Progress of long commands on a log. On a terminal `indicatif` draws bars; when stderr is not
//! a terminal (CI, `nohup`, a file) the bars are hidden, so a plain line goes to stderr every
//! few seconds and at the end of each stage: the stage, done/total, percent, rate, ETA.

use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// Seconds between lines.
const PERIOD: Duration = Duration::from_secs(5);

pub fn on_terminal() -> bool {
    std::io::stderr().is_terminal()
}

pub struct LogLines {
    what: String,
    stage: String,
    stage_start: Instant,
    last: Instant,
}

impl LogLines {
    /// `what` prefixes every line (the command).
    pub fn new(what: &str) -> LogLines {
        let now = Instant::now();
        LogLines {
            what: what.into(),
            stage: String::new(),
            stage_start: now,
            last: now,
        }
    }

    /// Reports `done` of `total` items of `stage`; `msg` of the stage's seconds so far (a rate)
    /// is appended.
    pub fn update(&mut self, stage: &str, done: usize, total: usize, msg: &dyn Fn(f64) -> String) {
        let now = Instant::now();
        if stage != self.stage {
            self.stage = stage.into();
            self.stage_start = now;
        }
        let finished = done >= total;
        if !finished && now - self.last < PERIOD {
            return;
        }
        self.last = now;
        let secs = (now - self.stage_start).as_secs_f64();
        let eta = if done > 0 && !finished {
            format!(", ETA {:.0} s", secs / done as f64 * (total - done) as f64)
        } else {
            String::new()
        };
        let msg = msg(secs.max(1e-3));
        eprintln!(
            "{}: {stage} {done}/{total} ({:.0}%) in {secs:.0} s{eta}{}",
            self.what,
            100.0 * done as f64 / total.max(1) as f64,
            if msg.is_empty() {
                String::new()
            } else {
                format!(", {msg}")
            }
        );
    }
}
