//! Streaming audio decoding: any supported file in, planar stereo `f32` out, one packet at a time.
//!
//! # Algorithm
//! [Symphonia](https://github.com/pdeljanov/Symphonia) 0.6 probes the container (WAV, FLAC,
//! MP3, Ogg, MP4/M4A, MKV, CAF, AIFF) and decodes the default audio track's codec (PCM 8–32-bit
//! integer and 32/64-bit float, FLAC, MP3, Vorbis, AAC-LC, ALAC, ADPCM). Each call to
//! [`AudioSource::read_block`] demuxes and decodes the next packet and appends it to the caller's
//! left/right vectors, so the source itself holds one packet of audio at most: memory does not
//! grow with the length of the song.
//!
//! Per packet, in order:
//! 1. **Gapless trim.** If the container signals encoder delay/padding on the packet and the
//!    decoder did not already trim it (Symphonia's MP3 and Vorbis decoders do; the AAC decoder
//!    does not), the signalled frames are cut here.
//! 2. **Sanitize.** Every NaN/±Inf sample becomes 0 and is counted ([`AudioSource::non_finite`]);
//!    subnormals are flushed (see [`tactus_dsp::sanitize`]). Nothing non-finite leaves this module.
//! 3. **To stereo.** Mono is duplicated to both sides; stereo passes through. More channels are
//!    downmixed with fixed gains per speaker position, in the spirit of ITU-R BS.775:
//!    front left/right 1.0 to their side; every centre channel (front, rear, top) 1/√2 to both;
//!    every other left-side (side, rear, wide, left-of-centre, top, bottom) channel 1/√2 to the
//!    left, and likewise right. **Deviation from BS.775:** LFE channels are *kept* (1/√2 to both),
//!    because kick and bass drive the glove. Each side's gains are then divided by their sum
//!    (when it exceeds 1), so a full-scale input can never exceed full scale after the downmix.
//!    Channels without positions (discrete, custom labels) go alternately to left (even index)
//!    and right (odd index), averaged per side; Ambisonics keeps only the omni (W) channel.
//!
//! # Damaged input
//! Opening decodes up to the first packet that yields audio; if none does, [`AudioSource::open`]
//! returns an error ([`SourceError::Truncated`] if the file ended early, [`SourceError::Corrupt`]
//! if its packets did not decode, [`SourceError::UnsupportedCodec`] if the codec or one of its
//! features is not implemented). Once audio has been found, damage is not an error:
//! * a packet the decoder rejects is skipped and counted ([`AudioSource::skipped_packets`]);
//! * a file that ends mid-stream (cut download, WAV header claiming more data than the file
//!   holds, a container that stops parsing) ends the stream early and sets
//!   [`AudioSource::truncated`]; every packet read before that point is delivered. A partially
//!   present last packet is lost (at most one packet, e.g. 1152 frames of MP3). The flag is also
//!   set when the container declared a frame count and fewer frames were delivered.
//!
//! # Limits
//! Chained Ogg streams end at the first link. A change of sample rate inside a stream is not
//! followed (the rate reported by [`AudioSource::info`] is that of the first packet).
//!
//! # Latency
//! None added: a packet is delivered as soon as it is decoded (the codec's own delay, e.g. the
//! AAC priming frames of a container without gapless information, stays in the signal).

use std::fs::File;
use std::io::{self, Read, Seek};
use std::path::{Path, PathBuf};

use symphonia::core::audio::{Channels, Position};
use symphonia::core::codecs::audio::{AudioDecoder, AudioDecoderOptions};
use symphonia::core::codecs::CodecParameters;
use symphonia::core::errors::Error as SymError;
use symphonia::core::formats::probe::Hint;
use symphonia::core::formats::{FormatOptions, FormatReader, TrackType};
use symphonia::core::io::{MediaSource, MediaSourceStream, ReadOnlySource};
use symphonia::core::meta::MetadataOptions;

