//! Streaming sample-rate conversion of planar `f32` audio, delay-compensated and exact in length.
//!
//! # Algorithm
//! [`rubato::Fft`], a synchronous FFT resampler: each block of `fft_in` input frames is
//! transformed, low-pass filtered in the frequency domain by a windowed-sinc anti-aliasing
//! filter (Blackman–Harris² window), zero-padded or truncated to `fft_out` bins, transformed
//! back and overlap-added. The conversion ratio is exact (`fft_out / fft_in = out_rate / in_rate`,
//! both multiples of `rate / gcd(in_rate, out_rate)`), unlike an asynchronous sinc resampler
//! whose ratio is a float.
//!
//! Why this one: for a fixed ratio it is the cheapest high-quality option rubato offers (one
//! FFT pair per block instead of a sinc dot product per output sample), its passband is flat
//! (the measured ripple at 440/880 Hz is far below the 0.1 dB the tests demand) and with
//! blocks of 1024 or more input frames the anti-aliasing cutoff sits at about 99 % of the lower
//! Nyquist frequency (about 21.8 kHz for 44.1 kHz ↔ 48 kHz), where the BH² window gives a deep
//! stop band. Everything the engine analyses (up to the 12 kHz cymbal band) is well inside.
//!
//! # Defaults
//! Input block: the smallest *even* multiple of `in_rate / gcd` that is at least 1024 frames
//! (44.1 → 48 kHz: 1176 in, 1280 out; 48 → 44.1 kHz: 1280 in, 1176 out; 22.05 → 44.1 kHz:
//! 1024 in, 2048 out). Even FFT sizes keep the delay an exact whole number of output frames.
//! Rate pairs with a small gcd get large blocks (44 100 → 44 101 Hz: 88 200 frames): correct,
//! but slow to start.
//!
//! # Stream contract
//! [`StreamResampler::process`] accepts blocks of any size (buffered internally to rubato's fixed
//! block) and appends to the output whatever is ready; [`StreamResampler::finish`] flushes.
//! Across a whole stream of `n` input frames the output is exactly `round(n · out / in)` frames
//! (halves round up) and aligned with the input: the resampler's own delay (`fft_out / 2`
//! output frames) is dropped from the start, so input frame `i` appears at output frame
//! `i · out / in`. Splitting the input into any chunks gives the same output.
//! `in_rate == out_rate` is an exact pass-through with no latency.
//!
//! # Latency
//! [`StreamResampler::latency_samples`]: at most `fft_out / 2 + fft_out` output frames (the
//! filter delay plus one block of buffering); 44.1 → 48 kHz: 640 + 1280 = 1920 frames, 40 ms.

use rubato::audioadapter_buffers::direct::SequentialSliceOfVecs;
use rubato::{Fft, FixedSync, Resampler, WindowFunction};

/// Input block size the resampler aims for, in frames (rounded up to a valid block).
pub const TARGET_BLOCK: usize = 1024;

/// Why a resampler could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ResampleError {
    /// A sample rate is zero.
    #[error("invalid sample rates {in_rate} Hz -> {out_rate} Hz: both must be above 0")]
    InvalidRate {
        /// Input rate in Hz.
        in_rate: u32,
        /// Output rate in Hz.
        out_rate: u32,
    },
    /// Zero channels were requested, or the input's channels differ in length.
    #[error("invalid channels: {0}")]
    InvalidChannels(String),
    /// rubato refused the configuration.
    #[error("cannot build the resampler: {0}")]
    Construction(String),
}

/// The FFT machinery; absent for an identity conversion.
struct Engine {
    fft: Fft<f32>,
    block_in: usize,
    block_out: usize,
    /// One block of input per channel, filled up to `fill`.
    input: Vec<Vec<f32>>,
    fill: usize,
    /// One block of output per channel.
    output: Vec<Vec<f32>>,
    /// Delay of the resampler in output frames (`fft_out / 2`).
    delay: usize,
    /// Output frames still to drop from the start of the stream.
    to_skip: usize,
}

