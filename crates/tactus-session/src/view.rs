//! The terminal glove view while a session runs (`live --tui`, `play --tui`).
//!
//! [`with_view`] runs a session on the calling thread while a second thread redraws
//! [`tactus_glove::tui::render`] in place every [`VIEW_EVERY`]: the dots are what the
//! sink last wrote to the link ([`tactus_transport::SinkStats::shown`]), so the view shows
//! the glove, not the engine's intentions; the link state comes from the sink too. The
//! session adds what only it knows (input level, latency, counters) through the
//! [`ViewFeed`] it is given. When the session returns, the sink is closed (all pins down)
//! and the view is drawn once more from the final counters, the cursor left below it.
//!
//! The drawing thread only reads counters and writes to its output: a slow terminal never
//! holds up the session.

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use tactus_glove::tui::{redraw, render, LinkState, ViewStatus};
use tactus_transport::{SinkHandle, SinkStats};

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

/// The view's lines for the sink's counters `st` (`closed`: after [`SinkHandle::close`])
/// and the feed's extras.
pub fn snapshot(st: &SinkStats, closed: bool, title: &str, feed: &ViewFeed) -> Vec<String> {
    let extra = feed.get();
    let status = ViewStatus {
        title: title.to_string(),
        time_s: f64::from(st.shown_time_ms) / 1e3,
        link: if closed {
            LinkState::Closed
        } else if st.link_up {
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

/// Runs `body` (the session, given the sink) with the view drawn on `out` every
/// [`VIEW_EVERY`] (see the module docs), then closes the sink and returns its final
/// counters; with `out` `None`, the same without drawing. A write error (the terminal
/// gone) stops the drawing, not the session.
pub fn with_view<R>(
    sink: SinkHandle,
    title: &str,
    out: Option<&mut (dyn Write + Send)>,
    body: impl FnOnce(&SinkHandle, &ViewFeed) -> R,
) -> (R, SinkStats) {
    let feed = ViewFeed::default();
    let Some(out) = out else {
        let r = body(&sink, &feed);
        return (r, sink.close());
    };
    let done = AtomicBool::new(false);
    let (r, (out, shown, ok)) = std::thread::scope(|scope| {
        let (feed, done, sink) = (&feed, &done, &sink);
        let drawer = scope.spawn(move || {
            let mut shown = 0;
            // Hide the cursor while drawing.
            let mut ok = out.write_all(b"\x1b[?25l").is_ok();
            while ok && !done.load(Ordering::Acquire) {
                let lines = snapshot(&sink.stats(), false, title, feed);
                ok = out
                    .write_all(redraw(&lines, shown).as_bytes())
                    .and_then(|()| out.flush())
                    .is_ok();
                shown = lines.len();
                std::thread::park_timeout(VIEW_EVERY);
            }
            (out, shown, ok)
        });
        let r = body(sink, feed);
        done.store(true, Ordering::Release);
        drawer.thread().unpark();
        // The drawer only writes and reads counters: it does not panic.
        (r, drawer.join().expect("the view's drawing thread"))
    });
    let stats = sink.close();
    if ok {
        let lines = snapshot(&stats, true, title, &feed);
        let _ = out.write_all(redraw(&lines, shown).as_bytes());
    }
    let _ = out.write_all(b"\x1b[?25h");
    let _ = out.flush();
    (r, stats)
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
        let (r, stats) = with_view(sink, "live", Some(&mut out), |sink, feed| {
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
        assert_eq!(stats.shown, Frame::DOWN, "closed");
        let text = String::from_utf8(screen.0.lock().unwrap().clone()).unwrap();
        assert!(text.starts_with("\x1b[?25l") && text.ends_with("\x1b[?25h"));
        let views: Vec<Vec<&str>> = text
            .trim_end_matches("\x1b[?25h")
            .split('\r')
            .map(|v| v.lines().map(|l| l.trim_end_matches("\x1b[K")).collect())
            .collect();
        // The view before the last showed the frame; the last one, after closing, all down.
        let shown = &views[views.len() - 2];
        assert_eq!(read_frame(shown), Some(frame), "{text}");
        assert!(shown[0].starts_with("tactus live   1.50 s   link up   latency 17.0 ms"));
        assert!(shown[1].starts_with("input  -12.0 dBFS"));
        assert_eq!(shown[2], "frames 1");
        let last = views.last().unwrap();
        assert_eq!(read_frame(last), Some(Frame::DOWN), "{text}");
        assert!(last[0].contains("link closed"), "{}", last[0]);
    }

    #[test]
    fn without_an_output_the_body_just_runs() {
        let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
        let (r, stats) = with_view(sink, "play", None, |sink, _| {
            sink.send_frame(Frame([1; 10]), 0);
            7
        });
        assert_eq!(r, 7);
        assert_eq!(stats.frames_sent + stats.dropped, 1);
    }
}