/// Why a file could not be opened or read. Every message starts with the file's path.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SourceError {
    /// The path does not exist.
    #[error("{}: file not found", .0.display())]
    NotFound(PathBuf),
    /// The file has zero bytes, or a valid container that holds zero audio frames.
    #[error("{}: file is empty (no audio in it)", .0.display())]
    Empty(PathBuf),
    /// The path is a directory.
    #[error("{}: is a directory, not an audio file (render takes one song; name the file)", .0.display())]
    Directory(PathBuf),
    /// The file is text (a document, a playlist, source code), not audio. Told apart from
    /// [`SourceError::UnsupportedFormat`] because a decoder library probing text may find
    /// what looks like a marker inside it and report that marker's problem instead.
    #[error("{}: not an audio file (no known audio format found; the file is text)", .0.display())]
    NotAudio(PathBuf),
    /// No container format recognised the file.
    #[error("{}: not a recognised audio file (unsupported or corrupt container)", .path.display())]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
    },
    /// The container was recognised but its codec (or a feature it uses) cannot be decoded.
    #[error("{}: audio codec not supported ({codec})", .path.display())]
    UnsupportedCodec {
        /// The file.
        path: PathBuf,
        /// What the decoder library said about the codec.
        codec: String,
    },
    /// The container holds no audio track.
    #[error("{}: contains no audio track", .0.display())]
    NoAudioTrack(PathBuf),
    /// The file's audio data is damaged beyond decoding.
    #[error("{}: damaged audio file, nothing could be decoded ({detail})", .path.display())]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What went wrong, from the decoder library.
        detail: String,
    },
    /// The file ends before any audio could be decoded.
    #[error("{}: file is truncated, it ends before any audio ({detail})", .path.display())]
    Truncated {
        /// The file.
        path: PathBuf,
        /// What went wrong, from the decoder library.
        detail: String,
    },
    /// The operating system failed to read the file.
    #[error("{}: read error: {source}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: io::Error,
    },
}

/// What is known about a stream once it is open.
#[derive(Debug, Clone, PartialEq)]
pub struct AudioInfo {
    /// Sample rate in Hz of the decoded audio.
    pub sample_rate: u32,
    /// Channel count of the decoded audio, before the stereo downmix.
    pub channels: usize,
    /// Frames per channel the container declares, if it does (may include codec priming).
    pub frames: Option<u64>,
    /// `frames / sample_rate` in seconds, if `frames` is known.
    pub duration_s: Option<f64>,
    /// Short codec name from the decoder, e.g. `"mp3"`, `"flac"`, `"pcm_s16le"`.
    pub codec: String,
    /// Short container name from the demuxer, e.g. `"wave"`, `"ogg"`, `"isomp4"`.
    pub container: String,
}

/// A whole file decoded into memory by [`decode_all`].
#[derive(Debug, Clone)]
pub struct Decoded {
    /// The stream's description.
    pub info: AudioInfo,
    /// Left channel (or the mono signal).
    pub left: Vec<f32>,
    /// Right channel (or the mono signal again).
    pub right: Vec<f32>,
    /// NaN/Inf samples that were replaced by 0 (counted per channel sample, before the downmix).
    pub non_finite: usize,
    /// Packets the decoder rejected and that were skipped.
    pub skipped_packets: usize,
    /// The stream ended early (see the module docs).
    pub truncated: bool,
}

/// A streaming decoder for one audio file. See the module docs.
pub struct AudioSource {
    path: PathBuf,
    reader: Box<dyn FormatReader>,
    decoder: Box<dyn AudioDecoder>,
    track_id: u32,
    info: AudioInfo,
    /// One decoded packet, one `Vec` per channel; reused for every packet.
    planes: Vec<Vec<f32>>,
    /// Valid range of `planes` after the gapless trim.
    valid: (usize, usize),
    /// `planes` holds a packet decoded by `open` that has not been delivered yet.
    pending: bool,
    /// Channel layout the downmix gains were computed for.
    layout: Channels,
    /// Per-channel (left, right) gains.
    gains: Vec<(f32, f32)>,
    frames_read: u64,
    non_finite: usize,
    skipped_packets: usize,
    truncated: bool,
    ended: bool,
}

impl std::fmt::Debug for AudioSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AudioSource")
            .field("path", &self.path)
            .field("info", &self.info)
            .field("frames_read", &self.frames_read)
            .field("non_finite", &self.non_finite)
            .field("skipped_packets", &self.skipped_packets)
            .field("truncated", &self.truncated)
            .finish_non_exhaustive()
    }
}