/// Its block sizes; rubato's FFT state has no `Debug`.
impl std::fmt::Debug for Engine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (i, o) = (self.block_in, self.block_out);
        write!(f, "Engine {{ block_in: {i}, block_out: {o}, .. }}")
    }
}

impl Engine {
    /// Resamples the (full) input block and appends at most `limit` output frames, after
    /// dropping the leading delay. Returns the number appended.
    fn run_block(&mut self, out: &mut [Vec<f32>], limit: u64) -> u64 {
        let channels = self.input.len();
        // Panics: cannot fail, both adapters and rubato's chunk sizes were fixed in `new`
        // and are only ever used with these exact lengths.
        let inp = SequentialSliceOfVecs::new(&self.input, channels, self.block_in)
            .expect("input block sized at construction");
        let mut outp = SequentialSliceOfVecs::new_mut(&mut self.output, channels, self.block_out)
            .expect("output block sized at construction");
        let (_, produced) = self
            .fft
            .process_into_buffer(&inp, &mut outp, None)
            .expect("rubato block sizes fixed at construction");
        let skip = self.to_skip.min(produced);
        self.to_skip -= skip;
        let take = ((produced - skip) as u64).min(limit) as usize;
        for (o, block) in out.iter_mut().zip(&self.output) {
            o.extend_from_slice(&block[skip..skip + take]);
        }
        take as u64
    }
}

/// A streaming resampler for planar audio; see the module docs.
#[derive(Debug)]
pub struct StreamResampler {
    in_rate: u32,
    out_rate: u32,
    channels: usize,
    engine: Option<Engine>,
    /// Input frames seen since the last reset.
    frames_in: u64,
    /// Output frames emitted since the last reset.
    frames_out: u64,
}

fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

impl StreamResampler {
    /// Builds a resampler from `in_rate` to `out_rate` Hz for `channels` planar channels.
    pub fn new(in_rate: u32, out_rate: u32, channels: usize) -> Result<Self, ResampleError> {
        if in_rate == 0 || out_rate == 0 {
            return Err(ResampleError::InvalidRate { in_rate, out_rate });
        }
        if channels == 0 {
            return Err(ResampleError::InvalidChannels(
                "at least one channel is needed".into(),
            ));
        }
        let engine = if in_rate == out_rate {
            None
        } else {
            let g = gcd(u64::from(in_rate), u64::from(out_rate));
            let min_in = (u64::from(in_rate) / g) as usize;
            // An even number of minimum blocks makes both FFT sizes even. With an odd size
            // the filter's true delay is `floor(fft_in / 2) · out / in` output frames, which
            // differs from rubato's `output_delay()` (`fft_out / 2`) by half a frame or so;
            // with even sizes the two agree exactly and the output is aligned to the frame.
            let block_in = TARGET_BLOCK.div_ceil(min_in).next_multiple_of(2) * min_in;
            let fft = Fft::<f32>::new_custom(
                in_rate as usize,
                out_rate as usize,
                block_in,
                1,
                channels,
                WindowFunction::BlackmanHarris2,
                FixedSync::Input,
            )
            .map_err(|e| ResampleError::Construction(e.to_string()))?;
            let block_out = fft.output_frames_next();
            if fft.input_frames_next() != block_in
                || fft.fft_size_in() != block_in
                || block_out != fft.fft_size_out()
            {
                return Err(ResampleError::Construction(format!(
                    "unexpected block sizes {} -> {}",
                    fft.input_frames_next(),
                    block_out
                )));
            }
            let delay = fft.output_delay();
            Some(Engine {
                block_in,
                block_out,
                input: vec![vec![0.0; block_in]; channels],
                fill: 0,
                output: vec![vec![0.0; fft.output_frames_max()]; channels],
                delay,
                to_skip: delay,
                fft,
            })
        };
        Ok(StreamResampler {
            in_rate,
            out_rate,
            channels,
            engine,
            frames_in: 0,
            frames_out: 0,
        })
    }

    /// Input rate in Hz.
    pub fn in_rate(&self) -> u32 {
        self.in_rate
    }

    /// Output rate in Hz.
    pub fn out_rate(&self) -> u32 {
        self.out_rate
    }

