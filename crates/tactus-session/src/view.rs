//! The terminal glove view while a session runs (`live --tui`, `play --tui`; issue 13).
//!
//! [`with_view`] runs a session on the calling thread while a second thread redraws
//! [`tactus_glove::tui::render`] in place every [`VIEW_EVERY`]: the dots are what the
//! sink last wrote to the link ([`tactus_transport::SinkStats::shown`]), so the view shows
//! the glove, not the engine's intentions; the link state comes from the sink too. The
//! session adds what only it knows (input level, latency, counters) through the
//! [`ViewFeed`] it is given. When the session returns, the view is drawn once more and the
//! cursor is left below it.
//!
//! The drawing thread only reads counters and writes to its output: a slow terminal never
//! holds up the session.

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use tactus_glove::tui::{redraw, render, LinkState, ViewStatus};
use tactus_transport::SinkHandle;

/// How often the view is redrawn: 20 times a second, faster than the 50 ms pin rise.
pub const VIEW_EVERY: Duration = Duration::from_millis(50);

/// What a session adds to the view (see [`ViewStatus`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ViewExtra {
    /// Input level, dBFS (`None`: no input).
    pub level_dbfs: Option<f32>,
    /// A latency, ms, and what it measures.
    pub latency: Option<(f64, String)>,
    /// One line of counters.
    pub counters: String,
}

/// The session's side of the view: [`ViewFeed::set`] replaces what it shows.
#[derive(Debug, Default)]
pub struct ViewFeed(Mutex<ViewExtra>);

impl ViewFeed {
    /// Shows `extra` from the next redraw on.
    pub fn set(&self, extra: ViewExtra) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = extra;
    }

    fn get(&self) -> ViewExtra {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

/// The view's lines now: the sink's shown frame and link, the feed's extras.
pub fn snapshot(sink: &SinkHandle, title: &str, feed: &ViewFeed) -> Vec<String> {
    let st = sink.stats();
    let extra = feed.get();
    let status = ViewStatus {
        title: title.to_string(),
        time_s: f64::from(st.shown_time_ms) / 1e3,
        link: if st.link_up {
            LinkState::Up
        } else if st.sent > 0 || st.errors > 0 {
            LinkState::Down
        } else {
            LinkState::Unknown
        },
        level_dbfs: extra.level_dbfs,
        latency: extra.latency,
        counters: extra.counters,
    };
    render(&st.shown, &status)
}

/// Runs `body` (the session) with the view drawn on `out` every [`VIEW_EVERY`] (see the
/// module docs); with `out` `None`, just runs `body`. A write error (the terminal gone)
/// stops the drawing, not the session.
pub fn with_view<R>(
    sink: &SinkHandle,
    title: &str,
    out: Option<&mut (dyn Write + Send)>,
    body: impl FnOnce(&ViewFeed) -> R,
) -> R {
    let feed = ViewFeed::default();
    let Some(out) = out else {
        return body(&feed);
    };
    let done = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let (feed, done) = (&feed, &done);
        let drawer = scope.spawn(move || {
            let mut shown = 0;
            // Hide the cursor while drawing.
            let mut ok = out.write_all(b"\x1b[?25l").is_ok();
            loop {
                let last = done.load(Ordering::Acquire);
                if ok {
                    let lines = snapshot(sink, title, feed);
                    ok = out
                        .write_all(redraw(&lines, shown).as_bytes())
                        .and_then(|()| out.flush())
                        .is_ok();
                    shown = lines.len();
                }
                if last {
                    break;
                }
                std::thread::park_timeout(VIEW_EVERY);
            }
            let _ = out.write_all(b"\x1b[?25h");
            let _ = out.flush();
        });
        let r = body(&feed);
        done.store(true, Ordering::Release);
        drawer.thread().unpark();
        let _ = drawer.join();
        r
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use tactus_glove::tui::read_frame;
    use tactus_glove::{Finger, Frame};
    use tactus_transport::{open_sink, SinkOptions, SinkSpec};

    /// A `Write` into shared memory, to look at what the view drew.
    #[derive(Clone, Default)]
    struct Screen(std::sync::Arc<Mutex<Vec<u8>>>);
    impl Write for Screen {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn the_view_draws_what_the_sink_wrote_and_the_feed() {
        let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
        let mut frame = Frame::DOWN;
        frame.set_cell(Finger::Ring, 1, 0b0100_0010);
        let screen = Screen::default();
        let mut out = screen.clone();
        let r = with_view(&sink, "live", Some(&mut out), |feed| {
            sink.send_frame(frame, 1500);
            feed.set(ViewExtra {
                level_dbfs: Some(-12.0),
                latency: Some((17.0, "bin end -> sent".into())),
                counters: "frames 1".into(),
            });
            let t0 = std::time::Instant::now();
            while sink.stats().shown != frame {
                assert!(t0.elapsed() < Duration::from_secs(5));
                std::thread::sleep(Duration::from_millis(1));
            }
            // At least two redraws after the frame was written.
            std::thread::sleep(VIEW_EVERY * 3);
            42
        });
        assert_eq!(r, 42);
        let text = String::from_utf8(screen.0.lock().unwrap().clone()).unwrap();
        assert!(text.starts_with("\x1b[?25l") && text.ends_with("\x1b[?25h"));
        // The last complete view drawn: its dots are the frame.
        let last = text.rsplit("\x1b[?25h").nth(1).unwrap();
        let last = last.rsplit('\r').next().unwrap();
        let lines: Vec<&str> = last.lines().map(|l| l.trim_end_matches("\x1b[K")).collect();
        assert_eq!(read_frame(&lines), Some(frame), "{last}");
        assert!(lines[0].starts_with("tactus live   1.50 s   link up   latency 17.0 ms"));
        assert!(lines[1].starts_with("input  -12.0 dBFS"));
        assert_eq!(lines[2], "frames 1");
        sink.close();
    }

    #[test]
    fn without_an_output_the_body_just_runs() {
        let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
        assert_eq!(with_view(&sink, "play", None, |_| 7), 7);
        sink.close();
    }
}