/// What decoding the next packet gave.
enum Step {
    /// `planes[valid]` holds this many frames (possibly 0).
    Frames(usize),
    /// The stream is over.
    End,
}

impl AudioSource {
    /// Opens `path`, recognises its container and codec, and decodes up to the first packet
    /// that holds audio (so that a file with no decodable audio fails here, not later).
    ///
    /// A file that cannot be decoded and whose first bytes are text is reported as
    /// [`SourceError::NotAudio`], whatever the decoder library said about it.
    pub fn open(path: &Path) -> Result<AudioSource, SourceError> {
        Self::open_decoding(path).map_err(|e| match e {
            SourceError::UnsupportedFormat { .. }
            | SourceError::UnsupportedCodec { .. }
            | SourceError::NoAudioTrack(_)
            | SourceError::Corrupt { .. }
            | SourceError::Truncated { .. }
                if file_is_text(path) =>
            {
                SourceError::NotAudio(path.to_path_buf())
            }
            e => e,
        })
    }

    /// [`AudioSource::open`] as the decoder library sees the file.
    fn open_decoding(path: &Path) -> Result<AudioSource, SourceError> {
        let p = path.to_path_buf();
        let meta = std::fs::metadata(path).map_err(|e| match e.kind() {
            io::ErrorKind::NotFound => SourceError::NotFound(p.clone()),
            _ => SourceError::Io {
                path: p.clone(),
                source: e,
            },
        })?;
        if meta.is_dir() {
            return Err(SourceError::Directory(p));
        }
        if meta.is_file() && meta.len() == 0 {
            return Err(SourceError::Empty(p));
        }
        let mut hint = Hint::new();
        if let Some(ext) = path.extension().and_then(|e| e.to_str()) {
            hint.with_extension(ext);
        }
        let reader = match probe(path, &hint, Probe::Plain) {
            Ok(reader) => reader,
            Err(first) if is_no_reader(&first) => return Err(probe_error(&p, first)),
            // Second chances for damaged files, see `Probe`.
            Err(first) => [Probe::Unseekable, Probe::RiffSizeIgnored]
                .into_iter()
                .find_map(|how| probe(path, &hint, how).ok())
                .ok_or_else(|| probe_error(&p, first))?,
        };

        let track = reader
            .default_track(TrackType::Audio)
            .ok_or_else(|| SourceError::NoAudioTrack(p.clone()))?;
        let params = match &track.codec_params {
            Some(CodecParameters::Audio(a)) => a.clone(),
            _ => return Err(SourceError::NoAudioTrack(p)),
        };
        let track_id = track.id;
        let declared_frames = track.num_frames;
        let decoder = symphonia::default::get_codecs()
            .make_audio_decoder(&params, &AudioDecoderOptions::default())
            .map_err(|e| SourceError::UnsupportedCodec {
                path: p.clone(),
                codec: format!("codec id {}: {e}", params.codec),
            })?;
        let info = AudioInfo {
            sample_rate: params.sample_rate.unwrap_or(0),
            channels: params.channels.as_ref().map_or(0, Channels::count),
            frames: declared_frames,
            duration_s: None,
            codec: decoder.codec_info().short_name.to_string(),
            container: reader.format_info().short_name.to_string(),
        };
        let mut source = AudioSource {
            path: p,
            reader,
            decoder,
            track_id,
            info,
            planes: Vec::new(),
            valid: (0, 0),
            pending: false,
            layout: Channels::None,
            gains: Vec::new(),
            frames_read: 0,
            non_finite: 0,
            skipped_packets: 0,
            truncated: false,
            ended: false,
        };
        source.prime()?;
        Ok(source)
    }

    /// Decodes until the first packet with audio; fills in rate and channels from it.
    fn prime(&mut self) -> Result<(), SourceError> {
        let mut last_error: Option<SymError> = None;
        loop {
            match self.step(&mut last_error)? {
                Step::Frames(0) => continue,
                Step::Frames(_) => break,
                Step::End => {
                    let detail = last_error.as_ref().map_or_else(
                        || "the file ends inside the first audio packet".to_string(),
                        ToString::to_string,
                    );
                    let path = self.path.clone();
                    return Err(if self.truncated {
                        SourceError::Truncated { path, detail }
                    } else {
                        match last_error {
                            None => SourceError::Empty(path),
                            Some(SymError::Unsupported(_)) => SourceError::UnsupportedCodec {
                                path,
                                codec: format!("{}: {detail}", self.info.codec),
                            },
                            Some(_) => SourceError::Corrupt { path, detail },
                        }
                    });
                }
            }
        }
        self.pending = true;
        if let Some(n) = self.info.frames {
            if self.info.sample_rate > 0 {
                self.info.duration_s = Some(n as f64 / f64::from(self.info.sample_rate));
            }
        }
        Ok(())
    }