    /// Channel count.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Output frames a stream of `frames_in` input frames yields in all: `round(n · out / in)`.
    pub fn output_len(&self, frames_in: u64) -> u64 {
        let num = u128::from(frames_in) * u128::from(self.out_rate);
        let den = u128::from(self.in_rate);
        ((num + den / 2) / den) as u64
    }

    /// Feeds `input` (one slice per channel, all the same length, any length) and appends the
    /// output frames that are ready to `output` (one `Vec` per channel). Reserve the vectors to
    /// avoid reallocation: a call appends at most `ceil(len / block_in + 1) · block_out` frames.
    ///
    /// # Panics
    /// If `input` or `output` does not have [`channels`](Self::channels) entries, or the input
    /// slices differ in length (programming errors, not data errors).
    pub fn process(&mut self, input: &[&[f32]], output: &mut [Vec<f32>]) {
        assert_eq!(input.len(), self.channels, "input channel count");
        assert_eq!(output.len(), self.channels, "output channel count");
        let n = input[0].len();
        assert!(
            input.iter().all(|c| c.len() == n),
            "input channels differ in length"
        );
        self.frames_in += n as u64;
        let Some(engine) = self.engine.as_mut() else {
            for (o, i) in output.iter_mut().zip(input) {
                o.extend_from_slice(i);
            }
            self.frames_out += n as u64;
            return;
        };
        let mut pos = 0;
        while pos < n {
            let take = (engine.block_in - engine.fill).min(n - pos);
            for (buf, src) in engine.input.iter_mut().zip(input) {
                buf[engine.fill..engine.fill + take].copy_from_slice(&src[pos..pos + take]);
            }
            engine.fill += take;
            pos += take;
            if engine.fill == engine.block_in {
                engine.fill = 0;
                self.frames_out += engine.run_block(output, u64::MAX);
            }
        }
    }

    /// Ends the stream: appends the remaining output so that the stream's total is exactly
    /// [`output_len`](Self::output_len)`(frames in)`, then resets, ready for a new stream.
    ///
    /// # Panics
    /// If `output` does not have [`channels`](Self::channels) entries.
    pub fn finish(&mut self, output: &mut [Vec<f32>]) {
        assert_eq!(output.len(), self.channels, "output channel count");
        let total = self.output_len(self.frames_in);
        if let Some(engine) = self.engine.as_mut() {
            while self.frames_out < total {
                for buf in &mut engine.input {
                    buf[engine.fill..].fill(0.0);
                }
                engine.fill = 0;
                self.frames_out += engine.run_block(output, total - self.frames_out);
            }
        }
        self.reset();
    }

    /// Back to the just-constructed state.
    pub fn reset(&mut self) {
        self.frames_in = 0;
        self.frames_out = 0;
        if let Some(engine) = self.engine.as_mut() {
            engine.fft.reset();
            engine.fill = 0;
            engine.to_skip = engine.delay;
        }
    }

    /// Upper bound, in output frames, on how far the emitted output trails the input:
    /// the filter delay plus one block of buffering. 0 for an identity conversion.
    pub fn latency_samples(&self) -> usize {
        self.engine.as_ref().map_or(0, |e| e.delay + e.block_out)
    }
}

/// Resamples whole signals (one slice per channel, equal lengths) from `in_rate` to
/// `out_rate` Hz; each output channel has exactly `round(len · out / in)` frames.
pub fn resample_all(
    input: &[&[f32]],
    in_rate: u32,
    out_rate: u32,
) -> Result<Vec<Vec<f32>>, ResampleError> {
    let n = input.first().map_or(0, |c| c.len());
    if input.iter().any(|c| c.len() != n) {
        return Err(ResampleError::InvalidChannels(
            "input channels differ in length".into(),
        ));
    }
    let mut resampler = StreamResampler::new(in_rate, out_rate, input.len())?;
    let cap = resampler.output_len(n as u64) as usize;
    let mut output = vec![Vec::with_capacity(cap); input.len()];
    resampler.process(input, &mut output);
    resampler.finish(&mut output);
    Ok(output)
}