    /// Demuxes and decodes the next packet of our track into `planes` (trimmed, sanitized).
    /// Decoder errors skip the packet and are remembered in `last_error`.
    /// [`AudioSource::step_inner`], with a panic inside the decoder (damaged data that a
    /// codec does not check) treated as the end of the readable data, like a truncation.
    fn step(&mut self, last_error: &mut Option<SymError>) -> Result<Step, SourceError> {
        match guarded(|| self.step_inner(last_error)) {
            Some(r) => r,
            None => {
                self.truncated = true;
                *last_error = Some(SymError::DecodeError("the decoder failed on damaged data"));
                Ok(self.end())
            }
        }
    }

    fn step_inner(&mut self, last_error: &mut Option<SymError>) -> Result<Step, SourceError> {
        if self.ended {
            return Ok(Step::End);
        }
        loop {
            let packet = match self.reader.next_packet() {
                Ok(Some(packet)) => packet,
                Ok(None) => return Ok(self.end()),
                Err(SymError::IoError(e)) if e.kind() != io::ErrorKind::UnexpectedEof => {
                    self.ended = true;
                    return Err(SourceError::Io {
                        path: self.path.clone(),
                        source: e,
                    });
                }
                // A chained Ogg stream: we stop at the end of the first link (documented).
                Err(SymError::ResetRequired) => return Ok(self.end()),
                // Unexpected end of file, or a container that stops parsing: keep what we have.
                Err(e) => {
                    self.truncated = true;
                    *last_error = Some(e);
                    return Ok(self.end());
                }
            };
            if packet.track_id != self.track_id {
                continue;
            }
            let decoded = match self.decoder.decode(&packet) {
                Ok(buf) => buf,
                Err(SymError::ResetRequired) => {
                    self.decoder.reset();
                    self.skipped_packets += 1;
                    continue;
                }
                Err(e) => {
                    self.skipped_packets += 1;
                    *last_error = Some(e);
                    continue;
                }
            };
            let frames = decoded.frames();
            let spec = decoded.spec().clone();
            decoded.copy_to_vecs_planar::<f32>(&mut self.planes);
            if self.frames_read == 0 && !self.pending {
                self.info.sample_rate = spec.rate();
            }
            if *spec.channels() != self.layout || self.gains.len() != self.planes.len() {
                self.layout = spec.channels().clone();
                self.gains = stereo_gains(&self.layout, self.planes.len());
                if self.frames_read == 0 {
                    self.info.channels = self.planes.len();
                }
            }
            // Gapless trim, unless the decoder already applied it.
            let (trim_start, trim_end) = (packet.trim_start.get(), packet.trim_end.get());
            let (mut start, mut end) = (0, frames);
            if (trim_start > 0 || trim_end > 0) && frames as u64 == packet.block_dur().get() {
                start = (trim_start as usize).min(frames);
                end = frames - (trim_end as usize).min(frames - start);
            }
            self.valid = (start, end);
            for plane in &mut self.planes {
                self.non_finite += tactus_dsp::sanitize::sanitize(&mut plane[start..end]);
            }
            return Ok(Step::Frames(end - start));
        }
    }

    fn end(&mut self) -> Step {
        self.ended = true;
        if let Some(n) = self.info.frames {
            if self.frames_read + self.valid_len_if_pending() < n {
                self.truncated = true;
            }
        }
        Step::End
    }

    fn valid_len_if_pending(&self) -> u64 {
        if self.pending {
            (self.valid.1 - self.valid.0) as u64
        } else {
            0
        }
    }

    /// Appends the next decoded packet to `left` and `right` as planar stereo and returns the
    /// number of frames appended; 0 means the stream is over (never returned before the end).
    /// The vectors grow by one packet (usually 576–4608 frames); reserve them to avoid
    /// reallocation. An `Err` is only an operating-system read error; damaged data is handled
    /// as the module docs describe.
    pub fn read_block(
        &mut self,
        left: &mut Vec<f32>,
        right: &mut Vec<f32>,
    ) -> Result<usize, SourceError> {
        if !self.pending {
            let mut last_error = None;
            loop {
                match self.step(&mut last_error)? {
                    Step::Frames(0) => continue,
                    Step::Frames(_) => break,
                    Step::End => return Ok(0),
                }
            }
        }
        self.pending = false;
        let (start, end) = self.valid;
        let n = end - start;
        match self.planes.len() {
            0 => {
                left.resize(left.len() + n, 0.0);
                right.resize(right.len() + n, 0.0);
            }
            1 => {
                left.extend_from_slice(&self.planes[0][start..end]);
                right.extend_from_slice(&self.planes[0][start..end]);
            }
            2 if self.gains == [(1.0, 0.0), (0.0, 1.0)] => {
                left.extend_from_slice(&self.planes[0][start..end]);
                right.extend_from_slice(&self.planes[1][start..end]);
            }
            _ => {
                let l0 = left.len();
                left.resize(l0 + n, 0.0);
                right.resize(l0 + n, 0.0);
                for (plane, &(gl, gr)) in self.planes.iter().zip(&self.gains) {
                    let src = &plane[start..end];
                    if gl != 0.0 {
                        for (o, &x) in left[l0..].iter_mut().zip(src) {
                            *o += gl * x;
                        }
                    }
                    if gr != 0.0 {
                        for (o, &x) in right[l0..].iter_mut().zip(src) {
                            *o += gr * x;
                        }
                    }
                }
            }
        }
        self.frames_read += n as u64;
        Ok(n)
    }

    /// The stream's description.
    pub fn info(&self) -> &AudioInfo {
        &self.info
    }

    /// The path this source was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// NaN/Inf samples replaced by 0 so far (per channel sample, before the downmix).
    pub fn non_finite(&self) -> usize {
        self.non_finite
    }

    /// Packets the decoder rejected and that were skipped so far.
    pub fn skipped_packets(&self) -> usize {
        self.skipped_packets
    }

    /// Whether the stream ended early: the file stopped mid-stream, or delivered fewer frames
    /// than its container declared. Meaningful once [`read_block`](Self::read_block) returned 0.
    pub fn truncated(&self) -> bool {
        self.truncated
    }

    /// Frames delivered so far.
    pub fn frames_read(&self) -> u64 {
        self.frames_read
    }
}

/// How [`probe`] presents the file to Symphonia.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Probe {
    /// As it is.
    Plain,
    /// Unseekable and of unknown length. Some readers (FLAC, Ogg) seek to the end of a seekable
    /// file to find its duration and fail when the end is cut off or damaged; without seeking
    /// they read from the front and deliver what is there.
    Unseekable,
    /// A RIFF/WAVE file with its RIFF size field read as 0xFFFF_FFFF ("unknown", as streaming
    /// writers leave it). A WAV whose data chunk claims more than the RIFF size (a header
    /// enlarged or never finalised) is then read up to where the file really ends.
    RiffSizeIgnored,
}

/// Opens `path` and probes its container, presenting the file as `how` says.
fn probe(path: &Path, hint: &Hint, how: Probe) -> Result<Box<dyn FormatReader>, SymError> {
    let file = File::open(path)?;
    let source: Box<dyn MediaSource> = match how {
        Probe::Plain => Box::new(file),
        Probe::Unseekable => Box::new(ReadOnlySource::new(file)),
        Probe::RiffSizeIgnored => Box::new(RiffSizeIgnored::new(file)?),
    };
    let mss = MediaSourceStream::new(source, Default::default());
    guarded(|| {
        symphonia::default::get_probe().probe(
            hint,
            mss,
            FormatOptions::default(),
            MetadataOptions::default(),
        )
    })
    .unwrap_or(Err(SymError::DecodeError(
        "the container parser failed on damaged data",
    )))
}

thread_local! {
    /// Set while [`guarded`] runs: the panic hook stays quiet for panics it catches.
    static GUARDED: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f` (a call into Symphonia on untrusted bytes); a panic inside it becomes `None`
/// instead of unwinding into the caller, and prints nothing (the caller reports it as one
/// error line). Found by `tests/fuzz_source.rs`: Symphonia 0.6.1's RIFF reader multiplies
/// header fields without checking for overflow. Panics elsewhere print as usual.
fn guarded<T>(f: impl FnOnce() -> T) -> Option<T> {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !GUARDED.with(|g| g.get()) {
                previous(info);
            }
        }));
    });
    let was = GUARDED.with(|g| g.replace(true));
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    GUARDED.with(|g| g.set(was));
    r.ok()
}

/// A RIFF/WAVE file whose bytes 4..8 (the RIFF size) read as 0xFF.
struct RiffSizeIgnored {
    file: File,
    pos: u64,
    len: u64,
}

impl RiffSizeIgnored {
    fn new(mut file: File) -> io::Result<Self> {
        let mut head = [0u8; 12];
        file.read_exact(&mut head)?;
        if &head[0..4] != b"RIFF" || &head[8..12] != b"WAVE" {
            return Err(io::Error::new(io::ErrorKind::InvalidData, "not RIFF/WAVE"));
        }
        let len = file.metadata()?.len();
        file.seek(io::SeekFrom::Start(0))?;
        Ok(RiffSizeIgnored { file, pos: 0, len })
    }
}

impl Read for RiffSizeIgnored {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.file.read(buf)?;
        for (i, b) in buf[..n].iter_mut().enumerate() {
            if (4..8).contains(&(self.pos + i as u64)) {
                *b = 0xFF;
            }
        }
        self.pos += n as u64;
        Ok(n)
    }
}

impl Seek for RiffSizeIgnored {
    fn seek(&mut self, to: io::SeekFrom) -> io::Result<u64> {
        self.pos = self.file.seek(to)?;
        Ok(self.pos)
    }
}

impl MediaSource for RiffSizeIgnored {
    fn is_seekable(&self) -> bool {
        true
    }

    fn byte_len(&self) -> Option<u64> {
        Some(self.len)
    }
}

/// Whether the file's first KiB reads as text ([`looks_like_text`]); false when it cannot be
/// read.
fn file_is_text(path: &Path) -> bool {
    let mut head = Vec::with_capacity(1024);
    File::open(path)
        .and_then(|f| f.take(1024).read_to_end(&mut head))
        .is_ok_and(|_| looks_like_text(&head))
}

/// Whether `head` (a file's first bytes) is text: UTF-8 (a character cut off at the end
/// allowed) without NUL or any other control character but tab, line feed, form feed and
/// carriage return. No audio container starts so: their headers hold binary sizes and
/// flags (zero bytes, bytes of 0x80 and above that are not UTF-8), and an MPEG stream
/// starts with 0xFF.
pub(crate) fn looks_like_text(head: &[u8]) -> bool {
    let text = match std::str::from_utf8(head) {
        Ok(t) => t,
        // A multi-byte character cut off by the end of `head`.
        Err(e) if e.error_len().is_none() => match std::str::from_utf8(&head[..e.valid_up_to()]) {
            Ok(t) => t,
            Err(_) => return false,
        },
        Err(_) => return false,
    };
    !text.is_empty()
        && text
            .chars()
            .all(|c| !c.is_control() || matches!(c, '\t' | '\n' | '\r' | '\x0c'))
}

fn is_no_reader(e: &SymError) -> bool {
    matches!(e, SymError::Unsupported(msg) if msg.contains("no suitable format reader"))
}

/// Maps a probe failure to the error a user should see.
fn probe_error(path: &Path, e: SymError) -> SourceError {
    let path = path.to_path_buf();
    match e {
        SymError::IoError(e) if e.kind() == io::ErrorKind::UnexpectedEof => {
            SourceError::Truncated {
                path,
                detail: "the container header is incomplete".to_string(),
            }
        }
        SymError::IoError(source) => SourceError::Io { path, source },
        // The probe found no reader at all.
        e if is_no_reader(&e) => SourceError::UnsupportedFormat { path },
        // A reader recognised the container but found its structure broken (Symphonia reports
        // these as "unsupported" too; they are told apart by their wording).
        SymError::Unsupported(msg)
            if ["missing", "marker", "not a ", "riff form", "not marked"]
                .iter()
                .any(|w| msg.contains(w)) =>
        {
            SourceError::Corrupt {
                path,
                detail: msg.to_string(),
            }
        }
        // A reader recognised the container but rejected what it holds (e.g. a WAV format tag
        // that has no decoder).
        SymError::Unsupported(msg) => SourceError::UnsupportedCodec {
            path,
            codec: msg.to_string(),
        },
        other => SourceError::Corrupt {
            path,
            detail: other.to_string(),
        },
    }
}

/// Per-channel (left, right) gains that fold `count` decoded planes into stereo.
/// See the module docs for the rule.
fn stereo_gains(layout: &Channels, count: usize) -> Vec<(f32, f32)> {
    let mut gains: Vec<(f32, f32)> = match count {
        0 => return Vec::new(),
        1 => return vec![(1.0, 1.0)],
        2 => return vec![(1.0, 0.0), (0.0, 1.0)],
        _ => match layout {
            Channels::Positioned(positions) if positions.bits().count_ones() as usize == count => {
                // Planes are in canonical order: ascending position bit.
                (0..64)
                    .map(|b| 1u64 << b)
                    .filter(|bit| positions.bits() & bit != 0)
                    .map(|bit| position_gains(Position::from_bits_retain(bit)))
                    .collect()
            }
            Channels::Ambisonic(_) => {
                let mut g = vec![(0.0, 0.0); count];
                g[0] = (1.0, 1.0);
                return g;
            }
            _ => (0..count)
                .map(|i| if i % 2 == 0 { (1.0, 0.0) } else { (0.0, 1.0) })
                .collect(),
        },
    };
    let sum_l: f32 = gains.iter().map(|g| g.0).sum();
    let sum_r: f32 = gains.iter().map(|g| g.1).sum();
    let norm = sum_l.max(sum_r).max(1.0);
    // Discrete channels are averaged per side, positioned ones share one normalisation so
    // that the left/right balance is kept.
    let per_side = !matches!(layout, Channels::Positioned(_));
    for g in &mut gains {
        if per_side {
            g.0 /= sum_l.max(1.0);
            g.1 /= sum_r.max(1.0);
        } else {
            g.0 /= norm;
            g.1 /= norm;
        }
    }
    gains
}

/// (left, right) gain of one speaker position.
fn position_gains(pos: Position) -> (f32, f32) {
    const H: f32 = std::f32::consts::FRAC_1_SQRT_2;
    let left = Position::REAR_LEFT
        | Position::FRONT_LEFT_CENTER
        | Position::SIDE_LEFT
        | Position::TOP_FRONT_LEFT
        | Position::TOP_REAR_LEFT
        | Position::TOP_SIDE_LEFT
        | Position::BOTTOM_FRONT_LEFT
        | Position::FRONT_LEFT_WIDE;
    let right = Position::REAR_RIGHT
        | Position::FRONT_RIGHT_CENTER
        | Position::SIDE_RIGHT
        | Position::TOP_FRONT_RIGHT
        | Position::TOP_REAR_RIGHT
        | Position::TOP_SIDE_RIGHT
        | Position::BOTTOM_FRONT_RIGHT
        | Position::FRONT_RIGHT_WIDE;
    if pos == Position::FRONT_LEFT {
        (1.0, 0.0)
    } else if pos == Position::FRONT_RIGHT {
        (0.0, 1.0)
    } else if left.contains(pos) {
        (H, 0.0)
    } else if right.contains(pos) {
        (0.0, H)
    } else {
        // Centres (front, rear, top, bottom), LFE 1 and 2, and positions unknown to us.
        (H, H)
    }
}

/// Decodes a whole file into memory (convenience over [`AudioSource`]).
pub fn decode_all(path: &Path) -> Result<Decoded, SourceError> {
    let mut source = AudioSource::open(path)?;
    let capacity = source.info().frames.unwrap_or(0).min(1 << 28) as usize;
    let mut left = Vec::with_capacity(capacity);
    let mut right = Vec::with_capacity(capacity);
    while source.read_block(&mut left, &mut right)? > 0 {}
    Ok(Decoded {
        info: source.info().clone(),
        left,
        right,
        non_finite: source.non_finite(),
        skipped_packets: source.skipped_packets(),
        truncated: source.truncated(),
    })
}
